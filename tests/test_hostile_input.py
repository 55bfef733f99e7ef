"""Hostile input: a real ArduCopter flight's frames with a million mutated frames among them.

The flight is ``tests/data/arducopter_guided.tlog`` (ArduCopter SITL, see tests/data/SOURCE.md).
Between its frames come, from fixed seeds: real frames with 1–3 bits flipped, real frames cut
short, random bytes, and frames with a valid CRC from the autopilot's own system/component id
carrying NaN, ±inf, 1e30, speeds and heights no multirotor reaches, voltages and powers beyond
the vehicle's pack, negative or huge currents and consumed charge, stamps hours away, and
forged reboots (up to four frames of an earlier clock). At most four frames with a stamp off
the clock come between two of the flight's stamped frames: five agreeing frames with nothing
of the real clock between them are a real reboot to the decoder (that case is tested on its
own, with the daemon's throttling).

In-process every datagram goes through what the daemon runs for a UDP datagram (a fresh
:class:`FrameParser`, :class:`TelemetryDecoder` with the vehicle's limits, :class:`Pipeline`);
the estimates must equal the clean flight's and the counters must show the skips. Over a real
socket, ``uav-energy run`` gets the flight with garbage among it, then garbage alone.
"""

from __future__ import annotations

import asyncio
import math
import random
import signal
import socket
import sys
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator.analysis.replay import replay_log
from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.logs.tlog import STAMP_BYTES, frame_length
from estimator.mavlink.publish import json_line
from estimator.physics.vehicle import BatterySpec, Vehicle, default_vehicle
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.plausibility import InputLimits
from estimator.telemetry.samples import BatterySample, Sample, VelocitySample
from estimator.telemetry.skip_counters import SKIP_COUNTERS

FLIGHT_TLOG = Path(__file__).parent / "data" / "arducopter_guided.tlog"
EXE = Path(sys.executable).with_name("uav-energy")
#: Mutated frames in the in-process test, over its two variants.
HOSTILE_FRAMES = 1_000_000
#: Frames with a stamp off the clock allowed between two stamped frames of the flight.
MAX_OFF_CLOCK_RUN = 4
_BAD_FLOATS = (math.nan, math.inf, -math.inf, 1e30, -1e30)
UINT32_MAX = 2**32 - 1


def sitl_vehicle() -> Vehicle:
    """The built-in model on SITL's 3S 3.3 Ah pack (as tests/test_ardupilot_sitl.py)."""
    return replace(default_vehicle(), name="sitl-quad", battery=BatterySpec(3.3, 3, 0.2))


def flight_frames(drop: frozenset[str] = frozenset()) -> list[bytes]:
    """The flight's frames in order, without the message types in ``drop``."""
    data = FLIGHT_TLOG.read_bytes()
    parser, out, pos = FrameParser(), [], 0
    while pos + STAMP_BYTES < len(data):
        header = frame_length(data, pos + STAMP_BYTES)
        assert header is not None
        frame = data[pos + STAMP_BYTES : pos + STAMP_BYTES + header[0]]
        pos += STAMP_BYTES + header[0]
        msg = parser.decode_frame(frame)
        if msg is not None and msg.get_type() not in drop:
            out.append(frame)
    return out


class Hostile:
    """Mutated datagrams from one seed. ``now_ms`` is the flight's clock (time_boot_ms) when
    a datagram is made; values-only frames carry it, so only their values are wrong."""

    def __init__(self, seed: int, frames: list[bytes], limits: InputLimits) -> None:
        self.rng = random.Random(seed)
        self.frames = frames
        self.limits = limits
        self.codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        self.bad_values: list[Callable[[int], mavlink.MAVLink_message]] = [
            self._local_position_not_finite,
            self._global_position_beyond_limits,
            self._sys_status_beyond_pack,
            self._battery_status_beyond_pack,
        ]

    def garbage(self) -> bytes:
        """A real frame with bits flipped or cut short, or random bytes."""
        rng = self.rng
        kind = rng.randrange(3)
        frame = rng.choice(self.frames)
        if kind == 0:
            flipped = bytearray(frame)
            for bit in rng.sample(range(8 * len(frame)), rng.randint(1, 3)):  # distinct bits
                flipped[bit // 8] ^= 1 << (bit % 8)
            return bytes(flipped)
        if kind == 1:
            return frame[: rng.randrange(1, len(frame))]
        head = rng.choice((b"", b"\xfd", b"\xfe"))
        return head + rng.randbytes(rng.randint(1, 280))

    def values(self, now_ms: int) -> bytes:
        """A valid frame of the autopilot carrying values beyond the limits."""
        return self.rng.choice(self.bad_values)(now_ms).pack(self.codec)

    def off_clock(self, now_ms: int, frames: int) -> list[bytes]:
        """``frames`` plausible frames stamped off the clock: hours ahead or anywhere in the
        32-bit range (one frame), or a forged reboot (frames of one earlier clock)."""
        rng = self.rng
        if frames == 1 or now_ms < 20_000:
            start_ms = rng.choice(
                (now_ms + rng.randint(10_000, 36_000_000), rng.randint(0, UINT32_MAX))
            )
            frames = 1
        else:
            start_ms = rng.randint(0, now_ms - 10_000)
        out = []
        for k in range(frames):
            t_ms = min(start_ms + 100 * k, UINT32_MAX)
            if rng.random() < 0.5:
                msg = self.codec.attitude_encode(t_ms, 0.01, -0.02, 1.5, 0.0, 0.0, 0.0)
            else:
                msg = self.codec.global_position_int_encode(
                    t_ms, -353632611, 1491652300, 594000, 10000, 150, -80, 10, 9000
                )
            out.append(msg.pack(self.codec))
        return out

    def _local_position_not_finite(self, now_ms: int) -> mavlink.MAVLink_message:
        v = [0.5, -0.3, 0.1, 1.0, 2.0, -10.0]
        v[self.rng.randrange(2, 6)] = self.rng.choice(_BAD_FLOATS)  # z, vx, vy or vz
        if self.rng.random() < 0.3:
            v[3] = self.rng.choice((250.0, -250.0))  # beyond any multirotor's speed
        return self.codec.local_position_ned_encode(now_ms, *v)

    def _global_position_beyond_limits(self, now_ms: int) -> mavlink.MAVLink_message:
        rng = self.rng
        vx, vz, rel_alt_mm = 300, -50, 10_000
        field = rng.randrange(3)
        if field == 0:
            vx = rng.choice((-1, 1)) * rng.randint(20_001, 32_767)  # cm/s: above 200 m/s
        elif field == 1:
            vz = rng.choice((-1, 1)) * rng.randint(10_001, 32_767)
        else:
            rel_alt_mm = rng.choice((-1, 1)) * rng.randint(20_000_001, 2**31 - 1)
        return self.codec.global_position_int_encode(
            now_ms, -353632611, 1491652300, 594000, rel_alt_mm, vx, 20, vz, 9000
        )

    def _sys_status_beyond_pack(self, now_ms: int) -> mavlink.MAVLink_message:
        rng = self.rng
        voltage_mv, current_ca = 12_400, 2_800
        kind = rng.randrange(3)
        if kind == 0:
            voltage_mv = rng.randint(13_501, 65_534)  # above 4.5 V per cell of 3S
        elif kind == 1:
            current_ca = rng.randint(-32_768, -2_001)  # below -20 A
        else:  # V·I above the power limit (10 × hover power)
            voltage_mv = 13_400
            above_ca = math.ceil(self.limits.max_power_w / 13.4 * 100) + 1
            current_ca = rng.randint(above_ca, 32_767)
        return self.codec.sys_status_encode(
            0, 0, 0, 500, voltage_mv, current_ca, 80, 0, 0, 0, 0, 0, 0
        )

    def _battery_status_beyond_pack(self, now_ms: int) -> mavlink.MAVLink_message:
        rng = self.rng
        cells = [4_100, 4_100, 4_100] + [65_535] * 7
        current_ca, consumed_mah = 2_800, 500
        kind = rng.randrange(3)
        if kind == 0:
            cells[3] = rng.randint(1_500, 60_000)  # a fourth cell: above 13.5 V
        elif kind == 1:
            consumed_mah = rng.choice(
                (rng.randint(-(2**31), -2), rng.randint(10**6 + 1, 2**31 - 1))
            )
        else:
            current_ca = rng.randint(-32_768, -2_001)
        return self.codec.battery_status_encode(
            0, 0, 0, 2_500, cells, current_ca, consumed_mah, -1, 80
        )


def hostile_stream(
    frames: list[bytes], total: int, seed: int, limits: InputLimits, velocity: str
) -> Iterator[tuple[bool, bytes]]:
    """(is the flight's, datagram): the flight's frames in order, ``total`` mutated ones among
    them; at most :data:`MAX_OFF_CLOCK_RUN` frames off the clock between two frames that
    carry the clock to the decoder (ATTITUDE and the ``velocity`` message in use)."""
    hostile = Hostile(seed, frames, limits)
    rng = hostile.rng
    parser = FrameParser()
    per_gap, extra = divmod(total, len(frames))
    now_ms, off_clock_run = 0, 0
    for i, frame in enumerate(frames):
        msg = parser.decode_frame(frame)
        assert msg is not None
        stamped = msg.get_type() in ("ATTITUDE", velocity)
        if stamped:
            now_ms = msg.time_boot_ms
        n = per_gap + (i < extra)
        burst: list[bytes] = []
        if off_clock_run < MAX_OFF_CLOCK_RUN and rng.random() < 0.5:
            frames_off = rng.randint(1, MAX_OFF_CLOCK_RUN - off_clock_run)
            burst = hostile.off_clock(now_ms, frames_off)
            off_clock_run += frames_off
        at = rng.randint(0, max(n - len(burst), 0))
        for k in range(max(n - len(burst), 0)):
            if k == at:
                yield from ((False, b) for b in burst)
            yield False, hostile.values(now_ms) if rng.random() < 0.4 else hostile.garbage()
        if at >= max(n - len(burst), 0):
            yield from ((False, b) for b in burst)
        yield True, frame
        if stamped:  # the flight's clock is heard: stamps off it start over
            off_clock_run = 0


def run_datagrams(
    datagrams: Iterator[tuple[bool, bytes]], vehicle: Vehicle
) -> tuple[list[Estimate], TelemetryDecoder, int, int]:
    """Every datagram as the daemon takes one over UDP: (estimates, decoder, bad frames,
    datagrams)."""
    decoder = TelemetryDecoder(limits=vehicle.input_limits())
    pipeline = Pipeline(vehicle)
    estimates, bad_frames, n = [], 0, 0
    for _, data in datagrams:
        n += 1
        parser = FrameParser()
        for msg in parser.feed(data):
            for sample in decoder.decode(msg):
                if (estimate := pipeline.process(sample)) is not None:
                    estimates.append(estimate)
        bad_frames += parser.bad_frames
    if (last := pipeline.flush()) is not None:
        estimates.append(last)
    return estimates, decoder, bad_frames, n


def assert_same_estimates(got: list[Estimate], want: list[Estimate]) -> None:
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        for key, value in w.as_dict().items():
            other = g.as_dict()[key]
            if isinstance(value, float):
                assert other == pytest.approx(value, rel=1e-9, abs=1e-9, nan_ok=True), key
            else:
                assert other == value, key


@pytest.mark.parametrize(
    ("velocity", "drop", "seed"),
    [
        ("GLOBAL_POSITION_INT", frozenset(), 11),
        ("LOCAL_POSITION_NED", frozenset({"GLOBAL_POSITION_INT"}), 12),
    ],
)
def test_a_million_hostile_frames_leave_the_estimates_of_the_clean_flight(
    velocity: str, drop: frozenset[str], seed: int
) -> None:
    """Half the million per variant: velocity from GLOBAL_POSITION_INT (integers: limits and
    stamps) or from LOCAL_POSITION_NED (floats: NaN, ±inf, 1e30 reach the used source)."""
    vehicle = sitl_vehicle()
    frames = flight_frames(drop)
    clean, clean_decoder, _, _ = run_datagrams(((True, f) for f in frames), vehicle)
    assert clean_decoder.velocity_type == velocity
    assert len(clean) > 60 and clean[-1].energy_remaining_wh > 0
    assert not any(clean_decoder.counts[k] for k in SKIP_COUNTERS)

    total = HOSTILE_FRAMES // 2
    hostile, decoder, bad_frames, n = run_datagrams(
        hostile_stream(frames, total, seed, vehicle.input_limits(), velocity), vehicle
    )

    assert n == len(frames) + total
    assert_same_estimates(hostile, clean)
    counts = decoder.counts
    assert decoder.velocity_type == velocity
    assert counts["reboots"] == counts["clock_jumps"] == counts["clock_gaps"] == 0
    assert bad_frames > total // 10  # bit flips and random bytes: CRC or framing errors
    expected_skips = ["voltage_implausible", "current_implausible", "consumed_implausible"]
    expected_skips += ["time_jump", "velocity_beyond_limits", "altitude_implausible"]
    if velocity == "LOCAL_POSITION_NED":
        expected_skips.append("velocity_not_finite")
    for key in expected_skips:
        assert counts[key] > 1000, (key, dict(counts))


def test_a_forged_reboot_of_five_frames_is_believed_then_undone_when_the_clock_returns() -> None:
    """Five agreeing frames of an earlier clock look like a reboot; the real clock coming back
    re-references again (a jump, not a gap: the time between is not integrated). The energy
    state survives: the estimates after it stay close to the clean flight's."""
    vehicle = sitl_vehicle()
    frames = flight_frames()
    clean, _, _, _ = run_datagrams(((True, f) for f in frames), vehicle)
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    forged = [
        codec.attitude_encode(5_000 + 100 * k, 0, 0, 0, 0, 0, 0).pack(codec) for k in range(5)
    ]
    at = len(frames) // 2
    stream = [(True, f) for f in frames[:at]] + [(False, f) for f in forged]
    stream += [(True, f) for f in frames[at:]]
    estimates, decoder, _, _ = run_datagrams(iter(stream), vehicle)
    assert decoder.counts["reboots"] == 1 and decoder.counts["clock_jumps"] == 1
    assert decoder.counts["clock_gaps"] == 0
    assert estimates[-1].time_s == pytest.approx(clean[-1].time_s)
    assert estimates[-1].energy_remaining_wh == pytest.approx(
        clean[-1].energy_remaining_wh, rel=0.02
    )


# -- over a real socket, into `uav-energy run` ------------------------------------------------


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Heartbeats(asyncio.DatagramProtocol):
    """The daemon's HEARTBEAT.system_status as it arrives (component 191)."""

    def __init__(self) -> None:
        self.codec = mavlink.MAVLink(None)
        self.codec.robust_parsing = True
        self.states: list[int] = []

    def datagram_received(self, data: bytes, addr: object) -> None:
        for msg in self.codec.parse_buffer(data) or []:
            if msg.get_type() == "HEARTBEAT" and msg.get_srcComponent() == 191:
                self.states.append(msg.system_status)


async def test_the_daemon_over_udp_survives_garbage_and_stays_honest(tmp_path: Path) -> None:
    """The flight with 10 hostile datagrams per frame into ``uav-energy run`` over UDP: the
    JSON estimates equal the replay of the clean flight; then garbage alone until HEARTBEAT
    turns CRITICAL (stale; within 20 s): no estimate comes from it, the log counts the skips,
    and SIGTERM stops the daemon with exit code 0."""
    vehicle = sitl_vehicle()
    vehicle_file = tmp_path / "sitl.toml"
    vehicle.save(vehicle_file)
    limits = vehicle.input_limits()
    expected = [json_line(e) for e in replay_log(FLIGHT_TLOG, vehicle).estimates]
    frames = flight_frames()
    daemon_port, gcs_port = _free_udp_port(), _free_udp_port()
    loop = asyncio.get_running_loop()
    gcs, heartbeats = await loop.create_datagram_endpoint(
        _Heartbeats, local_addr=("127.0.0.1", gcs_port)
    )
    out_path, log_path = tmp_path / "daemon.jsonl", tmp_path / "daemon.log"
    args = ["run", "--connect", f"udpin:127.0.0.1:{daemon_port}", "--json", "-"]
    args += ["--vehicle", str(vehicle_file), "--publish", f"udpout:127.0.0.1:{gcs_port}"]
    with out_path.open("wb") as out, log_path.open("wb") as err:
        proc = await asyncio.create_subprocess_exec(str(EXE), *args, stdout=out, stderr=err)
    try:
        async with asyncio.timeout(60):
            while not heartbeats.states:  # the daemon is up
                await asyncio.sleep(0.05)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as autopilot:
            for i, (_, data) in enumerate(
                hostile_stream(frames, 10 * len(frames), 13, limits, "GLOBAL_POSITION_INT")
            ):
                autopilot.sendto(data, ("127.0.0.1", daemon_port))
                if i % 20 == 19:  # paced: the kernel must not drop the flight's datagrams
                    await asyncio.sleep(0.002)
            async with asyncio.timeout(30):
                while out_path.read_bytes().count(b"\n") < len(expected) - 1:
                    await asyncio.sleep(0.05)
            lines_before = out_path.read_bytes().count(b"\n")
            beats_before = len(heartbeats.states)
            garbage = Hostile(14, frames, limits)
            # garbage alone, the flight's clock stopped, until a heartbeat says stale: the link
            # is stale 3 s after its last believed message, which the daemon may still be
            # working through when the output is complete, and a heartbeat tells it at most
            # 2 s later (its watchdog runs after each beat)
            async with asyncio.timeout(20):
                while mavlink.MAV_STATE_CRITICAL not in heartbeats.states[beats_before:]:
                    for _ in range(20):
                        data = (
                            garbage.values(94_000)
                            if garbage.rng.random() < 0.4
                            else garbage.garbage()
                        )
                        autopilot.sendto(data, ("127.0.0.1", daemon_port))
                    await asyncio.sleep(0.002)
        late = heartbeats.states[beats_before:]
        assert out_path.read_bytes().count(b"\n") == lines_before  # nothing estimated from it
    finally:
        if proc.returncode is None:
            proc.send_signal(signal.SIGTERM)
        await asyncio.wait_for(proc.wait(), 15)
        gcs.close()
    log = log_path.read_text()
    assert proc.returncode == 0, log
    assert "Traceback" not in log and "internal error" not in log
    lines = out_path.read_text().splitlines()
    assert lines == expected
    assert mavlink.MAV_STATE_ACTIVE in heartbeats.states[:beats_before]
    assert late and late[-1] == mavlink.MAV_STATE_CRITICAL, late
    assert "link silent" in log
    assert "implausible inputs skipped so far" in log
    stopped = log[log.index("stopped:") :]
    # stamps off the clock never reach the decoder: the autopilot lock drops them unproven
    counters = ("decode_voltage_implausible=", "autopilot_off_clock_frames=", "link_bad_frames=")
    for counter in counters:
        assert counter in stopped


# -- the clock on its own -------------------------------------------------------------------------


def _decoder_run(stamps_ms: list[int]) -> tuple[TelemetryDecoder, list[Sample]]:
    """GLOBAL_POSITION_INT frames (1 m/s north) with these stamps, each followed by a
    SYS_STATUS, through a decoder: (decoder, samples)."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = FrameParser()
    decoder = TelemetryDecoder()
    samples: list[Sample] = []
    heartbeat = codec.heartbeat_encode(2, 3, 0, 0, 4).pack(codec)
    for msg in parser.feed(heartbeat):
        decoder.decode(msg)
    for t_ms in stamps_ms:
        for frame in (
            codec.global_position_int_encode(t_ms, 0, 0, 0, 5_000, 100, 0, 0, 0).pack(codec),
            codec.sys_status_encode(0, 0, 0, 500, 12_000, 1_000, 80, 0, 0, 0, 0, 0, 0).pack(codec),
        ):
            for msg in parser.feed(frame):
                samples += decoder.decode(msg)
    return decoder, samples


def _kinds(samples: list[Sample]) -> list[tuple[str, float]]:
    return [(type(s).__name__[:3], round(s.time_s, 3)) for s in samples]


def test_one_stamp_hours_away_is_skipped_and_its_battery_reading_keeps_its_place() -> None:
    base = list(range(1_000, 3_000, 100))
    decoder, samples = _decoder_run([*base[:10], 3 * 3_600_000, *base[10:]])
    _, clean = _decoder_run(base)
    assert decoder.counts["time_jump"] == 1
    velocity = [s for s in samples if isinstance(s, VelocitySample)]
    assert velocity == [s for s in clean if isinstance(s, VelocitySample)]
    battery = _kinds([s for s in samples if isinstance(s, BatterySample)])
    assert battery[:10] == _kinds([s for s in clean if isinstance(s, BatterySample)])[:10]
    assert battery[10] == ("Bat", 1.9)  # the reading after the odd frame, on the real clock


def test_a_real_reboot_is_believed_after_five_frames_and_loses_nothing() -> None:
    decoder, samples = _decoder_run([*range(100_000, 102_000, 100), *range(500, 1_500, 100)])
    assert decoder.counts["reboots"] == 1 and decoder.counts["time_jump"] == 4
    after = _kinds(samples)[_kinds(samples).index(("Reb", 0.5)) :]
    # every frame of the new clock is there, the battery readings on its time
    assert [k for k in after if k[0] == "Vel"] == [
        ("Vel", t / 1000) for t in range(500, 1_500, 100)
    ]
    assert ("Bat", 0.5) in after and ("Bat", 0.9) in after


def test_a_short_gap_is_integrated_and_a_long_jump_is_a_new_reference() -> None:
    gap, _ = _decoder_run([*range(1_000, 3_000, 100), *range(30_000, 31_000, 100)])
    assert gap.counts["clock_gaps"] == 1 and gap.counts["clock_jumps"] == 0
    jump, samples = _decoder_run([*range(1_000, 3_000, 100), *range(1_000_000, 1_001_000, 100)])
    assert jump.counts["clock_jumps"] == 1 and jump.counts["clock_gaps"] == 0
    assert ("Reb", 1000.0) in _kinds(samples)
