"""``uav-energy fit LOG...``: fit the power model to flight logs and validate it held-out.

Reads tlogs / CMU CSVs (format by content), applies the paper's preprocessing, fits eq. (2)
with standard errors, scores theory / polynomial / network on held-out flights, and optionally
writes a vehicle file (``--out``), a report (``--report``) and a JSON summary (``--json``).
With ``--capacity-ah``, logs with a rest and a long discharge also give the pack's resistance
and resting curve (:mod:`estimator.analysis.pack_fit`), written into the vehicle file.
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
from estimator.analysis.pack_fit import PackFit, fit_pack
from estimator.analysis.theory_fit import Priors
from estimator.errors import UserError
from estimator.logs import FORMATS, FlightSeries, load_flights
from estimator.logs.sanity import flight_warnings
from estimator.physics.effects import Heave
from estimator.physics.vehicle import CHEMISTRIES, SLOW_ERROR_RANGE, BatterySpec, Vehicle

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
    v.add_argument(
        "--capacity-ah",
        type=float,
        help="the pack's capacity (also the charge axis of its fitted resting curve)",
    )
    v.add_argument(
        "--chemistry",
        default="lipo",
        choices=CHEMISTRIES,
        help="the pack's chemistry: its full voltage and typical curve beyond the fitted one",
    )
    v.add_argument("--cells", type=int, help="series cells (default: from the peak voltage)")
    v.add_argument("--reserve-fraction", type=float, default=0.2)
    v.add_argument(
        "--slow-error-fraction",
        type=float,
        help="1σ of the model's error that stays correlated over tens of seconds, as a "
        "fraction of its hover power (the online tracker's; default: not stated)",
    )
    v.add_argument(
        "--heave-gain",
        type=float,
        help="state the heave effect (the thrust of a vertical acceleration) with this gain; "
        "1 is eq. (2)'s rotor, whose profile power does not follow the thrust (default: not "
        "stated)",
    )
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
        status.update("fitting the pack")
        pack, pack_notes = _fit_pack(flights, args)
        if args.report is not None:
            from estimator.reports.fit_report import write_report

            status.update("writing the report")
            title = args.title or f"Power model fit: {_describe(args.logs)}"
            write_report(report, args.report, title, pack)
    for line in pack_lines(pack, pack_notes):
        console.print(f"uav-energy fit: {line}", highlight=False, soft_wrap=True, markup=False)
    if args.out is not None:
        _save_vehicle(
            _vehicle(report, flights, args, pack),
            args.out,
            [*args.note, *pack_note(pack, args.chemistry)],
        )
    summary = report.summary()
    summary["pack"] = None if pack is None else pack.summary()
    summary["pack_left_out"] = pack_notes
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
    slow = args.slow_error_fraction
    low, high = SLOW_ERROR_RANGE
    if slow is not None and not (math.isfinite(slow) and low <= slow <= high):
        raise UserError(f"--slow-error-fraction must be between {low:g} and {high:g}")
    heave = args.heave_gain
    low, high = Heave.bounds["gain"]
    if heave is not None and not (math.isfinite(heave) and low <= heave <= high):
        raise UserError(f"--heave-gain must be between {low:g} and {high:g}")
    if not 0.0 <= args.reserve_fraction < 1.0:
        raise UserError("--reserve-fraction must be in [0, 1)")
    if args.out is not None and (args.mass_kg is None or args.capacity_ah is None):
        raise UserError("--out needs --mass-kg and --capacity-ah (logs do not record them)")
    if args.out is not None and not args.out.parent.is_dir():
        raise UserError(f"--out {args.out}: folder {args.out.parent} does not exist")


def _flight_masses(flights: list[FlightSeries], mass_kg: float | None) -> np.ndarray | None:
    """Per-flight take-off mass: vehicle mass plus the payload column, if the logs have one."""
    if mass_kg is None or not any("payload_kg" in f.extras for f in flights):
        return None
    return np.array(
        [mass_kg + float(np.nanmedian(f.extras.get("payload_kg", np.zeros(1)))) for f in flights]
    )


def _fit_pack(
    flights: list[FlightSeries], args: argparse.Namespace
) -> tuple[PackFit | None, list[str]]:
    """The pack's fit when the logs can give it (with ``--capacity-ah`` and a pack voltage),
    and the notes on what was left out."""
    if args.capacity_ah is None:
        return None, ["its charge axis needs --capacity-ah"]
    if args.cells is None and not any(np.isfinite(f.voltage_v).any() for f in flights):
        return None, ["the logs have no pack voltage"]
    return fit_pack(flights, _cells(flights, args.cells), args.capacity_ah, args.chemistry)


def _cells(flights: list[FlightSeries], cells: int | None) -> int:
    """Series cells: ``cells`` (``--cells``), else from the flights' peak voltage."""
    if cells is not None:
        return cells
    peaks = [
        float(np.nanpercentile(f.voltage_v, 99)) for f in flights if np.isfinite(f.voltage_v).any()
    ]
    if not peaks:
        raise UserError("the logs have no pack voltage: give --cells")
    # the typical flight's near-peak voltage: robust to one glitching sensor or log
    return max(1, math.ceil(float(np.median(peaks)) / MAX_CELL_VOLTAGE_V))


def _vehicle(
    report: FitReport, flights: list[FlightSeries], args: argparse.Namespace, pack: PackFit | None
) -> Vehicle:
    curve = None if pack is None or pack.cell_ocv_v is None else pack.cell_ocv_v
    resistance_ohm = None if pack is None or pack.resistance_ohm <= 0 else pack.resistance_ohm
    battery = BatterySpec(
        args.capacity_ah,
        _cells(flights, args.cells),
        args.reserve_fraction,
        cell_ocv_v=None if curve is None else tuple(float(v) for v in curve),
        chemistry=args.chemistry,
        internal_resistance_ohm=resistance_ohm,
    )
    return Vehicle(
        name=args.name or args.logs[0].stem,
        mass_kg=args.mass_kg,
        model=report.theory.model,
        battery=battery,
        model_stderr=dict(report.theory.coeff_stderr),
        slow_error_fraction=args.slow_error_fraction,
        effects={} if args.heave_gain is None else {Heave.name: {"gain": args.heave_gain}},
    )


def _save_vehicle(vehicle: Vehicle, path: Path, notes: list[str]) -> None:
    """Write the vehicle file with ``notes`` as leading TOML comments (sources, assumptions)."""
    header = "".join(f"# {line}\n" for line in notes)
    path.write_text(header + tomli_w.dumps(vehicle.to_toml()))


def _describe(paths: list[Path]) -> str:
    return paths[0].name if len(paths) == 1 else f"{len(paths)} logs"


def pack_note(pack: PackFit | None, chemistry: str) -> list[str]:
    """The vehicle file's comment on a fitted curve: where it was fitted, what fills the rest."""
    if pack is None or pack.fitted_soc is None or pack.sigma_v is None:
        return []
    lo, hi = (100 * s for s in pack.fitted_soc)
    return [
        f"[battery] cell_ocv_v fitted by uav-energy fit from {lo:.0f} to {hi:.0f} % charge "
        f"(RMS residual {1000 * pack.sigma_v:.1f} mV/cell: the readings' noise, not the "
        "curve's error, so cell_ocv_sigma_v is left to its default); beyond, the "
        f"{chemistry} typical curve shifted to join it",
    ]


def pack_lines(pack: PackFit | None, notes: list[str], shown: int = 3) -> list[str]:
    """What the pack fit gave, and the first ``shown`` notes on what it left out (one line
    each; ``--json`` has them all)."""
    lines = [f"pack: {note}" for note in notes[:shown]]
    if len(notes) > shown:
        lines.append(f"pack: … and {len(notes) - shown} more (--json lists them)")
    if pack is None:
        lines.append("pack: not fitted (the power model is)")
        return lines
    curve = (
        ""
        if pack.fitted_soc is None or pack.sigma_v is None
        else f"; resting curve fitted from {100 * pack.fitted_soc[0]:.0f} to "
        f"{100 * pack.fitted_soc[1]:.0f} % charge, σ {1000 * pack.sigma_v:.1f} mV/cell"
    )
    lines.append(
        f"pack: {1000 * pack.resistance_ohm:.1f} mΩ from {len(pack.flights)} flight(s){curve}"
    )
    return lines


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
