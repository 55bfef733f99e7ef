"""The seed paper's two experiments, reproduced on generated flights (offline, ~10 s).

Experiment 1 (straight and level, 0–14 m/s) is generated from a vehicle's model, fitted with
:mod:`estimator.analysis.fit` and scored held-out; experiment 2 (circles, 1–6 m/s, r = 10 and 20 m)
is
predicted with eq. (2) from that fit. :func:`reproduce` writes the report; run it as
``uav-energy experiments [--out DIR] [--seed N]``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from estimator.analysis.fit import FitReport, FlightCheck, check_flights, fit_all
from estimator.analysis.fit_points import preprocess
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.reports.fit_report import circles_figure, circles_markdown, save_figure, write_report
from estimator.sim import flightgen


@dataclass
class Experiments:
    """Experiment 1's fit and experiment 2's per-circle checks (with each circle's radius)."""

    vehicle: Vehicle
    fit: FitReport
    circles: list[FlightCheck]
    radii_m: list[float]


def reproduce(
    out_dir: Path,
    vehicle: Vehicle | None = None,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> Experiments:
    """Generate, fit, predict, and write ``out_dir/summary.md`` with plots."""
    say = progress or (lambda _msg: None)
    vehicle = vehicle or default_vehicle()
    truth = vehicle.model
    say("generating experiments 1 and 2")
    exp1 = flightgen.experiment1(truth, vehicle.mass_kg, seed=seed)
    exp2 = flightgen.experiment2(truth, vehicle.mass_kg, seed=seed + 1)
    say("fitting experiment 1")
    report = fit_all(preprocess(exp1), progress=lambda m: say(f"experiment 1: {m}"))
    say("predicting experiment 2 and writing the report")
    checks = check_flights(report.theory, preprocess(exp2), min_speed_mps=0.5)
    radius_of_flight = {f.flight_id: float(f.extras["radius_m"][0]) for f in exp2}
    radii = [radius_of_flight[c.flight_id] for c in checks]
    write_report(report, out_dir / "experiment1", "Experiment 1 (generated): straight and level")
    save_figure(circles_figure(report.theory.model, checks, radii), out_dir / "experiment2.png")
    result = Experiments(vehicle, report, checks, radii)
    (out_dir / "summary.md").write_text(summary_markdown(result))
    return result


def curve_table(result: Experiments) -> str:
    """Experiment 1's fitted power curve against the truth, with its 1σ (W), every 2 m/s."""
    truth, fitted = result.vehicle.model, result.fit.theory.model
    v = np.arange(0.0, 15.0, 2.0)
    rows = {
        "truth (W)": truth.power_w(v),
        "fitted (W)": fitted.power_w(v),
        "1σ (W)": result.fit.theory.curve_stderr_w(v),
    }
    table = [
        "| V (m/s) | " + " | ".join(f"{x:.0f}" for x in v) + " |",
        "|---" * (len(v) + 1) + "|",
    ] + [f"| {name} | " + " | ".join(f"{x:.1f}" for x in r) + " |" for name, r in rows.items()]
    return "\n".join(table)


def summary_markdown(result: Experiments) -> str:
    truth = result.vehicle.model
    return (
        "# The seed paper's experiments on generated flights\n\n"
        f"Truth: `{truth}` ({result.vehicle.name}, {result.vehicle.mass_kg} kg).\n\n"
        "## Experiment 1: fit\n\nSee [experiment1/summary.md](experiment1/summary.md).\n\n"
        + curve_table(result)
        + "\n\n## Experiment 2: circles predicted with eq. (2)\n\n"
        + circles_markdown(result.circles, result.radii_m)
        + "\n![experiment 2](experiment2.png)\n"
    )
