"""The figures of the paper's experiments in README.md and docs/fit.md (``experiments-*``):
``uav-energy experiments`` on its generated flights (seed 0), the fit against the truth it
flew and the circles.

``scripts/figures.py`` registers the blocks (:func:`generators`); ``tests/test_figures.py``
checks them.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from functools import cache, partial
from pathlib import Path
from types import ModuleType

import numpy as np

from estimator.reports.fit_report import circles_markdown
from estimator.sim.experiments import Experiments, curve_table, reproduce


@cache
def experiments_run() -> Experiments:
    """``uav-energy experiments`` (seed 0)."""
    with tempfile.TemporaryDirectory() as out:
        return reproduce(Path(out), seed=0)


@cache
def sentences() -> tuple[str, str]:
    """``uav-energy experiments`` (seed 0): the fit's and the circles' sentences."""
    result = experiments_run()
    truth, fitted = result.vehicle.model, result.fit.theory.model
    scores = result.fit.scores
    fit = (
        f"fitted hover power {fitted.hover_power_w:.1f} W (truth {truth.hover_power_w:.1f}), "
        f"V_me {fitted.max_endurance_speed_mps():.2f} m/s "
        f"({truth.max_endurance_speed_mps():.2f}), V_mr {fitted.max_range_speed_mps():.2f} m/s "
        f"({truth.max_range_speed_mps():.2f}); held-out RMSE theory "
        f"{scores['theory'].rmse_w:.2f} W, polynomial {scores['polynomial'].rmse_w:.2f} W, "
        f"network {scores['dnn'].rmse_w:.2f} W at a residual σ of "
        f"{result.fit.theory.sigma_w:.1f} W"
    )
    eq2 = max(abs(c.eq2_w - c.measured_w) for c in result.circles)
    miss, worst = max(
        (abs(c.eq1_w - c.measured_w), (c, r))
        for c, r in zip(result.circles, result.radii_m, strict=True)
    )
    circle, radius = worst
    circles = (
        f"eq. (2) predicts the power within {np.ceil(eq2):.0f} W; eq. (1), which ignores a⊥, "
        f"misses by up to {miss:.0f} W at {circle.speed_mps:.0f} m/s, r = {radius:.0f} m"
    )
    return fit, circles


def points() -> str:
    """How many of the fit's points it kept."""
    fit = experiments_run().fit
    return f"{len(fit.points.kept()):,} of {len(fit.points):,} points kept"


def circles_table() -> str:
    result = experiments_run()
    return circles_markdown(result.circles, result.radii_m).rstrip()


def fit_details(fits: ModuleType) -> str:
    """docs/fit.md's sentence: hover power, V_me and V_mr ± 1σ against the truth, held-out
    RMSE / MAPE of each model (and the network's worst fold), the residual σ; ``fits``:
    ``scripts/fit_figures.py``."""
    result = experiments_run()
    truth, fit = result.vehicle.model, result.fit.summary()
    return (
        f"Hover {fit['hover_power_w']:.1f} W (truth {truth.hover_power_w:.1f}), V_me "
        f"{fits.pm(fit['v_me_mps'], fit['v_me_stderr_mps'], '.2f')} m/s (truth "
        f"{truth.max_endurance_speed_mps():.2f}), V_mr "
        f"{fits.pm(fit['v_mr_mps'], fit['v_mr_stderr_mps'], '.2f')} m/s (truth "
        f"{truth.max_range_speed_mps():.2f}). Held-out by flight: theory "
        f"{fits.held_out(fit, 'theory')}, polynomial {fits.held_out(fit, 'polynomial')}, "
        f"network {fits.held_out(fit, 'dnn')} (its worst fold "
        f"{max(fit['fold_rmse_w']['dnn']):.1f} W). Residual σ {fit['noise_sigma_w']:.1f} W"
    )


def generators(fits: ModuleType) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it; ``fits``: ``scripts/fit_figures.py``."""
    return {
        "experiments-fit": lambda: sentences()[0],
        "experiments-circles": lambda: sentences()[1],
        "experiments-curve": lambda: curve_table(experiments_run()),
        "experiments-points": points,
        "experiments-circles-table": circles_table,
        "experiments-fit-details": partial(fit_details, fits),
    }
