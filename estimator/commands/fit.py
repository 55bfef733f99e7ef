"""``uav-energy fit LOG...``: fit the power model to flight logs and validate it held-out.

Reads tlogs / CMU CSVs (format by content), applies the paper's preprocessing, fits eq. (2)
with standard errors, scores theory / polynomial / network on held-out flights, and optionally
writes a vehicle file (``--out``), a report (``--report``) and a JSON summary (``--json``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
from rich.console import Console

from estimator.analysis.fit import FitOptions, FitReport, fit_all
from estimator.analysis.fit_points import PreprocessOptions, preprocess
from estimator.analysis.theory_fit import Priors
from estimator.errors import UserError
from estimator.logs import FORMATS, FlightSeries, load_flights
from estimator.logs.sanity import flight_warnings
from estimator.physics.vehicle import BatterySpec, Vehicle

#: Highest per-cell voltage of a charged LiPo under light load, V (for inferring the cell count).
MAX_CELL_VOLTAGE_V = 4.25


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    d = PreprocessOptions()
    p = subparsers.add_parser(
        "fit",
        description="Fit c1..c5 of the power model to logs, with standard errors and held-out "
        "errors of the theory, a polynomial and a neural network.",
    )
    p.add_argument("logs", nargs="+", type=Path, metavar="LOG", help="tlog / CMU CSV files")
    p.add_argument("--format", default="auto", choices=("auto", *FORMATS))
    p.add_argument("--out", type=Path, metavar="FILE.toml", help="write a vehicle file")
    p.add_argument("--report", type=Path, metavar="DIR", help="write PNG plots and summary.md")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    p.add_argument("--title", default=None, help="title of the report")
    p.add_argument(
        "--jobs",
        type=int,
        default=os.cpu_count() or 1,
        metavar="N",
        help="processes reading the logs (default: the number of CPUs)",
    )
    v = p.add_argument_group("vehicle file (--out)")
    v.add_argument("--name", default=None, help="vehicle name (default: first log's name)")
    v.add_argument(
        "--mass-kg",
        type=float,
        help="take-off mass without payload; with payload columns (CMU) the model is "
        "fitted for this mass and each flight is rescaled to mass + payload",
    )
    v.add_argument("--capacity-ah", type=float, help="rated battery capacity")
    v.add_argument("--cells", type=int, help="series cells (default: from the peak voltage)")
    v.add_argument("--reserve-fraction", type=float, default=0.2)
    v.add_argument(
        "--note", action="append", default=[], help="comment line at the top of the file"
    )
    g = p.add_argument_group("preprocessing (the paper's values are the defaults)")
    g.add_argument("--rate-hz", type=float, default=d.sample_rate_hz, help="resampling rate")
    g.add_argument("--max-accel", type=float, default=d.max_accel_mps2, help="|a| limit, m/s²")
    g.add_argument("--min-alt", type=float, default=d.min_alt_m, help="ground below this, m")
    g.add_argument(
        "--max-vz", type=float, default=d.max_vertical_speed_mps, help="level-flight |v_z| limit"
    )
    g.add_argument(
        "--trim-s", type=float, default=d.edge_trim_s, help="cut after take-off/before landing"
    )
    g.add_argument(
        "--max-gap-s", type=float, default=d.max_gap_s, help="no interpolation across gaps"
    )
    m = p.add_argument_group("models and validation")
    m.add_argument("--degree", type=int, default=3, help="polynomial degree")
    m.add_argument("--folds", type=int, default=5)
    m.add_argument("--split", default="auto", choices=("auto", "flight", "block"))
    m.add_argument("--no-priors", action="store_true", help="fit the data alone (ill-conditioned)")
    m.add_argument("--seed", type=int, default=0, help="network initialisation")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    console = Console(stderr=True)
    _check_args(args)
    with console.status("reading logs") as status:
        flights = load_flights(args.logs, args.format, workers=args.jobs)
        for warning in flight_warnings(flights, args.cells):
            console.print(
                f"uav-energy fit: warning: {warning}", highlight=False, soft_wrap=True, markup=False
            )
        options = FitOptions(
            preprocess=PreprocessOptions(
                sample_rate_hz=args.rate_hz,
                max_accel_mps2=args.max_accel,
                min_alt_m=args.min_alt,
                max_vertical_speed_mps=args.max_vz,
                edge_trim_s=args.trim_s,
                max_gap_s=args.max_gap_s,
            ),
            priors=None if args.no_priors else Priors(),
            polynomial_degree=args.degree,
            folds=args.folds,
            split=args.split,
            seed=args.seed,
        )
        mass_kg = _flight_masses(flights, args.mass_kg)
        status.update(f"preprocessing {len(flights)} flights")
        points = preprocess(flights, options.preprocess, mass_kg, args.mass_kg)
        report = fit_all(points, options, progress=lambda msg: status.update(f"fitting: {msg}"))
        if args.report is not None:
            from estimator.reports.fit_report import write_report

            status.update("writing the report")
            title = args.title or f"Power model fit: {_describe(args.logs)}"
            write_report(report, args.report, title)
    if args.out is not None:
        _save_vehicle(_vehicle(report, flights, args), args.out, args.note)
    summary = report.summary()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    if args.out is not None:
        console.print(f"wrote {args.out}")
    if args.report is not None:
        console.print(f"wrote {args.report}/summary.md and plots")
    return 0


def _check_args(args: argparse.Namespace) -> None:
    for name in ("mass_kg", "capacity_ah", "rate_hz", "max_accel", "max_gap_s"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise UserError(f"--{name.replace('_', '-')} must be a positive number")
    if args.folds < 2:
        raise UserError("--folds must be at least 2")
    if args.jobs < 1:
        raise UserError("--jobs must be at least 1")
    if not 0.0 <= args.reserve_fraction < 1.0:
        raise UserError("--reserve-fraction must be in [0, 1)")
    if args.out is not None and (args.mass_kg is None or args.capacity_ah is None):
        raise UserError("--out needs --mass-kg and --capacity-ah (logs do not record them)")


def _flight_masses(flights: list[FlightSeries], mass_kg: float | None) -> np.ndarray | None:
    """Per-flight take-off mass: vehicle mass plus the payload column, if the logs have one."""
    if mass_kg is None or not any("payload_kg" in f.extras for f in flights):
        return None
    return np.array(
        [mass_kg + float(np.nanmedian(f.extras.get("payload_kg", np.zeros(1)))) for f in flights]
    )


def _vehicle(report: FitReport, flights: list[FlightSeries], args: argparse.Namespace) -> Vehicle:
    cells = args.cells
    if cells is None:
        peaks = [
            float(np.nanpercentile(f.voltage_v, 99))
            for f in flights
            if np.isfinite(f.voltage_v).any()
        ]
        if not peaks:
            raise UserError("the logs have no pack voltage: give --cells")
        # the typical flight's near-peak voltage: robust to one glitching sensor or log
        cells = max(1, math.ceil(float(np.median(peaks)) / MAX_CELL_VOLTAGE_V))
    return Vehicle(
        name=args.name or args.logs[0].stem,
        mass_kg=args.mass_kg,
        model=report.theory.model,
        battery=BatterySpec(args.capacity_ah, cells, args.reserve_fraction),
        model_stderr=dict(report.theory.coeff_stderr),
    )


def _save_vehicle(vehicle: Vehicle, path: Path, notes: list[str]) -> None:
    """Write the vehicle file with ``notes`` as leading TOML comments (sources, assumptions)."""
    header = "".join(f"# {line}\n" for line in notes)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + tomli_w.dumps(vehicle.to_toml()))


def _describe(paths: list[Path]) -> str:
    return paths[0].name if len(paths) == 1 else f"{len(paths)} logs"


def format_summary(s: dict[str, Any]) -> str:
    """A few human-readable lines of the fit summary."""
    p, e = s["params"], s["stderr"]
    lines = [
        f"{s['n_points']} points from {s['n_flights']} flights, "
        f"speeds {s['speed_range_mps'][0]:.1f}–{s['speed_range_mps'][1]:.1f} m/s",
        "  " + "  ".join(f"{k}={p[k]:.4g}±{e[k]:.2g}" for k in p),
        f"  hover {s['hover_power_w']:.1f}±{s['hover_power_stderr_w']:.1f} W   "
        f"V_me {s['v_me_mps']:.2f}±{s['v_me_stderr_mps']:.2f} m/s   "
        f"V_mr {s['v_mr_mps']:.2f}±{s['v_mr_stderr_mps']:.2f} m/s",
        f"held-out errors (split by {s['split']}):",
    ]
    for name, m in s["models"].items():
        lines.append(f"  {name:<11} RMSE {m['rmse_w']:7.2f} W   MAPE {m['mape_pct']:6.2f} %")
    return "\n".join(lines)
