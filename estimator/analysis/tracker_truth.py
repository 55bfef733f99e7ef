"""The daemon's online wind and mass tracker against a flight's truth, step by step.

A flight is fed to the pipeline as the daemon would see it (:class:`Pipeline`), and after each
step of its tracker (:mod:`estimator.estimation.online_effects`, one per ``track_period_s`` of
flying readings) the running wind and mass and their 1σ are compared with the truth: the
payload carried and the ambient wind. Scored is the running value over the whole airborne
flight, not a late median: the share of steps within 2σ and 3σ, and the largest |error|/σ.

CMU M100 flights (:mod:`estimator.logs.cmu`) carry their truth: ``payload`` (g) and an
anemometer on the airframe (the airflow's speed and the direction it comes from). Ambient wind
= ground velocity − the vehicle's velocity through the air (the airflow's speed towards where
it comes from), its median over the cruise regime (SOURCE.md: the sensor sits in the rotor
wash, so it is itself approximate).

Units: m/s (NED north/east, the air mass's velocity over ground), kg, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimator.estimation.pipeline import Pipeline
from estimator.logs import FlightSeries
from estimator.logs.cmu import flight_samples
from estimator.physics.vehicle import Vehicle

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
    """One flight's tracker steps: time (s), estimate [w_n, w_e, δm] and its 1σ, one row per
    step (n × 3 each)."""

    name: str
    truth: Truth
    time_s: np.ndarray
    estimate: np.ndarray
    sigma: np.ndarray

    def z(self) -> np.ndarray:
        """|error|/σ per step: wind north, wind east, mass (n × 3)."""
        want = np.array([*self.truth.wind_ne_mps, self.truth.mass_delta_kg])
        return np.abs(self.estimate - want) / self.sigma

    def within(self, sigmas: float) -> tuple[float, float]:
        """Share of steps whose mass, and whose wind (both components), lie within
        ``sigmas`` σ of the truth."""
        z = self.z()
        return float(np.mean(z[:, 2] <= sigmas)), float(np.mean(z[:, :2].max(axis=1) <= sigmas))


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
    pipeline = Pipeline(vehicle)
    rows: list[tuple[float, ...]] = []
    steps = 0
    for sample in flight_samples([flight]):
        pipeline.process(sample)
        tracker = pipeline.online
        if tracker is None or tracker.steps == steps:
            continue
        steps = tracker.steps
        sigma = tracker.sigma
        rows.append(
            (
                sample.time_s,
                *tracker.wind.vector_ne_mps(),
                tracker.mass_delta_kg,
                sigma["wind_n_mps"],
                sigma["wind_e_mps"],
                sigma["mass_kg"],
            )
        )
    table = np.array(rows, dtype=float).reshape(-1, 7)
    return TrackerRun(flight.flight_id, truth, table[:, 0], table[:, 1:4], table[:, 4:7])
