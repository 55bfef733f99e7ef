"""MAVLink telemetry logs (``.tlog``; the IRIS+ ``.log`` files are the same thing).

A tlog is a sequence of records: an 8-byte big-endian receive stamp (µs since the Unix epoch)
followed by one MAVLink 1 (STX 0xFE) or MAVLink 2 (STX 0xFD) frame. The receive stamp is not
used: sample times come from the autopilot's ``time_boot_ms`` (:class:`TelemetryDecoder`), as
in the daemon, so a replay gives the same samples as a live run.

Speed: the frame header is read here and frames the decoder would not use (by message id, and
once it knows the autopilot by source, see :meth:`TelemetryDecoder.discards`) are skipped
without being parsed. A record without a frame start is corrupt: it is counted and the
reader re-synchronises on the next plausible record. A file that ends inside a record is read
up to the damage and flagged ``truncated``. A file converted to CRLF line endings as text is
read with the conversion undone, and says so (:mod:`estimator.logs.line_endings`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

from pymavlink.dialects.v20.common import MAVLink_message, mavlink_map

from estimator.errors import UserError
from estimator.logs import SampleStream
from estimator.logs.line_endings import crlf_undone
from estimator.telemetry.decode import USED_MESSAGE_IDS, TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.plausibility import InputLimits
from estimator.telemetry.samples import Sample
from estimator.telemetry.vehicle_kind import frame_note

STAMP_BYTES = 8
_STX_V1, _STX_V2 = 0xFE, 0xFD
_V1_OVERHEAD = 8  # STX len seq sys comp msgid + crc16
_V2_OVERHEAD = 12  # STX len incompat compat seq sys comp msgid[3] + crc16
_V2_SIGNATURE = 13
_SIGNED_FLAG = 0x01
#: SMART_BATTERY_INFO (MAVLink 2): the pack's identity, read for ``SampleStream.pack_id``.
_SMART_BATTERY_INFO = 370
#: The battery and velocity message types, as named in ``SampleStream.missing``.
BATTERY_TYPES = ("BATTERY_STATUS", "SYS_STATUS")
VELOCITY_TYPES = ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED")
#: A resync candidate's stamp must lie within this distance (µs) of the last good stamp.
_RESYNC_WINDOW_US = 3600 * 1_000_000


def iter_samples(path: Path, limits: InputLimits | None = None) -> SampleStream:
    """Stream the samples of a tlog (see :class:`estimator.logs.SampleStream`); values beyond
    ``limits`` are skipped and counted by the decoder."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    data, repair_note = crlf_undone(data)
    if len(data) <= STAMP_BYTES or data[STAMP_BYTES] not in (_STX_V1, _STX_V2):
        raise UserError(f"{path} is not a MAVLink telemetry log (no frame after the first stamp)")
    stream = SampleStream(path, "tlog", iter(()))
    stream.sanity.repair_note = repair_note
    stream.start_unix_s = _stamp_us(data, 0) / 1e6
    stream.battery_types = BATTERY_TYPES
    stream.velocity_types = VELOCITY_TYPES
    stream._it = _records(data, stream, TelemetryDecoder(limits=limits))
    return stream


def frame_length(data: bytes | memoryview, start: int) -> tuple[int, int] | None:
    """(total frame length, message id) of the frame at ``start``, or None if no STX there.

    The length may run past the end of ``data`` (a truncated frame): callers check.
    """
    if start + 6 > len(data):
        return None
    stx = data[start]
    if stx == _STX_V1:
        return data[start + 1] + _V1_OVERHEAD, data[start + 5]
    if stx == _STX_V2:
        if start + 10 > len(data):
            return None
        length = data[start + 1] + _V2_OVERHEAD
        if data[start + 2] & _SIGNED_FLAG:
            length += _V2_SIGNATURE
        msgid = data[start + 7] | data[start + 8] << 8 | data[start + 9] << 16
        return length, msgid
    return None


def frame_source(data: bytes, start: int) -> tuple[int, int]:
    """(system id, component id) of the frame at ``start`` (its header was checked)."""
    if data[start] == _STX_V1:
        return data[start + 3], data[start + 4]
    return data[start + 5], data[start + 6]


def _records(data: bytes, stream: SampleStream, decoder: TelemetryDecoder) -> Iterator[Sample]:
    parser = FrameParser()
    end = len(data)
    pos = 0
    last_good: int | None = None  # offset of the last good record (its stamp anchors resync)
    used = USED_MESSAGE_IDS
    found: set[int] = set()
    while pos < end:
        if pos + STAMP_BYTES >= end:
            stream.truncated = True
            break
        header = frame_length(data, pos + STAMP_BYTES)
        if header is None:
            stream.bad_frames += 1
            last_stamp_us = None if last_good is None else _stamp_us(data, last_good)
            pos = _resync(data, pos + 1, last_stamp_us)
            continue
        length, msgid = header
        frame_end = pos + STAMP_BYTES + length
        if frame_end > end:
            stream.truncated = True
            break
        last_good = pos
        if msgid == _SMART_BATTERY_INFO and stream.pack_id is None:
            stream.pack_id = _pack_id(parser.decode_frame(data[pos + STAMP_BYTES : frame_end]))
        if msgid not in used:
            stream.skipped += 1
            pos = frame_end
            continue
        found.add(msgid)
        if decoder.discards(msgid, *frame_source(data, pos + STAMP_BYTES)):
            stream.skipped += 1
            pos = frame_end
            continue
        msg = parser.decode_frame(data[pos + STAMP_BYTES : frame_end])
        pos = frame_end
        if msg is None:
            stream.bad_frames += 1
            continue
        yield from decoder.decode(msg)
    yield from decoder.flush()
    stream.count_checks(decoder.counts)
    stream.sanity.vertical_notes = list(decoder.vz_sense.notes)
    stream.firmware = decoder.firmware_text
    stream.sanity.vehicle_note = frame_note(decoder.frame_type)
    if decoder.velocity_type is not None:
        stream.velocity_source = f"{decoder.velocity_type}.vz"
    stream.autopilot = decoder.target
    stream.message_types = {_message_name(msgid) for msgid in found}


def _message_name(msgid: int) -> str:
    """The MAVLink name of a message id the decoder uses (ArduPilot's WIND is not common)."""
    entry = mavlink_map.get(msgid)
    return "WIND" if entry is None else str(entry.msgname)


def _pack_id(msg: MAVLink_message | None) -> str | None:
    """A SMART_BATTERY_INFO's serial number, else its device name; None if both are empty."""
    if msg is None:
        return None
    for text in (msg.serial_number, msg.device_name):
        value = str(text).strip("\x00 ")
        if value:
            return value
    return None


def _stamp_us(data: bytes, record: int) -> int:
    """The receive stamp (µs) of the record at ``record``."""
    return int(struct.unpack_from(">Q", data, record)[0])


def _resync(data: bytes, start: int, last_stamp_us: int | None) -> int:
    """Offset of the next record whose frame starts with STX and whose stamp is plausible."""
    end = len(data)
    pos = start
    while pos + STAMP_BYTES < end:
        candidates = [
            i
            for i in (data.find(bytes([s]), pos + STAMP_BYTES) for s in (_STX_V1, _STX_V2))
            if i >= 0
        ]
        if not candidates:
            return end
        record = min(candidates) - STAMP_BYTES
        stamp = _stamp_us(data, record)
        if last_stamp_us is None or abs(stamp - last_stamp_us) < _RESYNC_WINDOW_US:
            return record
        pos = record + 1
    return end
