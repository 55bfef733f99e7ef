"""``uav-energy experiments``: the seed paper's two experiments, reproduced on the built-in vehicle.

A thin front end to :func:`estimator.sim.experiments.reproduce`: generate experiment 1
(straight-and-level, 0–14 m/s) and experiment 2 (circles, 1–6 m/s, r = 10 and 20 m), fit on
experiment 1, predict experiment 2 with eq. (2), write a report, print a summary.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.table import Table

from estimator.sim.experiments import reproduce


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "experiments",
        description="Generate the paper's experiments 1 and 2 for the built-in 3 kg quadrotor, "
        "fit on experiment 1, predict experiment 2 with eq. (2), write a report.",
    )
    p.add_argument("--out", type=Path, default=Path("out/experiments"), help="report directory")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    err = Console(stderr=True)
    with err.status("starting") as status:
        result = reproduce(args.out, seed=args.seed, progress=status.update)
    truth, fitted = result.vehicle.model, result.fit.theory.model
    console = Console()
    table = Table(title="Experiment 1 (fit) — held-out by flight")
    for col in ("model", "RMSE (W)", "MAPE (%)"):
        table.add_column(col)
    for name, s in result.fit.scores.items():
        table.add_row(name, f"{s.rmse_w:.1f}", f"{s.mape_pct:.2f}")
    console.print(table)
    console.print(
        f"fitted hover {fitted.hover_power_w:.1f} W (truth {truth.hover_power_w:.1f}), "
        f"V_me {fitted.max_endurance_speed_mps():.2f} m/s "
        f"(truth {truth.max_endurance_speed_mps():.2f}), "
        f"V_mr {fitted.max_range_speed_mps():.2f} m/s (truth {truth.max_range_speed_mps():.2f})"
    )
    circles = Table(title="Experiment 2 (circles) predicted with eq. (2)")
    for col in ("r (m)", "V (m/s)", "measured (W)", "eq. (2) (W)", "eq. (1) (W)"):
        circles.add_column(col)
    pairs = sorted(
        zip(result.circles, result.radii_m, strict=True), key=lambda x: (x[1], x[0].speed_mps)
    )
    for c, r in pairs:
        circles.add_row(
            f"{r:.0f}",
            f"{c.speed_mps:.1f}",
            f"{c.measured_w:.1f}",
            f"{c.eq2_w:.1f}",
            f"{c.eq1_w:.1f}",
        )
    console.print(circles)
    err.print(f"report written to {args.out}/summary.md")
    return 0
