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
- ``vehicle_status``: ``arming_state`` (2 = armed), as changes;
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
import math
from collections.abc import Iterator
from operator import attrgetter
from pathlib import Path
from typing import Any

import numpy as np
from pyulog import ULog

from estimator.errors import UserError
from estimator.logs import SampleStream
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    LandedSample,
    Sample,
    VelocitySample,
)

#: The GPS topics, most preferred first (velocity when the local position has none).
GPS_TOPICS = ("vehicle_gps_position", "sensor_gps")
TOPICS = (
    "vehicle_local_position",
    "battery_status",
    "vehicle_status",
    "vehicle_land_detected",
    *GPS_TOPICS,
)
#: A GPS ``fix_type`` at least this is a 3-D fix.
GPS_FIX_3D = 3
#: ``vehicle_status.arming_state`` value of an armed vehicle (PX4 ≥ 1.8).
ARMING_STATE_ARMED = 2
#: The type byte of ``ver_sw_release`` for a release build.
_RELEASE_TYPE = 0xFF


_buffered_read = io.BufferedReader.read


class _ReadProbe(io.BufferedReader):
    """A file whose last read tells whether pyulog stopped inside a message."""

    last_read_short = False

    def read(self, size: int | None = -1) -> bytes:
        # the unbound C method, not super(): pyulog reads each message header and body
        # separately, and super()'s lookup doubled the cost of a read
        data = _buffered_read(self, size)
        self.last_read_short = size is not None and 0 < len(data) < size
        return data


def iter_samples(path: str | Path) -> SampleStream:
    """Samples of a ULog in time order (see :class:`estimator.logs.SampleStream`)."""
    path = Path(path)
    ulog, truncated = _load(path)
    stream = SampleStream(path, "ulog", ())
    stream.truncated = truncated
    stream.bad_frames = int(ulog.file_corruption)
    stream.firmware = firmware(ulog.msg_info_dict)
    stream.message_types = {d.name for d in ulog.data_list}
    stream.battery_types = ("battery_status",)
    stream.velocity_types = ("vehicle_local_position",)
    stream._it = _samples(ulog, stream)
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


def _load(path: Path) -> tuple[ULog, bool]:
    if path.is_dir():
        raise UserError(f"{path} is a directory, not a log file")
    try:
        probe = _ReadProbe(io.FileIO(path, "rb"))
    except FileNotFoundError:
        raise UserError(f"{path} does not exist") from None
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    try:
        # pyulog reports corruption with print(); our counters report it instead
        with contextlib.redirect_stdout(io.StringIO()):
            ulog = ULog(probe, message_name_filter_list=list(TOPICS))
    except Exception as exc:  # pyulog on a damaged file: ULogException, struct/index errors
        raise UserError(f"{path} is not a readable PX4 ULog: {exc}") from None
    finally:
        probe.close()
    return ulog, probe.last_read_short


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


def _local_velocities(data: dict[str, Any], stream: SampleStream) -> list[Sample]:
    t = data["timestamp"] / 1e6
    v = np.column_stack([data["vx"], data["vy"], data["vz"]]).astype(float)
    alt = -np.asarray(data["z"], dtype=float)
    ok = _flag(data, "v_xy_valid", len(t)) & _flag(data, "v_z_valid", len(t))
    return _velocities(t, v, alt, ok, stream, "vehicle_local_position.vz")


def _gps_velocities(data: dict[str, Any], topic: str, stream: SampleStream) -> list[Sample]:
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
) -> list[Sample]:
    """Velocity samples (NED m/s, height m) of the rows ``ok`` with a finite velocity; the
    others are counted as skipped. Built column-wise: each column is taken out of numpy once."""
    ok = ok & np.isfinite(v).all(axis=1)
    stream.skipped += int(np.count_nonzero(~ok))
    if ok.any():
        stream.velocity_source = source
    rows = np.flatnonzero(ok)
    alts = [a if math.isfinite(a) else None for a in alt[rows].tolist()]
    return list(map(VelocitySample, t[rows].tolist(), *v[rows].T.tolist(), alts))


def _batteries(data: dict[str, Any], stream: SampleStream) -> list[Sample]:
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
    percent = [None if not r >= 0.0 else r * 100.0 for r in remaining[rows].tolist()]
    return list(
        map(
            BatterySample,
            t[rows].tolist(),
            volt[rows].tolist(),
            _known(current[rows]),
            _known(consumed[rows]),
            percent,
        )
    )


def _arming(data: dict[str, Any]) -> list[Sample]:
    armed = np.asarray(data["arming_state"]) == ARMING_STATE_ARMED
    t = data["timestamp"] / 1e6
    rows = _changes(armed)
    return list(map(ArmedSample, t[rows].tolist(), armed[rows].tolist()))


def _landing(data: dict[str, Any]) -> list[Sample]:
    landed = np.asarray(data["landed"], dtype=bool)
    t = data["timestamp"] / 1e6
    rows = _changes(landed)
    return list(map(LandedSample, t[rows].tolist(), landed[rows].tolist()))


def _changes(flags: np.ndarray) -> np.ndarray:
    """Indices of the first flag and of every flag unlike the one before it."""
    return np.flatnonzero(np.concatenate([[True], flags[1:] != flags[:-1]]))


def _known(values: np.ndarray) -> list[float | None]:
    """Each finite non-negative value, else None (PX4 logs −1 or NaN for unknown)."""
    return [x if x >= 0.0 and math.isfinite(x) else None for x in values.tolist()]


#: Fields each topic needs; a topic whose (damaged) format lacks them is not used.
_NEEDED = {
    "vehicle_status": ("timestamp", "arming_state"),
    "vehicle_local_position": ("timestamp", "vx", "vy", "vz", "z"),
    "battery_status": ("timestamp", "voltage_v"),
    "vehicle_land_detected": ("timestamp", "landed"),
    **dict.fromkeys(GPS_TOPICS, ("timestamp", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s", "fix_type")),
}


def _samples(ulog: ULog, stream: SampleStream) -> Iterator[Sample]:
    readers = (
        ("vehicle_status", lambda d: _arming(d)),
        ("vehicle_land_detected", lambda d: _landing(d)),
        ("vehicle_local_position", lambda d: _local_velocities(d, stream)),
        *(
            (topic, lambda d, topic=topic: _gps_velocities(d, topic, stream))
            for topic in GPS_TOPICS
        ),
        ("battery_status", lambda d: _batteries(d, stream)),
    )
    merged: list[Sample] = []
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
            samples = read(data)
            velocity = velocity or any(isinstance(s, VelocitySample) for s in samples)
            merged.extend(samples)
    if {"vehicle_local_position", "battery_status"} <= stream.message_types and not velocity:
        stream.missing = (
            "vehicle_local_position present but its velocity is never valid (v_xy_valid, "
            "v_z_valid), nor a GPS velocity with a 3-D fix; it has "
            f"{', '.join(sorted(stream.message_types))}"
        )
    # stable sort: at equal times the arming and landed states come first, then velocity,
    # then battery
    merged.sort(key=attrgetter("time_s"))
    yield from merged
