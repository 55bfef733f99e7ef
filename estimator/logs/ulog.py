"""PX4 ULog (.ulg) logs → :mod:`estimator.telemetry.samples` samples, read with pyulog.

Topics used (instance 0 unless said), time from each record's ``timestamp`` (µs since
boot) / 1e6:

- ``vehicle_local_position``: ``vx, vy, vz`` (NED, m/s), altitude ``−z`` (m above the
  local origin); records flagged ``v_xy_valid``/``v_z_valid`` false are skipped;
- without any valid one, the GPS: ``vehicle_gps_position``, else ``sensor_gps`` (the
  receiver's own topic, PX4 ≥ 1.14): ``vel_n_m_s, vel_e_m_s, vel_d_m_s`` (NED, m/s) of the
  records with a 3-D fix (``fix_type`` ≥ 3) and ``vel_ned_valid``, altitude above the first
  of them from ``alt`` (mm above sea level, PX4 ≤ 1.14) or ``altitude_msl_m`` (m, PX4 ≥ 1.15);
- ``battery_status``, the instance with the most readings of a connected pack:
  ``voltage_v`` (V), ``current_a`` (A, −1 = unknown), ``discharged_mah`` (mAh, negative =
  unknown), ``remaining`` (fraction 0–1, negative = unknown → percent); records with
  ``connected`` false or no usable voltage are skipped;
- ``vehicle_status``: ``arming_state`` (2 = armed), as changes; ``system_type`` (MAV_TYPE)
  for a vehicle that is not a multirotor (:mod:`estimator.telemetry.vehicle_kind`);
- ``vehicle_land_detected``: ``landed``, PX4's landed detector (the one EXTENDED_SYS_STATE
  sends), as changes.

``firmware`` comes from the info messages (:func:`firmware`); ``missing`` names the topics
of these the log has (:mod:`estimator.logs.coverage`; with batteries, a local position
whose velocity is never valid is said as such).

Counters: ``skipped`` (records with unusable values), ``bad_frames`` (1 when pyulog detected
corruption and re-synchronised), ``truncated`` (the file ends inside a message: what came
before is read).
"""

from __future__ import annotations

import contextlib
import io
import os
from collections.abc import Callable
from dataclasses import dataclass
from itertools import chain
from pathlib import Path
from typing import Any

import numpy as np
from pyulog import ULog

from estimator.errors import UserError
from estimator.logs import SampleStream
from estimator.logs.line_endings import repaired_copy
from estimator.telemetry.sample_columns import CHECKED_FIELDS, SampleColumns
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    LandedSample,
    Sample,
    VelocitySample,
    of_columns,
)
from estimator.telemetry.vehicle_kind import frame_note

#: The GPS topics, most preferred first (velocity when the local position has none).
GPS_TOPICS = ("vehicle_gps_position", "sensor_gps")
TOPICS = (
    "vehicle_local_position",
    "battery_status",
    "vehicle_status",
    "vehicle_land_detected",
    *GPS_TOPICS,
)
#: The topics whose samples are velocities.
_VELOCITY_TOPICS = frozenset({"vehicle_local_position", *GPS_TOPICS})
#: A GPS ``fix_type`` at least this is a 3-D fix.
GPS_FIX_3D = 3
#: ``vehicle_status.arming_state`` value of an armed vehicle (PX4 ≥ 1.8).
ARMING_STATE_ARMED = 2
#: The type byte of ``ver_sw_release`` for a release build.
_RELEASE_TYPE = 0xFF


#: pyulog reads at most this many bytes at once (a message's uint16 size, or a sync search
#: within one): a read that starts further than this from the end of the file cannot be short.
MAX_READ_BYTES = 0xFFFF

_buffered_read = io.BufferedReader.read


class _ReadProbe:
    """The file pyulog reads, telling whether its last read came back short: the file ended
    inside a message. Only the reads of the file's last :data:`MAX_READ_BYTES` are watched
    (:class:`_WatchedFile` says when they begin); the others go to the buffered reader's C
    method untouched (a watched read costs a Python call: the whole file watched added a
    third to pyulog's own time)."""

    def __init__(self, path: Path) -> None:
        self.last_read_short = False
        raw = _WatchedFile(path, os.path.getsize(path) - MAX_READ_BYTES, self._watch)
        self.file = io.BufferedReader(raw)
        raw.reached(0)  # a file no longer than the tail is watched from its start

    def _watch(self) -> None:
        # an instance attribute hides the class's C method from pyulog's `file.read(n)`
        self.file.read = self._read  # type: ignore[method-assign]

    def _read(self, size: int | None = -1) -> bytes:
        data = _buffered_read(self.file, size)
        self.last_read_short = size is not None and 0 < len(data) < size
        return data


class _WatchedFile(io.FileIO):
    """A file that calls ``on_tail`` once its position first reaches ``tail_start`` (bytes):
    then every read of its buffered reader that may come back short is yet to come (the
    buffered reader's position never passes the raw file's)."""

    def __init__(self, path: Path, tail_start: int, on_tail: Callable[[], None]) -> None:
        super().__init__(path, "rb")
        self._tail_start = tail_start
        self._on_tail: Callable[[], None] | None = on_tail

    def readinto(self, buffer: Any) -> int | None:
        count = super().readinto(buffer)
        if self._on_tail is not None:
            self.reached(self.tell())
        return count

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        position = super().seek(offset, whence)
        self.reached(position)
        return position

    def reached(self, position: int) -> None:
        if self._on_tail is not None and position >= self._tail_start:
            self._on_tail()
            self._on_tail = None

    def close(self) -> None:
        self._on_tail = None  # the probe and this file refer to each other until now
        super().close()


def iter_samples(path: str | Path) -> SampleStream:
    """Samples of a ULog in time order (see :class:`estimator.logs.SampleStream`), decoded
    at once: the stream's ``columns`` hold them column-wise, for the value and time checks."""
    path = Path(path)
    ulog, truncated, repair_note = _load(path)
    stream = SampleStream(path, "ulog", ())
    stream.sanity.repair_note = repair_note
    stream.truncated = truncated
    stream.bad_frames = int(ulog.file_corruption)
    stream.firmware = firmware(ulog.msg_info_dict)
    stream.sanity.vehicle_note = frame_note(_frame_type(ulog))
    stream.message_types = {d.name for d in ulog.data_list}
    stream.battery_types = ("battery_status",)
    stream.velocity_types = ("vehicle_local_position",)
    samples, stream.columns = _samples(ulog, stream)
    stream._it = iter(samples)
    return stream


def firmware(info: dict[str, Any]) -> str | None:
    """The firmware a ULog's info messages name: ``sys_name`` and the release of
    ``ver_sw_release`` (0xMMmmppTT: major, minor, patch, type; type 255 a release, below it
    a development build), else the first 8 digits of the ``ver_sw`` commit; None if neither."""
    name = str(info.get("sys_name", "PX4"))
    release = info.get("ver_sw_release")
    if isinstance(release, int) and release >> 8:
        major, minor, patch = release >> 24 & 0xFF, release >> 16 & 0xFF, release >> 8 & 0xFF
        kind = "" if release & 0xFF == _RELEASE_TYPE else " (development build)"
        return f"{name} v{major}.{minor}.{patch}{kind}"
    commit = info.get("ver_sw")
    return f"{name} (commit {str(commit)[:8]})" if commit else None


def _load(path: Path) -> tuple[ULog, bool, str | None]:
    """The log at ``path`` read by pyulog, whether it ends inside a message, and a sentence
    on a repair made before reading it (:mod:`estimator.logs.line_endings`), else None."""
    if path.is_dir():
        raise UserError(f"{path} is a directory, not a log file")
    with repaired_copy(path) as (source, note):
        try:
            probe = _ReadProbe(source)
        except FileNotFoundError:
            raise UserError(f"{path} does not exist") from None
        except OSError as exc:
            raise UserError(f"cannot read {path}: {exc.strerror}") from None
        try:
            # pyulog reports corruption with print(); our counters report it instead
            with contextlib.redirect_stdout(io.StringIO()):
                ulog = ULog(probe.file, message_name_filter_list=list(TOPICS))
        except Exception as exc:  # pyulog on a damaged file: ULogException, struct/index errors
            raise UserError(f"{path} is not a readable PX4 ULog: {exc}") from None
        finally:
            probe.file.close()
    return ulog, probe.last_read_short, note


def _frame_type(ulog: ULog) -> int | None:
    """``vehicle_status.system_type`` (MAV_TYPE) at its last record, None if not logged."""
    data = _dataset(ulog, "vehicle_status")
    types = None if data is None else data.get("system_type")
    return None if types is None or len(types) == 0 else int(types[-1])


def _dataset(ulog: ULog, topic: str) -> dict[str, Any] | None:
    """One instance of ``topic`` as a dict of arrays, or None if not logged: the lowest
    instance, except for batteries: the one with the most readings of a connected pack."""
    instances = sorted((d for d in ulog.data_list if d.name == topic), key=lambda d: d.multi_id)
    if not instances:
        return None
    if topic == "battery_status":
        best = max(instances, key=_connected_readings)  # max keeps the first of equals
        return dict(best.data)
    return dict(instances[0].data)


def _connected_readings(dataset: Any) -> int:
    data = dataset.data
    if "voltage_v" not in data:
        return 0
    with np.errstate(all="ignore"):
        volt = np.asarray(data["voltage_v"], dtype=float)
        ok = np.isfinite(volt) & (volt > 0.0) & _flag(data, "connected", len(volt))
    return int(np.count_nonzero(ok))


def _flag(data: dict[str, Any], name: str, n: int) -> np.ndarray:
    return np.asarray(data[name], dtype=bool) if name in data else np.ones(n, dtype=bool)


@dataclass(frozen=True)
class _Decoded:
    """Samples of one topic: the objects and their columns (same rows, same order)."""

    samples: list[Sample]
    columns: SampleColumns


def _decoded(
    sample_type: type,
    time_s: np.ndarray,
    fields: dict[str, np.ndarray],
    known: dict[str, np.ndarray] | None = None,
) -> _Decoded:
    """Samples of ``sample_type`` stamped ``time_s`` (s), with ``fields`` (its other fields
    by name, in its order), each None where ``known`` (by optional field) is False."""
    known = known or {}
    objects: list[list[Any]] = [time_s.tolist()]
    for name, column in fields.items():
        flags = known.get(name)
        if flags is not None and not flags.all():
            column = column.astype(object)
            column[~flags] = None
        objects.append(column.tolist())
    checked = {
        name: np.where(known[name], fields[name], 0.0) if name in known else fields[name]
        for name in CHECKED_FIELDS.get(sample_type, ())
    }
    checked_known = {name: flags for name, flags in known.items() if name in checked}
    columns = SampleColumns.of_type(sample_type, time_s, checked, checked_known)
    return _Decoded(of_columns(sample_type, *objects), columns)


def _local_velocities(data: dict[str, Any], stream: SampleStream) -> _Decoded:
    t = data["timestamp"] / 1e6
    v = np.column_stack([data["vx"], data["vy"], data["vz"]]).astype(float)
    alt = -np.asarray(data["z"], dtype=float)
    ok = _flag(data, "v_xy_valid", len(t)) & _flag(data, "v_z_valid", len(t))
    return _velocities(t, v, alt, ok, stream, "vehicle_local_position.vz")


def _gps_velocities(data: dict[str, Any], topic: str, stream: SampleStream) -> _Decoded:
    t = data["timestamp"] / 1e6
    v = np.column_stack([data["vel_n_m_s"], data["vel_e_m_s"], data["vel_d_m_s"]]).astype(float)
    if "altitude_msl_m" in data:
        alt = np.asarray(data["altitude_msl_m"], dtype=float)
    else:
        alt = np.asarray(data.get("alt", np.full(len(t), np.nan)), dtype=float) / 1e3
    ok = (np.asarray(data["fix_type"]) >= GPS_FIX_3D) & _flag(data, "vel_ned_valid", len(t))
    first = np.flatnonzero(ok & np.isfinite(alt))
    alt = alt - (alt[first[0]] if len(first) else np.nan)
    return _velocities(t, v, alt, ok, stream, f"{topic}.vel_d_m_s")


def _velocities(
    t: np.ndarray,
    v: np.ndarray,
    alt: np.ndarray,
    ok: np.ndarray,
    stream: SampleStream,
    source: str,
) -> _Decoded:
    """Velocity samples (NED m/s, height m or None where not finite) of the rows ``ok`` with
    a finite velocity; the others are counted as skipped."""
    ok = ok & np.isfinite(v).all(axis=1)
    stream.skipped += int(np.count_nonzero(~ok))
    if ok.any():
        stream.velocity_source = source
    rows = np.flatnonzero(ok)
    vn, ve, vd = v[rows].T
    alt = alt[rows]
    fields = {"vn_mps": vn, "ve_mps": ve, "vd_mps": vd, "alt_m": alt}
    return _decoded(VelocitySample, t[rows], fields, {"alt_m": np.isfinite(alt)})


def _batteries(data: dict[str, Any], stream: SampleStream) -> _Decoded:
    t = data["timestamp"] / 1e6
    volt = np.asarray(data["voltage_v"], dtype=float)
    n = len(t)
    nan = np.full(n, np.nan)
    current = np.asarray(data.get("current_a", nan), dtype=float)
    consumed = np.asarray(data.get("discharged_mah", nan), dtype=float)
    remaining = np.asarray(data.get("remaining", nan), dtype=float)
    ok = _flag(data, "connected", n) & np.isfinite(volt) & (volt > 0.0)
    stream.skipped += int(np.count_nonzero(~ok))
    rows = np.flatnonzero(ok)
    current, consumed, remaining = current[rows], consumed[rows], remaining[rows]
    fields = {
        "voltage_v": volt[rows],
        "current_a": current,
        "consumed_mah": consumed,
        "remaining_pct": remaining * 100.0,
    }
    known = {
        "current_a": _known(current),
        "consumed_mah": _known(consumed),
        "remaining_pct": remaining >= 0.0,
    }
    return _decoded(BatterySample, t[rows], fields, known)


def _arming(data: dict[str, Any]) -> _Decoded:
    armed = np.asarray(data["arming_state"]) == ARMING_STATE_ARMED
    rows = _changes(armed)
    return _decoded(ArmedSample, data["timestamp"][rows] / 1e6, {"armed": armed[rows]})


def _landing(data: dict[str, Any]) -> _Decoded:
    landed = np.asarray(data["landed"], dtype=bool)
    rows = _changes(landed)
    return _decoded(LandedSample, data["timestamp"][rows] / 1e6, {"on_ground": landed[rows]})


def _changes(flags: np.ndarray) -> np.ndarray:
    """Indices of the first flag and of every flag unlike the one before it."""
    return np.flatnonzero(np.concatenate([[True], flags[1:] != flags[:-1]]))


def _known(values: np.ndarray) -> np.ndarray:
    """Which values are known: finite and non-negative (PX4 logs −1 or NaN for unknown)."""
    return np.isfinite(values) & (values >= 0.0)


#: Fields each topic needs; a topic whose (damaged) format lacks them is not used.
_NEEDED = {
    "vehicle_status": ("timestamp", "arming_state"),
    "vehicle_local_position": ("timestamp", "vx", "vy", "vz", "z"),
    "battery_status": ("timestamp", "voltage_v"),
    "vehicle_land_detected": ("timestamp", "landed"),
    **dict.fromkeys(GPS_TOPICS, ("timestamp", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s", "fix_type")),
}


def _samples(ulog: ULog, stream: SampleStream) -> tuple[list[Sample], SampleColumns]:
    """The samples of every topic used, in time order, and their columns."""
    readers: tuple[tuple[str, Callable[[dict[str, Any]], _Decoded]], ...] = (
        ("vehicle_status", _arming),
        ("vehicle_land_detected", _landing),
        ("vehicle_local_position", lambda d: _local_velocities(d, stream)),
        *(
            (topic, lambda d, topic=topic: _gps_velocities(d, topic, stream))
            for topic in GPS_TOPICS
        ),
        ("battery_status", lambda d: _batteries(d, stream)),
    )
    parts: list[_Decoded] = []
    velocity = False  # a velocity sample given: the GPS topics are not read
    # values of a damaged file may not convert cleanly: they are dropped as non-finite
    with np.errstate(all="ignore"):
        for topic, read in readers:
            data = _dataset(ulog, topic)
            if data is None or (velocity and topic in GPS_TOPICS):
                continue
            if not all(name in data for name in _NEEDED[topic]):
                stream.bad_frames += 1
                continue
            part = read(data)
            velocity = velocity or (bool(part.samples) and topic in _VELOCITY_TOPICS)
            parts.append(part)
    if {"vehicle_local_position", "battery_status"} <= stream.message_types and not velocity:
        stream.missing = (
            "vehicle_local_position present but its velocity is never valid (v_xy_valid, "
            "v_z_valid), nor a GPS velocity with a 3-D fix; it has "
            f"{', '.join(sorted(stream.message_types))}"
        )
    samples = list(chain.from_iterable(part.samples for part in parts))
    if not parts:
        return samples, SampleColumns.of_samples(samples)
    columns = SampleColumns.joined([part.columns for part in parts])
    # stable: at equal times the arming and landed states come first, then velocity, then
    # battery
    order = np.argsort(columns.time_s, kind="stable")
    return list(map(samples.__getitem__, order.tolist())), columns.rows(order)
