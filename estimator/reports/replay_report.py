"""PNG plots of replayed flights (matplotlib, Agg) and a summary page.

Per flight, over log time (s): measured vs model power; speed, centripetal and tangential
acceleration; remaining energy and endurance, each with its 1σ band. One ``summary.md`` lists
the figures and the power error table (airborne points only, see :mod:`estimator.analysis.replay`).
Flights flown to their reserve with a truth beside the log add the endurance against the truth
(:mod:`estimator.reports.endurance_reliability`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from estimator.analysis.endurance_truth import ScoredFlight
from estimator.analysis.replay import FlightReplay, Summary, summarize
from estimator.reports.endurance_reliability import plot_endurance_truth, reliability_section
from estimator.reports.output_dir import make_report_dir


def write_report(
    flights: Sequence[FlightReplay],
    out_dir: Path,
    vehicle_name: str,
    scored: Sequence[ScoredFlight] = (),
    capacity_ah: float | None = None,
) -> Path:
    """Write the plots and ``summary.md`` into ``out_dir``; return the summary's path.
    ``scored``: the flights with a reserve truth, replayed under ``capacity_ah`` (Ah)."""
    make_report_dir(out_dir)
    lines = [
        "# Replay report",
        "",
        f"Vehicle: `{vehicle_name}`. Errors over airborne battery samples "
        "(model power vs measured V·I).",
        "",
        _table_header(),
    ]
    for flight in flights:
        lines.append(_table_row(flight.name, summarize([flight])))
    if len(flights) > 1:
        lines.append(_table_row("**all**", summarize(flights)))
    lines.append("")
    lines += reliability_section(scored, out_dir, capacity_ah)
    truths = {f.name: f for f in scored}
    for flight in flights:
        if not flight.estimates:
            lines += [f"## {flight.name}", "", "No estimates (no battery telemetry?).", ""]
            continue
        stem = _file_stem(flight.name)
        figures = {
            "power": _plot_power(flight),
            "kinematics": _plot_kinematics(flight),
            "energy": _plot_energy(flight),
        }
        if flight.name in truths:
            figures["endurance-truth"] = plot_endurance_truth(flight, truths[flight.name])
        lines += [f"## {flight.name}", ""]
        for kind, fig in figures.items():
            name = f"{stem}-{kind}.png"
            fig.savefig(out_dir / name, dpi=110)
            plt.close(fig)
            lines.append(f"![{kind}]({name})")
        lines.append("")
    summary = out_dir / "summary.md"
    summary.write_text("\n".join(lines))
    return summary


def _table_header() -> str:
    return (
        "| flight | samples | duration s | airborne s | power RMSE W | power MAPE % "
        "| energy measured Wh | energy model Wh |\n|---|---:|---:|---:|---:|---:|---:|---:|"
    )


def _table_row(name: str, s: Summary) -> str:
    def fmt(x: float | None, spec: str) -> str:
        return "–" if x is None else format(x, spec)

    return (
        f"| {name} | {s.messages} | {s.duration_s:.0f} | {s.airborne_s:.0f} "
        f"| {fmt(s.power_rmse_w, '.1f')} | {fmt(s.power_mape_pct, '.1f')} "
        f"| {s.energy_measured_wh:.2f} | {s.energy_predicted_wh:.2f} |"
    )


def _file_stem(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_") or "flight"


def _series(flight: FlightReplay, name: str) -> np.ndarray:
    return np.array([getattr(e, name) for e in flight.estimates], dtype=float)


def _plot_power(flight: FlightReplay) -> plt.Figure:
    fig, ax = plt.subplots(figsize=(10, 4))
    t, measured, model, airborne = flight.power.arrays()
    ax.plot(t, measured, lw=0.8, color="tab:blue", label="measured V·I")
    ax.plot(t, model, lw=0.8, color="tab:orange", label="model")
    _shade_ground(ax, t, airborne)
    ax.set(xlabel="log time (s)", ylabel="power (W)", title=f"{flight.name}: power")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _plot_kinematics(flight: FlightReplay) -> plt.Figure:
    t = _series(flight, "time_s")
    fig, (ax_v, ax_a) = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    ax_v.plot(t, _series(flight, "speed_mps"), lw=0.8, label="horizontal speed")
    ax_v.plot(t, _series(flight, "climb_mps"), lw=0.8, label="climb rate")
    ax_v.set(ylabel="m/s", title=f"{flight.name}: flight state")
    ax_a.plot(t, _series(flight, "accel_centripetal_mps2"), lw=0.8, label="a⊥ centripetal")
    ax_a.plot(t, _series(flight, "accel_tangential_mps2"), lw=0.8, label="a∥ tangential")
    ax_a.set(xlabel="log time (s)", ylabel="m/s²")
    for ax in (ax_v, ax_a):
        ax.legend(loc="upper right")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _plot_energy(flight: FlightReplay) -> plt.Figure:
    t = _series(flight, "time_s")
    fig, (ax_e, ax_t) = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    _band(
        ax_e,
        t,
        _series(flight, "energy_remaining_wh"),
        _series(flight, "energy_remaining_sigma_wh"),
        "tab:green",
        "remaining energy ±1σ",
    )
    ax_e.set(ylabel="Wh (above reserve)", title=f"{flight.name}: energy and endurance")
    endurance_min = _series(flight, "endurance_s") / 60.0
    sigma_min = _series(flight, "endurance_sigma_s") / 60.0
    finite = np.isfinite(endurance_min) & np.isfinite(sigma_min)
    _band(ax_t, t[finite], endurance_min[finite], sigma_min[finite], "tab:purple", "endurance ±1σ")
    hover = _series(flight, "hover_endurance_s") / 60.0
    ax_t.plot(t, hover, lw=0.7, ls="--", color="gray", label="hover endurance")
    ax_t.set(xlabel="log time (s)", ylabel="minutes")
    for ax in (ax_e, ax_t):
        ax.legend(loc="upper right")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _band(
    ax: Axes, t: np.ndarray, y: np.ndarray, sigma: np.ndarray, color: str, label: str
) -> None:
    ax.plot(t, y, lw=0.9, color=color, label=label)
    ax.fill_between(t, y - sigma, y + sigma, color=color, alpha=0.25, lw=0)


def _shade_ground(ax: Axes, t: np.ndarray, airborne: np.ndarray) -> None:
    """Grey out the power points not counted in the error (on the ground)."""
    if len(t) == 0:
        return
    ax.fill_between(
        t,
        0,
        1,
        where=~airborne,
        transform=ax.get_xaxis_transform(),
        color="gray",
        alpha=0.12,
        lw=0,
        label="not airborne",
    )
