"""The model's power as the pipeline uses it: every prediction goes through
:func:`~estimator.physics.effects.predict_power_w`, with the effects in use (the vehicle
file's, or the wind and mass tracked online while they predict the measured power better),
along the course flown and in the turn held (:mod:`estimator.estimation.held_turn`); and the
hover power, V_me and V_mr with those effects.

Frames and units: velocities NED (m/s), accelerations horizontal NED (m/s²), power at the
battery terminals (W), course over ground in rad from north.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from estimator.estimation.courses_flown import CoursesFlown
from estimator.estimation.held_turn import HeldTurn
from estimator.estimation.online_effects import OnlineEffects
from estimator.physics.effects import Effect, FlightState, predict_power_w
from estimator.physics.kinematics import KinematicState
from estimator.physics.vehicle import Vehicle

#: Speeds (m/s) on which V_me and V_mr are searched, with the effects in use.
_SPEED_GRID_MPS = np.linspace(0.0, 30.0, 601)
#: Above this horizontal speed (m/s) the course over ground is the direction of flight.
_TRACK_MIN_SPEED_MPS = 1.0
#: Tracked wind and mass replace the file's while they predict the measured power better (one
#: step ahead) than the file's, each part once it is known: the wind (or its component along
#: the track flown) to this 1σ (m/s), the mass to this fraction of the vehicle's (1σ).
#: Before that (hover, one-direction flight) wind and mass trade off against each other and
#: the point estimate is biased by the curvature of P(V).
_TRACKED_WIND_SIGMA_MPS = 1.0
_TRACKED_MASS_SIGMA_FRACTION = 0.05
#: Faster than this along the track (m/s², either sign) the vehicle is changing speed: the
#: speed it flies is not one it holds, and does not count among the courses held.
_CHANGING_SPEED_MPS2 = 1.0
#: Gain of the moving averages that score tracked against vehicle-file effects (per update).
_SCORE_GAIN = 1.0 / 30.0


@dataclass(frozen=True, slots=True)
class PowerEvent:
    """A sample that changes the model power: a new kinematic state (None after a reboot),
    the armed state then (None = unknown) and the battery voltage then (V, NaN unknown)."""

    time_s: float
    state: KinematicState | None
    armed: bool | None
    voltage_v: float


class _Ahead(NamedTuple):
    """The endurance's mean as a period's prediction made it: with ``effects``, the rows and
    weights (:meth:`FlightPower._mean_rows`; None: the steady power) and their mean (W)."""

    effects: tuple[Effect, ...]
    mean: tuple[np.ndarray, np.ndarray] | None
    mean_w: float | None


class FlightPower:
    """The effects in use and the model power of the flight with them."""

    def __init__(self, vehicle: Vehicle, file_effects: tuple[Effect, ...]) -> None:
        self.vehicle = vehicle
        self.file_effects = file_effects
        self.effects = file_effects
        #: One-step-ahead squared power errors (W², moving averages) of the tracked effects
        #: and of the vehicle file's: the tracked ones are used only while they predict better.
        self.tracked_sq_w2 = 0.0
        self.file_sq_w2 = 0.0
        self.track_rad = 0.0  # course over ground (the last one while moving)
        self.courses = CoursesFlown()
        self._held_w = 0.0  # the endurance's last figure at a speed held, W
        #: While the vehicle changes speed: how far (fraction) the endurance's figure is from
        #: the one at the speed held before the change; 0 otherwise.
        self.change_spread = 0.0
        self._held_turn = HeldTurn()
        self.held_accel_mps2 = 0.0  # the a⊥ steady figures assume, m/s²
        #: The endurance's mean made with the period's prediction (:meth:`event_powers_w`).
        self._ahead: _Ahead | None = None
        self.v_me_mps = self.v_mr_mps = 0.0
        self.p_hover_w = self.p_me_w = self.p_mr_w = 0.0

    def observe(self, state: KinematicState) -> None:
        """A new kinematic state: the turn held follows it."""
        self.held_accel_mps2 = self._held_turn.update(state.time_s, state.accel_centripetal_mps2)

    def follow_track(self, state: KinematicState | None) -> None:
        """The course over ground of ``state`` while it moves (else the last one kept), and
        the speed and course flown."""
        if state is None:
            return
        if state.speed_mps > _TRACK_MIN_SPEED_MPS:
            self.track_rad = math.atan2(state.ve_mps, state.vn_mps)
        held = abs(state.accel_tangential_mps2) <= _CHANGING_SPEED_MPS2
        self.courses.record(state.time_s, state.speed_mps, self.track_rad, held)

    def restart(self) -> None:
        """The autopilot's clock moved: the turn held is forgotten."""
        self._held_turn.reset()
        self.held_accel_mps2 = 0.0
        self._held_w = self.change_spread = 0.0

    def predict(
        self,
        states: Sequence[KinematicState],
        steady_speeds_mps: np.ndarray,
        latest_v: float,
        accel_centripetal_mps2: float = 0.0,
        voltages_v: Sequence[float] = (),
        time_s: float = 0.0,
        effects: Sequence[Effect] | None = None,
        tracks_rad: np.ndarray | None = None,
    ) -> np.ndarray:
        """Model power (W, ≥ 0): one row per kinematic state (at its battery voltage in
        ``voltages_v``, V, else ``latest_v``), then level flight at each steady speed along
        the course (it matters in wind) in a steady turn of a⊥ ``accel_centripetal_mps2``, at
        ``time_s`` and ``latest_v``; with ``effects`` (default: those in use); along
        ``tracks_rad`` (one course per steady speed, rad from north) instead."""
        rows = self._rows(
            states, steady_speeds_mps, latest_v, accel_centripetal_mps2, voltages_v, time_s,
            tracks_rad,
        )  # fmt: skip
        return self._predict_rows(rows, effects)

    def _rows(
        self,
        states: Sequence[KinematicState],
        steady_speeds_mps: np.ndarray,
        latest_v: float,
        accel_centripetal_mps2: float,
        voltages_v: Sequence[float],
        time_s: float,
        tracks_rad: np.ndarray | None,
    ) -> np.ndarray:
        """The flight states :meth:`predict` predicts, one row each (the
        :class:`~estimator.physics.effects.FlightState` fields in order)."""
        k = len(states)
        rows = np.empty((k + len(steady_speeds_mps), 9))
        if k:
            rows[:k] = [
                (s.time_s, s.vn_mps, s.ve_mps, s.vd_mps, s.an_mps2, s.ae_mps2, 0.0, v, s.ad_mps2)
                for s, v in zip(states, voltages_v or [latest_v] * k, strict=True)
            ]
        # steady rows: level, along the track, a⊥ across it
        if tracks_rad is None:  # one course for all (scalars: the per-sample path)
            north, east = math.cos(self.track_rad), math.sin(self.track_rad)
            a = accel_centripetal_mps2
            rows[k:] = (time_s, 0.0, 0.0, 0.0, -east * a, north * a, 0.0, latest_v, 0.0)
        else:
            north, east = np.cos(tracks_rad), np.sin(tracks_rad)
            rows[k:] = (time_s, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, latest_v, 0.0)
            rows[k:, 4] = -east * accel_centripetal_mps2
            rows[k:, 5] = north * accel_centripetal_mps2
        rows[k:, 1] = north * steady_speeds_mps
        rows[k:, 2] = east * steady_speeds_mps
        return rows

    def _predict_rows(
        self, rows: np.ndarray, effects: Sequence[Effect] | None = None
    ) -> np.ndarray:
        """Model power (W, ≥ 0) of each row of :meth:`_rows` with ``effects`` (default: those
        in use)."""
        flight = FlightState.of_columns(rows.T)
        if effects is None:
            effects = self.effects
        power = predict_power_w(self.vehicle.model, self.vehicle.mass_kg, flight, effects)
        return np.maximum(power, 0.0)

    def event_powers_w(
        self,
        events: Sequence[PowerEvent],
        state: KinematicState | None,
        armed: bool | None,
        latest_v: float,
        time_s: float,
        endurance: bool = False,
    ) -> tuple[list[float], float]:
        """Model power after each of ``events`` (W), in one prediction, and the steady power
        of ``state``, the latest kinematic state (W, at ``time_s``; ``armed`` then, ``latest_v``
        the newest battery voltage). Disarmed: 0; armed with no kinematic state yet: hover.
        With ``endurance`` (a period's close, whose estimate follows), the same prediction
        also makes the mean :meth:`endurance_w` then takes, while the effects stay those in
        use."""
        self._ahead = None
        rows = [e for e in events if e.state is not None and e.armed is not False]
        steady = state is not None and armed is not False
        predicted: list[float] = []
        if rows or steady:
            self.follow_track(state)
            event_states = [e.state for e in rows if e.state is not None]
            speeds = np.array([state.speed_mps] if steady and state is not None else [])
            voltages_v = [e.voltage_v for e in rows]
            accel = self.held_accel_mps2
            now = self._rows(event_states, speeds, latest_v, accel, voltages_v, time_s, None)
            mean = mean_w = None
            if endurance and steady and state is not None:
                mean = self._mean_rows(state, latest_v, time_s)
            if mean is None:
                predicted = self._predict_rows(now).tolist()
            else:  # one prediction for both
                power = self._predict_rows(np.concatenate((now, mean[0])))
                mean_w = float(power[len(now) :] @ mean[1])
                predicted = power[: len(now)].tolist()
            if endurance and steady:
                self._ahead = _Ahead(self.effects, mean, mean_w)
        idle_w = 0.0 if armed is False else self.p_hover_w
        steady_w = predicted.pop() if steady else idle_w
        rows_w = iter(predicted)
        hover_w = self.p_hover_w
        powers_w = [
            0.0 if e.armed is False else hover_w if e.state is None else next(rows_w)
            for e in events
        ]
        return powers_w, steady_w

    def steady_w(self, speed_mps: float, time_s: float, latest_v: float) -> float:
        """Model power (W) in steady level flight at ``speed_mps`` along the course, in the
        turn held."""
        speed = np.array([speed_mps])
        return float(self.predict((), speed, latest_v, self.held_accel_mps2, time_s=time_s)[0])

    def hover_w(self, latest_v: float, effects: Sequence[Effect]) -> float:
        """Model power (W) in hover with ``effects`` (at time 0, ``latest_v``)."""
        return float(self.predict((), np.zeros(1), latest_v, effects=effects)[0])

    def endurance_w(
        self, state: KinematicState, steady_w: float, time_s: float, latest_v: float
    ) -> float:
        """Model power (W) the endurance holds: while the flight repeats a pattern, its mean
        over the last period as flown (each speed and course, no turn); else the courses'
        mean at the present speed (:meth:`course_mean_w`), or the steady power ``steady_w``
        (W) when none was flown or while the vehicle changes speed (a speed it does not
        hold; :attr:`change_spread` says how far that is from the figure before). The mean
        is the one :meth:`event_powers_w` made, unless the effects changed since."""
        self.change_spread = 0.0
        ahead, self._ahead = self._ahead, None
        if ahead is None:  # not made with a period's prediction
            mean, mean_w = self._mean_rows(state, latest_v, time_s), None
        else:  # the same rows; predicted again when the effects changed
            mean, mean_w = ahead.mean, ahead.mean_w if ahead.effects is self.effects else None
        if mean is not None and mean_w is None:
            mean_w = float(self._predict_rows(mean[0]) @ mean[1])
        if mean_w is not None:
            self._held_w = mean_w
        elif self.courses.pattern() is None and abs(state.accel_tangential_mps2) > (
            _CHANGING_SPEED_MPS2
        ):
            if self._held_w > 0 and steady_w > 0:
                self.change_spread = abs(steady_w - self._held_w) / steady_w
            return steady_w
        else:
            self._held_w = steady_w
        return self._held_w

    def _mean_rows(
        self, state: KinematicState, latest_v: float, time_s: float
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The rows (:meth:`_rows`) whose weighted mean the endurance holds, and their
        weights (summing to 1): the pattern's last period as flown, else the courses held
        at the present speed (:meth:`_course_rows`); None: neither (the steady power)."""
        pattern = self.courses.pattern()
        if pattern is not None:
            speeds, tracks_rad, weights = pattern
            return self._rows((), speeds, latest_v, 0.0, (), time_s, tracks_rad), weights
        if abs(state.accel_tangential_mps2) > _CHANGING_SPEED_MPS2:
            return None
        return self._course_rows(state.speed_mps, latest_v, time_s)

    def _course_rows(
        self, speed_mps: float, latest_v: float, time_s: float
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """Rows of steady level flight at ``speed_mps`` in the turn held along each course
        held lately at about that speed (:mod:`estimator.estimation.courses_flown`), and the
        fraction of them on each; None when none was."""
        tracks_rad, weights = self.courses.near(speed_mps)
        if not len(tracks_rad):
            return None
        speeds = np.full(len(tracks_rad), speed_mps)
        accel = self.held_accel_mps2
        return self._rows((), speeds, latest_v, accel, (), time_s, tracks_rad), weights

    def course_mean_w(self, speed_mps: float, time_s: float, latest_v: float) -> float | None:
        """Model power (W) in steady level flight at ``speed_mps`` in the turn held, averaged
        over the courses held lately at about that speed (:meth:`_course_rows`); None when
        none was."""
        course = self._course_rows(speed_mps, latest_v, time_s)
        return None if course is None else float(self._predict_rows(course[0]) @ course[1])

    def refresh_speeds(self, time_s: float, latest_v: float) -> None:
        """V_me, V_mr and their powers, and the hover power, with the effects in use."""
        power = self.predict((), _SPEED_GRID_MPS, latest_v, time_s=time_s)
        i_me = int(np.argmin(power))
        i_mr = int(np.argmin(power[1:] / _SPEED_GRID_MPS[1:])) + 1
        self.v_me_mps, self.v_mr_mps = float(_SPEED_GRID_MPS[i_me]), float(_SPEED_GRID_MPS[i_mr])
        self.p_me_w, self.p_mr_w = float(power[i_me]), float(power[i_mr])
        self.p_hover_w = float(power[0])

    def choose(self, online: OnlineEffects) -> tuple[Effect, ...] | None:
        """After a step of the online tracker: score the tracked and the file's effects on
        its readings (as predicted before the step) and give the effects to use from now on
        (the file's when the tracked ones predict worse; the tracked ones once identified),
        or None to keep those in use."""
        measured_w, tracked_w, file_w = online.last_step_w
        self.tracked_sq_w2 += _SCORE_GAIN * ((measured_w - tracked_w) ** 2 - self.tracked_sq_w2)
        self.file_sq_w2 += _SCORE_GAIN * ((measured_w - file_w) ** 2 - self.file_sq_w2)
        if self.tracked_sq_w2 >= self.file_sq_w2:
            chosen = self.file_effects  # the tracker went astray: the file's model is better
        else:
            identified = online.identified_effects(
                self.track_rad,
                _TRACKED_WIND_SIGMA_MPS,
                _TRACKED_MASS_SIGMA_FRACTION * self.vehicle.mass_kg,
                self.effects,
            )
            if identified is None:
                return None  # nothing identified (yet, or since a change)
            chosen = identified
        return None if chosen == self.effects else chosen
