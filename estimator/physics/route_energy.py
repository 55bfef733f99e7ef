"""Energy and time of flying a route: straight legs, hovers, vertical moves, landings.

Pure functions of a :class:`RouteVehicle` (the vehicle file's power model, mass and effects) and
:class:`Conditions` (wind, payload and their uncertainty). Power comes from the project's one
prediction, :func:`~estimator.physics.effects.predict_power_w`, at a constant velocity (no
acceleration): every segment is flown at one steady state.

Conventions: positions and velocities NED (north, east, down), horizontal tracks in degrees
clockwise from north; the wind follows :class:`~estimator.physics.effects.Wind`: ``speed_mps``
and ``from_deg``, the direction it blows **from** (0 = a north wind, blowing south).
Ground speeds are over ground (what an autopilot's waypoint speed sets), airspeeds relative to
the air mass. Energies are electrical, at the battery, Wh.

Climbs and descents: the vehicle file's ``[effects.climb]`` when it has one; otherwise the same
momentum-theory term with its consistency efficiency m g v0 / c3 capped at 1 (see
:class:`~estimator.physics.effects.Climb`): about m g v_c / 2 extra for slow climbs, less power
in descent. Effects of the vehicle file with a time window are taken as they are at the
flight's start (time 0); the file's wind is replaced by the conditions' wind.

Uncertainty (1σ, first order): each result carries ``sensitivity_wh``, the signed change of its
energy for a 1σ change of each independent source in :data:`UNCERTAINTY_SOURCES` — the model's
coefficients (the vehicle file's ``[model.stderr]``, taken as independent: the file has no
covariance, so σ is conservative where c1 and c3 anticorrelate), each horizontal wind component
and the payload. Summing sensitivities over segments (:func:`sum_energies`) keeps the sources'
correlation along a route; ``energy_sigma_wh`` is their root sum of squares. Speeds chosen as
wind-optimal are held at the nominal choice (a commanded speed) when propagating.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from estimator.physics.effects import (
    Climb,
    Effect,
    FlightState,
    Mass,
    Wind,
    effects_from_tables,
    predict_power_w,
)
from estimator.physics.model import COEFFICIENT_NAMES, G_MPS2, FloatArray, PowerModel
from estimator.physics.model import _argmin_on_grid as argmin_on_grid
from estimator.physics.vehicle import Vehicle

#: The independent sources of :attr:`RouteEnergy.sensitivity_wh`, in order.
UNCERTAINTY_SOURCES = (*COEFFICIENT_NAMES, "wind_n", "wind_e", "payload")
#: Default vertical rates, m/s: ArduCopter's WPNAV_SPEED_UP / WPNAV_SPEED_DN defaults.
DEFAULT_CLIMB_RATE_MPS = 2.5
DEFAULT_DESCENT_RATE_MPS = 1.5
#: Default speed limits, m/s: ArduCopter's WPNAV_SPEED range (ground) and a multirotor's
#: sensible airspeed ceiling.
DEFAULT_MAX_GROUND_SPEED_MPS = 20.0
DEFAULT_MAX_AIRSPEED_MPS = 20.0
#: Slowest ground speed the wind-optimal search considers, m/s.
MIN_GROUND_SPEED_MPS = 0.2
#: Finite-difference step of the sensitivities, in units of each source's 1σ.
_STEP_SIGMAS = 0.05
_J_PER_WH = 3600.0


class InfeasibleTrack(ValueError):
    """The wind is too strong to make headway along a track within the airspeed limit."""


@dataclass(frozen=True)
class Conditions:
    """Wind and payload of a flight, with their 1σ.

    wind_speed_mps, wind_from_deg: steady horizontal wind, blowing FROM ``wind_from_deg``
    (° clockwise from north). payload_kg: mass beyond the vehicle file's (kg; negative:
    lighter). wind_sigma_mps: 1σ of each horizontal wind component (north, east), m/s.
    payload_sigma_kg: 1σ of the payload, kg.
    """

    wind_speed_mps: float = 0.0
    wind_from_deg: float = 0.0
    payload_kg: float = 0.0
    wind_sigma_mps: float = 0.0
    payload_sigma_kg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("wind_speed_mps", "wind_sigma_mps", "payload_sigma_kg"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"Conditions.{name} must be finite and ≥ 0, got {value}")
        for name in ("wind_from_deg", "payload_kg"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"Conditions.{name} must be finite")

    @property
    def wind(self) -> Wind:
        return Wind(speed_mps=self.wind_speed_mps, from_deg=self.wind_from_deg)

    def wind_ne_mps(self) -> tuple[float, float]:
        """Air-mass velocity over ground (north, east), m/s: where the wind blows TO."""
        return self.wind.vector_ne_mps()


@dataclass(frozen=True)
class RouteVehicle:
    """What route energy needs from a vehicle file.

    model: eq. (1)/(2) coefficients at ``mass_kg`` (kg). model_stderr: 1σ of c1..c5 (0 where
    the file has none). effects: the file's effects without its wind, with a climb term.
    """

    model: PowerModel
    mass_kg: float
    model_stderr: tuple[float, float, float, float, float]
    effects: tuple[Effect, ...]

    @classmethod
    def from_vehicle(cls, vehicle: Vehicle) -> RouteVehicle:
        effects = [e for e in effects_from_tables(vehicle.effects) if not isinstance(e, Wind)]
        if not any(isinstance(e, Climb) for e in effects):
            effects.append(Climb(efficiency=consistent_climb_efficiency(vehicle)))
        stderr = tuple(float(vehicle.model_stderr.get(n, 0.0)) for n in COEFFICIENT_NAMES)
        return cls(vehicle.model, vehicle.mass_kg, stderr, tuple(effects))  # type: ignore[arg-type]


def consistent_climb_efficiency(vehicle: Vehicle) -> float:
    """m g v0 / c3 capped to (0, 1]: the electrical-to-rotor efficiency a model's hover induced
    power implies (:class:`~estimator.physics.effects.Climb`)."""
    model = vehicle.model
    v0 = float(model.hover_induced_velocity_mps())
    if model.c3 <= 0:
        return 1.0
    return float(min(1.0, vehicle.mass_kg * G_MPS2 * v0 / model.c3))


@dataclass(frozen=True)
class SpeedChoice:
    """The wind-optimal speed along a track: ground_speed_mps (over ground, along the track),
    airspeed_mps, power_w (electrical, W) and energy_per_m_j (J per metre over ground)."""

    track_deg: float
    ground_speed_mps: float
    airspeed_mps: float
    power_w: float
    energy_per_m_j: float


@dataclass(frozen=True)
class RouteEnergy:
    """Energy and time of one segment (or a sum of segments, :func:`sum_energies`).

    kind: "leg", "hover", "vertical", "landing" or "sum". distance_m: horizontal over ground,
    m. climb_m: height gained (negative: lost), m. time_s: duration, s. ground_speed_mps,
    airspeed_mps: horizontal, of the steady state (0 for a sum). power_w: mean electrical
    power, W. energy_wh, energy_sigma_wh: electrical energy and its 1σ, Wh.
    sensitivity_wh: signed energy change for 1σ of each of :data:`UNCERTAINTY_SOURCES`, Wh.
    """

    kind: str
    distance_m: float
    climb_m: float
    time_s: float
    ground_speed_mps: float
    airspeed_mps: float
    power_w: float
    energy_wh: float
    sensitivity_wh: tuple[float, ...]

    @property
    def energy_sigma_wh(self) -> float:
        return float(math.sqrt(sum(s * s for s in self.sensitivity_wh)))


# -- steady power --------------------------------------------------------------------------------


def _velocity_ne(track_deg: float, ground_speed_mps: FloatArray | float) -> tuple[FloatArray, ...]:
    rad = math.radians(track_deg)
    v = np.asarray(ground_speed_mps, dtype=float)
    return v * math.cos(rad), v * math.sin(rad)


def steady_power_w(
    vehicle: RouteVehicle,
    conditions: Conditions,
    vn_mps: FloatArray | float,
    ve_mps: FloatArray | float,
    vd_mps: FloatArray | float = 0.0,
) -> FloatArray:
    """Electrical power (W) at constant ground velocity (NED, m/s; arrays broadcast)."""
    vn, ve, vd = np.broadcast_arrays(
        np.atleast_1d(np.asarray(vn_mps, dtype=float)),
        np.atleast_1d(np.asarray(ve_mps, dtype=float)),
        np.atleast_1d(np.asarray(vd_mps, dtype=float)),
    )
    zeros = np.zeros(vn.shape)
    state = FlightState(
        time_s=zeros,
        vn_mps=vn.copy(),
        ve_mps=ve.copy(),
        vd_mps=vd.copy(),
        an_mps2=zeros,
        ae_mps2=zeros,
        alt_m=np.full(vn.shape, np.nan),
        voltage_v=np.full(vn.shape, np.nan),
    )
    effects: list[Effect] = [conditions.wind, *vehicle.effects]
    if conditions.payload_kg != 0.0:
        effects.append(Mass(delta_kg=conditions.payload_kg))
    return predict_power_w(vehicle.model, vehicle.mass_kg, state, effects)


def _perturbed(
    vehicle: RouteVehicle, conditions: Conditions
) -> Iterable[tuple[int, float, RouteVehicle, Conditions]]:
    """(source index, step in σ, vehicle, conditions) pairs for central differences."""
    coeffs = vehicle.model.as_array()
    wn, we = conditions.wind_ne_mps()
    for k, sigma in enumerate(vehicle.model_stderr):
        if sigma <= 0:
            continue
        for sign in (1.0, -1.0):
            c = coeffs.copy()
            c[k] += sign * _STEP_SIGMAS * sigma
            if c[k] <= 0:  # one-sided difference at a coefficient's lower bound
                continue
            model = PowerModel.from_array(c)
            yield k, sign * _STEP_SIGMAS, replace(vehicle, model=model), conditions
    if conditions.wind_sigma_mps > 0:
        for k, (dn, de) in ((5, (1.0, 0.0)), (6, (0.0, 1.0))):
            for sign in (1.0, -1.0):
                step = sign * _STEP_SIGMAS * conditions.wind_sigma_mps
                yield (
                    k,
                    sign * _STEP_SIGMAS,
                    vehicle,
                    _with_wind_ne(conditions, wn + step * dn, we + step * de),
                )
    if conditions.payload_sigma_kg > 0:
        for sign in (1.0, -1.0):
            payload = conditions.payload_kg + sign * _STEP_SIGMAS * conditions.payload_sigma_kg
            yield 7, sign * _STEP_SIGMAS, vehicle, replace(conditions, payload_kg=payload)


def _with_wind_ne(conditions: Conditions, wn_mps: float, we_mps: float) -> Conditions:
    """``conditions`` with the air-mass velocity (north, east) m/s, as speed and from-bearing."""
    from_deg = math.degrees(math.atan2(-we_mps, -wn_mps)) % 360.0
    return replace(conditions, wind_speed_mps=math.hypot(wn_mps, we_mps), wind_from_deg=from_deg)


def _energy_with_sensitivity(
    vehicle: RouteVehicle,
    conditions: Conditions,
    phases: Sequence[tuple[float, float, float, float]],
) -> tuple[float, tuple[float, ...]]:
    """Energy (Wh) of steady phases (vn, ve, vd m/s, duration s) and its 1σ sensitivities."""
    vn, ve, vd, dur = (np.array(col, dtype=float) for col in zip(*phases, strict=True))

    def energy_wh(v: RouteVehicle, c: Conditions) -> float:
        return float(np.sum(steady_power_w(v, c, vn, ve, vd) * dur) / _J_PER_WH)

    nominal = energy_wh(vehicle, conditions)
    slopes = np.zeros(len(UNCERTAINTY_SOURCES))
    steps = np.zeros(len(UNCERTAINTY_SOURCES))
    for k, step, v, c in _perturbed(vehicle, conditions):
        slopes[k] += math.copysign(1.0, step) * (energy_wh(v, c) - nominal)
        steps[k] += abs(step)
    sens = np.divide(slopes, steps, out=np.zeros_like(slopes), where=steps > 0)
    return nominal, tuple(float(s) for s in sens)


# -- speeds --------------------------------------------------------------------------------------


def energy_per_metre_j(
    vehicle: RouteVehicle, conditions: Conditions, track_deg: float, ground_speed_mps: float
) -> float:
    """Energy per metre over ground (J/m) along ``track_deg`` at ``ground_speed_mps`` (> 0)."""
    if ground_speed_mps <= 0:
        raise ValueError("ground speed must be > 0")
    vn, ve = _velocity_ne(track_deg, ground_speed_mps)
    return float(steady_power_w(vehicle, conditions, vn, ve)[0] / ground_speed_mps)


def optimal_speed(
    vehicle: RouteVehicle,
    conditions: Conditions,
    track_deg: float,
    *,
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS,
    max_airspeed_mps: float = DEFAULT_MAX_AIRSPEED_MPS,
) -> SpeedChoice:
    """The ground speed along ``track_deg`` with the least energy per metre over ground, with
    ground speed in [:data:`MIN_GROUND_SPEED_MPS`, max_ground_speed_mps] and airspeed at most
    ``max_airspeed_mps``; in still air this is the model's V_mr. InfeasibleTrack when no
    ground speed in range keeps the airspeed within its limit."""
    wn, we = conditions.wind_ne_mps()
    un, ue = math.cos(math.radians(track_deg)), math.sin(math.radians(track_deg))

    def airspeed(vg: FloatArray) -> FloatArray:
        return np.asarray(np.hypot(vg * un - wn, vg * ue - we), dtype=float)

    def cost(vg: FloatArray) -> FloatArray:
        vn, ve = _velocity_ne(track_deg, vg)
        per_m = steady_power_w(vehicle, conditions, vn, ve) / vg
        return np.asarray(np.where(airspeed(vg) <= max_airspeed_mps, per_m, np.inf))

    lo, hi = MIN_GROUND_SPEED_MPS, max(max_ground_speed_mps, MIN_GROUND_SPEED_MPS)
    grid = np.linspace(lo, hi, 601)
    if not np.any(airspeed(grid) <= max_airspeed_mps):
        raise InfeasibleTrack(
            f"a {conditions.wind_speed_mps:g} m/s wind from {conditions.wind_from_deg:g}° allows "
            f"no ground speed along {track_deg:.0f}° within {max_airspeed_mps:g} m/s airspeed"
        )
    vg = argmin_on_grid(cost, lo, hi)
    per_m = float(cost(np.array([vg]))[0])
    return SpeedChoice(track_deg, vg, float(airspeed(np.array([vg]))[0]), per_m * vg, per_m)


# -- segments ------------------------------------------------------------------------------------


def leg_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    *,
    distance_m: float,
    track_deg: float,
    climb_m: float = 0.0,
    ground_speed_mps: float | None = None,
    climb_rate_mps: float = DEFAULT_CLIMB_RATE_MPS,
    descent_rate_mps: float = DEFAULT_DESCENT_RATE_MPS,
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS,
    max_airspeed_mps: float = DEFAULT_MAX_AIRSPEED_MPS,
) -> RouteEnergy:
    """A straight leg of ``distance_m`` over ground along ``track_deg`` while changing height by
    ``climb_m`` (m, + up), at ``ground_speed_mps`` (None: :func:`optimal_speed`).

    Horizontal and vertical motion run together, as a multicopter's waypoint controller flies a
    sloped leg: the leg takes the longer of distance / ground speed and |climb| / vertical rate
    (``climb_rate_mps`` up, ``descent_rate_mps`` down), both at a constant velocity.
    """
    if distance_m < 0 or not math.isfinite(distance_m):
        raise ValueError("distance must be finite and ≥ 0")
    if ground_speed_mps is None:
        ground_speed_mps = optimal_speed(
            vehicle,
            conditions,
            track_deg,
            max_ground_speed_mps=max_ground_speed_mps,
            max_airspeed_mps=max_airspeed_mps,
        ).ground_speed_mps
    if ground_speed_mps <= 0:
        raise ValueError("ground speed must be > 0")
    rate_mps = climb_rate_mps if climb_m >= 0 else descent_rate_mps
    if rate_mps <= 0:
        raise ValueError("vertical rates must be > 0")
    time_s = max(distance_m / ground_speed_mps, abs(climb_m) / rate_mps)
    if time_s <= 0:
        return _segment(vehicle, conditions, "leg", 0.0, track_deg, 0.0, 0.0)
    return _segment(
        vehicle, conditions, "leg", distance_m / time_s, track_deg, climb_m / time_s, time_s
    )


def hover_energy(vehicle: RouteVehicle, conditions: Conditions, duration_s: float) -> RouteEnergy:
    """Holding position for ``duration_s`` (s): airspeed is the wind speed."""
    if duration_s < 0:
        raise ValueError("duration must be ≥ 0")
    return _segment(vehicle, conditions, "hover", 0.0, 0.0, 0.0, duration_s)


def vertical_energy(
    vehicle: RouteVehicle, conditions: Conditions, climb_m: float, rate_mps: float
) -> RouteEnergy:
    """Climbing (``climb_m`` > 0) or descending in place at ``rate_mps`` (m/s, > 0)."""
    if rate_mps <= 0:
        raise ValueError("vertical rate must be > 0")
    time_s = abs(climb_m) / rate_mps
    vz = math.copysign(rate_mps, climb_m) if climb_m else 0.0
    return _segment(vehicle, conditions, "vertical", 0.0, 0.0, vz, time_s)


def landing_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    height_m: float,
    descent_rate_mps: float,
    *,
    final_height_m: float = 0.0,
    final_rate_mps: float | None = None,
    touchdown_s: float = 0.0,
) -> RouteEnergy:
    """Landing from ``height_m`` (m above the ground): down to ``final_height_m`` at
    ``descent_rate_mps``, the rest at ``final_rate_mps`` (m/s; None: the same rate), then
    ``touchdown_s`` (s) at hover power until the motors stop (ArduCopter's LAND: WPNAV_SPEED_DN
    above LAND_ALT_LOW, then LAND_SPEED)."""
    if height_m < 0 or descent_rate_mps <= 0:
        raise ValueError("landing needs a height ≥ 0 and a descent rate > 0")
    slow_rate = descent_rate_mps if final_rate_mps is None else final_rate_mps
    if slow_rate <= 0:
        raise ValueError("final descent rate must be > 0")
    fast_m = max(height_m - final_height_m, 0.0)
    slow_m = height_m - fast_m
    phases = [
        (0.0, 0.0, descent_rate_mps, fast_m / descent_rate_mps),
        (0.0, 0.0, slow_rate, slow_m / slow_rate),
        (0.0, 0.0, 0.0, max(touchdown_s, 0.0)),
    ]
    energy_wh, sens = _energy_with_sensitivity(vehicle, conditions, phases)
    time_s = sum(p[3] for p in phases)
    return RouteEnergy(
        kind="landing",
        distance_m=0.0,
        climb_m=-height_m,
        time_s=time_s,
        ground_speed_mps=0.0,
        airspeed_mps=conditions.wind_speed_mps,
        power_w=energy_wh * _J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=sens,
    )


def _segment(
    vehicle: RouteVehicle,
    conditions: Conditions,
    kind: str,
    ground_speed_mps: float,
    track_deg: float,
    climb_rate_mps: float,
    time_s: float,
) -> RouteEnergy:
    """One steady segment: horizontal ground speed along a track and a vertical rate (+ up)."""
    vn, ve = _velocity_ne(track_deg, ground_speed_mps)
    energy_wh, sens = _energy_with_sensitivity(
        vehicle, conditions, [(float(vn), float(ve), -climb_rate_mps, time_s)]
    )
    wn, we = conditions.wind_ne_mps()
    return RouteEnergy(
        kind=kind,
        distance_m=ground_speed_mps * time_s,
        climb_m=climb_rate_mps * time_s,
        time_s=time_s,
        ground_speed_mps=ground_speed_mps,
        airspeed_mps=float(math.hypot(float(vn) - wn, float(ve) - we)),
        power_w=energy_wh * _J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=sens,
    )


def sum_energies(segments: Iterable[RouteEnergy]) -> RouteEnergy:
    """Several segments flown one after the other: distances, climbs, times, energies and
    sensitivities add (the sources are shared, so their σ add per source, not in quadrature)."""
    items = list(segments)
    time_s = sum(s.time_s for s in items)
    energy_wh = sum(s.energy_wh for s in items)
    sens = np.sum([s.sensitivity_wh for s in items], axis=0) if items else None
    return RouteEnergy(
        kind="sum",
        distance_m=sum(s.distance_m for s in items),
        climb_m=sum(s.climb_m for s in items),
        time_s=time_s,
        ground_speed_mps=0.0,
        airspeed_mps=0.0,
        power_w=energy_wh * _J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=(
            tuple(float(s) for s in sens) if sens is not None else (0.0,) * len(UNCERTAINTY_SOURCES)
        ),
    )
