"""Flight plans for the simulator: built-in plans and the TOML plan file format.

A plan is a take-off altitude and a list of legs flown in order; after the last leg the
vehicle lands. Leg kinds (all speeds over ground, m/s; headings degrees clockwise from north):

- ``hover``: hold position for ``duration_s``.
- ``straight``: fly at ``speed_mps`` towards ``heading_deg``; with ``distance_m`` it brakes to
  a stop at the end (a waypoint), with ``duration_s`` it flies on into the next leg, with
  neither it never ends (the flight ends at the battery reserve).
- ``circle``: fly ``turns`` turns (or ``duration_s``) of radius ``radius_m`` at ``speed_mps``,
  ``clockwise`` seen from above, starting tangent to ``heading_deg``.

Every leg may set ``alt_m`` (target altitude above home, reached at up to ``climb_mps`` while
the leg flies; default: keep the current one).

Plan file (TOML)::

    name = "survey"            # optional
    takeoff_alt_m = 20         # optional, default 20
    [[legs]]
    kind = "straight"
    speed_mps = 8
    heading_deg = 90
    distance_m = 300
    alt_m = 40                 # optional
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from estimator.errors import UserError
from estimator.toml_files import read_toml

LEG_KINDS = ("hover", "straight", "circle")
BUILTIN_PLANS = ("straight", "circles", "mixed", "hover-cruise")
DEFAULT_TAKEOFF_ALT_M = 20.0
DEFAULT_CLIMB_MPS = 2.0


@dataclass(frozen=True)
class Leg:
    """One leg of a plan; see the module docstring for the meaning of each field."""

    kind: str
    speed_mps: float = 0.0
    heading_deg: float = 0.0
    distance_m: float | None = None
    duration_s: float | None = None
    radius_m: float = 0.0
    turns: float | None = None
    clockwise: bool = True
    alt_m: float | None = None
    climb_mps: float = DEFAULT_CLIMB_MPS

    @property
    def endless(self) -> bool:
        return self.duration_s is None and self.distance_m is None and self.turns is None


@dataclass(frozen=True)
class Plan:
    name: str
    legs: tuple[Leg, ...]
    takeoff_alt_m: float = DEFAULT_TAKEOFF_ALT_M

    @property
    def endless(self) -> bool:
        return any(leg.endless for leg in self.legs)


def builtin_plan(name: str, climb: bool = False, cruise_speed_mps: float = 10.0) -> Plan:
    """A built-in plan by name. ``climb`` adds altitude changes between legs (20 ↔ 50 m)."""
    if name == "straight":
        legs = _straight_legs()
    elif name == "circles":
        legs = _circle_legs()
    elif name == "mixed":
        legs = _mixed_legs()
    elif name == "hover-cruise":
        legs = [
            Leg("hover", duration_s=60.0),
            Leg("straight", speed_mps=cruise_speed_mps, heading_deg=45.0),
        ]
    else:
        raise UserError(f"unknown plan '{name}' (built-in: {', '.join(BUILTIN_PLANS)})")
    if climb:
        legs = [
            replace(leg, alt_m=50.0 if i % 2 == 0 else DEFAULT_TAKEOFF_ALT_M, climb_mps=2.5)
            for i, leg in enumerate(legs)
        ]
    return Plan(name, tuple(legs))


def _straight_legs() -> list[Leg]:
    """The paper's experiment 1: round trips on a 150 m line at 2..14 m/s, stopping to turn."""
    legs = []
    for speed in range(2, 15, 2):
        for _ in range(2):
            legs.append(Leg("straight", float(speed), heading_deg=0.0, distance_m=150.0))
            legs.append(Leg("straight", float(speed), heading_deg=180.0, distance_m=150.0))
    return legs


def _circle_legs() -> list[Leg]:
    """The paper's experiment 2: circles of radius 10 and 20 m at 2..6 m/s (two turns each)."""
    legs = []
    for radius in (10.0, 20.0):
        for speed in (2.0, 4.0, 6.0):
            legs.append(Leg("circle", speed, radius_m=radius, turns=2.0))
            legs.append(Leg("hover", duration_s=5.0))
    legs.append(Leg("circle", 8.0, radius_m=20.0, turns=2.0, clockwise=False))
    return legs


def _mixed_legs() -> list[Leg]:
    """A survey-like mission: hover, legs at several speeds and headings, turns, circles."""
    return [
        Leg("hover", duration_s=20.0),
        Leg("straight", 6.0, heading_deg=30.0, duration_s=40.0),
        Leg("straight", 10.0, heading_deg=120.0, duration_s=40.0),
        Leg("circle", 8.0, heading_deg=120.0, radius_m=40.0, turns=1.0),
        Leg("straight", 12.0, heading_deg=210.0, distance_m=500.0),
        Leg("hover", duration_s=15.0),
        Leg("circle", 5.0, radius_m=15.0, turns=1.5, clockwise=False),
        Leg("straight", 4.0, heading_deg=300.0, duration_s=45.0),
        Leg("straight", 9.0, heading_deg=0.0, distance_m=400.0),
        Leg("circle", 10.0, radius_m=50.0, turns=1.0),
        Leg("straight", 7.0, heading_deg=90.0, distance_m=300.0),
        Leg("hover", duration_s=20.0),
    ]


def load_plan(path: str | Path) -> Plan:
    """Read a TOML plan file; every problem is one clear sentence (UserError)."""
    doc = read_toml(path, "plan")
    return plan_from_toml(doc, str(path))


def resolve_plan(spec: str, climb: bool = False) -> Plan:
    """A built-in plan name or the path of a plan file."""
    if spec in BUILTIN_PLANS:
        return builtin_plan(spec, climb=climb)
    if not spec.endswith(".toml") and not Path(spec).exists():
        raise UserError(
            f"plan '{spec}' is neither built in ({', '.join(BUILTIN_PLANS)}) nor a plan file"
        )
    plan = load_plan(spec)
    if climb:
        raise UserError("--climb adds altitude changes to built-in plans; set alt_m in the file")
    return plan


def plan_from_toml(doc: Mapping[str, Any], where: str = "plan") -> Plan:
    legs_doc = doc.get("legs")
    if not isinstance(legs_doc, list) or not legs_doc:
        raise UserError(f"{where} needs at least one [[legs]] table")
    legs = tuple(_leg(item, f"{where} leg {i + 1}") for i, item in enumerate(legs_doc))
    for leg in legs[:-1]:
        if leg.endless:
            raise UserError(f"{where}: only the last leg may be endless (no duration or distance)")
    takeoff = _float(doc, "takeoff_alt_m", where, DEFAULT_TAKEOFF_ALT_M)
    if not 1.0 <= takeoff <= 500.0:
        raise UserError(f"{where}: takeoff_alt_m must be between 1 and 500 m")
    return Plan(str(doc.get("name", Path(where).stem)), legs, takeoff)


_LEG_FIELDS = {f.name for f in fields(Leg)}


def _leg(item: Any, where: str) -> Leg:
    if not isinstance(item, dict):
        raise UserError(f"{where} must be a table")
    unknown = set(item) - _LEG_FIELDS
    if unknown:
        raise UserError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
    kind = item.get("kind")
    if kind not in LEG_KINDS:
        raise UserError(f"{where}: kind must be one of {', '.join(LEG_KINDS)}, got {kind!r}")
    clockwise = item.get("clockwise", True)
    if not isinstance(clockwise, bool):
        raise UserError(f"{where}: clockwise must be true or false")
    leg = Leg(
        kind=kind,
        speed_mps=_float(item, "speed_mps", where, 0.0),
        heading_deg=_float(item, "heading_deg", where, 0.0),
        distance_m=_optional(item, "distance_m", where),
        duration_s=_optional(item, "duration_s", where),
        radius_m=_float(item, "radius_m", where, 0.0),
        turns=_optional(item, "turns", where),
        clockwise=clockwise,
        alt_m=_optional(item, "alt_m", where),
        climb_mps=_float(item, "climb_mps", where, DEFAULT_CLIMB_MPS),
    )
    _check_leg(leg, where)
    return leg


def _check_leg(leg: Leg, where: str) -> None:
    if not 0.0 <= leg.speed_mps <= 30.0:
        raise UserError(f"{where}: speed_mps must be between 0 and 30")
    for name in ("distance_m", "duration_s", "turns"):
        value = getattr(leg, name)
        if value is not None and value <= 0:
            raise UserError(f"{where}: {name} must be > 0")
    if leg.alt_m is not None and not 1.0 <= leg.alt_m <= 500.0:
        raise UserError(f"{where}: alt_m must be between 1 and 500 m")
    if not 0.1 <= leg.climb_mps <= 10.0:
        raise UserError(f"{where}: climb_mps must be between 0.1 and 10")
    if leg.kind == "hover" and leg.duration_s is None:
        raise UserError(f"{where}: a hover leg needs duration_s")
    if leg.kind == "straight" and leg.speed_mps <= 0:
        raise UserError(f"{where}: a straight leg needs speed_mps > 0")
    if leg.kind == "circle":
        if leg.speed_mps <= 0 or leg.radius_m <= 0:
            raise UserError(f"{where}: a circle leg needs speed_mps > 0 and radius_m > 0")
        if leg.speed_mps**2 / leg.radius_m > 6.0:
            raise UserError(f"{where}: speed²/radius above 6 m/s² is more than a multirotor turns")
        if leg.distance_m is not None:
            raise UserError(f"{where}: a circle leg ends by turns or duration_s, not distance_m")


def _float(table: Mapping[str, Any], key: str, where: str, default: float) -> float:
    value = _optional(table, key, where)
    return default if value is None else value


def _optional(table: Mapping[str, Any], key: str, where: str) -> float | None:
    if key not in table:
        return None
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise UserError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)
