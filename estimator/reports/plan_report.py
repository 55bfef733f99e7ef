"""PNG plots of a planned mission (matplotlib, Agg) and a summary page.

``route.png``: the route seen from above (east, north m from home), each leg coloured by its
mean power, with the wind arrow (pointing where the wind blows to). ``energy.png``: energy left
in the pack along the distance flown (Wh, ±1σ band) against the reserve line; take-off and
landing drop it in place. ``summary.md`` lists the legs and the totals.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection

from estimator.analysis.mission_energy import MissionEnergy
from estimator.errors import UserError


def write_report(result: MissionEnergy, out_dir: Path, title: str) -> Path:
    """Write ``route.png``, ``energy.png`` and ``summary.md`` into ``out_dir``; return the
    summary's path."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create report directory {out_dir}: {exc.strerror}") from None
    for name, fig in (
        ("route", _plot_route(result, title)),
        ("energy", _plot_energy(result, title)),
    ):
        fig.savefig(out_dir / f"{name}.png", dpi=110)
        plt.close(fig)
    t, c = result.total, result.conditions
    lines = [
        f"# Mission plan: {title}",
        "",
        f"Wind {c.wind_speed_mps:g} m/s from {c.wind_from_deg:03.0f}°, "
        f"payload {c.payload_kg:g} kg.",
        "",
        "| leg | kind | distance m | climb m | time s | power W | energy Wh | best speed m/s |",
        "|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for i, r in enumerate(result.legs):
        e = r.energy
        best = f"{r.recommended.ground_speed_mps:.1f}" if r.recommended else "–"
        lines.append(
            f"| {i + 1} | {r.name} | {e.distance_m:.0f} | {e.climb_m:+.0f} | {e.time_s:.0f} "
            f"| {e.power_w:.0f} | {e.energy_wh:.2f} ± {e.energy_sigma_wh:.2f} | {best} |"
        )
    lines += [
        "",
        f"Total {t.energy_wh:.2f} ± {t.energy_sigma_wh:.2f} Wh in {t.time_s:.0f} s; usable above "
        f"the reserve {result.usable_wh:.2f} Wh; margin {result.margin_wh:+.2f} Wh: "
        f"{'feasible' if result.feasible else 'NOT feasible'}. PX4-style estimate: "
        f"{result.px4.energy_wh:.2f} Wh in {result.px4.time_s:.0f} s.",
        "",
        "![route](route.png)",
        "",
        "![energy](energy.png)",
        "",
    ]
    summary = out_dir / "summary.md"
    summary.write_text("\n".join(lines))
    return summary


def _plot_route(result: MissionEnergy, title: str) -> plt.Figure:
    fig, ax = plt.subplots(figsize=(7, 6.5))
    segments, powers = [], []
    for r in result.legs:
        (n0, e0, _), (n1, e1, _) = r.leg.start_ned_m, r.leg.end_ned_m
        segments.append([(e0, n0), (e1, n1)])
        powers.append(r.energy.power_w)
        if r.leg.turns > 0 and r.leg.radius_m > 0:
            theta = np.linspace(0, 2 * math.pi, 73)
            ax.plot(
                e1 + r.leg.radius_m * np.sin(theta),
                n1 + r.leg.radius_m * np.cos(theta),
                lw=1.0,
                ls=":",
                color="gray",
            )
    lines = LineCollection(segments, cmap="plasma", linewidths=3.5)
    lines.set_array(np.asarray(powers))
    ax.add_collection(lines)
    fig.colorbar(lines, ax=ax, label="mean leg power (W)")
    points = np.array([p for seg in segments for p in seg])
    ax.plot(points[:, 0], points[:, 1], "o", ms=3, color="black")
    ax.plot(0, 0, marker="H", ms=11, color="tab:green", label="home", ls="none")
    span = max(float(np.ptp(points[:, 0])), float(np.ptp(points[:, 1])), 50.0)
    c = result.conditions
    if c.wind_speed_mps > 0:
        wn, we = c.wind_ne_mps()
        scale = 0.2 * span / c.wind_speed_mps
        x0 = float(points[:, 0].min()) - 0.15 * span
        y0 = float(points[:, 1].max()) + 0.15 * span
        tip = (x0 + we * scale, y0 + wn * scale)
        ax.plot([x0, tip[0]], [y0, tip[1]], alpha=0.0)  # keeps the arrow inside the axes
        ax.annotate(
            "",
            xy=tip,
            xytext=(x0, y0),
            arrowprops={"arrowstyle": "-|>", "lw": 2.5, "color": "tab:blue"},
        )
        ax.text(
            x0,
            y0,
            f"wind {c.wind_speed_mps:g} m/s\nfrom {c.wind_from_deg:03.0f}°  ",
            color="tab:blue",
            ha="right" if we >= 0 else "left",
            va="center",
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.margins(0.15)
    ax.set(xlabel="east (m)", ylabel="north (m)", title=f"{title}: route by power")
    ax.legend(loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def _plot_energy(result: MissionEnergy, title: str) -> plt.Figure:
    fig, ax = plt.subplots(figsize=(9, 4.5))
    distance, usable, sigma = result.profile()
    left = usable + result.reserve_wh
    ax.plot(distance, left, "o-", ms=3, lw=1.2, color="tab:green", label="energy left (plan)")
    ax.fill_between(
        distance, left - sigma, left + sigma, alpha=0.25, color="tab:green", label="±1σ"
    )
    ax.axhline(result.reserve_wh, color="tab:red", ls="--", label="reserve")
    ax.set(
        xlabel="distance over ground (m)",
        ylabel="energy in the pack (Wh)",
        title=f"{title}: energy along the route",
    )
    ax.set_ylim(bottom=0)
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
