"""Kalman fusion of the power model with the battery: remaining energy, model bias, endurance.

Two linear Kalman filters, in scalar arithmetic (at two states and one, numpy's calls cost
more than the products), both driven only by sample times:

- :class:`EnergyFilter`, state ``[E, b]`` (:class:`~estimator.estimation.kalman.LinearKalman`):
  E is the usable chemical energy left above the reserve (Wh), b the scale between the
  model's power and the power actually drawn (1 = the model is right). Predict: E decreases
  by ``b · P_model · k · dt`` where k = OCV / V is the pack's internal loss factor (chemical
  energy leaves at OCV·I, the terminals see V·I).
  Updates: measured power V·I (observes b·P_model), and the charge the autopilot counted
  (consumed mAh from a resting-voltage state of charge, via :class:`PackModel`; observes E).
  The starting-charge uncertainty (resting voltage, capacity) is an offset that no later
  measurement in this filter can reduce: it is kept out of P and added to the reported σ.
  Without a current sensor only the model runs: b keeps its prior and random walk, so σ
  grows, and :attr:`EnergyFilter.model_only` says so.
- :class:`ResistanceFilter`, state ``[R]``: the pack's internal resistance (Ω) from terminal
  voltage and current, V = OCV(SoC) − I·R, the SoC from the energy state. It supplies k and
  the voltage sag that endurance predictions integrate. A voltage that does not follow the
  load (:mod:`estimator.estimation.load_response`: a simulator's battery) teaches it nothing:
  R goes back to its prior and stays there, and
  :attr:`EnergyFilter.voltage_follows_load` says so.

Endurance integrates the pack forward at constant terminal power: as the voltage sags the
current, and with it the I²R loss, rises — what a current-based "charge / average current"
estimate misses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from estimator.estimation.kalman import LinearKalman, state_from_json
from estimator.estimation.load_response import LoadResponse
from estimator.estimation.pack_state import PackEstimate
from estimator.physics.battery import PackModel
from estimator.physics.model import FloatArray
from estimator.telemetry.samples import BatterySample

#: Energy levels (fractions of what is left) at which endurance integrates the pack.
_UNIT_GRID = np.linspace(0.0, 1.0, 24)
#: The model's scale a state may hold (a model off by more is no model of the vehicle).
BIAS_RANGE = (0.2, 5.0)
#: The real pack may hold up to this multiple of its label: the pack filter's capacity bound
#: (:mod:`estimator.estimation.pack_state`, q = label / real ≥ 0.4).
MAX_CAPACITY_PER_LABEL = 2.5
#: The autopilot's clock (s) ends here (time_boot_ms is an unsigned 32-bit count).
_MAX_CLOCK_S = 2**32 / 1000.0


@dataclass(frozen=True, slots=True)
class FusionSettings:
    """Noise figures of the fusion (1σ unless said otherwise).

    bias_prior_sigma: model scale before any measured power (fraction).
    bias_walk_per_sqrt_s: random walk of the scale, 1/√s (how fast the model's error may
    change: wind, payload, temperature).
    model_power_noise_fraction: short-term error of the model's instantaneous power (fraction;
    white, adds energy process noise).
    power_noise_fraction, power_noise_floor_w: error of one measured V·I reading.
    rest_voltage_sigma_v_per_cell: error of the resting cell voltage that gives the start SoC.
    capacity_sigma_fraction: error of the configured capacity (fraction).
    charge_sigma_fraction: error of the autopilot's consumed-charge counter (fraction).
    current_gain_sigma_fraction: gain error of the current sensor (fraction): it biases the
    measured drain and the consumed charge alike, so no measurement here removes it.
    state_change_step, state_change_bias_sigma: see :meth:`EnergyFilter.flight_state_changed`.
    internal_resistance_ohm: the pack's resistance; None estimates it (prior 4 mΩ per cell).
    voltage_noise_v: error of one terminal-voltage reading (pack), V.
    resistance_walk_ohm_per_sqrt_s: random walk of the resistance (temperature), Ω/√s.
    resistance_min_current_a: below this current (A) a voltage reading does not update the
    resistance (at rest I·R is far below the voltage noise).
    ocv_curve_sigma_v_per_cell: error of the configured OCV curve, V per cell.
    """

    bias_prior_sigma: float = 0.10
    bias_walk_per_sqrt_s: float = 0.003
    model_power_noise_fraction: float = 0.05
    power_noise_fraction: float = 0.03
    power_noise_floor_w: float = 2.0
    rest_voltage_sigma_v_per_cell: float = 0.01
    capacity_sigma_fraction: float = 0.01
    charge_sigma_fraction: float = 0.01
    internal_resistance_ohm: float | None = None
    voltage_noise_v: float = 0.05
    resistance_prior_ohm_per_cell: float = 0.004
    resistance_walk_ohm_per_sqrt_s: float = 1e-5
    resistance_min_current_a: float = 1.0
    ocv_curve_sigma_v_per_cell: float = 0.01
    current_gain_sigma_fraction: float = 0.01
    state_change_step: float = 0.05
    state_change_bias_sigma: float = 1.0


class ResistanceFilter:
    """The pack's internal resistance R (Ω) from V = OCV(SoC) − I·R, with the SoC from the
    energy state (one state with a slow random walk: R falls as the pack warms)."""

    def __init__(self, pack: PackModel, settings: FusionSettings) -> None:
        self.pack = pack
        self.settings = settings
        cells = pack.spec.cells
        self.ohm, self.var_ohm2 = self._prior()
        ocv_sigma_v = settings.ocv_curve_sigma_v_per_cell * cells
        self._voltage_var_v2 = settings.voltage_noise_v**2 + ocv_sigma_v**2
        self._fixed = settings.internal_resistance_ohm is not None
        #: Whether the voltage follows the load at all.
        self.load = LoadResponse(cells)

    def _prior(self) -> tuple[float, float]:
        """R (Ω) at its start and its variance (Ω²): the fixed value, else the per-cell
        prior."""
        fixed = self.settings.internal_resistance_ohm
        if fixed is not None:
            return fixed, 0.0
        prior = self.settings.resistance_prior_ohm_per_cell * self.pack.spec.cells
        return prior, prior**2

    @property
    def resistance_ohm(self) -> float:
        return max(self.ohm, 0.0)

    def snapshot(self) -> dict[str, float]:
        """R (Ω) and its variance (Ω²), to continue from after a restart."""
        return {"ohm": self.ohm, "var_ohm2": self.var_ohm2}

    def restore(self, state: Mapping[str, Any]) -> None:
        """Continue from :meth:`snapshot` (a fixed resistance stays fixed)."""
        if not self._fixed:
            self.ohm = _finite(state["ohm"], 0.0, 1.0, "resistance (Ω)")
            self.var_ohm2 = _finite(state["var_ohm2"], 0.0, 1.0, "resistance variance")

    def update(self, dt_s: float, soc: float, voltage_v: float, current_a: float) -> None:
        """Fold in a terminal voltage (V) at ``current_a`` (A, measured or modelled) and state
        of charge ``soc``, ``dt_s`` (s) after the last; once the voltage is found not to follow
        the load, R is its prior again and learns no more. One state: the Kalman step
        (Joseph form) in scalars."""
        if self.load.take(dt_s, voltage_v, current_a):
            self.ohm, self.var_ohm2 = self._prior()
        if self._fixed or self.load.unresponsive:
            return
        if dt_s > 0:
            self.var_ohm2 += self.settings.resistance_walk_ohm_per_sqrt_s**2 * dt_s
        if abs(current_a) < self.settings.resistance_min_current_a:
            return  # the drop I·R is lost in the voltage noise (a pack at rest)
        drop_v = self.pack.ocv_scalar_v(soc) - voltage_v  # = I·R + noise
        r_var = self._voltage_var_v2
        gain = self.var_ohm2 * current_a / (current_a * (self.var_ohm2 * current_a) + r_var)
        ohm = self.ohm + gain * (drop_v - current_a * self.ohm)
        keep = 1.0 - gain * current_a
        self.var_ohm2 = keep * self.var_ohm2 * keep + r_var * (gain * gain)
        self.ohm = min(max(ohm, 0.0), 1.0)

    def terminal_voltage_v(self, ocv_v: ArrayLike, power_w: ArrayLike) -> FloatArray:
        """Terminal voltage at terminal power ``power_w``: the root of V² − OCV·V + P·R = 0."""
        ocv, power = np.asarray(ocv_v, dtype=float), np.asarray(power_w, dtype=float)
        disc = np.maximum(ocv * ocv - 4.0 * power * self.resistance_ohm, 0.0)
        return np.asarray(0.5 * (ocv + np.sqrt(disc)))

    def terminal_voltage_scalar_v(self, ocv_v: float, power_w: float) -> float:
        """:meth:`terminal_voltage_v` of one OCV (V) and power (W): the same value, scalar."""
        disc = max(ocv_v * ocv_v - 4.0 * power_w * self.resistance_ohm, 0.0)
        return 0.5 * (ocv_v + math.sqrt(disc))


def _finite(value: Any, low: float, high: float, what: str = "value") -> float:
    """``value`` as a float within [low, high]; ValueError naming ``what`` otherwise (a
    boolean, or an integer too large for a float, included)."""
    if isinstance(value, bool):
        raise ValueError(f"{what} {value!r} is not a number")
    try:
        number = float(value)
    except OverflowError:
        raise ValueError(f"{what} is beyond a float's range") from None
    if not (math.isfinite(number) and low <= number <= high):
        raise ValueError(f"{what} {number:g} is not within [{low:g}, {high:g}]")
    return number


def _flag(value: Any) -> bool:
    """``value`` if it is a JSON boolean; ValueError otherwise."""
    if not isinstance(value, bool):
        raise ValueError(f"{value!r} is not true or false")
    return value


def _scale_bias_row_column(p: list[list[float]], factor: float) -> None:
    """Scale the bias's row and column of the [E, b] covariance ``p`` by ``factor`` (its
    variance by factor²), in place."""
    p[0][1] *= factor
    p[1][0] *= factor
    p[1][1] = p[1][1] * factor * factor  # as a row, then a column, scaled


def _ocv_slope_v(pack: PackModel, soc: float) -> float:
    """dOCV/dSoC of the pack at ``soc`` (V per unit SoC), by a central difference."""
    h = 0.01
    lo, hi = max(soc - h, 0.0), min(soc + h, 1.0)
    return float((pack.ocv_v(hi) - pack.ocv_v(lo)) / (hi - lo))


@dataclass(frozen=True, slots=True)
class EnergyEstimate:
    """Fused energy state: E (Wh, usable above reserve), scale b, their 1σ and covariance."""

    energy_wh: float
    energy_sigma_wh: float
    bias: float
    bias_sigma: float
    #: 2 × 2 over [E, b] (Wh², Wh, 1), including the starting-charge offset.
    covariance: tuple[tuple[float, float], tuple[float, float]]


class EnergyFilter:
    """State [E (Wh usable above reserve), b (model scale)]; see the module docstring."""

    def __init__(self, pack: PackModel, settings: FusionSettings | None = None) -> None:
        self.pack = pack
        self.settings = settings or FusionSettings()
        self._kf: LinearKalman | None = None
        self._time_s: float | None = None
        self._soc_ref = 1.0  # SoC when the consumed-charge counter read 0
        self._charge_rebase = False  # the counter's next reading is its new zero (rebase)
        self._offset_sigma_wh = 0.0
        self._initial_wh = 0.0
        self._anchor_power_w: float | None = None
        self._reserve_wh = float(pack.energy_wh(pack.spec.reserve_fraction))
        #: The pack the energy is of: the configured one until :meth:`anchor`.
        self.real_pack = pack
        self.anchored = False
        self.voltage: ResistanceFilter | None = None
        self.has_current = False
        self.has_charge = False

    # -- state ------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        return self._kf is not None

    @property
    def model_only(self) -> bool:
        """True while no measured current has been fused (the estimate is the model's)."""
        return not self.has_current

    @property
    def voltage_follows_load(self) -> bool:
        """False once the pack voltage is found not to follow the load
        (:mod:`estimator.estimation.load_response`): nothing is learnt from it."""
        return self.voltage is None or not self.voltage.load.unresponsive

    @property
    def time_s(self) -> float:
        """Sample time (s) the energy state is at."""
        self._require()
        assert self._time_s is not None
        return self._time_s

    @property
    def soc(self) -> float:
        """State of charge that the energy state implies."""
        kf = self._require()
        return self.real_pack.soc_from_energy_scalar(max(kf.x[0], 0.0) + self._reserve_wh)

    def estimate(self) -> EnergyEstimate:
        kf = self._require()
        (p_ee, p_eb), (p_be, p_bb) = kf.P
        p_ee += self._offset_sigma_wh**2
        if self.has_current and not self.anchored:
            # A current-sensor gain error g scales both the measured drain and the bias.
            var_g = self.settings.current_gain_sigma_fraction**2
            j_e, j_b = -(self._initial_wh - kf.x[0]), kf.x[1]
            p_ee, p_eb = p_ee + var_g * (j_e * j_e), p_eb + var_g * (j_e * j_b)
            p_be, p_bb = p_be + var_g * (j_b * j_e), p_bb + var_g * (j_b * j_b)
        return EnergyEstimate(
            energy_wh=max(kf.x[0], 0.0),
            energy_sigma_wh=math.sqrt(p_ee),
            bias=kf.x[1],
            bias_sigma=math.sqrt(p_bb),
            covariance=((p_ee, p_eb), (p_be, p_bb)),
        )

    def _require(self) -> LinearKalman:
        if self._kf is None:
            raise RuntimeError("EnergyFilter used before the first battery sample")
        return self._kf

    # -- initialization ---------------------------------------------------------------------

    def initialize(self, sample: BatterySample, power_model_w: float) -> None:
        """Start from one battery reading: SoC from the voltage at rest (corrected by I·R
        under load), the charge counter's zero from the consumed mAh already counted."""
        s, pack, cells = self.settings, self.pack, self.pack.spec.cells
        r_ohm = (
            s.internal_resistance_ohm
            if s.internal_resistance_ohm is not None
            else s.resistance_prior_ohm_per_cell * cells
        )
        current_a = (
            sample.current_a
            if sample.current_a is not None
            else power_model_w / max(sample.voltage_v, 1.0)
        )
        soc = float(pack.soc_from_ocv(sample.voltage_v + max(current_a, 0.0) * r_ohm))
        consumed_ah = (sample.consumed_mah or 0.0) / 1000.0
        self._soc_ref = min(soc + consumed_ah / pack.spec.capacity_ah, 1.0)
        energy_wh = float(pack.usable_energy_wh(soc))
        self._offset_sigma_wh = self._start_sigma_wh(soc, s.capacity_sigma_fraction)
        self._kf = LinearKalman([energy_wh, 1.0], [[0.0, 0.0], [0.0, s.bias_prior_sigma**2]])
        self._initial_wh = energy_wh
        self._time_s = sample.time_s
        self.voltage = ResistanceFilter(pack, s)

    def _start_sigma_wh(self, soc: float, capacity_sigma_fraction: float) -> float:
        """1σ (Wh) of the energy at a start of charge ``soc`` read from the resting voltage
        against the label: the curve's slope there, and the label's error (a fraction)."""
        s, pack = self.settings, self.pack
        high, low = min(soc + 0.01, 1.0), max(soc - 0.01, 0.0)
        slope_wh = float(pack.energy_wh(high) - pack.energy_wh(low)) / (high - low)
        rest_sigma_v = s.rest_voltage_sigma_v_per_cell * pack.spec.cells
        sigma_soc = rest_sigma_v / max(_ocv_slope_v(pack, soc), 0.05)
        energy_wh = float(pack.usable_energy_wh(soc))
        return math.hypot(min(sigma_soc, 0.5) * slope_wh, capacity_sigma_fraction * energy_wh)

    def snapshot(self) -> dict[str, Any]:
        """Everything needed to continue after a daemon restart within the same autopilot
        boot (JSON-ready): time (s, autopilot clock), [E, b] and covariance, the SoC at which
        the consumed-charge counter read 0 (the energy anchor), the start-error terms, the
        resistance filter."""
        kf = self._require()
        assert self.voltage is not None
        return {
            "time_s": self._time_s,
            "x": list(kf.x),
            "P": [list(row) for row in kf.P],
            "soc_ref": self._soc_ref,
            "offset_sigma_wh": self._offset_sigma_wh,
            "initial_wh": self._initial_wh,
            "anchor_power_w": self._anchor_power_w,
            "has_current": self.has_current,
            "has_charge": self.has_charge,
            "resistance": self.voltage.snapshot(),
        }

    def restore(self, state: Mapping[str, Any]) -> None:
        """Continue from :meth:`snapshot`; ValueError/KeyError/TypeError on a bad one. Every
        value must lie in its range: E from minus the reserve to the most energy above it
        of the largest pack (:data:`MAX_CAPACITY_PER_LABEL`), b within :data:`BIAS_RANGE`,
        the covariance symmetric positive semi-definite with b's variance within the prior's
        (the filter's cap), E's within the pack's energy squared."""
        x, p = state_from_json(state["x"], state["P"], 2, "energy state [E, b]")
        most_wh = MAX_CAPACITY_PER_LABEL * float(self.pack.energy_wh(1.0))
        _finite(x[0], -MAX_CAPACITY_PER_LABEL * self._reserve_wh, most_wh, "energy (Wh)")
        _finite(x[1], *BIAS_RANGE, "bias")
        _finite(p[0, 0], 0.0, most_wh**2, "energy variance (Wh²)")
        bias_var_cap = self.settings.bias_prior_sigma**2 * (1.0 + 1e-9)
        _finite(p[1, 1], 0.0, bias_var_cap, "bias variance")
        voltage = ResistanceFilter(self.pack, self.settings)
        voltage.restore(state["resistance"])
        anchor = state["anchor_power_w"]
        self._kf, self.voltage = LinearKalman(x.tolist(), p.tolist()), voltage
        self._time_s = _finite(state["time_s"], 0.0, _MAX_CLOCK_S, "time (s)")
        # the counter's zero lies above full after a reboot the counter did not follow
        self._soc_ref = _finite(state["soc_ref"], 0.0, 2.0, "soc_ref")
        self._offset_sigma_wh = _finite(state["offset_sigma_wh"], 0.0, most_wh, "offset (Wh)")
        self._initial_wh = _finite(state["initial_wh"], 0.0, most_wh, "initial energy (Wh)")
        if anchor is not None:
            anchor = _finite(anchor, 0.0, math.inf, "anchor power (W)")
        self._anchor_power_w = anchor
        self.has_current = _flag(state["has_current"])
        self.has_charge = _flag(state["has_charge"])

    def rebase(self, time_s: float) -> None:
        """The autopilot rebooted: its clock restarts at ``time_s``. Keep the energy state;
        re-reference the clock now and the consumed-charge counter at its first reading
        after the reboot (a real reboot restarts it at 0; a forged one, five frames of an
        earlier clock, does not, and taking it for 0 counted the charge drawn twice)."""
        self._require()
        self._time_s = time_s
        self._soc_ref = self.soc
        self._charge_rebase = True

    # -- predict / update -------------------------------------------------------------------

    def predict(
        self, time_s: float, power_model_w: float, loss_factor: float, measured: bool = False
    ) -> None:
        """Advance to ``time_s`` drawing ``b · power_model_w`` at the terminals (W), with
        chemical energy leaving ``loss_factor`` (= OCV/V ≥ 1) times faster. ``measured``: the
        power is a measured one (V·I, where the model does not hold: on the ground, at
        take-off), drawn as it is, with the measurement's error and no tie to the bias."""
        kf = self._require()
        assert self._time_s is not None
        dt = time_s - self._time_s
        if dt <= 0:
            return
        self._time_s = time_s
        s = self.settings
        drain_wh = power_model_w * loss_factor * dt / 3600.0
        q_b = s.bias_walk_per_sqrt_s**2 * dt
        if measured:
            q_e = (s.power_noise_fraction * drain_wh) ** 2
            kf.x[0] -= drain_wh
            f = ((1.0, 0.0), (0.0, 1.0))
        else:
            f = ((1.0, -drain_wh), (0.0, 1.0))
            q_e = (s.model_power_noise_fraction * drain_wh) ** 2
        kf.predict(f, ((q_e, 0.0), (0.0, q_b)))
        self._cap_bias_variance()

    def flight_state_changed(self, steady_power_w: float) -> None:
        """The model's steady power moved: the bias learned at the old flight state transfers
        only partly to the new one (the model's error depends on the state, e.g. unknown
        wind matters more in cruise than in hover). Each move of more than
        ``state_change_step`` (fraction) since the last one adds variance to the bias of
        (``state_change_bias_sigma`` × relative move)²."""
        kf = self._require()
        s = self.settings
        if self._anchor_power_w is None or self._anchor_power_w <= 0:
            self._anchor_power_w = steady_power_w
            return
        move = abs(steady_power_w - self._anchor_power_w) / self._anchor_power_w
        if move > s.state_change_step:
            kf.P[1][1] += (s.state_change_bias_sigma * move) ** 2
            self._anchor_power_w = steady_power_w
            self._cap_bias_variance()

    def rescale_bias(self, factor: float) -> None:
        """The model's effects changed so that its power is 1/``factor`` times what it was
        for the same flight (e.g. a payload now in the model): the measured power did not
        change, so the bias (and its uncertainty and the state-change anchor) scales by
        ``factor``."""
        kf = self._require()
        if not (math.isfinite(factor) and factor > 0):
            return
        kf.x[1] *= factor
        _scale_bias_row_column(kf.P, factor)
        if self._anchor_power_w is not None:
            self._anchor_power_w /= factor
        self._cap_bias_variance()

    def _cap_bias_variance(self) -> None:
        """The bias is never less known than the prior says the model is: without
        measurements its variance stops at ``bias_prior_sigma²`` (row and column scaled
        together, so P stays positive semi-definite)."""
        kf = self._require()
        cap = self.settings.bias_prior_sigma**2
        if kf.P[1][1] > cap:
            _scale_bias_row_column(kf.P, math.sqrt(cap / kf.P[1][1]))

    def update_power(
        self,
        measured_w: float,
        power_model_w: float,
        model_sigma_w: float = 0.0,
        readings: int = 1,
    ) -> None:
        """Fold in measured terminal power V·I (W) against the model's power (W), whose
        flight-state uncertainty (e.g. from the filtered acceleration) is ``model_sigma_w``.
        With ``readings`` > 1 both are means of that many readings: the reading noise averages
        down by √readings."""
        kf = self._require()
        self.has_current = True
        s = self.settings
        reading_sigma_w = s.power_noise_fraction * abs(measured_w) + s.power_noise_floor_w
        sigma_w = math.hypot(reading_sigma_w / math.sqrt(readings), model_sigma_w)
        kf.update(measured_w, (0.0, power_model_w), sigma_w**2)

    def anchor(self, pack: PackEstimate) -> None:
        """The pack filter (:mod:`estimator.estimation.pack_state`) knows the energy left
        better than the counted charge against the label: the energy state becomes its
        (value and variance, no longer tied to the scale, no start offset), of the pack with
        its learned capacity."""
        kf = self._require()
        self.anchored = True
        self.real_pack = self.pack.with_capacity(pack.capacity_ah)
        self._reserve_wh = self.real_pack.energy_scalar_wh(self.pack.spec.reserve_fraction)
        kf.x[0] = pack.energy_wh
        kf.P[0][0] = pack.energy_sigma_wh**2
        kf.P[0][1] = kf.P[1][0] = 0.0
        self._offset_sigma_wh = 0.0

    def count_against_label(self, drawn_ah: float, capacity_sigma_fraction: float) -> None:
        """The pack filter was refuted (:attr:`PackFilter.refuted`): from now on the energy is
        the label's, as before :meth:`anchor`: the charge at the start less ``drawn_ah`` (Ah,
        since the counter read 0, or since the start without one) over the label, with the
        start's 1σ (resting voltage, and the label known to ``capacity_sigma_fraction``, the
        pack filter's prior: it learnt nothing) and the counted charge's."""
        kf = self._require()
        self.anchored = False
        self.real_pack = self.pack
        self._reserve_wh = float(self.pack.energy_wh(self.pack.spec.reserve_fraction))
        soc = min(max(self._soc_ref - drawn_ah / self.pack.spec.capacity_ah, 0.0), 1.0)
        used_wh = float(self.pack.energy_wh(self._soc_ref) - self.pack.energy_wh(soc))
        kf.x[0] = float(self.pack.usable_energy_wh(soc))
        kf.P[0][0] = self._counted_sigma_wh(used_wh) ** 2
        kf.P[0][1] = kf.P[1][0] = 0.0
        self._initial_wh = float(self.pack.usable_energy_wh(self._soc_ref))
        self._offset_sigma_wh = self._start_sigma_wh(
            min(self._soc_ref, 1.0), capacity_sigma_fraction
        )

    def update_charge(self, consumed_mah: float) -> None:
        """Fold in the autopilot's consumed charge (mAh) as the energy it leaves (Wh)."""
        kf = self._require()
        self.has_charge = True
        pack = self.pack
        if self._charge_rebase:  # the counter's first reading since a reboot: its new zero
            self._charge_rebase = False
            self._soc_ref = self.soc + consumed_mah / 1000.0 / pack.spec.capacity_ah
        soc_now = self._soc_ref - consumed_mah / 1000.0 / pack.spec.capacity_ah
        energy_wh = float(pack.usable_energy_wh(soc_now))
        used_wh = float(pack.energy_wh(self._soc_ref) - pack.energy_wh(soc_now))
        kf.update(energy_wh, (1.0, 0.0), self._counted_sigma_wh(used_wh) ** 2)

    def _counted_sigma_wh(self, used_wh: float) -> float:
        """1σ (Wh) of the energy left as the counted charge says, ``used_wh`` (Wh) used."""
        return self.settings.charge_sigma_fraction * abs(used_wh) + 0.2

    # -- endurance --------------------------------------------------------------------------

    @property
    def bias(self) -> float:
        return self._require().x[1]

    def endurance_s(
        self, terminal_power_w: ArrayLike, est: EnergyEstimate | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Time (s) until the reserve at each constant terminal power (W), and its 1σ.

        Integrates the pack forward: at each energy level the OCV, the sagging terminal
        voltage, the current and the chemical drain P·OCV/V follow from the pack model and
        the estimated resistance. σ by first-order propagation of [E, b] (each power is
        ``b`` times a model power, so T scales as 1/b). Non-positive power: infinite time.
        """
        est = est or self.estimate()
        power_w = np.array(terminal_power_w, dtype=float, ndmin=1)
        if est.energy_wh <= 0:
            return np.zeros_like(power_w), np.zeros_like(power_w)
        assert self.voltage is not None
        e_grid = est.energy_wh * _UNIT_GRID
        ocv = self.real_pack.ocv_from_energy_v(self._reserve_wh + e_grid)
        positive = np.maximum(power_w, 1e-9)[:, None]
        terminal_v = self.voltage.terminal_voltage_v(ocv[None, :], positive)
        inv_drain = np.maximum(terminal_v, 1e-3) / (positive * ocv[None, :])
        step_wh = e_grid[1] - e_grid[0]
        time_s = (
            3600.0 * step_wh * (inv_drain.sum(axis=1) - 0.5 * (inv_drain[:, 0] + inv_drain[:, -1]))
        )
        d_energy = 3600.0 * inv_drain[:, -1]
        d_bias = -time_s / max(est.bias, 1e-3)
        (var_e, cov_eb), (_, var_b) = est.covariance
        var = d_energy**2 * var_e + 2 * d_energy * d_bias * cov_eb + d_bias**2 * var_b
        sigma_s = np.sqrt(np.maximum(var, 0.0))
        off = power_w <= 0
        time_s[off] = sigma_s[off] = np.inf
        return time_s, sigma_s

    def loss_factor(self, terminal_power_w: float) -> float:
        """OCV / V at the current state and terminal power (≥ 1)."""
        if self.voltage is None or terminal_power_w <= 0:
            return 1.0
        ocv_v = self.real_pack.ocv_scalar_v(self.soc)
        v = self.voltage.terminal_voltage_scalar_v(ocv_v, terminal_power_w)
        return ocv_v / max(v, 1e-3)
