"""Power effects the base model lacks, and the one function that predicts power from state.

:func:`predict_power_w` is the single place where electrical power is predicted from a flight
state: the pipeline, the residual tool and the simulator's hidden truth all call it. It works
on whole arrays (vectorized numpy) in this order:

1. *frame* effects change what the model sees: ``wind`` turns ground velocity into air
   velocity, ``mass`` and ``air_density`` rescale the model (Zeng et al.'s W and ρ laws,
   :meth:`PowerModel.rescaled`);
2. eq. (2) of the seed paper at horizontal airspeed V with centripetal acceleration a⊥ (both
   in the air-mass frame), plus the kinetic term m vᵀa;
3. *propulsion* effects add power the rotors need: ``climb``, ``heave``, ``acceleration``,
   ``turn``;
4. *electrical* effects act at the battery: ``voltage`` (wiring/ESC losses that grow as the
   pack sags), ``avionics`` (a constant or stepped load).

Each effect is a frozen dataclass whose fields are its parameters (names are part of the
output format, see ``docs/sim.md``). ``at_s``/``until_s`` parameters bound the time window in
which an effect acts, on the flight's own clock (the ``time_s`` of the :class:`FlightState`):
from ``at_s`` (``None``: from the start) until ``until_s`` (``None``: to the end). A wind that
starts, a payload released in flight, a load switched off are such windows.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from estimator.physics.axial import axial_induced_power_ratio
from estimator.physics.kinematics import centripetal_accel_mps2
from estimator.physics.model import (
    G_MPS2,
    SEA_LEVEL_DENSITY_KGPM3,
    Coefficients,
    FloatArray,
    PowerModel,
    hover_induced_velocity_mps,
    induced_power_w,
    level_power_w,
)


def _arr(x: ArrayLike) -> FloatArray:
    return np.asarray(x, dtype=float)


@dataclass(frozen=True)
class FlightState:
    """Flight state over time, all arrays of the same length.

    time_s: flight clock (autopilot time), s.  vn/ve/vd_mps: velocity over ground, NED, m/s.
    an/ae_mps2: horizontal acceleration over ground, NED, m/s².  alt_m: altitude above home, m.
    voltage_v: battery terminal voltage, V (NaN where unknown; only ``voltage`` uses it).
    ad_mps2: vertical acceleration, NED (down positive), m/s² (None: zero; only ``heave`` uses
    it).
    """

    time_s: FloatArray
    vn_mps: FloatArray
    ve_mps: FloatArray
    vd_mps: FloatArray
    an_mps2: FloatArray
    ae_mps2: FloatArray
    alt_m: FloatArray
    voltage_v: FloatArray
    ad_mps2: FloatArray | None = None

    def __post_init__(self) -> None:
        n = len(self.time_s)
        if self.ad_mps2 is None:
            object.__setattr__(self, "ad_mps2", np.zeros(n))
        for name in _FLIGHT_STATE_FIELDS:
            value = _arr(getattr(self, name))
            if value.shape != (n,):
                raise ValueError(f"FlightState.{name} has shape {value.shape}, expected ({n},)")
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return len(self.time_s)

    @classmethod
    def of_columns(cls, columns: FloatArray) -> FlightState:
        """A state from a 9 × n float array whose rows are the fields in their order
        (``ad_mps2`` last), taken as they are: the checks of the constructor are the
        caller's (the pipeline builds the array, once per prediction)."""
        state = object.__new__(cls)
        for name, column in zip(_FLIGHT_STATE_FIELDS, columns, strict=True):
            object.__setattr__(state, name, column)
        return state

    @classmethod
    def from_velocity(
        cls,
        time_s: ArrayLike,
        vn_mps: ArrayLike,
        ve_mps: ArrayLike,
        vd_mps: ArrayLike,
        alt_m: ArrayLike | None = None,
        voltage_v: ArrayLike | None = None,
    ) -> FlightState:
        """State from sampled velocity; acceleration by central differences (np.gradient).

        Needs at least two samples with strictly increasing times. Smooth noisy velocity
        first if the accelerations matter.
        """
        t = _arr(time_s)
        vn, ve = _arr(vn_mps), _arr(ve_mps)
        nan = np.full(t.shape, np.nan)
        return cls(
            time_s=t,
            vn_mps=vn,
            ve_mps=ve,
            vd_mps=_arr(vd_mps),
            an_mps2=np.gradient(vn, t),
            ae_mps2=np.gradient(ve, t),
            alt_m=nan if alt_m is None else _arr(alt_m),
            voltage_v=nan if voltage_v is None else _arr(voltage_v),
            ad_mps2=np.gradient(_arr(vd_mps), t),
        )


_FLIGHT_STATE_FIELDS = tuple(f.name for f in fields(FlightState))


@dataclass
class PowerContext:
    """Intermediate quantities of one prediction, shared by the effects (arrays per sample).

    air_vn/air_ve_mps: horizontal velocity relative to the air, NED, m/s.
    mass_kg: actual mass. mass_ratio: mass over the vehicle file's (both one float for every
    sample until a mass effect makes them arrays). density_ratio: ρ / ρ₀.
    coefficients: the model's c1..c5 at that mass and density (:meth:`PowerModel.scaled`).
    speed_mps, accel_centripetal_mps2: airspeed V and a⊥ used by eq. (2).
    propulsion_w: power the rotors draw so far (eq. (2) + kinetic + propulsion effects), W.
    """

    state: FlightState
    air_vn_mps: FloatArray
    air_ve_mps: FloatArray
    mass_kg: FloatArray | float
    mass_ratio: FloatArray | float
    density_ratio: float = 1.0
    coefficients: Coefficients | None = None
    speed_mps: FloatArray | None = None
    accel_centripetal_mps2: FloatArray | None = None
    hover_induced_velocity_mps: FloatArray | None = None
    propulsion_w: FloatArray | None = None


def active(time_s: FloatArray, at_s: float | None, until_s: float | None) -> FloatArray | float:
    """1 where ``at_s`` ≤ t < ``until_s`` (None: unbounded on that side), else 0; the scalar
    1.0 when unbounded on both sides (every sample: no array to build)."""
    if at_s is None and until_s is None:
        return 1.0
    on = np.ones_like(time_s, dtype=float)
    if at_s is not None:
        on *= time_s >= at_s
    if until_s is not None:
        on *= time_s < until_s
    return on


@dataclass(frozen=True)
class Effect:
    """Base class: a named term with a few physical parameters (the dataclass fields)."""

    name: ClassVar[str] = ""
    #: Plausible range of each continuous parameter, for fitters (inclusive).
    bounds: ClassVar[dict[str, tuple[float, float]]] = {}

    @property
    def params(self) -> dict[str, Any]:
        return asdict(self)

    def with_params(self, **params: Any) -> Effect:
        return replace(self, **params)

    def adjust(self, ctx: PowerContext) -> None:
        """Frame stage: change what the model sees (airspeed, mass, density)."""

    def propulsion_w(self, ctx: PowerContext) -> FloatArray | None:
        """Propulsion stage: extra rotor power, W (None = nothing)."""
        return None

    def electrical_w(self, ctx: PowerContext) -> FloatArray | None:
        """Electrical stage: extra battery power, W (None = nothing)."""
        return None


@dataclass(frozen=True)
class Wind(Effect):
    """Steady horizontal wind. The model's airspeed is ground velocity minus the wind vector.

    speed_mps: wind speed, m/s. from_deg: direction the wind blows FROM, degrees clockwise from
    north (0 = a north wind, blowing towards the south). It blows from ``at_s`` until
    ``until_s`` (s, flight clock; None: from the start / to the end).
    """

    name: ClassVar[str] = "wind"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "speed_mps": (0.0, 20.0),
        "from_deg": (0.0, 360.0),
    }
    speed_mps: float = 0.0
    from_deg: float = 0.0
    at_s: float | None = None
    until_s: float | None = None

    def vector_ne_mps(self) -> tuple[float, float]:
        """Air-mass velocity over ground (north, east), m/s."""
        return self._vector_ne_mps

    @cached_property
    def _vector_ne_mps(self) -> tuple[float, float]:
        wn, we = wind_vector_ne_mps(self.speed_mps, self.from_deg)
        return float(wn), float(we)

    def adjust(self, ctx: PowerContext) -> None:
        wn, we = self.vector_ne_mps()
        on = active(ctx.state.time_s, self.at_s, self.until_s)
        ctx.air_vn_mps = ctx.air_vn_mps - wn * on
        ctx.air_ve_mps = ctx.air_ve_mps - we * on


def wind_vector_ne_mps(speed_mps: ArrayLike, from_deg: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Air-mass velocity over ground (north, east), m/s, of a wind of ``speed_mps`` blowing
    from ``from_deg`` (degrees clockwise from north): it moves the opposite way."""
    rad = np.radians(from_deg)
    return -_arr(speed_mps) * np.cos(rad), -_arr(speed_mps) * np.sin(rad)


def wind_from_deg(wn_mps: ArrayLike, we_mps: ArrayLike) -> FloatArray:
    """Where a wind whose air mass moves over ground at (north, east) m/s blows from, degrees
    clockwise from north in [0, 360)."""
    return np.asarray(np.degrees(np.arctan2(-_arr(we_mps), -_arr(wn_mps))) % 360.0)


def wind_from_vector(wn_mps: float, we_mps: float) -> Wind:
    """The :class:`Wind` whose air mass moves over ground at (north, east) m/s."""
    speed = math.hypot(wn_mps, we_mps)
    from_deg = float(wind_from_deg(wn_mps, we_mps)) if speed > 0 else 0.0
    return Wind(speed_mps=speed, from_deg=from_deg)


@dataclass(frozen=True)
class ReportedWind(Effect):
    """A wind given as a time series: the autopilot's own estimate (ArduPilot WIND, PX4
    WIND_COV). The air mass moves over ground at ``scale`` × (``wind_n_mps``, ``wind_e_mps``)
    (NED, m/s), linear between the report times ``time_s`` (s, flight clock). ``scale``: the
    share of the reported wind the power shows (the autopilot's drag model is not the
    vehicle's).

    It blows from ``at_s`` until ``until_s`` (s, flight clock; None: from the start / to the
    end), calm outside: an estimate that holds its value after the wind stops (ArduCopter's
    EKF lets it decay over 20-55 s on SITL, docs/residuals.md) is the wind only inside the
    window.

    A recording of one flight, not a vehicle property: its parameter is ``scale`` (and the
    window); :meth:`steady` summarises the scaled report as steady winds, the form a vehicle
    file holds.
    """

    name: ClassVar[str] = "wind"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"scale": (0.0, 2.0)}
    #: A scaled report below this (m/s) is calm in the summary.
    CALM_MPS: ClassVar[float] = 1.0
    #: The summary splits the windy stretch in two where the two mean winds differ by at
    #: least this (m/s, vector difference), each part lasting at least ``MIN_PART_S`` and the
    #: first steady that long (reports within half of it of its mean: the estimate's ramp
    #: after an onset is not a wind of its own); the second starts after the last report
    #: within half of it of the first's mean (the estimate's decay after a stop is the second,
    #: so the first ends at the stop).
    CHANGE_MPS: ClassVar[float] = 2.0
    MIN_PART_S: ClassVar[float] = 20.0
    scale: float
    time_s: FloatArray = field(repr=False, compare=False)
    wind_n_mps: FloatArray = field(repr=False, compare=False)
    wind_e_mps: FloatArray = field(repr=False, compare=False)
    at_s: float | None = None
    until_s: float | None = None

    @property
    def params(self) -> dict[str, Any]:
        return {"scale": self.scale, "at_s": self.at_s, "until_s": self.until_s}

    def steady(self) -> tuple[Wind, ...]:
        """The scaled report as steady winds: over the stretch where it is above
        :attr:`CALM_MPS` inside the window (open at the recording's ends), one wind, or two
        where it changed (the split that leaves the least variance). Each: median speed,
        direction of the mean vector."""
        on = active(self.time_s, self.at_s, self.until_s)
        n, e = self.scale * on * self.wind_n_mps, self.scale * on * self.wind_e_mps
        windy = np.flatnonzero(np.hypot(n, e) >= self.CALM_MPS)
        if not len(windy):
            return ()
        first, last = int(windy[0]), int(windy[-1]) + 1
        bounds = [first, *self._change(first, last), last]
        return tuple(
            self._wind(lo, hi, at_open=lo == 0, until_open=hi == len(n))
            for lo, hi in itertools.pairwise(bounds)
        )

    def _change(self, first: int, last: int) -> list[int]:
        """The index splitting rows [first, last) into two winds, if they differ enough."""
        n = self.scale * self.wind_n_mps[first:last]
        e = self.scale * self.wind_e_mps[first:last]
        t = self.time_s[first:last]
        k = np.arange(1, len(n))
        if not len(k):
            return []
        cn, ce = np.cumsum(n)[:-1], np.cumsum(e)[:-1]
        # between-part sum of squares (to maximise) of each split k: rows [0, k) and [k, m)
        m = len(n)
        gain = ((cn - k * n.mean()) ** 2 + (ce - k * e.mean()) ** 2) * m / (k * (m - k))
        long_enough = (t[k] - t[0] >= self.MIN_PART_S) & (t[-1] - t[k - 1] >= self.MIN_PART_S)
        if not long_enough.any():
            return []
        best = int(k[long_enough][np.argmax(gain[long_enough])])
        mean_n, mean_e = n[:best].mean(), e[:best].mean()
        if math.hypot(mean_n - n[best:].mean(), mean_e - e[best:].mean()) < self.CHANGE_MPS:
            return []
        near = np.hypot(n[:best] - mean_n, e[:best] - mean_e) <= self.CHANGE_MPS / 2
        if near.sum() * float(np.median(np.diff(t))) < self.MIN_PART_S:
            return []
        return [first + int(np.flatnonzero(near)[-1]) + 1]

    def _wind(self, lo: int, hi: int, at_open: bool, until_open: bool) -> Wind:
        n, e = self.scale * self.wind_n_mps[lo:hi], self.scale * self.wind_e_mps[lo:hi]
        return replace(
            wind_from_vector(float(np.mean(n)), float(np.mean(e))),
            speed_mps=float(np.median(np.hypot(n, e))),
            at_s=None if at_open else float(self.time_s[lo]),
            until_s=None if until_open else float(self.time_s[hi]),
        )

    def adjust(self, ctx: PowerContext) -> None:
        t = ctx.state.time_s
        gain = self.scale * active(t, self.at_s, self.until_s)
        ctx.air_vn_mps = ctx.air_vn_mps - gain * np.interp(t, self.time_s, self.wind_n_mps)
        ctx.air_ve_mps = ctx.air_ve_mps - gain * np.interp(t, self.time_s, self.wind_e_mps)


@dataclass(frozen=True)
class Mass(Effect):
    """Mass differs from the vehicle file's by ``delta_kg`` (kg) from ``at_s`` until ``until_s``
    (s; None: from take-off / to the end): a payload picked up, or carried and released.

    The model is rescaled by Zeng's laws (induced c3 ∝ W^{3/2}, c4 ∝ W); the kinetic and climb
    terms use the actual mass.
    """

    name: ClassVar[str] = "mass"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"delta_kg": (-2.0, 5.0)}
    delta_kg: float = 0.0
    at_s: float | None = None
    until_s: float | None = None

    def adjust(self, ctx: PowerContext) -> None:
        _add_mass(ctx, self.delta_kg * active(ctx.state.time_s, self.at_s, self.until_s))


@dataclass(frozen=True, eq=False)
class SampleMass(Effect):
    """A mass difference per sample, ``delta_kg`` (kg, one per row of the flight state): one
    prediction for many mass hypotheses (the online tracker's sigma points). Not a vehicle
    file effect."""

    delta_kg: FloatArray

    def adjust(self, ctx: PowerContext) -> None:
        _add_mass(ctx, self.delta_kg)


def _add_mass(ctx: PowerContext, delta_kg: FloatArray | float) -> None:
    """Add ``delta_kg`` (per sample, or one for every sample) to the mass and rescale the
    model's mass ratio."""
    base_kg = ctx.mass_kg / ctx.mass_ratio
    ctx.mass_kg = ctx.mass_kg + delta_kg
    if np.any(ctx.mass_kg <= 0):
        raise ValueError("mass effect makes the vehicle's mass ≤ 0")
    ctx.mass_ratio = ctx.mass_kg / base_kg


@dataclass(frozen=True)
class AirDensity(Effect):
    """Air density ``rho_kgpm3`` (kg/m³) instead of the model's reference, sea-level ISA 1.225.

    c1, c5 ∝ ρ; c3 ∝ ρ^{-1/2}; c4 ∝ 1/ρ.
    """

    name: ClassVar[str] = "air_density"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"rho_kgpm3": (0.6, 1.5)}
    rho_kgpm3: float = SEA_LEVEL_DENSITY_KGPM3

    def adjust(self, ctx: PowerContext) -> None:
        if self.rho_kgpm3 <= 0:
            raise ValueError("air density must be > 0")
        ctx.density_ratio *= self.rho_kgpm3 / SEA_LEVEL_DENSITY_KGPM3


@dataclass(frozen=True)
class Climb(Effect):
    """Axial flight (climb and descent), by momentum theory at the hover induced velocity
    v0 = sqrt(c4/2) (:mod:`estimator.physics.axial`, Leishman ch. 2).

    Rotor power changes by m g (v_c + v_i(v_c) − v0) / efficiency, with climb rate
    v_c = −v_d (m/s, up) and v_i the induced velocity of the climb branch
    v_i = −v_c/2 + sqrt(v_c²/4 + v0²) in climb (≈ m g v_c/2 extra for slow climbs,
    → m g (v_c − v0) for fast ones), of the vortex-ring bridge for descents slower than 2 v0
    and of the windmill branch beyond. Descent needs less power, and saves at most
    m g v0 / efficiency, hover's induced share (v_c + v_i is held ≥ 0: no power returns to
    the battery). efficiency
    (0..1]: electrical to rotor-work conversion (motor × ESC × rotor figure of merit); about
    m g v0 / c3 for a consistent model.
    """

    name: ClassVar[str] = "climb"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"efficiency": (0.2, 1.0)}
    efficiency: float = 0.6

    def propulsion_w(self, ctx: PowerContext) -> FloatArray:
        assert ctx.hover_induced_velocity_mps is not None
        v0 = ctx.hover_induced_velocity_mps
        ratio = axial_induced_power_ratio(-ctx.state.vd_mps, v0)
        return ctx.mass_kg * G_MPS2 * v0 * (ratio - 1.0) / self.efficiency


@dataclass(frozen=True)
class Heave(Effect):
    """The thrust of a vertical acceleration, which eq. (2)'s load factor leaves out.

    The rotors carry the weight and accelerate the vehicle (Newton in 3-D): thrust over weight
    n with n² = (1 + a_up/g)² + (a⊥/g)², a_up = −a_d the vertical acceleration (m/s², up
    positive, held ≥ −g: rotors do not pull down), where eq. (2) has n² = 1 + (a⊥/g)². The
    rotor power changes by ``gain`` × (P_i(n) − P_i(n₂)), P_i eq. (2)'s induced term
    (:meth:`PowerModel.induced_w`): gain 1 for eq. (2)'s rotor, whose profile power does not
    follow thrust; more where it does (ArduPilot SITL, whose current is linear in thrust:
    hover power / (1.5 × its induced share), as P_i ∝ n^1.5 near hover). A climb that starts
    costs more power for as long as it accelerates; one that stops, or a descent that starts,
    less.
    """

    name: ClassVar[str] = "heave"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"gain": (0.0, 3.0)}
    gain: float = 1.0

    def propulsion_w(self, ctx: PowerContext) -> FloatArray:
        assert ctx.speed_mps is not None and ctx.accel_centripetal_mps2 is not None
        assert ctx.state.ad_mps2 is not None and ctx.coefficients is not None
        turn2 = np.square(ctx.accel_centripetal_mps2 / G_MPS2)
        vertical = np.maximum(1.0 - ctx.state.ad_mps2 / G_MPS2, 0.0)
        coefficients, v = ctx.coefficients, ctx.speed_mps
        with_heave = induced_power_w(coefficients, v, vertical**2 + turn2)
        level = induced_power_w(coefficients, v, 1.0 + turn2)
        return self.gain * (with_heave - level)


@dataclass(frozen=True)
class Avionics(Effect):
    """A constant electrical load ``power_w`` (W; may be negative) switched on at ``at_s`` and
    off at ``until_s`` (s; None: on from the start / until the end).
    """

    name: ClassVar[str] = "avionics"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"power_w": (-100.0, 200.0)}
    power_w: float = 0.0
    at_s: float | None = None
    until_s: float | None = None

    def electrical_w(self, ctx: PowerContext) -> FloatArray:
        return _arr(self.power_w * active(ctx.state.time_s, self.at_s, self.until_s))


@dataclass(frozen=True)
class Voltage(Effect):
    """Resistive losses between the battery sensor and the motors that grow as the pack sags.

    At propulsion power P the current is P/V, so a series resistance ``resistance_ohm`` (Ω:
    wiring, connectors, ESC) loses R P²/V². The model already contains the loss at the
    reference voltage ``reference_v`` (V) it was fitted at, so the term is
    R P² (1/V² − 1/V_ref²): positive below V_ref, growing as the battery sags. Samples without
    a known voltage get no term.
    """

    name: ClassVar[str] = "voltage"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"resistance_ohm": (0.0, 1.0)}
    resistance_ohm: float = 0.0
    reference_v: float = 25.2

    def electrical_w(self, ctx: PowerContext) -> FloatArray:
        assert ctx.propulsion_w is not None
        v = ctx.state.voltage_v
        inv2 = np.where(np.isfinite(v) & (v > 0), 1.0 / np.square(v), 1.0 / self.reference_v**2)
        return self.resistance_ohm * np.square(ctx.propulsion_w) * (inv2 - self.reference_v**-2)


@dataclass(frozen=True)
class Acceleration(Effect):
    """Non-ideal speed changes: eq. (2) counts m vᵀa as exchanged with kinetic energy both ways.

    efficiency (0..1]: share of electrical power that becomes kinetic energy when speeding up
    (adds (1/efficiency − 1)·m vᵀa when vᵀa > 0). recovery (0..1): share of kinetic energy
    returned when slowing down (a multirotor brakes by tilting back, so little comes back;
    adds (1 − recovery)·m |vᵀa| when vᵀa < 0). Air-mass frame, like the kinetic term.
    """

    name: ClassVar[str] = "acceleration"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {
        "efficiency": (0.2, 1.0),
        "recovery": (0.0, 1.0),
    }
    efficiency: float = 1.0
    recovery: float = 1.0

    def propulsion_w(self, ctx: PowerContext) -> FloatArray:
        s = ctx.state
        kinetic_w = ctx.mass_kg * (ctx.air_vn_mps * s.an_mps2 + ctx.air_ve_mps * s.ae_mps2)
        gain = np.where(kinetic_w > 0, 1.0 / self.efficiency - 1.0, self.recovery - 1.0)
        return np.asarray(gain * kinetic_w, dtype=float)


@dataclass(frozen=True)
class Turn(Effect):
    """Extra power in turns beyond eq. (2)'s load factor (attitude and yaw control, rotor
    inflow asymmetry): ``power_w_per_g2`` (W) × (a⊥/g)².
    """

    name: ClassVar[str] = "turn"
    bounds: ClassVar[dict[str, tuple[float, float]]] = {"power_w_per_g2": (-500.0, 2000.0)}
    power_w_per_g2: float = 0.0

    def propulsion_w(self, ctx: PowerContext) -> FloatArray:
        assert ctx.accel_centripetal_mps2 is not None
        return self.power_w_per_g2 * np.square(ctx.accel_centripetal_mps2 / G_MPS2)


#: Every effect type by its name (the vehicle file's ``[effects.NAME]`` tables).
EFFECT_TYPES: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (Wind, Mass, AirDensity, Climb, Heave, Avionics, Voltage, Acceleration, Turn)
}


def predict_power_w(
    model: PowerModel, mass_kg: float, state: FlightState, effects: Sequence[Effect] = ()
) -> FloatArray:
    """Electrical power at the battery (W) for each sample of ``state``.

    ``model`` and ``mass_kg`` come from the vehicle file (the model is valid at that mass and
    sea-level density); ``effects`` are applied in the stage order of the module docstring.
    """
    return predict_context(model, mass_kg, state, effects)[1]


def predict_context(
    model: PowerModel, mass_kg: float, state: FlightState, effects: Sequence[Effect] = ()
) -> tuple[PowerContext, FloatArray]:
    """Like :func:`predict_power_w`, also returning the intermediate quantities."""
    ctx = PowerContext(
        state=state,
        air_vn_mps=state.vn_mps,
        air_ve_mps=state.ve_mps,
        mass_kg=float(mass_kg),
        mass_ratio=1.0,
    )
    for effect in effects:
        effect.adjust(ctx)
    ctx.speed_mps = np.hypot(ctx.air_vn_mps, ctx.air_ve_mps)
    ctx.accel_centripetal_mps2 = centripetal_accel_mps2(
        ctx.air_vn_mps, ctx.air_ve_mps, state.an_mps2, state.ae_mps2
    )
    ctx.coefficients = model.scaled(ctx.mass_ratio, ctx.density_ratio)
    power_w = level_power_w(ctx.coefficients, ctx.speed_mps, ctx.accel_centripetal_mps2)
    ctx.hover_induced_velocity_mps = hover_induced_velocity_mps(ctx.coefficients)
    power_w += ctx.mass_kg * (ctx.air_vn_mps * state.an_mps2 + ctx.air_ve_mps * state.ae_mps2)
    for effect in effects:
        extra = effect.propulsion_w(ctx)
        if extra is not None:
            power_w = power_w + extra
    ctx.propulsion_w = power_w
    total_w = power_w.copy()
    for effect in effects:
        extra = effect.electrical_w(ctx)
        if extra is not None:
            total_w += extra
    return ctx, total_w
