"""Does the pack's terminal voltage follow its load? A voltage that does not is no pack's
terminal voltage (a simulator's battery falling with armed time, a fixed value): it must teach
neither the resistance nor the charge or capacity.

A real pack's voltage drops by ΔI·R when its current steps by ΔI, R at least its cells' own:
new high-rate LiPo cells measure 1–4 mΩ each
(https://www.rchelicopterfun.com/lipo-internal-resistance.html), and the pack's leads,
connector and current shunt add to that. :data:`FLOOR_OHM_PER_CELL` is half the lowest.

Each reading (one an estimate period: the measured current, else the modelled one) joins the
two before it, each pair at most :data:`~estimator.estimation.step_resistance.PAIR_MAX_S`
apart, all three under load (:data:`~estimator.estimation.step_resistance.STEP_MIN_A` or
more: arming and disarming, where a simulator's battery starts or resets, are no steps).
Their second differences, x = ΔI_k − ΔI_(k−1) and y = ΔV_k − ΔV_(k−1), remove a resting
voltage that drifts linearly (the charge drawn, or a fall with time), and y = −R·x + e is
fitted through the origin: R̂ = −Σxy / Σx², σ² = s² / Σx², s² the mean squared residual (at
least that of four readings of 1 mV resolution). The voltage does not follow the load once
:data:`MIN_STEPS` second differences moved the current by ``STEP_MIN_A`` or more, and by
enough that a pack at the floor would have moved the voltage by more than the noise of a
second difference (a simulator's voltage with 50 mV of noise and 1 A steps at take-off read
−47 ± 16 mΩ over three such steps, and was taken for no pack, before this), and
R̂ + :data:`Z`·σ is below the floor times the cells; the verdict stands from then on (a
daemon restarted in flight finds it again).
"""

from __future__ import annotations

import math

from estimator.estimation.step_resistance import PAIR_MAX_S, STEP_MIN_A

#: Half the least resistance (Ω) per cell a real pack shows (see the module).
FLOOR_OHM_PER_CELL = 0.0005
#: One-sided bound: R̂ + Z·σ (99.87 % for a normal error).
Z = 3.0
#: Steps of load (second differences of the current of at least STEP_MIN_A) before a verdict.
MIN_STEPS = 3
#: Least noise of one second difference of readings (V): four readings of 1 mV resolution.
_FLOOR_V = 0.002


class LoadResponse:
    """The voltage's response to steps of load, and whether it is a pack's (see the module)."""

    def __init__(self, cells: int) -> None:
        self.cells = cells
        self.floor_ohm = FLOOR_OHM_PER_CELL * cells
        self._last: tuple[float, float] | None = None  # (V, A) of the reading before
        self._last_step: tuple[float, float] | None = None  # (ΔV, ΔI) of the last pair
        self._sxx = self._sxy = self._syy = 0.0
        self._pairs = 0
        self.steps = 0
        #: The voltage was found not to follow the load (it stays so).
        self.unresponsive = False

    @property
    def resistance_ohm(self) -> float:
        """R̂ (Ω) of the steps so far (NaN before any)."""
        return -self._sxy / self._sxx if self._sxx > 0 else math.nan

    @property
    def noise_v(self) -> float:
        """1σ of one second difference of the voltage about the fit (V; the floor before two
        pairs)."""
        if self._sxx <= 0 or self._pairs < 2:
            return _FLOOR_V
        residual_v2 = (self._syy - self._sxy**2 / self._sxx) / (self._pairs - 1)
        return math.sqrt(max(residual_v2, _FLOOR_V**2))

    @property
    def sigma_ohm(self) -> float:
        """1σ of :attr:`resistance_ohm` (Ω; infinite before two pairs)."""
        if self._sxx <= 0 or self._pairs < 2:
            return math.inf
        return self.noise_v / math.sqrt(self._sxx)

    def describe(self) -> str:
        """One line on the verdict: R̂ and its σ per cell, the steps, the floor."""
        cells = self.cells
        return (
            f"the pack voltage does not follow the load: {1000 * self.resistance_ohm / cells:.2f}"
            f" ± {1000 * self.sigma_ohm / cells:.2f} mΩ per cell over {self.steps} steps of"
            f" current (a pack shows ≥ {1000 * FLOOR_OHM_PER_CELL:g}): its resistance, charge"
            " and capacity are not learnt from it"
        )

    def take(self, dt_s: float, voltage_v: float, current_a: float) -> bool:
        """One reading (V, A), ``dt_s`` (s) after the one before: True when it is the one that
        shows the voltage does not follow the load."""
        if not (math.isfinite(voltage_v) and math.isfinite(current_a)):
            return False
        if current_a < STEP_MIN_A or not 0.0 < dt_s <= PAIR_MAX_S or self._last is None:
            self._last_step = None
        else:
            step = (voltage_v - self._last[0], current_a - self._last[1])
            if self._last_step is not None:
                self._add(step[1] - self._last_step[1], step[0] - self._last_step[0])
            self._last_step = step
        self._last = None if current_a < STEP_MIN_A else (voltage_v, current_a)
        if self.unresponsive or self.steps < MIN_STEPS:
            return False
        self.unresponsive = self.resistance_ohm + Z * self.sigma_ohm < self.floor_ohm
        return self.unresponsive

    def _add(self, x_a: float, y_v: float) -> None:
        # a step counts towards a verdict when a pack at the floor would show above the noise
        telling = abs(x_a) >= STEP_MIN_A and abs(x_a) * self.floor_ohm >= self.noise_v
        self._sxx += x_a * x_a
        self._sxy += x_a * y_v
        self._syy += y_v * y_v
        self._pairs += 1
        self.steps += telling
