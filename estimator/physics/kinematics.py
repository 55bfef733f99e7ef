"""Flight-state kinematics: speed, tangential and centripetal acceleration (horizontal plane).

Frames: velocity and acceleration are NED components (north, east, down), m/s and m/s².
The pure functions work on floats and arrays alike; :class:`KinematicsFilter` is the causal,
noise-robust estimator the pipeline runs on each velocity sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from estimator.telemetry.samples import VelocitySample

#: Scalars (one sample) or numpy arrays (many): the functions below take either, alike.
FloatOrArray = TypeVar("FloatOrArray", float, NDArray[np.float64])

#: Below about this speed the direction of flight is noise; a⊥ is faded out smoothly.
DEFAULT_SPEED_FLOOR_MPS = 0.5


def centripetal_accel_mps2(
    vn_mps: FloatOrArray,
    ve_mps: FloatOrArray,
    an_mps2: FloatOrArray,
    ae_mps2: FloatOrArray,
    speed_floor_mps: float = DEFAULT_SPEED_FLOOR_MPS,
) -> FloatOrArray:
    """a⊥ = |v × a| / |v| with a continuous low-speed treatment (floats or arrays alike).

    The exact a⊥ is undefined at V = 0. We use |v × a| / sqrt(V² + V_f²): equal to a⊥ within
    1 − V_f²/(2V²) above the floor (3 % at 2 m/s for V_f = 0.5 m/s), tending to 0 in hover,
    continuous everywhere. A fixed-radius turn has a⊥ = V²/r → 0 as V → 0 anyway.
    """
    cross = vn_mps * ae_mps2 - ve_mps * an_mps2
    return abs(cross) / (vn_mps * vn_mps + ve_mps * ve_mps + speed_floor_mps**2) ** 0.5


def tangential_accel_mps2(
    vn_mps: FloatOrArray,
    ve_mps: FloatOrArray,
    an_mps2: FloatOrArray,
    ae_mps2: FloatOrArray,
    speed_floor_mps: float = DEFAULT_SPEED_FLOOR_MPS,
) -> FloatOrArray:
    """Signed acceleration along the velocity, vᵀa / sqrt(V² + V_f²) (same treatment as a⊥)."""
    dot = vn_mps * an_mps2 + ve_mps * ae_mps2
    return dot / (vn_mps * vn_mps + ve_mps * ve_mps + speed_floor_mps**2) ** 0.5


@dataclass(frozen=True, slots=True)
class KinematicState:
    """Filtered flight state at one instant (NED frame; horizontal accelerations over ground).

    time_s: sample time, s.  vn/ve/vd_mps: velocity, m/s.  an/ae_mps2: horizontal
    acceleration, m/s².  speed_mps: horizontal speed.  accel_tangential/centripetal_mps2: along
    and across the horizontal velocity (low-speed treatment of the functions above).
    climb_mps: −vd, m/s (up positive).  alt_m: altitude above home, m (None if unknown).
    accel_sigma_mps2: 1σ of each horizontal acceleration component, m/s².  ad_mps2: vertical
    acceleration, m/s² (down positive).
    """

    time_s: float
    vn_mps: float
    ve_mps: float
    vd_mps: float
    an_mps2: float
    ae_mps2: float
    speed_mps: float
    accel_tangential_mps2: float
    accel_centripetal_mps2: float
    climb_mps: float
    alt_m: float | None
    accel_sigma_mps2: float = 0.0
    ad_mps2: float = 0.0

    @classmethod
    def of_motion(
        cls,
        time_s: float,
        v_ned_mps: tuple[float, float, float],
        a_ne_mps2: tuple[float, float],
        alt_m: float | None = None,
        accel_sigma_mps2: float = 0.0,
        ad_mps2: float = 0.0,
    ) -> KinematicState:
        """The state with velocity (north, east, down), horizontal acceleration (north, east)
        and vertical acceleration ``ad_mps2`` (down); speed, tangential and centripetal
        acceleration and climb derived from them."""
        (vn, ve, vd), (an, ae) = v_ned_mps, a_ne_mps2
        return cls(
            time_s,
            vn,
            ve,
            vd,
            an,
            ae,
            speed_mps=math.hypot(vn, ve),
            accel_tangential_mps2=tangential_accel_mps2(vn, ve, an, ae),
            accel_centripetal_mps2=centripetal_accel_mps2(vn, ve, an, ae),
            climb_mps=-vd,
            alt_m=alt_m,
            accel_sigma_mps2=accel_sigma_mps2,
            ad_mps2=ad_mps2,
        )


@dataclass(frozen=True, slots=True)
class KinematicsSettings:
    """Tuning of :class:`KinematicsFilter`.

    jerk_psd: white-jerk spectral density of the constant-acceleration model, m²/s⁵ (larger
    follows manoeuvres faster, smooths less).  velocity_noise_mps: 1σ of a velocity sample
    (GNSS/EKF velocity), m/s.  max_gap_s: a longer gap between samples restarts the filter
    from the next sample (the acceleration is unknown across it).
    """

    jerk_psd: float = 0.5
    velocity_noise_mps: float = 0.1
    vertical_velocity_noise_mps: float = 0.15
    max_gap_s: float = 1.5
    initial_accel_sigma_mps2: float = 1.0


class _Axis:
    """Constant-acceleration Kalman filter for one velocity axis, state [v, a], scalar math.

    The covariance depends only on the time steps and noise figures, so axes with the same
    noise could share it; keeping one per axis keeps the filter simple and exact.
    """

    __slots__ = ("a", "p_aa", "p_va", "p_vv", "v")

    def __init__(self, velocity_mps: float, velocity_var: float, accel_var: float) -> None:
        self.v, self.a = velocity_mps, 0.0
        self.p_vv, self.p_va, self.p_aa = velocity_var, 0.0, accel_var

    def step(self, dt_s: float, z_mps: float, jerk_psd: float, r_var: float) -> None:
        """Predict over ``dt_s`` (F = [[1, dt], [0, 1]], white-jerk Q), then update with z."""
        v = self.v + dt_s * self.a
        p_vv = self.p_vv + 2 * dt_s * self.p_va + dt_s * dt_s * self.p_aa + jerk_psd * dt_s**3 / 3
        p_va = self.p_va + dt_s * self.p_aa + jerk_psd * dt_s * dt_s / 2
        p_aa = self.p_aa + jerk_psd * dt_s
        s = p_vv + r_var
        k_v, k_a = p_vv / s, p_va / s
        innovation = z_mps - v
        self.v, self.a = v + k_v * innovation, self.a + k_a * innovation
        self.p_vv, self.p_va, self.p_aa = (1 - k_v) * p_vv, (1 - k_v) * p_va, p_aa - k_a * p_va


class KinematicsFilter:
    """Causal constant-acceleration Kalman filter per axis (north, east, down) on velocity.

    Each axis has state [v, a]; measurements are velocity samples at any, irregular rate
    (2–50 Hz). The transition and white-jerk process noise are built from each sample's own
    time step, so rates and jitter need no tuning. Gaps longer than ``max_gap_s``, time going
    backwards, and :meth:`reset` restart the filter from the next sample. Scalar arithmetic
    per axis (no matrices): a few microseconds per sample on a companion computer.
    """

    def __init__(self, settings: KinematicsSettings | None = None) -> None:
        self.settings = settings or KinematicsSettings()
        self._axes: tuple[_Axis, _Axis, _Axis] | None = None
        self._last_time_s: float | None = None
        self.restarts = 0

    def reset(self) -> None:
        """Forget the state (after an autopilot reboot or a source change)."""
        self._last_time_s = None

    def update(self, sample: VelocitySample) -> KinematicState:
        """Fold in one velocity sample and return the filtered state at its time."""
        s = self.settings
        r_h, r_v = s.velocity_noise_mps**2, s.vertical_velocity_noise_mps**2
        z = (sample.vn_mps, sample.ve_mps, sample.vd_mps)
        dt = None if self._last_time_s is None else sample.time_s - self._last_time_s
        if self._axes is None or dt is None or dt <= 0.0 or dt > s.max_gap_s:
            if self._last_time_s is not None:
                self.restarts += 1
            a_var = s.initial_accel_sigma_mps2**2
            self._axes = (_Axis(z[0], r_h, a_var), _Axis(z[1], r_h, a_var), _Axis(z[2], r_v, a_var))
        else:
            north, east, down = self._axes
            north.step(dt, z[0], s.jerk_psd, r_h)
            east.step(dt, z[1], s.jerk_psd, r_h)
            down.step(dt, z[2], s.jerk_psd, r_v)
        self._last_time_s = sample.time_s
        north, east, down = self._axes
        return KinematicState.of_motion(
            sample.time_s,
            (north.v, east.v, down.v),
            (north.a, east.a),
            sample.alt_m,
            math.sqrt(0.5 * (north.p_aa + east.p_aa)),
            down.a,
        )
