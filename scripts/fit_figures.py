"""The fit figures of README.md, docs/fit.md and docs/sitl.md, as text, from the ``--json``
objects of ``uav-energy fit`` (``scripts/figures.py`` runs the fits and registers the blocks).

Powers in W, speeds in m/s; ± is 1σ (for the per-fold differences: the mean's standard error).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from estimator.physics.model import COEFFICIENT_NAMES, PowerModel

Fit = Mapping[str, Any]

#: ``scripts/fit_real.sh``'s fits: column title, logs (under ../shared/data), mass (kg),
#: capacity (Ah) and cells.
REAL_FITS = {
    "IRIS+ March 2016": ("iris_quadcopter_logs/2016-03-*/*/*.log", 1.282, 5.1, 3),
    "IRIS+ June–Aug 2016": ("iris_quadcopter_logs/2016-0[678]-*/*/*.log", 1.58, 5.1, 3),
    "CMU DJI M100": ("cmu_m100_subset/*.csv", 2.355, 4.5, 6),
}
#: The fit's prior-dominated parameters, as docs/fit.md names them.
PRIOR_NAMES = {"logit_profile_fraction": "profile share", "ln_tip_speed": "tip speed"}


def number(value: float, spec: str) -> str:
    """``value`` formatted by ``spec``, a negative one with the documents' minus sign."""
    text = format(value, spec)
    return "−" + text[1:] if text.startswith("-") else text


def span(values: Iterable[float], spec: str) -> str:
    """The range of ``values`` formatted by ``spec`` ("a–b", or "a" when both read the same)."""
    low, high = (number(v, spec) for v in (min(values), max(values)))
    return low if low == high else f"{low}–{high}"


def pm(value: float, sigma: float, spec: str) -> str:
    return f"{number(value, spec)} ± {sigma:{spec}}"


def fold_difference(fit: Fit, other: str) -> str:
    """Theory minus ``other`` in per-fold held-out RMSE: mean ± its standard error (W)."""
    d = np.subtract(fit["fold_rmse_w"]["theory"], fit["fold_rmse_w"][other])
    return pm(float(d.mean()), float(d.std(ddof=1) / np.sqrt(len(d))), ".2f") + " W"


def held_out(fit: Fit, model: str) -> str:
    score = fit["models"][model]
    return f"{score['rmse_w']:.2f} W / {score['mape_pct']:.2f} %"


def _table(fits: Mapping[str, Fit], rows: Mapping[str, Callable[[Fit], str]]) -> str:
    lines = ["| | " + " | ".join(fits) + " |", "|---" * (len(fits) + 1) + "|"]
    for label, cell in rows.items():
        lines.append(f"| {label} | " + " | ".join(cell(f) for f in fits.values()) + " |")
    return "\n".join(lines)


def summary_table(fits: Mapping[str, Fit]) -> str:
    """The README's table of the fits (5-fold held out by whole flight)."""
    return _table(
        fits,
        {
            "flights / points kept": lambda f: f"{f['n_flights']} / {f['n_points']:,}",
            "hover power": lambda f: (
                pm(f["hover_power_w"], f["hover_power_stderr_w"], ".1f") + " W"
            ),
            "V_me": lambda f: pm(f["v_me_mps"], f["v_me_stderr_mps"], ".1f") + " m/s",
            "theory RMSE / MAPE": lambda f: held_out(f, "theory"),
            "polynomial (cubic)": lambda f: held_out(f, "polynomial"),
            "network 3×10 tanh": lambda f: held_out(f, "dnn"),
        },
    )


def _v_mr(fit: Fit) -> str:
    beyond = fit["v_mr_mps"] > fit["speed_range_mps"][1]
    return pm(fit["v_mr_mps"], fit["v_mr_stderr_mps"], ".1f") + (
        " (extrapolated)" if beyond else ""
    )


def _coefficient(name: str, spec: str) -> Callable[[Fit], str]:
    return lambda f: pm(f["params"][name], f["stderr"][name], spec)


def details_table(fits: Mapping[str, Fit]) -> str:
    """docs/fit.md's table: coefficients, derived figures, residual noise, held-out errors."""
    return _table(
        fits,
        {
            "flights / kept points": lambda f: f"{f['n_flights']} / {f['n_points']:,}",
            "speeds in the kept data (m/s)": lambda f: "{:.1f}–{:.1f}".format(
                *f["speed_range_mps"]
            ).replace("0.0–", "0–"),
            "c1 (W)": _coefficient("c1", ".1f"),
            "c2 (s²/m²)": _coefficient("c2", ".1e"),
            "c3 (W)": _coefficient("c3", ".1f"),
            "c4 (m²/s²)": _coefficient("c4", ".0f"),
            "c5 (W s³/m³)": _coefficient("c5", ".3f"),
            "**hover power (W)**": lambda f: (
                "**" + pm(f["hover_power_w"], f["hover_power_stderr_w"], ".1f") + "**"
            ),
            "V_me (m/s)": lambda f: pm(f["v_me_mps"], f["v_me_stderr_mps"], ".1f"),
            "V_mr (m/s)": _v_mr,
            "residual σ (W), noise inflation": lambda f: (
                f"{f['noise_sigma_w']:.1f}, ×{f['noise_inflation']:.1f}"
            ),
            "prior-dominated": lambda f: (
                ", ".join(PRIOR_NAMES[p] for p in f["prior_dominated"]) or "–"
            ),
            "**held-out RMSE / MAPE, theory**": lambda f: f"**{held_out(f, 'theory')}**",
            "held-out, polynomial (deg 3)": lambda f: held_out(f, "polynomial"),
            "held-out, network 3×10 tanh": lambda f: held_out(f, "dnn"),
            "theory − polynomial, per-fold RMSE": lambda f: fold_difference(f, "polynomial"),
            "theory − network, per-fold RMSE": lambda f: fold_difference(f, "dnn"),
        },
    )


def sitl_quad_summary(fit: Fit) -> str:
    theory = fit["models"]["theory"]
    return f"hover {fit['hover_power_w']:.1f} W, held-out RMSE {theory['rmse_w']:.2f} W"


def sitl_quad_data(fit: Fit) -> str:
    return (
        f"{fit['n_points']} points of {fit['n_flights']} flights, "
        f"0–{fit['speed_range_mps'][1]:.1f} m/s; hover power "
        f"**{pm(fit['hover_power_w'], fit['hover_power_stderr_w'], '.1f')} W**"
    )


def sitl_quad_errors(fit: Fit) -> str:
    models = fit["models"]
    return (
        f"V_mr {fit['v_mr_mps']:.1f} m/s, V_me {fit['v_me_mps']:.1f} m/s; **held-out RMSE "
        f"({fit['n_flights']} folds, one flight each) {models['theory']['rmse_w']:.2f} W, "
        f"MAPE {models['theory']['mape_pct']:.2f} %** for the theory (polynomial "
        f"{models['polynomial']['rmse_w']:.2f} W, network {models['dnn']['rmse_w']:.2f} W) at a "
        f"noise floor of {fit['noise_sigma_w']:.2f} W"
    )


def no_priors(fit: Fit) -> str:
    """``fit --no-priors``: how c1 and c3 correlate and how wide each is (W, to 100 W)."""
    corr = fit["correlation"][0][2]
    sigma_w = max(fit["stderr"]["c1"], fit["stderr"]["c3"])
    return f"correlate at {number(corr, '.2f')} (±{round(sigma_w, -2):.0f} W each)"


def no_priors_values(fit: Fit) -> str:
    """docs/fit.md's version of :func:`no_priors`: c1 ± its 1σ."""
    return f"{fit['params']['c1']:.3f} ± {round(fit['stderr']['c1'], -2):.0f} W"


def residual_noise(fit: Fit) -> str:
    """The residual σ (W) and the held-out RMSE range of the three models."""
    rmse = [s["rmse_w"] for s in fit["models"].values()]
    return (
        f"σ {fit['noise_sigma_w']:.0f} W; held-out RMSE {min(rmse):.1f}–{max(rmse):.1f} W "
        f"for every model"
    )


def _model(fit: Fit) -> PowerModel:
    return PowerModel(*(fit["params"][name] for name in COEFFICIENT_NAMES))


def inflation(fits: Iterable[Fit]) -> str:
    """The noise inflation factors of ``fits`` as a range."""
    return span([f["noise_inflation"] for f in fits], ".1f")


def flat(fits: Iterable[Fit], speed_mps: float) -> str:
    """How much the fitted power at ``speed_mps`` differs from hover (%), as a range."""
    changes = [100 * (float(_model(f).power_w(speed_mps)) / f["hover_power_w"] - 1) for f in fits]
    return f"{span(changes, '.0f')} % from hover to {speed_mps:g} m/s"


def determined(fits: Sequence[Fit]) -> str:
    """How well the fits pin down hover power and V_me (1σ)."""
    hover = max(f["hover_power_stderr_w"] for f in fits)
    v_me = span([f["v_me_stderr_mps"] for f in fits], ".1f")
    return f"Hover power is measured to ±{hover:.1f} W; V_me has ±{v_me} m/s"


def profile_and_induced(fits: Sequence[Fit]) -> str:
    """c1 and c3 (1σ) against their sum, the hover power, and their correlation."""
    each = span([f["stderr"][c] for f in fits for c in ("c1", "c3")], ".0f")
    total = span([f["hover_power_stderr_w"] for f in fits], ".1f")
    corr = span([f["correlation"][0][2] for f in fits], ".2f")
    return f"c1/c3 individually are ±{each} W while their sum is ±{total} W (correlation {corr})"


def noise(fits: Sequence[Fit]) -> str:
    """The residual σ (W) and the theory's held-out MAPE (%), as ranges."""
    sigma = span([f["noise_sigma_w"] for f in fits], ".0f")
    mape = span([f["models"]["theory"]["mape_pct"] for f in fits], ".0f")
    return f"σ {sigma} W, held-out MAPE {mape} %"


def dip(fit: Fit) -> str:
    """How far the fitted curve dips between hover and V_me (W)."""
    return f"{fit['hover_power_w'] - float(_model(fit).power_w(fit['v_me_mps'])):.0f} W"


def v_me(fit: Fit) -> str:
    """The fitted V_me ± 1σ against the speed range of the kept data (m/s)."""
    low, high = fit["speed_range_mps"]
    return (
        f"V_me = {pm(fit['v_me_mps'], fit['v_me_stderr_mps'], '.1f')} m/s is inside the data "
        f"({low:.1f}–{high:.1f} m/s)"
    )


def theory_against_polynomial(fit: Fit) -> str:
    models = fit["models"]
    return f"{models['theory']['rmse_w']:.1f} W vs {models['polynomial']['rmse_w']:.1f} W"


def speeds(fits: Sequence[Fit]) -> str:
    """The speed range of the kept data (m/s) over ``fits``."""
    low = min(f["speed_range_mps"][0] for f in fits)
    high = max(f["speed_range_mps"][1] for f in fits)
    return f"{low:.0f}–{high:.0f} m/s"
