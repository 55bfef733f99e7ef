"""Many MAVLink frames of one log checked and decoded together with numpy.

A log reader knows where every frame is before it decodes any, so the work pymavlink does
frame by frame in Python — the X.25 checksum (CRC-16/MCRF4XX with the message's CRC_EXTRA),
the payload unpacking, the zero-padding of MAVLink 2's trimmed payloads — is done here once per
message type and payload length over all such frames at once. The result for each frame is the
message object pymavlink's ``MAVLink.decode`` would have returned (same class, same field
values, same header; the raw buffer is kept only for message types the dialect does not know,
which is what the decoder reads from them), or ``None`` where that call would have raised: the
frame is corrupt. So a log and a live link feed
:class:`~estimator.telemetry.decode.TelemetryDecoder` the same messages.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pymavlink.dialects.v20 import common as mavlink

IntArray = NDArray[np.int64]

_STX_V1 = 0xFE
_V1_HEADER, _V2_HEADER = 6, 10
_STRUCT_TO_NUMPY = {
    "B": "u1",
    "b": "i1",
    "H": "u2",
    "h": "i2",
    "I": "u4",
    "i": "i4",
    "Q": "u8",
    "q": "i8",
    "f": "f4",
    "d": "f8",
    "c": "S1",
}


def _crc_table() -> NDArray[np.uint16]:
    """The byte-at-a-time table of MAVLink's X.25 checksum (CRC-16/MCRF4XX)."""
    byte = np.arange(256, dtype=np.uint32)
    t = (byte ^ (byte << 4)) & 0xFF
    return ((t << 8) ^ (t << 3) ^ (t >> 4)).astype(np.uint16)


_CRC_TABLE = _crc_table()


def x25_crc(rows: NDArray[np.uint8], crc_extra: int) -> NDArray[np.uint16]:
    """MAVLink checksum of each row of ``rows`` (the frame bytes after STX, up to the CRC)
    followed by the message's ``crc_extra`` byte: one uint16 per row."""
    crc = np.full(len(rows), 0xFFFF, dtype=np.uint16)
    columns = [*np.ascontiguousarray(rows.T), np.full(len(rows), crc_extra, dtype=np.uint8)]
    for byte in columns:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc


def payload_dtype(struct_format: str) -> np.dtype[Any]:
    """numpy dtype of a pymavlink message's wire layout (``Message.unpacker.format``): one
    field ``f0, f1, …`` per wire field, arrays as sub-arrays, char arrays as bytes."""
    fields: list[tuple[str, str] | tuple[str, str, int]] = []
    for count, code in re.findall(r"(\d*)([a-zA-Z])", struct_format.lstrip("<")):
        name = f"f{len(fields)}"
        if code == "s":
            fields.append((name, f"S{count or 1}"))
        elif count and int(count) > 1:
            fields.append((name, "<" + _STRUCT_TO_NUMPY[code], int(count)))
        else:
            fields.append((name, "<" + _STRUCT_TO_NUMPY[code]))
    return np.dtype(fields)


class FrameBatch:
    """Frames of one buffer, decoded by :meth:`message` on demand after one vectorised pass.

    ``data`` holds the frames at ``starts`` (offsets of their STX), each ``lengths`` bytes long
    (header, payload, CRC and any signature: the caller found them whole).
    """

    def __init__(self, data: bytes, starts: IntArray, lengths: IntArray) -> None:
        self._data = data
        raw = np.frombuffer(data, dtype=np.uint8)
        v1 = raw[starts] == _STX_V1
        self._v1 = v1
        self._header_bytes = np.where(v1, _V1_HEADER, _V2_HEADER)
        self._payload_bytes = raw[starts + 1].astype(np.int64)
        self._seq = np.where(v1, raw[starts + 2], raw[np.minimum(starts + 4, len(raw) - 1)])
        self._incompat = np.where(v1, 0, raw[starts + 2])
        self._compat = np.where(v1, 0, raw[starts + 3])
        self.system = np.where(v1, raw[starts + 3], raw[np.minimum(starts + 5, len(raw) - 1)])
        self.component = np.where(v1, raw[starts + 4], raw[np.minimum(starts + 6, len(raw) - 1)])
        v2_id = (
            raw[np.minimum(starts + 7, len(raw) - 1)].astype(np.int64)
            | raw[np.minimum(starts + 8, len(raw) - 1)].astype(np.int64) << 8
            | raw[np.minimum(starts + 9, len(raw) - 1)].astype(np.int64) << 16
        )
        self.msgid = np.where(v1, raw[starts + 5], v2_id)
        self._starts = starts
        self._lengths = lengths
        # per frame: its group (message type, header and payload length) and row in it
        self._group = np.full(len(starts), -1, dtype=np.int64)
        self._row = np.zeros(len(starts), dtype=np.int64)
        self._columns: list[list[list[Any]]] = []
        self._types: list[type[mavlink.MAVLink_message]] = []
        self._decode_groups(raw)

    def _decode_groups(self, raw: NDArray[np.uint8]) -> None:
        known = np.isin(self.msgid, list(mavlink.mavlink_map))
        key = self.msgid << 16 | self._header_bytes << 8 | self._payload_bytes
        for k in np.unique(key[known]):
            members = np.flatnonzero(key == k)
            first = members[0]
            msgtype = mavlink.mavlink_map[int(self.msgid[first])]
            header, payload = int(self._header_bytes[first]), int(self._payload_bytes[first])
            frames = raw[self._starts[members, None] + np.arange(header + payload + 2)]
            sent = frames[:, -2].astype(np.uint16) | frames[:, -1].astype(np.uint16) << 8
            good = sent == x25_crc(frames[:, 1:-2], msgtype.crc_extra)
            members = members[good]
            if not len(members):
                continue
            size = msgtype.unpacker.size
            padded = np.zeros((len(members), size), dtype=np.uint8)
            keep = min(payload, size)
            padded[:, :keep] = frames[good, header : header + keep]
            values = padded.view(payload_dtype(msgtype.unpacker.format)).ravel()
            assert values.dtype.names is not None
            self._group[members] = len(self._types)
            self._row[members] = np.arange(len(members))
            self._columns.append([values[name].tolist() for name in values.dtype.names])
            self._types.append(msgtype)

    def message(self, i: int) -> mavlink.MAVLink_message | None:
        """Frame ``i`` as pymavlink's ``MAVLink.decode`` returns it; None for a corrupt frame
        (checksum wrong)."""
        msgid = int(self.msgid[i])
        if msgid not in mavlink.mavlink_map:
            start = int(self._starts[i])
            return mavlink.MAVLink_unknown(
                msgid, bytearray(self._data[start : start + int(self._lengths[i])])
            )
        group = int(self._group[i])
        if group < 0:
            return None
        columns, row = self._columns[group], int(self._row[i])
        msgtype = self._types[group]
        msg = msgtype(*_field_values(columns, msgtype.orders, row))
        msg._header = mavlink.MAVLink_header(
            msgid,
            int(self._incompat[i]),
            int(self._compat[i]),
            int(self._payload_bytes[i]),
            int(self._seq[i]),
            int(self.system[i]),
            int(self.component[i]),
        )
        return msg


def _field_values(columns: list[list[Any]], orders: Sequence[int], row: int) -> list[Any]:
    """A message's constructor arguments (declaration order) from the wire-order columns."""
    return [columns[wire][row] for wire in orders]
