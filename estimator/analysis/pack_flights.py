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
from estimator.estimation.pipeline import PipelineSettings
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
