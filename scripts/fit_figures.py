"""The fit figures of README.md, docs/fit.md and docs/sitl.md, as text, from the ``--json``
objects of ``uav-energy fit``, and the fits they read:

- ``fit-*``: ``uav-energy fit`` of the real logs as ``make fit-real`` runs it
  (:data:`REAL_FITS`), and variants (``--degree 6``, ``--no-priors``); ``fit-sitl-run1``: the
  fit of ``../shared``'s recorded ArduCopter SITL flight;
- ``sitl-quad-fit*``: the fit of SITL's clean recordings the SITL vehicle file comes from;
- ``pack-fit-sitl-*``: ``python scripts/pack_fit_sitl.py`` (the pack fitted on SITL's pack
  flights).

``scripts/figures.py`` runs ``uav-energy`` in process and registers the blocks
(:func:`real_generators` and :func:`run1_generators`, which read ``../shared``, and
:func:`sitl_generators`); ``tests/test_figures.py`` checks them. :func:`number` and
:func:`span` are the documents' number formats, which the other ``*_figures.py`` use too.

Powers in W, speeds in m/s; ± is 1σ (for the per-fold differences: the mean's standard error).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from estimator.physics.model import COEFFICIENT_NAMES, PowerModel

Fit = Mapping[str, Any]
#: What ``uav-energy ARGV…`` prints on stdout (``scripts/figures.py`` runs it in process).
Cli = Callable[..., str]

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


# --- the fits -------------------------------------------------------------------------------------

#: The title of the CMU M100 fit in :data:`REAL_FITS`.
CMU = "CMU DJI M100"


def run_fit(cli: Cli, data: Path, title: str, *extra: str) -> dict[str, Any]:
    """``uav-energy fit`` of one dataset of :data:`REAL_FITS` (under ``data``, ../shared/data),
    with ``extra`` options."""
    pattern, mass_kg, capacity_ah, cells = REAL_FITS[title]
    logs = [str(p) for p in sorted(data.glob(pattern))]
    options = ("--mass-kg", f"{mass_kg}", "--capacity-ah", f"{capacity_ah}", "--cells", f"{cells}")
    return dict(json.loads(cli("fit", *logs, *options, *extra, "--json")))


@cache
def real_fits(cli: Cli, data: Path) -> dict[str, dict[str, Any]]:
    """``uav-energy fit LOG… --mass-kg M --capacity-ah C --cells N --json`` of each dataset as
    ``make fit-real`` runs it (without writing the vehicle files)."""
    return {title: run_fit(cli, data, title) for title in REAL_FITS}


def iris_fits(cli: Cli, data: Path) -> list[dict[str, Any]]:
    """The two IRIS+ periods' fits of :func:`real_fits`."""
    return [fit for title, fit in real_fits(cli, data).items() if "IRIS+" in title]


def iris_pooled_hover_w(cli: Cli, data: Path) -> list[float]:
    """The hover power (W) of each IRIS+ period's pooled fit."""
    return [fit["hover_power_w"] for fit in iris_fits(cli, data)]


@cache
def no_priors_fit(cli: Cli, data: Path) -> dict[str, Any]:
    """``uav-energy fit`` of the IRIS+ March flights with ``--no-priors`` (the data alone)."""
    return run_fit(cli, data, "IRIS+ March 2016", "--no-priors")


def degree_6(cli: Cli, data: Path) -> str:
    """``uav-energy fit … --degree 6``'s held-out polynomial RMSE on IRIS+ March and CMU."""
    rmse = [
        run_fit(cli, data, title, "--degree", "6")["models"]["polynomial"]["rmse_w"]
        for title in ("IRIS+ March 2016", CMU)
    ]
    return f"{rmse[0]:.2f} W on IRIS+ March and {rmse[1]:.2f} W on CMU"


def no_priors_cmu(cli: Cli, data: Path) -> str:
    """The theory's held-out RMSE of ``uav-energy fit`` of the CMU flights with
    ``--no-priors``."""
    fit = run_fit(cli, data, CMU, "--no-priors")
    return f"{fit['models']['theory']['rmse_w']:.1f} W"


@cache
def sitl_quad_fit(cli: Cli, sitl: ModuleType) -> dict[str, Any]:
    """``uav-energy fit`` of the clean SITL recordings, as docs/sitl.md gives the command (the
    SITL vehicle file is this fit plus the acceleration effect found later); ``sitl``:
    ``scripts/sitl_figures.py``."""
    logs = [str(sitl.SITL_RECORDINGS / s / "flight.tlog") for s in sitl.CLEAN_RECORDINGS]
    options = ("--mass-kg", "3.0", "--capacity-ah", "2.2", "--cells", "3")
    return dict(json.loads(cli("fit", *logs, *options, "--json")))


#: The speed (m/s) docs/fit.md compares the IRIS+ curves' power at with hover.
IRIS_LEG_SPEED_MPS = 5.0


def real_generators(cli: Cli, data: Path) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the blocks that read the real logs under
    ``data`` (../shared/data)."""
    real = partial(real_fits, cli, data)
    iris = partial(iris_fits, cli, data)
    no_priors_run = partial(no_priors_fit, cli, data)
    return {
        "fit-real-table": lambda: summary_table(real()),
        "fit-real-details": lambda: details_table(real()),
        "fit-real-folds": lambda: ", ".join(
            fold_difference(f, "polynomial") for f in real().values()
        ),
        "fit-real-inflation": lambda: inflation(real().values()),
        "fit-iris-speeds": lambda: speeds(iris()),
        "fit-iris-flat": lambda: flat(iris(), IRIS_LEG_SPEED_MPS),
        "fit-iris-determined": lambda: determined(iris()),
        "fit-iris-c1-c3": lambda: profile_and_induced(iris()),
        "fit-iris-noise": lambda: noise(iris()),
        "fit-cmu-dip": lambda: dip(real()[CMU]),
        "fit-cmu-vme": lambda: v_me(real()[CMU]),
        "fit-cmu-residual": lambda: residual_noise(real()[CMU]),
        "fit-degree-6": partial(degree_6, cli, data),
        "fit-no-priors-cmu": partial(no_priors_cmu, cli, data),
        "fit-no-priors": lambda: no_priors(no_priors_run()),
        "fit-no-priors-values": lambda: no_priors_values(no_priors_run()),
    }


def run1_generators(cli: Cli, run1: Path) -> dict[str, Callable[[], str]]:
    """The block that reads ``../shared``'s recorded SITL flight (``run1``): ``uav-energy fit
    RUN1 --json``'s theory against its polynomial."""
    return {
        "fit-sitl-run1": lambda: theory_against_polynomial(
            json.loads(cli("fit", str(run1), "--json"))
        )
    }


def sitl_generators(
    cli: Cli, sitl: ModuleType, pack_fit: ModuleType
) -> dict[str, Callable[[], str]]:
    """The blocks of SITL's recordings in the repository; ``sitl``:
    ``scripts/sitl_figures.py``; ``pack_fit``: ``scripts/pack_fit_sitl.py``, whose fits (3 s
    of CPU) its table and pooled line print."""
    quad = partial(sitl_quad_fit, cli, sitl)
    packs = cache(lambda: dict(pack_fit.halves()))
    return {
        "sitl-quad-fit": lambda: sitl_quad_summary(quad()),
        "sitl-quad-fit-data": lambda: sitl_quad_data(quad()),
        "sitl-quad-fit-errors": lambda: sitl_quad_errors(quad()),
        "pack-fit-sitl-table": lambda: pack_fit.table(packs()),
        "pack-fit-sitl-pooled": lambda: pack_fit.pooled(packs()),
    }
