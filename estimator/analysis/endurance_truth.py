"""The published endurance against a recorded flight's truth: the true time left to the
pack's reserve.

A log's truth is the ``truth.json`` beside it, as ``uav-energy sitl-record`` writes it
(:mod:`estimator.sitl.recorder`): ``events.takeoff_s`` and, for a flight flown to its reserve,
``events.reserve_s`` (s, autopilot clock). The true endurance at time t is ``reserve_s − t``.
An estimate is scored when its endurance is valid and it lies from :data:`SETTLE_S` after
take-off until :data:`SETTLE_S` before the reserve (where the time left gets short).

A σ is tested two-sided: for a nominal central coverage p, the fraction of scored estimates
whose truth lies inside the central p-interval of N(endurance, σ²), i.e. ``|z| ≤ Φ⁻¹((1+p)/2)``
with ``z = (endurance − truth)/σ`` (+: more time than there is). An estimate with no positive
σ is inside no interval. The estimates of one flight, a second apart, are strongly
correlated: pooled figures rest on the number of flights as much as on the number of
estimates.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from statistics import NormalDist
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimator.analysis.replay import FlightReplay
from estimator.errors import UserError
from estimator.estimation.estimate import Estimate

#: Scored from this long after take-off until this long before the reserve (s).
SETTLE_S = 60.0
#: The truth's file name, beside the log.
TRUTH_FILE = "truth.json"
#: A truth file larger than this (bytes) is not one.
MAX_TRUTH_BYTES = 1_000_000
#: Nominal central coverages of the reliability diagram.
NOMINAL_LEVELS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ReserveTruth:
    """A flight flown to its reserve: take-off and reserve times (s, autopilot clock) and the
    capacity on the pack's label (Ah; None when the truth does not give it)."""

    takeoff_s: float
    reserve_s: float
    labelled_capacity_ah: float | None


@dataclass(frozen=True)
class EnduranceScores:
    """The scored estimates of one flight: time (s), the true time left to the reserve (s),
    the published endurance and its 1σ (s)."""

    time_s: FloatArray
    left_s: FloatArray
    endurance_s: FloatArray
    sigma_s: FloatArray

    @property
    def errors(self) -> FloatArray:
        """Relative endurance errors (+: more time than there is)."""
        return (self.endurance_s - self.left_s) / self.left_s

    @property
    def z(self) -> FloatArray:
        """Endurance errors in σ (NaN where the σ is not positive)."""
        sigma = np.where(self.sigma_s > 0, self.sigma_s, np.nan)
        return (self.endurance_s - self.left_s) / sigma


@dataclass(frozen=True)
class ScoredFlight:
    """One replayed flight with a reserve truth, and its scored estimates."""

    name: str
    truth: ReserveTruth
    scores: EnduranceScores


def score_endurance(
    estimates: Iterable[Estimate], takeoff_s: float, reserve_s: float
) -> EnduranceScores:
    """The estimates scored against a reserve at ``reserve_s`` (see the module docstring)."""
    scored = [
        e
        for e in estimates
        if takeoff_s + SETTLE_S <= e.time_s <= reserve_s - SETTLE_S and e.endurance_valid
    ]
    time_s = np.array([e.time_s for e in scored], dtype=float)
    return EnduranceScores(
        time_s=time_s,
        left_s=reserve_s - time_s,
        endurance_s=np.array([e.endurance_s for e in scored], dtype=float),
        sigma_s=np.array([e.endurance_sigma_s for e in scored], dtype=float),
    )


def within(z: FloatArray, k: float) -> float:
    """Fraction of ``z`` with ``|z| ≤ k`` (NaN counts as outside; NaN when ``z`` is empty)."""
    return float(np.mean(np.abs(z) <= k)) if len(z) else math.nan


def reliability(z: FloatArray, levels: Sequence[float] = NOMINAL_LEVELS) -> FloatArray:
    """Observed central coverage at each nominal level (see the module docstring; Φ⁻¹ from
    the standard library, so that replay needs no scipy)."""
    return np.array([within(z, NormalDist().inv_cdf(0.5 + p / 2)) for p in levels])


def read_reserve_truth(log: Path) -> ReserveTruth | None:
    """The truth beside ``log`` when the flight was flown to its reserve; None without a
    truth file or without a reserve time. UserError for a file that is not a flight's truth."""
    path = log.parent / TRUTH_FILE
    if not path.is_file():
        return None
    try:
        if path.stat().st_size > MAX_TRUTH_BYTES:
            raise UserError(f"{path}: larger than {MAX_TRUTH_BYTES} bytes, not a flight's truth")
        raw = json.loads(path.read_bytes())
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    except (ValueError, RecursionError):  # bad JSON or UTF-8, an integer too long, deep nesting
        raise UserError(f"{path}: not JSON") from None
    events = raw.get("events") if isinstance(raw, dict) else None
    if not isinstance(events, dict):
        raise UserError(f"{path}: no 'events' object")
    if "reserve_s" not in events:
        return None
    takeoff_s = _seconds(events, "takeoff_s", path)
    reserve_s = _seconds(events, "reserve_s", path)
    if reserve_s <= takeoff_s:
        raise UserError(f"{path}: reserve_s {reserve_s:g} is not after takeoff_s {takeoff_s:g}")
    battery = raw.get("battery")
    label_ah = _finite(battery.get("labelled_capacity_ah")) if isinstance(battery, dict) else None
    return ReserveTruth(takeoff_s, reserve_s, label_ah if label_ah and label_ah > 0 else None)


def score_replays(flights: Iterable[FlightReplay]) -> tuple[list[ScoredFlight], list[str]]:
    """The replayed flights that have a reserve truth beside their log, scored; and one line
    for each truth file that could not be used."""
    scored: list[ScoredFlight] = []
    problems: list[str] = []
    for flight in flights:
        try:
            truth = None if flight.path is None else read_reserve_truth(flight.path)
        except UserError as exc:
            problems.append(str(exc))
            continue
        if truth is not None:
            scores = score_endurance(flight.estimates, truth.takeoff_s, truth.reserve_s)
            scored.append(ScoredFlight(flight.name, truth, scores))
    return scored, problems


def pooled_z(scored: Sequence[ScoredFlight]) -> FloatArray:
    """The z of every scored estimate of every flight."""
    return np.concatenate([f.scores.z for f in scored]) if scored else np.empty(0)


def coverage_json(scored: Sequence[ScoredFlight]) -> dict[str, Any]:
    """Pooled and per-flight coverage (``--json``'s ``endurance_truth``; NaN becomes null)."""
    z = pooled_z(scored)
    return {
        "flights": sum(len(f.scores.z) > 0 for f in scored),
        "estimates": len(z),
        "within_1sigma": _or_none(within(z, 1.0)),
        "within_3sigma": _or_none(within(z, 3.0)),
        "reliability": [
            {"nominal": p, "observed": _or_none(o)}
            for p, o in zip(NOMINAL_LEVELS, reliability(z), strict=True)
        ],
        "per_flight": [
            {
                "flight": f.name,
                "estimates": len(f.scores.z),
                "within_1sigma": _or_none(within(f.scores.z, 1.0)),
                "within_3sigma": _or_none(within(f.scores.z, 3.0)),
            }
            for f in scored
        ],
    }


def _or_none(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _finite(x: Any) -> float | None:
    """``x`` as a float when it is a finite JSON number, else None."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        return None
    try:
        value = float(x)
    except OverflowError:  # an integer beyond any float
        return None
    return value if math.isfinite(value) else None


def _seconds(events: dict[str, Any], key: str, path: Path) -> float:
    value = _finite(events.get(key))
    if value is None:
        raise UserError(f"{path}: events.{key} is not a finite number of seconds")
    return value
