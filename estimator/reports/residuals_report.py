"""``uav-energy residuals --report DIR``: residual plots before/after and the selection table.

Writes ``residual_time.png`` (residual over each flight, before and after the selected
effects, held-out, with the time windows of effects that change in flight shaded; lines
break at gaps in the samples, and of many flights only the names that stay clear are
written),
``residual_channels.png`` (the same against every channel, with binned
means), ``attribution.png`` (held-out R² of each channel, before and after) and
``summary.md`` (figures, selected effects, the full selection table, the verdict).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes

from estimator.analysis.replay import MAX_GAP_S
from estimator.analysis.residuals import FloatArray, ResidualResult, describe

#: Time between two flights on the time plot's axis, s.
FLIGHT_SPACING_S = 10.0
#: Most flight names along the time plot's top (rotated 6 pt text clears its neighbours).
MAX_FLIGHT_LABELS = 40
_BEFORE = dict(color="tab:red", alpha=0.35, s=3, linewidths=0)
_AFTER = dict(color="tab:blue", alpha=0.35, s=3, linewidths=0)


def write_report(result: ResidualResult, out_dir: Path, title: str) -> list[Path]:
    """Write the plots and ``summary.md`` into ``out_dir``; returns the files written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = [
        _time_plot(result, out_dir / "residual_time.png"),
        _channel_plot(result, out_dir / "residual_channels.png"),
        _attribution_plot(result, out_dir / "attribution.png"),
    ]
    summary = out_dir / "summary.md"
    summary.write_text(_markdown(result, title, files))
    return [*files, summary]


def _time_plot(result: ResidualResult, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(11, 4))
    draw_time(ax, result)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def draw_time(ax: Axes, result: ResidualResult) -> None:
    """The residual (W) before and after over each flight, flights end to end on one time axis
    (s, :data:`FLIGHT_SPACING_S` apart), lines broken where a flight's samples stop for more
    than :data:`~estimator.analysis.replay.MAX_GAP_S`; names only where they stay clear of the
    previous one (:func:`clear_labels`)."""
    s = result.samples
    offset = 0.0
    starts: list[float] = []
    for k in range(len(s.flight_ids)):
        rows = s.flight == k
        t = s.state.time_s[rows]
        x = t - t[0] + offset
        for residual, color, alpha in (
            (result.residual_before_w(), "tab:red", 0.7),
            (result.residual_after_w(), "tab:blue", 0.8),
        ):
            ax.plot(*broken_at_gaps(x, residual[rows]), color=color, lw=0.6, alpha=alpha)
        _mark_windows(ax, result, float(t[0]), float(t[-1]), offset - float(t[0]))
        starts.append(offset)
        offset = float(x[-1]) + FLIGHT_SPACING_S
    named = clear_labels(starts, offset) if len(starts) > 1 else []
    if named:
        for x0 in starts:
            ax.axvline(x0, color="0.7", lw=0.5)
        for k in named:
            ax.text(
                starts[k],
                1.0,
                f" {s.flight_ids[k]}",
                transform=ax.get_xaxis_transform(),
                fontsize=6,
                va="top",
                rotation=90,
            )
    ax.axhline(0.0, color="k", lw=0.5)
    names = f"; {len(named)} of {len(starts)} flights named" if named else ""
    ax.set_xlabel(f"flight time, flights end to end (s){names}")
    ax.set_ylabel("measured − model (W)")
    ax.set_title(
        f"held-out residual: before (red, RMSE {result.rmse_w(False):.1f} W), "
        f"after (blue, RMSE {result.rmse_w(True):.1f} W)"
    )


def broken_at_gaps(x_s: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``x_s`` (s) and ``y`` with a NaN point after every step of ``x_s`` longer than
    :data:`~estimator.analysis.replay.MAX_GAP_S`: a line drawn through them stops there."""
    cut = np.flatnonzero(np.diff(x_s) > MAX_GAP_S) + 1
    return np.insert(x_s, cut, np.nan), np.insert(np.asarray(y, dtype=float), cut, np.nan)


def clear_labels(starts_s: list[float], span_s: float) -> list[int]:
    """Indexes of the flights (starting at ``starts_s`` on an axis ``span_s`` long) whose
    names are written: the first, then each at least ``span_s`` / :data:`MAX_FLIGHT_LABELS`
    after the last one written."""
    room_s = span_s / MAX_FLIGHT_LABELS
    chosen: list[int] = []
    for k, x0 in enumerate(starts_s):
        if not chosen or x0 - starts_s[chosen[-1]] >= room_s:
            chosen.append(k)
    return chosen


def _mark_windows(
    ax: Axes, result: ResidualResult, first_s: float, last_s: float, shift_s: float
) -> None:
    """Shade each selected effect's time window (flight clock + ``shift_s``), labelled."""
    for k, effect in enumerate(result.steady_effects):
        params = effect.params
        if "at_s" not in params or (params["at_s"] is None and params.get("until_s") is None):
            continue
        lo = first_s if params["at_s"] is None else max(first_s, params["at_s"])
        hi = last_s if params.get("until_s") is None else min(last_s, params["until_s"])
        if hi <= lo:
            continue
        ax.axvspan(lo + shift_s, hi + shift_s, color=f"C{k + 2}", alpha=0.12, lw=0)
        ax.text(
            lo + shift_s,
            0.98 - 0.06 * k,
            f" {describe(effect)}",
            transform=ax.get_xaxis_transform(),
            fontsize=7,
            va="top",
            color=f"C{k + 2}",
        )


def _binned(x: FloatArray, y: FloatArray, bins: int = 20) -> tuple[FloatArray, FloatArray]:
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if len(x) < bins:
        return np.empty(0), np.empty(0)
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    counts = np.bincount(idx, minlength=len(edges) - 1)
    keep = counts > 0
    centers = np.bincount(idx, weights=x, minlength=len(edges) - 1)[keep] / counts[keep]
    means = np.bincount(idx, weights=y, minlength=len(edges) - 1)[keep] / counts[keep]
    return centers, means


def _channel_plot(result: ResidualResult, path: Path) -> Path:
    channels = result.samples.channels
    n = len(channels)
    cols = 4
    rows = max(1, -(-n // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    before, after = result.residual_before_w(), result.residual_after_w()
    lim = float(np.nanpercentile(np.abs(before), 99)) * 1.1 or 1.0
    for ax, (name, x) in zip(axes.flat, channels.items(), strict=False):
        ax.scatter(x, before, **_BEFORE)
        ax.scatter(x, after, **_AFTER)
        for y, color in ((before, "darkred"), (after, "navy")):
            cx, cy = _binned(x, y)
            ax.plot(cx, cy, color=color, lw=1.5)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylim(-lim, lim)
        ax.set_xlabel(name, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    axes[0, 0].set_ylabel("residual (W)")
    fig.suptitle("held-out residual vs channel: before (red), after (blue), binned means")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _attribution_plot(result: ResidualResult, path: Path) -> Path:
    before = {c.channel: c.r2 for c in result.attribution_before}
    after = {c.channel: c.r2 for c in result.attribution}
    names = [c.channel for c in result.attribution_before]
    y = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(names) + 1.2))
    ax.barh(y + 0.2, [before[k] for k in names], height=0.4, color="tab:red", label="before")
    ax.barh(
        y - 0.2, [after.get(k, np.nan) for k in names], height=0.4, color="tab:blue", label="after"
    )
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    ax.axvline(result.options.min_r2, color="0.5", ls="--", lw=0.8)
    ax.set_xlabel("held-out R² of the residual from this channel alone (k-NN)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _markdown(result: ResidualResult, title: str, files: list[Path]) -> str:
    s = result.summary()
    lines = [
        f"# {title}",
        "",
        f"{s['n_samples']} airborne samples from {s['n_flights']} flight(s). Held-out split: "
        f"{s['split']}. Test: {s['test']}.",
        "",
        "| | RMSE (W) | MAPE (%) |",
        "|---|---|---|",
        f"| before | {s['rmse_before_w']:.2f} | {s['mape_before_pct']:.2f} |",
        f"| after | {s['rmse_after_w']:.2f} | {s['mape_after_pct']:.2f} |",
        "",
        f"Noise floor (successive differences): {s['noise_floor_w']:.2f} W; held-out RMSE after "
        f"= {s['rmse_to_floor']:.1f} × the floor, {100 * s['unexplained_share']:.0f} % of the "
        "remaining variance above it.",
        "",
        f"**{s['attribution']['verdict']}**",
        "",
        "## Selected effects",
        "",
    ]
    if s["effects"]:
        lines += [
            "| order | effect (values, when) | parameters | ±1σ over folds | RMSE after (W) | z "
            "| as good held out (RMSE W, z) |",
            "|---|---|---|---|---|---|---|",
        ]
        for i, e in enumerate(s["effects"], 1):
            params = ", ".join(f"{k} = {v}" for k, v in e["params"].items())
            spread = ", ".join(f"{k} {v}" for k, v in e["params_fold_sd"].items())
            lines.append(
                f"| {i} | {e['description']} | {params} | {spread} | {e['rmse_after_w']:.2f} | "
                f"{e['z']:.1f} | "
                + ", ".join(
                    f"{t['candidate']} ({t['rmse_w']:.2f}, {t['z']:.1f})"
                    for t in e["indistinguishable_from"]
                )
                + " |"
            )
    else:
        lines.append("None.")
    lines += [
        "",
        "## Selection table (every candidate at every step, held-out)",
        "",
        "| step | candidate | RMSE (W) | gain (%) | z | qualifies | parameters (middle fold) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in s["selection"]:
        params = ", ".join(f"{k} = {v}" for k, v in row["params"].items())
        verdict = "yes" if row["qualifies"] else "no"
        if not row["within_reach"]:
            verdict = "no: a wind beyond the vehicle's airspeed"
        lines.append(
            f"| {row['step']} | {row['candidate']} | {row['rmse_w']:.2f} | {row['gain_pct']:.2f} "
            f"| {row['z']:.2f} | {verdict} | {params} |"
        )
    lines += [
        "",
        "## Attribution (held-out R² of the residual from one channel)",
        "",
        "| channel | before | after |",
        "|---|---|---|",
    ]
    after = {c["channel"]: c["r2"] for c in s["attribution"]["channels"]}
    for c in s["attribution"]["channels_before"]:
        lines.append(
            f"| {c['channel']} | {c['r2']:.3f} | {after.get(c['channel'], float('nan')):.3f} |"
        )
    lines.append("")
    lines += [f"![{f.stem}]({f.name})" for f in files]
    lines.append("")
    return "\n".join(lines)
