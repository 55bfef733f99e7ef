"""The one pipeline: telemetry samples in, energy and endurance estimates out.

The daemon feeds it from a socket, replay from a file, tests from lists; time comes only from
the samples, so the same samples always give the same estimates. Per velocity sample:
kinematics (causal Kalman filter) → flight state → model power
(:func:`estimator.effects.predict_power_w`, the one place power is predicted) → energy filter
predict. Per battery sample: measured power, consumed charge and terminal voltage update the
fusion (:mod:`estimator.fusion`). A :class:`RebootSample` restarts the kinematics and moves
the clocks, keeping the energy state.

Endurance figures are at a *steady* power: level flight at the current horizontal speed (and
centripetal acceleration: a steady turn continues), without the transient kinetic and climb
terms, scaled by the fused bias.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, fields

import numpy as np

from estimator.battery import PackModel
from estimator.effects import Climb, Effect, FlightState, effects_from_tables, predict_power_w
from estimator.fusion import EnergyFilter, FusionSettings
from estimator.kinematics import KinematicsFilter, KinematicsSettings, KinematicState
from estimator.online_effects import OnlineEffects
from estimator.telemetry import ArmedSample, BatterySample, RebootSample, Sample, VelocitySample
from estimator.vehicle import Vehicle

#: Speeds (m/s) on which V_me and V_mr are searched, with the vehicle's effects applied.
_SPEED_GRID_MPS = np.linspace(0.0, 30.0, 601)
#: Tracked wind and mass replace the file's once the wind is known to this 1σ (m/s) and they
#: predict the measured power better (one step ahead) than the file's.
#: Before that (hover, one-direction flight) wind and mass trade off against each other and
#: the point estimate is biased by the curvature of P(V).
_TRACKED_WIND_SIGMA_MPS = 1.0
#: Gain of the moving averages that score tracked against vehicle-file effects (per reading).
_SCORE_GAIN = 1.0 / 30.0
#: Above this horizontal speed (m/s) the course over ground is the direction of flight.
_TRACK_MIN_SPEED_MPS = 1.0
#: How often (s, sample clock) V_me, V_mr and hover power follow the tracked wind and mass.
_SPEEDS_REFRESH_S = 5.0


@dataclass(frozen=True, slots=True)
class PipelineSettings:
    """battery_stale_s: estimates are ``stale`` when the newest battery sample is older than
    this on the sample clock.  add_climb_effect: add a default :class:`Climb` effect when the
    vehicle file has none (climbing costs m·g·v_c/η).  track_effects: follow wind and mass
    online from measured power (:class:`~estimator.online_effects.OnlineEffects`), starting
    from the vehicle file's values; off keeps those values for the whole flight."""

    kinematics: KinematicsSettings = field(default_factory=KinematicsSettings)
    fusion: FusionSettings = field(default_factory=FusionSettings)
    battery_stale_s: float = 5.0
    add_climb_effect: bool = True
    track_effects: bool = True


@dataclass(frozen=True, slots=True)
class Estimate:
    """One published estimate. Powers in W, energy in Wh, times in s, speeds m/s, range m.

    power_model_w: the model's power for the current flight state (before the bias).
    power_measured_w: latest V·I, None without a current sensor.
    endurance_s: time to the reserve if the current steady power continues (1σ alongside).
    hover_endurance_s / vme_endurance_s: the same when hovering / flying at V_me.
    range_vmr_m: distance over ground (no wind) at V_mr until the reserve.
    bias: measured over modelled power (1 = the model is right).
    model_only: no measured current fused (uncertainty is wider).
    *_sigma_*: 1σ of the quantity named before it (first-order propagation).
    stale: battery telemetry older than the configured limit (or, in the daemon, a silent
    link).
    """

    time_s: float
    speed_mps: float
    accel_tangential_mps2: float
    accel_centripetal_mps2: float
    climb_mps: float
    power_model_w: float
    power_measured_w: float | None
    energy_remaining_wh: float
    energy_remaining_sigma_wh: float
    endurance_s: float
    endurance_sigma_s: float
    hover_endurance_s: float
    vme_endurance_s: float
    v_me_mps: float
    range_vmr_m: float
    bias: float
    bias_sigma: float
    model_only: bool
    stale: bool
    soc: float = math.nan
    voltage_v: float = math.nan
    resistance_ohm: float = math.nan
    steady_power_w: float = math.nan
    hover_endurance_sigma_s: float = math.nan
    vme_endurance_sigma_s: float = math.nan
    range_vmr_sigma_m: float = math.nan

    def as_dict(self) -> dict[str, float | bool | None]:
        return {name: getattr(self, name) for name in _ESTIMATE_FIELDS}


_ESTIMATE_FIELDS = tuple(f.name for f in fields(Estimate))


class Pipeline:
    """Samples in (:meth:`process`), estimates out; ``counts`` says what it did and skipped."""

    def __init__(self, vehicle: Vehicle, settings: PipelineSettings | None = None) -> None:
        self.vehicle = vehicle
        self.settings = settings or PipelineSettings()
        effects: list[Effect] = effects_from_tables(vehicle.effects)
        if self.settings.add_climb_effect and not any(isinstance(e, Climb) for e in effects):
            effects.append(Climb())
        self.effects: tuple[Effect, ...] = tuple(effects)
        self.file_effects = self.effects
        # one-step-ahead squared power errors (W², moving averages) of the tracked effects and
        # of the vehicle file's: the tracked ones are used only while they predict better
        self._tracked_sq_w2 = 0.0
        self._file_sq_w2 = 0.0
        self.online = (
            OnlineEffects(vehicle.model, vehicle.mass_kg, self.effects)
            if self.settings.track_effects
            else None
        )
        self._speeds_time_s = -math.inf
        self._track_rad = 0.0  # course over ground, rad from north (last one while moving)
        self.pack = PackModel(vehicle.battery)
        self.kinematics = KinematicsFilter(self.settings.kinematics)
        self.energy = EnergyFilter(self.pack, self.settings.fusion)
        self.counts: Counter[str] = Counter()
        self.last: Estimate | None = None
        self._state: KinematicState | None = None
        self._armed: bool | None = None
        self._battery: BatterySample | None = None
        self._power_model_w = 0.0
        self._steady_power_w = 0.0
        self._time_s: float | None = None
        self._loss_factor = 1.0
        self._refresh_speeds()

    # -- power: every prediction goes through predict_power_w ----------------------------------

    def _predict(
        self,
        speed_mps: np.ndarray,
        accel_centripetal_mps2: float = 0.0,
        state: KinematicState | None = None,
        effects: tuple[Effect, ...] | None = None,
    ) -> np.ndarray:
        """Model power (W) for level flight at each horizontal speed along the current track
        (it matters in wind), steady turn with a⊥ as given; with ``state``, the first entry is
        that full state instead. ``effects`` default to the ones in use."""
        n = len(speed_mps)
        north, east = math.cos(self._track_rad), math.sin(self._track_rad)
        speed = np.array(speed_mps, dtype=float)
        vn, ve = speed * north, speed * east
        vd = np.zeros(n)
        an = np.full(n, -east * accel_centripetal_mps2)  # across the track: a⊥ only
        ae = np.full(n, north * accel_centripetal_mps2)
        t = np.zeros(n)
        voltage = np.full(n, np.nan if self._battery is None else self._battery.voltage_v)
        if state is not None:
            t[:] = state.time_s
            vn[0], ve[0], vd[0] = state.vn_mps, state.ve_mps, state.vd_mps
            an[0], ae[0] = state.an_mps2, state.ae_mps2
        flight = FlightState(t, vn, ve, vd, an, ae, np.zeros(n), voltage)
        if effects is None:
            effects = self.effects
        power = predict_power_w(self.vehicle.model, self.vehicle.mass_kg, flight, effects)
        return np.maximum(power, 0.0)

    def _refresh_speeds(self) -> None:
        """V_me, V_mr and their powers, and hover power, with the current effects."""
        power = self._predict(_SPEED_GRID_MPS)
        i_me = int(np.argmin(power))
        i_mr = int(np.argmin(power[1:] / _SPEED_GRID_MPS[1:])) + 1
        self.v_me_mps, self.v_mr_mps = float(_SPEED_GRID_MPS[i_me]), float(_SPEED_GRID_MPS[i_mr])
        self._p_me_w, self._p_mr_w = float(power[i_me]), float(power[i_mr])
        self._p_hover_w = float(power[0])

    def _update_power(self) -> None:
        state = self._state
        if self._armed is False:
            self._power_model_w = self._steady_power_w = 0.0
            return
        if state is None:
            self._power_model_w = self._steady_power_w = self._p_hover_w
            return
        if state.speed_mps > _TRACK_MIN_SPEED_MPS:
            self._track_rad = math.atan2(state.ve_mps, state.vn_mps)
        full, steady = self._predict(
            np.array([0.0, state.speed_mps]), state.accel_centripetal_mps2, state
        )
        self._power_model_w, self._steady_power_w = float(full), float(steady)

    def _kinetic_sigma_w(self) -> float:
        """1σ of the kinetic term m vᵀa from the filtered acceleration's uncertainty, W."""
        state = self._state
        if state is None:
            return 0.0
        return self.vehicle.mass_kg * state.speed_mps * state.accel_sigma_mps2

    # -- samples ------------------------------------------------------------------------------

    def process(self, sample: Sample) -> Estimate | None:
        """Fold in one sample; return the new estimate when the state advanced."""
        if isinstance(sample, VelocitySample):
            return self._velocity(sample)
        if isinstance(sample, BatterySample):
            return self._battery_sample(sample)
        if isinstance(sample, ArmedSample):
            self.counts["armed" if sample.armed else "disarmed"] += 1
            self._armed = sample.armed
            self._update_power()
            return None
        if isinstance(sample, RebootSample):
            self._reboot(sample)
            return None
        self.counts["unknown_sample"] += 1
        return None

    def _velocity(self, sample: VelocitySample) -> Estimate | None:
        self.counts["velocity"] += 1
        if self._time_s is not None and sample.time_s < self._time_s:
            self.counts["velocity_out_of_order"] += 1
            return None
        self._state = self.kinematics.update(sample)
        self._update_power()
        if not self.energy.initialized:
            self.counts["velocity_before_battery"] += 1
            return None
        self._advance(sample.time_s)
        return self._emit(sample.time_s)

    def _battery_sample(self, sample: BatterySample) -> Estimate | None:
        self.counts["battery"] += 1
        if not math.isfinite(sample.voltage_v) or sample.voltage_v <= 0:
            self.counts["battery_invalid"] += 1
            return None
        if not self.energy.initialized:
            self._battery = sample
            self._update_power()
            self.energy.initialize(sample, self._power_model_w)
            self._time_s = sample.time_s
            self.counts["energy_initialized"] += 1
            return None
        if self._time_s is not None and sample.time_s < self._time_s:
            self.counts["battery_out_of_order"] += 1
            return None
        previous = self._battery
        self._battery = sample
        self._advance(sample.time_s)
        measured_w = sample.power_w
        if measured_w is not None and self._armed is not False and self._power_model_w > 0:
            self.energy.update_power(measured_w, self._power_model_w, self._kinetic_sigma_w())
            self._track_effects(sample.time_s, measured_w, sample.voltage_v)
        if sample.consumed_mah is not None:
            self.energy.update_charge(sample.consumed_mah)
        current_a = sample.current_a
        if current_a is None:
            current_a = self.energy.bias * self._power_model_w / sample.voltage_v
        assert self.energy.voltage is not None
        dt = 0.0 if previous is None else max(sample.time_s - previous.time_s, 0.0)
        self.energy.voltage.update(dt, self.energy.soc, sample.voltage_v, current_a)
        self._loss_factor = self.energy.loss_factor(self.energy.bias * self._power_model_w)
        return self._emit(sample.time_s)

    def _track_effects(self, time_s: float, measured_w: float, voltage_v: float) -> None:
        """Follow wind and mass with this power reading (after the fusion step, so each
        reading is fused with the effects that predicted it)."""
        state = self._state
        if self.online is None or state is None:
            return
        # score both hypotheses on this reading before the tracker learns from it
        zero = np.zeros(1)
        tracked_w = float(self._predict(zero, 0.0, state, self.online.effects)[0])
        file_w = float(self._predict(zero, 0.0, state, self.file_effects)[0])
        self._tracked_sq_w2 += _SCORE_GAIN * ((measured_w - tracked_w) ** 2 - self._tracked_sq_w2)
        self._file_sq_w2 += _SCORE_GAIN * ((measured_w - file_w) ** 2 - self._file_sq_w2)
        tracked = self.online.update_kinematics(state, measured_w, voltage_v)
        sigma = self.online.sigma
        identified = max(sigma["wind_n_mps"], sigma["wind_e_mps"]) <= _TRACKED_WIND_SIGMA_MPS
        in_use = self.effects != self.file_effects
        if self._tracked_sq_w2 >= self._file_sq_w2:
            chosen = self.file_effects  # the tracker went astray: the file's model is better
        elif identified or in_use:
            chosen = tracked
        else:
            return  # not identified yet: keep the file's effects (the fusion bias absorbs it)
        if chosen == self.file_effects and not in_use:
            return
        self.counts["tracked_effects" if chosen is tracked else "file_effects"] += 1
        self.effects = chosen
        self._update_power()
        if time_s - self._speeds_time_s >= _SPEEDS_REFRESH_S:
            self._refresh_speeds()
            self._speeds_time_s = time_s

    def _reboot(self, sample: RebootSample) -> None:
        self.counts["reboot"] += 1
        self.kinematics.reset()
        self._state = None
        self._armed = None
        self._update_power()
        if self.energy.initialized:
            self.energy.rebase(sample.time_s)
        if self._time_s is not None:
            self._time_s = sample.time_s
        self._battery = None

    def _advance(self, time_s: float) -> None:
        """Predict the energy state up to ``time_s`` at the current model power (the pack's
        loss factor OCV/V is refreshed with each battery sample: it changes slowly)."""
        self.energy.predict(time_s, self._power_model_w, self._loss_factor)
        if self._steady_power_w > 0:
            self.energy.flight_state_changed(self._steady_power_w)
        self._time_s = time_s

    def _emit(self, time_s: float) -> Estimate:
        est = self.energy.estimate()
        state = self._state
        steady_w = est.bias * self._steady_power_w
        model_w = np.array([self._steady_power_w, self._p_hover_w, self._p_me_w, self._p_mr_w])
        times_s, sigmas_s = self.energy.endurance_s(est.bias * model_w, est)
        endurance_s, hover_s, vme_s, vmr_s = (float(x) for x in times_s)
        endurance_sigma_s, hover_sigma_s, vme_sigma_s, vmr_sigma_s = (float(x) for x in sigmas_s)
        battery = self._battery
        stale = battery is None or time_s - battery.time_s > self.settings.battery_stale_s
        voltage = self.energy.voltage
        estimate = Estimate(
            time_s=time_s,
            speed_mps=0.0 if state is None else state.speed_mps,
            accel_tangential_mps2=0.0 if state is None else state.accel_tangential_mps2,
            accel_centripetal_mps2=0.0 if state is None else state.accel_centripetal_mps2,
            climb_mps=0.0 if state is None else state.climb_mps,
            power_model_w=self._power_model_w,
            power_measured_w=None if battery is None else battery.power_w,
            energy_remaining_wh=est.energy_wh,
            energy_remaining_sigma_wh=est.energy_sigma_wh,
            endurance_s=endurance_s,
            endurance_sigma_s=endurance_sigma_s,
            hover_endurance_s=hover_s,
            vme_endurance_s=vme_s,
            v_me_mps=self.v_me_mps,
            range_vmr_m=self.v_mr_mps * vmr_s,
            bias=est.bias,
            bias_sigma=est.bias_sigma,
            model_only=self.energy.model_only,
            stale=stale,
            soc=self.energy.soc,
            voltage_v=math.nan if battery is None else battery.voltage_v,
            resistance_ohm=math.nan if voltage is None else voltage.resistance_ohm,
            steady_power_w=steady_w,
            hover_endurance_sigma_s=hover_sigma_s,
            vme_endurance_sigma_s=vme_sigma_s,
            range_vmr_sigma_m=self.v_mr_mps * vmr_sigma_s,
        )
        self.last = estimate
        self.counts["estimates"] += 1
        return estimate
