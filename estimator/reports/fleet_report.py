"""The fleet trends report (matplotlib, Agg): ``trends.png``, ``summary.md`` and
``summary.json``.

One panel per metric (hover power, internal resistance, usable capacity from the resting
voltage, learnt capacity) against the flight date: every flight as a dot (with its 1σ error
bar where it has one), the per-day figures joined, one colour per vehicle or pack
(:mod:`estimator.analysis.fleet_trends`).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates
import matplotlib.pyplot as plt
import numpy as np

from estimator.analysis.fleet_trends import METRICS, FleetTrends
from estimator.reports.output_dir import make_report_dir

_FIGURE = "trends.png"


def write_report(trends: FleetTrends, out_dir: Path, title: str) -> Path:
    """Write the plot, ``summary.md`` and ``summary.json`` into ``out_dir``; return the
    summary's path."""
    make_report_dir(out_dir)
    _plot(trends, title).savefig(out_dir / _FIGURE, dpi=110)
    plt.close("all")
    lines = [
        f"# {title}",
        "",
        *(f"- {line}" for line in trends.lines()),
        "",
        f"![trends]({_FIGURE})",
    ]
    lines += [
        "",
        "| kind | group | metric | day | median | flights |",
        "|---|---|---|---|---:|---:|",
    ]
    for s in trends.series:
        for day, value, n in s.per_day():
            lines.append(
                f"| {s.kind} | {s.group} | {s.label} | {day} | {value:.4g} {s.unit} | {n} |"
            )
    summary = out_dir / "summary.md"
    summary.write_text("\n".join(lines) + "\n")
    (out_dir / "summary.json").write_text(json.dumps(trends.as_dict(), indent=2) + "\n")
    return summary


def _plot(trends: FleetTrends, title: str) -> plt.Figure:
    fig, axes = plt.subplots(len(METRICS), 1, figsize=(9, 10), sharex=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    groups = sorted({(s.kind, s.group) for s in trends.series})
    for ax, (metric, unit, label) in zip(axes, METRICS, strict=True):
        for s in trends.series:
            if s.metric != metric:
                continue
            colour = colours[groups.index((s.kind, s.group)) % len(colours)]
            if s.sigmas is None:
                ax.plot(_dates(s.days), s.values, ".", color=colour, alpha=0.4)
            else:
                ax.errorbar(_dates(s.days), s.values, s.sigmas, fmt=".", color=colour, alpha=0.4)
            daily = s.per_day()
            ax.plot(
                [datetime(d.year, d.month, d.day, tzinfo=UTC) for d, _, _ in daily],
                [v for _, v, _ in daily],
                "o-",
                color=colour,
                label=f"{s.kind} {s.group}",
            )
        ax.set_ylabel(f"{label}, {unit}")
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize="small")
        else:
            ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center")
    axes[-1].xaxis.set_major_formatter(mdates.DateFormatter("%Y-%m-%d"))
    fig.autofmt_xdate()
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _dates(days: np.ndarray) -> list[datetime]:
    return [datetime.fromtimestamp(d * 86400.0, UTC) for d in days]
