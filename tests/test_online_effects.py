"""Online wind and mass tracking on simulated flights replayed the daemon's way (tlog →
samples → causal kinematics → tracker): hidden wind and mass are recovered during flight, a
payload step is followed, clean flights stay at zero, and the vehicle file's values are the
start."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from estimator.estimation.online_effects import (
    OnlineEffects,
    TrackPoint,
    track_samples,
    wind_from_vector,
)
from estimator.logs import iter_samples
from estimator.physics.effects import Climb, Effect, Mass, Wind, effects_to_tables
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

VEHICLE = default_vehicle()


def track(tmp_path: Path, plan: str, seed: int, effects: tuple[Effect, ...]) -> list[TrackPoint]:
    duration = 600.0 if plan == "mixed" else None
    run = simulate(SimConfig(plan=plan, duration_s=duration, seed=seed, effects=effects))
    path = write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)
    return track_samples(iter_samples(path), OnlineEffects.from_vehicle(VEHICLE))


def at(points: list[TrackPoint], time_s: float) -> TrackPoint:
    times = np.array([p.time_s for p in points])
    return points[min(int(np.searchsorted(times, time_s)), len(points) - 1)]


def angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize(
    ("plan", "seed", "wind"), [("mixed", 41, Wind(5.0, 60.0)), ("circles", 42, Wind(4.0, 250.0))]
)
def test_wind_is_tracked_online(tmp_path: Path, plan: str, seed: int, wind: Wind) -> None:
    points = track(tmp_path, plan, seed, (wind,))
    for p in (at(points, 200.0), points[-1]):
        assert abs(p.wind_speed_mps - wind.speed_mps) < 1.0
        assert angle_diff_deg(p.wind_from_deg, wind.from_deg) < 20.0
        assert abs(p.mass_delta_kg) < 0.1


def test_mass_and_wind_together_are_tracked(tmp_path: Path) -> None:
    points = track(tmp_path, "mixed", 43, (Wind(6.0, 300.0), Mass(-0.4)))
    final = points[-1]
    assert abs(final.mass_delta_kg + 0.4) < 0.1
    assert final.mass_sigma_kg < 0.1
    assert abs(final.wind_speed_mps - 6.0) < 1.0
    assert angle_diff_deg(final.wind_from_deg, 300.0) < 20.0


def test_payload_picked_up_in_flight_is_followed(tmp_path: Path) -> None:
    points = track(tmp_path, "mixed", 44, (Mass(0.6, at_s=250.0),))
    assert abs(at(points, 240.0).mass_delta_kg) < 0.1
    assert abs(at(points, 330.0).mass_delta_kg - 0.6) < 0.1
    assert abs(points[-1].mass_delta_kg - 0.6) < 0.1


def test_clean_flight_stays_at_no_wind_and_file_mass(tmp_path: Path) -> None:
    points = track(tmp_path, "mixed", 45, ())
    late = [p for p in points if p.time_s > 120.0]
    assert max(p.wind_speed_mps for p in late) < 1.0
    assert max(abs(p.mass_delta_kg) for p in late) < 0.05


def test_starts_from_the_vehicle_file_and_keeps_other_effects() -> None:
    tables = effects_to_tables([Wind(4.0, 90.0), Mass(0.3), Climb(0.5)])
    vehicle = Vehicle(VEHICLE.name, VEHICLE.mass_kg, VEHICLE.model, VEHICLE.battery, {}, tables)
    tracker = OnlineEffects.from_vehicle(vehicle)
    assert tracker.wind.speed_mps == pytest.approx(4.0)
    assert tracker.wind.from_deg == pytest.approx(90.0)
    assert tracker.mass_delta_kg == pytest.approx(0.3)
    assert tracker.mass_ratio == pytest.approx(3.3 / 3.0)
    names = [e.name for e in tracker.effects]
    assert names == ["wind", "mass", "climb"]


def test_bad_samples_leave_the_estimate_alone() -> None:
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    before = tracker.effects
    assert tracker.update(1.0, math.nan, 0.0, 0.0, 0.0, 0.0, 400.0) == before
    tracker.update(2.0, 5.0, 0.0, 0.0, 0.0, 0.0, 400.0)
    after_good = tracker.effects
    assert tracker.update(1.5, 5.0, 0.0, 0.0, 0.0, 0.0, 400.0) == after_good  # time backwards
    assert tracker.rejected == 2


def test_wind_vector_round_trip() -> None:
    for wind in (Wind(5.0, 60.0), Wind(3.0, 250.0), Wind(0.0, 0.0)):
        wn, we = wind.vector_ne_mps()
        back = wind_from_vector(wn, we)
        assert back.speed_mps == pytest.approx(wind.speed_mps)
        if wind.speed_mps:
            assert angle_diff_deg(back.from_deg, wind.from_deg) < 1e-9


def test_a_covariance_that_lost_positive_definiteness_is_restarted_not_raised() -> None:
    """Damaged logs can drive the UKF covariance indefinite; the tracker restarts it and
    carries on (the daemon never dies on bad input)."""
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    tracker.update(0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 380.0)
    tracker._ukf.P = np.diag([1.0, -1.0, 1.0])  # what a run of garbage readings can leave
    tracker.update(0.5, 5.0, 0.0, 0.0, 0.0, 0.0, 380.0)
    assert tracker.resets == 1
    assert math.isfinite(tracker.wind.speed_mps) and math.isfinite(tracker.mass_delta_kg)
    assert np.all(np.linalg.eigvalsh(tracker._ukf.P) > 0)
