"""Online tracking of the effects that change during a flight: wind and mass.

:class:`OnlineEffects` is a small causal unscented Kalman filter (filterpy) over the state

    x = [w_n, w_e, δm]   air-mass velocity over ground (NED north/east, m/s) and the mass
                          difference from the vehicle file (kg),

each a random walk, observed through the measured electrical power: z = P(state; x) with
:func:`estimator.physics.effects.predict_power_w` (the vehicle's model, its other effects, and
``Wind``/``Mass`` built from x). It starts from the vehicle file's ``[effects.wind]`` and
``[effects.mass]`` (as written by ``uav-energy residuals --write``) and follows them as the
flight goes on: a changing wind, a payload picked up or dropped.

Robustness: the measurement noise is an absolute floor plus a fraction of the power plus the
kinetic term's uncertainty (m·V·σ_a from the kinematics filter) plus a learnt excess (the
squared innovations' surplus over their predicted variance, followed with gain
``noise_gain``: real power telemetry is noisier than a current sensor's datasheet says, and
model error looks like noise to the filter); an innovation beyond
``gate_sigma`` standard deviations is not used (counted in ``rejected``), nor are samples in
fast vertical motion (|v_z| > ``max_vertical_speed_mps``: take-off, landing, where the climb
term is the least certain part of the model; counted in ``vertical``) and readings below
``min_power_fraction_of_hover`` of the model's hover power (idle motors on the ground,
``idle``); when the recent
normalised innovations keep one sign (their mean over ``change_window`` samples is more than
``change_sigma`` standard errors from 0) the mass uncertainty is widened back to its initial
value so the filter can follow a payload step (``changes`` counts these).

A step takes one reading or several taken close together (:meth:`~OnlineEffects.update_readings`;
the pipeline gives it the readings of each ``track_period_s``): their mean measured power
against the mean of the predictions at each reading's own flight state, with the noise of a mean
(the learnt excess is not divided: model error does not average out). The sigma points and the
two hypotheses the pipeline scores (the estimate, the vehicle file's values) are predicted in
one vectorized call per step.

Identifiability: wind direction needs flight in more than one direction; in hover only the
wind speed is seen, and a hover power offset is shared between wind and mass until the vehicle
moves. The filter carries this in its covariance (``sigma``).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from estimator.logs import FlightSeries
from estimator.physics.effects import (
    Effect,
    FlightState,
    Mass,
    SampleMass,
    Wind,
    effects_from_tables,
    predict_power_w,
)
from estimator.physics.kinematics import KinematicsFilter, KinematicState
from estimator.physics.model import PowerModel
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    RebootSample,
    Sample,
    VelocitySample,
)

#: Below this height over home (m) the vehicle is on the ground (no update).
AIRBORNE_ALT_M = 1.0


def wind_from_vector(wn_mps: float, we_mps: float) -> Wind:
    """The :class:`Wind` whose air mass moves over ground at (north, east) m/s."""
    speed = math.hypot(wn_mps, we_mps)
    from_deg = math.degrees(math.atan2(-we_mps, -wn_mps)) % 360.0 if speed > 0 else 0.0
    return Wind(speed_mps=speed, from_deg=from_deg)


class TrackerReading(NamedTuple):
    """One measured power (W) with the filtered flight state then and the battery voltage
    (V, NaN unknown)."""

    state: KinematicState
    measured_power_w: float
    voltage_v: float = math.nan


@dataclass(frozen=True)
class OnlineSettings:
    """Tuning (SI units). Process noises are random-walk densities per √s."""

    wind_walk_mps_per_sqrt_s: float = 0.03
    mass_walk_kg_per_sqrt_s: float = 0.002
    initial_wind_sigma_mps: float = 3.0
    initial_mass_sigma_fraction: float = 0.15
    power_noise_w: float = 5.0
    power_noise_fraction: float = 0.03
    gate_sigma: float = 5.0
    max_vertical_speed_mps: float = 1.0
    #: Power below this fraction of the model's hover power is not flight (idle motors).
    min_power_fraction_of_hover: float = 0.3
    #: Gain of the adaptive measurement-noise estimate (per power sample).
    noise_gain: float = 0.02
    change_window: int = 30
    change_sigma: float = 5.0
    #: Mass may not drop below this fraction of the vehicle file's.
    min_mass_fraction: float = 0.3
    #: No multirotor flies in more wind than this (m/s): the estimate is held below it.
    max_wind_mps: float = 15.0


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
    ) -> None:
        self.model, self.mass_kg = model, float(mass_kg)
        self.settings = s = settings or OnlineSettings()
        wind = next((e for e in effects if isinstance(e, Wind)), Wind())
        mass = next((e for e in effects if isinstance(e, Mass)), Mass())
        self.others = tuple(e for e in effects if not isinstance(e, Wind | Mass))
        wn, we = wind.vector_ne_mps()
        self._file_wind_ne_mps, self._file_mass = (wn, we), mass
        # a stepped mass from the file has not happened yet at take-off
        delta0 = mass.delta_kg if mass.at_s is None else 0.0
        points = MerweScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
        self._sigma_powers_w: Iterator[float] = iter(())
        self._ukf = UnscentedKalmanFilter(
            3, 1, 1.0, hx=self._next_sigma_power, fx=_identity, points=points
        )
        self._ukf.x = np.array([wn, we, delta0])
        self._initial_var = np.array(
            [
                s.initial_wind_sigma_mps**2,
                s.initial_wind_sigma_mps**2,
                (s.initial_mass_sigma_fraction * self.mass_kg) ** 2,
            ]
        )
        self._ukf.P = np.diag(self._initial_var)
        self._time_s: float | None = None
        self._recent: deque[float] = deque(maxlen=s.change_window)
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
        #: Times the covariance was restarted after losing positive definiteness (bad data).
        self.resets = 0

    @classmethod
    def from_vehicle(
        cls, vehicle: Vehicle, extra: Sequence[Effect] = (), settings: OnlineSettings | None = None
    ) -> OnlineEffects:
        """Start from the vehicle file's model, mass and effects (plus ``extra`` ones, e.g. the
        pipeline's default climb)."""
        effects = [*effects_from_tables(vehicle.effects), *extra]
        return cls(vehicle.model, vehicle.mass_kg, effects, settings)

    # -- current estimate ----------------------------------------------------------------------

    @property
    def wind(self) -> Wind:
        return wind_from_vector(float(self._ukf.x[0]), float(self._ukf.x[1]))

    @property
    def mass_delta_kg(self) -> float:
        return float(self._ukf.x[2])

    @property
    def mass_ratio(self) -> float:
        """Actual over the vehicle file's mass."""
        return (self.mass_kg + self.mass_delta_kg) / self.mass_kg

    @property
    def sigma(self) -> dict[str, float]:
        """1σ of the wind components (m/s) and of the mass difference (kg)."""
        sd = np.sqrt(np.clip(np.diag(self._ukf.P), 0.0, None))
        return {"wind_n_mps": float(sd[0]), "wind_e_mps": float(sd[1]), "mass_kg": float(sd[2])}

    @property
    def effects(self) -> tuple[Effect, ...]:
        """Effects to predict power with now (frame effects first)."""
        return self._effects(self._ukf.x)

    def _effects(self, x: np.ndarray) -> tuple[Effect, ...]:
        return (wind_from_vector(float(x[0]), float(x[1])), Mass(float(x[2])), *self.others)

    # -- filter --------------------------------------------------------------------------------

    def _powers_w(self, points: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Model power (W) at each flight state of ``rows`` (k × 8, the FlightState fields)
        for each hypothesis [w_n, w_e, δm] of ``points`` (m × 3): an m × k array, from one
        prediction. The wind is taken out of the velocity (what :class:`Wind` does), the mass
        goes in as :class:`SampleMass`."""
        m, k = len(points), len(rows)
        columns = np.tile(rows.T, m)  # 8 × (m·k), hypothesis-major
        columns[1] -= np.repeat(points[:, 0], k)
        columns[2] -= np.repeat(points[:, 1], k)
        floor_kg = (self.settings.min_mass_fraction - 1.0) * self.mass_kg
        mass = SampleMass(np.repeat(np.maximum(points[:, 2], floor_kg), k))
        state = FlightState(*columns)
        return predict_power_w(self.model, self.mass_kg, state, (mass, *self.others)).reshape(m, k)

    def _next_sigma_power(self, _point: np.ndarray) -> np.ndarray:
        """filterpy's hx. The powers of all sigma points are predicted together before each
        update (:meth:`_powers_w`); filterpy then asks for them one point at a time, in the
        order of ``sigmas_f``."""
        return np.array([next(self._sigma_powers_w)])

    def restart_clock(self) -> None:
        """The autopilot rebooted: readings come on a new clock (the estimate is kept)."""
        self._time_s = None

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
        return self.update_readings([TrackerReading(state, measured_power_w, voltage_v)])

    def update_kinematics(
        self, state: KinematicState, measured_power_w: float, voltage_v: float = math.nan
    ) -> tuple[Effect, ...]:
        """:meth:`update` from the pipeline's filtered kinematic state."""
        return self.update_readings([TrackerReading(state, measured_power_w, voltage_v)])

    def update_readings(self, readings: Sequence[TrackerReading]) -> tuple[Effect, ...]:
        """Fold in readings taken close together (in time order) in one filter step: their
        mean measured power against the mean of the powers predicted at each reading's own
        flight state, with the noise of a mean. While the estimate moves little between
        the readings this carries what they would carry one by one, at the cost of one step.
        Readings that are not finite or go back in time (``rejected``), in fast vertical
        motion (``vertical``) or below the idle power (``idle``) are left out.

        Returns :attr:`effects` after the update.
        """
        s = self.settings
        kept = []
        for r in readings:
            st = r.state
            motion = (st.time_s, st.vn_mps, st.ve_mps, st.vd_mps, st.an_mps2, st.ae_mps2)
            if not all(math.isfinite(v) for v in (*motion, r.measured_power_w)) or (
                self._time_s is not None and st.time_s < self._time_s
            ):
                self.rejected += 1
            elif abs(st.vd_mps) > s.max_vertical_speed_mps:
                self.vertical += 1
            elif r.measured_power_w < s.min_power_fraction_of_hover * self._hover_w:
                self.idle += 1
            else:
                kept.append((r, motion))
        if not kept:
            return self.effects
        self.steps += 1
        ukf = self._ukf
        time_s = kept[-1][0].state.time_s
        dt = 0.0 if self._time_s is None else time_s - self._time_s
        self._time_s = time_s
        # predict even when dt = 0: it draws the sigma points the update evaluates
        wind_q = s.wind_walk_mps_per_sqrt_s**2 * dt
        ukf.Q = np.diag([wind_q, wind_q, s.mass_walk_kg_per_sqrt_s**2 * dt])
        try:
            ukf.predict(dt=dt)
        except np.linalg.LinAlgError:
            ukf.P = np.diag(self._initial_var)
            self.resets += 1
            ukf.predict(dt=dt)
        rows = np.array([(*motion, 0.0, r.voltage_v) for r, motion in kept], dtype=float)
        measured = np.array([r.measured_power_w for r, _ in kept])
        file_mass = self._file_mass
        file_delta_kg = file_mass.delta_kg * (file_mass.at_s is None or time_s >= file_mass.at_s)
        hypotheses = [ukf.x, [*self._file_wind_ne_mps, file_delta_kg]]
        powers_w = self._powers_w(np.vstack([ukf.sigmas_f, *hypotheses]), rows).mean(axis=1)
        self._sigma_powers_w = iter(powers_w[:-2].tolist())
        measured_w = float(measured.mean())
        self.last_step_w = (measured_w, float(powers_w[-2]), float(powers_w[-1]))
        kinetic_sd = self.mass_kg * np.array(
            [r.state.speed_mps * r.state.accel_sigma_mps2 for r, _ in kept]
        )
        r_each = s.power_noise_w**2 + (s.power_noise_fraction * measured) ** 2 + kinetic_sd**2
        noise_var_w2 = float(r_each.sum()) / len(kept) ** 2 + self.extra_noise_var_w2
        x_prior, p_prior = ukf.x.copy(), ukf.P.copy()
        try:
            ukf.update(np.array([measured_w]), R=np.array([[noise_var_w2]]))
        except np.linalg.LinAlgError:  # covariance lost positive definiteness: start it over
            ukf.x, ukf.P = x_prior, np.diag(self._initial_var)
            self.resets += 1
            return self.effects
        ukf.P = 0.5 * (ukf.P + ukf.P.T)
        y2, s_var = float(ukf.y[0]) ** 2, float(ukf.S[0, 0])
        nu = float(ukf.y[0]) / math.sqrt(s_var)
        # adaptive measurement noise: drive E[y²] towards S (outliers clipped at the gate)
        excess = min(y2, s.gate_sigma**2 * s_var) - s_var
        self.extra_noise_var_w2 = max(0.0, self.extra_noise_var_w2 + s.noise_gain * excess)
        if abs(nu) > s.gate_sigma:
            ukf.x, ukf.P = x_prior, p_prior
            self.rejected += 1
        else:
            self.updates += 1
        self._recent.append(nu)
        self._check_change()
        ukf.x[2] = max(ukf.x[2], (s.min_mass_fraction - 1.0) * self.mass_kg)
        wind_mps = math.hypot(ukf.x[0], ukf.x[1])
        if wind_mps > s.max_wind_mps:
            ukf.x[:2] *= s.max_wind_mps / wind_mps
        return self.effects

    def _check_change(self) -> None:
        """Widen the mass uncertainty back to the initial one when recent innovations keep one
        sign (a payload step); never beyond it."""
        s = self.settings
        if len(self._recent) < s.change_window:
            return
        mean = float(np.mean(self._recent))
        if abs(mean) * math.sqrt(len(self._recent)) > s.change_sigma:
            # only the mass steps (payload); wind changes slowly and follows its random walk
            raise_by = max(self._initial_var[2] - float(self._ukf.P[2, 2]), 0.0)
            self._ukf.P[2, 2] += raise_by
            self._recent.clear()
            self.changes += 1


def _identity(x: np.ndarray, dt: float) -> np.ndarray:
    return x


# -- offline runner ---------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackPoint:
    """The tracker's estimate after one update: time (s), wind (m/s, deg from), mass (kg)."""

    time_s: float
    wind_speed_mps: float
    wind_from_deg: float
    mass_delta_kg: float
    mass_sigma_kg: float


class _Runner:
    """Feeds a tracker the daemon's way: causal kinematics on velocity, an update per
    airborne power reading with the latest state (not older than ``max_age_s``)."""

    def __init__(self, tracker: OnlineEffects, max_age_s: float = 1.0) -> None:
        self.tracker = tracker
        self.max_age_s = max_age_s
        self.kinematics = KinematicsFilter()
        self.state: KinematicState | None = None
        self.armed: bool | None = None
        self.points: list[TrackPoint] = []

    def velocity(self, sample: VelocitySample) -> None:
        self.state = self.kinematics.update(sample)

    def reboot(self) -> None:
        self.kinematics.reset()
        self.state, self.armed = None, None

    def power(self, time_s: float, power_w: float, voltage_v: float) -> None:
        state = self.state
        if state is None or self.armed is False or time_s - state.time_s > self.max_age_s:
            return
        if state.alt_m is not None and state.alt_m < AIRBORNE_ALT_M:
            return
        tracker = self.tracker
        tracker.update_kinematics(state, power_w, voltage_v)
        wind = tracker.wind
        self.points.append(
            TrackPoint(
                time_s,
                wind.speed_mps,
                wind.from_deg,
                tracker.mass_delta_kg,
                tracker.sigma["mass_kg"],
            )
        )


def track_samples(samples: Iterable[Sample], tracker: OnlineEffects) -> list[TrackPoint]:
    """Run ``tracker`` over a log's samples the way the daemon would: the causal kinematics
    filter on velocity, an update at each airborne battery sample with a current reading."""
    runner = _Runner(tracker)
    for sample in samples:
        if isinstance(sample, VelocitySample):
            runner.velocity(sample)
        elif isinstance(sample, ArmedSample):
            runner.armed = sample.armed
        elif isinstance(sample, RebootSample):
            runner.reboot()
        elif isinstance(sample, BatterySample) and sample.power_w is not None:
            runner.power(sample.time_s, sample.power_w, sample.voltage_v)
    return runner.points


def track_series(series: FlightSeries, tracker: OnlineEffects) -> list[TrackPoint]:
    """:func:`track_samples` over a flight already read into arrays (one row = a velocity
    then a power reading; rows flagged disarmed in ``extras['armed']`` are skipped)."""
    runner = _Runner(tracker)
    armed = series.extras.get("armed", np.full(len(series), np.nan))
    for k in range(len(series)):
        vn, ve = float(series.vn_mps[k]), float(series.ve_mps[k])
        if not (math.isfinite(vn) and math.isfinite(ve)):
            continue
        alt = float(series.alt_m[k])
        vd = float(series.vd_mps[k])
        t = float(series.time_s[k])
        runner.velocity(
            VelocitySample(
                t, vn, ve, vd if math.isfinite(vd) else 0.0, alt if math.isfinite(alt) else None
            )
        )
        runner.armed = None if not math.isfinite(armed[k]) else bool(armed[k])
        runner.power(t, float(series.power_w[k]), float(series.voltage_v[k]))
    return runner.points
