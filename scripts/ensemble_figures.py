"""The figures of the simulator's ensemble of drawn packs (:mod:`estimator.sim.endurance_ensemble`,
as ``python tests/test_endurance_acceptance.py`` prints it) in docs/pack.md, docs/daemon.md and
the README: the coverage of the endurance's σ, its median |error| against the PX4-style
figure, and the hover→cruise acceptance flights.

``scripts/figures.py`` registers the blocks (:func:`generators`); ``tests/test_figures.py``
checks them.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache, partial

import numpy as np

from estimator.sim.endurance_ensemble import (
    CHECK_AFTER_CHANGE_S,
    ENSEMBLE_FLIGHTS,
    Flown,
    ensemble_configs,
    ensemble_errors,
    figures_after_change,
    hover_cruise,
    hover_cruise_config,
    signed_pct,
    table_rows,
)


@cache
def _drawn() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The simulator's ensemble of drawn packs (:mod:`estimator.sim.endurance_ensemble`, 22 s
    of CPU): the endurance estimates' |error|/σ, and |error| (%) of ours and of the
    PX4-style estimate."""
    drawn = ensemble_errors(ensemble_configs(ENSEMBLE_FLIGHTS))
    ours, px4 = (100 * np.abs(np.concatenate(e)) for e in (drawn.ours, drawn.px4))
    return drawn.z, ours, px4


def ensemble() -> tuple[float, float, float, float]:
    """% of the ensemble's estimates within 1σ and 3σ of the truth, and the median |error|
    (%) of ours and of the PX4-style estimate."""
    z, ours, px4 = _drawn()
    return (
        float(100 * np.mean(z <= 1.0)),
        float(100 * np.mean(z <= 3.0)),
        float(np.median(ours)),
        float(np.median(px4)),
    )


def ensemble_count() -> str:
    """How many endurance estimates the ensemble scores."""
    return f"{len(_drawn()[0])}"


def standard_sigma(cruise_speed_mps: float) -> str:
    """The acceptance flight at ``cruise_speed_mps`` scored as the ensemble's flights are:
    the share of its estimates within 1σ of the truth, and their mean |error|/σ."""
    z = ensemble_errors([hover_cruise_config(cruise_speed_mps)]).z
    return (
        f"{100 * np.mean(z <= 1.0):.0f} % of the {len(z)} errors within 1σ (mean |error|/σ "
        f"{np.mean(z):.2f})"
    )


def ensemble_sigma() -> str:
    one, three, _, _ = ensemble()
    return f"{one:.1f} % of estimates are within 1σ, and {three:.1f} % within 3σ"


def ensemble_error() -> str:
    _, _, ours, px4 = ensemble()
    return f"{ours:.2f} % for ours, {px4:.1f} % for PX4-style"


def ensemble_daemon() -> str:
    """docs/daemon.md's sentence: the median |error| and share within 3 % of ours and of the
    PX4-style figure, and the coverage."""
    _, ours, px4 = _drawn()
    one, three, _, _ = ensemble()
    return (
        f"|error| median {np.median(ours):.2f} %, {100 * np.mean(ours <= 3):.0f} % within 3 % "
        f"(PX4-style, told the true starting charge but counting against the label: "
        f"{np.median(px4):.1f} %, {100 * np.mean(px4 <= 3):.0f} %); **{one:.1f} % within 1σ, "
        f"{three:.1f} % within 3σ**"
    )


def ensemble_summary() -> str:
    """The README's sentence."""
    one, three, ours, px4 = ensemble()
    return (
        f"the median |error| is {ours:.2f} % against {px4:.1f} % for the PX4-style figure "
        f"(which is even told the starting charge), with {one:.1f} % of the errors within 1σ "
        f"and {three:.1f} % within 3σ"
    )


@cache
def _hover_cruise(cruise_speed_mps: float) -> Flown:
    return hover_cruise(cruise_speed_mps)


def hover_cruise_table(cruise_speed_mps: float) -> str:
    """docs/daemon.md's table of the acceptance flight at ``cruise_speed_mps``."""
    return "\n".join(
        [
            "| after change | truth s | estimate ± 1σ s | error | PX4-style s | error |",
            "|---:|---:|---:|---:|---:|---:|",
            *table_rows(_hover_cruise(cruise_speed_mps)),
        ]
    )


def _errors(cruise_speed_mps: float, after_s: float) -> tuple[str, str]:
    """Ours and the PX4-style relative error ``after_s`` after the change."""
    e, truth_s, px4_s = figures_after_change(_hover_cruise(cruise_speed_mps), after_s)
    return signed_pct(e.endurance_s / truth_s - 1), signed_pct(px4_s / truth_s - 1)


def hover_cruise_readme() -> str:
    """The README's table: ours and PX4-style at 10 s, 30 s and 2 min after the change, at
    each cruise speed."""
    rows = [
        "| cruise | after the change | uav-energy | PX4-style (charge / 50 s mean current) |",
        "|---|---|---|---|",
    ]
    for speed in (10.0, 14.0):
        errors = [_errors(speed, after_s) for after_s in CHECK_AFTER_CHANGE_S]
        ours = " / ".join(o.removesuffix(" %") for o, _ in errors)
        px4 = " / ".join(p.removesuffix(" %") for _, p in errors)
        rows.append(f"| {speed:.0f} m/s | +10 s / +30 s / +2 min | {ours} % | {px4} % |")
    return "\n".join(rows)


def hover_cruise_end() -> str:
    """Ours and PX4-style 20 min into each cruise."""
    (ours10, px4_10), (ours14, px4_14) = (_errors(speed, 1200.0) for speed in (10.0, 14.0))
    return (
        f"20 min: {ours10.removesuffix(' %')} / {ours14} vs {px4_10.removesuffix(' %')} / {px4_14}"
    )


def generators() -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it (``scripts/figures.py`` registers them)."""
    return {
        "pack-ensemble-sigma": ensemble_sigma,
        "pack-ensemble-error": ensemble_error,
        "pack-ensemble-summary": ensemble_summary,
        "pack-ensemble-daemon": ensemble_daemon,
        "pack-ensemble-count": ensemble_count,
        "hover-cruise-10-sigma": partial(standard_sigma, 10.0),
        "hover-cruise-10": partial(hover_cruise_table, 10.0),
        "hover-cruise-14": partial(hover_cruise_table, 14.0),
        "hover-cruise-readme": hover_cruise_readme,
        "hover-cruise-end": hover_cruise_end,
    }
