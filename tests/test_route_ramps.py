"""The leg's ramped cruise speed written out (``route_segments._ramped_cruise_mps``) equals
the bisection over :meth:`Kinematics.ramp_s` it replaced, to the bit."""

from __future__ import annotations

import random

import pytest

from estimator.physics.route_segments import Kinematics, _profile, _ramped_cruise_mps


def _reference_cruise_mps(
    distance_m: float, cruise_mps: float, ends: tuple[float, float], kin: Kinematics
) -> float:
    """The bisection as written before (speed23): each step through ``ramp_s``."""

    def ramps(v: float) -> tuple[float, float, float, float]:
        t1, t3 = kin.ramp_s(v - ends[0]), kin.ramp_s(v - ends[1])
        return t1, t3, 0.5 * (v + ends[0]) * t1, 0.5 * (v + ends[1]) * t3

    lo, hi = 0.0, cruise_mps
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if sum(ramps(mid)[2:]) <= distance_m else (lo, mid)
    return lo


KINEMATICS = [
    Kinematics(accel_mps2=1.0),
    Kinematics(accel_mps2=2.5, jerk_mps3=5.0),
    Kinematics(accel_mps2=3.0, jerk_mps3=1.0),
    Kinematics(accel_mps2=1.0, jerk_mps3=0.0),
]


@pytest.mark.parametrize("kin", KINEMATICS)
def test_ramped_cruise_equals_the_bisection_over_ramp_s(kin: Kinematics) -> None:
    rng = random.Random(24)
    for _ in range(3000):
        cruise = rng.uniform(0.5, 20.0)
        ends = (rng.choice([0.0, rng.uniform(0.0, cruise)]), rng.choice([0.0, rng.uniform(0, 8)]))
        distance = rng.choice(
            [rng.uniform(0.0, 5.0), rng.uniform(0.0, 120.0), 10 ** rng.uniform(-6, 1)]
        )
        assert _ramped_cruise_mps(distance, cruise, ends, kin) == _reference_cruise_mps(
            distance, cruise, ends, kin
        ), (distance, cruise, ends, kin)


def test_short_leg_profile_flies_its_distance() -> None:
    kin = Kinematics(accel_mps2=2.5, jerk_mps3=5.0)
    pieces = _profile(3.0, 10.0, (0.0, 0.0), kin)
    assert sum(v * d for v, _, d in pieces) == pytest.approx(3.0, rel=1e-12)
    assert max(v for v, _, _ in pieces) < 10.0
