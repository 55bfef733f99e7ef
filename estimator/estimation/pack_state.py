"""The pack in the vehicle: its charge, usable capacity and internal resistance, learned from
the terminal voltage, the current and the charge counted (an extended Kalman filter).

State ``x = [s, q, R, d]``:

- ``s``: state of charge (fraction of the pack's real capacity) when the filter started;
- ``q = Q_label / Q``: the configured (label) capacity over the real one (1: the label is
  right; 1.25: the pack holds 80 % of its label);
- ``R``: the pack's internal resistance (Ω);
- ``d``: the error of the configured resting curve at the present state of charge (V, pack),
  a Gauss–Markov process over the state of charge: the curve's error at one state of charge
  says little about its error ``ocv_curve_correlation_soc`` further on.

With ``c`` the charge drawn since the start (Ah: the autopilot's counter, else the measured or
modelled current integrated), the state of charge now is ``s − q·c/Q_label`` and one reading
of the terminal voltage at current ``I`` is

    V = cells · OCV_cell(s − q·c/Q_label) + d − I·R + noise.

A pack whose voltage falls faster than its coulombs allow holds less than its label (q > 1);
one that starts lower on the curve is less charged (s): the two separate as the charge drawn
grows, with σ from the data. The first reading (a resting pack at power-up, or whatever the
pack holds when the daemon starts) is folded in by an iterated update (the curve is far from
linear over the prior's width); later ones by one linearisation each. A current-sensor gain
error scales ``c`` and ``I`` alike: ``q`` and ``R`` take it up, and the time left (charge
over current) does not see it.

Usable energy above the reserve (Wh, chemical: OCV integrated over charge) is
``Q·[cells·(F(soc) − F(r)) + d·(soc − r)]`` with ``F`` the curve's integral per cell and Ah
(:meth:`PackModel.cell_energy_wh_per_ah`) and ``r`` the reserve fraction of the real pack;
its σ is first order in the state's covariance.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimator.estimation.kalman import state_from_json
from estimator.estimation.step_resistance import Step, StepResistance
from estimator.physics.battery import PackModel

#: Iterations of the first (iterated) update.
_FIRST_UPDATE_ITERATIONS = 6
#: Bounds of the state (s, q, R Ω, d V): a strayed linearisation never leaves physics
#: (no pack is more than full).
_S_RANGE = (-0.1, 1.0)
_Q_RANGE = (0.4, 3.0)
_R_RANGE = (0.0, 2.0)
#: Readings in a row whose update drove ``q`` to a bound of its range (a pack of 2.5 times
#: its label, or a third of it) before the filter is refuted (:attr:`PackFilter.refuted`):
#: the voltage does not follow the charge drawn as any pack's does. Clipped there, the
#: estimate kept the small 1σ of a state the readings pin (a SITL battery of an older
#: ArduCopter, whose voltage holds while about 1.5 Ah is drawn from a 2.2 Ah label: 5.5 ± 0.2 Ah,
#: and an endurance of 347 ± 20 s; docs/pack.md).
PINNED_READINGS = 10
#: Half-width (of charge) over which the curve's slope is averaged: at least a fifth of a
#: table segment, at most two segments.
_MIN_SLOPE_HALF_WIDTH = 0.01
_MAX_SLOPE_HALF_WIDTH = 0.1
#: Readings over which the voltage noise is averaged, and the least noise assumed (V): the
#: terminal voltage is read in mV, and below 5 mV the filter would trust its curve and its
#: current sensor more than either deserves.
_NOISE_MEMORY = 200.0
#: Readings the configured noise counts for in that average: the data's own noise takes
#: over within a few dozen readings, not after the whole memory.
_NOISE_PRIOR_READINGS = 10.0
_NOISE_FLOOR_V = 0.005
#: Prior 1σ of the starting state of charge before the first reading (uninformative).
_S_PRIOR_SIGMA = 0.5
#: Error of a resting curve measured on the pack itself (V per cell): what is left of the
#: table's interpolation and of the pack's ageing since (the vehicle file's ``cell_ocv_v``).
OWN_CURVE_SIGMA_V = 0.004
#: Error of a resistance measured on the pack (``uav-energy fit``), as a fraction: it falls
#: as the pack warms and rises as it ages.
MEASURED_RESISTANCE_SIGMA = 0.3
#: Prior error of the label against the real pack (fraction, 1σ) where the capacity is
#: learned: packs lose 20–40 % over a few hundred cycles.
LEARNED_CAPACITY_SIGMA = 0.25
#: Spread of one pack's resting curve about its chemistry's typical curve (V per cell):
#: cells of one chemistry from different makers and ages differ by 10–30 mV at rest.
TYPICAL_CURVE_SIGMA_V = 0.02


def capacity_range_ah(label_ah: float) -> tuple[float, float]:
    """The least and the most capacity (Ah) the filter may learn for a pack of label
    ``label_ah`` (Ah): the bounds of ``q``."""
    return label_ah / _Q_RANGE[1], label_ah / _Q_RANGE[0]


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    """a · b of two 4-vectors (scalar arithmetic: numpy costs more than it saves at this size)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


def _quadratic(p: Sequence[Sequence[float]], j: Sequence[float]) -> float:
    """jᵀ P j of a 4-vector ``j`` and a 4 × 4 matrix ``p`` (nested lists)."""
    j0, j1, j2, j3 = j
    return _dot(j, [r[0] * j0 + r[1] * j1 + r[2] * j2 + r[3] * j3 for r in p])


def _joseph(
    p: Sequence[Sequence[float]], gain: Sequence[float], h: Sequence[float], r_var: float
) -> list[list[float]]:
    """The covariance after a scalar update, Joseph form (I − K h) P (I − K h)ᵀ + K r Kᵀ
    (symmetric and positive), for the gain ``gain``, the gradient ``h`` and the reading's
    variance ``r_var``: with A = I − K h, A P = P − K (hᵀP) and (A P) Aᵀ = A P − (A P h) Kᵀ."""
    h0, h1, h2, h3 = h
    p0, p1, p2, p3 = p
    hp = [h0 * p0[j] + h1 * p1[j] + h2 * p2[j] + h3 * p3[j] for j in range(4)]
    hp0, hp1, hp2, hp3 = hp
    g0, g1, g2, g3 = gain
    out = []
    for row, gi in zip(p, gain, strict=True):
        a0, a1, a2, a3 = row[0] - gi * hp0, row[1] - gi * hp1, row[2] - gi * hp2, row[3] - gi * hp3
        aph = a0 * h0 + a1 * h1 + a2 * h2 + a3 * h3
        r_gi = r_var * gi
        out.append(
            [a0 - aph * g0 + r_gi * g0, a1 - aph * g1 + r_gi * g1, a2 - aph * g2 + r_gi * g2,
             a3 - aph * g3 + r_gi * g3]
        )  # fmt: skip
    return out


@dataclass(frozen=True, slots=True)
class PackSettings:
    """Noise figures of the pack filter (1σ).

    capacity_sigma_fraction: prior error of the configured (label) capacity against the real
    pack, as a fraction (0: the label is exact and ``q`` stays 1; None:
    :data:`LEARNED_CAPACITY_SIGMA` against a curve measured on the pack, 0 against a
    chemistry's typical curve, too loose to tell a smaller pack from another curve).
    resistance_prior_ohm_per_cell, resistance_sigma_ohm_per_cell: prior resistance per cell
    and its error (Ω); internal_resistance_ohm: a fixed pack resistance instead (Ω).
    resistance_walk_ohm_per_sqrt_s: random walk of the resistance (it falls as the pack warms).
    voltage_noise_v: error of one terminal-voltage reading, pack (V; with the pack's fast
    polarisation, which no state here follows).
    ocv_curve_sigma_v_per_cell: error of the configured resting curve (V per cell; None: the
    vehicle file's ``[battery] cell_ocv_sigma_v``, else :data:`OWN_CURVE_SIGMA_V`, for a curve
    measured on the pack, ``[battery] cell_ocv_v``,
    :data:`TYPICAL_CURVE_SIGMA_V` for a chemistry's typical curve), and
    ocv_curve_correlation_soc the state-of-charge distance over which it decorrelates.
    innovation_gate_sigma: a reading further than this many σ from the prediction is not
    used (a glitch, a forged or mis-scaled value).
    """

    capacity_sigma_fraction: float | None = None
    resistance_prior_ohm_per_cell: float = 0.004
    resistance_sigma_ohm_per_cell: float = 0.004
    internal_resistance_ohm: float | None = None
    resistance_walk_ohm_per_sqrt_s: float = 1e-5
    voltage_noise_v: float = 0.05
    ocv_curve_sigma_v_per_cell: float | None = None
    ocv_curve_correlation_soc: float = 0.1
    innovation_gate_sigma: float = 6.0


@dataclass(frozen=True, slots=True)
class PackPrior:
    """What is known of a pack before this flight (e.g. learned on its last flight): real
    capacity (Ah) and resistance (Ω), each with its 1σ."""

    capacity_ah: float
    capacity_sigma_ah: float
    resistance_ohm: float
    resistance_sigma_ohm: float


@dataclass(frozen=True, slots=True)
class PackEstimate:
    """The pack now: state of charge (fraction of the real pack), real capacity (Ah),
    resistance (Ω), usable energy above the reserve (Wh), each with its 1σ."""

    soc: float
    soc_sigma: float
    capacity_ah: float
    capacity_sigma_ah: float
    resistance_ohm: float
    resistance_sigma_ohm: float
    energy_wh: float
    energy_sigma_wh: float


class PackFilter:
    """The EKF over ``[s, q, R, d]`` of the module docstring, for one pack."""

    def __init__(
        self,
        pack: PackModel,
        settings: PackSettings,
        prior: PackPrior | None = None,
        resistance: tuple[float, float] | None = None,
    ) -> None:
        """``resistance``: the resistance (Ω) and its 1σ to start from, in place of the
        prior's or the settings' (one hypothesis of :mod:`estimator.estimation.pack_bank`)."""
        self.pack = pack
        self._resistance = resistance
        self.settings = settings
        self.prior = prior
        self.cells = pack.spec.cells
        self.label_ah = pack.spec.capacity_ah
        #: The state [s, q, R, d] and its covariance (4 × 4, nested lists: scalar arithmetic,
        #: numpy costs more than it saves at this size).
        self.x = [0.0] * 4
        self.P = [[0.0] * 4 for _ in range(4)]
        self.charge_ah = 0.0  # drawn since the start
        self._counter_base: tuple[float, float] | None = None  # (charge_ah, counter Ah) then
        self.rejected = 0
        self.updates = 0
        self._pinned = 0  # updates in a row that drove q to a bound of its range
        #: The voltage does not follow the charge drawn as any pack's does (``q`` held at a
        #: bound of its range for :data:`PINNED_READINGS` readings in a row): what the filter
        #: says is not the pack's; it stays so.
        self.refuted = False
        #: log p(readings so far | the filter's model), each reading from its prediction
        #: (a reading outside the gate counts at the gate's edge): what a bank of starts
        #: weighs its hypotheses by (:mod:`estimator.estimation.pack_bank`).
        self.log_likelihood = 0.0
        self.started = False
        #: Sample time (s) of the last reading :meth:`take` folded in (None: not known).
        self.last_time_s: float | None = None
        #: Variance of one terminal-voltage reading (V²): the configured one, then the data's.
        self.noise_var_v2 = settings.voltage_noise_v**2
        self._noise_mean_v2 = self.noise_var_v2
        #: Steps of current between consecutive readings: R where the absolute model is
        #: still unsure of the charge.
        self.steps = StepResistance(settings.voltage_noise_v)
        self._noise_readings = _NOISE_PRIOR_READINGS
        #: The resting curve is the pack's own (measured), not its chemistry's typical one.
        self.own_curve = pack.spec.cell_ocv_v is not None
        curve_sigma = settings.ocv_curve_sigma_v_per_cell
        if curve_sigma is None:
            curve_sigma = (
                (pack.spec.cell_ocv_sigma_v or OWN_CURVE_SIGMA_V)
                if self.own_curve
                else TYPICAL_CURVE_SIGMA_V
            )
        #: 1σ of the curve error state d (V, pack).
        self.curve_sigma_v = curve_sigma * self.cells

    # -- start ------------------------------------------------------------------------------

    def resistance_prior(self) -> tuple[float, float]:
        """The resistance (Ω) and its 1σ the filter starts from: fixed, the one it was made
        with, the pack's memory, the vehicle file's measured one (``[battery]
        internal_resistance_ohm``, ± :data:`MEASURED_RESISTANCE_SIGMA`), or the settings'
        per-cell prior."""
        s = self.settings
        if s.internal_resistance_ohm is not None:
            return s.internal_resistance_ohm, 0.0
        if self._resistance is not None:
            return self._resistance
        if self.prior is not None:
            return self.prior.resistance_ohm, self.prior.resistance_sigma_ohm
        measured_ohm = self.pack.spec.internal_resistance_ohm
        if measured_ohm is not None:
            return measured_ohm, MEASURED_RESISTANCE_SIGMA * measured_ohm
        cells = self.cells
        return s.resistance_prior_ohm_per_cell * cells, s.resistance_sigma_ohm_per_cell * cells

    def capacity_prior(self) -> tuple[float, float]:
        """``q`` (label over real capacity) the filter starts from and its 1σ: the prior's
        (e.g. the pack's memory), else 1 ± the settings' fraction (None:
        :data:`LEARNED_CAPACITY_SIGMA` against the pack's own curve, 0 against a typical
        one)."""
        if self.prior is not None:
            q0 = self.label_ah / self.prior.capacity_ah
            return q0, q0 * self.prior.capacity_sigma_ah / self.prior.capacity_ah
        fraction = self.settings.capacity_sigma_fraction
        if fraction is None:
            fraction = LEARNED_CAPACITY_SIGMA if self.own_curve else 0.0
        return 1.0, fraction

    def start(self, voltage_v: float, current_a: float) -> None:
        """Start from one reading (V, A): the prior, then an iterated update with it."""
        q0, q_sigma = self.capacity_prior()
        r0, r_sigma = self.resistance_prior()
        ocv_v = voltage_v + max(current_a, 0.0) * r0
        s0 = float(np.clip(self.pack.soc_from_ocv(ocv_v), 0.0, 1.0))
        self.started = True
        self.x = [s0, q0, r0, 0.0]
        diagonal = (_S_PRIOR_SIGMA**2, q_sigma**2, r_sigma**2, self.curve_sigma_v**2)
        self.P = [[var if i == j else 0.0 for j in range(4)] for i, var in enumerate(diagonal)]
        self._update(voltage_v, current_a, _FIRST_UPDATE_ITERATIONS, gate=False)

    def take(
        self, time_s: float, voltage_v: float, current_a: float, consumed_mah: float | None
    ) -> None:
        """One reading with a current (s, V, A; the autopilot's consumed-charge counter then,
        mAh, or None): the first starts the filter; each later one moves the charge drawn
        (the counter, else the current since the last reading), then folds in the voltage."""
        if not self.started:
            self.start(voltage_v, current_a)
            if consumed_mah is not None:
                self.count(consumed_mah)
            self.steps.take(time_s, voltage_v, current_a, 0.0, self.x[2])
        else:
            last_s = time_s if self.last_time_s is None else self.last_time_s
            dt_s = max(time_s - last_s, 0.0)
            if consumed_mah is not None:
                self.count(consumed_mah)
            else:
                self.draw(current_a, dt_s)
            drift_v_per_ah = self._resting_drift_v(1.0)
            step = self.steps.take(time_s, voltage_v, current_a, drift_v_per_ah, self.x[2])
            if step is not None and self.settings.internal_resistance_ohm is None:
                self._update_resistance(step)
            self.update(dt_s, voltage_v, current_a, learn_resistance=not self.steps.within_noise)
        self.last_time_s = time_s

    def _resting_drift_v(self, drawn_ah: float) -> float:
        """Change of the resting pack voltage (V) as ``drawn_ah`` (Ah) is drawn now."""
        slope_v = self.cells * self.pack.cell_ocv_slope_v(self.soc)[1]
        return -slope_v * self.x[1] * drawn_ah / self.label_ah

    def _update_resistance(self, step: Step) -> None:
        """Fold in the resistance a step of current measured, for what it adds to the two
        absolute readings of the step: they tell R to 2·(reading noise)/ΔI² already, so the
        step counts with the information beyond that (none where the differences are no
        cleaner than the readings)."""
        absolute_var_ohm2 = 2.0 * self.noise_var_v2 / step.current_step_a**2
        if not step.var_ohm2 > 0.0:
            return
        added_info = 1.0 / step.var_ohm2 - 1.0 / absolute_var_ohm2  # 1/Ω²
        if not (math.isfinite(added_info) and added_info > 0.0):
            return  # no cleaner than the readings (or a value no pack gives)
        var_ohm2 = 1.0 / added_info
        resistance_ohm = step.resistance_ohm
        if not (math.isfinite(var_ohm2) and math.isfinite(resistance_ohm)):
            return
        h = (0.0, 0.0, 1.0, 0.0)
        innovation = resistance_ohm - self.x[2]
        s_var = self.P[2][2] + var_ohm2
        if innovation**2 > self.settings.innovation_gate_sigma**2 * s_var:
            return
        self.log_likelihood -= 0.5 * (innovation**2 / s_var + math.log(2.0 * math.pi * s_var))
        p = self.P
        gain = [row[2] / s_var for row in p]
        self.x = [xi + gi * innovation for xi, gi in zip(self.x, gain, strict=True)]
        self.P = _joseph(p, gain, h, var_ohm2)
        self.x[2] = min(max(self.x[2], _R_RANGE[0]), _R_RANGE[1])

    # -- the charge drawn ---------------------------------------------------------------------

    def count(self, consumed_mah: float) -> None:
        """The autopilot's consumed-charge counter (mAh) now: the charge drawn follows it from
        the first value seen (a counter that restarts is re-based by :meth:`rebase`)."""
        counter_ah = consumed_mah / 1000.0
        if self._counter_base is None:
            self._counter_base = (self.charge_ah, counter_ah)
        base_ah, counter0_ah = self._counter_base
        self._advance(base_ah + counter_ah - counter0_ah)

    def draw(self, current_a: float, dt_s: float) -> None:
        """No counter: ``current_a`` (A, measured or modelled) drawn for ``dt_s`` (s)."""
        if self._counter_base is None and dt_s > 0:
            self._advance(self.charge_ah + current_a * dt_s / 3600.0)

    def rebase(self) -> None:
        """The autopilot restarted: its counter starts again from 0."""
        self._counter_base = None

    def _advance(self, charge_ah: float) -> None:
        """Move the charge drawn to ``charge_ah``: the curve error decorrelates with the
        state-of-charge travelled."""
        delta_soc = abs(charge_ah - self.charge_ah) * self.x[1] / self.label_ah
        self.charge_ah = charge_ah
        if delta_soc > 0:
            s = self.settings
            phi = math.exp(-delta_soc / s.ocv_curve_correlation_soc)
            self.x[3] *= phi
            p = self.P
            p[3] = [v * phi for v in p[3]]
            for row in p:
                row[3] *= phi
            p[3][3] += self.curve_sigma_v**2 * (1.0 - phi * phi)

    # -- voltage ------------------------------------------------------------------------------

    def update(
        self, dt_s: float, voltage_v: float, current_a: float, learn_resistance: bool = True
    ) -> None:
        """Fold in one terminal voltage (V) at ``current_a`` (A), ``dt_s`` (s) after the last;
        without ``learn_resistance`` the resistance's uncertainty is weighed but the reading
        does not move it (a current that moved only by its noise: errors in variables)."""
        if dt_s > 0 and self.settings.internal_resistance_ohm is None:
            self.P[2][2] += self.settings.resistance_walk_ohm_per_sqrt_s**2 * dt_s
        self._update(voltage_v, current_a, 1, gate=True, learn_resistance=learn_resistance)

    def _measurement(
        self, x: Sequence[float], p: Sequence[Sequence[float]], current_a: float
    ) -> tuple[float, list[float]]:
        """Predicted terminal voltage (V) at state ``x`` and its gradient over the state. The
        curve's slope is its mean over ±1σ of the state of charge (covariance ``p``), not the
        slope at the mean: the table's segments are 0.05 of charge wide and differ in slope
        by 2× and more, so a slope taken from a segment the charge may not be in would make
        the filter surer than its data (statistical linearisation)."""
        c_rel = self.charge_ah / self.label_ah
        soc = x[0] - x[1] * c_rel
        soc_sigma = math.sqrt(max(_quadratic(p, (1.0, -c_rel, 0.0, 0.0)), 0.0))
        half = min(max(soc_sigma, _MIN_SLOPE_HALF_WIDTH), _MAX_SLOPE_HALF_WIDTH)
        curve = self.pack.cell_ocv_slope_v
        slope_cell = (curve(soc + half)[0] - curve(soc - half)[0]) / (2.0 * half)
        k = self.cells * slope_cell
        h = [k, -k * c_rel, -current_a, 1.0]
        return self.cells * curve(soc)[0] + x[3] - current_a * x[2], h

    def _update(
        self,
        voltage_v: float,
        current_a: float,
        iterations: int,
        gate: bool,
        learn_resistance: bool = True,
    ) -> None:
        x0, p0 = self.x, self.P
        r_var = self.noise_var_v2
        x = list(x0)
        for _ in range(iterations):
            z_pred, h = self._measurement(x, p0, current_a)
            pht = [_dot(row, h) for row in p0]
            s_var = _dot(h, pht) + r_var
            innovation = voltage_v - z_pred - _dot(h, [a - b for a, b in zip(x0, x, strict=True)])
            if gate and innovation**2 > self.settings.innovation_gate_sigma**2 * s_var:
                self.rejected += 1
                self.log_likelihood -= 0.5 * (
                    self.settings.innovation_gate_sigma**2 + math.log(2.0 * math.pi * s_var)
                )
                return
            gain = [v / s_var for v in pht]
            if not learn_resistance:
                gain[2] = 0.0  # considered, not learnt (the covariance below stays right)
            x = [a + g * innovation for a, g in zip(x0, gain, strict=True)]
        self.log_likelihood -= 0.5 * (innovation**2 / s_var + math.log(2.0 * math.pi * s_var))
        self.P = _joseph(p0, gain, h, r_var)
        if gate:
            # residual after the update, plus what the state's remaining uncertainty explains
            residual_v = innovation * (1.0 - _dot(h, gain))
            self._learn_noise(residual_v**2 + _quadratic(self.P, h))
        pinned = not _Q_RANGE[0] < x[1] < _Q_RANGE[1]
        self._pinned = self._pinned + 1 if pinned else 0
        self.refuted |= self._pinned >= PINNED_READINGS
        x[0] = min(max(x[0], _S_RANGE[0]), _S_RANGE[1])
        x[1] = min(max(x[1], _Q_RANGE[0]), _Q_RANGE[1])
        x[2] = min(max(x[2], _R_RANGE[0]), _R_RANGE[1])
        self.x = x
        self.updates += 1

    def _learn_noise(self, sample_v2: float) -> None:
        """The readings' noise from the data: the square of each reading's residual after
        its update plus the state's remaining uncertainty in it (an estimate that stays
        positive while the state is still uncertain), averaged over the readings so far (the
        configured noise counting as :data:`_NOISE_PRIOR_READINGS`) and at most
        :data:`_NOISE_MEMORY`, kept between (:data:`_NOISE_FLOOR_V`)² and 4 × the configured
        variance."""
        self._noise_readings = min(self._noise_readings + 1.0, _NOISE_MEMORY)
        mean = self._noise_mean_v2 + (sample_v2 - self._noise_mean_v2) / self._noise_readings
        self.share_noise(mean)

    @property
    def noise_mean_v2(self) -> float:
        """The running mean behind :attr:`noise_var_v2` (V², before its bounds)."""
        return self._noise_mean_v2

    def share_noise(self, mean_v2: float) -> None:
        """Take ``mean_v2`` (V²) as the running mean of the readings' noise: the starts of a
        bank learn one noise, so none is favoured for a noise it learnt on its own."""
        self._noise_mean_v2 = mean_v2
        configured = self.settings.voltage_noise_v**2
        self.noise_var_v2 = min(max(mean_v2, _NOISE_FLOOR_V**2), 4.0 * configured)

    # -- what it says -------------------------------------------------------------------------

    @property
    def soc(self) -> float:
        """State of charge now (fraction of the real pack, within [0, 1])."""
        return min(max(self.x[0] - self.x[1] * self.charge_ah / self.label_ah, 0.0), 1.0)

    @property
    def capacity_ah(self) -> float:
        """The pack's real capacity (Ah)."""
        return self.label_ah / self.x[1]

    @property
    def resistance_ohm(self) -> float:
        return self.x[2]

    def estimate(self) -> PackEstimate:
        s, q, resistance_ohm, d = self.x
        label, cells, c = self.label_ah, self.cells, self.charge_ah
        reserve = self.pack.spec.reserve_fraction
        soc = s - q * c / label
        capacity = label / q
        pack = self.pack
        # energy above the reserve per Ah of the real pack (negative below it: published as 0,
        # its σ still the state's) and its gradient over the state
        per_ah = cells * (
            pack.cell_energy_wh_per_ah(soc) - pack.cell_energy_wh_per_ah(reserve)
        ) + d * (soc - reserve)
        d_per_ah = cells * pack.cell_ocv_slope_v(min(max(soc, 0.0), 1.0))[0] + d
        j_energy = (
            capacity * d_per_ah, -capacity / q * per_ah - c / q * d_per_ah, 0.0,
            capacity * (soc - reserve),
        )  # fmt: skip
        j_soc = (1.0, -c / label, 0.0, 0.0)
        j_capacity = (0.0, -label / (q * q), 0.0, 0.0)
        p = self.P
        return PackEstimate(
            soc=min(max(soc, 0.0), 1.0),
            soc_sigma=math.sqrt(max(_quadratic(p, j_soc), 0.0)),
            capacity_ah=capacity,
            capacity_sigma_ah=math.sqrt(max(_quadratic(p, j_capacity), 0.0)),
            resistance_ohm=resistance_ohm,
            resistance_sigma_ohm=math.sqrt(max(p[2][2], 0.0)),
            energy_wh=max(capacity * per_ah, 0.0),
            energy_sigma_wh=math.sqrt(max(_quadratic(p, j_energy), 0.0)),
        )

    # -- restart --------------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """The state, its covariance and the charge accounting (JSON-ready)."""
        return {
            "x": list(self.x),
            "P": [list(row) for row in self.P],
            "charge_ah": self.charge_ah,
            "counter_base": None if self._counter_base is None else list(self._counter_base),
        }

    def restore(self, state: Mapping[str, Any]) -> None:
        """Continue from :meth:`snapshot`; ValueError for one that is not a pack state
        (not finite, out of the state's bounds, a covariance that is not positive)."""
        x, p = state_from_json(state["x"], state["P"], 4, "pack state [s, q, R, d]")
        bounds = (_S_RANGE, _Q_RANGE, _R_RANGE, (-1.0, 1.0))
        if not all(lo <= v <= hi for v, (lo, hi) in zip(x, bounds, strict=True)):
            raise ValueError("pack state is out of its physical bounds")
        if not np.allclose(p, p.T) or np.linalg.eigvalsh(p).min() < -1e-12 or p.max() > 10.0:
            raise ValueError("pack covariance is not a positive semi-definite matrix")
        charge_ah = float(state["charge_ah"])
        if not (math.isfinite(charge_ah) and 0.0 <= charge_ah <= 10.0 * self.label_ah):
            raise ValueError("charge drawn is not within the pack's reach")
        base = state["counter_base"]
        counter_base = None if base is None else (float(base[0]), float(base[1]))
        if counter_base is not None and not (
            0.0 <= counter_base[0] <= 10.0 * self.label_ah and 0.0 <= counter_base[1] <= 1e3
        ):  # the charge drawn, and a consumed-charge counter (Ah) the decoder believes
            raise ValueError("counter base is not within the pack's reach")
        self.x, self.P = x.tolist(), p.tolist()
        self.charge_ah, self._counter_base = charge_ah, counter_base
        self.started = True
