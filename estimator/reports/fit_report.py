"""``uav-energy fit --report DIR``: PNG plots and a summary of a fit
(:class:`~estimator.analysis.fit.FitReport`).

Files: ``scatter.png`` (power vs speed before and after preprocessing), ``points_per_speed.png``,
``curves.png`` (theory, polynomial and network over the kept data), ``residuals.png``,
``pack.png`` (the pack's fitted resting curve over its resting points, when fitted) and
``summary.md`` (the numbers of ``fit --json`` as tables, linking the plots).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from estimator.analysis.fit import FitReport, FlightCheck
from estimator.analysis.fit_points import Points
from estimator.analysis.pack_fit import PackFit
from estimator.physics.model import COEFFICIENT_NAMES, PowerModel

MODEL_LABELS = {
    "theory": "theory, eq. (1)/(2)",
    "polynomial": "polynomial",
    "dnn": "network 3×10 tanh",
}
MODEL_COLORS = {"theory": "C3", "polynomial": "C2", "dnn": "C0"}


def write_report(
    report: FitReport,
    out_dir: Path,
    title: str = "Power model fit",
    pack: PackFit | None = None,
) -> list[Path]:
    """Write the plots and ``summary.md`` into ``out_dir``; returns the files written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [
        _save(scatter_figure(report.points), out_dir / "scatter.png"),
        _save(points_per_speed_figure(report.points.kept()), out_dir / "points_per_speed.png"),
        _save(curves_figure(report, title), out_dir / "curves.png"),
        _save(residuals_figure(report), out_dir / "residuals.png"),
    ]
    if pack is not None and pack.cell_ocv_v is not None:
        files.append(_save(pack_figure(pack), out_dir / "pack.png"))
    summary = out_dir / "summary.md"
    summary.write_text(summary_markdown(report, title, [f.name for f in files]))
    return [*files, summary]


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _speed_grid(points: Points) -> np.ndarray:
    return np.linspace(0.0, max(float(np.max(points.speed_mps)), 1.0), 200)


def scatter_figure(points: Points) -> Figure:
    """Power vs speed of every resampled point, and of the points kept for fitting."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    kept = points.kept()
    axes[0].scatter(points.speed_mps, points.power_w, s=2, alpha=0.3, color="0.4")
    axes[0].set_title(f"before preprocessing ({len(points)} points)")
    axes[1].scatter(kept.speed_mps, kept.power_w, s=2, alpha=0.3, color="C0")
    axes[1].set_title(f"after preprocessing ({len(kept)} points)")
    for ax in axes:
        ax.set_xlabel("horizontal speed (m/s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("battery power (W)")
    fig.tight_layout()
    return fig


def points_per_speed_figure(kept: Points) -> Figure:
    """Number of kept points per 1 m/s speed bin."""
    fig, ax = plt.subplots(figsize=(6, 3.5))
    edges = np.arange(0.0, np.ceil(np.max(kept.speed_mps)) + 1.0, 1.0) - 0.5
    ax.hist(kept.speed_mps, bins=list(edges), color="C0", edgecolor="white")
    ax.set_xlabel("horizontal speed (m/s)")
    ax.set_ylabel("valid points")
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    return fig


def _grid_points(report: FitReport, speed: np.ndarray) -> Points:
    n = len(speed)
    zeros = np.zeros(n)
    return Points(
        flight_ids=["grid"],
        flight=np.zeros(n, dtype=np.int64),
        time_s=zeros,
        speed_mps=speed,
        accel_tangential_mps2=zeros,
        accel_perp_mps2=zeros,
        vd_mps=zeros,
        power_w=zeros,
        mass_ratio=np.ones(n),
        keep=np.ones(n, dtype=bool),
    )


def curves_figure(report: FitReport, title: str) -> Figure:
    """Kept data with the three fitted curves (at the reference mass) and the theory's ±2σ."""
    kept = report.points.kept()
    v = _speed_grid(kept)
    grid = _grid_points(report, v)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.scatter(kept.speed_mps, kept.power_w, s=2, alpha=0.15, color="0.5", label="kept points")
    theory = report.theory.model.power_w(v)
    band = 2 * report.theory.curve_stderr_w(v)
    ax.fill_between(v, theory - band, theory + band, color=MODEL_COLORS["theory"], alpha=0.25)
    for name, curve in (
        ("theory", theory),
        ("polynomial", report.polynomial.predict(grid)),
        ("dnn", report.network.predict(grid)),
    ):
        s = report.scores[name]
        label = f"{MODEL_LABELS[name]}: held-out RMSE {s.rmse_w:.1f} W, MAPE {s.mape_pct:.1f} %"
        ax.plot(v, curve, color=MODEL_COLORS[name], lw=2, label=label)
    model = report.theory.model
    ax.axvline(model.max_endurance_speed_mps(), color="k", ls=":", lw=1)
    ax.axvline(model.max_range_speed_mps(), color="k", ls="--", lw=1)
    lo, hi = np.percentile(kept.power_w, [0.5, 99.5])
    pad = 0.15 * (hi - lo)
    ax.set_ylim(lo - pad, hi + pad)
    ax.set_xlabel("horizontal speed (m/s)   (dotted: V_me, dashed: V_mr)")
    ax.set_ylabel("battery power (W)")
    ax.set_title(title if not kept.varying_mass else f"{title} (curves at the reference mass)")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def residuals_figure(report: FitReport) -> Figure:
    """Theory residuals vs speed and their histogram."""
    kept = report.points.kept()
    resid = kept.power_w - report.theory.predict(kept)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
    axes[0].scatter(kept.speed_mps, resid, s=2, alpha=0.2, color="C3")
    axes[0].axhline(0.0, color="k", lw=1)
    axes[0].set_xlabel("horizontal speed (m/s)")
    axes[0].set_ylabel("measured − theory (W)")
    axes[1].hist(resid, bins=60, color="C3", alpha=0.8)
    axes[1].set_xlabel(f"residual (W), σ = {report.theory.sigma_w:.1f} W")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def pack_figure(pack: PackFit) -> Figure:
    """The pack's resting points ((V + I·R)/cells against the state of charge) and the fitted
    curve written to the vehicle file, the fitted stretch shaded."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.scatter(
        pack.points_soc, pack.points_cell_v, s=2, alpha=0.3, color="0.4", label="V + I·R per cell"
    )
    if pack.cell_ocv_v is not None and pack.fitted_soc is not None:
        soc = np.linspace(0.0, 1.0, len(pack.cell_ocv_v))
        ax.plot(soc, pack.cell_ocv_v, color="C3", lw=2, label="resting curve (vehicle file)")
        ax.axvspan(*pack.fitted_soc, color="C3", alpha=0.08, label="fitted stretch")
    sigma = "" if pack.sigma_v is None else f", σ {1000 * pack.sigma_v:.1f} mV/cell"
    ax.set_title(f"Pack: R {1000 * pack.resistance_ohm:.1f} mΩ{sigma}")
    ax.set_xlabel("state of charge")
    ax.set_ylabel("cell voltage at rest (V)")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def summary_markdown(report: FitReport, title: str, images: list[str]) -> str:
    """The fit's numbers as a short markdown page."""
    s = report.summary()
    params, stderr = report.theory.model.as_dict(), report.theory.coeff_stderr
    lines = [
        f"# {title}",
        "",
        f"{s['n_points']} points from {s['n_flights']} flights after preprocessing; "
        f"speeds {s['speed_range_mps'][0]:.1f}–{s['speed_range_mps'][1]:.1f} m/s "  # type: ignore[index]
        f"(of {len(report.points)} resampled points).",
        "",
        "| quantity | value | 1σ |",
        "|---|---|---|",
    ]
    lines += [f"| {n} | {params[n]:.5g} | {stderr[n]:.2g} |" for n in COEFFICIENT_NAMES]
    lines += [
        f"| hover power (W) | {s['hover_power_w']:.1f} | {s['hover_power_stderr_w']:.2g} |",
        f"| V_me (m/s) | {s['v_me_mps']:.2f} | {s['v_me_stderr_mps']:.2g} |",
        f"| V_mr (m/s) | {s['v_mr_mps']:.2f} | {s['v_mr_stderr_mps']:.2g} |",
        "",
        f"Residual σ {report.theory.sigma_w:.1f} W; standard errors inflated ×"
        f"{report.theory.noise_inflation:.2f} for correlated noise. "
        f"Prior-dominated parameters: {', '.join(report.theory.prior_dominated) or 'none'}.",
        "",
        f"Held-out errors (split by {report.split}, "
        f"{len(report.scores['theory'].fold_rmse_w)} folds):",
        "",
        "| model | RMSE (W) | MAPE (%) | RMSE per fold (W) |",
        "|---|---|---|---|",
    ]
    for name, sc in report.scores.items():
        folds = ", ".join(f"{x:.1f}" for x in sc.fold_rmse_w)
        lines.append(f"| {MODEL_LABELS[name]} | {sc.rmse_w:.2f} | {sc.mape_pct:.2f} | {folds} |")
    lines += ["", "Correlation of c1..c5:", "", "| | " + " | ".join(COEFFICIENT_NAMES) + " |"]
    lines.append("|---" * 6 + "|")
    for name, row in zip(COEFFICIENT_NAMES, report.theory.correlation, strict=True):
        lines.append(f"| {name} | " + " | ".join(f"{x:+.2f}" for x in row) + " |")
    lines += [""] + [f"![{name}]({name})" for name in images] + [""]
    return "\n".join(lines)


def circles_figure(model: PowerModel, checks: list[FlightCheck], radii_m: list[float]) -> Figure:
    """Experiment 2: measured mean power per circle flight vs eq. (2) with a⊥ = V²/r."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    v = np.linspace(0.0, max(c.speed_mps for c in checks) * 1.15, 200)
    radii = sorted(set(radii_m))
    for k, r in enumerate(radii):
        color = f"C{k}"
        ax.plot(v, model.power_w(v, v**2 / r), color=color, lw=2, label=f"eq. (2), r = {r:.0f} m")
        rows = [c for c, rr in zip(checks, radii_m, strict=True) if rr == r]
        ax.plot(
            [c.speed_mps for c in rows],
            [c.measured_w for c in rows],
            "o",
            color=color,
            label=f"measured, r = {r:.0f} m",
        )
    ax.plot(v, model.power_w(v), color="k", ls="--", lw=1.5, label="eq. (1), r = ∞")
    ax.set_xlabel("speed (m/s)")
    ax.set_ylabel("battery power (W)")
    ax.set_title("Experiment 2: circles, model fitted on experiment 1")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Write a figure as PNG and close it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return _save(fig, path)


def circles_markdown(checks: list[FlightCheck], radii_m: list[float]) -> str:
    """Experiment 2 table: measured vs predicted mean power per circle flight."""
    lines = [
        "| r (m) | V (m/s) | a⊥ (m/s²) | measured (W) | eq. (2) (W) | eq. (1) (W) "
        "| RMSE eq. (2) (W) |",
        "|---|---|---|---|---|---|---|",
    ]
    for c, r in sorted(zip(checks, radii_m, strict=True), key=lambda x: (x[1], x[0].speed_mps)):
        lines.append(
            f"| {r:.0f} | {c.speed_mps:.2f} | {c.accel_perp_mps2:.2f} | {c.measured_w:.1f} | "
            f"{c.eq2_w:.1f} | {c.eq1_w:.1f} | {c.eq2_rmse_w:.1f} |"
        )
    return "\n".join(lines) + "\n"
