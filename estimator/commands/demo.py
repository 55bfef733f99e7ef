"""``uav-energy demo``: the seed paper's two experiments, reproduced on the built-in vehicle.

Generates experiment 1 (straight-and-level, 0–14 m/s) and experiment 2 (circles, 1–6 m/s,
r = 10 and 20 m) with :mod:`estimator.flightgen`, fits the model on experiment 1
(:mod:`estimator.fit`), predicts experiment 2 with eq. (2), and writes a report.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from estimator import flightgen
from estimator.fit import check_flights, fit_all, preprocess
from estimator.fit_report import circles_figure, circles_markdown, save_figure, write_report
from estimator.vehicle import default_vehicle


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "demo",
        help="reproduce the paper's experiments on the built-in vehicle",
        description="Generate the paper's experiments 1 and 2 for the built-in 3 kg quadrotor, "
        "fit on experiment 1, predict experiment 2 with eq. (2), write a report.",
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="report directory")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    err = Console(stderr=True)
    vehicle = default_vehicle()
    truth = vehicle.model
    with err.status("generating experiments 1 and 2") as status:
        exp1 = flightgen.experiment1(truth, vehicle.mass_kg, seed=args.seed)
        exp2 = flightgen.experiment2(truth, vehicle.mass_kg, seed=args.seed + 1)
        status.update("fitting experiment 1")
        report = fit_all(preprocess(exp1), progress=lambda m: status.update(f"experiment 1: {m}"))
        status.update("predicting experiment 2 and writing the report")
        checks = check_flights(report.theory, preprocess(exp2), min_speed_mps=0.5)
        radii = {f.flight_id: float(f.extras["radius_m"][0]) for f in exp2}
        radius_of = [radii[c.flight_id] for c in checks]
        write_report(
            report, args.out / "experiment1", "Experiment 1 (generated): straight and level"
        )
        save_figure(
            circles_figure(report.theory.model, checks, radius_of), args.out / "experiment2.png"
        )
        fitted = report.theory.model
        v = np.arange(0.0, 15.0, 2.0)
        rows = {
            "truth (W)": truth.power_w(v),
            "fitted (W)": fitted.power_w(v),
            "1σ (W)": report.theory.curve_stderr_w(v),
        }
        curve_table = "\n".join(
            ["| V (m/s) | " + " | ".join(f"{x:.0f}" for x in v) + " |", "|---" * (len(v) + 1) + "|"]
            + [
                f"| {name} | " + " | ".join(f"{x:.1f}" for x in r) + " |"
                for name, r in rows.items()
            ]
        )
        (args.out / "summary.md").write_text(
            "# Demo: the seed paper's experiments on the built-in vehicle\n\n"
            f"Truth: `{truth}` ({vehicle.name}, {vehicle.mass_kg} kg).\n\n"
            "## Experiment 1: fit\n\nSee [experiment1/summary.md](experiment1/summary.md).\n\n"
            f"{curve_table}\n\n"
            "## Experiment 2: circles predicted with eq. (2)\n\n"
            + circles_markdown(checks, radius_of)
            + "\n![experiment 2](experiment2.png)\n"
        )
    table = Table(title="Experiment 1 (fit) — held-out by flight")
    for col in ("model", "RMSE (W)", "MAPE (%)"):
        table.add_column(col)
    for name, s in report.scores.items():
        table.add_row(name, f"{s.rmse_w:.1f}", f"{s.mape_pct:.2f}")
    console = Console()
    console.print(table)
    console.print(
        f"fitted hover {fitted.hover_power_w:.1f} W (truth {truth.hover_power_w:.1f}), "
        f"V_me {fitted.max_endurance_speed_mps():.2f} m/s "
        f"(truth {truth.max_endurance_speed_mps():.2f}), "
        f"V_mr {fitted.max_range_speed_mps():.2f} m/s (truth {truth.max_range_speed_mps():.2f})"
    )
    t2 = Table(title="Experiment 2 (circles) predicted with eq. (2)")
    for col in ("r (m)", "V (m/s)", "measured (W)", "eq. (2) (W)", "eq. (1) (W)"):
        t2.add_column(col)
    for c, r in sorted(zip(checks, radius_of, strict=True), key=lambda x: (x[1], x[0].speed_mps)):
        t2.add_row(
            f"{r:.0f}",
            f"{c.speed_mps:.1f}",
            f"{c.measured_w:.1f}",
            f"{c.eq2_w:.1f}",
            f"{c.eq1_w:.1f}",
        )
    console.print(t2)
    err.print(f"report written to {args.out}/summary.md")
    return 0
