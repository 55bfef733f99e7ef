"""The pack's resistance from the voltage's response to steps of current between consecutive
readings: ΔV = −ΔI·R + (the resting voltage's drift), where the slow errors of the absolute
model (the curve, the charge) cancel.

The drift is the resting voltage's change per Ah drawn (the caller's) times the charge drawn
between the two readings, from their own currents (trapezoid over the gap), not from the
autopilot's consumed-charge counter: that counter moves in steps of 1 mAh, as much as a second
at 4 A draws, and a transport may not carry it (PX4's ULog has it, the SYS_STATUS it sends over
MAVLink not): the same readings then give the same steps by either.

The pack filter (:mod:`estimator.estimation.pack_state`) reads each terminal voltage against
its whole model, with a reading noise learnt from its residuals: while the charge is
uncertain (a daemon started in flight), that noise stays near its configured tens of mV, and
a step of 1–2 A, which moves the voltage by 10–20 mV on a 10 mΩ pack, tells it little. Here
the noise of a difference is learnt model-free, from pairs of readings at a steady current
(the drift between them and the small current move times the resistance believed removed),
and each step gives R with its own σ.

A current reading has its own noise, and a ratio over a noisy ΔI is biased low (errors in
variables: a step selected for its size is partly noise). The current's white noise is learnt
model-free from consecutive differences: with ΔI_k = Δ(true)_k + e_k − e_(k−1), the product
ΔI_k·ΔI_(k−1) averages to the true current's own (small, positive: it moves smoothly) less the
noise's variance σ_e². A step counts only when it is :data:`STEP_NOISE_RATIO` times the noise
of a difference, √2·σ_e (the bias is then under 1/ratio² = 4 %), with that noise in its
variance; once the noise is known (:data:`_KNOWN_NOISE_PAIRS` pairs), a reading whose current
moved by less than 3√2·σ_e is flagged (:attr:`StepResistance.within_noise`): its voltage
tells R nothing but that noise, and the pack filter does not move R with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: A step (A) between two readings that measures the resistance, and the most a "steady" pair
#: may differ (A).
STEP_MIN_A = 1.0
STEADY_MAX_A = 0.25
#: A step must be this many times the noise of a difference of two current readings.
STEP_NOISE_RATIO = 5.0
#: The current's white noise assumed before any reading (A, 1σ of one reading): none, until
#: the readings show it; pairs of differences before that estimate flags a reading as
#: moved by noise only.
_PRIOR_CURRENT_NOISE_A = 0.0
_KNOWN_NOISE_PAIRS = 50.0
#: Longest gap (s) between the two readings of a pair.
PAIR_MAX_S = 2.0
#: Steady pairs the configured noise counts for, the pairs remembered, and the least noise of
#: one difference (V: readings in mV).
_PRIOR_PAIRS = 2.0
_MEMORY_PAIRS = 200.0
_FLOOR_V = 0.001


@dataclass(frozen=True, slots=True)
class Step:
    """The resistance (Ω) one step of current (A) measured, and its variance (Ω²)."""

    resistance_ohm: float
    var_ohm2: float
    current_step_a: float


class StepResistance:
    """Differences of consecutive terminal-voltage readings: their noise, and R from steps."""

    def __init__(self, configured_noise_v: float) -> None:
        self._noise_mean_v2 = 2.0 * configured_noise_v**2
        self._pairs = _PRIOR_PAIRS
        self._current_noise_a2 = _PRIOR_CURRENT_NOISE_A**2  # −mean(ΔI_k·ΔI_(k−1)), A²
        self._current_pairs = _PRIOR_PAIRS
        self._last_step_a: float | None = None
        #: The last reading's current moved from the one before by no more than the noise of a
        #: difference (3σ), once that is known: its voltage says nothing of R but that noise.
        self.within_noise = False
        self._last: tuple[float, float, float] | None = None  # (time_s, voltage_v, current_a)

    @property
    def difference_var_v2(self) -> float:
        """Variance of one difference of two readings (V²)."""
        return max(self._noise_mean_v2, _FLOOR_V**2)

    def take(
        self,
        time_s: float,
        voltage_v: float,
        current_a: float,
        drift_v_per_ah: float,
        resistance_ohm: float,
    ) -> Step | None:
        """One reading (s, V, A), the resting voltage's change per Ah drawn now (V/Ah, ≤ 0)
        and the resistance believed now (Ω, for the small current moves of a steady pair):
        the resistance where the current stepped, else None."""
        last, self._last = self._last, (time_s, voltage_v, current_a)
        self.within_noise = False
        if last is None or not 0.0 < time_s - last[0] <= PAIR_MAX_S:
            return None
        step_a = current_a - last[2]
        drawn_ah = 0.5 * (current_a + last[2]) * (time_s - last[0]) / 3600.0
        change_v = voltage_v - last[1] - drift_v_per_ah * drawn_ah
        current_var_a2 = 2.0 * max(self._current_noise_a2, 0.0)  # of a difference
        known = self._current_pairs >= _KNOWN_NOISE_PAIRS
        self.within_noise = known and step_a**2 <= 9.0 * current_var_a2
        before_a, self._last_step_a = self._last_step_a, step_a
        if before_a is not None and max(abs(step_a), abs(before_a)) < STEP_MIN_A:
            # pairs of differences away from the steps (a step's own size is no noise)
            self._current_pairs = min(self._current_pairs + 1.0, _MEMORY_PAIRS)
            self._current_noise_a2 += (-step_a * before_a - self._current_noise_a2) / (
                self._current_pairs
            )
        if abs(step_a) <= STEADY_MAX_A:
            residual_v = change_v + resistance_ohm * step_a
            self._pairs = min(self._pairs + 1.0, _MEMORY_PAIRS)
            self._noise_mean_v2 += (residual_v**2 - self._noise_mean_v2) / self._pairs
            return None
        least_a = max(STEP_MIN_A, STEP_NOISE_RATIO * math.sqrt(current_var_a2))
        if abs(step_a) < least_a or not math.isfinite(change_v):
            return None
        measured_ohm = -change_v / step_a
        var_v2 = self.difference_var_v2 + measured_ohm**2 * current_var_a2
        return Step(measured_ohm, var_v2 / step_a**2, step_a)
