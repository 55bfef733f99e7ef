"""Frames decoded together (estimator.logs.frame_batch) equal pymavlink's frame-by-frame decode:
checksum, MAVLink 1 and 2 (trimmed payloads, signed frames), arrays, unknown ids, corruption."""

from __future__ import annotations

import random

import numpy as np
from pymavlink.dialects.v20 import common as mavlink
from pymavlink.generator.mavcrc import x25crc

from estimator.logs.frame_batch import FrameBatch, x25_crc


def _frames() -> list[bytes]:
    """Frames of the types a log reader decodes, MAVLink 1 and 2, some signed, one unknown."""
    plain = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    signing = mavlink.MAVLink(None, srcSystem=7, srcComponent=42)
    signing.signing.secret_key = bytes(range(32))
    signing.signing.sign_outgoing = True
    messages = [
        mavlink.MAVLink_heartbeat_message(2, 3, 129, 0, 4, 3),
        mavlink.MAVLink_attitude_message(123_456, 0.1, -0.2, 3.0, 0.0, 0.0, 0.0),
        mavlink.MAVLink_global_position_int_message(5000, 1, 2, 3, -4500, 250, -130, 0, 0),
        mavlink.MAVLink_local_position_ned_message(7000, 1.5, -2.5, -10.0, 0.25, 3.5, -0.5),
        mavlink.MAVLink_sys_status_message(0, 0, 0, 500, 11_800, -1, 80, 0, 0, 0, 0, 0, 0),
        mavlink.MAVLink_battery_status_message(
            0, 0, 0, 2500, [4000, 4010, 4020] + [65535] * 7, 1234, 567, -1, 55, 0, 0, [0, 0, 0, 0]
        ),
        mavlink.MAVLink_wind_cov_message(10, 1.5, -2.0, 0.0, 0.5, 0.5, 100.0, 1.0, 1.0),
        mavlink.MAVLink_vfr_hud_message(3.0, 3.0, 90, 50, 5.0, 0.0),
    ]
    out = []
    for msg in messages:
        out.append(msg.pack(plain, force_mavlink1=True))
        out.append(msg.pack(plain))  # MAVLink 2: trailing zero bytes of the payload trimmed
        out.append(msg.pack(signing))
    # ArduPilot WIND (168): outside the common dialect, an unknown message to pymavlink
    payload = np.array([30.0, 4.0, 0.0], dtype="<f4").tobytes()
    header = bytes([0xFD, len(payload), 0, 0, 9, 1, 1, 168, 0, 0])
    out.append(header + payload + b"\x12\x34")
    return out


def _decode_with_pymavlink(frame: bytes) -> mavlink.MAVLink_message | None:
    try:
        return mavlink.MAVLink(None).decode(bytearray(frame))
    except Exception:
        return None


def _batch(frames: list[bytes]) -> FrameBatch:
    data = b"".join(frames)
    lengths = np.array([len(f) for f in frames], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    return FrameBatch(data, starts, lengths)


def _same(ours: mavlink.MAVLink_message | None, theirs: mavlink.MAVLink_message | None) -> None:
    if theirs is None:
        assert ours is None
        return
    assert ours is not None
    assert type(ours) is type(theirs)
    assert ours.get_type() == theirs.get_type()
    if isinstance(theirs, mavlink.MAVLink_unknown):
        assert ours.get_msgbuf() == theirs.get_msgbuf()
        return
    assert ours.to_dict() == theirs.to_dict()
    assert vars(ours.get_header()) == vars(theirs.get_header())


def test_checksum_equals_pymavlink_x25_on_random_bytes() -> None:
    rng = random.Random(3)
    for length in (1, 9, 40):
        rows = [bytes(rng.randrange(256) for _ in range(length)) for _ in range(50)]
        ours = x25_crc(np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(50, length), 154)
        assert ours.tolist() == [x25crc(bytearray(r) + bytes([154])).crc for r in rows]


def test_every_frame_decodes_as_pymavlink_decodes_it() -> None:
    frames = _frames()
    batch = _batch(frames)
    for i, frame in enumerate(frames):
        _same(batch.message(i), _decode_with_pymavlink(frame))


def test_a_corrupt_frame_is_refused_like_pymavlink_and_its_neighbours_still_decode() -> None:
    frames = _frames()
    damaged = []
    for i, frame in enumerate(frames):
        if i % 3 == 1:  # flip one payload byte of every plain MAVLink 2 frame
            frame = frame[:10] + bytes([frame[10] ^ 0x40]) + frame[11:]
        damaged.append(frame)
    batch = _batch(damaged)
    refused = 0
    for i, frame in enumerate(damaged):
        theirs = _decode_with_pymavlink(frame)
        _same(batch.message(i), theirs)
        refused += theirs is None
    assert refused == 8  # the eight known types; the unknown WIND is not checked by pymavlink
