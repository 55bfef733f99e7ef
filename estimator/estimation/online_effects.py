"""Online tracking of the effects that change during a flight: wind and mass.

:class:`OnlineEffects` is a small causal unscented Kalman filter (van der Merwe's scaled
sigma points, :mod:`estimator.estimation.kalman`) over the state

    x = [w_n, w_e, δm, b]   air-mass velocity over ground (NED north/east, m/s), the mass
                             difference from the vehicle file (kg) and the model's slow error
                             (W),

wind and mass random walks, observed through the measured electrical power: z = P(state; x) + b
with :func:`estimator.physics.effects.predict_power_w` (the vehicle's model, its other effects,
and ``Wind``/``Mass`` built from x). It starts from the vehicle file's ``[effects.wind]`` and
``[effects.mass]`` (as written by ``uav-energy residuals --write``) and follows them as the
flight goes on: a changing wind, a payload picked up or dropped.

The model's error is not white. On the CMU M100 flights, with the payload and the anemometer's
wind put in, the measured power's residual has a 45-70 W scatter that decorrelates within 2 s
but also a slow part: its 10 s means scatter by 13-30 W and stay correlated over tens of
seconds. Taken as independent, readings pinned the mass to ±0.02 kg within a minute while a
slow excursion of the residual moved it by half a kilogram (flight 273: −0.48 ± 0.02 kg for
80 s, no payload). ``b`` carries that part: a first-order Gauss-Markov process (zero mean,
1σ a fraction of the hover power, correlation time ``model_error_time_s``), so a constant mass
is told from it only as its excursions average out over the flight, and the mass's σ says how
far that has come. The fraction is the vehicle file's ``[model] slow_error_fraction`` (the
CMU M100 file states 0.05: the 10 s means above, 3-7 % of its 454 W hover), else
``model_error_fraction`` (0: a simulator's own model has no slow error). It is stated, not
learnt (the scatter of 10 s means also holds the fast noise's), and not assumed: a mass the
filter can no longer pin is not applied (:meth:`~OnlineEffects.identified_effects`), and with
5 % on every vehicle the IRIS+ March flights replayed on the June-August file kept that file's
mass, where the tracked one had made up for the other period's model (flight 004-F2: model
power RMSE 25 → 73 W).

Robustness: the measurement noise is an absolute floor plus a fraction of the power plus the
kinetic term's uncertainty (m·V·σ_a from the kinematics filter) plus a learnt excess (the
squared innovations' surplus over their predicted variance, followed with gain
``noise_gain``: real power telemetry is noisier than a current sensor's datasheet says, and
model error looks like noise to the filter); an innovation beyond ``gate_sigma`` standard
deviations is not used (counted in ``rejected``) unless it starts a detected change (below),
nor are samples in fast vertical motion (|v_z| > ``max_vertical_speed_mps``: take-off,
landing, where the climb term is the least certain part of the model) or in a vertical
acceleration beyond ``max_vertical_accel_mps2`` where the model has the ``heave`` term (a
climb that starts or stops: the power leads the filtered state, so the term is late),
counted in ``vertical`` (with the rest of a step whose readings they mostly left out: a
transition, :mod:`~estimator.estimation.tracker_readings`), and readings below
``min_power_fraction_of_hover`` of the model's hover power (idle motors, ``idle``).
Readings from the ground and the take-off transient never reach the filter: its callers gate
them (:class:`~estimator.estimation.airborne.AirborneGate`).

Steps (payload picked up or released, wind setting in): a random walk slow enough to keep the
estimate quiet follows a step only at its own pace (a 1 kg release took about a minute). Each
step's normalised innovation feeds a two-sided CUSUM
(:mod:`~estimator.estimation.change_detector`, drift ``cusum_drift_sigma``, threshold
``cusum_threshold_sigma``). On an alarm the step is undone and redone from the prior with the
uncertainty of a changed state back at its initial value (its cross-covariances cleared), and
(outside the duel below) so is the step after it when its innovation is beyond the gate: a
change that came in the middle of the alarm's step left that step's readings straddling it
and the estimate half way with the 1σ of a settled one, and the step after is then the rest
of the change, not an outlier (ArduCopter SITL: a release in hover read 0.5 kg with a 1σ of
0.07 kg for a step, 7.8–8.2σ). A step that did not settle the estimate (its readings beyond
the gate with no alarm, an alarm's redo outside a duel and the step after it, or a CUSUM sum
that grew past half way to its alarm) is reported with a changed state's wind and mass 1σ
until the next step (:attr:`~OnlineEffects.sigma`): an outlier and the start of a change look
alike for one step, an alarm's step may straddle the change (the step after reads the rest of
it), and innovations leaning one way say the estimate may be following a change at the random
walk's pace (a release read half way, at a settled 1σ).
In hover that state is the mass (a wind shows in hover only through translational lift, weakly,
and is held there, below). In forward flight a payload step and a wind change both move the
power, so both hypotheses run side by side (one with the mass widened, one with the wind) until
one is ``hypothesis_nats`` likelier or ``hypothesis_max_steps`` have passed, the estimate
their mixture till then (:mod:`~estimator.estimation.hypotheses`). ``changes`` counts the
alarms.
A step takes one reading or several taken close together (:meth:`~OnlineEffects.update_readings`;
the pipeline gives it the readings of each ``track_period_s``): their mean measured power
against the mean of the predictions at each reading's own flight state, with the noise of a mean
(the learnt excess is not divided: model error does not average out). The sigma points and the
two hypotheses the pipeline scores (the estimate, the vehicle file's values) are predicted in
one vectorized call per step.

Identifiability: wind direction needs flight in more than one direction; in hover only the
wind speed is seen, and a hover power offset is shared between wind and mass until the vehicle
moves. The filter carries this in its covariance (``sigma``), with one exception. In hover
(ground speed below ``moving_speed_mps``) the wind is *held* at its estimate: the sigma points
spread over the mass alone. At zero airspeed the power's slope in the wind is zero, so the
wind's sigma points would only shift the predicted mean by the curvature of P(V) (an unknown
wind of 3 m/s makes the mean hover power lower, and a clean hover read +0.2 kg), a shift
that the point estimate applied afterwards never reproduces. A mass learnt in hover is thus
conditional on the wind held: when the vehicle then moves while the wind is not known to
``wind_known_sigma_mps``, the mass variance goes back to its initial value and the moving
flight, which sees the wind, settles both. :meth:`~OnlineEffects.identified_effects` says
which parts are known well enough to apply (the wind along the track flown, the mass).

The covariance says how far the readings have pinned the state *within the model*; the 1σ
the tracker reports (``sigma``) adds what the model's form, the autopilot's report and a wind
held in hover leave unknown (:mod:`~estimator.estimation.reported_sigma`). Which parts are
identified, and applied, still follows the covariance alone.

The autopilot's own wind estimate is a second channel
(:mod:`estimator.estimation.autopilot_wind`); without its reports the tracker is the
power-only filter above.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from estimator.estimation.autopilot_wind import AutopilotWind, mahalanobis2
from estimator.estimation.change_detector import ChangeDetector
from estimator.estimation.form_error import carried
from estimator.estimation.hypotheses import Hypothesis, duel, mixture
from estimator.estimation.kalman import MerweSigmaPoints
from estimator.estimation.online_settings import OnlineSettings
from estimator.estimation.reported_sigma import held_wind_mass_var_kg2, reported_variances
from estimator.estimation.tracker_readings import (
    StepData,
    TrackerReading,
    select_readings,
    step_data,
)
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import (
    Effect,
    FlightState,
    Heave,
    Mass,
    SampleMass,
    Wind,
    predict_power_w,
    wind_from_vector,
)
from estimator.physics.kinematics import KinematicState
from estimator.physics.model import PowerModel
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import (
    WindSample,
)

#: Variance (m²/s²) standing in for a held wind's in the sigma points (positive definite).
_HELD_VARIANCE = 1e-9


class OnlineEffects:
    """Causal tracker of wind and mass from flight state and measured power.

    ``update`` takes one power measurement with the flight state at that instant and returns
    the effects to use now: ``effects`` minus any wind/mass, plus the tracked ``Wind`` and
    ``Mass`` (in the stage order of :mod:`estimator.physics.effects`).
    """

    def __init__(
        self,
        model: PowerModel,
        mass_kg: float,
        effects: Sequence[Effect] = (),
        settings: OnlineSettings | None = None,
        slow_error_fraction: float | None = None,
    ) -> None:
        """``slow_error_fraction``: the model's slow error b, 1σ as a fraction of its hover
        power (the vehicle file's; None: ``settings.model_error_fraction``)."""
        self.model, self.mass_kg = model, float(mass_kg)
        self.settings = s = settings or OnlineSettings()
        wind = next((e for e in effects if isinstance(e, Wind)), Wind())
        mass = next((e for e in effects if isinstance(e, Mass)), Mass())
        self.others = tuple(e for e in effects if not isinstance(e, Wind | Mass))
        # the vertical-acceleration gate guards the heave term's timing: without the term,
        # a noisy vertical velocity (real logs) would gate out readings for nothing
        self._max_vertical_accel_mps2 = (
            s.max_vertical_accel_mps2
            if any(isinstance(e, Heave) for e in self.others)
            else math.inf
        )
        wn, we = wind.vector_ne_mps()
        self._file_wind_ne_mps, self._file_mass = (wn, we), mass
        # a stepped mass from the file has not happened yet at take-off
        delta0 = mass.delta_kg if mass.at_s is None else 0.0
        if slow_error_fraction is None:
            slow_error_fraction = s.model_error_fraction
        # b is a state only where the model has a slow error (else [w_n, w_e, δm])
        self._model_error_var_w2 = (slow_error_fraction * model.hover_power_w) ** 2
        n = 4 if self._model_error_var_w2 > 0.0 else 3
        self._points = MerweSigmaPoints(n, alpha=1.0, beta=2.0, kappa=0.0)
        self._x = np.array([wn, we, delta0, 0.0][:n])
        self._initial_var = np.array(
            [
                s.initial_wind_sigma_mps**2,
                s.initial_wind_sigma_mps**2,
                (s.initial_mass_sigma_fraction * self.mass_kg) ** 2,
                self._model_error_var_w2,
            ][:n]
        )
        self._p = np.diag(self._initial_var)
        self._form = np.zeros(n)  # the estimate's sensitivity to the model form's error
        self._time_s: float | None = None
        self._detector = ChangeDetector(s.cusum_drift_sigma, s.cusum_threshold_sigma)
        self._hovering = False  # the last step was in hover (wind held)
        self._loglik = 0.0  # the estimate's summed innovation log-likelihood (while in a duel)
        self._rival: Hypothesis | None = None  # the other hypothesis after a change
        self._duel_steps = 0
        self._changing = False  # the last step raised a change alarm
        #: The last step did not settle the estimate (beyond the gate, an alarm's step or the
        #: one after, a CUSUM past half way: module docstring). Its 1σ is a changed state's.
        self._unsettled = False
        #: The mass's variance (kg²) from the wind held in the last step, a hover's
        #: (:mod:`~estimator.estimation.reported_sigma`); zero after a step in forward flight.
        self._held_wind_mass_var_kg2 = 0.0
        #: Measurement noise beyond the configured one, learnt from the innovations, W².
        self.extra_noise_var_w2 = 0.0
        self._hover_w = model.hover_power_w
        self.updates = 0
        self.idle = 0
        self.vertical = 0
        self.rejected = 0
        self.changes = 0
        #: Readings the filter was run on (updates and gate rejections).
        self.steps = 0
        #: The last step's mean measured power (W) and the mean powers predicted for its
        #: readings before the step: with the estimate then, and with the vehicle file's wind
        #: and mass.
        self.last_step_w = (math.nan, math.nan, math.nan)
        #: The last step's readings (their flight states, mean power and its noise), None
        #: before one: what :meth:`powers_w` predicts them at (an analysis's probe).
        self.last_step: StepData | None = None
        #: Times the covariance was restarted after losing positive definiteness (bad data).
        self.resets = 0
        self.autopilot = AutopilotWind(s)
        #: Steps that took the autopilot's wind, and its reports beyond the gate (not taken).
        self.autopilot_wind_steps = 0
        self.autopilot_wind_rejected = 0

    @classmethod
    def from_vehicle(
        cls, vehicle: Vehicle, extra: Sequence[Effect] = (), settings: OnlineSettings | None = None
    ) -> OnlineEffects:
        """Start from the vehicle file's model, mass and effects (plus ``extra`` ones, e.g. the
        pipeline's default climb)."""
        effects = [*effects_from_tables(vehicle.effects), *extra]
        return cls(vehicle.model, vehicle.mass_kg, effects, settings, vehicle.slow_error_fraction)

    # -- current estimate ----------------------------------------------------------------------

    def _reported(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The estimate it reports and applies: state, covariance and sensitivity to the
        model form's error; while two hypotheses run after a change, their mixture
        (:func:`~estimator.estimation.hypotheses.mixture`)."""
        if self._rival is None:
            return self._x, self._p, self._form
        return mixture(Hypothesis(self._x, self._p, self._form, self._loglik), self._rival)

    @property
    def state(self) -> np.ndarray:
        """The reported state [w_n, w_e, δm(, b)] (a copy): m/s NED, kg, W."""
        return np.array(self._reported()[0], dtype=float)

    @property
    def wind(self) -> Wind:
        x = self._reported()[0]
        return wind_from_vector(float(x[0]), float(x[1]))

    @property
    def mass_delta_kg(self) -> float:
        return float(self._reported()[0][2])

    @property
    def mass_ratio(self) -> float:
        """Actual over the vehicle file's mass."""
        return (self.mass_kg + self.mass_delta_kg) / self.mass_kg

    @property
    def sigma(self) -> dict[str, float]:
        """1σ of the wind components (m/s) and of the mass difference (kg): the filter's own,
        what the model's form leaves unknown, for the wind what the autopilot's report says
        is on its way, and for a mass learnt in hover what the wind held there leaves unknown
        (:mod:`~estimator.estimation.reported_sigma`). After a step that did not settle the
        estimate (module docstring), the wind and mass variances are a changed state's (their
        initial ones) until the next step."""
        _, wind_cov, mass_var = self._reported_variances()
        return {
            "wind_n_mps": math.sqrt(max(float(wind_cov[0, 0]), 0.0)),
            "wind_e_mps": math.sqrt(max(float(wind_cov[1, 1]), 0.0)),
            "mass_kg": math.sqrt(max(mass_var, 0.0) + self._held_wind_mass_var_kg2),
        }

    def _reported_variances(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The reported state, its wind's covariance (m²/s²) and its mass's variance (kg²)
        with the terms :attr:`sigma` adds, except the held wind's."""
        x, p, form = self._reported()
        if self._unsettled:  # either part may have changed
            p = self._widened(self._widened(p, wind=True), wind=False)
        return x, *reported_variances(
            x, p, form, self.settings, self.autopilot, self._time_s or 0.0
        )

    @property
    def effects(self) -> tuple[Effect, ...]:
        """Effects to predict power with now (frame effects first)."""
        return self._effects(self._reported()[0])

    def identified_effects(
        self,
        track_rad: float,
        wind_sigma_mps: float,
        mass_sigma_kg: float,
        in_use: Sequence[Effect] = (),
    ) -> tuple[Effect, ...] | None:
        """The effects to apply now: those ``in_use`` (default: the vehicle file's), with each
        part of the estimate that is known well enough in their place. Mass: when its 1σ is
        at most ``mass_sigma_kg``. Wind: the whole vector when both components' 1σ are at
        most ``wind_sigma_mps``; else its component along the track flown (``track_rad``,
        from north towards east), the one that sets the power at the current course, when
        that component's 1σ is, the component across keeping the value in use; and the whole
        vector whenever the wind so chosen is refuted by the estimate (``wind_refuted_chi2``:
        after a change the old wind is worse than the new one's first guess). None when
        nothing is identified."""
        x, p, _ = self._reported()
        used_wind = next((e for e in in_use if isinstance(e, Wind)), None)
        used_mass = next((e for e in in_use if isinstance(e, Mass)), None)
        wind = (
            np.array(self._file_wind_ne_mps)
            if used_wind is None
            else np.array(used_wind.vector_ne_mps())
        )
        mass = self._file_mass_kg() if used_mass is None else used_mass.delta_kg
        mass_known = float(p[2, 2]) <= mass_sigma_kg**2
        if mass_known:
            mass = float(x[2])
        along = np.array([math.cos(track_rad), math.sin(track_rad)])
        wind_var = p[:2, :2]
        known = mass_known
        if max(wind_var[0, 0], wind_var[1, 1]) <= wind_sigma_mps**2:
            wind, known = x[:2], True
        elif float(along @ wind_var @ along) <= wind_sigma_mps**2:
            wind, known = wind + along * float(along @ (x[:2] - wind)), True
        apart = x[:2] - wind
        if mahalanobis2(apart, wind_var) > self.settings.wind_refuted_chi2:
            wind, known = x[:2], True
        return self._effects(np.array([*wind, mass])) if known else None

    def _file_mass_kg(self) -> float:
        """The vehicle file's mass difference now (kg): a stepped one from its time on."""
        at_s = self._file_mass.at_s
        now = at_s is None or (self._time_s is not None and self._time_s >= at_s)
        return self._file_mass.delta_kg if now else 0.0

    def _effects(self, x: np.ndarray) -> tuple[Effect, ...]:
        return (wind_from_vector(float(x[0]), float(x[1])), Mass(float(x[2])), *self.others)

    # -- filter --------------------------------------------------------------------------------

    def powers_w(self, points: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Model power (W) at each flight state of ``rows`` (k × 9, the FlightState fields)
        for each hypothesis [w_n, w_e, δm] or [w_n, w_e, δm, b] of ``points`` (m rows): an
        m × k array, from one prediction, plus the hypothesis' model error b. The wind is
        taken out of the velocity (what :class:`Wind` does), the mass goes in as
        :class:`SampleMass`."""
        m, k = len(points), len(rows)
        blocks = np.empty((9, m, k))  # 9 × (m·k), hypothesis-major
        blocks[:] = rows.T[:, None, :]
        blocks[1:3] -= points[:, :2].T[:, :, None]
        floor_kg = (self.settings.min_mass_fraction - 1.0) * self.mass_kg
        delta_kg = np.empty((m, k))
        delta_kg[:] = np.maximum(points[:, 2], floor_kg)[:, None]
        state = FlightState.of_columns(blocks.reshape(9, m * k))
        mass = SampleMass(delta_kg.reshape(m * k))
        power = predict_power_w(self.model, self.mass_kg, state, (mass, *self.others))
        return power.reshape(m, k) + (points[:, 3:4] if points.shape[1] > 3 else 0.0)

    def restart_clock(self) -> None:
        """The autopilot rebooted: readings come on a new clock (the estimate is kept; its
        wind reports count again once they are not zero)."""
        self._time_s = None
        self.autopilot.restart()

    def take_autopilot_wind(self, sample: WindSample) -> None:
        """Keep the autopilot's latest wind estimate for the next steps."""
        self.autopilot.take(sample)

    def _with_autopilot_wind(self, h: Hypothesis, var: float) -> Hypothesis | None:
        """``h`` after the autopilot's report of variance ``var`` (m²/s², per component);
        None when it is beyond ``gate_sigma`` of the estimate."""
        taken = self.autopilot.update(h.x, h.p, var)
        if taken is None:
            return None
        return h._replace(x=taken[0], p=taken[1], form=carried(h.form, h.p, taken[1]))

    def update(
        self,
        time_s: float,
        vn_mps: float,
        ve_mps: float,
        vd_mps: float,
        an_mps2: float,
        ae_mps2: float,
        measured_power_w: float,
        voltage_v: float = math.nan,
        accel_sigma_mps2: float = 0.0,
    ) -> tuple[Effect, ...]:
        """Fold in one airborne power measurement (W) with the state then (NED, m/s, m/s²).

        Returns :attr:`effects` after the update. Non-finite input or time going backwards
        leaves the estimate as it was.
        """
        state = KinematicState.of_motion(
            time_s, (vn_mps, ve_mps, vd_mps), (an_mps2, ae_mps2), None, accel_sigma_mps2
        )
        self.update_readings([TrackerReading(state, measured_power_w, voltage_v)])
        return self.effects

    def update_kinematics(
        self, state: KinematicState, measured_power_w: float, voltage_v: float = math.nan
    ) -> tuple[Effect, ...]:
        """:meth:`update` from the pipeline's filtered kinematic state."""
        self.update_readings([TrackerReading(state, measured_power_w, voltage_v)])
        return self.effects

    def update_readings(self, readings: Sequence[TrackerReading]) -> None:
        """Fold in readings taken close together (in time order) in one filter step: their
        mean measured power against the mean of the powers predicted at each reading's own
        flight state, with the noise of a mean. While the estimate moves little between
        the readings this carries what they would carry one by one, at the cost of one step.
        The readings it takes are those
        :func:`~estimator.estimation.tracker_readings.select_readings` keeps (the others
        counted in ``rejected``, ``vertical``, ``idle``); :attr:`effects` then gives the
        effects after the update.
        """
        s = self.settings
        selection = select_readings(
            readings, s, self._time_s, self._max_vertical_accel_mps2, self._hover_w
        )
        self.rejected += selection.rejected
        self.vertical += selection.vertical
        self.idle += selection.idle
        kept = selection.kept
        if not kept:
            return
        self.steps += 1
        time_s = kept[-1][0].state.time_s
        dt = 0.0 if self._time_s is None else max(time_s - self._time_s, 0.0)
        self._time_s = time_s
        wind_q = s.wind_walk_mps_per_sqrt_s**2 * dt
        kept_b = math.exp(-dt / s.model_error_time_s)  # the model error's memory over dt
        n = len(self._x)
        q = np.diag(
            [
                wind_q,
                wind_q,
                s.mass_walk_kg_per_sqrt_s**2 * dt,
                self._model_error_var_w2 * (1.0 - kept_b**2),
            ][:n]
        )
        decay = np.array([1.0, 1.0, 1.0, kept_b][:n])
        step = step_data(kept, s, self.mass_kg, self.extra_noise_var_w2, self._x[:2], self._hover_w)
        self.last_step = step
        reopen = step.moving and self._hovering
        self._hovering = self.autopilot.hovering = not step.moving
        main = self._prior(Hypothesis(self._x, self._p, self._form, self._loglik), decay, q, reopen)
        wind_var = self.autopilot.variance(time_s, dt)
        if wind_var is not None:
            if self.autopilot.saw_a_change(main.x, main.p):
                self.changes += 1
                main = main._replace(p=self._widened(main.p, wind=True))
            taken = self._with_autopilot_wind(main, wind_var)
            self.autopilot_wind_steps += taken is not None
            self.autopilot_wind_rejected += taken is None
            main = main if taken is None else taken
        # the vehicle file's wind and mass, with the model error as estimated
        file_x = np.array([*self._file_wind_ne_mps, self._file_mass_kg(), *main.x[3:]])
        done, (estimate_w, file_w) = self._step(main, step, np.vstack([main.x, file_x]))
        self.last_step_w = (step.measured_w, estimate_w, file_w)
        changing, self._changing = self._changing, False
        fed = self._rival is None and done.nu is not None  # the CUSUM takes this step
        if self._rival is not None:
            rival = self._prior(self._rival, decay, q, reopen)
            if wind_var is not None:
                rival = self._with_autopilot_wind(rival, wind_var) or rival
            rival, _ = self._step(rival, step)
            main, self._rival = self._duel(done, rival)
        elif done.nu is not None and self._change_goes_on(done.nu, changing):
            # redo the step from the prior with the changed state's uncertainty restored; in
            # forward flight two hypotheses (a mass step, a wind change) run side by side
            mass_step, _ = self._step(main._replace(p=self._widened(main.p, False)), step)
            if step.moving:
                wind_step, _ = self._step(main._replace(p=self._widened(main.p, True)), step)
                self._duel_steps = 0
                main, self._rival = self._duel(mass_step, wind_step)
            else:
                main = mass_step
        else:
            main = done
            if done.nu is not None:
                # adaptive measurement noise: drive E[y²] towards S (outliers clipped at the
                # gate)
                excess = min(done.y2, s.gate_sigma**2 * done.s_var) - done.s_var
                self.extra_noise_var_w2 = max(0.0, self.extra_noise_var_w2 + s.noise_gain * excess)
        refused = main.nu is not None and abs(main.nu) > s.gate_sigma
        if refused:
            self.rejected += 1
        elif main.nu is not None:
            self.updates += 1
        leaning = fed and self._detector.half_way()
        self._unsettled = self._rival is None and (self._changing or changing or refused or leaning)
        self._x, self._p, self._form, self._loglik = main.x, main.p, main.form, main.loglik
        self._held_wind_mass_var_kg2 = 0.0
        if not step.moving:
            x, wind_cov, _ = self._reported_variances()
            self._held_wind_mass_var_kg2 = held_wind_mass_var_kg2(
                self.powers_w, x, wind_cov, step.rows, s.max_wind_mps
            )

    def _change_goes_on(self, nu: float, changing: bool) -> bool:
        """Whether the step of normalised innovation ``nu`` starts a change (an alarm of the
        CUSUM, counted in ``changes``) or, ``changing`` (the step before started one), is the
        rest of it: beyond the gate right after the alarm (see the module docstring)."""
        started = self._detector.alarm(nu)
        self.changes += started
        self._changing = started
        return started or (changing and abs(nu) > self.settings.gate_sigma)

    def _prior(self, h: Hypothesis, decay: np.ndarray, q: np.ndarray, reopen: bool) -> Hypothesis:
        """A hypothesis' prior for a step: each state times its ``decay`` (1 for the random
        walks, the model error's memory for b) and the process noise ``q`` added;
        ``reopen``: the vehicle starts moving after a hover (see the module docstring)."""
        p = h.p * np.outer(decay, decay) + q
        wind_known = max(p[0, 0], p[1, 1]) <= self.settings.wind_known_sigma_mps**2
        if reopen and not wind_known:
            p = self._widened(p, wind=False)
        x = np.array(h.x, dtype=float) * decay
        return Hypothesis(x, 0.5 * (p + p.T), h.form * decay, h.loglik)

    def _step(
        self, prior: Hypothesis, step: StepData, extra: np.ndarray | None = None
    ) -> tuple[Hypothesis, list[float]]:
        """One filter step of a hypothesis: the updated one (the prior itself when the
        innovation is beyond the gate or the covariance broke), and the mean model powers (W)
        of the step's readings at the points ``extra`` (one state a row), from the same
        prediction."""
        s = self.settings
        try:
            drawn_p, sigmas = self._draw(prior.x, prior.p, step.moving)
        except np.linalg.LinAlgError:  # covariance lost positive definiteness: start it over
            self.resets += 1
            prior = Hypothesis(prior.x, np.diag(self._initial_var), prior.form, prior.loglik)
            drawn_p, sigmas = self._draw(prior.x, prior.p, step.moving)
        points = sigmas if extra is None else np.vstack([sigmas, extra])
        powers_w = self.powers_w(points, step.rows).mean(axis=1)
        n = len(sigmas)
        extra_w = powers_w[n:].tolist()
        try:
            post = self._points.update(
                prior.x, drawn_p, sigmas, powers_w[:n], step.measured_w, step.noise_var_w2
            )
        except np.linalg.LinAlgError:  # covariance lost positive definiteness: start it over
            self.resets += 1
            restart = Hypothesis(prior.x, np.diag(self._initial_var), prior.form, prior.loglik)
            return restart, extra_w
        y2, s_var = post.y**2, post.s_var
        nu = post.y / math.sqrt(s_var)
        loglik = prior.loglik - 0.5 * (y2 / s_var + math.log(s_var))
        if abs(nu) > s.gate_sigma:
            gated = Hypothesis(prior.x, prior.p, prior.form, loglik, nu, y2, s_var)
            return gated, extra_w
        x, p = post.x, 0.5 * (post.p + post.p.T)
        form = carried(prior.form, drawn_p, p) + post.gain * step.form_w
        if not step.moving:  # the wind was held: its uncertainty is what it was
            p[:2, :] = p[:, :2] = 0.0
            p[:2, :2] = prior.p[:2, :2]
        x[2] = max(x[2], (s.min_mass_fraction - 1.0) * self.mass_kg)
        wind_mps = math.hypot(x[0], x[1])
        if wind_mps > s.max_wind_mps:
            x[:2] *= s.max_wind_mps / wind_mps
        return Hypothesis(x, p, form, loglik, nu, y2, s_var), extra_w

    def _duel(self, first: Hypothesis, second: Hypothesis) -> tuple[Hypothesis, Hypothesis | None]:
        """Two hypotheses after a change in forward flight: the likelier one is the estimate,
        the other its rival until :func:`~estimator.estimation.hypotheses.duel` decides."""
        self._duel_steps += 1
        s = self.settings
        return duel(first, second, self._duel_steps, s.hypothesis_nats, s.hypothesis_max_steps)

    def _draw(self, x: np.ndarray, p: np.ndarray, moving: bool) -> tuple[np.ndarray, np.ndarray]:
        """The covariance the update uses and the sigma points drawn from it around the
        estimate ``x`` with covariance ``p``; not ``moving`` (hover), with the wind held at its
        estimate (see the module docstring)."""
        p = p.copy()
        if not moving:
            p[:2, :] = p[:, :2] = 0.0
            p[0, 0] = p[1, 1] = _HELD_VARIANCE
        return p, self._points.points(x, p)

    def _widened(self, p: np.ndarray, wind: bool) -> np.ndarray:
        """``p`` with the wind (``wind``) or else the mass back at its initial variance and no
        covariance with the rest; never narrower than it was."""
        p = p.copy()
        for i in (0, 1) if wind else (2,):
            var = max(float(p[i, i]), float(self._initial_var[i]))
            p[i, :] = p[:, i] = 0.0
            p[i, i] = var
        return p
