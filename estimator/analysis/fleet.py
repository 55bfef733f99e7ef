"""Many logs on a dask.distributed cluster: one row per log (:mod:`fleet_flight`) into one
Parquet file (:mod:`fleet_table`).

The client hashes every log (SHA-256 of its content), skips those whose hash the results
file already holds for the same mode (resume) and identical files met twice in one run,
scatters the job (mode and vehicle) to the workers once, maps :func:`flight_row` over the
rest, consecutive small logs in one task (:func:`tasks`), and gathers rows as they complete.
A worker that dies on a log gives that log a failed row, like a log that cannot be read. The
results file is rewritten atomically every :data:`FLUSH_S` and at the end (also on Ctrl-C),
so an interrupted run resumes where it stopped. Workers must see the logs at the same
absolute paths (a shared file system).
"""

from __future__ import annotations

import glob
import logging
import os
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
from dask.typing import Key
from distributed import Client, KilledWorker, LocalCluster, as_completed

from estimator.analysis.fleet_flight import (
    UNEXPECTED,
    FleetJob,
    failure_reason,
    file_sha256,
    flight_row,
)
from estimator.analysis.fleet_table import done_keys, read_table, to_table, without, write_table
from estimator.errors import UserError
from estimator.file_checks import regular_file

#: Seconds between rewrites of the results file during a run.
FLUSH_S = 10.0
#: Seconds to wait for a scheduler given by address.
CONNECT_TIMEOUT_S = 5.0
#: A dask task replays consecutive logs up to this many bytes: dask's cost per task (a few
#: ms of CPU on the client and the scheduler) stays small beside the replay of small logs.
TASK_BYTES = 1 << 20
#: Tasks per worker at least, when the logs are too few for tasks of :data:`TASK_BYTES`.
TASKS_PER_WORKER = 4
#: A log to process: its path and content hash.
Log = tuple[str, str]
_GLOB_CHARS = frozenset("*?[")
#: Reason of a log whose workers died on it (dask gives up after its allowed failures).
_WORKER_DIED = "the workers analysing the log died on it (out of memory or crashed)"


@dataclass
class FleetRun:
    """Counts of one run: logs given, processed (ok / failed; ``unexpected``: of the failed,
    those no known cause explains, their reason naming the exception), skipped as already in
    the results file, skipped as duplicates of another log in this run; wall time, s."""

    logs: int = 0
    ok: int = 0
    failed: int = 0
    unexpected: int = 0
    already_done: int = 0
    duplicates: int = 0
    wall_s: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def expand_inputs(patterns: Sequence[str]) -> list[Path]:
    """Files named or matched by glob patterns (``**`` recurses), sorted, each once. Every
    match is kept, also a directory, a dangling or looping symbolic link or a FIFO: its row
    then says what it is (regular files by their real path, the others as matched)."""
    found: set[Path] = set()
    for pattern in patterns:
        if _GLOB_CHARS & set(pattern):
            matches = [Path(m) for m in glob.glob(pattern, recursive=True)]
            if not matches:
                raise UserError(f"no file matches {pattern!r}")
            found.update(m.resolve() if m.is_file() else Path(os.path.abspath(m)) for m in matches)
            continue
        path = Path(pattern)
        if path.is_dir():
            raise UserError(f"{path} is a directory: give files or a glob such as '{path}/**/*'")
        if not path.is_file():
            raise UserError(f"no such file: {path}")
        found.add(path.resolve())
    return sorted(found)


@contextmanager
def connect(scheduler: str | None, workers: int) -> Iterator[Client]:
    """A client of the scheduler at ``scheduler`` (e.g. ``tcp://host:8786``), or of a new
    LocalCluster of ``workers`` processes with one thread each (no dashboard)."""
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            raise UserError(f"cannot reach the dask scheduler at {scheduler} ({reason})") from None
        with client:
            yield client
        return
    if workers < 1:
        raise UserError("--workers must be at least 1")
    with (
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def run_fleet(
    client: Client,
    paths: Sequence[Path],
    job: FleetJob,
    out: Path,
    retry_failed: bool = False,
    on_total: Callable[[int], None] | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    every_path: bool = False,
) -> FleetRun:
    """Process ``paths`` on ``client``'s cluster into ``out`` (see the module docstring).
    ``on_total(n)`` is told how many logs will be processed, ``on_row(row)`` each row.
    ``every_path`` processes a path whose content another path of the run has too (a bench
    repeating logs under other names) instead of counting it in ``duplicates``."""
    start = time.perf_counter()
    counts = FleetRun(logs=len(paths))
    existing = read_table(out)
    done = done_keys(existing, job.mode, retry_failed)
    todo: dict[str, str] = {}  # path → hash
    sizes: dict[str, int] = {}  # path → bytes
    seen: set[str] = set()
    rows: list[dict[str, Any]] = []
    for path in paths:
        try:
            digest = file_sha256(regular_file(path, "log"))
            size = path.stat().st_size
        except UserError as exc:
            rows.append(_failed(str(path), None, job, str(exc)))
            continue
        except OSError as exc:
            rows.append(_failed(str(path), None, job, f"cannot read {path}: {exc.strerror}"))
            continue
        if digest in done:
            counts.already_done += 1
        elif digest in seen and not every_path:
            counts.duplicates += 1
        else:
            seen.add(digest)
            todo[str(path)] = digest
            sizes[str(path)] = size
    if existing is not None and retry_failed:
        existing = without(existing, job.mode, seen)
    if on_total is not None:
        on_total(len(todo) + len(rows))
    for row in rows:
        _count(counts, row, on_row)
    last_flush = time.perf_counter()
    try:
        if todo:
            # a fresh key per run: an equal job's key from a previous run may still be
            # being released on the scheduler
            job_future = client.scatter(job, broadcast=True, hash=False)
            workers = sum(client.nthreads().values())
            for row in _completed_rows(client, tasks(todo, sizes, workers), job, job_future):
                rows.append(row)
                _count(counts, row, on_row)
                if time.perf_counter() - last_flush > FLUSH_S:
                    _flush(out, existing, rows)
                    last_flush = time.perf_counter()
    finally:
        _flush(out, existing, rows)
    counts.wall_s = time.perf_counter() - start
    return counts


def tasks(todo: dict[str, str], sizes: dict[str, int], workers: int) -> list[list[Log]]:
    """``todo``'s logs (path → hash) in dask tasks of consecutive logs: a task is closed once
    its logs reach :data:`TASK_BYTES` (``sizes``: path → bytes), or less when the logs are too
    few to give each of ``workers`` :data:`TASKS_PER_WORKER` tasks; a larger log is a task
    of its own."""
    target = min(TASK_BYTES, sum(sizes[p] for p in todo) / (TASKS_PER_WORKER * max(workers, 1)))
    grouped: list[list[Log]] = []
    task: list[Log] = []
    task_bytes = 0
    for path, digest in todo.items():
        task.append((path, digest))
        task_bytes += sizes[path]
        if task_bytes >= target:
            grouped.append(task)
            task, task_bytes = [], 0
    if task:
        grouped.append(task)
    return grouped


def flight_rows(task: list[Log], job: FleetJob) -> list[dict[str, Any]]:
    """The rows of one task's logs (:func:`flight_row`, on a worker)."""
    return [flight_row(path, digest, job) for path, digest in task]


def _completed_rows(
    client: Client, grouped: list[list[Log]], job: FleetJob, job_future: Any
) -> Iterator[dict[str, Any]]:
    """Rows of ``grouped``'s tasks as they complete. A task whose workers died is split into
    tasks of one log, so that only the log they die on gets a failed row."""
    logs_of: dict[Key, list[Log]] = {}

    def submit(more: list[list[Log]]) -> list[Any]:
        futures = client.map(flight_rows, more, job=job_future, pure=False)
        logs_of.update(zip((f.key for f in futures), more, strict=True))
        return futures

    completed = as_completed(submit(grouped))
    for future in completed:
        task = logs_of.pop(future.key)
        try:
            found = future.result()
        except KilledWorker:
            if len(task) > 1:
                completed.update(submit([[log] for log in task]))
                found = []
            else:
                found = [_failed(path, digest, job, _WORKER_DIED) for path, digest in task]
        except Exception as exc:  # the task could not run
            found = [_failed(path, digest, job, failure_reason(exc)) for path, digest in task]
        future.release()
        yield from found


def _failed(path: str, digest: str | None, job: FleetJob, reason: str) -> dict[str, Any]:
    return {
        "path": path,
        "sha256": digest,
        "mode": job.mode,
        "vehicle": job.vehicle.name,
        "status": "failed",
        "error": reason,
    }


def _count(
    counts: FleetRun, row: dict[str, Any], on_row: Callable[[dict[str, Any]], None] | None
) -> None:
    if row["status"] == "ok":
        counts.ok += 1
    else:
        counts.failed += 1
        counts.unexpected += str(row["error"]).startswith(UNEXPECTED)
    if on_row is not None:
        on_row(row)


def _flush(out: Path, existing: pa.Table | None, rows: list[dict[str, Any]]) -> None:
    new = to_table(rows)
    write_table(out, new if existing is None else pa.concat_tables([existing, new]))
