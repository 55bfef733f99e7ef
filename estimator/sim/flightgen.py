"""Generator of the seed paper's flight experiments as logged flights (offline, no MAVLink).

- Experiment 1: straight-and-level legs at 0–14 m/s (one flight per speed); each leg
  accelerates from a hover, cruises, decelerates to a hover and turns around.
- Experiment 2: level circles at 1–6 m/s with radius 10 m and 20 m (one flight per pair).

Every flight has a ground idle, a climb to ``altitude_m``, the manoeuvre, a descent and a
ground idle, sampled at ``sample_rate_hz`` (5 Hz like the paper). Truth power at the battery:
eq. (2) of the given :class:`PowerModel` with the exact centripetal acceleration, plus the
kinetic-energy rate m vᵀa, plus the climb power m g v_climb (descent: half of it recovered),
plus ``idle_power_w`` on the ground. "Measured" values add noise (:class:`NoiseSpec`): the true
speed wanders around the command (gusts), velocity has white GNSS noise, power has white
sensor noise and a slow AR(1) drift. Output is :class:`estimator.logs.FlightSeries` with the
same layout the log readers produce, so the same preprocessing and fitting apply.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from estimator.logs import FlightSeries, FloatArray
from estimator.physics.model import G_MPS2, PowerModel, kinetic_power_w

_FINE_HZ = 100.0


@dataclass(frozen=True)
class NoiseSpec:
    """Noise of generated data: 1σ values (m/s, W) and correlation times (s)."""

    speed_wander_mps: float = 0.15
    wander_tau_s: float = 4.0
    velocity_mps: float = 0.05
    power_white_w: float = 8.0
    power_drift_w: float = 4.0
    power_drift_tau_s: float = 3.0

    @classmethod
    def white(cls, power_w: float = 8.0) -> NoiseSpec:
        """Independent power noise only (exact speeds): for checks of reported uncertainty."""
        return cls(0.0, 4.0, 0.0, power_w, 0.0, 3.0)


@dataclass(frozen=True)
class FlightPlan:
    """Common parameters of every generated flight."""

    altitude_m: float = 20.0
    climb_rate_mps: float = 2.0
    descent_rate_mps: float = 1.5
    accel_mps2: float = 1.5
    hover_s: float = 3.0
    ground_s: float = 3.0
    idle_power_w: float = 8.0
    sample_rate_hz: float = 5.0


def experiment1(
    model: PowerModel,
    mass_kg: float,
    speeds_mps: Iterable[float] = range(15),
    legs: int = 4,
    leg_s: float = 30.0,
    noise: NoiseSpec | None = None,
    plan: FlightPlan | None = None,
    seed: int = 0,
) -> list[FlightSeries]:
    """Straight-and-level flights, one per commanded speed, ``legs`` legs of ``leg_s`` s each."""
    plan = plan or FlightPlan()
    rng = np.random.default_rng(seed)
    flights = []
    for v in speeds_mps:
        speed, turn_rate = [], []
        for leg in range(legs):
            s = _ramp_cruise_ramp(float(v), leg_s, plan)
            speed.append(s)
            turn_rate.append(np.zeros(len(s)))
            # turnaround: reverse heading during the hover (a heading step at zero speed)
            flip = np.zeros(len(s))
            if leg < legs - 1:
                flip[-1] = math.pi * _FINE_HZ
            turn_rate[-1] = flip
        flights.append(
            _fly(
                f"exp1-v{float(v):04.1f}",
                np.concatenate(speed),
                np.concatenate(turn_rate),
                None,
                model,
                mass_kg,
                noise or NoiseSpec(),
                plan,
                rng,
            )
        )
    return flights


def experiment2(
    model: PowerModel,
    mass_kg: float,
    speeds_mps: Iterable[float] = range(1, 7),
    radii_m: Iterable[float] = (10.0, 20.0),
    circle_s: float = 90.0,
    noise: NoiseSpec | None = None,
    plan: FlightPlan | None = None,
    seed: int = 1,
) -> list[FlightSeries]:
    """Level circles, one flight per (speed, radius), ``circle_s`` s at constant speed."""
    plan = plan or FlightPlan()
    rng = np.random.default_rng(seed)
    flights = []
    for r in radii_m:
        for v in speeds_mps:
            speed = _ramp_cruise_ramp(float(v), circle_s, plan)
            flights.append(
                _fly(
                    f"exp2-r{float(r):02.0f}-v{float(v):03.1f}",
                    speed,
                    None,
                    float(r),
                    model,
                    mass_kg,
                    noise or NoiseSpec(),
                    plan,
                    rng,
                )
            )
    return flights


def _ramp_cruise_ramp(v: float, cruise_s: float, plan: FlightPlan) -> FloatArray:
    """Commanded speed at _FINE_HZ: hover, accelerate, cruise, decelerate (m/s)."""
    ramp = np.linspace(0.0, v, max(int(v / plan.accel_mps2 * _FINE_HZ), 1))
    hover = np.zeros(int(plan.hover_s * _FINE_HZ))
    cruise = np.full(int(cruise_s * _FINE_HZ), v)
    return np.concatenate([hover, ramp, cruise, ramp[::-1], hover])


def _ou(rng: np.random.Generator, n: int, sigma: float, tau_s: float, rate_hz: float) -> FloatArray:
    """Stationary AR(1)/Ornstein–Uhlenbeck noise with 1σ ``sigma`` and time constant ``tau_s``."""
    if sigma <= 0 or n == 0:
        return np.zeros(n)
    phi = math.exp(-1.0 / (tau_s * rate_hz))
    e = rng.normal(0.0, sigma * math.sqrt(1 - phi * phi), n)
    e[0] = rng.normal(0.0, sigma)
    return np.asarray(lfilter([1.0], [1.0, -phi], e), dtype=float)


def _smooth_noise(rng: np.random.Generator, n: int, sigma: float, tau_s: float) -> FloatArray:
    """Smooth random wander at _FINE_HZ (AR(1) filtered twice: differentiable), 1σ ``sigma``."""
    x = _ou(rng, n, 1.0, tau_s, _FINE_HZ)
    phi = math.exp(-1.0 / (tau_s * _FINE_HZ))
    x = np.asarray(lfilter([1.0 - phi], [1.0, -phi], x), dtype=float)
    sd = float(np.std(x))
    return x * (sigma / sd) if sd > 0 and sigma > 0 else np.zeros(n)


def _fly(
    flight_id: str,
    speed_cmd: FloatArray,
    turn_rate: FloatArray | None,
    radius_m: float | None,
    model: PowerModel,
    mass_kg: float,
    noise: NoiseSpec,
    plan: FlightPlan,
    rng: np.random.Generator,
) -> FlightSeries:
    """Assemble ground → climb → manoeuvre → descent → ground, compute truth and noise."""
    dt = 1.0 / _FINE_HZ
    # horizontal manoeuvre, with the speed wandering around its command while moving
    wander = _smooth_noise(rng, len(speed_cmd), noise.speed_wander_mps, noise.wander_tau_s)
    speed = np.where(
        speed_cmd > 0, np.maximum(speed_cmd + wander * np.minimum(speed_cmd, 1.0), 0.0), 0.0
    )
    if radius_m is not None:
        heading = np.cumsum(speed) * dt / radius_m
    else:
        assert turn_rate is not None
        heading = np.cumsum(turn_rate) * dt
    n_ground, n_climb = (
        int(plan.ground_s * _FINE_HZ),
        int(plan.altitude_m / plan.climb_rate_mps * _FINE_HZ),
    )
    n_descent = int(plan.altitude_m / plan.descent_rate_mps * _FINE_HZ)
    n_hover = int(plan.hover_s * _FINE_HZ)
    pad_before = n_ground + n_climb + n_hover
    pad_after = n_hover + n_descent + n_ground
    speed = np.concatenate([np.zeros(pad_before), speed, np.zeros(pad_after)])
    heading = np.concatenate(
        [np.full(pad_before, heading[0]), heading, np.full(pad_after, heading[-1])]
    )
    vd = np.concatenate(
        [
            np.zeros(n_ground),
            np.full(n_climb, -plan.climb_rate_mps),
            np.zeros(len(speed) - n_ground - n_climb - n_descent - n_ground),
            np.full(n_descent, plan.descent_rate_mps),
            np.zeros(n_ground),
        ]
    )
    alt = np.maximum(np.cumsum(-vd) * dt, 0.0)
    on_ground = np.zeros(len(speed), bool)
    on_ground[:n_ground] = True
    on_ground[-n_ground:] = True
    vn, ve = speed * np.cos(heading), speed * np.sin(heading)
    an, ae = np.gradient(vn, dt), np.gradient(ve, dt)
    # exact a⊥ = |v × a| / |v| (0 in hover), kinetic rate m vᵀa
    with np.errstate(invalid="ignore", divide="ignore"):
        a_perp = np.where(speed > 1e-6, np.abs(vn * ae - ve * an) / speed, 0.0)
    kinetic = kinetic_power_w(mass_kg, np.column_stack([vn, ve]), np.column_stack([an, ae]))
    climb = mass_kg * G_MPS2 * np.where(vd < 0, -vd, -0.5 * vd)
    truth = model.power_w(speed, a_perp) + kinetic + climb
    truth = np.where(on_ground, plan.idle_power_w, truth)
    # sample at the log rate
    step = round(_FINE_HZ / plan.sample_rate_hz)
    idx = np.arange(0, len(speed), step)
    n = len(idx)
    t = idx * dt

    def measured_velocity(v: np.ndarray) -> FloatArray:
        return np.asarray(v[idx] + rng.normal(0.0, noise.velocity_mps, n), dtype=float)

    power = (
        truth[idx]
        + rng.normal(0.0, noise.power_white_w, n)
        + _ou(rng, n, noise.power_drift_w, noise.power_drift_tau_s, plan.sample_rate_hz)
    )
    voltage = np.full(n, np.nan)
    return FlightSeries(
        flight_id=flight_id,
        time_s=np.asarray(t, dtype=float),
        vn_mps=measured_velocity(vn),
        ve_mps=measured_velocity(ve),
        vd_mps=measured_velocity(vd),
        alt_m=alt[idx].astype(float),
        voltage_v=voltage,
        current_a=voltage.copy(),
        power_w=power,
        extras={
            "armed": (~on_ground[idx]).astype(float),
            "truth_power_w": truth[idx].astype(float),
            "truth_speed_mps": speed[idx].astype(float),
            "truth_accel_perp_mps2": a_perp[idx].astype(float),
            "radius_m": np.full(n, np.inf if radius_m is None else radius_m),
        },
    )
