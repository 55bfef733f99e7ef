"""``uav-energy fleet {replay,fit,residuals} PATH|GLOB… [--scheduler tcp://HOST:8786]
[--workers N] [--out results.parquet] [--vehicle F] [--report DIR]`` and
``uav-energy fleet trends results.parquet --report DIR [--since DAY] [--until DAY]``.

Many logs on a dask.distributed cluster (:mod:`estimator.analysis.fleet`): a LocalCluster of
``--workers`` processes by default, or the scheduler at ``--scheduler``. One Parquet row per
log; a log that fails is a row with its reason (listed on stderr), never a stopped run; logs
whose content hash is already in ``--out`` for the same mode are skipped (resume). A
progress bar shows on a terminal (stderr); the counts go to stdout. ``--report DIR`` (or
``fleet trends``) writes the per-vehicle and per-pack trends across dates with a plot.
The logs' sanity warnings against the vehicle file (a pack of other cells, a vertical
velocity the wrong way up) go to stderr once per cause, with how many more logs they hold for.
"""

from __future__ import annotations

import argparse
import os
import sys
from datetime import date
from pathlib import Path
from typing import Any

from rich.console import Console

from estimator.analysis.fleet_flight import MODES
from estimator.commands.progress import logs_progress
from estimator.errors import naming
from estimator.logs.sanity import RunWarnings

DEFAULT_OUT = Path("results.parquet")


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "fleet",
        description="Run replay, fit or residuals over many logs on a dask cluster, one "
        "Parquet row per log; trends per vehicle and pack across dates.",
    )
    modes = parser.add_subparsers(dest="fleet_mode", required=True, metavar="MODE")
    for mode in MODES:
        p = modes.add_parser(mode, help=f"per-log {mode} into a Parquet file")
        p.add_argument("inputs", nargs="+", metavar="PATH|GLOB", help="logs or globs ('**')")
        p.add_argument(
            "--vehicle",
            type=Path,
            metavar="FILE.toml",
            required=mode == "residuals",
            help="vehicle file" + ("" if mode == "residuals" else " (default: built-in)"),
        )
        p.add_argument("--scheduler", metavar="tcp://HOST:8786", help="a running dask scheduler")
        p.add_argument(
            "--workers",
            type=int,
            default=os.cpu_count() or 1,
            metavar="N",
            help="LocalCluster worker processes, one thread each (default: CPU count)",
        )
        p.add_argument(
            "--out", type=Path, default=DEFAULT_OUT, metavar="FILE.parquet", help="results"
        )
        p.add_argument("--retry-failed", action="store_true", help="redo logs that failed in --out")
        p.add_argument("--report", type=Path, metavar="DIR", help="write the trends report")
        p.set_defaults(func=run)
    t = modes.add_parser("trends", help="trends across dates from a results file")
    t.add_argument("results", type=Path, metavar="FILE.parquet")
    t.add_argument("--report", type=Path, required=True, metavar="DIR")
    t.add_argument("--since", type=_day, metavar="YYYY-MM-DD", help="flights from this day")
    t.add_argument("--until", type=_day, metavar="YYYY-MM-DD", help="flights to this day")
    t.set_defaults(func=run_trends)


def run(args: argparse.Namespace) -> int:
    from estimator.analysis.fleet import connect, expand_inputs, run_fleet
    from estimator.analysis.fleet_flight import FleetJob
    from estimator.physics.vehicle import default_vehicle, load_vehicle

    vehicle = default_vehicle() if args.vehicle is None else load_vehicle(args.vehicle)
    paths = expand_inputs(args.inputs)
    job = FleetJob(args.fleet_mode, vehicle)
    console = Console(file=sys.stderr)
    progress = logs_progress(console, f"fleet {args.fleet_mode}")
    task = progress.add_task("logs", total=None)
    said = RunWarnings()  # each cause's warning once per run

    def say(line: str) -> None:
        progress.console.print(
            f"uav-energy fleet: {line}", highlight=False, markup=False, soft_wrap=True
        )

    def on_row(row: dict[str, Any]) -> None:
        progress.advance(task)
        if row["status"] != "ok":
            say(f"failed: {naming(row['path'], row['error'])}")
        for cause, warning in row.get("warnings") or ():
            if said.first(cause):
                say(f"warning: {row['path']}: {warning}")

    with connect(args.scheduler, args.workers) as client, progress:
        workers = len(client.scheduler_info()["workers"])
        counts = run_fleet(
            client,
            paths,
            job,
            args.out,
            args.retry_failed,
            on_total=lambda n: progress.update(task, total=n),
            on_row=on_row,
        )
        for line in said.repeats():
            say(f"warning: {line}")
    print(
        f"fleet {args.fleet_mode}: {counts.logs} logs: {counts.ok} ok, {counts.failed} failed "
        f"({counts.unexpected} unexpected), {counts.already_done} already in {args.out}, "
        f"{counts.duplicates} duplicates; "
        f"{counts.wall_s:.1f} s on {workers} worker(s)",
        flush=True,
    )
    if args.report is not None:
        _report(args.out, args.report)
    return 0


def run_trends(args: argparse.Namespace) -> int:
    from estimator.analysis.fleet_table import read_table
    from estimator.errors import UserError

    if read_table(args.results) is None:
        raise UserError(f"no such file: {args.results}")
    _report(args.results, args.report, args.since, args.until)
    return 0


def _day(text: str) -> date:
    try:
        return date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a date YYYY-MM-DD, got {text!r}") from None


def _report(
    results: Path, directory: Path, since: date | None = None, until: date | None = None
) -> None:
    from estimator.analysis.fleet_table import read_table
    from estimator.analysis.fleet_trends import fleet_trends
    from estimator.reports.fleet_report import write_report

    table = read_table(results)
    assert table is not None  # written by this run or checked by the caller
    trends = fleet_trends(table, since, until)
    write_report(trends, directory, f"Fleet trends: {results.name}")
    for line in trends.lines():
        print(line)
    print(f"wrote {directory}/summary.md and plots", flush=True)
