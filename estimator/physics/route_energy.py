"""Energy and time of flying a route: straight legs, hovers, vertical moves, landings.

Pure functions of a :class:`RouteVehicle` (the vehicle file's power model, mass and effects) and
:class:`Conditions` (wind, payload and their uncertainty). Power comes from the project's one
prediction, :func:`~estimator.physics.effects.predict_power_w`, piecewise: each phase of a
segment at one velocity with its mean acceleration (steady, unless
:class:`~estimator.physics.route_segments.Kinematics` adds the speed changes).

Conventions: positions and velocities NED (north, east, down), horizontal tracks in degrees
clockwise from north; the wind follows :class:`~estimator.physics.effects.Wind`: ``speed_mps``
and ``from_deg``, the direction it blows **from** (0 = a north wind, blowing south).
Ground speeds are over ground (what an autopilot's waypoint speed sets), airspeeds relative to
the air mass. Energies are electrical, at the battery, Wh.

The segments (legs, hovers, vertical moves, landings, their sum) are
:mod:`estimator.physics.route_segments`; this module holds what they rest on: the vehicle and
the conditions, a segment's result, the steady power and the energy of a segment's phases with
its sensitivities, and the wind-optimal speed.

Climbs and descents: the vehicle file's ``[effects.climb]`` when it has one; otherwise the same
momentum-theory term with its consistency efficiency m g v0 / c3 capped at 1 (see
:class:`~estimator.physics.effects.Climb`): about m g v_c / 2 extra for slow climbs, less power
in descent. Effects of the vehicle file with a time window are taken as they are at the
flight's start (time 0); the file's wind is replaced by the conditions' wind.

Uncertainty (1σ, first order): each result carries ``sensitivity_wh``, the signed change of its
energy for a 1σ change of each independent source in :data:`UNCERTAINTY_SOURCES` — the model's
coefficients (the vehicle file's ``[model.stderr]``, taken as independent: the file has no
covariance, so σ is conservative where c1 and c3 anticorrelate), each horizontal wind component
and the payload. Summing sensitivities over segments
(:func:`~estimator.physics.route_segments.sum_energies`) keeps the sources' correlation along a
route; ``energy_sigma_wh`` is their root sum of squares. Speeds chosen as wind-optimal are held
at the nominal choice (a commanded speed) when propagating.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from typing import NamedTuple

import numpy as np

from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import (
    Climb,
    Effect,
    FlightState,
    Mass,
    SampleMass,
    Wind,
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
J_PER_WH = 3600.0
#: Energy per metre (J/m) standing for "beyond the airspeed limit" in the speed search.
_OUT_OF_RANGE = 1e12
#: Phase states whose powers a :class:`RouteVehicle` keeps per set of hypotheses, and sets of
#: hypotheses it keeps (each starts over when full).
_PHASE_POWERS_SIZE = 4096
_HYPOTHESES_KEPT = 8
#: A new set of hypotheses predicts, with its first missing states, the states of the set
#: before it when that held at most this many (:func:`_energies_wh`).
_CARRIED_STATES = 64


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
    """Energy and time of one segment (or a sum of segments,
    :func:`~estimator.physics.route_segments.sum_energies`).

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
    broadcast to one length (scalars and 1-D arrays); no time, altitude or voltage (steady
    flight anywhere). One 9 × n array, copied from the inputs (the prediction may not share
    the caller's arrays), without the constructor's checks (the shape is made here)."""
    given = (vn_mps, ve_mps, vd_mps, an_mps2, ae_mps2)
    shapes = [np.shape(x) for x in given]
    if any(len(shape) > 1 for shape in shapes):
        raise ValueError(f"steady states are scalars or 1-D arrays, got the shapes {shapes}")
    columns = np.empty((9, max((shape[0] for shape in shapes if shape), default=1)))
    columns[0] = columns[8] = 0.0
    for row, x in enumerate(given, start=1):
        columns[row] = x
    columns[6:8] = np.nan
    return FlightState.of_columns(columns)


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
class Phase:
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
    vehicle: RouteVehicle, phases: Sequence[Phase], hypotheses: Sequence[_Hypothesis]
) -> list[float]:
    """Energy (Wh) of ``phases`` under each hypothesis. The powers of phase states not yet in
    the vehicle's :attr:`~RouteVehicle.phase_powers_w` come from one prediction over those
    states × hypotheses: the wind taken out of the ground velocity (what :class:`Wind` does),
    the payload as a per-row :class:`SampleMass` (what :class:`Mass` does). A new set of
    hypotheses (a live return's wind or payload moved) predicts in that call the states of the
    set before it too (up to :data:`_CARRIED_STATES`): the return's next segments ask them
    again, and each row's power is the same whichever rows it is predicted with."""
    tables = vehicle.phase_powers_w
    key = tuple(hypotheses)
    table = tables.get(key)
    carried: list[_PhaseState] = []
    if table is None or len(table) >= _PHASE_POWERS_SIZE:
        before = next(reversed(tables.values()), {}) if table is None else {}
        if len(before) <= _CARRIED_STATES:
            carried = list(before)
        if len(tables) >= _HYPOTHESES_KEPT:
            tables.clear()
        table = tables[key] = {}
    states = [ph.state for ph in phases]
    missing = list(dict.fromkeys(s for s in states if s not in table))
    if missing:
        missing = list(dict.fromkeys([*missing, *carried]))
        m, n = len(hypotheses), len(missing)
        pairs = [(hyp, s) for hyp in hypotheses for s in missing]  # hypothesis-major
        state = _steady_state(
            np.array([s.vn_mps - hyp.wind_n_mps for hyp, s in pairs]),
            np.array([s.ve_mps - hyp.wind_e_mps for hyp, s in pairs]),
            np.array([s.vd_mps for _, s in pairs]),
            np.array([s.an_mps2 for _, s in pairs]),
            np.array([s.ae_mps2 for _, s in pairs]),
        )
        effects = (*vehicle.effects, SampleMass(np.array([hyp.payload_kg for hyp, _ in pairs])))
        power_w = predict_power_w(vehicle.model, vehicle.mass_kg, state, effects).reshape(m, n)
        for s, powers in zip(missing, power_w.T.tolist(), strict=True):
            table[s] = tuple(powers)
    rows = [(table[s], ph.duration_s) for s, ph in zip(states, phases, strict=True)]
    return [sum(p[i] * d for p, d in rows) / J_PER_WH for i in range(len(hypotheses))]


def energy_with_sensitivity(
    vehicle: RouteVehicle, conditions: Conditions, phases: Sequence[Phase]
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
    :func:`~estimator.physics.route_segments.reachable_ground_speed_mps`); in still air this is
    the model's V_mr. InfeasibleTrack when no ground speed in range keeps the airspeed within
    its limit."""
    search = _SpeedSearch(vehicle, conditions, track_deg, max_airspeed_mps, along_track)
    vg = search.best_mps(max_ground_speed_mps)
    per_m = float(search.cost(np.array([vg]))[0])
    return SpeedChoice(track_deg, vg, float(search.airspeed(np.array([vg]))[0]), per_m * vg, per_m)


def optimal_ground_speed_mps(
    vehicle: RouteVehicle,
    conditions: Conditions,
    track_deg: float,
    *,
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS,
    max_airspeed_mps: float = DEFAULT_MAX_AIRSPEED_MPS,
    along_track: bool = False,
) -> float:
    """:func:`optimal_speed`'s ground speed (m/s) alone, without the power and airspeed at it
    (one prediction fewer: the live return needs only the speed)."""
    search = _SpeedSearch(vehicle, conditions, track_deg, max_airspeed_mps, along_track)
    return search.best_mps(max_ground_speed_mps)


@dataclass(frozen=True)
class _SpeedSearch:
    """The wind-optimal speed search along ``track_deg`` (:func:`optimal_speed`): airspeed
    (m/s), whether within the limit, and energy per metre over ground (J/m) at ground speeds
    (m/s)."""

    vehicle: RouteVehicle
    conditions: Conditions
    track_deg: float
    max_airspeed_mps: float
    along_track: bool

    def airspeed(self, vg: FloatArray) -> FloatArray:
        wn, we = self.conditions.wind_ne_mps()
        rad = math.radians(self.track_deg)
        un, ue = math.cos(rad), math.sin(rad)
        return np.asarray(np.hypot(vg * un - wn, vg * ue - we), dtype=float)

    def within(self, vg: FloatArray) -> FloatArray:
        if self.along_track:
            wn, we = self.conditions.wind_ne_mps()
            rad = math.radians(self.track_deg)
            limited = vg - (wn * math.cos(rad) + we * math.sin(rad))
        else:
            limited = self.airspeed(vg)
        return np.asarray(limited <= self.max_airspeed_mps)

    def cost(self, vg: FloatArray) -> FloatArray:
        vn, ve = _velocity_ne(self.track_deg, vg)
        per_m = steady_power_w(self.vehicle, self.conditions, vn, ve) / vg
        return np.asarray(np.where(self.within(vg), per_m, _OUT_OF_RANGE))

    def best_mps(self, max_ground_speed_mps: float) -> float:
        """The ground speed of least :meth:`cost` in [:data:`MIN_GROUND_SPEED_MPS`,
        ``max_ground_speed_mps``] (m/s); InfeasibleTrack when none is within the limit."""
        lo, hi = MIN_GROUND_SPEED_MPS, max(max_ground_speed_mps, MIN_GROUND_SPEED_MPS)
        if not np.any(self.within(np.linspace(lo, hi, 601))):
            c = self.conditions
            raise InfeasibleTrack(
                f"a {c.wind_speed_mps:g} m/s wind from {c.wind_from_deg:g}° allows no ground "
                f"speed along {self.track_deg:.0f}° within {self.max_airspeed_mps:g} m/s airspeed"
            )
        return argmin_on_grid(self.cost, lo, hi)
