"""Vehicle files: the fitted power model, its uncertainty and the battery, as TOML.

Layout (all sections but ``[effects]`` required)::

    [vehicle]        name, mass_kg, max_airspeed_mps (optional: the fastest it flies, m/s)
    [model]          c1, c2, c3, c4, c5        (electrical power at the battery, W)
    [model.stderr]   c1, c2, c3, c4, c5        (1σ, same units; optional)
    [battery]        capacity_ah, cells, reserve_fraction, chemistry (optional: lipo, lihv,
                     liion), cell_ocv_v (optional: the pack's own curve)
    [effects.NAME]   parameters of effects added by ``uav-energy residuals`` (optional)
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from itertools import pairwise
from pathlib import Path
from typing import Any

import tomli_w

from estimator.errors import UserError
from estimator.physics.model import COEFFICIENT_NAMES, PowerModel
from estimator.telemetry.plausibility import InputLimits
from estimator.toml_files import read_toml

#: Resting cell voltages of a pack curve: evenly spaced from state of charge 0 to 1, at least
#: this many (0, 0.1, …, 1) and at most that many (every 0.5 %).
OCV_TABLE_POINTS = (11, 201)
#: A cell voltage outside this range (V) is no lithium cell at rest.
OCV_RANGE_V = (2.0, 4.5)
#: Chemistries with a built-in resting curve (estimator.physics.battery.CHEMISTRY_OCV_V).
CHEMISTRIES = ("lipo", "lihv", "liion")


@dataclass(frozen=True)
class BatterySpec:
    """Pack as configured: rated (label) capacity (Ah), series cells, the reserve not to be
    used, the chemistry, and the pack's resting cell voltage (V) at evenly spaced states of
    charge from 0 to 1 (``cell_ocv_v``; None: the chemistry's built-in curve in
    :mod:`estimator.physics.battery`)."""

    capacity_ah: float
    cells: int
    reserve_fraction: float = 0.2
    cell_ocv_v: tuple[float, ...] | None = None
    chemistry: str = "lipo"


@dataclass(frozen=True)
class Vehicle:
    name: str
    mass_kg: float
    model: PowerModel
    battery: BatterySpec
    model_stderr: dict[str, float] = field(default_factory=dict)
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: The highest airspeed the vehicle reaches (m/s; None: not known), e.g. at its tilt limit.
    max_airspeed_mps: float | None = None

    def input_limits(self) -> InputLimits:
        """Plausibility limits of telemetry for this vehicle's pack (cells) and hover power."""
        return InputLimits.for_pack(self.battery.cells, self.model.hover_power_w)

    def to_toml(self) -> dict[str, Any]:
        model: dict[str, Any] = self.model.as_dict()
        if self.model_stderr:
            model["stderr"] = dict(self.model_stderr)
        doc: dict[str, Any] = {
            "vehicle": {
                "name": self.name,
                "mass_kg": self.mass_kg,
                **(
                    {"max_airspeed_mps": self.max_airspeed_mps}
                    if self.max_airspeed_mps is not None
                    else {}
                ),
            },
            "model": model,
            "battery": {
                "capacity_ah": self.battery.capacity_ah,
                "cells": self.battery.cells,
                "reserve_fraction": self.battery.reserve_fraction,
                **(
                    {"chemistry": self.battery.chemistry}
                    if self.battery.chemistry != "lipo"
                    else {}
                ),
                **(
                    {"cell_ocv_v": list(self.battery.cell_ocv_v)}
                    if self.battery.cell_ocv_v is not None
                    else {}
                ),
            },
        }
        if self.effects:
            doc["effects"] = {k: _toml_safe(v) for k, v in self.effects.items()}
        return doc

    def save(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(tomli_w.dumps(self.to_toml()))


def _toml_safe(params: dict[str, Any]) -> dict[str, Any]:
    """TOML has no null: drop None-valued parameters (readers treat missing as None)."""
    return {k: v for k, v in params.items() if v is not None}


def load_vehicle(path: str | Path) -> Vehicle:
    """Read and validate a vehicle file; every problem is one clear sentence (UserError)."""
    doc = read_toml(path, "vehicle")
    return vehicle_from_toml(doc, str(path))


def vehicle_from_toml(doc: dict[str, Any], where: str = "vehicle file") -> Vehicle:
    vehicle = _section(doc, "vehicle", where)
    model = _section(doc, "model", where)
    battery = _section(doc, "battery", where)
    coeffs = {n: _number(model, n, f"{where} [model]") for n in COEFFICIENT_NAMES}
    try:
        power_model = PowerModel(**coeffs)
    except ValueError as exc:
        raise UserError(f"{where} [model]: {exc}") from None
    stderr_doc = model.get("stderr", {})
    stderr = {n: _number(stderr_doc, n, f"{where} [model.stderr]") for n in stderr_doc}
    mass_kg = _number(vehicle, "mass_kg", f"{where} [vehicle]", positive=True)
    max_airspeed = (
        _number(vehicle, "max_airspeed_mps", f"{where} [vehicle]", positive=True)
        if "max_airspeed_mps" in vehicle
        else None
    )
    spec = BatterySpec(
        capacity_ah=_number(battery, "capacity_ah", f"{where} [battery]", positive=True),
        cells=int(_number(battery, "cells", f"{where} [battery]", positive=True)),
        reserve_fraction=_number(battery, "reserve_fraction", f"{where} [battery]"),
        cell_ocv_v=_ocv_table(battery.get("cell_ocv_v"), f"{where} [battery] cell_ocv_v"),
        chemistry=_chemistry(battery.get("chemistry", "lipo"), f"{where} [battery] chemistry"),
    )
    if not 0.0 <= spec.reserve_fraction < 1.0:
        raise UserError(f"{where} [battery] reserve_fraction must be in [0, 1)")
    effects = doc.get("effects", {})
    if not isinstance(effects, dict) or not all(isinstance(v, dict) for v in effects.values()):
        raise UserError(f"{where} [effects] must hold one table per effect")
    return Vehicle(
        name=str(vehicle.get("name", "unnamed")),
        mass_kg=mass_kg,
        model=power_model,
        battery=spec,
        model_stderr=stderr,
        effects=effects,
        max_airspeed_mps=max_airspeed,
    )


def _section(doc: dict[str, Any], name: str, where: str) -> dict[str, Any]:
    value = doc.get(name)
    if not isinstance(value, dict):
        raise UserError(f"{where} has no [{name}] section")
    return value


def _number(table: dict[str, Any], key: str, where: str, positive: bool = False) -> float:
    if key not in table:
        raise UserError(f"{where} is missing '{key}'")
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise UserError(f"{where} '{key}' must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise UserError(f"{where} '{key}' must be > 0, got {value!r}")
    return float(value)


def _ocv_table(value: Any, where: str) -> tuple[float, ...] | None:
    """A pack curve from a vehicle file: None, or cell voltages (:data:`OCV_TABLE_POINTS`)
    rising with the state of charge, each within :data:`OCV_RANGE_V`."""
    if value is None:
        return None
    lo, hi = OCV_RANGE_V
    numbers = isinstance(value, list) and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    )
    lo_n, hi_n = OCV_TABLE_POINTS
    if not numbers or not lo_n <= len(value) <= hi_n:
        raise UserError(
            f"{where} must be a list of {lo_n} to {hi_n} cell voltages (V) at evenly spaced "
            "states of charge from 0 to 1"
        )
    table = tuple(float(v) for v in value)
    if not all(lo <= v <= hi for v in table):
        raise UserError(f"{where} must hold cell voltages between {lo:g} and {hi:g} V")
    if any(b <= a for a, b in pairwise(table)):
        raise UserError(f"{where} must rise with the state of charge (SoC 0 first)")
    return table


def _chemistry(value: Any, where: str) -> str:
    if value not in CHEMISTRIES:
        raise UserError(f"{where} must be one of {', '.join(CHEMISTRIES)}, got {value!r}")
    return str(value)


def default_vehicle() -> Vehicle:
    """The built-in 3 kg paper-like quadrotor (``estimator/data/default_vehicle.toml``)."""
    path = resources.files("estimator") / "data" / "default_vehicle.toml"
    return vehicle_from_toml(tomllib.loads(path.read_text()), "built-in default vehicle")
