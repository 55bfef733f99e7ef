"""The turn the endurance figures assume continues (:mod:`estimator.estimation.held_turn`):
an orbit's centripetal acceleration once held for 5 s, not a waypoint corner's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.estimation.held_turn import TURN_HOLD_S, HeldTurn
from estimator.estimation.pipeline import Pipeline
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import default_vehicle
from estimator.telemetry.samples import ArmedSample, BatterySample, Sample, VelocitySample


def test_an_orbit_counts_once_held_and_a_corner_never() -> None:
    held = HeldTurn()
    t = np.arange(0.0, 20.0, 0.1)
    orbit = [held.update(float(s), 2.0) for s in t]
    assert max(orbit[: int(TURN_HOLD_S * 10) - 1]) == 0.0
    assert orbit[-1] == 2.0
    held.reset()
    corner = [held.update(float(s), 2.5 if 10.0 <= s < 12.0 else 0.0) for s in t]
    assert max(corner) == 0.0


def test_the_held_turn_is_the_smallest_over_the_window() -> None:
    held = HeldTurn(hold_s=1.0)
    values = [3.0, 1.0, 2.0, 4.0, 5.0, 6.0, 0.5, 7.0]
    out = [held.update(0.5 * k, a) for k, a in enumerate(values)]
    # from 1 s on: the smallest of the states at most 1 s old (three of them)
    assert out[2:] == [min(values[k - 2 : k + 1]) for k in range(2, len(values))]


VEHICLE = default_vehicle()
FULL_V = float(PackModel(VEHICLE.battery).ocv_v(1.0))


def _circle(turn_s: tuple[float, float], seconds: float = 60.0) -> list[Sample]:
    """Level flight at 8 m/s, turning at 3 m/s² during ``turn_s`` (s), straight otherwise:
    10 Hz velocity, 2 Hz battery drawing the model's straight-flight power."""
    samples: list[Sample] = [BatterySample(0.0, FULL_V, 0.0, 0.0), ArmedSample(0.0, True)]
    speed, accel, heading = 8.0, 3.0, 0.0
    power_w = float(VEHICLE.model.power_w(speed))
    for k in range(1, int(seconds * 10)):
        t = 0.1 * k
        if turn_s[0] <= t < turn_s[1]:
            heading += accel / speed * 0.1
        samples.append(
            VelocitySample(t, speed * math.cos(heading), speed * math.sin(heading), 0.0, 20.0)
        )
        if k % 5 == 0:
            v = FULL_V - 0.6
            samples.append(BatterySample(t, v, power_w / v, power_w / v * t / 3.6))
    return samples


@pytest.mark.parametrize(("turn_s", "follows"), [((30.0, 32.0), False), ((30.0, 60.0), True)])
def test_the_steady_power_follows_an_orbit_not_a_corner(
    turn_s: tuple[float, float], follows: bool
) -> None:
    pipeline = Pipeline(VEHICLE)
    estimates = [e for s in _circle(turn_s) if (e := pipeline.process(s)) is not None]
    straight = np.median([e.steady_power_w for e in estimates if 20.0 <= e.time_s < 29.0])
    turning = max(e.steady_power_w for e in estimates if e.time_s >= 30.0)
    assert bool(turning > 1.01 * straight) is follows
