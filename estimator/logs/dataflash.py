"""ArduPilot DataFlash (.bin) logs → :mod:`estimator.telemetry.samples` samples.

Records are indexed by pymavlink's ``DFReader_binary`` (no ``mavutil`` connection, no
process-wide state); those of the types we use are decoded column-wise from its index and
format tables (:mod:`estimator.logs.dataflash_records`), or read as its messages where a
damaged or forged format makes its own read differ from that. Time is
seconds since the autopilot's boot: each record's ``TimeUS`` (µs; Copter ≥ 3.3), else its
``TimeMS`` (ms; Copter ≤ 3.2, whose ``GPS.TimeMS`` is the GPS time of week and ``GPS.T`` the
boot time); a record without a time column (Copter 3.2's ``EV`` and ``MSG``) takes the time of
the record before it. What is used:

- velocity (NED, m/s): the EKF's ``XKF1`` (EKF3, its first core ``C``), ``NKF1`` (EKF2) or
  ``EKF1`` (the first EKF, Copter 3.2–3.3) ``VN, VE, VD`` with altitude ``−PD``; without any,
  ``GPS`` (instance 0 where it has an ``I`` column, Copter ≥ 4.1) ``Spd, GCrs, VZ`` (3-D fix
  only) with altitude above the first fix;
- battery: ``BAT``, the instance with the most known non-zero currents (else 0; a vehicle
  with several monitors may measure the current on one only): ``Volt`` (V), ``Curr`` (A),
  ``CurrTot`` (mAh), ``RemPct`` (%); ArduPilot logs NaN for values it does not know: they
  become ``None`` (no usable voltage drops the record). Logs older than ``BAT``
  (Copter ≤ 3.4) have ``CURR``: its ``Volt`` / ``Curr`` are integer centivolts / centiamps up
  to Copter 3.3 and float V / A in 3.4, ``CurrTot`` mAh;
- firmware: the first ``MSG`` text naming it
  (:func:`~estimator.telemetry.firmware.firmware_named`), as ``firmware``, and the vehicle it
  names when that is not a Copter (:func:`~estimator.telemetry.vehicle_kind.firmware_note`);
- gripper actions: ``MSG`` texts "Gripper load released"/"grabbed" (as the tlog's STATUSTEXT,
  :func:`~estimator.telemetry.decode.gripper_released`);
- armed state: ``ARM.ArmState``, or ``EV`` ids 10 (armed) / 11 (disarmed) in older logs.
  ArduCopter opens its log at arming (``LOG_DISARMED`` 0, the default) and the ``ARM`` record
  of that arming is written before the file is ready: a log whose first arming record is a
  disarm was armed from its start, and says so with an armed sample at its first record.

Counters, final after iteration: ``skipped`` (records with unusable values, or older than
samples already given), ``bad_frames`` (corrupt regions between records), ``truncated`` (the
last record is cut off); ``missing`` says what a log without a usable battery current or
velocity lacks, naming the message types it has (a current of 0 A throughout: no current
sensor, :mod:`estimator.logs.coverage`).
"""

from __future__ import annotations

import contextlib
import heapq
import io
import itertools
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.DFReader import DFReader_binary

from estimator.errors import UserError
from estimator.logs import SampleStream, dataflash_records
from estimator.logs.line_endings import repaired_copy
from estimator.telemetry.decode import gripper_released
from estimator.telemetry.firmware import firmware_named
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    Sample,
    VelocitySample,
)
from estimator.telemetry.vehicle_kind import firmware_note

#: Velocity sources, most preferred first.
VELOCITY_TYPES = ("XKF1", "NKF1", "EKF1", "GPS")
#: Battery sources, most preferred first.
BATTERY_TYPES = ("BAT", "CURR")
#: ArduPilot event ids in ``EV``.
EVENT_ARMED, EVENT_DISARMED = 10, 11
#: A GPS ``Status`` at least this is a 3-D fix.
GPS_FIX_3D = 3
#: Records are re-sorted by time within this window (ArduPilot logs from several threads).
REORDER_WINDOW_S = 0.5
#: Records the library parses between yields (its diagnostics are silenced per batch).
_BATCH = 2000
_INSTANCE_COLUMNS = ("Inst", "Instance", "I")
_CLOCK_COLUMNS = ("TimeUS", "T", "TimeMS")
#: Every column the record handlers read.
_COLUMNS = (
    *_CLOCK_COLUMNS,
    *_INSTANCE_COLUMNS,
    *("C", "VN", "VE", "VD", "PD"),  # EKF
    *("Status", "Alt", "GCrs", "Spd", "VZ"),  # GPS
    *("Volt", "Curr", "CurrTot", "RemPct"),  # battery
    *("ArmState", "Id", "Message"),
)
_INTEGER_CHARS = frozenset("bBhHiI")
FMT_TYPE = 0x80


class _DataFlashIndex(DFReader_binary):
    """``DFReader_binary`` without its whole-file clock search: records carry their boot time."""

    def init_clock(self) -> None:
        self.clock = None


def iter_samples(path: str | Path) -> SampleStream:
    """Samples of a DataFlash log in time order (see :class:`estimator.logs.SampleStream`)."""
    path = Path(path)
    stream = SampleStream(path, "dataflash", ())
    log, stream.sanity.repair_note = _open(path)
    decoder = _Decoder(log, stream)
    stream.message_types = {name for name in _HANDLERS if decoder.count(name) > 0}
    stream.battery_types = BATTERY_TYPES
    stream.velocity_types = VELOCITY_TYPES
    if decoder.velocity_type is not None:
        stream.velocity_source = (
            f"{decoder.velocity_type}.{'VZ' if decoder.velocity_type == 'GPS' else 'VD'}"
        )
    stream._it = decoder.samples()
    return stream


class _Decoder:
    """DataFlash records → samples; counts what it skips into ``stream``."""

    def __init__(self, log: _DataFlashIndex, stream: SampleStream) -> None:
        self._log = log
        self._stream = stream
        self.velocity_type = next((t for t in VELOCITY_TYPES if self.count(t) > 0), None)
        self._ekf_core: int | None = None
        self._gps_alt0_m: float | None = None
        self._armed: bool | None = None
        self._battery_type = next((t for t in BATTERY_TYPES if self.count(t) > 0), "BAT")
        self._bat_instance = _column(log, self._battery_type, _INSTANCE_COLUMNS)
        self._bat_chosen = self._battery_with_current()
        self._gps_instance = _column(log, "GPS", _INSTANCE_COLUMNS)
        self._arming_type = "ARM" if self.count("ARM") > 0 else "EV"
        self._clocks = {name: _clock(log, name) for name in _HANDLERS}
        self._time_s = 0.0  # the time of the record being read, s since boot
        self._battery_seen = False
        self._current_seen = False
        self._armed_from_start = self._first_arming_is_disarm()

    # -- reading -------------------------------------------------------------------------------

    def count(self, name: str) -> int:
        type_id = self._log.name_to_id.get(name)
        return 0 if type_id is None else int(self._log.counts[type_id])

    def _clock_in(self, msg: Any) -> None:
        """Take the record's time (s since boot); without a time column, keep the previous
        record's."""
        clock = self._clocks[msg.get_type()]
        if clock is not None:
            self._time_s = getattr(msg, clock[0]) / clock[1]

    def missing(self) -> str | None:
        """After iteration: what the log lacks for an estimate, and the types it has; None
        when it gave a battery current and a velocity."""
        if self.count(self._battery_type) == 0:
            gap = f"no battery record ({' or '.join(BATTERY_TYPES)})"
        elif _column(self._log, self._battery_type, ("Curr",)) is None:
            gap = f"{self._battery_type} present but no current column"
        elif not self._battery_seen:
            gap = f"{self._battery_type} present but its voltage is never known (0 or NaN)"
        elif not self._current_seen:
            gap = f"{self._battery_type} present but its current is never known (NaN)"
        elif self.velocity_type is None:
            gap = f"no velocity record ({', '.join(VELOCITY_TYPES)})"
        else:
            return None
        found = [name for name in _HANDLERS if self.count(name) > 0]
        return f"{gap}; it has {', '.join(found) or 'none of the records read'}"

    def _battery_with_current(self) -> int:
        """The battery instance with the most known, non-zero current readings (the lowest of
        equals; 0 when none has any): a vehicle with several monitors may measure the
        current on one only."""
        if self._bat_instance is None or self.count(self._battery_type) == 0:
            return 0
        readings: dict[int, int] = {}
        for msg in itertools.chain.from_iterable(self._records({self._battery_type})):
            try:
                instance = int(getattr(msg, self._bat_instance))
                current_a = float(msg.Curr)
            except (AttributeError, KeyError, TypeError, ValueError):
                continue  # a corrupt FMT: counted when the records are read
            measured = math.isfinite(current_a) and current_a != 0.0
            readings[instance] = readings.get(instance, 0) + int(measured)
        if not readings or not any(readings.values()):
            return 0
        return min(readings, key=lambda i: (-readings[i], i))

    def _first_arming_is_disarm(self) -> bool:
        """Whether the log's first arming record (ARM, else EV 10/11) is a disarm."""
        if self.count(self._arming_type) == 0:
            return False
        for msg in itertools.chain.from_iterable(self._records({self._arming_type})):
            try:
                if msg.get_type() == "ARM":
                    return not msg.ArmState
                if msg.Id in (EVENT_ARMED, EVENT_DISARMED):
                    return bool(msg.Id == EVENT_DISARMED)
            except (AttributeError, KeyError, TypeError, ValueError):
                continue  # a corrupt FMT: counted when the records are read
        return False

    def samples(self) -> Iterator[Sample]:
        self._check_framing()
        wanted = {t for t in (self._battery_type, self._arming_type, "MSG") if self.count(t) > 0}
        if self.velocity_type is not None:
            wanted.add(self.velocity_type)
        heap: list[tuple[float, int, Sample]] = []
        last_out_s = -math.inf
        seq = 0
        for batch in self._records(wanted) if wanted else ():
            for msg in batch:
                try:
                    self._clock_in(msg)
                    sample = _HANDLERS[msg.get_type()](self, msg)
                except (AttributeError, KeyError, TypeError, ValueError):
                    self._stream.bad_frames += 1  # a corrupt FMT left the record unreadable
                    continue
                if sample is None:
                    continue
                if self._armed_from_start:
                    self._armed_from_start = False
                    self._armed = True
                    heapq.heappush(heap, (sample.time_s, seq, ArmedSample(sample.time_s, True)))
                    seq += 1
                if sample.time_s < last_out_s:
                    self._stream.skipped += 1
                    continue
                heapq.heappush(heap, (sample.time_s, seq, sample))
                seq += 1
                while heap and heap[0][0] < sample.time_s - REORDER_WINDOW_S:
                    last_out_s = heap[0][0]
                    yield heapq.heappop(heap)[2]
        while heap:
            yield heapq.heappop(heap)[2]
        self._stream.missing = self.missing()
        self._log.close()

    def _records(self, names: set[str]) -> Iterator[list[Any]]:
        """The records of message types ``names`` in file order, in batches: rows decoded
        column-wise (:mod:`estimator.logs.dataflash_records`), else (a damaged or forged
        format) the library's own messages, read from the start of the log."""
        plan = dataflash_records.plan(self._log, names, _COLUMNS)
        if plan is not None:
            yield from plan.rows()
            return
        self._log.rewind()
        done = False
        while not done:
            batch = []
            with _quiet_python_output():
                for _ in range(_BATCH):
                    msg = self._log.recv_match(type=names, strict=True)
                    if msg is None:
                        done = True
                        break
                    batch.append(msg)
            yield batch

    def _check_framing(self) -> None:
        """Count gaps between indexed records (corruption) and a cut-off last record."""
        starts, ends = [], []
        for type_id, offsets in enumerate(self._log.offsets):
            if offsets and type_id in self._log.formats:
                ofs = np.asarray(offsets, dtype=np.int64)
                starts.append(ofs)
                ends.append(ofs + self._log.formats[type_id].len)
        if not starts:
            self._stream.bad_frames = 1
            return
        start = np.concatenate(starts)
        end = np.concatenate(ends)
        order = np.argsort(start, kind="stable")
        start, end = start[order], end[order]
        self._stream.bad_frames = int(start[0] > 0) + int(np.count_nonzero(start[1:] != end[:-1]))
        self._stream.truncated = bool(end[-1] > self._log.data_len)

    # -- record handlers -----------------------------------------------------------------------

    def _ekf(self, msg: Any) -> Sample | None:
        if "C" in msg.fmt.colhash:
            core = msg.C
            if self._ekf_core is None:
                self._ekf_core = core
            if core != self._ekf_core:
                return None
        v = (msg.VN, msg.VE, msg.VD)
        if not all(math.isfinite(x) for x in v):
            self._stream.skipped += 1
            return None
        return VelocitySample(self._time_s, v[0], v[1], v[2], -msg.PD)

    def _gps(self, msg: Any) -> Sample | None:
        if self._gps_instance is not None and getattr(msg, self._gps_instance) != 0:
            return None
        if msg.Status < GPS_FIX_3D:
            self._stream.skipped += 1
            return None
        if self._gps_alt0_m is None:
            self._gps_alt0_m = msg.Alt
        course = math.radians(msg.GCrs)
        return VelocitySample(
            self._time_s,
            msg.Spd * math.cos(course),
            msg.Spd * math.sin(course),
            msg.VZ,
            msg.Alt - self._gps_alt0_m,
        )

    def _battery(self, msg: Any) -> Sample | None:
        if self._bat_instance is not None and getattr(msg, self._bat_instance) != self._bat_chosen:
            return None
        voltage_v = _centi_if_integer(msg, "Volt")
        if not math.isfinite(voltage_v) or voltage_v <= 0.0:
            self._stream.skipped += 1
            return None
        remaining = msg.RemPct if "RemPct" in msg.fmt.colhash else None
        current_a = _finite(_centi_if_integer(msg, "Curr")) if "Curr" in msg.fmt.colhash else None
        self._battery_seen = True
        self._current_seen = self._current_seen or current_a is not None
        return BatterySample(
            self._time_s,
            voltage_v,
            current_a,
            _finite(msg.CurrTot) if "CurrTot" in msg.fmt.colhash else None,
            float(remaining) if remaining is not None and 0 <= remaining <= 100 else None,
        )

    def _arm(self, msg: Any) -> Sample | None:
        return self._armed_change(self._time_s, bool(msg.ArmState))

    def _event(self, msg: Any) -> Sample | None:
        if msg.Id not in (EVENT_ARMED, EVENT_DISARMED):
            return None
        return self._armed_change(self._time_s, msg.Id == EVENT_ARMED)

    def _message(self, msg: Any) -> Sample | None:
        text = str(msg.Message)
        if self._stream.firmware is None and (named := firmware_named(text)) is not None:
            self._stream.firmware = named
            self._stream.sanity.vehicle_note = firmware_note(text)
        released = gripper_released(text)
        return None if released is None else GripperSample(self._time_s, released)

    def _armed_change(self, time_s: float, armed: bool) -> Sample | None:
        if armed == self._armed:
            return None
        self._armed = armed
        return ArmedSample(time_s, armed)


_HANDLERS = {
    "XKF1": _Decoder._ekf,
    "NKF1": _Decoder._ekf,
    "EKF1": _Decoder._ekf,
    "GPS": _Decoder._gps,
    "BAT": _Decoder._battery,
    "CURR": _Decoder._battery,
    "ARM": _Decoder._arm,
    "EV": _Decoder._event,
    "MSG": _Decoder._message,
}


def _open(path: Path) -> tuple[_DataFlashIndex, str | None]:
    """The index of the log at ``path``, and a sentence on a repair made before reading it
    (:mod:`estimator.logs.line_endings`), else None."""
    if path.is_dir():
        raise UserError(f"log {path} is a directory, not a file")
    if not path.exists():
        raise UserError(f"log {path} does not exist")
    if path.stat().st_size == 0:
        raise UserError(f"log {path} is empty")
    try:
        # the index maps the file it reads: a repaired copy's bytes outlive its removal
        with repaired_copy(path) as (source, note), _quiet_stderr(), _quiet_python_output():
            log = _DataFlashIndex(str(source))
    except UserError:
        raise
    except Exception as exc:  # pymavlink raises plain Exception on corrupt FMT records
        raise UserError(f"cannot read DataFlash log {path}: {exc}") from None
    if not any(log.counts[t] for t in log.formats if t != FMT_TYPE):
        log.close()
        raise UserError(f"{path} is not a DataFlash log (no records found)")
    return log, note


@contextlib.contextmanager
def _quiet_stderr() -> Iterator[None]:
    """Silence pymavlink's per-byte diagnostics while it indexes a damaged log.

    Its C indexer writes to file descriptor 2 directly, so the descriptor is redirected for
    the duration (briefly process-wide); the damage is reported by our counters instead.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@contextlib.contextmanager
def _quiet_python_output() -> Iterator[None]:
    """pymavlink's Python diagnostics go to sys.stdout and sys.stderr: keep them out of our
    output (``--json`` owns stdout). Held only while pymavlink code runs, never across a
    yield to the caller."""
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        yield


def _column(log: _DataFlashIndex, name: str, candidates: tuple[str, ...]) -> str | None:
    """The first of ``candidates`` that message ``name`` has, or None."""
    type_id = log.name_to_id.get(name)
    if type_id is None:
        return None
    columns = log.formats[type_id].colhash
    return next((c for c in candidates if c in columns), None)


def _clock(log: _DataFlashIndex, name: str) -> tuple[str, float] | None:
    """Message ``name``'s boot-time column and its units per second; None without one."""
    column = _column(log, name, _CLOCK_COLUMNS)
    return None if column is None else (column, 1e6 if column == "TimeUS" else 1e3)


def _centi_if_integer(msg: Any, column: str) -> float:
    """A volt or amp column: old logs store them as integer centi-units."""
    value = float(getattr(msg, column))
    return value / 100.0 if msg.fmt.format[msg.fmt.colhash[column]] in _INTEGER_CHARS else value


def _finite(value: float) -> float | None:
    """ArduPilot logs NaN for a value it does not know."""
    return float(value) if math.isfinite(value) else None
