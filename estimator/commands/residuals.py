"""``uav-energy residuals LOG... --vehicle FILE.toml``: find what the model lacks.

Computes the residual (measured − model power) over the whole flight, tries the candidate
effects with held-out scoring and greedy forward selection (:mod:`estimator.analysis.residuals`),
points at the telemetry channel that best predicts what is left, and optionally writes the
vehicle file with the chosen effects (``--write``), a report (``--report``) and JSON
(``--json``). Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console

from estimator.analysis.residual_samples import ResidualOptions
from estimator.analysis.residuals import ResidualResult, analyze
from estimator.analysis.tracker_truth import track_samples
from estimator.errors import UserError
from estimator.logs import FORMATS, FlightSeries, load_flights
from estimator.logs.sanity import flight_warnings
from estimator.logs.series_samples import series_samples
from estimator.physics.effect_tables import effects_to_tables
from estimator.physics.effects import EFFECT_TYPES, wind_from_deg
from estimator.physics.vehicle import Vehicle, load_vehicle
from estimator.telemetry.plausibility import NOMINAL_CELL_VOLTAGE_V


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    d = ResidualOptions()
    p = subparsers.add_parser(
        "residuals",
        description="Residual analysis: measured minus model power over whole flights, "
        "candidate effects fitted on some time blocks and scored on others, greedy forward "
        "selection while the held-out error drops by more than chance.",
    )
    p.add_argument("logs", nargs="+", type=Path, metavar="LOG", help="tlog / CMU CSV / .bin / .ulg")
    p.add_argument("--vehicle", required=True, type=Path, metavar="FILE.toml")
    p.add_argument("--format", default="auto", choices=("auto", *FORMATS))
    p.add_argument("--report", type=Path, metavar="DIR", help="write PNG plots and summary.md")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    p.add_argument(
        "--write", type=Path, metavar="FILE.toml", help="save the vehicle with the chosen effects"
    )
    g = p.add_argument_group("selection")
    g.add_argument("--folds", type=int, default=d.folds, help="held-out folds")
    g.add_argument(
        "--chunk-s", type=float, default=d.chunk_s, help="held-out chunk length, s (in turn)"
    )
    g.add_argument("--block-s", type=float, default=d.block_s, help="test block length, s")
    g.add_argument("--guard-s", type=float, default=d.guard_s, help="gap around held-out, s")
    g.add_argument("--z", type=float, default=d.z_threshold, help="test threshold (z)")
    g.add_argument(
        "--min-gain", type=float, default=100 * d.min_gain_fraction, help="min RMSE gain, %%"
    )
    g.add_argument(
        "--candidates",
        default=",".join(EFFECT_TYPES),
        help="comma-separated effect names to try (default: all)",
    )
    g.add_argument("--min-alt", type=float, default=d.min_alt_m, help="airborne above this, m")
    p.add_argument(
        "--flight",
        action="append",
        default=[],
        metavar="ID",
        help="analyse only this flight (repeatable; ids as in the output's 'flights')",
    )
    p.add_argument(
        "--online",
        action="store_true",
        help="also run the daemon's online wind/mass tracker over each flight, starting from "
        "the given vehicle file (an independent check), and report its final estimate",
    )
    p.set_defaults(func=run)


def _options(args: argparse.Namespace) -> ResidualOptions:
    if args.folds < 2:
        raise UserError("--folds must be at least 2")
    for name in ("block_s", "z"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise UserError(f"--{name.replace('_', '-')} must be a positive number")
    if not (math.isfinite(args.guard_s) and args.guard_s >= 0):
        raise UserError("--guard-s must be a number ≥ 0")
    if not (math.isfinite(args.min_gain) and 0 <= args.min_gain < 100):
        raise UserError("--min-gain must be a percentage in [0, 100)")
    names = tuple(n.strip() for n in args.candidates.split(",") if n.strip())
    unknown = [n for n in names if n not in EFFECT_TYPES]
    if unknown or not names:
        raise UserError(
            f"--candidates: unknown effect(s) {', '.join(unknown) or '(none given)'} "
            f"(known: {', '.join(EFFECT_TYPES)})"
        )
    return ResidualOptions(
        folds=args.folds,
        chunk_s=args.chunk_s,
        block_s=args.block_s,
        guard_s=args.guard_s,
        z_threshold=args.z,
        min_gain_fraction=args.min_gain / 100.0,
        min_alt_m=args.min_alt,
        candidates=names,
    )


def with_effects(
    vehicle: Vehicle, result: ResidualResult, console: Console | None = None
) -> Vehicle:
    """``vehicle`` with the selected effects added to its ``[effects.NAME]`` tables. A vehicle
    file holds one table per effect: a second window of the same effect is left out (with a
    warning on ``console``); the autopilot's reported wind is written as its first steady
    wind."""
    tables = dict(vehicle.effects)
    first: dict[str, Any] = {}
    for effect in result.steady_effects:
        if effect.name in first:
            if console is not None:
                console.print(f"--write: a second {effect.name} window is not written")
            continue
        first[effect.name] = effect
    for name, params in effects_to_tables(list(first.values())).items():
        # six significant digits: far below the parameters' uncertainty, readable files
        tables[name] = {
            k: (v if v is None else float(f"{float(v):.6g}")) for k, v in params.items()
        }
    return dataclasses.replace(vehicle, effects=tables)


def run(args: argparse.Namespace) -> int:
    console = Console(stderr=True)
    options = _options(args)
    vehicle = load_vehicle(args.vehicle)
    if args.write is not None and args.write.is_dir():
        raise UserError(f"--write {args.write} is a directory")
    with console.status("reading logs") as status:
        flights = _select(load_flights(args.logs, args.format), args.flight)
        for warning in flight_warnings(flights, vehicle.battery.cells):
            console.print(
                f"uav-energy residuals: warning: {warning}",
                highlight=False,
                soft_wrap=True,
                markup=False,
            )
        status.update(f"analysing {len(flights)} flight(s)")
        result = analyze(
            flights, vehicle, options, progress=lambda m: status.update(f"residuals: {m}")
        )
        if args.report is not None:
            from estimator.reports.residuals_report import write_report

            status.update("writing the report")
            write_report(result, args.report, _title(args.logs, vehicle))
    summary = result.summary()
    improved = with_effects(vehicle, result, console if args.write is not None else None)
    if args.online:
        with console.status("online tracking"):
            summary["online"] = online_summary(flights, vehicle)
    if args.write is not None:
        improved.save(args.write)
    if args.json:
        print(json.dumps(summary, indent=2), flush=True)
    else:
        print(format_summary(summary), flush=True)
    if args.write is not None:
        console.print(f"wrote {args.write}")
    if args.report is not None:
        console.print(f"wrote {args.report}/summary.md and plots")
    return 0


def _select(flights: list[FlightSeries], ids: list[str]) -> list[FlightSeries]:
    if not ids:
        return flights
    chosen = [f for f in flights if f.flight_id in ids]
    missing = sorted(set(ids) - {f.flight_id for f in chosen})
    if missing:
        known = ", ".join(f.flight_id for f in flights)
        raise UserError(f"--flight {', '.join(missing)} not in the logs (flights: {known})")
    return chosen


def online_summary(flights: list[FlightSeries], vehicle: Vehicle) -> list[dict[str, Any]]:
    """Per flight, the online tracker's final wind and mass and their medians over the second
    half of its steps: each flight fed to the daemon's pipeline (started from ``vehicle``) as
    the samples of its rows (:func:`~estimator.logs.series_samples.series_samples`; where the
    log has power only, at the pack's nominal voltage), the tracker read after each step."""
    nominal_v = vehicle.battery.cells * NOMINAL_CELL_VOLTAGE_V
    out = []
    for flight in flights:
        samples = series_samples(flight, nominal_v)
        run = track_samples(flight.flight_id, samples, vehicle)
        if not len(run.time_s):
            continue
        wind_n, wind_e, mass_kg = run.estimate[-1]
        late = run.estimate[len(run.time_s) // 2 :]
        late_n, late_e = float(np.median(late[:, 0])), float(np.median(late[:, 1]))
        out.append(
            {
                "flight": flight.flight_id,
                "steps": len(run.time_s),
                "wind_speed_mps": round(math.hypot(wind_n, wind_e), 3),
                "wind_from_deg": round(float(wind_from_deg(wind_n, wind_e)), 1),
                "mass_delta_kg": round(float(mass_kg), 4),
                "mass_sigma_kg": round(float(run.sigma[-1, 2]), 4),
                "late_median": {
                    "wind_speed_mps": round(math.hypot(late_n, late_e), 3),
                    "wind_from_deg": round(float(wind_from_deg(late_n, late_e)), 1),
                    "mass_delta_kg": round(float(np.median(late[:, 2])), 4),
                },
            }
        )
    return out


def _title(paths: list[Path], vehicle: Vehicle) -> str:
    logs = paths[0].name if len(paths) == 1 else f"{len(paths)} logs"
    return f"Residuals: {logs} against {vehicle.name}"


def format_summary(s: dict[str, Any]) -> str:
    """Human-readable lines of the summary."""
    lines = [
        f"{s['n_samples']} airborne samples from {s['n_flights']} flight(s); held-out: "
        f"{s['split']}",
        f"  before: RMSE {s['rmse_before_w']:.2f} W  MAPE {s['mape_before_pct']:.2f} %",
        f"  after:  RMSE {s['rmse_after_w']:.2f} W  MAPE {s['mape_after_pct']:.2f} %   "
        f"(noise floor ≈ {s['noise_floor_w']:.2f} W, ×{s['rmse_to_floor']:.1f})",
    ]
    if not s["effects"]:
        lines.append("  effects: none")
    for e in s["effects"]:
        lines.append(f"  + {e['description']}  → RMSE {e['rmse_after_w']:.2f} W (z {e['z']:.1f})")
        for t in e["indistinguishable_from"]:
            lines.append(f"      as good held out: {t['candidate']} (RMSE {t['rmse_w']:.2f} W)")
    lines.append(s["attribution"]["verdict"])
    for o in s.get("online", []):
        lines.append(
            f"  online {o['flight']}: final wind {o['wind_speed_mps']:.1f} m/s from "
            f"{o['wind_from_deg']:.0f}°, mass {o['mass_delta_kg']:+.3f} ± "
            f"{o['mass_sigma_kg']:.3f} kg; second-half median mass "
            f"{o['late_median']['mass_delta_kg']:+.3f} kg"
        )
    return "\n".join(lines)
