"""The pack filter as the pipeline runs it: one filter, or a bank of starts when the pack is
first seen under load.

A pack at rest gives its charge from its voltage whatever its resistance. Under load (the
daemon (re)started in flight without a state file) the voltage is OCV(charge) − I·R: the
charge and the resistance are one unknown until the current moves, and one filter
linearised at its prior resistance may settle on a wrong pair, surely (on the SITL flight
pack_c80_r3, 30 mΩ against a 12 ± 12 mΩ prior, one filter held a charge of 0.33 ± 0.01 a
minute later where the truth was 0.69).

So when the first reading's current times the prior resistance's 1σ exceeds
:data:`AMBIGUOUS_SAG_V`, the pack starts as a Gaussian sum: one
:class:`~estimator.estimation.pack_state.PackFilter` per resistance on a geometric grid
over the prior's plausible range (:func:`resistance_grid`), each weighed by the likelihood
of the readings under it (:attr:`PackFilter.log_likelihood`; the starts share one learnt
reading noise, so none gains weight by a noise it learnt alone), tempered
(:data:`LIKELIHOOD_POWER`). The estimate is the mixture's mean and variance, so its σ holds
the spread between the starts while they disagree; once one holds :data:`COLLAPSE_WEIGHT`
of the weight the others are dropped, and so is a start refuted on its own
(:attr:`PackFilter.refuted`) while another is not.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from estimator.estimation.pack_state import PackEstimate, PackFilter, PackPrior, PackSettings
from estimator.physics.battery import PackModel
from estimator.telemetry.samples import BatterySample

#: Sag (V) the prior resistance's 1σ may hide at the first reading's current before the
#: start is a bank: 50 mV is a few percent of charge on the flat of a LiPo curve.
AMBIGUOUS_SAG_V = 0.05
#: Weight one start must hold for the others to be dropped.
COLLAPSE_WEIGHT = 0.999
#: The weights take the readings' likelihood to this power (a tempered likelihood; Grünwald
#: & van Ommen, "Inconsistency of Bayesian inference for misspecified linear models", Bayesian
#: Analysis 12(4), 2017). The likelihood counts each reading as independent evidence, but what
#: tells the starts apart (the pack's curve against the configured one, the lag of its voltage
#: behind a step) persists over many readings: at full weight, on the SITL pack flights
#: restarted in flight, the weight swung to 0.99 on a wrong start and back within a minute,
#: and the mixture's σ was that start's own (pack_c60_r1: −15 % at 6.2σ). Chosen on those 35
#: restarted development flights: worst |error|/σ 6.2 → 2.5, median |error| 60 s after the
#: restart 8.9 → 5.6 % (``python scripts/pack_state_sitl.py``).
LIKELIHOOD_POWER = 0.3
#: Most starts in a bank.
MAX_STARTS = 8
#: Ratio between neighbouring resistances of the grid (at most).
GRID_RATIO = 2.0


def resistance_grid(resistance_ohm: float, sigma_ohm: float) -> list[tuple[float, float]]:
    """Starts (resistance Ω, 1σ) over a prior ``resistance_ohm`` ± ``sigma_ohm``: from
    max(R − 2σ, R/4) to R + 3σ, neighbours at most :data:`GRID_RATIO` apart, each with a 1σ
    of half its value (at most the prior's)."""
    low = max(resistance_ohm - 2.0 * sigma_ohm, resistance_ohm / 4.0, 1e-4)
    high = max(resistance_ohm + 3.0 * sigma_ohm, low)
    n = min(max(2, math.ceil(math.log(high / low) / math.log(GRID_RATIO)) + 1), MAX_STARTS)
    return [(float(r), min(sigma_ohm, 0.5 * float(r))) for r in np.geomspace(low, high, n)]


class PackBank:
    """The pack's filter(s) for one flight; the same interface as one
    :class:`~estimator.estimation.pack_state.PackFilter` where the pipeline uses it."""

    def __init__(
        self, pack: PackModel, settings: PackSettings, prior: PackPrior | None = None
    ) -> None:
        self.pack, self.settings, self.prior = pack, settings, prior
        self.filters = [PackFilter(pack, settings, prior)]
        self.weights = np.ones(1)

    @property
    def refuted(self) -> bool:
        """Every start is refuted (:attr:`PackFilter.refuted`): the voltage does not follow
        the charge drawn as any pack's does. A refuted start among others is dropped."""
        return all(f.refuted for f in self.filters)

    @property
    def best(self) -> PackFilter:
        """The start that holds the most weight."""
        return self.filters[int(np.argmax(self.weights))]

    @property
    def last_time_s(self) -> float | None:
        return self.filters[0].last_time_s

    @last_time_s.setter
    def last_time_s(self, time_s: float | None) -> None:
        for f in self.filters:
            f.last_time_s = time_s

    def take(
        self, time_s: float, voltage_v: float, current_a: float, consumed_mah: float | None
    ) -> None:
        """One reading (:meth:`PackFilter.take`) into every start, then the weights."""
        first = self.filters[0]
        if not first.started and len(self.filters) == 1:
            r_ohm, sigma_ohm = first.resistance_prior()
            if max(current_a, 0.0) * sigma_ohm > AMBIGUOUS_SAG_V:
                grid = resistance_grid(r_ohm, sigma_ohm)
                self.filters = [
                    PackFilter(self.pack, self.settings, self.prior, start) for start in grid
                ]
        for f in self.filters:
            f.take(time_s, voltage_v, current_a, consumed_mah)
        if any(f.refuted for f in self.filters) and not self.refuted:
            self.filters = [f for f in self.filters if not f.refuted]
        if len(self.filters) == 1 and math.isfinite(self.filters[0].log_likelihood):
            self.weights = np.ones(1)  # one start holds all the weight
            return
        log_l = np.array([f.log_likelihood for f in self.filters])
        weights = np.exp(LIKELIHOOD_POWER * (log_l - log_l.max()))
        self.weights = weights / weights.sum()
        if len(self.filters) > 1:
            noise_v2 = float(self.weights @ np.array([f.noise_mean_v2 for f in self.filters]))
            for f in self.filters:
                f.share_noise(noise_v2)
        if len(self.filters) > 1 and self.weights.max() >= COLLAPSE_WEIGHT:
            self.filters, self.weights = [self.best], np.ones(1)

    def rebase(self) -> None:
        """The autopilot restarted: its counter starts again from 0 (every start)."""
        for f in self.filters:
            f.rebase()

    def estimate(self) -> PackEstimate:
        """The mixture's mean and 1σ of each figure (one start: its own)."""
        if len(self.filters) == 1:
            return self.filters[0].estimate()
        parts = [f.estimate() for f in self.filters]
        w = self.weights

        def moments(mean: str, sigma: str) -> tuple[float, float]:
            m = np.array([getattr(p, mean) for p in parts])
            s = np.array([getattr(p, sigma) for p in parts])
            mu = float(w @ m)
            return mu, math.sqrt(max(float(w @ (s * s + (m - mu) ** 2)), 0.0))

        soc, soc_sigma = moments("soc", "soc_sigma")
        capacity, capacity_sigma = moments("capacity_ah", "capacity_sigma_ah")
        resistance, resistance_sigma = moments("resistance_ohm", "resistance_sigma_ohm")
        energy, energy_sigma = moments("energy_wh", "energy_sigma_wh")
        return PackEstimate(
            soc, soc_sigma, capacity, capacity_sigma, resistance, resistance_sigma, energy,
            energy_sigma,
        )  # fmt: skip

    def snapshot(self) -> dict[str, Any]:
        """The most weighted start's state (:meth:`PackFilter.snapshot`)."""
        return self.best.snapshot()

    def restore(self, state: Mapping[str, Any]) -> None:
        """Continue from a snapshot as one filter (:meth:`PackFilter.restore`)."""
        restored = PackFilter(self.pack, self.settings, self.prior)
        restored.restore(state)
        self.filters, self.weights = [restored], np.ones(1)


def track_pack(
    samples: Iterable[BatterySample],
    pack: PackModel,
    settings: PackSettings | None = None,
    prior: PackPrior | None = None,
) -> list[tuple[float, PackEstimate]]:
    """The pack's filter(s) over a flight's battery readings that carry a current: (time s,
    estimate) after each (:meth:`PackBank.take`)."""
    tracker = PackBank(pack, settings or PackSettings(), prior)
    out: list[tuple[float, PackEstimate]] = []
    for sample in samples:
        if sample.current_a is None or not math.isfinite(sample.voltage_v):
            continue
        tracker.take(sample.time_s, sample.voltage_v, sample.current_a, sample.consumed_mah)
        out.append((sample.time_s, tracker.estimate()))
    return out
