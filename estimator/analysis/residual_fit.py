"""Fitting candidate effects to measured power: robust least squares of their parameters
(``scipy.optimize.least_squares``, soft-L1) and the search of a time window in linear time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from estimator.analysis.residual_candidates import Candidate
from estimator.analysis.residual_samples import Samples
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Effect, predict_power_w
from estimator.physics.model import FloatArray
from estimator.physics.vehicle import Vehicle


@dataclass
class Term:
    """A candidate with fitted parameters (and, when windowed, its time window, s; for a
    switch, ``at_s`` is the switch time)."""

    candidate: Candidate
    x: FloatArray
    at_s: float | None = None
    until_s: float | None = None

    def effects(self) -> tuple[Effect, ...]:
        return self.candidate.effects(self.x, self.at_s, self.until_s)


class FitProblem:
    """Predictions for a set of rows with the vehicle's model and base effects.

    ``first_s``/``last_s``: the flight clock's first and last airborne time over all samples
    (a window reaching them is open on that side).
    """

    def __init__(self, vehicle: Vehicle, samples: Samples, rows: NDArray[np.bool_]) -> None:
        self.vehicle = vehicle
        self.state = samples.state_at(rows)
        self.power_w = samples.power_w[rows]
        self.base = effects_from_tables(vehicle.effects)
        self.first_s = float(samples.state.time_s.min())
        self.last_s = float(samples.state.time_s.max())

    def predict(self, effects: Sequence[Effect]) -> FloatArray:
        return predict_power_w(
            self.vehicle.model, self.vehicle.mass_kg, self.state, [*self.base, *effects]
        )


def _fit_terms(
    problem: FitProblem,
    terms: list[Term],
    f_scale_w: float,
    warm: frozenset[int] = frozenset(),
    fixed: Sequence[Effect] = (),
) -> list[Term]:
    """Joint least squares of all terms' x (windows held) on top of the ``fixed`` effects;
    multi-start where given, except for terms whose index is in ``warm`` (their x is already
    a good start)."""
    if not terms:
        return terms
    sizes = [len(t.x) for t in terms]
    lower = np.concatenate([t.candidate.lower for t in terms])
    upper = np.concatenate([t.candidate.upper for t in terms])

    def unpack(x: FloatArray) -> list[Term]:
        out, k = [], 0
        for term, n in zip(terms, sizes, strict=True):
            out.append(Term(term.candidate, x[k : k + n].copy(), term.at_s, term.until_s))
            k += n
        return out

    def resid(x: FloatArray) -> FloatArray:
        return (
            problem.predict([*fixed, *(e for t in unpack(x) for e in t.effects())])
            - problem.power_w
        )

    starts = [np.concatenate([t.x for t in terms])]
    for i, term in enumerate(terms):
        if i in warm:
            continue
        for s in term.candidate.starts:
            x = starts[0].copy()
            k = sum(sizes[:i])
            x[k : k + sizes[i]] = s
            starts.append(x)
    best = None
    for x0 in starts:
        # strictly inside the bounds: least_squares stalls when started on one
        x0 = np.clip(x0, lower + 1e-3 * (upper - lower), upper - 1e-3 * (upper - lower))
        sol = least_squares(
            resid, x0, bounds=(lower, upper), loss="soft_l1", f_scale=f_scale_w, x_scale="jac"
        )
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    return unpack(best.x)


def best_window(time_s: FloatArray, gain: FloatArray) -> tuple[int, int, float]:
    """The time window where an effect helps most: first and last index (into the rows sorted
    by time) and the summed ``gain`` (per-row loss without the effect minus with it) of the
    contiguous run with the largest sum. Prefix sums: O(n log n) for the sort, O(n) after."""
    order = np.argsort(time_s, kind="stable")
    prefix = np.concatenate([[0.0], np.cumsum(gain[order])])
    low = np.minimum.accumulate(prefix[:-1])
    sums = prefix[1:] - low
    last = int(np.argmax(sums))
    first = int(np.argmin(prefix[: last + 1]))
    return first, last, float(sums[last])


def best_switch(time_s: FloatArray, loss_diff: FloatArray) -> float:
    """The switch time (s) from one parameter set to another: ``loss_diff`` is the per-row
    loss with the first set minus with the second; the split of the rows sorted by time with
    the lowest total (the first set before it, the second after), at least one row on each
    side, placed midway between the two rows around it. Prefix sums: linear after the sort."""
    order = np.argsort(time_s, kind="stable")
    ts = time_s[order]
    if len(ts) < 2:
        return float(np.median(time_s))
    k = int(np.argmin(np.cumsum(loss_diff[order])[:-1]))
    return 0.5 * float(ts[k] + ts[k + 1])


#: Window ends this close (s) to the flight's first/last airborne sample are open.
_OPEN_END_S = 10.0


def _window_times(
    problem: FitProblem, t: FloatArray, ts: FloatArray, gain: FloatArray, cost: float
) -> tuple[float | None, float | None]:
    """The window (at_s, until_s) with the largest summed ``gain`` per row (rows at times
    ``t``, sorted ``ts``); an end near the flight's first/last sample is open, and so is an
    end whose closing gains less than ``cost`` (a change point's price, in loss units), or
    where the effect helps at least half of the rows outside it: a window must not end on a
    dip of the model's own error (a manoeuvre the model gets wrong)."""
    lo, hi, _sum = best_window(t, gain)
    by_time = gain[np.argsort(t, kind="stable")]
    before, after = by_time[:lo], by_time[hi + 1 :]
    if lo > 0 and (before.sum() > -cost or np.median(before) >= 0.0):
        lo = 0
    if hi < len(ts) - 1 and (after.sum() > -cost or np.median(after) >= 0.0):
        hi = len(ts) - 1
    return (
        None
        if lo == 0 or ts[lo] - problem.first_s < _OPEN_END_S
        # any time between two training rows splits them alike (a held-out gap)
        else 0.5 * float(ts[lo - 1] + ts[lo]),
        None
        if hi == len(ts) - 1 or problem.last_s - ts[hi] < _OPEN_END_S
        else 0.5 * float(ts[hi] + ts[hi + 1]),
    )


def _search_window(
    problem: FitProblem, others: list[Term], term: Term, f_scale_w: float, warm: bool
) -> Term:
    """Fit ``term``'s parameters and time window (or switch time) on top of ``others``.

    Starts: the parameters fitted over the whole flight, and over its first and second half
    (an effect present in one half only); a switch starts at the middle. From each,
    alternately the window with the largest robust gain for these parameters
    (:func:`best_window`) or the best switch time (:func:`best_switch`), both linear in the
    samples, and the parameters for that window; the start with the lowest robust loss wins.
    """
    fixed = [e for t in others for e in t.effects()]
    loss_cap = (3.0 * f_scale_w) ** 2
    # a change point costs log(n) robust variances (f_scale is 3 σ), as in BIC
    change_cost = math.log(max(len(problem.power_w), 2)) * (f_scale_w / 3.0) ** 2

    def loss(effects: Sequence[Effect]) -> FloatArray:
        return np.minimum((problem.power_w - problem.predict([*fixed, *effects])) ** 2, loss_cap)

    loss_without = loss([])
    t = problem.state.time_s
    ts = np.sort(t)
    middle = float(np.median(ts))
    first_fit = frozenset({0} if warm else ())
    cand = term.candidate
    starts: list[tuple[float | None, float | None]] = (
        [(middle, None)] if cand.switch else [(None, None), (None, middle), (middle, None)]
    )
    best: tuple[float, Term] | None = None
    for window in starts:
        start = Term(cand, term.x, *window)
        current = _fit_terms(problem, [start], f_scale_w, first_fit, fixed)[0]
        found: tuple[float | None, float | None] | None = None
        for _ in range(4):
            if cand.switch:
                half = len(current.x) // 2
                before = loss([cand.build(current.x[:half], None, None)])
                after = loss([cand.build(current.x[half:], None, None)])
                window = (best_switch(t, before - after), None)
            else:
                always = loss(Term(cand, current.x).effects())
                window = _window_times(problem, t, ts, loss_without - always, change_cost)
            if window == found:
                break
            found = window
            current = Term(cand, current.x, *window)
            current = _fit_terms(problem, [current], f_scale_w, frozenset({0}), fixed)[0]
        total = float(np.sum(loss(current.effects())))
        if best is None or total < best[0]:
            best = (total, current)
    assert best is not None
    return best[1]


def fit_design(
    problem: FitProblem,
    candidates: Sequence[Candidate],
    f_scale_w: float,
    warm: Sequence[FloatArray | None] = (),
) -> list[Term]:
    """Fit ``candidates`` together: constant ones first, then each window, then all.

    ``warm``: starting x per candidate position (e.g. from the previous selection step).
    """
    warm = [*warm, *([None] * (len(candidates) - len(warm)))]
    terms = [
        Term(c, np.asarray(c.x0 if w is None else w, dtype=float))
        for c, w in zip(candidates, warm, strict=True)
    ]
    known = frozenset(i for i, w in enumerate(warm) if w is not None)
    steady = [i for i, t in enumerate(terms) if not t.candidate.windowed]
    fitted = _fit_terms(
        problem,
        [terms[i] for i in steady],
        f_scale_w,
        frozenset(k for k, i in enumerate(steady) if i in known),
    )
    for i, term in zip(steady, fitted, strict=True):
        terms[i] = term
    resolved = list(steady)
    for i, term in enumerate(terms):
        if term.candidate.windowed:
            others = [terms[k] for k in resolved]
            terms[i] = _search_window(problem, others, term, f_scale_w, i in known)
            resolved.append(i)
    return _fit_terms(problem, terms, f_scale_w, frozenset(range(len(terms))))
