"""The daemon's online wind and mass tracker against a flight's truth, step by step.

A flight is fed to the pipeline as the daemon would see it (:class:`Pipeline`), and after each
step of its tracker (:mod:`estimator.estimation.online_effects`, one per ``track_period_s`` of
flying readings) the running wind and mass and their 1σ are compared with the truth: the
payload carried and the ambient wind. Scored is the running value over the whole airborne
flight, not a late median: the share of steps within 2σ and 3σ, and the largest |error|/σ;
also the share of steps after which the pipeline predicted with the vehicle file's effects,
the tracked ones not (or not yet) applied.

CMU M100 flights (:mod:`estimator.logs.cmu`) carry their truth: ``payload`` (g) and an
anemometer on the airframe (the airflow's speed and the direction it comes from). Ambient wind
= ground velocity − the vehicle's velocity through the air (the airflow's speed towards where
it comes from), its median over the cruise regime (SOURCE.md: the sensor sits in the rotor
wash, so it is itself approximate). ArduCopter SITL recordings carry theirs in
``truth.json`` (:mod:`estimator.analysis.sitl_truth`), a wind and a payload that may change
in flight: each step is compared with the truth at its time.

Units: m/s (NED north/east, the air mass's velocity over ground), kg, s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.pipeline import Pipeline
from estimator.logs import FlightSeries
from estimator.logs.cmu import flight_samples
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import Sample

#: The truth of a flight without one (its steps are all kept: :func:`track_samples`).
_UNKNOWN = (math.nan, math.nan, math.nan)
#: The CMU log's regime code of cruise (take-off 0, cruise 1, landing 2).
CRUISE_REGIME = 1


@dataclass(frozen=True)
class Truth:
    """What the tracker should find: payload (kg, the mass above the vehicle file's) and the
    ambient wind (m/s, north/east velocity of the air over ground)."""

    mass_delta_kg: float
    wind_ne_mps: tuple[float, float]


@dataclass(frozen=True)
class TrackerRun:
    """One flight's tracker steps, one row per step: time (s), estimate [w_n, w_e, δm], its
    1σ and the truth then (n × 3 each), whether the pipeline predicted with the tracked
    effects after the step (``applied``, n), and what could have told the truth from the
    estimate there (``told``, n × 2, see :func:`track_samples`)."""

    name: str
    time_s: np.ndarray
    estimate: np.ndarray
    sigma: np.ndarray
    truth: np.ndarray
    applied: np.ndarray
    #: Steps left out: the truth changed between the previous step and this one, while the
    #: readings it took were queued (a payload released, a wind switched).
    across_changes: int = 0
    #: Per step: the model's mean power over the step's readings at the truth less at the
    #: estimate, in units of the step's noise 1σ; and the autopilot's latest wind report's
    #: distance from the true wind (m/s; NaN without one).
    told: np.ndarray | None = None

    def z(self) -> np.ndarray:
        """|error|/σ per step: wind north, wind east, mass (n × 3)."""
        return np.abs(self.estimate - self.truth) / self.sigma

    def within(self, sigmas: float) -> tuple[float, float]:
        """Share of steps whose mass, and whose wind (both components), lie within
        ``sigmas`` σ of the truth."""
        z = self.z()
        return float(np.mean(z[:, 2] <= sigmas)), float(np.mean(z[:, :2].max(axis=1) <= sigmas))

    def not_applied(self) -> float:
        """Share of steps after which the vehicle file's effects were in use."""
        return float(np.mean(~self.applied))

    def coverage_cells(self) -> str:
        """A table's cells: mass within 2σ / 3σ, its largest |error|/σ, the same of the wind
        (its larger component)."""
        mass_2, wind_2 = self.within(2.0)
        mass_3, wind_3 = self.within(3.0)
        z = self.z()
        return (
            f"{100 * mass_2:.0f} / {100 * mass_3:.0f} % | {z[:, 2].max():.1f} | "
            f"{100 * wind_2:.0f} / {100 * wind_3:.0f} % | {z[:, :2].max():.1f}"
        )


def cmu_truth(flight: FlightSeries) -> Truth:
    """A CMU flight's payload and its ambient wind over the cruise (module docstring)."""
    extras = flight.extras
    from_rad = np.radians(extras["airflow_from_deg"])
    airspeed = extras["airflow_speed_mps"]
    wind_n = flight.vn_mps - airspeed * np.cos(from_rad)
    wind_e = flight.ve_mps - airspeed * np.sin(from_rad)
    cruise = (extras["regime"] == CRUISE_REGIME) & np.isfinite(wind_n) & np.isfinite(wind_e)
    return Truth(
        float(np.nanmedian(extras["payload_kg"])),
        (float(np.median(wind_n[cruise])), float(np.median(wind_e[cruise]))),
    )


def track_flight(flight: FlightSeries, vehicle: Vehicle, truth: Truth) -> TrackerRun:
    """Feed ``flight`` to a fresh pipeline with ``vehicle`` and record its tracker's running
    estimate after each of its steps."""
    want = (*truth.wind_ne_mps, truth.mass_delta_kg)
    return track_samples(flight.flight_id, flight_samples([flight]), vehicle, lambda _: want)


def track_samples(
    name: str,
    samples: Iterable[Sample],
    vehicle: Vehicle,
    truth_at: Callable[[float], Sequence[float]] | None = None,
    span_s: tuple[float, float] = (-math.inf, math.inf),
) -> TrackerRun:
    """Feed ``samples`` to a fresh pipeline with ``vehicle`` and record its tracker's running
    estimate after each of its steps taken within ``span_s`` (s), with the truth
    ``truth_at(time_s)`` then: [w_n, w_e, δm] (m/s, kg). A step across a change of the truth
    (:attr:`TrackerRun.across_changes`) is counted, not scored: its readings saw both. Without
    ``truth_at`` every step is kept and the truth is NaN (the estimates alone)."""
    pipeline = Pipeline(vehicle)
    rows: list[tuple[float, ...]] = []
    steps = across = 0
    before: tuple[float, ...] | None = None
    for sample in samples:
        pipeline.process(sample)
        tracker = pipeline.online
        if tracker is None or tracker.steps == steps:
            continue
        steps = tracker.steps
        if not span_s[0] <= sample.time_s <= span_s[1]:
            continue
        truth = _UNKNOWN if truth_at is None else tuple(truth_at(sample.time_s))
        changed = truth_at is not None and before is not None and truth != before
        before = truth
        if changed:
            across += 1
            continue
        sigma = tracker.sigma
        applied = pipeline.power.effects != pipeline.power.file_effects
        rows.append(
            (
                sample.time_s,
                *tracker.wind.vector_ne_mps(),
                tracker.mass_delta_kg,
                sigma["wind_n_mps"],
                sigma["wind_e_mps"],
                sigma["mass_kg"],
                *truth,
                applied,
                *_told(tracker, truth),
            )
        )
    table = np.array(rows, dtype=float).reshape(-1, 13)
    return TrackerRun(
        name,
        table[:, 0],
        table[:, 1:4],
        table[:, 4:7],
        table[:, 7:10],
        table[:, 10] > 0,
        across,
        table[:, 11:13],
    )


def _told(tracker: OnlineEffects, truth: Sequence[float]) -> tuple[float, float]:
    """What could have told ``truth`` [w_n, w_e, δm] from the tracker's estimate after its
    step: the model's mean power over the step's readings at the truth (the estimate's model
    error kept) less at the estimate, over the step's noise 1σ; and the autopilot's latest
    wind report's distance from the true wind (m/s). NaN where there is no truth or report."""
    step, state = tracker.last_step, tracker.state
    if step is None or not all(math.isfinite(v) for v in truth):
        return math.nan, math.nan
    at_truth = state.copy()
    at_truth[:3] = truth
    estimate_w, truth_w = tracker.powers_w(np.vstack([state, at_truth]), step.rows).mean(axis=1)
    report = tracker.autopilot.report
    off_mps = (
        math.nan
        if report is None
        else math.hypot(report.wind_n_mps - truth[0], report.wind_e_mps - truth[1])
    )
    return float(truth_w - estimate_w) / math.sqrt(step.noise_var_w2), off_mps
