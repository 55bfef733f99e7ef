"""Attacks on the autopilot link over real UDP sockets: nobody but the autopilot is listened to
or answered, and forged reboots change nothing.

The autopilot replays a real ArduCopter SITL flight (``tests/data/arducopter_guided.tlog``) at
10× into ``udpin``; a forger sends on its own port (or in-band, from the autopilot's socket).
One task sends every datagram of both in the order of one schedule (the tlog's receive stamps
scaled, the forger's period), so what the daemon receives is the same on every run; the test
waits until the daemon has taken every datagram. Each attack holds when the autopilot keeps
the lock, the daemon gives at least 99 % of the clean flight's estimates and they equal the
clean flight's within 1 %, and a forger on its own socket receives nothing.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
import math
import random
import socket
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_hostile_input import FLIGHT_TLOG, sitl_vehicle
from test_service import replay, running, wait_for

from estimator.estimation.estimate import Estimate
from estimator.logs.tlog import STAMP_BYTES, frame_length
from estimator.mavlink import autopilot_lock
from estimator.mavlink.autopilot_lock import AutopilotLock
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.service import Service
from estimator.telemetry.frames import FrameParser

#: The flight is sent this many times faster than it was recorded (SITL ran at 5×).
SPEEDUP = 10.0
SITL_SPEEDUP = 5.0
#: Seconds the forger speaks before the autopilot.
LEAD_S = 1.0
AUTOPILOT = (1, 1)


@dataclass(frozen=True, slots=True)
class Record:
    """A frame of the flight: when it was received (s from the first), its bytes, message."""

    at_s: float
    frame: bytes
    msg: mavlink.MAVLink_message


@pytest.fixture(scope="module")
def sitl() -> list[Record]:
    data = FLIGHT_TLOG.read_bytes()
    parser, out, pos = FrameParser(), [], 0
    first_us = int.from_bytes(data[:STAMP_BYTES], "big")
    while pos + STAMP_BYTES < len(data):
        length = frame_length(data, pos + STAMP_BYTES)
        assert length is not None
        frame = data[pos + STAMP_BYTES : pos + STAMP_BYTES + length[0]]
        stamp_us = int.from_bytes(data[pos : pos + STAMP_BYTES], "big")
        msg = parser.decode_frame(frame)
        assert msg is not None
        out.append(Record((stamp_us - first_us) / 1e6, frame, msg))
        pos += STAMP_BYTES + length[0]
    return out


@pytest.fixture(scope="module")
def clean(sitl: list[Record]) -> list[Estimate]:
    """The clean flight's estimates (the daemon's equal a replay of the same bytes)."""
    return replay([r.msg for r in sitl], sitl_vehicle())


class Peer(asyncio.DatagramProtocol):
    """A UDP socket of its own towards the daemon; counts what it receives."""

    def __init__(self) -> None:
        self.received: list[mavlink.MAVLink_message] = []
        self.datagrams = 0
        self.sent = 0
        self.codec = mavlink.MAVLink(None)
        self.codec.robust_parsing = True
        self.transport: asyncio.DatagramTransport | None = None

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.datagrams += 1
        parsed = self.codec.parse_buffer(data) or []
        self.received += [m for m in parsed if not isinstance(m, mavlink.MAVLink_bad_data)]

    def send(self, data: bytes) -> None:
        assert self.transport is not None
        self.transport.sendto(data)
        self.sent += 1


async def peer_to(port: int) -> Peer:
    loop = asyncio.get_running_loop()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    sock.bind(("127.0.0.1", 0))
    sock.connect(("127.0.0.1", port))
    transport, peer = await loop.create_datagram_endpoint(Peer, sock=sock)
    peer.transport = transport
    return peer


#: A forger's schedule: (s after the forger starts, frame) in time order, given a codec
#: with its ids.
Forgery = Callable[[], Iterator[tuple[float, bytes]]]


def codec(system: int, component: int = 1) -> mavlink.MAVLink:
    return mavlink.MAVLink(None, srcSystem=system, srcComponent=component)


def heartbeats(
    system: int, rate_hz: float, duration_s: float, vehicle_type: int = mavlink.MAV_TYPE_QUADROTOR
) -> Iterator[tuple[float, bytes]]:
    """ArduPilot HEARTBEATs (disarmed) at ``rate_hz``."""
    mav = codec(system)
    for k in range(int(duration_s * rate_hz)):
        hb = mav.heartbeat_encode(vehicle_type, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 81, 0, 3)
        yield k / rate_hz, hb.pack(mav)


def forged_reboots(
    start_s: float, rate_hz: float, duration_s: float, vehicle_type: int | None = None
) -> Iterator[tuple[float, bytes]]:
    """Resets of the autopilot's clock (its ids): ``rate_hz`` times a second, five agreeing
    frames of a clock at 1 s each (attitude and position a quadrotor at rest could send),
    with a HEARTBEAT of ``vehicle_type`` after each when given."""
    mav = codec(*AUTOPILOT)
    for k in range(int(duration_s * rate_hz)):
        at_s = start_s + k / rate_hz
        for j in range(5):
            t_ms = 1_000 + 100 * j
            yield at_s, mav.attitude_encode(t_ms, 0.0, 0.0, 1.5, 0, 0, 0).pack(mav)
            position = mav.global_position_int_encode(
                t_ms, -353632610, 1491652300, 584_000, 0, 0, 0, 0, 35_300
            )
            yield at_s, position.pack(mav)
        if vehicle_type is not None:
            hb = mav.heartbeat_encode(vehicle_type, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 81, 0, 3)
            yield at_s, hb.pack(mav)


@dataclass
class Outcome:
    service: Service
    estimates: list[Estimate]
    autopilot: Peer
    forger: Peer | None
    log: str


async def attack(
    sitl: list[Record],
    forgery: Iterator[tuple[float, bytes]],
    in_band: bool,
    caplog: pytest.LogCaptureFixture,
    config: ServiceConfig | None = None,
) -> Outcome:
    """The flight at :data:`SPEEDUP` into a daemon, ``forgery`` (s after the forger starts,
    :data:`LEAD_S` before the flight) from its own socket or, ``in_band``, the autopilot's."""
    caplog.set_level(logging.INFO)
    config = config or ServiceConfig(heartbeat_to_autopilot=True, values_to_autopilot=True)
    config = replace(config, stale_after_s=30.0)
    async with running(config, sitl_vehicle()) as (service, _sender):
        estimates: list[Estimate] = []
        deliver = service.out.deliver

        def record(estimate: Estimate, now_s: float) -> None:
            estimates.append(estimate)
            deliver(estimate, now_s)

        service.out.deliver = record  # type: ignore[method-assign]
        assert service.link is not None and service.link.local_address is not None
        port = service.link.local_address[1]
        autopilot = await peer_to(port)
        forger = None if in_band else await peer_to(port)
        scale = SITL_SPEEDUP / SPEEDUP
        schedule = heapq.merge(
            ((LEAD_S + r.at_s * scale, 1, r.frame) for r in sitl),
            ((at_s, 0, frame) for at_s, frame in forgery),
        )
        loop = asyncio.get_running_loop()
        start_s = loop.time()
        for at_s, is_flight, frame in schedule:
            if (delay_s := start_s + at_s - loop.time()) > 0:
                await asyncio.sleep(delay_s)
            (autopilot if is_flight or forger is None else forger).send(frame)
        sent = autopilot.sent + (0 if forger is None else forger.sent)
        link = service.link
        taken = lambda: link.counts["rx_messages"] + link.counts["skipped_frames"]  # noqa: E731
        await wait_for(lambda: taken() >= sent)
        got = list(estimates)
    return Outcome(service, got, autopilot, forger, caplog.text)


def assert_holds(outcome: Outcome, clean: list[Estimate]) -> None:
    """The autopilot keeps the lock; ≥ 99 % of the clean estimates, each within 1 %; a forger
    on its own socket gets nothing, the autopilot gets its stream requests."""
    service = outcome.service
    assert service.lock.locked == AUTOPILOT
    by_time = {e.time_s: e for e in clean}
    matched = [(e, by_time[e.time_s]) for e in outcome.estimates if e.time_s in by_time]
    assert len(matched) == len(outcome.estimates)
    assert len(matched) >= math.ceil(0.99 * len(clean))
    for got, want in matched:
        for name in ("energy_remaining_wh", "endurance_s", "power_model_w", "soc"):
            assert getattr(got, name) == pytest.approx(getattr(want, name), rel=0.01, abs=1e-6)
    if outcome.forger is not None:
        assert outcome.forger.datagrams == 0
    kinds = {m.get_type() for m in outcome.autopilot.received}
    assert {"REQUEST_DATA_STREAM", "HEARTBEAT", "NAMED_VALUE_FLOAT"} <= kinds


async def test_autopilot_heartbeats_alone_from_a_first_speaker_lock_nothing_out(
    sitl: list[Record], clean: list[Estimate], caplog: pytest.LogCaptureFixture
) -> None:
    """System 5 sends autopilot HEARTBEATs at 20 Hz from before the autopilot speaks to the
    end: it is never locked, never asked for telemetry, never answered."""
    duration_s = LEAD_S + sitl[-1].at_s * SITL_SPEEDUP / SPEEDUP
    outcome = await attack(sitl, heartbeats(5, 20.0, duration_s), False, caplog)
    assert_holds(outcome, clean)


async def test_a_first_sender_with_the_autopilots_ids_on_another_port_takes_nothing(
    sitl: list[Record], clean: list[Estimate], caplog: pytest.LogCaptureFixture
) -> None:
    """Another port speaks first with the autopilot's ids (1, 1), HEARTBEATs at 2 Hz: the
    ``udpin`` answers only the address whose telemetry confirmed it."""
    duration_s = LEAD_S + sitl[-1].at_s * SITL_SPEEDUP / SPEEDUP
    outcome = await attack(sitl, heartbeats(1, 2.0, duration_s), False, caplog)
    assert_holds(outcome, clean)
    assert outcome.service.lock.counts["foreign_peer"] > 0


@pytest.mark.parametrize(
    ("in_band", "vehicle_type"),
    [(False, None), (True, None), (True, mavlink.MAV_TYPE_FIXED_WING)],
    ids=["other-port", "in-band", "in-band-with-heartbeat-of-another-type"],
)
async def test_forged_reboots_change_nothing(
    sitl: list[Record],
    clean: list[Estimate],
    caplog: pytest.LogCaptureFixture,
    in_band: bool,
    vehicle_type: int | None,
) -> None:
    """The autopilot's clock reset to 1 s ten times a second for 60 s of its clock (five
    agreeing frames each), from another port or in-band (its own address), with or without a
    HEARTBEAT of another vehicle type: no reboot is believed, the frames are dropped, the
    lock stays."""
    forgery = forged_reboots(2.0, 10.0, 60.0 / SPEEDUP, vehicle_type)
    outcome = await attack(sitl, forgery, in_band, caplog)
    assert_holds(outcome, clean)
    counts = outcome.service.decoder.counts
    assert counts["reboots"] == 0 and counts["clock_jumps"] == 0
    assert "rebooted" not in outcome.log and "selecting" not in outcome.log


async def test_heartbeats_of_199_systems_in_band_are_one_log_line(
    sitl: list[Record], clean: list[Estimate], caplog: pytest.LogCaptureFixture
) -> None:
    """HEARTBEATs of systems 2-200 (ArduPilot quadrotors, disarmed) from the autopilot's own
    address, each five times over the flight: ignored, logged in aggregate."""

    def forgery() -> Iterator[tuple[float, bytes]]:
        for k in range(5 * 199):
            system = 2 + k % 199
            yield LEAD_S + 0.009 * k, next(heartbeats(system, 1.0, 1.0))[1]

    outcome = await attack(sitl, forgery(), True, caplog)
    assert_holds(outcome, clean)
    others = [line for line in outcome.log.splitlines() if "ignored" in line]
    assert 1 <= len(others) <= 2, others


def test_stamped_frames_of_500_senders_keep_the_candidates_bounded(sitl: list[Record]) -> None:
    """Between the flight's frames, a stamped frame of a new sender each (random clocks, seeded):
    at most MAX_CANDIDATES senders are evaluated, each holding at most MAX_HELD messages, and
    the autopilot is still locked with its held messages handed over in order."""
    rng = random.Random(5)
    forger = codec(2)
    lock = AutopilotLock(None, (1, 191))
    parser = FrameParser()
    admitted: list[mavlink.MAVLink_message] = []
    for k, record in enumerate(sitl):
        if k < 500:
            forger.srcSystem, forger.srcComponent = 2 + k % 250, 1 + k // 250
            frame = forger.attitude_encode(rng.randrange(2**32), 0, 0, 0, 0, 0, 0).pack(forger)
            lock.admit(parser.feed(frame)[0], k * 0.01, ("127.0.0.1", 40_000))
            assert len(lock._candidates) <= autopilot_lock.MAX_CANDIDATES
        admitted += lock.admit(record.msg, k * 0.01, ("127.0.0.1", 50_000))
    assert lock.locked == AUTOPILOT
    # held from the first stamped frame on, after the HEARTBEAT before it (what comes between
    # has no clock yet: a replay decodes nothing of it either)
    stamped = next(i for i, r in enumerate(sitl) if hasattr(r.msg, "time_boot_ms"))
    heartbeat = max(i for i in range(stamped) if sitl[i].msg.get_type() == "HEARTBEAT")
    assert admitted == [sitl[heartbeat].msg] + [r.msg for r in sitl[stamped:]]
    assert all(len(c.held) <= autopilot_lock.MAX_HELD for c in lock._candidates.values())
