"""The one pipeline: telemetry samples in, energy and endurance estimates out.

The daemon feeds it from a socket, replay from a file, tests from lists; time comes only from
the samples, so the same samples always give the same estimates.

Work happens in *periods* of the sample clock (``estimate_period_s``, 1 s by default): each
velocity sample runs the kinematics (causal Kalman filter, scalar arithmetic) and is queued;
each battery sample is queued in the period its time falls in. The sample that reaches the end
of a period closes it (a velocity sample as the period's last event, a battery reading as the
next period's first), and then, once for the whole period:

1. the model power after every queued velocity sample and the endurance's (step 5), in one
   call of :func:`estimator.physics.effects.predict_power_w` (the one place power is predicted);
2. the energy filter integrates that power over the period (each power holds until the next
   sample);
3. the period's battery readings update the fusion (:mod:`estimator.estimation.fusion`): their mean
   measured power against the mean model power in force when each arrived; the reading the
   period ends with (:mod:`estimator.estimation.period_reading`) into the charge counter, the
   voltage model and the pack filter (:mod:`estimator.estimation.pack_learning`);
4. the online wind/mass tracker takes the readings queued since its last step (every
   ``track_period_s``);
5. one :class:`Estimate` is published.

Only *flying* readings (:mod:`estimator.estimation.airborne`: not on the ground, not in the take-off
transient) teach the fusion's bias and the tracker; before the first of them the energy
state draws the measured power, and the endurance is flagged not yet valid
(:attr:`Estimate.endurance_valid`) until they have been fused for
``endurance_valid_after_s``.

Per-sample numpy work would cost more than decoding the sample; per period it is amortized
over every sample of the period. A :class:`RebootSample` closes the open period, restarts the
kinematics and moves the clocks, keeping the energy state.

Endurance figures are at a *steady* power: level flight at the current horizontal speed (and
centripetal acceleration held over the last few seconds: an orbit continues, a waypoint
corner does not; :mod:`estimator.estimation.held_turn`), without the transient kinetic and climb
terms, scaled by the fused bias.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from estimator.estimation.airborne import AirborneGate, Phase
from estimator.estimation.estimate import Estimate, PowerReading
from estimator.estimation.flight_power import FlightPower, PowerEvent
from estimator.estimation.fusion import EnergyEstimate, EnergyFilter
from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.pack_bank import PackBank
from estimator.estimation.pack_learning import PackLearning
from estimator.estimation.pack_state import PackPrior
from estimator.estimation.period_estimate import period_estimate
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.estimation.pipeline_snapshot import Resume, parse_snapshot, take_snapshot
from estimator.estimation.return_home import (
    MissionEnergyFn,
    MissionSample,
    ReturnFigures,
    ReturnHome,
    ReturnInputs,
)
from estimator.estimation.tracker_readings import TrackerReading
from estimator.estimation.tracker_steps import TrackerSteps
from estimator.physics.battery import PackModel
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Climb, Effect
from estimator.physics.kinematics import KinematicsFilter, KinematicState
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    HomeSample,
    LandedSample,
    MissionCurrentSample,
    PositionSample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
)

#: How often (s, sample clock) V_me, V_mr and hover power follow the tracked wind and mass.
_SPEEDS_REFRESH_S = 5.0


@dataclass(frozen=True, slots=True)
class _Reading:
    """A queued battery sample, the number of events of the period before it, and the armed
    state, height over home (m), kinematic state and the autopilot's landed state when it
    arrived (None = unknown)."""

    sample: BatterySample
    events_before: int
    armed: bool | None
    alt_m: float | None
    state: KinematicState | None
    on_ground: bool | None = None


class Pipeline:
    """Samples in (:meth:`process`), estimates out; ``counts`` says what it did and skipped.

    ``readings`` holds the :class:`PowerReading` of the period that the last estimate closed.
    """

    def __init__(
        self,
        vehicle: Vehicle,
        settings: PipelineSettings | None = None,
        mission_energy: MissionEnergyFn | None = None,
        pack_prior: PackPrior | None = None,
    ) -> None:
        """``pack_prior``: what is known of this pack (capacity, resistance; e.g. from its
        last flight), else its label and the settings' prior."""
        self.vehicle = vehicle
        self.settings = settings or PipelineSettings()
        if not (self.settings.estimate_period_s > 0 and self.settings.track_period_s > 0):
            raise ValueError("estimate_period_s and track_period_s must be > 0")
        effects: list[Effect] = effects_from_tables(vehicle.effects)
        if self.settings.add_climb_effect and not any(isinstance(e, Climb) for e in effects):
            effects.append(Climb())
        #: The effects in use and the model power with them.
        self.power = FlightPower(vehicle, tuple(effects))
        #: The online wind/mass tracker and its steps.
        self.tracking = TrackerSteps(
            vehicle, self.power.effects, self.settings.track_period_s, self.settings.track_effects
        )
        self._speeds_time_s = -math.inf
        self.pack = PackModel(vehicle.battery)
        self.kinematics = KinematicsFilter(self.settings.kinematics)
        self.energy = EnergyFilter(self.pack, self.settings.fusion)
        #: The pack filter and the voltage model (:mod:`estimator.estimation.pack_learning`).
        self.packs = PackLearning(self.pack, self.settings.pack, pack_prior)
        self._gate = AirborneGate(vehicle.model.hover_power_w)
        self._phase = Phase.GROUND  # of the latest battery reading
        self._phases: dict[int, Phase] = {}  # of the open period's readings, by id
        #: Flying readings have been fused (or, without a current sensor, seen) for
        #: ``endurance_valid_after_s``: endurance is published from then on
        #: (:attr:`Estimate.endurance_valid`).
        self.endurance_valid = False
        self._flying_since_s: float | None = None  # first flying reading fused (sample clock)
        self.counts: Counter[str] = Counter()
        self.last: Estimate | None = None
        self.readings: list[PowerReading] = []
        self._state: KinematicState | None = None
        self._armed: bool | None = None
        self._on_ground: bool | None = None  # the autopilot's landed detector (PX4)
        self._battery: BatterySample | None = None
        # the open period: power-changing samples and battery readings (with the number of
        # events before each), and when it ends
        self._events: list[PowerEvent] = []
        self._pending: list[_Reading] = []
        self._period_end_s = math.inf
        self._power_model_w = 0.0  # in force after the last closed period's last event
        self._steady_power_w = 0.0
        self._time_s: float | None = None  # newest sample time (ordering)
        self._loss_factor = 1.0
        self._resume: Resume | None = None
        #: Position, home and mission for the return figures of each estimate.
        self.returning = ReturnHome(vehicle, self.settings.return_home, mission_energy)
        self._refresh_speeds()

    # -- power ------------------------------------------------------------------------------

    @property
    def online(self) -> OnlineEffects | None:
        """The online wind/mass tracker (None when effects are not tracked)."""
        return self.tracking.online

    @property
    def effects(self) -> tuple[Effect, ...]:
        """The effects in use: the vehicle file's, or the tracked wind and mass."""
        return self.power.effects

    @property
    def pack_state(self) -> PackBank | None:
        """The pack learned in flight (:attr:`PackLearning.state`)."""
        return self.packs.state

    @property
    def pack_prior(self) -> PackPrior | None:
        """What is known of this pack before the flight (:attr:`PackLearning.prior`)."""
        return self.packs.prior

    @pack_prior.setter
    def pack_prior(self, prior: PackPrior | None) -> None:
        self.packs.prior = prior

    def _latest_v(self) -> float:
        """The newest battery voltage (V; NaN before any)."""
        return math.nan if self._battery is None else self._battery.voltage_v

    def _refresh_speeds(self) -> None:
        self.power.refresh_speeds(self._time_s or 0.0, self._latest_v())

    def _event_powers_w(
        self, events: Sequence[PowerEvent], time_s: float, endurance: bool = False
    ) -> list[float]:
        """Model power after each of ``events`` (W); also sets the steady power of the latest
        state, and with ``endurance`` the endurance's (:meth:`FlightPower.event_powers_w`)."""
        powers_w, self._steady_power_w = self.power.event_powers_w(
            events, self._state, self._armed, self._latest_v(), time_s, endurance
        )
        return powers_w

    def _kinetic_sigma_w(self) -> float:
        """1σ of the kinetic term m vᵀa from the filtered acceleration's uncertainty, W."""
        if (state := self._state) is None:
            return 0.0
        return self.vehicle.mass_kg * state.speed_mps * state.accel_sigma_mps2

    # -- samples ------------------------------------------------------------------------------

    def process(self, sample: Sample | MissionSample) -> Estimate | None:
        """Fold in one sample (or a mission read from the autopilot); return the new estimate
        when it closed a period. ``mission_energy`` gives the rest of a mission's energy
        (:mod:`estimator.estimation.return_home`; without it, no mission figures)."""
        if isinstance(sample, VelocitySample):
            self.counts["velocity"] += 1
            if self._out_of_order(sample.time_s, "velocity_out_of_order"):
                return None
            self._state = self.kinematics.update(sample)
            self.power.observe(self._state)
            if not self.energy.initialized:
                self.counts["velocity_before_battery"] += 1
                return None
            self._queue_event(sample.time_s)
        elif isinstance(sample, BatterySample):
            self.counts["battery"] += 1
            if not math.isfinite(sample.voltage_v) or sample.voltage_v <= 0:
                self.counts["battery_invalid"] += 1
                return None
            if self._out_of_order(sample.time_s, "battery_out_of_order"):
                return None
            if not self.energy.initialized:
                self._initialize(sample)
                return None
            return self._queue_reading(sample)
        elif isinstance(sample, ArmedSample):
            self.counts["armed" if sample.armed else "disarmed"] += 1
            self._armed = sample.armed
            if self.energy.initialized:
                self._queue_event(sample.time_s)
            return None
        elif isinstance(sample, LandedSample):
            self.counts["on_ground" if sample.on_ground else "off_ground"] += 1
            self._on_ground = sample.on_ground
            return None
        elif isinstance(sample, RebootSample):
            return self._reboot(sample)
        elif isinstance(sample, WindSample):
            self.counts["autopilot_wind"] += 1
            if self.online is not None:
                self.online.take_autopilot_wind(sample)
            self.returning.take(sample)
            return None
        elif isinstance(sample, PositionSample | HomeSample | MissionSample | MissionCurrentSample):
            self.returning.take(sample)
            return None
        elif isinstance(sample, GripperSample):
            # the online tracker learns a payload change from the power; the event is for
            # the residual analysis (estimator.analysis.residual_candidates)
            self.counts["gripper_released" if sample.released else "gripper_grabbed"] += 1
            return None
        else:
            self.counts["unknown_sample"] += 1
            return None
        self._time_s = sample.time_s
        if sample.time_s < self._period_end_s:
            return None
        return self._close_period(sample.time_s)

    def _queue_reading(self, sample: BatterySample) -> Estimate | None:
        """Queue a battery reading in the period its time falls in: one past the open
        period's end closes that period first (so the period's readings, and the one the pack
        filter takes, are the same whichever other samples came between them: a log and a
        link that interleave them differently fuse the same readings)."""
        self._time_s = sample.time_s
        closing = sample.time_s >= self._period_end_s
        estimate = self._close_period(sample.time_s) if closing else None
        alt_m = None if self._state is None else self._state.alt_m
        reading = _Reading(
            sample, len(self._events), self._armed, alt_m, self._state, self._on_ground
        )
        self._pending.append(reading)
        self._battery = sample
        return estimate

    def flush(self) -> Estimate | None:
        """Close the open period at the newest sample's time (end of a log): the estimate of
        its samples, or None when there is nothing to close."""
        if not self.energy.initialized or self._time_s is None:
            return None
        if not self._events and not self._pending:
            return None
        return self._close_period(self._time_s)

    def _out_of_order(self, time_s: float, counter: str) -> bool:
        if self._time_s is not None and time_s < self._time_s:
            self.counts[counter] += 1
            return True
        return False

    def _queue_event(self, time_s: float) -> None:
        self._events.append(PowerEvent(time_s, self._state, self._armed, self._latest_v()))

    # -- continuing after a restart ---------------------------------------------------------------

    def snapshot(self) -> dict[str, Any] | None:
        """What a restarted process needs to continue this flight
        (:func:`~estimator.estimation.pipeline_snapshot.take_snapshot`); None before the energy
        state starts."""
        return take_snapshot(self.energy, self.power, self.endurance_valid, self.packs)

    def resume(self, snapshot: Mapping[str, Any]) -> None:
        """Continue from ``snapshot`` (:meth:`snapshot` of the same autopilot boot, checked by
        the caller) at the first battery sample instead of starting from its voltage (a
        sample older than the snapshot starts afresh). ValueError for a snapshot that does
        not parse or holds a value out of its range (:meth:`check_snapshot`)."""
        self._resume = self._parsed(snapshot)

    def check_snapshot(self, snapshot: Mapping[str, Any]) -> None:
        """ValueError when :meth:`resume` would refuse ``snapshot``
        (:func:`~estimator.estimation.pipeline_snapshot.parse_snapshot`)."""
        self._parsed(snapshot)

    def _parsed(self, snapshot: Mapping[str, Any]) -> Resume:
        return parse_snapshot(
            snapshot,
            lambda: EnergyFilter(self.pack, self.settings.fusion),
            self.packs.new_bank,
            lambda effects: self.power.hover_w(self._latest_v(), effects),
            self.vehicle.model.hover_power_w,
        )

    def _initialize(self, sample: BatterySample) -> None:
        """First valid battery sample: start the energy state at the model power now (and
        the pack filter from the sample, when it has a current), or continue from a snapshot
        (:meth:`resume`): the time since it is drawn at this sample's power, and the charge
        counter then corrects it."""
        resume, self._resume = self._resume, None
        resumed = resume is not None and resume.energy.time_s <= sample.time_s
        resumed_pack, refuted = None, False
        if resumed:
            assert resume is not None
            resumed_pack, refuted = resume.pack, resume.pack_refuted
            self.energy, self.power.effects, self.endurance_valid = (
                resume.energy,
                resume.effects,
                resume.endurance_valid,
            )
            self.power.tracked_sq_w2 = resume.tracked_sq_w2
            self.power.file_sq_w2 = resume.file_sq_w2
            self.tracking.renew(self.power.effects)
            self._refresh_speeds()
        self.packs.begin(sample, resumed_pack, refuted)
        self._battery = sample
        self._time_s = sample.time_s
        now = PowerEvent(sample.time_s, self._state, self._armed, sample.voltage_v)
        self._power_model_w = self._event_powers_w([now], sample.time_s)[0]
        if resumed:
            power_w = sample.power_w
            if power_w is None:
                power_w = self.energy.bias * self._power_model_w
            loss = self.energy.loss_factor(power_w)
            self.energy.predict(sample.time_s, power_w, loss, measured=sample.power_w is not None)
            self.counts["resumed"] += 1
        else:
            self.energy.initialize(sample, self._power_model_w)
            self.counts["energy_initialized"] += 1
            # the first estimate rests on the pack filter as every later one does, not on
            # the fusion's own start (whose σ knows nothing of the pack's capacity prior)
            self.packs.first(sample, self.energy)
        self._start_period(sample.time_s)

    def _start_period(self, time_s: float) -> None:
        period = self.settings.estimate_period_s
        self._period_end_s = (math.floor(time_s / period) + 1.0) * period

    def _reboot(self, sample: RebootSample) -> Estimate | None:
        """Close the old clock's period, then restart the kinematics on the new clock."""
        self.counts["reboot"] += 1
        estimate = self.flush()
        self.kinematics.reset()
        self.power.restart()
        self.tracking.restart_clock()
        self._speeds_time_s = -math.inf
        self._gate.reset()
        self._phase, self._flying_since_s = Phase.GROUND, None
        self._state = None
        self._armed = self._on_ground = None
        self._battery = None
        self.returning.restart()
        initialized = self.energy.initialized
        self.packs.reboot(sample.time_s if initialized else None)
        if initialized:
            self.energy.rebase(sample.time_s)
            self._queue_event(sample.time_s)
            self._start_period(sample.time_s)
        if self._time_s is not None:
            self._time_s = sample.time_s
        return estimate

    # -- one period -----------------------------------------------------------------------------

    def _close_period(self, time_s: float) -> Estimate:
        self._classify_readings()
        powers_w = self._event_powers_w(self._events, time_s, endurance=True)
        self._integrate(time_s, powers_w)
        # each reading against the power in force when it arrived
        model_w = [
            powers_w[r.events_before - 1] if r.events_before else self._power_model_w
            for r in self._pending
        ]
        if powers_w:
            self._power_model_w = powers_w[-1]
        self._fuse(model_w)
        self._events, self._pending = [], []
        self._start_period(time_s)
        return self._emit(time_s)

    def _classify_readings(self) -> None:
        """The flight phase of each of the period's readings
        (:mod:`estimator.estimation.airborne`): only
        flying readings teach the bias and the tracker; counts the others."""
        self._phases = {
            id(r): self._gate.phase(
                r.sample.time_s,
                r.armed,
                r.alt_m,
                r.sample.power_w,
                None if r.state is None else r.state.vd_mps,
                r.on_ground,
            )
            for r in self._pending
        }
        for phase in self._phases.values():
            if phase is not Phase.FLYING:
                self.counts[f"readings_{phase.value}"] += 1
        if self._pending:
            self._phase = self._phases[id(self._pending[-1])]

    def _integrate(self, time_s: float, powers_w: list[float]) -> None:
        """Energy predict to ``time_s`` at the period's mean model power (each power holds
        until the next event); the pack's loss factor OCV/V is the one of the last battery
        update (it changes slowly)."""
        start_s = self.energy.time_s
        if time_s <= start_s:
            return
        energy_ws, t, p = 0.0, start_s, self._power_model_w
        for event, power_w in zip(self._events, powers_w, strict=True):
            if event.time_s > t:
                energy_ws += p * (event.time_s - t)
                t = event.time_s
            p = power_w
        energy_ws += p * (time_s - t)
        measured_w = [r.sample.power_w for r in self._pending if r.sample.power_w is not None]
        if self._phase is not Phase.FLYING and measured_w:
            # the flight model does not hold on the ground nor at take-off: draw what is measured
            mean_w = sum(measured_w) / len(measured_w)
            self.energy.predict(time_s, mean_w, self._loss_factor, measured=True)
        else:
            self.energy.predict(time_s, energy_ws / (time_s - start_s), self._loss_factor)
        if self._steady_power_w > 0:
            self.energy.flight_state_changed(self._steady_power_w)

    def _fuse(self, model_w: list[float]) -> None:
        """The period's battery readings into the fusion and the online tracker; ``model_w``
        is the model power in force when each arrived (W)."""
        pending = self._pending
        if not pending:
            self.readings = []
            return
        # readings with a current: (queued reading, model power then, measured power)
        scored = [
            (r, p_w, measured_w)
            for r, p_w in zip(pending, model_w, strict=True)
            if (measured_w := r.sample.power_w) is not None
        ]
        self.readings = [
            PowerReading(r.sample.time_s, measured_w, p_w, r.armed, r.alt_m)
            for r, p_w, measured_w in scored
        ]
        phases = self._phases
        flying = Phase.FLYING in phases.values()
        powered = [
            (r, p_w, measured_w)
            for r, p_w, measured_w in scored
            if p_w > 0 and phases[id(r)] is Phase.FLYING
        ]
        latest = pending[-1].sample
        if powered:
            n = len(powered)
            self.energy.update_power(
                sum(measured_w for _, _, measured_w in powered) / n,
                sum(p_w for _, p_w, _ in powered) / n,
                self._kinetic_sigma_w(),
                n,
            )
            self.tracking.queue(
                TrackerReading(r.state, measured_w, r.sample.voltage_v)
                for r, _, measured_w in powered
                if r.state is not None
            )
            self._track_effects(latest.time_s)
        if powered or (flying and not scored):
            if self._flying_since_s is None:
                self._flying_since_s = latest.time_s
            flown_s = latest.time_s - self._flying_since_s
            self.endurance_valid |= flown_s >= self.settings.endurance_valid_after_s
        readings = [r.sample for r in pending]
        self.packs.period_end(self.energy, readings, self._period_end_s, model_w[-1])
        self._loss_factor = self.energy.loss_factor(self.energy.bias * self._power_model_w)

    def adopt_pack_prior(self, prior: PackPrior) -> bool:
        """Learn the pack from ``prior`` (a memory named late, e.g. by the pack's serial):
        before the first flying reading the pack filter starts again from it at the next
        reading (the readings on the ground give the charge again); False once flying (the
        flight goes on with what it has learnt)."""
        if self._flying_since_s is not None:
            return False
        self.packs.adopt(prior)
        return True

    def _track_effects(self, time_s: float) -> None:
        """A step of the tracker (:mod:`estimator.estimation.tracker_steps`); when it changes
        the effects in use, the bias moves by the model's change."""
        chosen = self.tracking.step(time_s, self.power)
        if chosen is None:
            return
        file_chosen = chosen == self.power.file_effects
        self.counts["file_effects" if file_chosen else "tracked_effects"] += 1
        before_w = self._steady_power_w
        self.power.effects = chosen
        speed_mps = 0.0 if self._state is None else self._state.speed_mps
        after_w = self.power.steady_w(speed_mps, self._time_s or 0.0, self._latest_v())
        if before_w > 0 and after_w > 0:
            # the bias absorbed what the model now explains: it moves by the model's change
            self.energy.rescale_bias(before_w / after_w)
            self._steady_power_w = after_w
        if time_s - self._speeds_time_s >= _SPEEDS_REFRESH_S:
            self._refresh_speeds()
            self._speeds_time_s = time_s

    def _return_figures(self, time_s: float, est: EnergyEstimate, steady_w: float) -> ReturnFigures:
        """The return figures (:mod:`estimator.estimation.return_home`), and the state they
        rest on, gathered only once the vehicle and home are located."""
        if not self.returning.located:
            return self.returning.unlocated(self.endurance_valid)
        settings, state = self.settings.return_home, self._state
        if self.online is not None:
            sigma = self.online.sigma
            wind_sigma, mass_sigma_kg = (sigma["wind_n_mps"], sigma["wind_e_mps"]), sigma["mass_kg"]
        else:
            wind_sigma = (settings.untracked_wind_sigma_mps,) * 2
            mass_sigma_kg = settings.untracked_mass_sigma_fraction * self.vehicle.mass_kg
        inputs = ReturnInputs(
            time_s=self._time_s or 0.0,
            velocity_ne_mps=(0.0, 0.0) if state is None else (state.vn_mps, state.ve_mps),
            effects=self.power.effects,
            wind_sigma_ne_mps=wind_sigma,
            mass_sigma_kg=mass_sigma_kg,
            bias=est.bias,
            bias_sigma=est.bias_sigma,
            energy_wh=est.energy_wh,
            energy_sigma_wh=est.energy_sigma_wh,
            loss_factor=self._loss_factor,
            steady_power_w=steady_w,
            flying=self.endurance_valid,
        )
        return self.returning.figures(time_s, inputs)

    def _endurance_power_w(self) -> float:
        """Model power (W) the endurance holds (:meth:`FlightPower.endurance_w`)."""
        state = self._state
        if state is None or self._steady_power_w <= 0:
            return self._steady_power_w
        time_s = self._time_s or 0.0
        return self.power.endurance_w(state, self._steady_power_w, time_s, self._latest_v())

    def _emit(self, time_s: float) -> Estimate:
        est = self.energy.estimate()
        steady_w = est.bias * self._steady_power_w
        endurance_model_w = self._endurance_power_w()
        battery = self._battery
        stale = battery is None or time_s - battery.time_s > self.settings.battery_stale_s
        back = self._return_figures(time_s, est, steady_w)
        estimate = period_estimate(
            time_s, self.energy, est, self.power, endurance_model_w, self._power_model_w,
            self._state, battery, self.packs.estimate, back, stale, self.endurance_valid,
            steady_w,
        )  # fmt: skip
        self.last = estimate
        self.counts["estimates"] += 1
        return estimate
