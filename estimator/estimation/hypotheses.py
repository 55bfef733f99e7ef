"""The online tracker's hypotheses (:mod:`estimator.estimation.online_effects`): a filter
state with what the tracker carries beside it, the duel between two of them after a change,
and the estimate it reports while they run.

After a change in forward flight a payload step and a wind change both move the power, so
the tracker runs a mass-step and a wind-change hypothesis side by side, each its own filter
from the same prior, scored by its summed innovation log-likelihood −½(ν² + ln S): the
likelier one is the estimate, and the other is dropped once the ratio passes
``hypothesis_nats`` (100:1) or after ``hypothesis_max_steps`` steps, a multiple-model test that
the next change of speed or heading, where a wind and a mass differ, settles. Until then the
estimate reported and applied is the two hypotheses' mixture, each weighted by its likelihood:
read as the leader alone, a duel led by a fraction of a nat had the tracker report a wind
change as a 0.4 kg mass step at 3.6–5.1σ (ArduCopter SITL, four held8_* flights).

States [w_n, w_e, δm, b]: NED wind m/s, mass difference kg, the model's slow error W.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class Hypothesis(NamedTuple):
    """A filter state [w_n, w_e, δm, b] with covariance and its sensitivity to the model
    form's error (:mod:`~estimator.estimation.form_error`), its summed innovation
    log-likelihood, and its last step's normalised innovation (None: no update), squared
    innovation (W²) and innovation variance (W²)."""

    x: np.ndarray
    p: np.ndarray
    form: np.ndarray
    loglik: float = 0.0
    nu: float | None = None
    y2: float = 0.0
    s_var: float = 1.0


def second_probability(log_ratio: float) -> float:
    """The probability of the second of two hypotheses, at even prior odds, from the log of
    its likelihood over the first's (the logistic; its exponent bounded, so a ratio beyond a
    float's range gives 0 or 1, never an overflow)."""
    return 1.0 / (1.0 + math.exp(min(-log_ratio, 700.0)))


def duel(
    first: Hypothesis, second: Hypothesis, steps: int, nats: float, max_steps: int
) -> tuple[Hypothesis, Hypothesis | None]:
    """The likelier of two hypotheses, and the other as its rival until their log-likelihood
    ratio exceeds ``nats`` or ``steps`` (the duel's so far) reaches ``max_steps`` (then
    None: it is dropped)."""
    lead, trail = (first, second) if first.loglik >= second.loglik else (second, first)
    if lead.loglik - trail.loglik > nats or steps >= max_steps:
        return lead, None
    return lead, trail


def mixture(a: Hypothesis, b: Hypothesis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State, covariance and form sensitivity of the two hypotheses' mixture, each weighted
    by its likelihood (the moments of a Gaussian sum: Magill 1965; Bar-Shalom, Li &
    Kirubarajan 2001, §11.6): the mean between them and a covariance that spans both, so an
    undecided duel is reported as undecided and its state stays unidentified rather than
    confidently the leader's. The sensitivity is the weighted mean of theirs."""
    w_b = second_probability(b.loglik - a.loglik)
    w_a = 1.0 - w_b
    x = w_a * a.x + w_b * b.x
    d_a, d_b = a.x - x, b.x - x
    p = w_a * (a.p + np.outer(d_a, d_a)) + w_b * (b.p + np.outer(d_b, d_b))
    return x, p, w_a * a.form + w_b * b.form
