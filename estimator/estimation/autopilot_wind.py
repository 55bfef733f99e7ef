"""The autopilot's own wind estimate as a measurement for the online tracker
(:mod:`estimator.estimation.online_effects`).

The autopilot's wind (ArduPilot WIND from its EKF's drag or airspeed fusion, PX4 WIND_COV;
:meth:`~estimator.estimation.online_effects.OnlineEffects.take_autopilot_wind`) is a second
channel: before each step the latest report, when at most ``autopilot_wind_max_age_s`` old, is
a linear measurement of the wind states (H = [I₂ 0]). Its errors are slow (the EKF's), not
white: each step takes it with the variance σ² · ``autopilot_wind_correlation_s`` / Δt, so a
minute of reports weighs as one measurement of 1σ ``autopilot_wind_sigma_mps``. Through the
covariance it also moves the mass: where power alone sees only a combination (at a constant
power on one leg, a lower airspeed and a heavier vehicle look alike), the report separates
them. An autopilot that does not estimate the wind (ArduCopter without drag fusion or an
airspeed sensor) reports exactly zero: reports count only once one above
``autopilot_wind_active_mps`` has come since boot. A report far from the estimate on several
steps in a row is a wind change the autopilot saw (:meth:`AutopilotWind.saw_a_change`).

The report lags the wind: the EKF follows a change with a time constant of ~10 s (ArduCopter
SITL: 9 s after an onset, 15 s after a stop; docs/residuals.md). While it moves, the wind
already differs from it by about the lag times its rate (a first-order lag r' = (w − r)/τ gives
w − r = τ r'): :meth:`AutopilotWind.lag_mps`. The rate r' is the report's change over the
last ``autopilot_wind_rate_span_s``, measured at every report (measured once a span, it
showed a change up to a span late: ArduCopter SITL, the first steps after a wind change were
3.1-4.8σ on nine flights where they are now within 3σ), and only from reports of an autopilot
already estimating the wind (:meth:`AutopilotWind._rate_to`). That gap closes at the lag's own pace,
e^(−t/τ), not faster: where the report stalls for a moment as it follows a change (ArduCopter
SITL: 2 m/s into a 7 m/s gust, held still 3.5 s, then rising on), its rate over the last
seconds falls to zero while the wind is still far, so the term is the larger of τ r' and
its last value decayed by e^(−Δt/τ), per component. The term is the magnitude of the two and
widens both components alike: the EKF's components follow a change at their own paces
(ArduCopter SITL, held5_turn_legs: a wind of 6 m/s turning from 330° to 060° during legs; the
report's north moved 2.2 m/s in 10 s while its east held its old value, 8.5 m/s from the
wind's, for 30 s), so the direction the report moves in does not say which way the wind
moved. And it can stop: in hover ArduCopter's EKF holds its wind (an onset or a stop
arrives only once the vehicle moves), so while the vehicle hovers (the tracker's last step)
the lag term holds as well instead of decaying: the gap it stands for closes only once the
EKF follows again (ArduCopter SITL, held5_turn_legs: the wind turned 8 m/s away as a 24 s
hover began; the report's east component held its old value through it while the term
decayed, and the steps from 14 to 32 s after the turn were 3.0-9.4σ). Where the report and
the tracker's wind disagree beyond both their 1σ, one of them is likely wrong, the more so
the further apart they are: :meth:`AutopilotWind.gap_ne_mps`. The tracker adds both to the
1σ it reports, not to its covariance (its estimate is unchanged).

States: the tracker's [w_n, w_e, …] (NED m/s first, then its other states); times in s of
the autopilot's clock.
"""

from __future__ import annotations

import math
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from estimator.estimation.hypotheses import second_probability
from estimator.telemetry.samples import WindSample

if TYPE_CHECKING:
    from estimator.estimation.online_settings import OnlineSettings


def mahalanobis2(d: np.ndarray, cov: np.ndarray) -> float:
    """dᵀ cov⁻¹ d: the squared Mahalanobis distance of ``d`` under ``cov``."""
    return float(d @ np.linalg.solve(cov, d))


class AutopilotWind:
    """The latest wind report of the autopilot and how it enters the tracker's state."""

    def __init__(self, settings: OnlineSettings) -> None:
        self.settings = settings
        self.report: WindSample | None = None
        self._active = False  # it has reported a wind since boot
        self._apart = 0  # steps in a row its report was far from the estimate
        #: The reports of the last two rate spans, oldest first: the rate's anchors.
        self._recent: deque[WindSample] = deque()
        self._rate_ne_mps2 = (0.0, 0.0)
        #: The lag term (m/s, magnitudes) at the last report, and that report's time (s).
        self._lag_ne_mps, self._lag_time_s = (0.0, 0.0), 0.0
        #: The vehicle hovers (the tracker's last step): the EKF holds its wind, so the lag
        #: term holds too (:meth:`lag_mps`).
        self.hovering = False

    def take(self, sample: WindSample) -> None:
        """Keep ``sample`` for the next steps (non-finite values are ignored)."""
        wind = (sample.wind_n_mps, sample.wind_e_mps)
        if not all(math.isfinite(v) for v in (sample.time_s, *wind)):
            return
        self.report = sample
        was_active = self._active
        self._active |= math.hypot(*wind) > self.settings.autopilot_wind_active_mps
        self._rate_ne_mps2 = self._rate_to(sample, was_active)
        self._lag_ne_mps = self._lag_at(sample.time_s)
        self._lag_time_s = sample.time_s

    def _rate_to(self, sample: WindSample, was_active: bool) -> tuple[float, float]:
        """The report's rate (m/s², north and east) at ``sample``, over the last
        ``autopilot_wind_rate_span_s``: from the latest report at least that old, none older
        than twice that (zero without one). Only reports of an autopilot that already
        estimated the wind count: its step from the zero it reported before is no change it
        follows (ArduCopter SITL: 0 to 8.5 m/s in one report at take-off in a 9 m/s wind, read
        as a lag of 24 m/s for the take-off hover)."""
        span_s, recent = self.settings.autopilot_wind_rate_span_s, self._recent
        if not was_active or (recent and sample.time_s < recent[-1].time_s):
            recent.clear()
        recent.append(sample)
        while len(recent) > 1 and sample.time_s - recent[1].time_s >= span_s:
            recent.popleft()  # the next one is old enough to be the anchor
        anchor = recent[0]
        dt = sample.time_s - anchor.time_s
        if dt > 2.0 * span_s:
            recent.popleft()  # a gap in the reports: too old to be an anchor
        if not span_s <= dt <= 2.0 * span_s:
            return 0.0, 0.0
        return (
            (sample.wind_n_mps - anchor.wind_n_mps) / dt,
            (sample.wind_e_mps - anchor.wind_e_mps) / dt,
        )

    def lag_mps(self, time_s: float) -> float:
        """How far the wind may already be from the latest report, in any direction (m/s):
        per component, the report's rate over the last ``autopilot_wind_rate_span_s`` times
        the EKF's time constant ``autopilot_wind_lag_s``, or the last such term decayed at the
        lag's own pace when that is larger; the magnitude of the two (module docstring). Zero
        without a fresh report from an autopilot that estimates the wind."""
        if not self.fresh(time_s):
            return 0.0
        return math.hypot(*self._lag_at(time_s))

    def _lag_at(self, time_s: float) -> tuple[float, float]:
        """The lag term at ``time_s`` (m/s, magnitudes): τ times the report's rate, or the last
        term decayed at the lag's own pace, whichever is larger."""
        lag_s = self.settings.autopilot_wind_lag_s
        held = 1.0 if self.hovering else math.exp(-max(time_s - self._lag_time_s, 0.0) / lag_s)
        return (
            max(abs(lag_s * self._rate_ne_mps2[0]), self._lag_ne_mps[0] * held),
            max(abs(lag_s * self._rate_ne_mps2[1]), self._lag_ne_mps[1] * held),
        )

    def restart(self) -> None:
        """The autopilot rebooted: its reports count again once they are not zero."""
        self.report, self._active = None, False
        self._recent.clear()
        self._rate_ne_mps2 = (0.0, 0.0)
        self._lag_ne_mps, self._lag_time_s = (0.0, 0.0), 0.0
        self.hovering = False

    def fresh(self, time_s: float) -> bool:
        """Whether there is a report at most ``autopilot_wind_max_age_s`` old at ``time_s`` from
        an autopilot that estimates the wind."""
        wind = self.report
        return (
            wind is not None
            and self._active
            and 0.0 <= time_s - wind.time_s <= self.settings.autopilot_wind_max_age_s
        )

    def variance(self, time_s: float, dt: float) -> float | None:
        """The variance (m²/s², per component) the report takes in a step of ``dt`` s ending
        at ``time_s``; None when there is no fresh report (:meth:`fresh`)."""
        s = self.settings
        if dt <= 0.0 or not self.fresh(time_s):
            return None
        return s.autopilot_wind_sigma_mps**2 * max(s.autopilot_wind_correlation_s / dt, 1.0)

    def gap_ne_mps(self, x: np.ndarray, p: np.ndarray, time_s: float) -> tuple[float, float]:
        """The share of the latest fresh report's distance from the wind of state ``x``
        (covariance ``p``; m/s, north and east) the tracker's reported 1σ covers: the gap
        times the square root of the probability that one of the two is wrong — a change
        the tracker has not taken up, or a report the EKF holds after the wind changed —
        given their squared Mahalanobis distance d² (with both their variances). Where they
        agree, d² follows χ²₂ (density ∝ e^(−d²/2)); where one is wrong, it is spread over
        a far wider range (a flat density): the probability is the logistic
        1 / (1 + e^(−(d² − d₀²)/2)), even odds at d₀² = ``autopilot_wind_gap_chi2``. So the
        1σ grows with the disagreement, not all at once at a threshold (a covariance a
        little wider used to drop the whole gap). Zero without a fresh report."""
        if not self.fresh(time_s):
            return 0.0, 0.0
        gap, _, distance2 = self._innovation(x, p, self.settings.autopilot_wind_sigma_mps**2)
        log_ratio = 0.5 * (distance2 - self.settings.autopilot_wind_gap_chi2)
        weight = math.sqrt(second_probability(log_ratio))
        return float(weight * gap[0]), float(weight * gap[1])

    def _innovation(
        self, x: np.ndarray, p: np.ndarray, var: float
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """The report against the wind of state ``x`` (covariance ``p``): innovation (m/s,
        north and east), its covariance with the report's variance ``var`` (m²/s²) per
        component, and its squared Mahalanobis distance."""
        assert self.report is not None
        wind = self.report
        innovation = np.array([wind.wind_n_mps, wind.wind_e_mps]) - x[:2]
        s_mat = p[:2, :2] + var * np.eye(2)
        return innovation, s_mat, mahalanobis2(innovation, s_mat)

    def saw_a_change(self, x: np.ndarray, p: np.ndarray) -> bool:
        """Whether the report has been beyond ``autopilot_wind_change_chi2`` of the wind of
        ``x`` (with the report's own variance) for ``autopilot_wind_change_steps`` steps in a
        row (then the count starts over)."""
        s = self.settings
        _, _, distance2 = self._innovation(x, p, s.autopilot_wind_sigma_mps**2)
        apart = distance2 > s.autopilot_wind_change_chi2
        self._apart = self._apart + 1 if apart else 0
        if self._apart < s.autopilot_wind_change_steps:
            return False
        self._apart = 0
        return True

    def update(
        self, x: np.ndarray, p: np.ndarray, var: float
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """State ``x`` and covariance ``p`` after the report as a linear measurement of the
        wind states with variance ``var`` (m²/s²): a Kalman update with H = [I₂ 0], which
        moves the other states through their covariance with the wind. None when the report
        is beyond ``gate_sigma`` of the estimate."""
        innovation, s_mat, distance2 = self._innovation(x, p, var)
        if distance2 > self.settings.gate_sigma**2:
            return None
        gain = np.linalg.solve(s_mat, p[:2, :]).T  # n × 2: P Hᵀ S⁻¹
        posterior = p - gain @ p[:2, :]
        return x + gain @ innovation, 0.5 * (posterior + posterior.T)
