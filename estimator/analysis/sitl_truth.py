"""What a SITL recording flew, as functions of the autopilot's clock.

A recording's ``truth.json`` (written by ``uav-energy sitl-record``, :mod:`estimator.sitl`)
lists the effects SITL switched on and off (``start_s``/``end_s``, s on the autopilot's clock)
and the flight's events (``takeoff_s``, ``landed_s``). Read here: the wind (SITL's
``SIM_WIND_SPD``/``SIM_WIND_DIR``, a speed and the direction it comes from) as the air mass's
velocity over ground, north/east (m/s), and the mass carried above the vehicle file's (kg):
the gripper payloads while held, plus the simulated frame's mass off the file's.

The recorder closes a payload spell when its own pilot opens the gripper or when the load
touches the ground in the landing (below the gripper's 2 m string); a release a mission
commands itself (DO_GRIPPER) it does not see, and the spell runs on to the landing
(``missions/release_wind2``: the autopilot reported "Gripper load released" 47 s after take-off,
the truth holds the load for 104 s more). :meth:`RecordingTruth.released_at` ends such a spell
at the release the autopilot reported.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from estimator.errors import UserError
from estimator.physics.effects import Wind


@dataclass(frozen=True)
class Spell:
    """One effect switched on from ``start_s`` until ``end_s`` (s): a wind (``speed_mps``,
    ``from_deg``) or a payload (``mass_kg``)."""

    start_s: float
    end_s: float
    speed_mps: float = 0.0
    from_deg: float = 0.0
    mass_kg: float = 0.0

    def on(self, time_s: float) -> bool:
        return self.start_s <= time_s < self.end_s


@dataclass(frozen=True)
class RecordingTruth:
    """One recording's truth: scenario, airframe (``frame``; ``custom_model``: SITL flew a
    frame model of its own, not the stock one the vehicle file describes), take-off and landing
    (s), the wind and payload spells, and the frame's mass above the vehicle file's (kg)."""

    scenario: str
    frame: str
    custom_model: bool
    takeoff_s: float
    landed_s: float
    winds: tuple[Spell, ...]
    payloads: tuple[Spell, ...]
    frame_extra_kg: float

    @property
    def stock_quad(self) -> bool:
        """SITL's stock quad, the airframe ``config/vehicles/ardupilot_sitl_quad.toml`` is."""
        return self.frame == "quad" and not self.custom_model

    def wind_ne_mps(self, time_s: float) -> np.ndarray:
        """The air mass's velocity over ground at ``time_s`` (north, east; m/s): the first
        wind spell on then, still air outside them."""
        for w in self.winds:
            if w.on(time_s):
                return air_velocity_ne(w.speed_mps, w.from_deg)
        return np.zeros(2)

    def released_at(self, times_s: Sequence[float]) -> RecordingTruth:
        """The same truth with each payload spell ending at the first gripper release the
        autopilot reported (``times_s``, s) while it was held."""
        payloads = []
        for p in self.payloads:
            inside = [t for t in times_s if p.on(t)]
            payloads.append(replace(p, end_s=min(inside)) if inside else p)
        return replace(self, payloads=tuple(payloads))

    def mass_delta_kg(self, time_s: float) -> float:
        """The mass above the vehicle file's at ``time_s`` (kg)."""
        return self.frame_extra_kg + sum(p.mass_kg for p in self.payloads if p.on(time_s))


def air_velocity_ne(speed_mps: float, from_deg: float) -> np.ndarray:
    """The air mass's velocity over ground (north, east), m/s, of a wind from ``from_deg``."""
    return np.array(Wind(speed_mps, from_deg).vector_ne_mps())


def _number(raw: object, what: str) -> float:
    if isinstance(raw, bool) or not isinstance(raw, int | float) or not math.isfinite(raw):
        raise ValueError(f"{what} is not a number")
    return float(raw)


def load_truth(path: Path, vehicle_mass_kg: float) -> RecordingTruth:
    """``truth.json`` at ``path``; ``vehicle_mass_kg``: the vehicle file's mass. UserError,
    naming the file, when it is missing or not a recording's truth."""
    try:
        raw = json.loads(path.read_text())
        events = raw["events"]
        winds, payloads = [], []
        for e in raw["effects"]:
            span = (_number(e["start_s"], "start_s"), _number(e["end_s"], "end_s"))
            if e["effect"] == "wind":
                speed, from_deg = _number(e["speed_mps"], "speed"), _number(e["from_deg"], "from")
                winds.append(Spell(*span, speed_mps=speed, from_deg=from_deg))
            elif e["effect"] == "payload":
                payloads.append(Spell(*span, mass_kg=_number(e["mass_kg"], "mass_kg")))
        frame_kg = _number(raw.get("mass_kg", vehicle_mass_kg), "mass_kg")
        return RecordingTruth(
            scenario=str(raw["scenario"]),
            frame=str(raw["frame"]),
            custom_model=bool(raw.get("model_json")),
            takeoff_s=_number(events["takeoff_s"], "takeoff_s"),
            landed_s=_number(events["landed_s"], "landed_s"),
            winds=tuple(winds),
            payloads=tuple(payloads),
            frame_extra_kg=frame_kg - vehicle_mass_kg,
        )
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror or exc}") from exc
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise UserError(f"{path} is not a SITL recording's truth ({exc!s})") from exc
