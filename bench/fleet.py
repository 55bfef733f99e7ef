"""``fleet replay`` at scale: N logs (default 10,000) on a LocalCluster of 1 and of 2 worker
processes and on a ``dask scheduler`` + ``dask worker`` pair started by the bench.

The logs are the committed logs that replay in under 0.15 s each (:data:`CORPUS`: the five
IRIS+ flights of ``replay/iris``, a tlog, a DataFlash ``.bin`` and a PX4 ``.ulg`` of
``tests/data/corpus``), repeated under other names as hard links (symbolic links where the
file system has none) in a temporary directory: no log is copied. Every name is processed
(``run_fleet(every_path=True)``: the run does not skip a content met before under another
name), so N logs are N replays, hashed on the client as in any run.

Per run, the cluster already started (its start-up printed apart): wall time, logs per second,
ok and failed rows, the per-log work summed over the workers (wall-clock and CPU time, from
the rows' ``wall_s`` and ``cpu_s``), how busy that kept the workers, the CPU time of the
client and the scheduler per log (the scheduler runs in the client's process on a
LocalCluster), and the machine's load average before the run. Then the speed-up 1 → 2 workers
on the LocalCluster and on the scheduler pair (its 2 workers against the LocalCluster's 1).
Progress goes to stdout every :data:`PROGRESS_S`.

Run: ``python -m bench fleet`` (or ``make bench``); ``python -m bench.fleet --logs 1000`` for a
shorter run; ``--json FILE`` also writes the figures.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import psutil
import pyarrow.compute as pc
import pyarrow.parquet as pq
from distributed import Client

from estimator.analysis.fleet import connect, flight_rows, run_fleet
from estimator.analysis.fleet_flight import FleetJob
from estimator.physics.vehicle import default_vehicle

REPO = Path(__file__).resolve().parent.parent
#: The committed logs repeated, relative to the repository (0.01–0.13 s of replay each).
CORPUS = (
    *sorted(str(p.relative_to(REPO)) for p in (REPO / "replay" / "iris").rglob("*.log")),
    "tests/data/corpus/adgfuzz_sitl_copter.tlog",
    "tests/data/corpus/adgfuzz_sitl_copter.bin",
    "tests/data/corpus/roboto_px4_v1_12.ulg",
)
DEFAULT_LOGS = 10_000
#: Seconds between progress lines during a run.
PROGRESS_S = 30.0
#: Seconds allowed for the scheduler pair to start and its workers to join.
PAIR_START_S = 60.0


@dataclass
class Measurement:
    """One run: cluster, workers, logs given / ok / failed; wall time of the run and start-up
    of its cluster, s; per-log work summed over the workers (wall-clock and CPU), s; CPU of the
    client and the scheduler over the run, s; 1-minute load average before the run."""

    cluster: str
    workers: int
    logs: int
    ok: int
    failed: int
    wall_s: float
    startup_s: float
    work_wall_s: float
    work_cpu_s: float
    overhead_cpu_s: float
    load_before: float

    @property
    def logs_per_s(self) -> float:
        return self.logs / self.wall_s


def link_logs(directory: Path, count: int) -> list[Path]:
    """``count`` links named ``log-NNNNN<suffix>`` to the :data:`CORPUS` logs in turn."""
    links = []
    for k in range(count):
        target = REPO / CORPUS[k % len(CORPUS)]
        link = directory / f"log-{k:05d}{target.suffix}"
        try:
            os.link(target, link)
        except OSError:  # another file system, or one without hard links
            link.symlink_to(target)
        links.append(link)
    return links


@contextmanager
def scheduler_pair(directory: Path, workers: int) -> Iterator[tuple[Client, psutil.Process]]:
    """A client of a ``dask scheduler`` and a ``dask worker`` of ``workers`` processes (one
    thread each) started as subprocesses, stopped on exit; and the scheduler's process."""
    dask = Path(sys.executable).with_name("dask")
    address_file = directory / "scheduler.json"
    quiet = subprocess.DEVNULL
    common = ["--no-dashboard", "--scheduler-file", str(address_file)]
    scheduler = subprocess.Popen(
        [dask, "scheduler", "--host", "127.0.0.1", "--port", "0", *common],
        stdout=quiet,
        stderr=quiet,
    )
    worker = None
    try:
        deadline = time.monotonic() + PAIR_START_S
        while not address_file.exists():
            if scheduler.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"dask scheduler did not start (exit {scheduler.returncode})")
            time.sleep(0.1)
        worker = subprocess.Popen(
            [dask, "worker", "--nworkers", str(workers), "--nthreads", "1", *common],
            stdout=quiet,
            stderr=quiet,
        )
        address = json.loads(address_file.read_text())["address"]
        with connect(address, 0) as client:
            client.wait_for_workers(workers, timeout=PAIR_START_S)
            yield client, psutil.Process(scheduler.pid)
    finally:
        for process in (worker, scheduler):
            if process is not None:
                process.terminate()
                try:
                    process.wait(timeout=PAIR_START_S)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()


@contextmanager
def cluster(
    kind: str, directory: Path, workers: int
) -> Iterator[tuple[Client, psutil.Process | None]]:
    """A client of a LocalCluster or of a scheduler pair, and the pair's scheduler process;
    the scheduler and every worker have imported the per-log code (the scheduler unpickles
    the tasks; a pair's processes start without it, a LocalCluster's import the bench)."""
    with ExitStack() as stack:
        if kind == "LocalCluster":
            client, scheduler = stack.enter_context(connect(None, workers)), None
        else:
            client, scheduler = stack.enter_context(scheduler_pair(directory, workers))
        client.run(importlib.import_module, flight_rows.__module__)
        client.run_on_scheduler(importlib.import_module, flight_rows.__module__)
        yield client, scheduler


def overhead_cpu_s(scheduler: psutil.Process | None) -> float:
    """CPU time so far of this process (the client; a LocalCluster's scheduler too) and of
    the scheduler pair's scheduler process where there is one, s."""
    cpu = time.process_time()
    if scheduler is not None:
        times = scheduler.cpu_times()
        cpu += times.user + times.system
    return cpu


def measure(kind: str, workers: int, logs: list[Path], directory: Path) -> Measurement:
    load = os.getloadavg()[0]
    start = time.perf_counter()
    with cluster(kind, directory, workers) as (client, scheduler):
        startup_s = time.perf_counter() - start
        seen = len(client.nthreads())
        if seen != workers:
            raise RuntimeError(f"{kind}: {seen} workers joined, not {workers}")
        out = directory / f"{kind}-{workers}.parquet"
        cpu_before = overhead_cpu_s(scheduler)
        counts = run_fleet(
            client,
            logs,
            FleetJob("replay", default_vehicle()),
            out,
            on_row=progress(f"{kind}, {workers} worker(s)", len(logs)),
            every_path=True,
        )
        overhead_s = overhead_cpu_s(scheduler) - cpu_before
    rows = pq.read_table(out, columns=["wall_s", "cpu_s"])
    out.unlink()
    work_wall_s, work_cpu_s = (pc.sum(rows[c]).as_py() or 0.0 for c in ("wall_s", "cpu_s"))
    return Measurement(
        kind,
        workers,
        counts.logs,
        counts.ok,
        counts.failed,
        counts.wall_s,
        startup_s,
        work_wall_s,
        work_cpu_s,
        overhead_s,
        load,
    )


def progress(label: str, total: int) -> Callable[[dict[str, Any]], None]:
    """An ``on_row`` callback printing ``label: done/total`` every :data:`PROGRESS_S`."""
    state = {"done": 0, "start": time.perf_counter(), "said": time.perf_counter()}

    def on_row(row: dict[str, Any]) -> None:
        state["done"] += 1
        now = time.perf_counter()
        if now - state["said"] >= PROGRESS_S:
            state["said"] = now
            elapsed_s = now - state["start"]
            print(f"    … {label}: {state['done']}/{total} logs, {elapsed_s:.0f} s", flush=True)

    return on_row


def report(m: Measurement) -> None:
    busy_pct = 100 * m.work_wall_s / (m.wall_s * m.workers)
    print(
        f"  {m.cluster}, {m.workers} worker(s): {m.wall_s:7.1f} s  ({m.logs_per_s:6.1f} logs/s, "
        f"{m.ok} ok, {m.failed} failed; cluster start {m.startup_s:.1f} s)\n"
        f"    per-log work summed {m.work_wall_s:.1f} s (CPU {m.work_cpu_s:.1f} s), workers busy "
        f"{busy_pct:.0f} %, client + scheduler CPU {1000 * m.overhead_cpu_s / m.logs:.1f} ms "
        f"per log, load average before {m.load_before:.1f}",
        flush=True,
    )


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m bench.fleet", description=__doc__)
    parser.add_argument("--logs", type=int, default=DEFAULT_LOGS, metavar="N")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the figures")
    args, _ = parser.parse_known_args(argv)  # under ``python -m bench fleet``: the bench names
    if args.logs < 1:
        parser.error("--logs must be at least 1")
    return args


def main(argv: list[str]) -> int:
    args = parse_args(argv)
    print(
        f"bench fleet: fleet replay of {args.logs} logs ({len(CORPUS)} committed logs repeated), "
        f"processes with one thread, {os.cpu_count()} CPUs",
        flush=True,
    )
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        logs = link_logs(directory, args.logs)
        for kind, workers in (("LocalCluster", 1), ("LocalCluster", 2), ("scheduler pair", 2)):
            runs.append(measure(kind, workers, logs, directory))
            report(runs[-1])
    one = runs[0].wall_s
    print(
        f"  speed-up 1 → 2 workers: LocalCluster {one / runs[1].wall_s:.2f}×, "
        f"scheduler pair {one / runs[2].wall_s:.2f}×"
    )
    if args.json is not None:
        figures = [{**asdict(m), "logs_per_s": m.logs_per_s} for m in runs]
        args.json.write_text(json.dumps(figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
