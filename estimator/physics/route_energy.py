"""Energy and time of flying a route: straight legs, hovers, vertical moves, landings.

Pure functions of a :class:`RouteVehicle` (the vehicle file's power model, mass and effects) and
:class:`Conditions` (wind, payload and their uncertainty). Power comes from the project's one
prediction, :func:`~estimator.physics.effects.predict_power_w`, piecewise: each phase of a
segment at one velocity with its mean acceleration (steady, unless :class:`Kinematics` adds
the speed changes).

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
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from typing import NamedTuple

import numpy as np

from estimator.physics.effects import (
    Climb,
    Effect,
    FlightState,
    Mass,
    SampleMass,
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
#: ArduCopter's speed changes: WPNAV_ACCEL (m/s²), WPNAV_JERK (m/s³), WPNAV_ACCEL_Z (m/s²).
DEFAULT_ACCEL_MPS2 = 2.5
DEFAULT_JERK_MPS3 = 1.0
DEFAULT_VERTICAL_ACCEL_MPS2 = 1.0
#: ArduCopter's RTL and landing: RTL_ALT (m), the start in place before it turns home (s,
#: measured in SITL), RTL_LOIT_TIME (s), LAND_ALT_LOW (m) and LAND_SPEED (m/s) below it.
DEFAULT_RTL_ALT_M = 15.0
DEFAULT_RTL_PAUSE_S = 2.0
DEFAULT_RTL_LOITER_S = 5.0
DEFAULT_LAND_ALT_LOW_M = 10.0
DEFAULT_LAND_SPEED_MPS = 0.5
#: Slowest ground speed the wind-optimal search considers, m/s.
MIN_GROUND_SPEED_MPS = 0.2
#: Finite-difference step of the sensitivities, in units of each source's 1σ.
_STEP_SIGMAS = 0.05
_J_PER_WH = 3600.0
#: Energy per metre (J/m) standing for "beyond the airspeed limit" in the speed search.
_OUT_OF_RANGE = 1e12
#: Phase states whose powers a :class:`RouteVehicle` keeps per set of hypotheses, and sets of
#: hypotheses it keeps (each starts over when full).
_PHASE_POWERS_SIZE = 4096
_HYPOTHESES_KEPT = 8


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
        return self._wind_ne_mps

    @cached_property
    def _wind_ne_mps(self) -> tuple[float, float]:
        return self.wind.vector_ne_mps()


@dataclass(frozen=True)
class RouteVehicle:
    """What route energy needs from a vehicle file.

    model: eq. (1)/(2) coefficients at ``mass_kg`` (kg). model_stderr: 1σ of c1..c5 (0 where
    the file has none). effects: the file's effects without its wind, with a climb term.
    phase_powers_w: the electrical power (W) of each phase state already predicted, per
    hypothesis, by set of hypotheses (:func:`_energies_wh`): a live return repeats the same
    hovers, climbs and landings at every estimate, so only its leg is predicted anew.
    """

    model: PowerModel
    mass_kg: float
    model_stderr: tuple[float, float, float, float, float]
    effects: tuple[Effect, ...]
    phase_powers_w: dict[tuple[_Hypothesis, ...], dict[_PhaseState, tuple[float, ...]]] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

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


def _velocity_ne(track_deg: float, ground_speed_mps: FloatArray) -> tuple[FloatArray, ...]:
    rad = math.radians(track_deg)
    return ground_speed_mps * math.cos(rad), ground_speed_mps * math.sin(rad)


def _steady_state(
    vn_mps: FloatArray | float,
    ve_mps: FloatArray | float,
    vd_mps: FloatArray | float,
    an_mps2: FloatArray | float,
    ae_mps2: FloatArray | float,
) -> FlightState:
    """A flight state of these velocities (NED, m/s) and horizontal accelerations (NED, m/s²),
    broadcast to one shape; no time, altitude or voltage (steady flight anywhere)."""
    vn, ve, vd, an, ae = (
        np.array(x, dtype=float)  # copies: the prediction may not share the caller's arrays
        for x in np.broadcast_arrays(
            *(
                np.atleast_1d(np.asarray(x, dtype=float))
                for x in (vn_mps, ve_mps, vd_mps, an_mps2, ae_mps2)
            )
        )
    )
    nan = np.full(vn.shape, np.nan)
    return FlightState(np.zeros(vn.shape), vn, ve, vd, an, ae, nan, nan.copy())


def steady_power_w(
    vehicle: RouteVehicle,
    conditions: Conditions,
    vn_mps: FloatArray | float,
    ve_mps: FloatArray | float,
    vd_mps: FloatArray | float = 0.0,
    an_mps2: FloatArray | float = 0.0,
    ae_mps2: FloatArray | float = 0.0,
) -> FloatArray:
    """Electrical power (W) at ground velocity (NED, m/s) and horizontal acceleration (NED,
    m/s²; 0: steady flight); arrays broadcast."""
    state = _steady_state(vn_mps, ve_mps, vd_mps, an_mps2, ae_mps2)
    effects: list[Effect] = [conditions.wind, *vehicle.effects]
    if conditions.payload_kg != 0.0:
        effects.append(Mass(delta_kg=conditions.payload_kg))
    return predict_power_w(vehicle.model, vehicle.mass_kg, state, effects)


def _model_perturbations(vehicle: RouteVehicle) -> Iterable[tuple[int, float, RouteVehicle]]:
    """(source index, step in σ, vehicle) for central differences over c1..c5."""
    coeffs = vehicle.model.as_array()
    for k, sigma in enumerate(vehicle.model_stderr):
        if sigma <= 0:
            continue
        for sign in (1.0, -1.0):
            c = coeffs.copy()
            c[k] += sign * _STEP_SIGMAS * sigma
            if c[k] <= 0:  # one-sided difference at a coefficient's lower bound
                continue
            yield k, sign * _STEP_SIGMAS, replace(vehicle, model=PowerModel.from_array(c))


class _Hypothesis(NamedTuple):
    """Conditions to evaluate phases in: the uncertainty source stepped (index in
    :data:`UNCERTAINTY_SOURCES`, -1 for none) and its step in σ, the air mass's velocity over
    ground (north, east, m/s) and the payload (kg)."""

    source: int
    step: float
    wind_n_mps: float
    wind_e_mps: float
    payload_kg: float


@lru_cache(maxsize=64)
def _condition_hypotheses(conditions: Conditions) -> tuple[_Hypothesis, ...]:
    """The nominal conditions first, then central-difference steps of the wind components and
    the payload (those with a σ); kept for recent conditions (every segment of a route asks)."""
    wn, we = conditions.wind_ne_mps()
    payload = conditions.payload_kg
    out = [_Hypothesis(-1, 0.0, wn, we, payload)]
    if conditions.wind_sigma_mps > 0:
        for k, (dn, de) in ((5, (1.0, 0.0)), (6, (0.0, 1.0))):
            for sign in (1.0, -1.0):
                step = sign * _STEP_SIGMAS * conditions.wind_sigma_mps
                out.append(
                    _Hypothesis(k, sign * _STEP_SIGMAS, wn + step * dn, we + step * de, payload)
                )
    if conditions.payload_sigma_kg > 0:
        for sign in (1.0, -1.0):
            step = sign * _STEP_SIGMAS * conditions.payload_sigma_kg
            out.append(_Hypothesis(7, sign * _STEP_SIGMAS, wn, we, payload + step))
    return tuple(out)


class _PhaseState(NamedTuple):
    """A phase's mean state: velocity NED (m/s) and horizontal acceleration NED (m/s²)."""

    vn_mps: float
    ve_mps: float
    vd_mps: float
    an_mps2: float
    ae_mps2: float


@dataclass(frozen=True)
class _Phase:
    """A piece of flight at one mean state: velocity NED (m/s), horizontal acceleration NED
    (m/s²), duration (s)."""

    vn_mps: float
    ve_mps: float
    vd_mps: float
    duration_s: float
    an_mps2: float = 0.0
    ae_mps2: float = 0.0

    @property
    def state(self) -> _PhaseState:
        return _PhaseState(self.vn_mps, self.ve_mps, self.vd_mps, self.an_mps2, self.ae_mps2)


def _energies_wh(
    vehicle: RouteVehicle, phases: Sequence[_Phase], hypotheses: Sequence[_Hypothesis]
) -> list[float]:
    """Energy (Wh) of ``phases`` under each hypothesis. The powers of phase states not yet in
    the vehicle's :attr:`~RouteVehicle.phase_powers_w` come from one prediction over those
    states × hypotheses: the wind taken out of the ground velocity (what :class:`Wind` does),
    the payload as a per-row :class:`SampleMass` (what :class:`Mass` does)."""
    tables = vehicle.phase_powers_w
    key = tuple(hypotheses)
    table = tables.get(key)
    if table is None or len(table) >= _PHASE_POWERS_SIZE:
        if len(tables) >= _HYPOTHESES_KEPT:
            tables.clear()
        table = tables[key] = {}
    states = [ph.state for ph in phases]
    missing = list(dict.fromkeys(s for s in states if s not in table))
    if missing:
        m, n = len(hypotheses), len(missing)
        h = np.array([hyp[2:] for hyp in hypotheses], dtype=float)  # m × (wind n, e, payload)
        columns = np.tile(np.array(missing, dtype=float).T, m)  # 5 × (m·n), hypothesis-major
        state = _steady_state(
            columns[0] - np.repeat(h[:, 0], n),
            columns[1] - np.repeat(h[:, 1], n),
            columns[2],
            columns[3],
            columns[4],
        )
        effects = (*vehicle.effects, SampleMass(np.repeat(h[:, 2], n)))
        power_w = predict_power_w(vehicle.model, vehicle.mass_kg, state, effects).reshape(m, n)
        for s, powers in zip(missing, power_w.T.tolist(), strict=True):
            table[s] = tuple(powers)
    rows = [(table[s], ph.duration_s) for s, ph in zip(states, phases, strict=True)]
    return [sum(p[i] * d for p, d in rows) / _J_PER_WH for i in range(len(hypotheses))]


def _energy_with_sensitivity(
    vehicle: RouteVehicle, conditions: Conditions, phases: Sequence[_Phase]
) -> tuple[float, tuple[float, ...]]:
    """Energy (Wh) of ``phases`` and its 1σ sensitivities (:data:`UNCERTAINTY_SOURCES`): the
    wind and payload steps in one prediction with the nominal, each model step in its own."""
    hypotheses = _condition_hypotheses(conditions)
    energies = _energies_wh(vehicle, phases, hypotheses)
    nominal = energies[0]
    slopes = [0.0] * len(UNCERTAINTY_SOURCES)
    steps = [0.0] * len(UNCERTAINTY_SOURCES)
    stepped = [(h.source, h.step, e) for h, e in zip(hypotheses[1:], energies[1:], strict=True)]
    for k, step, v in _model_perturbations(vehicle):
        stepped.append((k, step, _energies_wh(v, phases, hypotheses[:1])[0]))
    for k, step, energy_wh in stepped:
        slopes[k] += math.copysign(1.0, step) * (energy_wh - nominal)
        steps[k] += abs(step)
    return nominal, tuple(s / w if w > 0 else 0.0 for s, w in zip(slopes, steps, strict=True))


# -- speeds --------------------------------------------------------------------------------------


def energy_per_metre_j(
    vehicle: RouteVehicle, conditions: Conditions, track_deg: float, ground_speed_mps: float
) -> float:
    """Energy per metre over ground (J/m) along ``track_deg`` at ``ground_speed_mps`` (> 0)."""
    if ground_speed_mps <= 0:
        raise ValueError("ground speed must be > 0")
    vn, ve = _velocity_ne(track_deg, np.array([ground_speed_mps]))
    return float(steady_power_w(vehicle, conditions, vn, ve)[0] / ground_speed_mps)


def optimal_speed(
    vehicle: RouteVehicle,
    conditions: Conditions,
    track_deg: float,
    *,
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS,
    max_airspeed_mps: float = DEFAULT_MAX_AIRSPEED_MPS,
    along_track: bool = False,
) -> SpeedChoice:
    """The ground speed along ``track_deg`` with the least energy per metre over ground, with
    ground speed in [:data:`MIN_GROUND_SPEED_MPS`, max_ground_speed_mps] and airspeed at most
    ``max_airspeed_mps`` (its component along the track when ``along_track``, see
    :func:`reachable_ground_speed_mps`); in still air this is the model's V_mr.
    InfeasibleTrack when no ground speed in range keeps the airspeed within its limit."""
    wn, we = conditions.wind_ne_mps()
    un, ue = math.cos(math.radians(track_deg)), math.sin(math.radians(track_deg))

    def airspeed(vg: FloatArray) -> FloatArray:
        return np.asarray(np.hypot(vg * un - wn, vg * ue - we), dtype=float)

    def within(vg: FloatArray) -> FloatArray:
        limited = vg - (wn * un + we * ue) if along_track else airspeed(vg)
        return np.asarray(limited <= max_airspeed_mps)

    def cost(vg: FloatArray) -> FloatArray:
        vn, ve = _velocity_ne(track_deg, vg)
        per_m = steady_power_w(vehicle, conditions, vn, ve) / vg
        return np.asarray(np.where(within(vg), per_m, _OUT_OF_RANGE))

    lo, hi = MIN_GROUND_SPEED_MPS, max(max_ground_speed_mps, MIN_GROUND_SPEED_MPS)
    grid = np.linspace(lo, hi, 601)
    if not np.any(within(grid)):
        raise InfeasibleTrack(
            f"a {conditions.wind_speed_mps:g} m/s wind from {conditions.wind_from_deg:g}° allows "
            f"no ground speed along {track_deg:.0f}° within {max_airspeed_mps:g} m/s airspeed"
        )
    vg = argmin_on_grid(cost, lo, hi)
    per_m = float(cost(np.array([vg]))[0])
    return SpeedChoice(track_deg, vg, float(airspeed(np.array([vg]))[0]), per_m * vg, per_m)


# -- segments ------------------------------------------------------------------------------------


def reachable_ground_speed_mps(
    conditions: Conditions, track_deg: float, max_airspeed_mps: float, along_track: bool = False
) -> float:
    """The fastest ground speed along ``track_deg`` at ``max_airspeed_mps`` in the wind (m/s;
    0 when the wind allows no headway). ``along_track``: the limit holds for the airspeed's
    component along the track only (a multicopter facing its track whose limit is forward
    drag, as ArduCopter SITL's quad), so a crosswind costs no ground speed."""
    wn, we = conditions.wind_ne_mps()
    un, ue = math.cos(math.radians(track_deg)), math.sin(math.radians(track_deg))
    along, across = wn * un + we * ue, -wn * ue + we * un
    if along_track:
        return max(along + max_airspeed_mps, 0.0)
    if abs(across) >= max_airspeed_mps:
        return 0.0
    return max(along + math.sqrt(max_airspeed_mps**2 - across**2), 0.0)


@dataclass(frozen=True)
class Kinematics:
    """How the autopilot changes speed: horizontal ``accel_mps2`` (m/s²) with ``jerk_mps3``
    (m/s³; None: no jerk limit), vertical ``vertical_accel_mps2`` (m/s²; None: at once) with
    ``vertical_jerk_mps3`` (m/s³; None: none, ArduCopter's model; PX4's MPC_JERK_AUTO limits
    every axis). A speed change of Δv takes Δv/a + a/j when Δv ≥ a²/j, else 2 sqrt(Δv/j) (a
    jerk-limited S-curve), and is flown at the mean speed with the mean acceleration (so eq.
    (2)'s kinetic term and the file's ``acceleration`` effect count the kinetic energy gained
    and lost)."""

    accel_mps2: float
    jerk_mps3: float | None = None
    vertical_accel_mps2: float | None = None
    vertical_jerk_mps3: float | None = None

    def ramp_s(self, dv_mps: float, vertical: bool = False) -> float:
        """Time (s) to change speed by ``dv_mps``."""
        dv = abs(dv_mps)
        accel, jerk = self.accel_mps2, self.jerk_mps3
        if vertical:
            accel, jerk = self.vertical_accel_mps2 or 0.0, self.vertical_jerk_mps3
            if not accel:
                return 0.0
        if jerk is None or jerk <= 0:
            return dv / accel
        if dv >= accel**2 / jerk:
            return dv / accel + accel / jerk
        return 2.0 * math.sqrt(dv / jerk)


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
    kinematics: Kinematics | None = None,
    start_speed_mps: float = 0.0,
    end_speed_mps: float = 0.0,
    along_track: bool = False,
) -> RouteEnergy:
    """A straight leg of ``distance_m`` over ground along ``track_deg`` while changing height by
    ``climb_m`` (m, + up), at ``ground_speed_mps`` (None: :func:`optimal_speed`), never faster
    than ``max_airspeed_mps`` allows in the wind.

    Horizontal and vertical motion run together, as a multicopter's waypoint controller flies a
    sloped leg: the leg takes the longer of the horizontal and the vertical time (``climb_rate_mps``
    up, ``descent_rate_mps`` down; the horizontal speed is lowered to match). Without
    ``kinematics`` the whole leg is flown at one speed; with it the leg speeds up from
    ``start_speed_mps`` and slows to ``end_speed_mps`` (m/s: 0 to stop at its end, more to
    round a corner), the cruise speed lowered when the leg is too short to reach it.
    ``along_track``: the airspeed limit holds along the track (:func:`reachable_ground_speed_mps`).
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
            along_track=along_track,
        ).ground_speed_mps
    if ground_speed_mps <= 0:
        raise ValueError("ground speed must be > 0")
    rate_mps = climb_rate_mps if climb_m >= 0 else descent_rate_mps
    if rate_mps <= 0:
        raise ValueError("vertical rates must be > 0")
    if distance_m > 0:
        reachable = reachable_ground_speed_mps(conditions, track_deg, max_airspeed_mps, along_track)
        if reachable <= 0:
            raise InfeasibleTrack(
                f"a {conditions.wind_speed_mps:g} m/s wind from {conditions.wind_from_deg:g}° "
                f"allows no headway along {track_deg:.0f}° within {max_airspeed_mps:g} m/s airspeed"
            )
        ground_speed_mps = min(ground_speed_mps, reachable)
    vertical_s = abs(climb_m) / rate_mps
    if kinematics is not None and climb_m:
        vertical_s += kinematics.ramp_s(rate_mps, vertical=True)
    ends = (min(start_speed_mps, ground_speed_mps), min(end_speed_mps, ground_speed_mps))
    cruise = ground_speed_mps
    pieces = _profile(distance_m, cruise, ends, kinematics)
    if sum(d for _, _, d in pieces) < vertical_s:  # the climb sets the pace
        cruise = _speed_for_time(distance_m, vertical_s, ends, kinematics)
        pieces = _profile(distance_m, cruise, ends, kinematics)
    time_s = max(sum(d for _, _, d in pieces), vertical_s)
    if time_s <= 0:
        return _result(vehicle, conditions, "leg", [], 0.0, 0.0, 0.0)
    rad = math.radians(track_deg)
    vd = -climb_m / time_s
    phases = [
        _Phase(v * math.cos(rad), v * math.sin(rad), vd, d, a * math.cos(rad), a * math.sin(rad))
        for v, a, d in pieces
    ]
    if time_s > sum(ph.duration_s for ph in phases):  # waiting on the climb, in place
        phases.append(_Phase(0.0, 0.0, vd, time_s - sum(ph.duration_s for ph in phases)))
    return _result(vehicle, conditions, "leg", phases, distance_m, climb_m, cruise, track_deg)


def _profile(
    distance_m: float,
    cruise_mps: float,
    ends: tuple[float, float],
    kinematics: Kinematics | None,
) -> list[tuple[float, float, float]]:
    """(mean speed m/s, acceleration m/s², duration s) of the speed-up, cruise and slow-down
    of a leg; the cruise speed lowered (bisection) when the leg is too short for it."""
    if distance_m <= 0 or cruise_mps <= 0:
        return []
    if kinematics is None:
        return [(cruise_mps, 0.0, distance_m / cruise_mps)]

    def ramps(v: float) -> tuple[float, float, float, float]:
        t1, t3 = kinematics.ramp_s(v - ends[0]), kinematics.ramp_s(v - ends[1])
        return t1, t3, 0.5 * (v + ends[0]) * t1, 0.5 * (v + ends[1]) * t3

    v = cruise_mps
    t1, t3, d1, d3 = ramps(v)
    if d1 + d3 > distance_m:
        lo, hi = 0.0, v
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if sum(ramps(mid)[2:]) <= distance_m else (lo, mid)
        v = lo
        t1, t3, d1, d3 = ramps(v)
        scale = distance_m / (d1 + d3) if d1 + d3 > 0 else 0.0
        t1, t3, d1, d3 = t1 * scale, t3 * scale, d1 * scale, d3 * scale
    out = []
    if t1 > 0:
        out.append((d1 / t1, (v - ends[0]) / t1, t1))
    if distance_m - d1 - d3 > 0 and v > 0:
        out.append((v, 0.0, (distance_m - d1 - d3) / v))
    if t3 > 0:
        out.append((d3 / t3, (ends[1] - v) / t3, t3))
    return out


def _profile_s(
    distance_m: float, cruise_mps: float, ends: tuple[float, float], kin: Kinematics | None
) -> float:
    return sum(d for _, _, d in _profile(distance_m, cruise_mps, ends, kin))


def _speed_for_time(
    distance_m: float, time_s: float, ends: tuple[float, float], kin: Kinematics | None
) -> float:
    """The cruise speed (m/s) that flies the leg in ``time_s`` (bisection; time falls with
    speed)."""
    lo, hi = 1e-3, distance_m / max(time_s, 1e-9) * 4.0 + 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _profile_s(distance_m, mid, ends, kin) <= time_s else (mid, hi)
    return hi


def hover_energy(vehicle: RouteVehicle, conditions: Conditions, duration_s: float) -> RouteEnergy:
    """Holding position for ``duration_s`` (s): airspeed is the wind speed."""
    if duration_s < 0:
        raise ValueError("duration must be ≥ 0")
    return _result(vehicle, conditions, "hover", [_Phase(0.0, 0.0, 0.0, duration_s)], 0, 0, 0)


def vertical_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    climb_m: float,
    rate_mps: float,
    *,
    kinematics: Kinematics | None = None,
) -> RouteEnergy:
    """Climbing (``climb_m`` > 0) or descending in place at ``rate_mps`` (m/s, > 0); with
    ``kinematics``, from and to rest at its vertical acceleration."""
    if rate_mps <= 0:
        raise ValueError("vertical rate must be > 0")
    return _result(
        vehicle,
        conditions,
        "vertical",
        _vertical_phases(climb_m, rate_mps, kinematics),
        0.0,
        climb_m,
        0.0,
    )


def _vertical_phases(climb_m: float, rate_mps: float, kin: Kinematics | None) -> list[_Phase]:
    """A vertical move as (speed-up, steady, slow-down) phases at their mean rates; the
    rate lowered when the move is too short to reach it."""
    if climb_m == 0:
        return []
    sign = -1.0 if climb_m > 0 else 1.0  # NED: climbing is negative down-velocity
    height = abs(climb_m)
    ramp = kin.ramp_s(rate_mps, vertical=True) if kin is not None else 0.0
    if ramp <= 0:
        return [_Phase(0.0, 0.0, sign * rate_mps, height / rate_mps)]
    accel = rate_mps / ramp
    rate = min(rate_mps, math.sqrt(height * accel))  # triangular when too short
    ramp = rate / accel
    steady_m = height - rate * ramp
    phases = [_Phase(0.0, 0.0, sign * rate / 2, ramp), _Phase(0.0, 0.0, sign * rate / 2, ramp)]
    if steady_m > 0:
        phases.insert(1, _Phase(0.0, 0.0, sign * rate, steady_m / rate))
    return phases


def landing_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    height_m: float,
    descent_rate_mps: float,
    *,
    final_height_m: float = 0.0,
    final_rate_mps: float | None = None,
    blend_height_m: float | None = None,
    touchdown_s: float = 0.0,
    kinematics: Kinematics | None = None,
) -> RouteEnergy:
    """Landing from ``height_m`` (m above the ground): down to ``final_height_m`` at
    ``descent_rate_mps``, the rest at ``final_rate_mps`` (m/s; None: the same rate), then
    ``touchdown_s`` (s) at hover power until the motors stop (ArduCopter's LAND: WPNAV_SPEED_DN
    above LAND_ALT_LOW, then LAND_SPEED); with ``blend_height_m`` (m, above
    ``final_height_m``), the rate goes linearly with height from the first to the final
    between the two heights (PX4's MPC_LAND_ALT1 / MPC_LAND_ALT2); with ``kinematics``, the
    first descent starts from rest at its vertical acceleration."""
    if height_m < 0 or descent_rate_mps <= 0:
        raise ValueError("landing needs a height ≥ 0 and a descent rate > 0")
    slow_rate = descent_rate_mps if final_rate_mps is None else final_rate_mps
    if slow_rate <= 0:
        raise ValueError("final descent rate must be > 0")
    top_m = final_height_m if blend_height_m is None else max(blend_height_m, final_height_m)
    fast_m = max(height_m - top_m, 0.0)
    blend_m = max(min(height_m, top_m) - final_height_m, 0.0)
    ramp_s = kinematics.ramp_s(descent_rate_mps, vertical=True) if kinematics else 0.0
    ramp_s = min(ramp_s, 2.0 * fast_m / descent_rate_mps)  # starting from rest
    phases = [
        _Phase(0.0, 0.0, descent_rate_mps / 2, ramp_s),
        _Phase(
            0.0, 0.0, descent_rate_mps, (fast_m - descent_rate_mps * ramp_s / 2) / descent_rate_mps
        ),
        _blend_phase(blend_m, top_m - final_height_m, descent_rate_mps, slow_rate),
        _Phase(0.0, 0.0, slow_rate, (height_m - fast_m - blend_m) / slow_rate),
        _Phase(0.0, 0.0, 0.0, max(touchdown_s, 0.0)),
    ]
    return _result(vehicle, conditions, "landing", phases, 0.0, -height_m, 0.0)


def _blend_phase(height_m: float, span_m: float, top_rate: float, low_rate: float) -> _Phase:
    """The last ``height_m`` of a ``span_m`` over which the descent rate goes linearly with
    height from ``top_rate`` (at its top) to ``low_rate`` (at its bottom), as one phase at its
    mean rate: at rate v(h) = low + k·h, the time is ln(v(height)/low)/k."""
    if height_m <= 0:
        return _Phase(0.0, 0.0, 0.0, 0.0)
    slope = (top_rate - low_rate) / span_m
    if abs(slope) < 1e-9:
        return _Phase(0.0, 0.0, low_rate, height_m / low_rate)
    time_s = math.log((low_rate + slope * height_m) / low_rate) / slope
    return _Phase(0.0, 0.0, height_m / time_s, time_s)


def _result(
    vehicle: RouteVehicle,
    conditions: Conditions,
    kind: str,
    phases: Sequence[_Phase],
    distance_m: float,
    climb_m: float,
    ground_speed_mps: float,
    track_deg: float = 0.0,
) -> RouteEnergy:
    """A segment's energy, time and sensitivities from its phases; ``ground_speed_mps`` along
    ``track_deg`` is its cruise (for the airspeed)."""
    phases = [ph for ph in phases if ph.duration_s > 0]
    time_s = sum(ph.duration_s for ph in phases)
    if phases:
        energy_wh, sens = _energy_with_sensitivity(vehicle, conditions, phases)
    else:
        energy_wh, sens = 0.0, (0.0,) * len(UNCERTAINTY_SOURCES)
    rad = math.radians(track_deg)
    wn, we = conditions.wind_ne_mps()
    return RouteEnergy(
        kind=kind,
        distance_m=distance_m,
        climb_m=climb_m,
        time_s=time_s,
        ground_speed_mps=ground_speed_mps,
        airspeed_mps=math.hypot(
            ground_speed_mps * math.cos(rad) - wn, ground_speed_mps * math.sin(rad) - we
        ),
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
    # per source, in segment order (as numpy's sum over the first axis adds)
    sens = tuple(map(sum, zip(*(s.sensitivity_wh for s in items), strict=True)))
    return RouteEnergy(
        kind="sum",
        distance_m=sum(s.distance_m for s in items),
        climb_m=sum(s.climb_m for s in items),
        time_s=time_s,
        ground_speed_mps=0.0,
        airspeed_mps=0.0,
        power_w=energy_wh * _J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=sens if items else (0.0,) * len(UNCERTAINTY_SOURCES),
    )
