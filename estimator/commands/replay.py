"""``uav-energy replay LOG... [--vehicle FILE.toml] [--config FILE.toml] [--mission FILE]
[--pack ID] [--pack-dir DIR] [--out CSV] [--report DIR] [--json] [--speed max|N]``: recorded
flights through the daemon's pipeline (:mod:`estimator.analysis.replay`), with the daemon's
settings when given its ``--config`` file. ``--mission`` gives the pipeline the mission the
autopilot flew (a QGC ``.plan`` or ``.waypoints``), as the daemon's download does, for the
MIS_* figures. ``--pack-dir`` keeps the packs' memory as the daemon does
(:mod:`estimator.estimation.pack_identity`), logs in the order given: the pack is ``--pack``,
else the one each log's SMART_BATTERY_INFO serial names.

Output: a table of the power error per flight on stdout (or one JSON object with ``--json``),
the estimates as CSV with ``--out``, plots with ``--report``. A log with a ``truth.json``
beside it flown to the pack's reserve (``uav-energy sitl-record``) has its endurance and σ
scored against the true time left (:mod:`estimator.analysis.endurance_truth`).
``--speed N`` paces the samples at N times the log's own time (``max``, the default, as fast
as possible); pacing happens here, outside the pipeline, so it never changes an estimate. A
progress bar shows on a terminal.
A log with estimates but no airborne time says why on stderr
(:func:`~estimator.analysis.replay.no_airborne_reason`: what it lacks, the message types it
has). With several logs, one that cannot be read is reported and skipped
(``logs_skipped``); with a single log, or when none can be read, the error ends the command
(exit 2).
"""

from __future__ import annotations

import argparse
import csv
import gc
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import fields
from itertools import chain
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import (
    Progress,
    TaskID,
)
from rich.table import Table

from estimator.analysis.endurance_truth import coverage_json, score_replays
from estimator.analysis.replay import (
    FlightReplay,
    Summary,
    no_airborne_reason,
    replay_stream,
    summarize,
)
from estimator.commands.progress import logs_progress
from estimator.errors import UserError, naming
from estimator.estimation.estimate import Estimate
from estimator.estimation.pack_identity import FlightPack
from estimator.estimation.pack_memory import check_pack_id
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.estimation.return_home import MissionSample
from estimator.logs import (
    FORMATS,
    SampleStream,
    battery_window_problem,
    iter_samples,
    suffixed_where_shared,
)
from estimator.logs.mission_files import MissionFile, load_mission
from estimator.logs.sanity import RunWarnings
from estimator.mavlink.config import build_config, load_config_file
from estimator.physics.vehicle import Vehicle, default_vehicle, load_vehicle
from estimator.telemetry.samples import Sample

#: CSV columns, in order; every other Estimate field follows them.
CSV_COLUMNS = (
    "time_s",
    "speed_mps",
    "accel_tangential_mps2",
    "accel_centripetal_mps2",
    "climb_mps",
    "power_measured_w",
    "power_model_w",
    "energy_remaining_wh",
    "energy_remaining_sigma_wh",
    "endurance_s",
    "endurance_sigma_s",
)
_PROGRESS_EVERY = 500
_MIN_SLEEP_S = 0.002
_PIPE_WIDTH = 120
#: Path components kept in a flight's label.
_NAME_PARTS = 3
_LOGS_TASK = TaskID(0)  # the first task of :func:`_progress`


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "replay",
        description="Replay logs (tlog, DataFlash .bin, PX4 .ulg, CMU CSV; format by content) "
        "through the same pipeline the daemon runs, timed by the logs' own stamps.",
    )
    parser.add_argument("logs", nargs="+", type=Path, metavar="LOG", help="log files")
    parser.add_argument(
        "--vehicle", type=Path, metavar="FILE.toml", help="vehicle file (default: built-in)"
    )
    parser.add_argument(
        "--config",
        type=Path,
        metavar="FILE.toml",
        help="the daemon's configuration: its [fusion] settings and [vehicle] file apply",
    )
    parser.add_argument(
        "--format", default="auto", choices=("auto", *FORMATS), help="log format (default: auto)"
    )
    parser.add_argument(
        "--mission",
        type=Path,
        metavar="FILE",
        help="the mission the autopilot flew (.plan or .waypoints), for the MIS_* figures "
        "the daemon computes from its download",
    )
    parser.add_argument(
        "--pack",
        metavar="ID",
        help="the pack flown (needs --pack-dir): each log starts from what the pack's memory "
        "holds and stores what it learnt, logs in the order given",
    )
    parser.add_argument(
        "--pack-dir",
        type=Path,
        metavar="DIR",
        help="the packs' memory (one JSON file a pack); without --pack, each log's pack "
        "serial (SMART_BATTERY_INFO) names its pack",
    )
    parser.add_argument("--out", type=Path, metavar="FILE.csv", help="write every estimate")
    parser.add_argument("--report", type=Path, metavar="DIR", help="write plots and a summary")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--speed",
        type=parse_speed,
        default=None,
        metavar="max|N",
        help="pace at N× log time (default: max, as fast as possible)",
    )
    parser.set_defaults(func=run)


def parse_speed(text: str) -> float | None:
    """``max`` → None (no pacing), else a positive factor of real time."""
    if text.strip().lower() == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'max' or a number, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"speed must be > 0, got {text!r}")
    return value


def paced(samples: Iterable[Sample], speed: float) -> Iterator[Sample]:
    """Yield samples no faster than ``speed`` × their own clock (rebased when it jumps back)."""
    base: tuple[float, float] | None = None  # (wall s, log s)
    last_log_s = -math.inf
    for sample in samples:
        now = time.perf_counter()
        if base is None or sample.time_s < last_log_s:
            base = (now, sample.time_s)
        delay = base[0] + (sample.time_s - base[1]) / speed - now
        if delay > _MIN_SLEEP_S:  # shorter waits are left to the next sample (no drift)
            time.sleep(delay)
        last_log_s = sample.time_s
        yield sample


def run(args: argparse.Namespace) -> int:
    vehicle, settings = vehicle_and_settings(args.vehicle, args.config)
    if args.pack is not None and args.pack_dir is None:
        raise UserError("--pack ID needs --pack-dir DIR")
    if args.pack is not None:
        check_pack_id(args.pack)
    mission = None if args.mission is None else load_mission(args.mission)
    names = flight_names(args.logs)
    console = Console(file=sys.stderr)
    flights: list[FlightReplay] = []
    skipped_logs: list[dict[str, str]] = []
    said = RunWarnings()  # each cause's warning once per run
    gc.freeze()  # modules and codecs loaded so far leave the collector's scans (as the daemon)
    wall_start = time.perf_counter()
    with _progress(console, len(args.logs)) as progress:
        for path, name in zip(args.logs, names, strict=True):
            try:
                flight = _replay_one(path, name, vehicle, settings, mission, args, progress, said)
            except UserError as exc:
                if len(args.logs) == 1:
                    raise
                console.print(
                    f"uav-energy replay: skipped: {naming(path, str(exc))}",
                    highlight=False,
                    soft_wrap=True,
                    markup=False,
                )
                skipped_logs.append({"log": str(path), "error": str(exc)})
                continue
            if not flight.estimates:
                why = flight.missing or "no battery telemetry?"
                console.print(
                    f"uav-energy replay: {path} gave no estimates: {why}",
                    highlight=False,
                    soft_wrap=True,
                )
            flights.append(flight)
    wall_s = time.perf_counter() - wall_start
    for line in said.repeats():
        console.print(f"uav-energy replay: warning: {line}", highlight=False, soft_wrap=True)
    if not flights:
        raise UserError(f"no log could be replayed ({skipped_logs[0]['error']})")
    if args.out is not None:
        write_csv(args.out, flights)
    scored, truth_problems = score_replays(flights)
    for problem in truth_problems:
        console.print(
            f"uav-energy replay: warning: {problem}: endurance not scored",
            highlight=False,
            soft_wrap=True,
            markup=False,
        )
    if args.report is not None:
        from estimator.reports.replay_report import write_report  # matplotlib only when asked

        write_report(flights, args.report, vehicle.name, scored, vehicle.battery.capacity_ah)
    result = result_json(flights, wall_s, vehicle, skipped_logs)
    if scored:
        result["endurance_truth"] = coverage_json(scored)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        _print_table(flights, result, vehicle)
    return 0


def vehicle_and_settings(
    vehicle_path: Path | None, config_path: Path | None
) -> tuple[Vehicle, PipelineSettings]:
    """The vehicle and pipeline settings the daemon would run with: ``--vehicle``, else the
    config file's ``[vehicle] file``, else the built-in; the config's ``[fusion]`` figures
    and ``track_effects``."""
    config = build_config(load_config_file(config_path) if config_path else {}, {})
    settings = config.pipeline_settings()
    if vehicle_path is None and config.vehicle:
        vehicle_path = Path(config.vehicle)
    vehicle = default_vehicle() if vehicle_path is None else load_vehicle(vehicle_path)
    return vehicle, settings


def _replay_one(
    path: Path,
    name: str,
    vehicle: Vehicle,
    settings: PipelineSettings,
    mission: MissionFile | None,
    args: argparse.Namespace,
    progress: Progress,
    said: RunWarnings,
) -> FlightReplay:
    stream = iter_samples(path, args.format, vehicle.input_limits())
    task = progress.add_task(name, total=None)

    def on_sample(n: int) -> None:
        if n % _PROGRESS_EVERY == 0:
            progress.update(task, completed=n)

    samples: Iterable[Sample | MissionSample] = (
        stream if args.speed is None else paced(stream, args.speed)
    )
    mission_energy = None
    if mission is not None:  # the daemon's download, known before the first sample
        from estimator.analysis.mission_energy import remaining_energy_fn

        mission_energy = remaining_energy_fn(vehicle)
        samples = chain([MissionSample(0.0, mission.items)], samples)
    pipeline = Pipeline(vehicle, settings, mission_energy)
    when_s = stream.start_unix_s or path.stat().st_mtime
    pack = FlightPack(pipeline, args.pack_dir, args.pack, when_s)

    def note(text: str | None, what: str = "note") -> None:
        if text is not None:
            progress.console.print(
                f"uav-energy replay: {what}: {name}: {text}",
                highlight=False,
                soft_wrap=True,
                markup=False,
            )

    try:
        samples = _naming_pack(stream, pack, samples, note)
        flight = replay_stream(stream, vehicle, name, settings, samples, on_sample, pipeline)
        if not flight.estimates:
            limits = vehicle.input_limits()
            problem = battery_window_problem(stream, vehicle.battery.cells, limits)
            if problem is not None:
                raise UserError(f"{path}: {problem}")
        elif summarize([flight]).airborne_s == 0:
            note(no_airborne_reason(flight, stream, vehicle.name), "no airborne time")
        voltage = pipeline.energy.voltage
        if voltage is not None and voltage.load.unresponsive:
            note(voltage.load.describe(), "warning")
        note(pipeline.packs.refuted_note(), "warning")
        note(pack.remember(), "warning")
        note(pack.unnamed())
        for cause, warning in stream.problems(vehicle.battery.cells):
            if said.first(cause):
                note(warning, "warning")
        return flight
    finally:
        progress.remove_task(task)
        progress.advance(_LOGS_TASK)


def _naming_pack(
    stream: SampleStream,
    pack: FlightPack,
    samples: Iterable[Sample | MissionSample],
    note: Callable[[str | None], None],
) -> Iterator[Sample | MissionSample]:
    """``samples`` unchanged; the log's pack serial goes to ``pack`` as soon as the reader has
    met it, before the next sample reaches the pipeline (as the daemon does)."""
    reported = False
    for sample in samples:
        if not reported and stream.pack_id is not None and pack.wants_serial:
            reported = True
            note(pack.reported(stream.pack_id))
        yield sample


def _progress(console: Console, n_logs: int) -> Progress:
    """Logs done of all, and the current log's samples; only on a terminal (stderr)."""
    progress = logs_progress(console)
    progress.add_task("logs", total=n_logs)
    return progress


def flight_names(paths: Sequence[Path]) -> list[str]:
    """Short unique labels: the path below the logs' common folder, without the suffix unless
    only it tells two logs apart (``flight.BIN``, ``flight.tlog``)."""
    if len(paths) == 1:
        return [paths[0].stem]
    absolute = [p.resolve() for p in paths]
    common = Path(os.path.commonpath([p.parent for p in absolute]))
    names = ["/".join(p.relative_to(common).with_suffix("").parts[-_NAME_PARTS:]) for p in absolute]
    return suffixed_where_shared(names, paths)


def write_csv(path: Path, flights: Sequence[FlightReplay]) -> None:
    """One row per estimate: ``flight``, :data:`CSV_COLUMNS`, then the other Estimate fields."""
    extra = [f.name for f in fields(Estimate) if f.name not in CSV_COLUMNS]
    columns = ["flight", *CSV_COLUMNS, *extra]
    try:
        with path.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(columns)
            for flight in flights:
                for estimate in flight.estimates:
                    row = estimate.as_dict()
                    writer.writerow([flight.name, *(_cell(row[c]) for c in columns[1:])])
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return format(value, ".10g")
    return str(value)


def result_json(
    flights: Sequence[FlightReplay],
    wall_s: float,
    vehicle: Vehicle,
    skipped_logs: list[dict[str, str]],
) -> dict[str, Any]:
    """The ``--json`` object: totals, reader counters, and one row per flight."""
    total = summarize(flights)
    result: dict[str, Any] = {
        **_finite(total.as_dict()),
        "wall_s": wall_s,
        "samples_per_s": total.messages / wall_s if wall_s > 0 else None,
        "vehicle": vehicle.name,
        "logs": len(flights),
        "logs_skipped": skipped_logs,
        "skipped": sum(f.skipped for f in flights),
        "bad_frames": sum(f.bad_frames for f in flights),
        "truncated": sum(f.truncated for f in flights),
        "flights": [_flight_row(f) for f in flights],
    }
    return result


def _flight_row(flight: FlightReplay) -> dict[str, Any]:
    return {
        "flight": flight.name,
        "log": str(flight.path),
        "format": flight.format,
        **_finite(summarize([flight]).as_dict()),
        "estimates": len(flight.estimates),
        "skipped": flight.skipped,
        "bad_frames": flight.bad_frames,
        "truncated": flight.truncated,
    }


def _finite(values: dict[str, Any]) -> dict[str, Any]:
    """JSON has no NaN/inf: such values become null."""
    return {
        k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in values.items()
    }


def _print_table(flights: Sequence[FlightReplay], result: dict[str, Any], vehicle: Vehicle) -> None:
    table = Table(title=f"replay with vehicle '{vehicle.name}' (errors over airborne samples)")
    for header in (
        "flight",
        "samples",
        "airborne s",
        "RMSE W",
        "MAPE %",
        "E meas Wh",
        "E model Wh",
    ):
        if header == "flight":
            table.add_column(header, overflow="fold")
        else:
            table.add_column(header, justify="right", no_wrap=True)
    for flight in flights:
        table.add_row(flight.name, *_cells(summarize([flight])))
    if len(flights) > 1:
        table.add_row("all", *_cells(summarize(flights)), style="bold")
    console = Console()
    if not console.is_terminal:
        console = Console(width=_PIPE_WIDTH)  # a file or a pipe: room for the flight names
    console.print(table)
    console.print(
        f"{result['messages']} samples in {result['wall_s']:.2f} s "
        f"({result['samples_per_s'] or 0:.0f} samples/s); skipped {result['skipped']}, "
        f"bad frames {result['bad_frames']}, truncated logs {result['truncated']}",
        highlight=False,
        soft_wrap=True,
    )
    truth = result.get("endurance_truth")
    if truth is not None and truth["estimates"]:
        console.print(
            f"endurance against truth.json: {100 * truth['within_1sigma']:.1f} % within 1σ, "
            f"{100 * truth['within_3sigma']:.1f} % within 3σ, {truth['estimates']} estimates of "
            f"{truth['flights']} flight{'' if truth['flights'] == 1 else 's'}",
            highlight=False,
            soft_wrap=True,
        )


def _cells(s: Summary) -> list[str]:
    def fmt(x: float | None, spec: str) -> str:
        return "–" if x is None else format(x, spec)

    return [
        str(s.messages),
        f"{s.airborne_s:.0f}",
        fmt(s.power_rmse_w, ".1f"),
        fmt(s.power_mape_pct, ".1f"),
        f"{s.energy_measured_wh:.2f}",
        f"{s.energy_predicted_wh:.2f}",
    ]
