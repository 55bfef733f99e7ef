"""Predicted against measured energy of recorded AUTO missions (``replay/sitl/missions/``).

A recording directory holds ``flight.tlog``, ``truth.json`` and the flown ``mission.plan`` or
``mission.waypoints`` (``uav-energy sitl-record --mission``). Measured energy: V·I of the
battery telemetry (SYS_STATUS voltage × BATTERY_STATUS current, as the log readers pair
them), integrated by trapezoids from the mission start (MAV_CMD_MISSION_START accepted) to
the disarm after landing. Predicted: :func:`~estimator.analysis.mission_energy.mission_energy`
on the mission file with the wind and payload of the truth, and the PX4-style estimate beside.
Per leg (:func:`leg_checks`): each planned leg against the stretch of the flight from the
first report of its mission item (MISSION_CURRENT, :func:`mission_item_starts`) to the next
planned item's (the disarm for the last).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from estimator.analysis.mission_energy import FlightSettings, MissionEnergy, mission_energy
from estimator.errors import UserError
from estimator.logs import iter_samples, load_flights
from estimator.logs.mission_files import load_mission
from estimator.physics.route_energy import Conditions
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import MissionCurrentSample, VelocitySample


@dataclass(frozen=True)
class MissionCheck:
    """One recorded mission: predicted (± 1σ) and PX4-style energy (Wh) and time (s) against
    the measured."""

    name: str
    predicted_wh: float
    predicted_sigma_wh: float
    px4_wh: float
    measured_wh: float
    predicted_time_s: float
    px4_time_s: float
    measured_time_s: float

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.predicted_wh - self.measured_wh) / self.measured_wh

    @property
    def px4_error_pct(self) -> float:
        return 100.0 * (self.px4_wh - self.measured_wh) / self.measured_wh


@dataclass(frozen=True)
class LegCheck:
    """One planned leg (its mission item ``seq`` and ``kind``) against the flight: time (s)
    and energy (Wh) planned and flown."""

    seq: int
    kind: str
    planned_time_s: float
    planned_wh: float
    flown_time_s: float
    flown_wh: float

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.planned_wh - self.flown_wh) / self.flown_wh


def measured_energy(tlog: Path, start_s: float, end_s: float) -> tuple[float, float]:
    """Battery energy (Wh) and duration (s) between ``start_s`` and ``end_s`` of the
    autopilot's clock in ``tlog``."""
    return _energy_between(tlog, *_battery_power(tlog), start_s, end_s)


def _battery_power(tlog: Path) -> tuple[np.ndarray, np.ndarray]:
    """Autopilot time (s) and battery power (W, finite readings) of ``tlog``'s longest flight."""
    flights = load_flights([tlog])
    if not flights:
        raise UserError(f"{tlog}: no battery telemetry")
    f = max(flights, key=len)
    finite = np.isfinite(f.power_w)
    return f.time_s[finite], f.power_w[finite]


def _energy_between(
    tlog: Path, time_s: np.ndarray, power_w: np.ndarray, start_s: float, end_s: float
) -> tuple[float, float]:
    """Energy (Wh) and duration (s) of the readings between ``start_s`` and ``end_s``."""
    inside = (time_s >= start_s) & (time_s <= end_s)
    t, p = time_s[inside], power_w[inside]
    if len(t) < 2:
        raise UserError(f"{tlog}: no battery readings between {start_s:g} and {end_s:g} s")
    return float(np.trapezoid(p, t) / 3600.0), float(t[-1] - t[0])


def item_ground_speeds_mps(tlog: Path, seq: int) -> np.ndarray:
    """Horizontal ground speeds (m/s) of ``tlog``'s velocity readings while the autopilot
    flew to mission item ``seq`` (MISSION_CURRENT)."""
    flying, speeds = False, []
    for sample in iter_samples(tlog):
        if isinstance(sample, MissionCurrentSample):
            flying = sample.seq == seq
        elif flying and isinstance(sample, VelocitySample):
            speeds.append(math.hypot(sample.vn_mps, sample.ve_mps))
    return np.asarray(speeds, dtype=float)


def mission_item_starts(tlog: Path) -> list[tuple[int, float]]:
    """(mission item, autopilot time in s) of each item's first MISSION_CURRENT in ``tlog``,
    in the order reported; UserError when the log reports no mission progress."""
    starts: list[tuple[int, float]] = []
    for sample in iter_samples(tlog):
        if isinstance(sample, MissionCurrentSample) and all(s != sample.seq for s, _ in starts):
            starts.append((sample.seq, sample.time_s))
    if not starts:
        raise UserError(f"{tlog}: no MISSION_CURRENT from the autopilot (not an AUTO mission?)")
    return starts


def truth_conditions(truth: dict, wind_sigma_mps: float = 0.0) -> Conditions:
    """Wind and payload a recording's truth switched on (the first of each)."""
    wind = next((e for e in truth.get("effects", []) if e["effect"] == "wind"), None)
    payload = next((e for e in truth.get("effects", []) if e["effect"] == "payload"), None)
    return Conditions(
        wind_speed_mps=float(wind["speed_mps"]) if wind else 0.0,
        wind_from_deg=float(wind["from_deg"]) if wind else 0.0,
        payload_kg=float(payload["mass_kg"]) if payload else 0.0,
        wind_sigma_mps=wind_sigma_mps,
    )


def predict_recording(
    directory: Path,
    vehicle: Vehicle,
    settings: FlightSettings | None = None,
    conditions: Conditions | None = None,
) -> MissionEnergy:
    """The plan of a recording's mission file in its truth's wind and payload (or in
    ``conditions``: what the planner is told instead)."""
    files = sorted(directory.glob("mission.*"))
    if not files:
        raise UserError(f"{directory}: no mission.plan or mission.waypoints")
    if conditions is None:
        conditions = truth_conditions(json.loads((directory / "truth.json").read_text()))
    legs = load_mission(files[0]).legs()
    return mission_energy(legs, vehicle, conditions, settings or FlightSettings())


def check_recording(
    directory: Path,
    vehicle: Vehicle,
    settings: FlightSettings | None = None,
    conditions: Conditions | None = None,
) -> MissionCheck:
    """Predicted against measured for one recording directory (planned in its truth's
    conditions, or in ``conditions``)."""
    truth = json.loads((directory / "truth.json").read_text())
    events = truth["events"]
    start, end = events.get("mission_start_s", math.nan), events.get("disarmed_s", math.nan)
    measured_wh, measured_s = measured_energy(directory / "flight.tlog", start, end)
    plan = predict_recording(directory, vehicle, settings, conditions)
    return MissionCheck(
        name=directory.name,
        predicted_wh=plan.total.energy_wh,
        predicted_sigma_wh=plan.total.energy_sigma_wh,
        px4_wh=plan.px4.energy_wh,
        measured_wh=measured_wh,
        predicted_time_s=plan.total.time_s,
        px4_time_s=plan.px4.time_s,
        measured_time_s=measured_s,
    )


def leg_checks(directory: Path, vehicle: Vehicle) -> list[LegCheck]:
    """Each planned leg of a recording (planned in its truth's wind and payload) against the
    flight between its item's first report and the next planned item's; the first leg starts
    at the mission's start, the last ends at the disarm. Legs of one item (a return the plan
    added) are one row."""
    events = json.loads((directory / "truth.json").read_text())["events"]
    tlog = directory / "flight.tlog"
    plan = predict_recording(directory, vehicle)
    reached = mission_item_starts(tlog)
    rows: list[tuple[int, str, float, float]] = []
    for result in plan.legs:
        seq, energy = result.leg.seq, result.energy
        if rows and rows[-1][0] == seq:
            _, kind, time_s, wh = rows[-1]
            rows[-1] = (seq, kind, time_s + energy.time_s, wh + energy.energy_wh)
        else:
            rows.append((seq, result.leg.kind, energy.time_s, energy.energy_wh))
    starts = [next((t for s, t in reached if s >= seq), math.nan) for seq, *_ in rows]
    starts[0] = events["mission_start_s"]
    ends = [*starts[1:], events["disarmed_s"]]
    power = _battery_power(tlog)
    checks = []
    for (seq, kind, time_s, wh), start_s, end_s in zip(rows, starts, ends, strict=True):
        flown_wh, flown_s = _energy_between(tlog, *power, start_s, end_s)
        checks.append(LegCheck(seq, kind, time_s, wh, flown_s, flown_wh))
    return checks
