"""Flights with a known pack (``truth.json`` beside the log, as ``uav-energy sitl-record``
writes it) replayed with the LABELLED capacity: endurance against the true time to the
pack's reserve, with the autopilots' own figures beside (:mod:`peer_endurance`).

The endurance is scored as ``uav-energy replay`` scores it against a truth
(:func:`estimator.analysis.endurance_truth.score_endurance`): from 60 s after take-off until
60 s before the true reserve (where the time left gets short), once a second (s, autopilot
clock).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from estimator.analysis.endurance_truth import score_endurance
from estimator.analysis.peer_endurance import peer_endurance_s
from estimator.analysis.replay import replay_stream, with_batteries
from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.logs import iter_samples
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import BatterySample


@dataclass(frozen=True)
class PackFlight:
    """One flight's scores: relative endurance errors (ours, PX4-style, ArduPilot's) and
    ours in σ (signed: + is more time than there is), at the scored estimates; the pack's
    truth; the estimates and the battery readings."""

    name: str
    truth: dict[str, Any]
    errors: np.ndarray
    z: np.ndarray
    px4_errors: np.ndarray
    ardupilot_errors: np.ndarray
    estimates: list[Estimate]
    readings: list[BatterySample]


def replay_pack_flight(
    directory: Path, vehicle: Vehicle, settings: PipelineSettings | None = None
) -> PackFlight:
    """Replay ``directory``'s ``flight.tlog`` with ``vehicle`` under the pack's label."""
    truth = json.loads((directory / "truth.json").read_text())
    battery = truth["battery"]
    label = replace(vehicle.battery, capacity_ah=battery["labelled_capacity_ah"])
    labelled = replace(vehicle, battery=label)
    stream = iter_samples(directory / "flight.tlog", "auto", labelled.input_limits())
    readings: list[BatterySample] = []
    samples = with_batteries(stream, readings)
    flight = replay_stream(stream, labelled, directory.name, settings, samples)
    events = truth["events"]
    scores = score_endurance(flight.estimates, events["takeoff_s"], events["reserve_s"])
    left = scores.left_s
    peers = peer_endurance_s(readings, label, vehicle.battery.cells * 0.004)
    peer_t = np.array([t for t, _, _ in peers])
    at = np.clip(np.searchsorted(peer_t, scores.time_s, side="right") - 1, 0, None)
    px4 = np.array([peers[i][1] for i in at]) if len(peers) else np.full(len(left), np.nan)
    ardupilot = np.array([peers[i][2] for i in at]) if len(peers) else px4
    return PackFlight(
        name=directory.name,
        truth=truth,
        errors=scores.errors,
        z=scores.z,
        px4_errors=(px4 - left) / left,
        ardupilot_errors=(ardupilot - left) / left,
        estimates=flight.estimates,
        readings=readings,
    )


def half_used_s(readings: list[BatterySample], battery: dict[str, Any]) -> float:
    """When half of the pack's charge at power-up had been drawn (s, autopilot clock), from
    the autopilot's counter and the truth's pack (``truth.json``'s ``battery``)."""
    half_mah = 500.0 * battery["start_soc"] * battery["capacity_ah"]
    return next(
        s.time_s for s in readings if s.consumed_mah is not None and s.consumed_mah >= half_mah
    )


#: A daemon restarted this long after take-off (s) with no state file, and when its endurance
#: is judged after the restart (s).
RESTART_AFTER_TAKEOFF_S = 90.0
RESTART_JUDGED_AFTER_S = 60.0


@dataclass(frozen=True)
class Restart:
    """A flight replayed from :data:`RESTART_AFTER_TAKEOFF_S` on, as a daemon restarted then
    under load with no state file: the endurance's relative error and z (σ, + is more time
    than there is) :data:`RESTART_JUDGED_AFTER_S` after the restart; the largest |z| from
    10 s after the restart until 60 s before the reserve, over ``scored`` estimates."""

    name: str
    error_at: float
    z_at: float
    worst_abs_z: float
    scored: int


def replay_restarted(directory: Path, vehicle: Vehicle) -> Restart | None:
    """``directory``'s flight restarted (:class:`Restart`) under the pack's label; None when
    the reserve comes too soon after the restart to judge."""
    truth = json.loads((directory / "truth.json").read_text())
    label = replace(vehicle.battery, capacity_ah=truth["battery"]["labelled_capacity_ah"])
    labelled = replace(vehicle, battery=label)
    start_s = truth["events"]["takeoff_s"] + RESTART_AFTER_TAKEOFF_S
    reserve_s = truth["events"]["reserve_s"]
    if reserve_s - start_s < RESTART_JUDGED_AFTER_S + 70.0:
        return None
    stream = iter_samples(directory / "flight.tlog", "auto", labelled.input_limits())
    samples = (s for s in stream if getattr(s, "time_s", 0.0) >= start_s)
    estimates = replay_stream(stream, labelled, directory.name, samples=samples).estimates
    first_s = estimates[0].time_s
    at = min(estimates, key=lambda e: abs(e.time_s - first_s - RESTART_JUDGED_AFTER_S))
    left_s = reserve_s - at.time_s
    scored = [e for e in estimates if first_s + 10.0 <= e.time_s <= reserve_s - 60.0]
    z = [(e.endurance_s - (reserve_s - e.time_s)) / e.endurance_sigma_s for e in scored]
    return Restart(
        name=directory.name,
        error_at=(at.endurance_s - left_s) / left_s,
        z_at=(at.endurance_s - left_s) / at.endurance_sigma_s,
        worst_abs_z=max(abs(v) for v in z),
        scored=len(scored),
    )
