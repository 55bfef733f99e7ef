"""The pack side of the pipeline: what each period's end teaches about the battery.

The reading a period ends with (:mod:`estimator.estimation.period_reading`: the readings
held over its last 50 ms) goes, with the consumed charge then, into

- the fusion's charge counter, while no pack filter runs (:meth:`EnergyFilter.update_charge`);
- the voltage model (the pack's resistance, :class:`estimator.estimation.fusion.ResistanceFilter`),
  with the current measured, else the model's (bias × model power / V);
- the pack filter (:mod:`estimator.estimation.pack_bank`), when the reading has a current: the
  fusion's energy then rests on the pack's (:meth:`EnergyFilter.anchor`). A voltage that does
  not follow the load teaches it nothing: no pack is learnt. Nor does one that does not
  follow the charge drawn as any pack's does (:attr:`PackBank.refuted`): the energy is
  counted against the label from then on (:meth:`EnergyFilter.count_against_label`).

The first reading of a start goes to the pack filter too, so the first estimate rests on the
pack as every later one does. Units: V, A, mAh, s (sample clock).
"""

from __future__ import annotations

from estimator.estimation.fusion import EnergyFilter
from estimator.estimation.pack_bank import PackBank
from estimator.estimation.pack_state import (
    PackEstimate,
    PackPrior,
    PackSettings,
    capacity_range_ah,
)
from estimator.estimation.period_reading import period_end_reading
from estimator.physics.battery import PackModel
from estimator.telemetry.samples import BatterySample


class PackLearning:
    """The pack filter and the voltage model, fed once per period."""

    def __init__(self, pack: PackModel, settings: PackSettings, prior: PackPrior | None) -> None:
        """``prior``: what is known of this pack (capacity, resistance; e.g. from its last
        flight), else its label and ``settings``' prior."""
        self.pack, self.settings, self.prior = pack, settings, prior
        #: The pack learned in flight (started at the first battery reading with a current).
        self.state: PackBank | None = None
        #: The pack filter's estimate after its last reading.
        self.estimate: PackEstimate | None = None
        #: The pack filter was refuted (:attr:`PackBank.refuted`: the voltage does not follow
        #: the charge drawn as any pack's does): the energy is counted against the label for
        #: the rest of the flight.
        self.refuted = False
        self._held: BatterySample | None = None  # the last reading before the open period
        self._resistance_time_s: float | None = None

    def refuted_note(self) -> str | None:
        """One sentence once the pack filter is refuted (None before)."""
        if not self.refuted:
            return None
        label_ah = self.pack.spec.capacity_ah
        low_ah, high_ah = capacity_range_ah(label_ah)
        return (
            "the pack voltage does not follow the charge drawn as a pack's does (its capacity "
            f"would lie outside {low_ah:.1f}-{high_ah:.1f} Ah, for a label of {label_ah:.1f} "
            "Ah): the capacity is not learnt; the energy left is counted against the label"
        )

    def new_bank(self) -> PackBank:
        """A pack filter from the prior (or the label)."""
        return PackBank(self.pack, self.settings, self.prior)

    def begin(
        self, sample: BatterySample, resumed: PackBank | None = None, refuted: bool = False
    ) -> None:
        """The first reading after a start: held into the first period; with a pack filter
        ``resumed`` from a snapshot, that filter continues from here; ``refuted``: the
        snapshot's pack filter was refuted, so none is learnt for the rest of the flight."""
        self._held = sample
        self._resistance_time_s = sample.time_s
        self.refuted |= refuted
        if resumed is not None:
            resumed.last_time_s = sample.time_s
            self.state, self.estimate = resumed, resumed.estimate()

    def first(self, sample: BatterySample, energy: EnergyFilter) -> None:
        """The first reading of a fresh start into the pack filter (after :meth:`begin`)."""
        self._learn(sample, sample.consumed_mah, energy)

    def reboot(self, time_s: float | None) -> None:
        """The autopilot rebooted: no reading is held; the pack filter's charge counter
        starts again; ``time_s``: the new clock's time (None before the energy starts)."""
        self._held = None
        if self.state is not None:
            self.state.rebase()
        if time_s is not None:
            self._resistance_time_s = time_s

    def adopt(self, prior: PackPrior) -> None:
        """Learn the pack from ``prior`` from the next reading on."""
        self.prior, self.state, self.estimate = prior, None, None

    def period_end(
        self,
        energy: EnergyFilter,
        readings: list[BatterySample],
        end_s: float,
        model_w: float,
    ) -> None:
        """A period that ends at ``end_s`` with its ``readings`` (at least one, in time
        order): the charge counter, the voltage model and the pack filter; ``model_w``: the
        model power in force at the last reading (W), for a reading without a current."""
        end = period_end_reading(self._held, readings, end_s)
        self._held = readings[-1]
        consumed_mah = end.consumed_mah
        if consumed_mah is None:  # the period's last counter value, if any reading had one
            charge = [r.consumed_mah for r in readings if r.consumed_mah is not None]
            consumed_mah = charge[-1] if charge else None
        if consumed_mah is not None and self.state is None:
            energy.update_charge(consumed_mah)
        current_a = end.current_a
        if current_a is None:
            current_a = energy.bias * model_w / end.voltage_v
        assert energy.voltage is not None and self._resistance_time_s is not None
        dt = max(end.time_s - self._resistance_time_s, 0.0)
        self._resistance_time_s = end.time_s
        energy.voltage.update(dt, energy.soc, end.voltage_v, current_a)
        self._learn(end, consumed_mah, energy)

    def _learn(
        self, reading: BatterySample, consumed_mah: float | None, energy: EnergyFilter
    ) -> None:
        """``reading``, when it has a current, into the pack filter (with the counter's value
        then); the fusion's energy then rests on the pack's."""
        if not energy.voltage_follows_load or self.refuted:
            self.state = self.estimate = None
            return
        if reading.current_a is not None:
            if self.state is None:
                self.state = self.new_bank()
            bank = self.state
            bank.take(reading.time_s, reading.voltage_v, reading.current_a, consumed_mah)
            if bank.refuted:
                self.refuted, self.state, self.estimate = True, None, None
                refuted = bank.best
                drawn_ah = refuted.charge_ah if consumed_mah is None else consumed_mah / 1e3
                q0, q_sigma = refuted.capacity_prior()
                energy.count_against_label(drawn_ah, q_sigma / q0)
                return
            self.estimate = bank.estimate()
            energy.anchor(self.estimate)
