"""Frames of unused message ids are dropped by their header before parsing (the daemon's
autopilot link), without changing what the decoder gets from the used ones."""

from __future__ import annotations

import random

from pymavlink.dialects.v20 import ardupilotmega
from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.decode import USED_MESSAGE_IDS, TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import WindSample


def autopilot_frames() -> list[bytes]:
    """An ArduCopter-like mix (MAVLink 2 and 1, common and ardupilotmega ids): most of it
    unused, as in a real stream."""
    apm = ardupilotmega.MAVLink(None, srcSystem=1, srcComponent=1)
    out: list[bytes] = []
    for k in range(40):
        t_ms = 1_000 + 100 * k
        msgs = [
            apm.heartbeat_encode(2, 3, 0, 0, 4),
            apm.attitude_encode(t_ms, 0.1, 0.2, 0.3, 0, 0, 0),
            apm.vfr_hud_encode(5.0, 5.0, 90, 50, 20.0, 0.0),
            apm.global_position_int_encode(t_ms, 0, 0, 20_000, 20_000, 500, -300, 0, 9000),
            apm.raw_imu_encode(t_ms * 1000, 1, 2, 3, 4, 5, 6, 7, 8, 9),
            apm.ahrs_encode(0, 0, 0, 0, 0, 0, 0),
            apm.sys_status_encode(0, 0, 0, 500, 22_000, 1_000, 80, 0, 0, 0, 0, 0, 0),
            apm.wind_encode(270.0, 4.0, 0.0),
            apm.esc_telemetry_1_to_4_encode([1] * 4, [2] * 4, [3] * 4, [4] * 4, [5] * 4, [6] * 4),
        ]
        for msg in msgs:
            apm.WIRE_PROTOCOL_VERSION = "1.0" if k % 5 == 0 and msg.id < 256 else "2.0"
            out.append(bytes(msg.pack(apm, force_mavlink1=apm.WIRE_PROTOCOL_VERSION == "1.0")))
    return out


def frame_id(msg: mavlink.MAVLink_message) -> int:
    """The id in the frame's header (ids outside the common dialect parse as unknown)."""
    buf = bytes(msg.get_msgbuf())
    return buf[7] | buf[8] << 8 | buf[9] << 16 if buf[0] == 0xFD else buf[5]


def used_of(messages: list[mavlink.MAVLink_message]) -> list[mavlink.MAVLink_message]:
    return [m for m in messages if frame_id(m) in USED_MESSAGE_IDS]


def fields(messages: list[mavlink.MAVLink_message]) -> list[tuple[int, bytes]]:
    return [(frame_id(m), bytes(m.get_msgbuf())) for m in messages]


def test_filtered_datagrams_give_the_used_messages_unparsed_others_counted() -> None:
    frames = autopilot_frames()
    everything = [m for f in frames for m in FrameParser().feed(f)]
    used = used_of(everything)
    kept, skipped = [], 0
    for f in frames:  # one frame a datagram, a parser each: what the UDP link does
        parser = FrameParser(USED_MESSAGE_IDS)
        kept += parser.feed(f)
        skipped += parser.skipped_frames
    assert fields(kept) == fields(used)
    assert skipped == len(everything) - len(used) > 0
    assert {frame_id(m) for m in kept} == {0, 1, 30, 33, 168}


def test_a_stream_cut_anywhere_gives_the_same_messages_as_whole_frames() -> None:
    data = b"".join(autopilot_frames())
    used = used_of(FrameParser().feed(data))
    rng = random.Random(3)
    parser, kept, at = FrameParser(USED_MESSAGE_IDS, stream=True), [], 0
    while at < len(data):
        size = rng.randint(1, 80)
        kept += parser.feed(data[at : at + size])
        at += size
    assert fields(kept) == fields(used)
    assert parser.skipped_frames > 0 and parser.bad_frames == 0


def test_garbage_between_frames_loses_no_used_message_and_is_counted() -> None:
    frames = autopilot_frames()
    rng = random.Random(5)
    chunks = []
    for f in frames:
        chunks.append(f)
        if rng.random() < 0.2:
            chunks.append(bytes(rng.randrange(1, 0xFD) for _ in range(rng.randint(1, 30))))
    data = b"".join(chunks)
    plain = FrameParser()
    used = used_of(plain.feed(data))
    filtered = FrameParser(USED_MESSAGE_IDS, stream=True)
    kept = [m for k in range(0, len(data), 64) for m in filtered.feed(data[k : k + 64])]
    assert fields(used_of(kept)) == fields(used)  # after garbage, frames are parsed unfiltered
    assert filtered.bad_frames > 0 and filtered.skipped_frames > 0


def test_ardupilot_wind_passes_the_filter_and_is_decoded() -> None:
    decoder = TelemetryDecoder()
    samples = []
    for f in autopilot_frames():
        for msg in FrameParser(USED_MESSAGE_IDS).feed(f):
            samples += decoder.decode(msg)
    winds = [s for s in samples if isinstance(s, WindSample)]
    assert winds and abs(winds[-1].wind_e_mps - 4.0) < 1e-5  # from 270°: blows towards east
