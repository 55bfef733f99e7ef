"""Flight-log readers, recognised by content (never by file name).

Two views of a log:

- :func:`iter_samples` streams :mod:`estimator.telemetry.samples` samples in time order (replay, the
  daemon-equivalence tests). Counters ``skipped``, ``bad_frames``, ``truncated`` and
  ``checks``, and the sanity warnings (:mod:`estimator.logs.sanity`), are readable on the
  returned :class:`SampleStream` after iteration. Every sample passes the plausibility and
  time checks of :mod:`estimator.telemetry.plausibility` (MAVLink logs in the decoder, the others
  in a
  :class:`~estimator.telemetry.plausibility.SampleGuard`).
- :func:`load_flights` gives whole flights as numpy arrays (:class:`FlightSeries`) for offline
  work: fitting, residual analysis.

Formats: ``tlog`` (MAVLink telemetry log, :mod:`estimator.logs.tlog`), ``cmu-csv`` (CMU DJI
M100 dataset, :mod:`estimator.logs.cmu`), ``dataflash`` (ArduPilot .bin) and ``ulog`` (PX4);
the last two live in their own modules, imported only when such a file is met.
"""

from __future__ import annotations

import importlib
import itertools
import os
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from estimator.errors import UserError
from estimator.file_checks import regular_file
from estimator.logs.coverage import Coverage
from estimator.logs.sanity import SanityRecorder
from estimator.physics.effects import wind_from_deg
from estimator.telemetry.plausibility import InputLimits, SampleGuard, battery_problem
from estimator.telemetry.sample_columns import SampleColumns
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
)
from estimator.telemetry.skip_counters import SKIP_COUNTERS

FloatArray = NDArray[np.float64]

FORMATS = ("tlog", "cmu-csv", "dataflash", "ulog")
#: Velocity older than this (s) is not attached to a battery sample in :func:`series_from_samples`.
DEFAULT_VELOCITY_MAX_AGE_S = 1.0

_DATAFLASH_MAGIC = b"\xa3\x95"
_ULOG_MAGIC = b"ULog"
_MAVLINK_STX = (0xFE, 0xFD)
#: A tlog record starts with its receive time, µs since 1970 (big-endian): below 2⁵² (the
#: year 2112), so 1 in ~10⁴ random heads passes, not 1 in 128 as on the STX byte alone.
_TLOG_MAX_TIME_US = 2**52
_MODULES = {"tlog": "tlog", "cmu-csv": "cmu", "dataflash": "dataflash", "ulog": "ulog"}
#: Samples a log reader gives the value and time checks at once.
_GUARD_BATCH = 512


@dataclass
class FlightSeries:
    """One flight as aligned arrays (one row per power sample), time on the log's own clock.

    Velocity is NED over ground (m/s), ``alt_m`` above home/take-off (m). ``voltage_v`` and
    ``current_a`` are NaN when the source only has their product ``power_w`` (W).
    ``extras`` holds source-specific per-row columns (CMU: ``payload_kg``,
    ``airflow_speed_mps``, ``airflow_from_deg``; tlogs: ``armed`` as 0/1/NaN, and when the
    autopilot sends its wind estimate ``autopilot_wind_speed_mps`` and
    ``autopilot_wind_from_deg``, NaN before the first; when it reports gripper actions
    ``gripper_released``: 1 released, 0 grabbed, the other state before the first report;
    when the autopilot counts it ``consumed_mah``, the charge drawn since its boot, mAh, NaN
    where unknown).
    """

    flight_id: str
    time_s: FloatArray
    vn_mps: FloatArray
    ve_mps: FloatArray
    vd_mps: FloatArray
    alt_m: FloatArray
    voltage_v: FloatArray
    current_a: FloatArray
    power_w: FloatArray
    extras: dict[str, FloatArray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def speed_mps(self) -> FloatArray:
        """Horizontal ground speed, m/s."""
        return np.asarray(np.hypot(self.vn_mps, self.ve_mps), dtype=float)

    def subset(self, mask: NDArray[np.bool_], flight_id: str | None = None) -> FlightSeries:
        """The rows where ``mask`` is true (same columns, same extras)."""
        return FlightSeries(
            flight_id=self.flight_id if flight_id is None else flight_id,
            time_s=self.time_s[mask],
            vn_mps=self.vn_mps[mask],
            ve_mps=self.ve_mps[mask],
            vd_mps=self.vd_mps[mask],
            alt_m=self.alt_m[mask],
            voltage_v=self.voltage_v[mask],
            current_a=self.current_a[mask],
            power_w=self.power_w[mask],
            extras={k: v[mask] for k, v in self.extras.items()},
        )


class SampleStream(Iterator[Sample]):
    """Samples of one log in time order; counters are final once iteration has ended.

    ``skipped``: records passed over on purpose (message types the decoder does not use, rows
    with missing values, values or stamps not believed); ``checks``: of those, the ones the
    plausibility and time checks skipped, by reason; ``bad_frames``: corrupt records;
    ``truncated``: the file ended in the middle of a record (everything before the damage was
    read). ``velocity_source`` names the logged vertical velocity (for warnings). ``missing``:
    once iterated, what a log that gave no battery voltage, no known non-zero current or no
    velocity lacks, naming the message types it has (a sentence part,
    :meth:`~estimator.logs.coverage.Coverage.gap` over the reader's ``message_types``,
    ``battery_types`` and ``velocity_types``, unless the reader said more); None otherwise.
    ``firmware``: the autopilot's name and version as the log states it, else None.
    ``columns``: the reader's samples column-wise, when it decodes the whole log at once
    (ULog): :func:`iter_samples` then checks them at once and hands the stream the checked
    list (:meth:`take`).
    Where the log has them (tlogs): ``start_unix_s``, the first record's receive time (s since
    the Unix epoch, UTC); ``autopilot``, the (system id, component id) decoded; ``pack_id``, the
    pack's serial number (else its device name) from SMART_BATTERY_INFO. None otherwise.
    """

    def __init__(self, path: Path, fmt: str, samples: Iterable[Sample]) -> None:
        self.path = path
        self.format = fmt
        self.skipped = 0
        self.bad_frames = 0
        self.truncated = False
        self.checks: Counter[str] = Counter()
        self.velocity_source = "vertical velocity"
        self.missing: str | None = None
        self.start_unix_s: float | None = None
        self.autopilot: tuple[int, int] | None = None
        self.pack_id: str | None = None
        self.firmware: str | None = None
        self.message_types: set[str] = set()
        self.battery_types: tuple[str, ...] = ()
        self.velocity_types: tuple[str, ...] = ()
        self.sanity = SanityRecorder()
        self.coverage = Coverage()
        self.columns: SampleColumns | None = None
        self._it = iter(samples)
        self._observed = False  # every sample observed already (take)

    def __iter__(self) -> Iterator[Sample]:
        return self._it if self._observed else self

    def __next__(self) -> Sample:
        try:
            sample = next(self._it)
        except StopIteration:
            self._ended()
            raise
        if not self._observed:
            self.sanity.observe(sample)
            self.coverage.observe(sample)
        return sample

    def take(self, samples: list[Sample]) -> None:
        """All the stream's samples at once (a reader that decoded the whole log): observed
        now, column-wise, then iterated as a list; the counters are final already."""
        self.sanity.observe_many(samples)
        self.coverage.observe_many(samples)
        self._it, self._observed = iter(samples), True
        self._ended()

    def _ended(self) -> None:
        if self.missing is None and self.battery_types:
            self.missing = self.coverage.gap(
                self.message_types, self.battery_types, self.velocity_types
            )

    def warnings(self, cells: int | None = None) -> list[str]:
        """The sanity checks' warnings once iterated (pack voltage when ``cells`` is given)."""
        return self.sanity.warnings(cells, self.velocity_source)

    def problems(self, cells: int | None = None) -> list[tuple[str, str]]:
        """The sanity checks' (cause, warning) once iterated, as :meth:`warnings`."""
        return self.sanity.problems(cells, self.velocity_source)

    def count_checks(self, counts: Counter[str]) -> None:
        """Take the plausibility and time checks' skips from ``counts`` (added to ``skipped``)."""
        found = Counter({k: counts[k] for k in SKIP_COUNTERS if counts[k]})
        self.checks.update(found)
        self.skipped += sum(found.values())


def detect_format(path: str | Path) -> str:
    """The log format of ``path`` from its first bytes: one of :data:`FORMATS`."""
    path = Path(path)
    head = _read_head(path)
    if not head:
        raise UserError(f"{path} is empty")
    if head.startswith(_ULOG_MAGIC):
        return "ulog"
    if head.startswith(_DATAFLASH_MAGIC):
        return "dataflash"
    if any(_tlog_head(h) for h in (head, head.replace(b"\r\n", b"\n"))):
        return "tlog"  # the second: converted to CRLF as text (the reader undoes it)
    first_line = head.split(b"\n", 1)[0].decode("utf-8", "replace")
    if _module("cmu-csv").looks_like_cmu_header(first_line):
        return "cmu-csv"
    raise UserError(
        f"{path} is not a recognised log (expected a MAVLink tlog, a CMU CSV, "
        "a DataFlash .bin or a PX4 .ulg)"
    )


def _tlog_head(head: bytes) -> bool:
    """Whether ``head`` starts as a tlog: a plausible receive stamp, then a frame start."""
    return (
        len(head) > 8
        and head[8] in _MAVLINK_STX
        and int.from_bytes(head[:8], "big") < _TLOG_MAX_TIME_US
    )


def iter_samples(
    path: str | Path, fmt: str = "auto", limits: InputLimits | None = None
) -> SampleStream:
    """Stream the telemetry samples of one log (see :class:`SampleStream`); values beyond
    ``limits`` (default: any multirotor's) are skipped and counted."""
    path = Path(path)
    fmt = _resolve(path, fmt)
    if fmt == "tlog":
        return _module(fmt).iter_samples(path, limits)
    stream: SampleStream = _module(fmt).iter_samples(path)
    guard = SampleGuard(limits)
    if stream.columns is None:
        stream._it = _guarded(stream._it, stream, guard)
    else:
        stream.take([*guard.check_many(list(stream._it), stream.columns), *guard.flush()])
        stream.count_checks(guard.counts)
    return stream


def _guarded(
    samples: Iterator[Sample], stream: SampleStream, guard: SampleGuard
) -> Iterator[Sample]:
    while batch := list(itertools.islice(samples, _GUARD_BATCH)):
        yield from guard.check_many(batch)
    yield from guard.flush()
    stream.count_checks(guard.counts)


def load_flights(
    paths: Sequence[str | Path], fmt: str = "auto", workers: int = 1
) -> list[FlightSeries]:
    """Read logs into flights. CMU CSV files are read together (regime files join up).
    ``workers`` > 1: the files of the other formats are read in that many forked processes
    (same flights, same order)."""
    if not paths:
        raise UserError("no log files given")
    by_format: dict[str, list[Path]] = {}
    for p in paths:
        path = Path(p)
        by_format.setdefault(_resolve(path, fmt), []).append(path)
    flights: list[FlightSeries] = []
    for name, group in by_format.items():
        module = _module(name)
        if hasattr(module, "load_flights"):
            flights.extend(module.load_flights(group))
            continue
        jobs = list(zip(group, _unique_names(paths, group), [name] * len(group), strict=True))
        if workers > 1 and len(jobs) > 1:
            import multiprocessing  # only here: the daemon imports this module
            from concurrent.futures import ProcessPoolExecutor

            fork = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=fork) as pool:
                for read in pool.map(_read_flights, jobs):
                    flights.extend(read)
        else:
            for job in jobs:
                flights.extend(_read_flights(job))
    return flights


def _read_flights(job: tuple[Path, str, str]) -> list[FlightSeries]:
    """The flights of one log: (path, flight name, format)."""
    path, flight_name, fmt = job
    return list(flights_from_stream(iter_samples(path, fmt), flight_name))


def _unique_names(paths: Sequence[str | Path], group: list[Path]) -> list[str]:
    """Short distinct names of the logs ``group`` among all ``paths`` read together: file
    stems, or paths below the common folder if stems repeat (with the suffix where only it
    tells two apart: ``flight.BIN``, ``flight.tlog``)."""
    every = [Path(p) for p in paths]
    stems = [p.stem for p in every]
    if len(set(stems)) == len(stems):
        names = stems
    else:
        resolved = [p.resolve() for p in every]
        common = Path(os.path.commonpath(resolved))
        below = [p.relative_to(common).with_suffix("").as_posix() for p in resolved]
        names = suffixed_where_shared(below, every)
    of_path = dict(zip(every, names, strict=True))
    return [of_path[p] for p in group]


def suffixed_where_shared(names: Sequence[str], paths: Sequence[Path]) -> list[str]:
    """``names`` of the files ``paths``, each name that several files share followed by its
    file's suffix (``flight.BIN`` and ``flight.tlog`` rather than ``flight`` twice)."""
    counts = Counter(names)
    return [
        f"{name}{path.suffix}" if counts[name] > 1 else name
        for name, path in zip(names, paths, strict=True)
    ]


def flights_from_stream(
    stream: SampleStream,
    name: str,
    velocity_max_age_s: float = DEFAULT_VELOCITY_MAX_AGE_S,
) -> list[FlightSeries]:
    """Build flights from a sample stream: one per autopilot boot, one row per power sample.

    Each battery sample gets the latest velocity sample not older than
    ``velocity_max_age_s`` (previous-sample alignment, no look-ahead); samples without a recent
    velocity, or without a newer autopilot time than the previous row, are dropped. Raises
    UserError when the log has no velocity or no current.
    """
    segments: list[list[Sample]] = [[]]
    for sample in stream:
        if isinstance(sample, RebootSample):
            segments.append([])
        else:
            segments[-1].append(sample)
    if stream.missing is not None:
        raise UserError(f"{stream.path}: {stream.missing}")
    all_samples = [s for seg in segments for s in seg]
    batteries = [s for s in all_samples if isinstance(s, BatterySample)]
    if not any(isinstance(s, VelocitySample) for s in all_samples):
        raise UserError(
            f"{stream.path} has no velocity messages (GLOBAL_POSITION_INT/LOCAL_POSITION_NED)"
        )
    if not batteries:
        raise UserError(f"{stream.path} has no battery messages (SYS_STATUS/BATTERY_STATUS)")
    if all(b.current_a is None for b in batteries):
        raise UserError(f"{stream.path} has no battery current (the autopilot reports it unknown)")
    flights = []
    for i, seg in enumerate(segments):
        flight_id = name if len(segments) == 1 else f"{name}#{i + 1}"
        series = _align(seg, flight_id, velocity_max_age_s)
        if series is not None:
            flights.append(series)
    if not flights:
        raise UserError(
            f"{stream.path} has no battery sample with a velocity within {velocity_max_age_s} s"
        )
    return flights


def battery_window_problem(stream: SampleStream, cells: int, limits: InputLimits) -> str | None:
    """Why a log read through ``limits`` (a pack of ``cells``) gave no battery reading, when
    the reason is that every reading in it lies outside the vehicle's window: every voltage
    outside the pack's (the vehicle file's ``cells`` is likely wrong), every current outside
    what the vehicle draws, or every consumed charge below zero (below zero: a current sensor
    wired or calibrated the wrong way round), else how many were refused for what; None when a
    reading passes. Reads the log again, believing any finite current and consumed charge
    (:meth:`InputLimits.any_current`)."""
    checks = stream.checks
    refused = ("voltage_implausible", "current_implausible", "consumed_implausible")
    if not any(checks[reason] for reason in refused):
        return None
    readings = [
        s
        for s in iter_samples(stream.path, stream.format, InputLimits.any_current())
        if isinstance(s, BatterySample)
    ]
    problems = [battery_problem(s, limits) for s in readings]
    if not readings or None in problems:
        return None
    voltages = [s.voltage_v for s in readings]
    if not any(limits.min_voltage_v < v <= limits.max_voltage_v for v in voltages):
        return (
            f"every battery voltage ({min(voltages):.1f}–{max(voltages):.1f} V) is outside the "
            f"window of a {cells}-cell pack ({limits.min_voltage_v:.1f}–"
            f"{limits.max_voltage_v:.1f} V): is `cells` right?"
        )
    currents = [s.current_a for s in readings if s.current_a is not None]
    if currents and all(problem == "current_implausible" for problem in problems):
        low_a, high_a = min(currents), max(currents)
        question = "is the current sensor reversed?" if high_a < 0 else "is its scale right?"
        return (
            f"every battery current ({low_a:.1f} to {high_a:.1f} A) is outside what the vehicle "
            f"draws ({limits.min_current_a:.1f} A, a charge, to {limits.max_current_a:.0f} A "
            f"and {limits.max_power_w:.0f} W): {question}"
        )
    consumed = [s.consumed_mah for s in readings if s.consumed_mah is not None]
    if consumed and max(consumed) < 0:
        return (
            f"every consumed charge ({min(consumed):.0f} to {max(consumed):.0f} mAh) is below "
            "zero: is the current sensor reversed?"
        )
    counts = ", ".join(f"{checks[r]} for its {r.split('_')[0]}" for r in refused if checks[r])
    return f"every battery reading was refused as beyond the vehicle's limits ({counts})"


def _align(samples: list[Sample], flight_id: str, max_age_s: float) -> FlightSeries | None:
    rows: list[tuple[float, ...]] = []
    winds: list[tuple[float, float]] = []
    last_v: VelocitySample | None = None
    last_wind = (float("nan"), float("nan"))
    armed = float("nan")
    gripper = float("nan")
    for s in samples:
        if isinstance(s, VelocitySample):
            last_v = s
        elif isinstance(s, WindSample):
            last_wind = (s.wind_n_mps, s.wind_e_mps)
        elif isinstance(s, GripperSample):
            gripper = 1.0 if s.released else 0.0
        elif isinstance(s, ArmedSample):
            armed = 1.0 if s.armed else 0.0
        elif isinstance(s, BatterySample) and s.current_a is not None and last_v is not None:
            if s.time_s - last_v.time_s > max_age_s or (rows and s.time_s <= rows[-1][0]):
                continue
            alt = float("nan") if last_v.alt_m is None else last_v.alt_m
            rows.append(
                (
                    s.time_s,
                    last_v.vn_mps,
                    last_v.ve_mps,
                    last_v.vd_mps,
                    alt,
                    s.voltage_v,
                    s.current_a,
                    armed,
                    gripper,
                    float("nan") if s.consumed_mah is None else s.consumed_mah,
                )
            )
            winds.append(last_wind)
    if not rows:
        return None
    a = np.array(rows, dtype=float)
    extras = {"armed": a[:, 7]}
    if any(isinstance(s, WindSample) for s in samples):
        w = np.array(winds, dtype=float)
        extras["autopilot_wind_speed_mps"] = np.hypot(w[:, 0], w[:, 1])
        extras["autopilot_wind_from_deg"] = wind_from_deg(w[:, 0], w[:, 1])
    if np.isfinite(a[:, 9]).any():
        extras["consumed_mah"] = a[:, 9]
    reported = a[np.isfinite(a[:, 8]), 8]
    if len(reported):
        # 1 after the autopilot reported the gripper released, 0 after grabbed; before its
        # first report the other state (a release tells that it held something)
        extras["gripper_released"] = np.where(np.isfinite(a[:, 8]), a[:, 8], 1.0 - reported[0])
    return FlightSeries(
        flight_id=flight_id,
        time_s=a[:, 0],
        vn_mps=a[:, 1],
        ve_mps=a[:, 2],
        vd_mps=a[:, 3],
        alt_m=a[:, 4],
        voltage_v=a[:, 5],
        current_a=a[:, 6],
        power_w=a[:, 5] * a[:, 6],
        extras=extras,
    )


def _resolve(path: Path, fmt: str) -> str:
    """The format of the log at ``path`` (``fmt``, or detected for "auto"); a path that is no
    regular file (a directory, a FIFO that would block, a device) is refused first."""
    regular_file(path, "log")
    if fmt == "auto":
        return detect_format(path)
    if fmt not in FORMATS:
        raise UserError(f"unknown log format {fmt!r} (choose from auto, {', '.join(FORMATS)})")
    return fmt


def _read_head(path: Path, size: int = 4096) -> bytes:
    regular_file(path, "log")
    try:
        with path.open("rb") as f:
            return f.read(size)
    except FileNotFoundError:
        raise UserError(f"{path} does not exist") from None
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None


def _module(fmt: str) -> ModuleType:
    name = f"estimator.logs.{_MODULES[fmt]}"
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name == name:
            raise UserError(f"log format {fmt!r} is not supported yet") from None
        raise
