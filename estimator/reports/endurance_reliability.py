"""The endurance's σ against the flights' truth in a replay report (matplotlib, Agg): a
reliability diagram pooled over the flights flown to their reserve, the z histogram against
N(0, 1), and per flight the endurance ±1σ over time with the true time left.

Scoring and coverage: :mod:`estimator.analysis.endurance_truth`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.stats import norm

from estimator.analysis.endurance_truth import (
    NOMINAL_LEVELS,
    SETTLE_S,
    ScoredFlight,
    pooled_z,
    reliability,
    within,
)
from estimator.analysis.replay import FlightReplay

#: The pooled figure's file name in the report folder (flights' files all carry a suffix).
RELIABILITY_PNG = "reliability.png"
#: The z histogram's range (σ); estimates beyond are counted in its title (the bars' area is
#: the share of all scored estimates inside).
Z_RANGE = 5.0


def reliability_section(
    scored: Sequence[ScoredFlight], out_dir: Path, capacity_ah: float | None
) -> list[str]:
    """The summary's lines on the endurance against the truth, the pooled figure written
    into ``out_dir``; ``capacity_ah``: the vehicle file's capacity the flights were replayed
    under (Ah; None: not said). Nothing for no flight."""
    if not scored:
        return []
    z = pooled_z(scored)
    n_flights = sum(len(f.scores.z) > 0 for f in scored)
    flights = f"{n_flights} flight{'' if n_flights == 1 else 's'}"
    lines = [
        "## Endurance against the truth",
        "",
        f"Flights with a `truth.json` flown to the reserve: {len(scored)}. Endurance scored from "
        f"{SETTLE_S:.0f} s after take-off until {SETTLE_S:.0f} s before the reserve, against "
        "the true time left (z = (estimate − truth)/σ, + is more time than there is).",
        "",
    ]
    label_off = [
        f"{f.name} ({label_ah:g} Ah)"
        for f in scored
        if (label_ah := f.truth.labelled_capacity_ah) is not None
        and capacity_ah is not None
        and not math.isclose(label_ah, capacity_ah)
    ]
    if label_off:
        lines += [
            f"Replayed under the vehicle file's {capacity_ah:g} Ah; the pack's label differs on: "
            + ", ".join(label_off)
            + ".",
            "",
        ]
    if not len(z):
        return [*lines, "No estimate in the scored span.", ""]
    lines += [
        f"**{_pct(within(z, 1.0))} within 1σ (68.3 % nominal), {_pct(within(z, 3.0))} within "
        f"3σ (99.7 % nominal), over {len(z)} estimates of {flights}.** Estimates a "
        "second apart within one flight are strongly correlated: the pooled figure rests on "
        f"{flights}, not on {len(z)} independent draws.",
        "",
        "| flight | scored estimates | within 1σ | within 3σ | median abs error % |",
        "|---|---:|---:|---:|---:|",
    ]
    for f in scored:
        errors = np.abs(f.scores.errors)
        median = f"{100 * np.median(errors):.1f}" if len(errors) else "–"
        lines.append(
            f"| {f.name} | {len(f.scores.z)} | {_pct(within(f.scores.z, 1.0))} "
            f"| {_pct(within(f.scores.z, 3.0))} | {median} |"
        )
    fig = _plot_reliability(z, flights)
    fig.savefig(out_dir / RELIABILITY_PNG, dpi=110)
    plt.close(fig)
    return [*lines, "", f"![reliability]({RELIABILITY_PNG})", ""]


def plot_endurance_truth(flight: FlightReplay, scored: ScoredFlight) -> plt.Figure:
    """The endurance ±1σ from take-off to the reserve with the true time left (minutes, over
    log time); the scored span shaded."""
    truth = scored.truth
    kept = [e for e in flight.estimates if truth.takeoff_s <= e.time_s <= truth.reserve_s]
    t = np.array([e.time_s for e in kept], dtype=float)
    endurance_min = np.array([e.endurance_s for e in kept], dtype=float) / 60.0
    sigma_min = np.array([e.endurance_sigma_s for e in kept], dtype=float) / 60.0
    valid = np.array([e.endurance_valid for e in kept], dtype=bool) & np.isfinite(sigma_min)
    fig, ax = plt.subplots(figsize=(10, 4))
    ax.plot(t[valid], endurance_min[valid], lw=1.2, color="tab:purple", label="endurance", zorder=3)
    ax.fill_between(
        t[valid],
        (endurance_min - sigma_min)[valid],
        (endurance_min + sigma_min)[valid],
        color="tab:purple",
        alpha=0.25,
        lw=0,
        label="±1σ",
    )
    span = np.array([truth.takeoff_s, truth.reserve_s])
    ax.plot(
        span,
        (truth.reserve_s - span) / 60.0,
        color="black",
        lw=1.0,
        ls="--",
        label="true time left",
    )
    ax.axvspan(
        truth.takeoff_s + SETTLE_S,
        truth.reserve_s - SETTLE_S,
        color="gray",
        alpha=0.1,
        lw=0,
        label="scored",
    )
    ax.set(
        xlabel="log time (s)",
        ylabel="minutes to the reserve",
        title=f"{flight.name}: endurance against the truth",
    )
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _pct(x: float) -> str:
    return "–" if not np.isfinite(x) else f"{100 * x:.1f} %"


def _plot_reliability(z: np.ndarray, flights: str) -> plt.Figure:
    """Observed against nominal central coverage, and the z histogram against N(0, 1)."""
    fig, (ax_r, ax_z) = plt.subplots(1, 2, figsize=(11, 4.5))
    levels = np.array(NOMINAL_LEVELS)
    ax_r.plot([0, 1], [0, 1], color="gray", lw=0.8, ls="--", label="calibrated")
    ax_r.plot(levels, reliability(z), "o-", color="tab:purple", label="observed")
    ax_r.set(
        xlim=(0, 1),
        ylim=(0, 1),
        xlabel="nominal central coverage p",
        ylabel="fraction of truths inside the p-interval",
        title=f"reliability: {len(z)} estimates, {flights}",
    )
    ax_r.set_aspect("equal")
    ax_r.legend(loc="upper left")
    ax_r.grid(alpha=0.3)
    finite = z[np.isfinite(z)]
    inside = finite[np.abs(finite) <= Z_RANGE]
    bins = 40
    density = np.full(len(inside), bins / (2 * Z_RANGE * len(z)))  # area: the share inside
    ax_z.hist(inside, bins=bins, range=(-Z_RANGE, Z_RANGE), weights=density, color="tab:purple")
    x = np.linspace(-Z_RANGE, Z_RANGE, 201)
    ax_z.plot(x, norm.pdf(x), color="black", lw=1.0, label="N(0, 1)")
    outside = len(z) - len(inside)
    ax_z.set(
        xlabel="z = (estimate − truth) / σ",
        ylabel="density",
        title=f"z; {outside} beyond ±{Z_RANGE:g} or without σ",
    )
    ax_z.legend(loc="upper right")
    ax_z.grid(alpha=0.3)
    fig.tight_layout()
    return fig
