"""Causal kinematics filter: acceleration from noisy, irregular velocity samples."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.physics.kinematics import (
    KinematicsFilter,
    centripetal_accel_mps2,
    tangential_accel_mps2,
)
from estimator.telemetry.samples import VelocitySample


def circle_samples(rate_hz: float, jitter: float, noise_mps: float, seed: int = 0):
    """A 4 m/s circle of radius 20 m (a⊥ = 0.8 m/s²) sampled at an irregular rate."""
    rng = np.random.default_rng(seed)
    speed, radius = 4.0, 20.0
    omega = speed / radius
    t = 0.0
    out = []
    while t < 60.0:
        vn = -speed * math.sin(omega * t) + rng.normal(0, noise_mps)
        ve = speed * math.cos(omega * t) + rng.normal(0, noise_mps)
        out.append(VelocitySample(t, vn, ve, rng.normal(0, noise_mps)))
        t += (1.0 / rate_hz) * (1.0 + rng.uniform(-jitter, jitter))
    return out


def test_existing_pure_functions_keep_their_low_speed_treatment() -> None:
    assert float(centripetal_accel_mps2(0.0, 0.0, 1.0, 1.0)) == 0.0
    assert float(centripetal_accel_mps2(10.0, 0.0, 0.0, 2.0)) == pytest.approx(2.0, rel=0.01)
    assert float(tangential_accel_mps2(10.0, 0.0, 1.5, 0.0)) == pytest.approx(1.5, rel=0.01)


@pytest.mark.parametrize("rate_hz", [2.0, 5.0, 10.0, 50.0])
def test_centripetal_acceleration_on_a_circle_at_any_rate(rate_hz: float) -> None:
    kf = KinematicsFilter()
    states = [kf.update(s) for s in circle_samples(rate_hz, jitter=0.3, noise_mps=0.05)]
    settled = [s for s in states if s.time_s > 20.0]
    a_perp = np.mean([s.accel_centripetal_mps2 for s in settled])
    a_tan = np.mean([s.accel_tangential_mps2 for s in settled])
    assert a_perp == pytest.approx(0.8 * 4 / math.sqrt(16 + 0.25), abs=0.08)
    assert abs(a_tan) < 0.08
    assert np.mean([s.speed_mps for s in settled]) == pytest.approx(4.0, abs=0.05)


def test_filter_is_smoother_than_a_finite_difference() -> None:
    samples = circle_samples(10.0, jitter=0.0, noise_mps=0.1, seed=2)
    kf = KinematicsFilter()
    filtered = np.array([kf.update(s).an_mps2 for s in samples])[100:]
    vn = np.array([s.vn_mps for s in samples])
    t = np.array([s.time_s for s in samples])
    raw = (np.diff(vn) / np.diff(t))[99:]
    true = np.array([-0.8 * math.cos(0.2 * x) for x in t[100:]])
    assert np.std(filtered - true) < 0.3 * np.std(raw - true)


def test_filter_is_causal_future_samples_do_not_change_past_output() -> None:
    samples = circle_samples(10.0, jitter=0.2, noise_mps=0.05)
    a = KinematicsFilter()
    first = [a.update(s) for s in samples[:200]]
    b = KinematicsFilter()
    again = [b.update(s) for s in samples][:200]
    assert first == again


def test_gap_and_time_going_backwards_restart_the_filter() -> None:
    kf = KinematicsFilter()
    kf.update(VelocitySample(0.0, 0.0, 0.0, 0.0))
    kf.update(VelocitySample(0.1, 1.0, 0.0, 0.0))
    after_gap = kf.update(VelocitySample(10.0, 5.0, 0.0, 0.0))
    assert kf.restarts == 1
    assert after_gap.an_mps2 == 0.0 and after_gap.vn_mps == 5.0
    kf.update(VelocitySample(5.0, 2.0, 0.0, -1.0))
    assert kf.restarts == 2
    kf.reset()
    state = kf.update(VelocitySample(0.0, 3.0, 4.0, -2.0))
    assert state.speed_mps == pytest.approx(5.0) and state.climb_mps == pytest.approx(2.0)


def test_acceleration_step_is_followed_within_a_second() -> None:
    kf = KinematicsFilter()
    state = None
    for k in range(100):  # 10 Hz: still for 5 s, then accelerate at 2 m/s²
        t = k * 0.1
        v = 0.0 if t < 5.0 else 2.0 * (t - 5.0)
        state = kf.update(VelocitySample(t, v, 0.0, 0.0))
        if t >= 6.0:
            assert state.an_mps2 == pytest.approx(2.0, abs=0.3)
    assert state is not None


def test_vertical_acceleration_is_followed_like_the_horizontal() -> None:
    """A climb that starts at 2 m/s² (vd falling): the state's ad_mps2 (down positive) follows
    it within a second, and is 0 while the climb rate holds."""
    kf = KinematicsFilter()
    for k in range(150):  # 10 Hz: hover 5 s, climb rate building for 1.5 s, then 3 m/s up
        t = k * 0.1
        climb = 0.0 if t < 5.0 else min(2.0 * (t - 5.0), 3.0)
        state = kf.update(VelocitySample(t, 0.0, 0.0, -climb))
        if 6.0 <= t < 6.5:
            assert state.ad_mps2 == pytest.approx(-2.0, abs=0.4)
        if t < 5.0 or t >= 12.0:
            assert state.ad_mps2 == pytest.approx(0.0, abs=0.1)
