"""Score what ``uav-energy residuals`` names on a recorded SITL flight against its truth.

A recording's ``truth.json`` (:mod:`estimator.sitl.recorder`) lists the effects switched in
flight with their start and end on the autopilot's clock (s). A mass that differs from the
vehicle file's counts as a payload carried all flight. A named effect matches a true one of
its kind when its values and times are within :class:`Tolerance`; a time at take-off (or
before) matches an effect "from the start", one at the end of the analysed data (or after)
"to the end": times are compared within the span of the samples the analysis kept.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from estimator.analysis.residuals import ResidualResult, analyze
from estimator.logs import load_flights
from estimator.physics.vehicle import Vehicle

#: Residual effect name → truth effect name.
KINDS = {"wind": "wind", "mass": "payload", "avionics": "load"}


@dataclass(frozen=True)
class Tolerance:
    """How close a named effect must be: wind speed (m/s) and direction (°), mass (kg), load
    (W), start and end times (s)."""

    wind_mps: float = 1.5
    wind_deg: float = 25.0
    mass_kg: float = 0.15
    load_w: float = 10.0
    time_s: float = 10.0


@dataclass
class TruthEffect:
    kind: str
    values: dict[str, float]
    start_s: float | None
    end_s: float | None


@dataclass
class FlightTruth:
    """Effects of one recording; ``takeoff_s``/``landed_s`` bound the span they are compared
    in (s, autopilot clock)."""

    scenario: str
    effects: list[TruthEffect]
    takeoff_s: float
    landed_s: float

    def within(self, first_s: float, last_s: float) -> FlightTruth:
        """The same truth compared within the analysed samples' span ``first_s``..``last_s``."""
        return FlightTruth(
            self.scenario, self.effects, max(self.takeoff_s, first_s), min(self.landed_s, last_s)
        )

    @classmethod
    def load(cls, path: Path, vehicle_mass_kg: float) -> FlightTruth:
        """``truth.json`` at ``path``; a true mass off the vehicle's by more than 10 g is a
        payload for the whole flight."""
        raw = json.loads(path.read_text())
        events = raw["events"]
        takeoff_s, landed_s = float(events["takeoff_s"]), float(events["landed_s"])
        effects = []
        for e in raw["effects"]:
            kind = e["effect"]
            if kind == "wind":
                values = {"speed_mps": e["speed_mps"], "from_deg": e["from_deg"]}
            elif kind == "payload":
                values = {"mass_kg": e["mass_kg"]}
            else:
                values = {"power_w": e["power_w"]}
            effects.append(TruthEffect(kind, values, e.get("start_s"), e.get("end_s")))
        extra_kg = float(raw.get("mass_kg", vehicle_mass_kg)) - vehicle_mass_kg
        if abs(extra_kg) > 0.01:
            effects.append(TruthEffect("payload", {"mass_kg": extra_kg}, None, None))
        return cls(raw["scenario"], effects, takeoff_s, landed_s)


@dataclass
class Match:
    """A named effect (as in the ``effects`` list of ``residuals --json``) against the truth."""

    label: str
    params: dict[str, Any]
    matched: TruthEffect | None
    misses: list[str] = field(default_factory=list)


@dataclass
class FlightScore:
    truth: FlightTruth
    matches: list[Match]
    rmse_before_w: float
    rmse_after_w: float
    noise_floor_w: float

    @property
    def first_right(self) -> bool:
        """Clean flights: nothing named. Otherwise: the first named effect matches one true."""
        if not self.truth.effects:
            return not self.matches
        return bool(self.matches) and self.matches[0].matched is not None

    @property
    def rmse_to_floor(self) -> float:
        return self.rmse_after_w / self.noise_floor_w if self.noise_floor_w > 0 else math.inf


def angle_deg(a: float, b: float) -> float:
    """The angle between two directions, ° (0–180)."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def span_s(truth: FlightTruth, start_s: float | None, end_s: float | None) -> tuple[float, float]:
    """An effect's start and end within the truth's span (None: take-off / landing), s."""
    start = truth.takeoff_s if start_s is None else max(start_s, truth.takeoff_s)
    end = truth.landed_s if end_s is None else min(end_s, truth.landed_s)
    return start, end


def _time_misses(
    truth: FlightTruth, effect: TruthEffect, at_s: float | None, until_s: float | None, tol: float
) -> list[str]:
    """Start and end of a named effect against the true ones (None: start / end of flight)."""
    misses = []
    true_start, true_end = span_s(truth, effect.start_s, effect.end_s)
    start, end = span_s(truth, at_s, until_s)
    if abs(start - true_start) > tol:
        misses.append(f"starts at {start:.0f} s, truth {true_start:.0f} s")
    if abs(end - true_end) > tol:
        misses.append(f"ends at {end:.0f} s, truth {true_end:.0f} s")
    return misses


def _value_misses(kind: str, effect: TruthEffect, p: dict[str, Any], tol: Tolerance) -> list[str]:
    v = effect.values
    if kind == "wind":
        out = []
        if abs(p["speed_mps"] - v["speed_mps"]) > tol.wind_mps:
            out.append(f"wind {p['speed_mps']:.1f} m/s, truth {v['speed_mps']:g}")
        if angle_deg(p["from_deg"], v["from_deg"]) > tol.wind_deg:
            out.append(f"from {p['from_deg']:.0f}°, truth {v['from_deg']:g}°")
        return out
    if kind == "payload":
        ok = abs(p["delta_kg"] - v["mass_kg"]) <= tol.mass_kg
        return [] if ok else [f"mass {p['delta_kg']:+.2f} kg, truth {v['mass_kg']:+g}"]
    ok = abs(p["power_w"] - v["power_w"]) <= tol.load_w
    return [] if ok else [f"load {p['power_w']:.0f} W, truth {v['power_w']:g}"]


def match_effect(truth: FlightTruth, named: dict[str, Any], tol: Tolerance = Tolerance()) -> Match:
    """The true effect that ``named`` (an entry of ``residuals --json`` ``effects``) matches,
    or the misses against the closest true effect of its kind."""
    kind = KINDS.get(named["name"], named["name"])
    params = named["params"]
    label = named.get("label", named["name"])
    tried = [
        (
            _value_misses(kind, effect, params, tol)
            + _time_misses(truth, effect, params.get("at_s"), params.get("until_s"), tol.time_s),
            effect,
        )
        for effect in truth.effects
        if effect.kind == kind
    ]
    if not tried:
        return Match(label, params, None, [f"no true {kind}"])
    misses, effect = min(tried, key=lambda t: len(t[0]))
    return Match(label, params, None if misses else effect, misses)


def score_summary(
    truth: FlightTruth, summary: dict[str, Any], tol: Tolerance = Tolerance()
) -> FlightScore:
    """Score the JSON object of ``uav-energy residuals --json`` for one flight."""
    return FlightScore(
        truth,
        [match_effect(truth, e, tol) for e in summary["effects"]],
        float(summary["rmse_before_w"]),
        float(summary["rmse_after_w"]),
        float(summary["noise_floor_w"]),
    )


@dataclass
class RecordingCheck:
    """``uav-energy residuals`` on one recording (``result``; ``summary``: its ``--json``
    object) and the score of what it named against the recording's truth."""

    result: ResidualResult
    score: FlightScore

    @cached_property
    def summary(self) -> dict[str, Any]:
        return self.result.summary()


def score_recording(folder: Path, vehicle: Vehicle) -> RecordingCheck:
    """Analyse ``folder/flight.tlog`` against ``vehicle`` and score it against
    ``folder/truth.json`` within the span of the samples the analysis kept."""
    truth = FlightTruth.load(folder / "truth.json", vehicle.mass_kg)
    result = analyze(load_flights([folder / "flight.tlog"]), vehicle)
    time_s = result.samples.state.time_s
    span = truth.within(float(time_s.min()), float(time_s.max()))
    return RecordingCheck(result, score_summary(span, result.summary()))
