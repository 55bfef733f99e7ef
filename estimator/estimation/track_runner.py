"""The online wind and mass tracker (:mod:`estimator.estimation.online_effects`) run alone over
a log's samples: the causal kinematics filter on velocity, the autopilot's wind reports, and an
update per airborne power reading (:class:`~estimator.estimation.airborne.AirborneGate`). The
tests use it to see the filter's own behaviour. The daemon's pipeline steps the tracker once
per ``track_period_s`` on the readings since the last; ``uav-energy residuals --online`` and
the figures of the daemon's tracker run that pipeline
(:func:`estimator.analysis.tracker_truth.track_samples`).

Units: s (the log's clock), m/s, deg (direction the wind comes from), kg, W, V.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from estimator.estimation.airborne import AirborneGate, Phase
from estimator.estimation.online_effects import OnlineEffects
from estimator.physics.kinematics import KinematicsFilter, KinematicState
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
)


@dataclass(frozen=True)
class TrackPoint:
    """The tracker's estimate after one update: time (s), wind (m/s, deg from), mass (kg)."""

    time_s: float
    wind_speed_mps: float
    wind_from_deg: float
    mass_delta_kg: float
    mass_sigma_kg: float


class _Runner:
    """Feeds a tracker the daemon's way: causal kinematics on velocity, an update per
    flying power reading (:class:`~estimator.estimation.airborne.AirborneGate`: not on the ground
    nor
    in the take-off transient) with the latest state (not older than ``max_age_s``)."""

    def __init__(self, tracker: OnlineEffects, max_age_s: float = 1.0) -> None:
        self.tracker = tracker
        self.max_age_s = max_age_s
        self.kinematics = KinematicsFilter()
        self.state: KinematicState | None = None
        self.armed: bool | None = None
        self.gate = AirborneGate(tracker.model.hover_power_w)
        self.points: list[TrackPoint] = []

    def velocity(self, sample: VelocitySample) -> None:
        self.state = self.kinematics.update(sample)

    def reboot(self) -> None:
        self.kinematics.reset()
        self.state, self.armed = None, None
        self.gate.reset()

    def power(self, time_s: float, power_w: float, voltage_v: float) -> None:
        state = self.state
        if state is None or time_s - state.time_s > self.max_age_s:
            return
        phase = self.gate.phase(time_s, self.armed, state.alt_m, power_w, state.vd_mps)
        if phase is not Phase.FLYING:
            return
        tracker = self.tracker
        tracker.update_kinematics(state, power_w, voltage_v)
        wind = tracker.wind
        self.points.append(
            TrackPoint(
                time_s,
                wind.speed_mps,
                wind.from_deg,
                tracker.mass_delta_kg,
                tracker.sigma["mass_kg"],
            )
        )


def track_samples(samples: Iterable[Sample], tracker: OnlineEffects) -> list[TrackPoint]:
    """Run ``tracker`` over a log's samples the way the daemon would: the causal kinematics
    filter on velocity, the autopilot's wind reports, an update at each airborne battery sample
    with a current reading."""
    runner = _Runner(tracker)
    for sample in samples:
        if isinstance(sample, VelocitySample):
            runner.velocity(sample)
        elif isinstance(sample, ArmedSample):
            runner.armed = sample.armed
        elif isinstance(sample, RebootSample):
            runner.reboot()
        elif isinstance(sample, WindSample):
            tracker.take_autopilot_wind(sample)
        elif isinstance(sample, BatterySample) and sample.power_w is not None:
            runner.power(sample.time_s, sample.power_w, sample.voltage_v)
    return runner.points
