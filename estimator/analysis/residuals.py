"""Residual analysis: what the power model lacks, found on data it was not fitted on.

The residual is r = measured electrical power − model power (the vehicle file's model and
effects through :func:`estimator.physics.effects.predict_power_w`) at every sample of level
flight, from the first after take-off to the last before landing.

This module holds the selection and its result; the steps below live in
:mod:`~estimator.analysis.residual_samples` (1–2), :mod:`~estimator.analysis.residual_candidates`
(3), :mod:`~estimator.analysis.residual_fit` (fitting, window search) and
:mod:`~estimator.analysis.residual_attribution` (5).

Method
------
1. **Samples** (:func:`prepare`): each flight's rows (one per power sample) while airborne
   (armed or unknown, above ``min_alt_m`` when the altitude is known, measured power above
   ``min_power_w`` and above ``min_power_fraction`` of the flight's median: motors at idle on
   touch-down are not flight). Ground velocity is smoothed with a Gaussian kernel of
   ``smooth_s`` (s, 1σ) inside gap-free stretches and differentiated for the horizontal
   acceleration (NED). Channels for the structure and the attribution: flight time, ground
   speed, heading, a⊥, tangential acceleration, climb rate, altitude, battery voltage, energy
   drawn so far (a state-of-charge proxy from the measured power), and the log's own numeric
   extras (CMU: payload, airflow).
2. **Held-out split**: each flight is cut into contiguous time chunks of ``chunk_s`` seconds,
   assigned to the ``folds`` in turn; fold j holds out its chunks and trains on the rest minus
   a guard of ``guard_s`` seconds on both sides of each held-out chunk (correlated noise must
   not leak). Never random samples. Short chunks keep the training data close to every
   held-out time: an effect that changes in flight is located within a chunk.
3. **Candidates**: one :class:`Candidate` per effect of :mod:`estimator.physics.effects` not
already in
   the vehicle file, each with one or two parameters fitted by ``scipy.optimize.least_squares``
   (soft-L1 loss, bounds from the effect's ``bounds``). ``wind``, ``mass`` and ``avionics``
   also come in a time window searched on the training data (prefix sums), and ``wind`` as a
   change (two winds, one switch time); the simplest form wins unless a richer one cuts the
   held-out RMSE by ``min_gain_fraction``.
4. **Greedy forward selection**: at each step every remaining candidate is added to the
   selected set and scored by its held-out predictions. The held-out squared errors of the
   current and the extended model are summed per evaluation block of ``block_s`` seconds and
   compared pairwise over the blocks (a Wilcoxon signed-rank test on the block gains, as a z:
   a rank test because block gains are heavy-tailed, a few manoeuvre blocks dominating their
   spread, which would hide an effect that helps nearly every block; 2.5 s blocks outlast the
   residual's correlation, which falls to zero within 2 s on SITL telemetry, so block gains
   are nearly independent, and are short because n blocks that all gain reach at most
   z = √(3n(n+1)/(2(2n+1))): z 3 takes 12 of them, so an effect confined to a time window
   can be named only if it lasts 12 blocks, 30 s). A candidate qualifies when
   z > ``z_threshold`` (3: one-sided p ≈ 0.001, ≈ 1 % family-wise over the candidates) *and*
   it cuts the held-out RMSE by at least ``min_gain_fraction`` *and*, for a wind, the vehicle
   could fly through it (:func:`~estimator.analysis.residual_candidates.winds_within_reach`,
   in most folds, where the vehicle file states its airspeed); the best qualifying one is
   added; selection stops when none qualifies. On clean data nothing qualifies.
5. **Attribution**: the held-out residual left after selection is regressed on each channel
   alone with a k-nearest-neighbour regressor (sklearn, same folds; the mean per value for
   channels with at most 16 distinct values, like a payload column); the channel with the
   highest held-out R² is where the remaining structure lives. When nothing was selected and a
   channel still predicts the residual, no candidate explains it and that channel is where to
   look.

Final parameters are refitted on all samples; their spread over the folds is reported too.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import rankdata

from estimator.analysis.residual_attribution import ChannelScore, attribute
from estimator.analysis.residual_candidates import (
    Candidate,
    candidates_for,
    winds_within_reach,
)
from estimator.analysis.residual_fit import FitProblem, Term, fit_design
from estimator.analysis.residual_samples import ResidualOptions, Samples, prepare
from estimator.errors import UserError
from estimator.logs import FlightSeries
from estimator.physics.effects import (
    Avionics,
    Effect,
    Mass,
    ReportedWind,
    Wind,
)
from estimator.physics.lean_limit import airspeed_reach_mps
from estimator.physics.model import FloatArray
from estimator.physics.vehicle import Vehicle


@dataclass
class CandidateScore:
    """One candidate tried at one selection step (held-out figures)."""

    step: int
    label: str
    rmse_w: float
    gain_fraction: float
    z: float
    qualifies: bool
    params: dict[str, Any]
    #: False when its wind is beyond the vehicle's reach in most folds (it cannot qualify).
    within_reach: bool = True


@dataclass
class Selected:
    """An effect chosen by the selection: final parameters (all data) and held-out RMSE after.
    ``effects``: one, or two for a change (the first until the switch time, the second
    after)."""

    name: str
    effects: tuple[Effect, ...]
    rmse_after_w: float
    z: float
    #: Spread over the folds of each effect's parameters (one dict per effect).
    params_fold_sd: list[dict[str, float]]
    #: Qualifying candidates as good on held-out data (label, RMSE W, z of chosen vs it).
    ties: list[tuple[str, float, float]] = field(default_factory=list)
    #: The best other candidate of that step (label, RMSE W, z of chosen vs it), if any.
    runner_up: tuple[str, float, float] | None = None
    #: The candidate's label ("mass (window)" for one in a time window).
    label: str = ""

    def as_dicts(self) -> list[dict[str, Any]]:
        """One JSON object per effect (a change gives two, in time order; a reported wind
        one per steady wind of its summary, with its scale)."""
        out: list[dict[str, Any]] = []
        for effect, sd in zip(self.effects, self.params_fold_sd, strict=True):
            if isinstance(effect, ReportedWind):
                out.extend(
                    self._as_dict(
                        f"{_reported(effect)}: {describe(wind)}", effect.params | wind.params, sd
                    )
                    for wind in effect.steady()
                )
            else:
                out.append(self._as_dict(describe(effect), effect.params, sd))
        return out

    def _as_dict(
        self, description: str, params: dict[str, Any], fold_sd: dict[str, float]
    ) -> dict[str, Any]:
        return {
            "name": self.name,
            "label": self.label or self.name,
            "description": description,
            "params": _round_params(params),
            "rmse_after_w": round(self.rmse_after_w, 3),
            "z": round(self.z, 2),
            "params_fold_sd": {k: round(v, 4) for k, v in fold_sd.items()},
            "indistinguishable_from": [
                {"candidate": label, "rmse_w": round(r, 3), "z": round(z, 2)}
                for label, r, z in self.ties
            ],
            "runner_up": None
            if self.runner_up is None
            else {
                "candidate": self.runner_up[0],
                "rmse_w": round(self.runner_up[1], 3),
                "z": round(self.runner_up[2], 2),
            },
        }


@dataclass
class ResidualResult:
    """Everything the command prints, writes and plots."""

    samples: Samples
    options: ResidualOptions
    predicted_before_w: FloatArray
    predicted_after_w: FloatArray
    selected: list[Selected]
    table: list[CandidateScore]
    attribution: list[ChannelScore]
    attribution_before: list[ChannelScore]
    noise_floor_w: float
    #: The final effects (fitted on all samples) at every sample: the in-sample fit, W.
    predicted_final_w: FloatArray | None = None

    @property
    def effects(self) -> list[Effect]:
        return [e for s in self.selected for e in s.effects]

    @property
    def steady_effects(self) -> list[Effect]:
        """:attr:`effects` with a reported wind as its steady winds (the vehicle file's form)."""
        return [
            part
            for effect in self.effects
            for part in (effect.steady() if isinstance(effect, ReportedWind) else (effect,))
        ]

    def residual_before_w(self) -> FloatArray:
        return self.samples.power_w - self.predicted_before_w

    def residual_after_w(self) -> FloatArray:
        return self.samples.power_w - self.predicted_after_w

    def rmse_w(self, after: bool) -> float:
        r = self.residual_after_w() if after else self.residual_before_w()
        return float(np.sqrt(np.mean(r**2)))

    def mape_pct(self, after: bool) -> float:
        r = self.residual_after_w() if after else self.residual_before_w()
        return float(np.mean(np.abs(r) / np.abs(self.samples.power_w)) * 100.0)

    def rmse_in_sample_w(self) -> float:
        """RMSE of the final effects (fitted on all samples, change times included), W: what
        the held-out RMSE cannot reach when a change falls inside a held-out chunk."""
        final = self.predicted_after_w if self.predicted_final_w is None else self.predicted_final_w
        return float(np.sqrt(np.mean((self.samples.power_w - final) ** 2)))

    def rmse_to_floor(self) -> float:
        """Held-out RMSE after selection over the noise floor (1 = white noise only)."""
        floor = self.noise_floor_w
        return self.rmse_w(True) / floor if floor > 0 else math.inf

    def unexplained_share(self) -> float:
        """Share of the remaining residual's variance above the white noise floor (0..1):
        structure the selected effects do not explain."""
        rmse = self.rmse_w(True)
        return max(0.0, 1.0 - (self.noise_floor_w / rmse) ** 2) if rmse > 0 else 0.0

    def verdict(self) -> str:
        """One sentence: what was added and what is left. Never "noise" when the residual's
        RMSE is more than ``noise_ratio`` noise floors."""
        best = self.attribution[0] if self.attribution else None
        channel = None if best is None else f"{best.channel} (held-out R² {best.r2:.2f})"
        predictive = best is not None and best.r2 >= self.options.min_r2
        ratio = self.rmse_to_floor()
        level = (
            f"held-out RMSE {self.rmse_w(True):.1f} W is {ratio:.1f}× the noise floor "
            f"{self.noise_floor_w:.1f} W"
        )
        added = "; ".join(
            " then ".join(describe(e) for e in s.effects)
            + (f" (as good held out: {', '.join(t[0] for t in s.ties)})" if s.ties else "")
            for s in self.selected
        )
        head = (
            f"added {added}" if self.selected else "no candidate effect improves the held-out error"
        )
        if ratio > self.options.noise_ratio:
            where = (
                f"the channel that best predicts it is {channel}"
                if predictive
                else f"no channel predicts it well (best: {channel or 'none'})"
            )
            return (
                f"{head}; the remaining residual is not noise: {level}, "
                f"{100 * self.unexplained_share():.0f} % of its variance is unexplained "
                f"structure; {where}"
            )
        if predictive:
            return f"{head}; {level}; the remaining residual is best predicted by {channel}"
        if not self.selected:
            return f"{head} and no channel predicts the residual ({level}): it looks like noise"
        return f"{head}; {level}: the remaining residual is at the noise level"

    def summary(self) -> dict[str, Any]:
        """The JSON object of ``uav-energy residuals --json``."""
        return {
            "rmse_before_w": round(self.rmse_w(False), 3),
            "rmse_after_w": round(self.rmse_w(True), 3),
            "mape_before_pct": round(self.mape_pct(False), 3),
            "mape_after_pct": round(self.mape_pct(True), 3),
            "effects": [d for s in self.selected for d in s.as_dicts()],
            "attribution": {
                "verdict": self.verdict(),
                "best_channel": self.attribution[0].channel if self.attribution else None,
                "channels": [
                    {"channel": c.channel, "r2": round(c.r2, 4)} for c in self.attribution
                ],
                "channels_before": [
                    {"channel": c.channel, "r2": round(c.r2, 4)} for c in self.attribution_before
                ],
            },
            "selection": [
                {
                    "step": c.step,
                    "candidate": c.label,
                    "rmse_w": round(c.rmse_w, 3),
                    "gain_pct": round(100.0 * c.gain_fraction, 2),
                    "z": round(c.z, 2),
                    "qualifies": c.qualifies,
                    "within_reach": c.within_reach,
                    "params": _round_params(c.params),
                }
                for c in self.table
            ],
            "n_samples": len(self.samples),
            "n_flights": len(self.samples.flight_ids),
            "flights": self.samples.flight_ids,
            "skipped_flights": self.samples.skipped_flights,
            "split": f"chunks of {self.options.chunk_s:g} s assigned to {self.options.folds} "
            f"folds in turn, guard {self.options.guard_s:g} s",
            "test": f"Wilcoxon signed-rank over {len(np.unique(self.samples.block))} blocks of "
            f"{self.options.block_s:g} s, z > {self.options.z_threshold:g} and RMSE gain ≥ "
            f"{100 * self.options.min_gain_fraction:g} %",
            "noise_floor_w": round(self.noise_floor_w, 3),
            "rmse_to_floor": round(self.rmse_to_floor(), 2),
            "rmse_in_sample_w": round(self.rmse_in_sample_w(), 3),
            "unexplained_share": round(self.unexplained_share(), 3),
        }


def _when(at_s: float | None, until_s: float | None) -> str:
    if at_s is None and until_s is None:
        return "all flight"
    if at_s is None:
        return f"from the start until {until_s:.0f} s"
    if until_s is None:
        return f"from {at_s:.0f} s on"
    return f"from {at_s:.0f} s until {until_s:.0f} s"


def describe(effect: Effect) -> str:
    """The effect in words with units, e.g. "wind 6.0 m/s from 61°, from 150 s on"."""
    p = effect.params
    if isinstance(effect, ReportedWind):
        winds = "; then ".join(describe(w) for w in effect.steady()) or "calm"
        return f"{_reported(effect)} ({winds})"
    if isinstance(effect, Wind):
        what = f"wind {effect.speed_mps:.1f} m/s from {effect.from_deg:.0f}°"
    elif isinstance(effect, Mass):
        what = f"mass {effect.delta_kg:+.2f} kg"
    elif isinstance(effect, Avionics):
        what = f"load {effect.power_w:+.1f} W"
    else:
        what = effect.name + " " + ", ".join(f"{k} {v:.4g}" for k, v in p.items())
    if "at_s" in p:
        return f"{what}, {_when(p['at_s'], p.get('until_s'))}"
    return what


def _reported(effect: ReportedWind) -> str:
    return f"the autopilot's wind × {effect.scale:.2f}"


def _round_params(params: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if v is None else round(float(v), 4)) for k, v in params.items()}


def _robust_scale_w(r: FloatArray) -> float:
    """Soft-L1 scale: 3 robust σ (MAD) of the residual, at least 1 W."""
    mad = float(np.median(np.abs(r - np.median(r))))
    return max(3.0 * 1.4826 * mad, 1.0)


def _held_out(
    vehicle: Vehicle,
    samples: Samples,
    candidates: Sequence[Candidate],
    opt: ResidualOptions,
    f_scale_w: float,
    warm: Sequence[FloatArray | None],
) -> tuple[FloatArray, list[list[Term]]]:
    """Held-out predictions of the design ``candidates`` and the terms fitted in each fold."""
    predicted = np.empty(len(samples))
    per_fold = []
    for j in range(opt.folds):
        test = samples.fold == j
        if not test.any():
            continue
        train = samples.train_rows(j, opt.guard_s)
        terms = fit_design(FitProblem(vehicle, samples, train), candidates, f_scale_w, warm)
        predicted[test] = FitProblem(vehicle, samples, test).predict(
            [e for t in terms for e in t.effects()]
        )
        per_fold.append(terms)
    return predicted, per_fold


def _block_gain_z(samples: Samples, err_old: FloatArray, err_new: FloatArray) -> float:
    """Wilcoxon signed-rank statistic (normal approximation, as a z) of the per-block gains
    in held-out squared error: positive when the new errors are smaller. A rank test, not the
    mean over its standard error: block gains are heavy-tailed (a few manoeuvre blocks
    dominate the spread), which would hide an effect that helps nearly every block."""
    gain = np.bincount(samples.block, weights=err_old**2 - err_new**2)
    counts = np.bincount(samples.block)
    gain = gain[(counts > 0) & (gain != 0.0)]
    n = len(gain)
    if n < 2:
        return 0.0
    ranks = rankdata(np.abs(gain))
    w_plus = float(ranks[gain > 0].sum())
    mean = n * (n + 1) / 4.0
    _, tie_counts = np.unique(ranks, return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24.0 - float(np.sum(tie_counts**3 - tie_counts)) / 48.0
    return (w_plus - mean) / math.sqrt(var) if var > 0 else 0.0


def analyze(
    flights: Sequence[FlightSeries],
    vehicle: Vehicle,
    options: ResidualOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> ResidualResult:
    """Residual analysis of ``flights`` against ``vehicle`` (see the module docstring)."""
    opt = options or ResidualOptions()
    if opt.folds < 2:
        raise UserError("need at least 2 folds for held-out scoring")
    if not opt.chunk_s > 2 * opt.guard_s:
        raise UserError(
            "held-out chunks must be longer than two guards (--chunk-s > 2 × --guard-s)"
        )
    samples = prepare(flights, opt)
    everything = np.ones(len(samples), dtype=bool)
    before = FitProblem(vehicle, samples, everything).predict([])
    f_scale_w = _robust_scale_w(samples.power_w - before)
    remaining = candidates_for(vehicle, samples, opt.candidates)
    reach_mps = (
        math.inf
        if vehicle.max_airspeed_mps is None
        else airspeed_reach_mps(vehicle.drag, vehicle.max_airspeed_mps)
    )
    chosen: list[Candidate] = []
    warm: list[FloatArray | None] = []
    current = before
    selected: list[Selected] = []
    table: list[CandidateScore] = []
    step = 0
    while remaining:
        step += 1
        rmse_now = float(np.sqrt(np.mean((samples.power_w - current) ** 2)))
        trials = []
        for k, cand in enumerate(remaining):
            if progress is not None:
                progress(f"step {step}: {cand.label} ({k + 1}/{len(remaining)})")
            predicted, folds = _held_out(vehicle, samples, [*chosen, cand], opt, f_scale_w, warm)
            rmse = float(np.sqrt(np.mean((samples.power_w - predicted) ** 2)))
            gain = 1.0 - rmse / rmse_now if rmse_now > 0 else 0.0
            z = _block_gain_z(samples, samples.power_w - current, samples.power_w - predicted)
            # a wind beyond the vehicle's reach in most folds is a fit absorbing another effect
            reachable = 2 * sum(
                winds_within_reach(terms[-1].effects(), samples.state, reach_mps) for terms in folds
            ) > len(folds)
            ok = reachable and z > opt.z_threshold and gain >= opt.min_gain_fraction
            median_params = folds[len(folds) // 2][-1].effects()[0].params
            table.append(
                CandidateScore(step, cand.label, rmse, gain, z, ok, median_params, reachable)
            )
            trials.append((rmse, z, ok, cand, predicted, folds))
        good = [t for t in trials if t[2]]
        if not good:
            break
        rmse, z, _, cand, predicted, folds = _pick(samples, good, opt)
        # the other candidates of this step, best first (z: chosen vs it); qualifying ones
        # the held-out data cannot tell from the chosen one are ties
        others = [t for t in sorted(trials, key=lambda t: t[0]) if t[3] is not cand]
        rivals = [
            (
                t[3].label,
                t[0],
                _block_gain_z(samples, samples.power_w - t[4], samples.power_w - predicted),
            )
            for t in others
        ]
        # a richer form of the chosen effect (a change for a window) nests it: no rival
        ties = [
            rival
            for rival, t in zip(rivals, others, strict=True)
            if t[2]
            and rival[2] < opt.z_threshold
            and not (t[3].name == cand.name and _parameter_count(t[3]) > _parameter_count(cand))
        ]
        chosen.append(cand)
        current = predicted
        final = fit_design(FitProblem(vehicle, samples, everything), chosen, f_scale_w, warm)
        warm = [t.x for t in final]
        fold_effects = [terms[-1].effects() for terms in folds]
        selected.append(
            Selected(
                cand.name,
                final[-1].effects(),
                rmse,
                z,
                _fold_sd(fold_effects, final[-1]),
                ties,
                rivals[0] if rivals else None,
                cand.label,
            )
        )
        # earlier effects are refitted jointly with the new one
        for i, term in enumerate(final[:-1]):
            selected[i].effects = term.effects()
        # a windowed effect may come again (a wind that turns, a second payload): only its
        # all-flight form leaves; an all-flight effect is final
        remaining = [
            c
            for c in remaining
            if c.name != cand.name
            or (cand.windowed and c.windowed and not cand.switch and len(chosen) < opt.max_effects)
        ]
    if progress is not None:
        progress("attribution")
    after_resid = samples.power_w - current
    attribution = attribute(samples, after_resid, opt)
    attribution_before = attribute(samples, samples.power_w - before, opt)
    return ResidualResult(
        samples=samples,
        options=opt,
        predicted_before_w=before,
        predicted_after_w=current,
        selected=selected,
        table=table,
        attribution=attribution,
        attribution_before=attribution_before,
        noise_floor_w=_noise_floor_w(samples, after_resid),
        predicted_final_w=FitProblem(vehicle, samples, everything).predict(
            [e for s in selected for e in s.effects]
        ),
    )


def _pick(samples: Samples, good: list[Any], opt: ResidualOptions) -> Any:
    """The qualifying trial (rmse, z, ok, candidate, predicted, folds) with the lowest held-out
    RMSE; among the forms of that effect (all flight, in a window, changing), a form with
    more fitted numbers only when it cuts the simpler one's held-out RMSE by
    ``min_gain_fraction``, as an added effect must (a wind that stops rather than one that
    changes to a light breeze). A constant load above
    ``max_load_w`` that held-out data cannot tell from a mass (a payload draws power in every
    flight state alike when current is linear in thrust) is named as that mass: loads that
    large are payloads, not electronics."""

    def indistinguishable(trial: Any, best: Any) -> bool:
        z = _block_gain_z(samples, samples.power_w - trial[4], samples.power_w - best[4])
        return z < opt.z_threshold

    lowest = min(good, key=lambda t: t[0])
    forms = sorted(
        (t for t in good if t[3].name == lowest[3].name), key=lambda t: _parameter_count(t[3])
    )
    best = forms[0]
    for trial in forms[1:]:
        if trial[0] <= (1.0 - opt.min_gain_fraction) * best[0]:
            best = trial
    cand, folds = best[3], best[5]
    if cand.name != "avionics":
        return best
    load_w = float(np.median([terms[-1].x[0] for terms in folds]))
    if abs(load_w) <= opt.max_load_w:
        return best
    for trial in good:
        same_kind = trial[3].name == "mass" and trial[3].windowed == cand.windowed
        if same_kind and indistinguishable(trial, best):
            return trial
    return best


def _parameter_count(candidate: Candidate) -> int:
    """Fitted numbers of a candidate: its parameters and its change time(s)."""
    return len(candidate.x0) + (1 if candidate.windowed else 0)


def _fold_sd(fold_effects: list[tuple[Effect, ...]], final: Term) -> list[dict[str, float]]:
    """Spread (1σ) of each numeric parameter of each of the term's effects over the folds
    (angles wrapped to the final)."""
    spreads = []
    for k, effect in enumerate(final.effects()):
        out: dict[str, float] = {}
        for key, value in effect.params.items():
            values = [effects[k].params[key] for effects in fold_effects]
            if value is None or any(v is None for v in values):
                continue
            diffs = np.asarray(values, dtype=float) - float(value)
            if key.endswith("_deg"):
                diffs = (diffs + 180.0) % 360.0 - 180.0
            out[key] = float(np.sqrt(np.mean(diffs**2)))
        spreads.append(out)
    return spreads


def _noise_floor_w(samples: Samples, resid: FloatArray) -> float:
    """Sample-to-sample noise of the residual, W: RMS of successive differences / √2.

    What no smooth effect can explain (white measurement noise); slow structure cancels.
    """
    same = samples.flight[1:] == samples.flight[:-1]
    d = np.diff(resid)[same]
    return float(np.sqrt(np.mean(d**2) / 2.0)) if len(d) else math.nan
