"""Vehicle files: the fitted power model, its uncertainty and the battery, as TOML.

Layout (all sections but ``[effects]`` required)::

    [vehicle]        name, mass_kg, max_airspeed_mps (optional: the fastest it flies, m/s)
    [model]          c1, c2, c3, c4, c5        (electrical power at the battery, W)
    [model.stderr]   c1, c2, c3, c4, c5        (1σ, same units; optional)
    [model]          slow_error_fraction       (optional: 1σ of the model's error that stays
                                               correlated over tens of seconds, a fraction of
                                               its hover power; the online tracker's default
                                               when absent)
    [battery]        capacity_ah, cells, reserve_fraction, chemistry (optional: lipo, lihv,
                     liion), cell_ocv_v (optional: the pack's own curve), cell_ocv_sigma_v
                     (optional: its 1σ error), internal_resistance_ohm (optional: measured)
    [effects.NAME]   parameters of effects added by ``uav-energy residuals`` (optional)
    [drag]           bcoef_x_kgpm2, bcoef_y_kgpm2, mcoef_per_s (optional: the drag per body
                     axis, ArduPilot's EK3_DRAG_* meanings; the planner's airspeed limit off
                     the nose, :mod:`estimator.physics.lean_limit`)
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from estimator.errors import UserError
from estimator.file_checks import number_in_range
from estimator.physics.lean_limit import DragLaw
from estimator.physics.model import COEFFICIENT_NAMES, PowerModel
from estimator.telemetry.plausibility import MAX_POWER_PER_HOVER, InputLimits
from estimator.toml_files import read_toml

#: Resting cell voltages of a pack curve: evenly spaced from state of charge 0 to 1, at least
#: this many (0, 0.1, …, 1) and at most that many (every 0.5 %).
OCV_TABLE_POINTS = (11, 201)
#: A cell voltage outside this range (V) is no lithium cell at rest.
OCV_RANGE_V = (2.0, 4.5)
#: 1σ error of a pack's own resting curve (V per cell): from a simulator's exact table to a
#: curve no better than a chemistry's typical one.
OCV_SIGMA_RANGE_V = (0.0001, 0.05)
#: A pack's internal resistance (Ω) as measured: above 0, at most this (no flying pack).
MAX_RESISTANCE_OHM = 2.0
#: Ranges of a vehicle file's numbers (inclusive): mass (kg), fastest airspeed (m/s), the
#: power model's coefficients (:class:`PowerModel` units: W, s²/m², W, m²/s², W·s³/m³; c4 is
#: twice the squared hover induced velocity, 0.3 to 70 m/s) and their 1σ (the same units),
#: label capacity (Ah) and series cells.
MASS_RANGE_KG = (0.01, 1000.0)
AIRSPEED_RANGE_MPS = (0.5, 100.0)
COEFFICIENT_RANGES = {
    "c1": (0.0, 1e5),
    "c2": (0.0, 1.0),
    "c3": (0.0, 1e5),
    "c4": (0.1, 1e4),
    "c5": (0.0, 100.0),
}
STDERR_RANGE = (1e-9, 1e5)
SLOW_ERROR_RANGE = (0.0, 0.5)
#: ``[drag]`` keys and their ranges: EK3_DRAG_BCOEF_X/Y (kg/m²) and EK3_DRAG_MCOEF (1/s).
DRAG_RANGES = {
    "bcoef_x_kgpm2": (1.0, 1000.0),
    "bcoef_y_kgpm2": (1.0, 1000.0),
    "mcoef_per_s": (0.0, 1.0),
}
CAPACITY_RANGE_AH = (0.05, 1000.0)
CELLS_RANGE = (1, 24)
#: Chemistries with a built-in resting curve (estimator.physics.battery.CHEMISTRY_OCV_V).
CHEMISTRIES = ("lipo", "lihv", "liion")
#: A cell's voltage believed in telemetry (V): down to its resting curve's empty voltage less
#: this sag under load (the committed SITL packs sag 0.6 V below it), up to its full voltage
#: plus this (a charger's or a sensor's overshoot).
CELL_SAG_ALLOWANCE_V = 1.0
CELL_CHARGE_ALLOWANCE_V = 0.15
#: A pack one would power a vehicle up with rests above its reserve's voltage less this (V a
#: cell: a light load's sag).
CELL_LIGHT_SAG_V = 0.1
#: Airspeeds (m/s) on which the model's power-limited speed is searched.
_AIRSPEED_GRID_MPS = np.linspace(0.0, 200.0, 801)


@dataclass(frozen=True)
class BatterySpec:
    """Pack as configured: rated (label) capacity (Ah), series cells, the reserve not to be
    used, the chemistry, and the pack's resting cell voltage (V) at evenly spaced states of
    charge from 0 to 1 (``cell_ocv_v``; None: the chemistry's built-in curve in
    :mod:`estimator.physics.battery`) with its 1σ error per cell (V, ``cell_ocv_sigma_v``;
    None: the pack filter's default for a measured curve), and the pack's internal
    resistance (Ω, ``internal_resistance_ohm``; None: not measured)."""

    capacity_ah: float
    cells: int
    reserve_fraction: float = 0.2
    cell_ocv_v: tuple[float, ...] | None = None
    chemistry: str = "lipo"
    cell_ocv_sigma_v: float | None = None
    internal_resistance_ohm: float | None = None


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
    #: 1σ of the model's slow error as a fraction of its hover power (None: not stated; see
    #: :mod:`estimator.estimation.online_effects`).
    slow_error_fraction: float | None = None
    #: The drag per body axis (None: not stated; the airspeed limit then holds along the
    #: track whatever the heading).
    drag: DragLaw | None = None

    def flyable_cells(self, voltage_v: float) -> list[int]:
        """The cell counts at which a pack reading ``voltage_v`` (V, at rest or light load)
        holds more than its reserve: each cell on this pack's resting curve between the
        reserve (less :data:`CELL_LIGHT_SAG_V`) and full (plus
        :data:`CELL_CHARGE_ALLOWANCE_V`). One count: the voltage says how many cells the pack
        has; two or more (large packs near full), or none: it does not."""
        from estimator.physics.battery import PackModel  # battery imports this module

        pack = PackModel(self.battery)
        low_v = pack.cell_ocv_slope_v(self.battery.reserve_fraction)[0] - CELL_LIGHT_SAG_V
        high_v = float(max(pack.cell_ocv_v)) + CELL_CHARGE_ALLOWANCE_V
        if not 0 < voltage_v <= InputLimits().max_voltage_v:  # NaN too: no pack reads it
            return []
        return list(range(max(1, math.ceil(voltage_v / high_v)), math.floor(voltage_v / low_v) + 1))

    def input_limits(self) -> InputLimits:
        """Plausibility limits of telemetry for this vehicle (:meth:`InputLimits.for_pack`):
        its pack's cells, each from its resting curve's empty voltage less
        :data:`CELL_SAG_ALLOWANCE_V` to its full voltage plus :data:`CELL_CHARGE_ALLOWANCE_V`;
        its hover power; its airspeed (``max_airspeed_mps``, else the speed at which the
        model asks :data:`MAX_POWER_PER_HOVER` × hover power)."""
        from estimator.physics.battery import PackModel  # battery imports this module

        curve_v = PackModel(self.battery).cell_ocv_v
        window_v = (
            float(min(curve_v)) - CELL_SAG_ALLOWANCE_V,
            float(max(curve_v)) + CELL_CHARGE_ALLOWANCE_V,
        )
        hover_w = self.model.hover_power_w
        airspeed_mps = self.max_airspeed_mps
        if airspeed_mps is None:
            power_w = self.model.power_w(_AIRSPEED_GRID_MPS)
            reached = np.flatnonzero(power_w >= MAX_POWER_PER_HOVER * hover_w)
            airspeed_mps = float(_AIRSPEED_GRID_MPS[reached[0]]) if reached.size else None
        return InputLimits.for_pack(self.battery.cells, hover_w, window_v, airspeed_mps)

    def to_toml(self) -> dict[str, Any]:
        model: dict[str, Any] = self.model.as_dict()
        if self.slow_error_fraction is not None:
            model["slow_error_fraction"] = self.slow_error_fraction
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
                **(
                    {"cell_ocv_sigma_v": self.battery.cell_ocv_sigma_v}
                    if self.battery.cell_ocv_sigma_v is not None
                    else {}
                ),
                **(
                    {"internal_resistance_ohm": self.battery.internal_resistance_ohm}
                    if self.battery.internal_resistance_ohm is not None
                    else {}
                ),
            },
        }
        if self.effects:
            doc["effects"] = {k: _toml_safe(v) for k, v in self.effects.items()}
        if self.drag is not None:
            doc["drag"] = {k: getattr(self.drag, k) for k in DRAG_RANGES}
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
    coeffs = {
        n: number_in_range(model, n, f"{where} [model]", COEFFICIENT_RANGES[n])
        for n in COEFFICIENT_NAMES
    }
    try:
        power_model = PowerModel(**coeffs)
    except ValueError as exc:
        raise UserError(f"{where} [model]: {exc}") from None
    stderr_doc = model.get("stderr", {})
    if not isinstance(stderr_doc, dict) or not set(stderr_doc) <= set(COEFFICIENT_NAMES):
        raise UserError(f"{where} [model.stderr] may hold only {', '.join(COEFFICIENT_NAMES)}")
    stderr = {
        n: number_in_range(stderr_doc, n, f"{where} [model.stderr]", STDERR_RANGE)
        for n in stderr_doc
    }
    slow_error = (
        number_in_range(model, "slow_error_fraction", f"{where} [model]", SLOW_ERROR_RANGE)
        if "slow_error_fraction" in model
        else None
    )
    mass_kg = number_in_range(vehicle, "mass_kg", f"{where} [vehicle]", MASS_RANGE_KG, "kg")
    max_airspeed = (
        number_in_range(
            vehicle, "max_airspeed_mps", f"{where} [vehicle]", AIRSPEED_RANGE_MPS, "m/s"
        )
        if "max_airspeed_mps" in vehicle
        else None
    )
    where_battery = f"{where} [battery]"
    spec = BatterySpec(
        capacity_ah=number_in_range(battery, "capacity_ah", where_battery, CAPACITY_RANGE_AH, "Ah"),
        cells=int(number_in_range(battery, "cells", where_battery, CELLS_RANGE, integer=True)),
        reserve_fraction=_number(battery, "reserve_fraction", f"{where} [battery]"),
        cell_ocv_v=_ocv_table(battery.get("cell_ocv_v"), f"{where} [battery] cell_ocv_v"),
        chemistry=_chemistry(battery.get("chemistry", "lipo"), f"{where} [battery] chemistry"),
        cell_ocv_sigma_v=_curve_sigma(battery, f"{where} [battery]"),
        internal_resistance_ohm=_resistance(battery, f"{where} [battery]"),
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
        slow_error_fraction=slow_error,
        drag=_drag(doc, where),
    )


def _drag(doc: dict[str, Any], where: str) -> DragLaw | None:
    """The optional ``[drag]`` table: every key of :data:`DRAG_RANGES`, each in its range."""
    if "drag" not in doc:
        return None
    table = _section(doc, "drag", where)
    if set(table) != set(DRAG_RANGES):
        raise UserError(f"{where} [drag] must hold exactly {', '.join(DRAG_RANGES)}")
    return DragLaw(
        **{k: number_in_range(table, k, f"{where} [drag]", r) for k, r in DRAG_RANGES.items()}
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


def _curve_sigma(battery: dict[str, Any], where: str) -> float | None:
    """``cell_ocv_sigma_v``: None, or the 1σ error (V per cell, within
    :data:`OCV_SIGMA_RANGE_V`) of the pack's own curve, which it must come with."""
    if "cell_ocv_sigma_v" not in battery:
        return None
    sigma_v = _number(battery, "cell_ocv_sigma_v", where)
    lo, hi = OCV_SIGMA_RANGE_V
    if not lo <= sigma_v <= hi:
        raise UserError(f"{where} 'cell_ocv_sigma_v' must be between {lo:g} and {hi:g} V")
    if "cell_ocv_v" not in battery:
        raise UserError(f"{where} 'cell_ocv_sigma_v' is the error of 'cell_ocv_v': give both")
    return sigma_v


def _resistance(battery: dict[str, Any], where: str) -> float | None:
    """``internal_resistance_ohm``: None, or the pack's resistance (Ω, above 0 and at most
    :data:`MAX_RESISTANCE_OHM`)."""
    if "internal_resistance_ohm" not in battery:
        return None
    resistance_ohm = _number(battery, "internal_resistance_ohm", where, positive=True)
    if resistance_ohm > MAX_RESISTANCE_OHM:
        raise UserError(
            f"{where} 'internal_resistance_ohm' must be at most {MAX_RESISTANCE_OHM:g} Ω"
        )
    return resistance_ohm


def _chemistry(value: Any, where: str) -> str:
    if value not in CHEMISTRIES:
        raise UserError(f"{where} must be one of {', '.join(CHEMISTRIES)}, got {value!r}")
    return str(value)


def default_vehicle() -> Vehicle:
    """The built-in 3 kg paper-like quadrotor (``estimator/data/default_vehicle.toml``)."""
    path = resources.files("estimator") / "data" / "default_vehicle.toml"
    return vehicle_from_toml(tomllib.loads(path.read_text()), "built-in default vehicle")
