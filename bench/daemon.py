"""The daemon over real UDP: memory, CPU at 50 messages/s, latency, highest sustainable rate.

Stream: an ArduCopter SITL flight recorded by ``uav-energy sitl-record``
(replay/sitl/wind_onset/flight.tlog: ArduPilot's own stream mix, 27 message ids, about two
thirds of its frames of ids the estimator does not use, WIND id 168 included), one frame a
datagram as ArduPilot sends them, into ``uav-energy run`` (a subprocess, default
configuration, the SITL quad's vehicle file) which writes a JSON line for every estimate to a
UDP port of this process.

1. Resident memory (psutil) after start-up (START_UP_S after it listens), before any
   telemetry (idle).
2. 50 messages/s for SECONDS (default 60): CPU share of one core over that window, resident
   memory after it, and latency. The daemon's latency is the time from sending the datagram
   that closed an estimate period (the last one sent before the estimate arrived: at
   20 ms between datagrams nothing else is in flight) to receiving its JSON line (same
   monotonic clock). The baseline is a bare asyncio + pymavlink loop in its own process
   that parses every datagram and answers each with a JSON line: what the transport and
   codec alone cost. Both latencies are over the same datagrams. For scale, the CPU of an
   asyncio endpoint that does nothing with its datagrams (the event loop's wake-ups alone).
3. Highest sustainable rate: TRIAL_S of the log at each rate, a fresh daemon each time
   (doubling from 2000 messages/s, then three halvings of the step between the last rate
   kept up with and the first not): sustainable when every estimate the same frames give in
   process arrives (no datagram dropped) and the last within LAG_S of the last send
   (estimates keep pace).

Run: ``python -m bench.daemon [SECONDS]``.
"""

from __future__ import annotations

import asyncio
import bisect
import json
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import psutil

from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.config import build_config
from estimator.mavlink.publish import json_line
from estimator.physics.vehicle import load_vehicle
from estimator.telemetry.decode import USED_MESSAGE_IDS, TelemetryDecoder
from estimator.telemetry.frames import FrameParser

REPO = Path(__file__).resolve().parent.parent
TLOG = REPO / "replay/sitl/wind_onset/flight.tlog"
VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
RATE_MSG_S = 50.0
WARMUP_S = 3.0
START_UP_S = 2.0
#: Seconds of the log sent at each rate when looking for the highest sustainable one.
TRIAL_S = 5.0
#: The last estimate must arrive within this (s) of the last datagram sent.
LAG_S = 0.25
RSS_GOAL_MB, CPU_GOAL = 60.0, 0.01

BASELINE = r"""
import asyncio, json, sys
from pymavlink.dialects.v20 import common as mavlink
LISTEN, ANSWER = int(sys.argv[1]), int(sys.argv[2])
class Bare(asyncio.DatagramProtocol):
    def connection_made(self, transport):
        self.transport, self.count = transport, 0
    def datagram_received(self, data, addr):
        codec = mavlink.MAVLink(None)
        codec.robust_parsing = True
        msgs = codec.parse_buffer(data) or []
        line = json.dumps({"datagram": self.count, "types": [m.get_type() for m in msgs]})
        self.transport.sendto(line.encode(), ("127.0.0.1", ANSWER))
        self.count += 1
async def main():
    loop = asyncio.get_running_loop()
    await loop.create_datagram_endpoint(Bare, local_addr=("127.0.0.1", LISTEN))
    await asyncio.Event().wait()
asyncio.run(main())
"""

#: The floor of any asyncio daemon here: an endpoint that does nothing with its datagrams.
EMPTY_ENDPOINT = r"""
import asyncio, sys
class Empty(asyncio.DatagramProtocol):
    def datagram_received(self, data, addr):
        pass
async def main():
    loop = asyncio.get_running_loop()
    await loop.create_datagram_endpoint(Empty, local_addr=("127.0.0.1", int(sys.argv[1])))
    await asyncio.Event().wait()
asyncio.run(main())
"""


def tlog_frames(path: Path) -> Iterator[bytes]:
    """The MAVLink frames of a tlog (each after an 8-byte time stamp)."""
    data = path.read_bytes()
    at = 8
    while at + 10 <= len(data):
        if data[at] == 0xFD:
            size = 12 + data[at + 1] + (13 if data[at + 2] & 0x01 else 0)
        else:
            size = 8 + data[at + 1]
        yield data[at : at + size]
        at += size + 8


def frame_id(frame: bytes) -> int:
    return frame[7] | frame[8] << 8 | frame[9] << 16 if frame[0] == 0xFD else frame[5]


def daemon_estimates(frames: list[bytes]) -> Iterator[tuple[int, Estimate]]:
    """The estimates the daemon's path gives on ``frames``, in process, each with the index of
    the frame that closed it (no flush at the end: the daemon publishes the open period only
    when it stops)."""
    config = build_config({}, {})
    vehicle = load_vehicle(VEHICLE)
    decoder = TelemetryDecoder(own=(config.system_id, 191), limits=vehicle.input_limits())
    pipeline = Pipeline(vehicle, config.pipeline_settings())
    for i, frame in enumerate(frames):
        for msg in FrameParser(USED_MESSAGE_IDS).feed(frame):
            for sample in decoder.decode(msg):
                if (estimate := pipeline.process(sample)) is not None:
                    yield i, estimate


def estimates_after_each(frames: list[bytes]) -> np.ndarray:
    """How many estimates the daemon's path has given after each frame, in process."""
    closed_by = [i for i, _ in daemon_estimates(frames)]
    return np.searchsorted(closed_by, np.arange(len(frames)), side="right")


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def daemon_command(
    listen: int, answer: int, program: tuple[str, ...] = (sys.executable, "-m", "estimator.cli")
) -> list[str]:
    """``uav-energy run`` (``program``: how to start ``uav-energy``) on the bench's ports."""
    return [
        *program,
        *("run", "--vehicle", str(VEHICLE)),
        *("--connect", f"udpin:127.0.0.1:{listen}", "--json", f"udp:127.0.0.1:{answer}"),
        *("--publish", f"udpout:127.0.0.1:{free_port()}", "--log-level", "warning"),
    ]


class Answers(asyncio.DatagramProtocol):
    """Receives JSON lines: their arrival times and contents, in order."""

    def __init__(self) -> None:
        self.arrival_s: list[float] = []
        self.lines: list[dict[str, object]] = []

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.arrival_s.append(time.perf_counter())
        self.lines.append(json.loads(data))


@dataclass
class Run:
    """One process fed at 50 messages/s: latency (ms) by the index of the datagram answered,
    CPU share of one core, resident memory idle and after the stream (MB), time from start to
    listening (s), and the raw timings: each datagram's send time, each answer's arrival time
    and content (s, ``time.perf_counter``)."""

    latency_ms: dict[int, float]
    cpu_share: float
    idle_rss_mb: float
    rss_mb: float
    start_up_s: float
    sent_s: list[float]
    answers: Answers


async def send_paced(
    sock: socket.socket, frames: list[bytes], port: int, rate: float
) -> list[float]:
    """Send ``frames`` from ``sock`` at ``rate`` datagrams/s (in batches of 1 ms above
    1000/s); the send time of each. One socket for a whole stream: the daemon takes frames
    from another source port for a forger's (dropped for 3 s)."""
    sent: list[float] = []
    start = time.perf_counter()
    while len(sent) < len(frames):
        due = min(len(frames), int((time.perf_counter() - start) * rate) + 1)
        for frame in frames[len(sent) : due]:
            sent.append(time.perf_counter())
            sock.sendto(frame, ("127.0.0.1", port))
        delay = start + len(sent) / rate - time.perf_counter()
        await asyncio.sleep(max(delay, 0.0) if rate < 1000 else 0.001)
    return sent


def udp_socket() -> socket.socket:
    return socket.socket(socket.AF_INET, socket.SOCK_DGRAM)


async def listening(ps: psutil.Process, port: int, timeout_s: float = 60.0) -> float:
    """Seconds from now until ``ps`` has a UDP socket bound to ``port``."""
    start = time.perf_counter()
    while all(c.laddr.port != port for c in ps.net_connections(kind="udp")):
        if time.perf_counter() - start > timeout_s:
            raise TimeoutError(f"{ps.cmdline()[:4]} not listening on {port}")
        await asyncio.sleep(0.02)
    return time.perf_counter() - start


async def at_50_msg_s(
    command: list[str],
    listen: int,
    answer: int,
    frames: list[bytes],
    preexec_fn: Callable[[], None] | None = None,
) -> Run:
    """Start ``command`` (``preexec_fn`` runs in the child before it), stream ``frames`` to it
    at 50 msg/s once it listens, return its figures."""
    loop = asyncio.get_running_loop()
    transport, answers = await loop.create_datagram_endpoint(
        Answers, local_addr=("127.0.0.1", answer)
    )
    proc = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, preexec_fn=preexec_fn
    )
    ps = psutil.Process(proc.pid)
    try:
        start_up_s = await listening(ps, listen)
        await asyncio.sleep(START_UP_S)
        idle_rss_mb = ps.memory_info().rss / 1e6
        warmup = int(WARMUP_S * RATE_MSG_S)
        with udp_socket() as sock:
            sent = await send_paced(sock, frames[:warmup], listen, RATE_MSG_S)
            cpu_start = (time.perf_counter(), sum(ps.cpu_times()[:2]))
            sent += await send_paced(sock, frames[warmup:], listen, RATE_MSG_S)
        await asyncio.sleep(0.5)
        wall = time.perf_counter() - cpu_start[0]
        cpu = sum(ps.cpu_times()[:2]) - cpu_start[1]
        rss_mb = ps.memory_info().rss / 1e6
    finally:
        proc.terminate()
        proc.wait(5)
        transport.close()
    latency: dict[int, float] = {}
    for arrival, line in zip(answers.arrival_s, answers.lines, strict=True):
        i = line["datagram"] if "datagram" in line else bisect.bisect_right(sent, arrival) - 1
        assert isinstance(i, int)
        if i >= warmup:
            latency.setdefault(i, 1000 * (arrival - sent[i]))
    return Run(latency, cpu / wall, idle_rss_mb, rss_mb, start_up_s, sent, answers)


async def keeps_up(frames: list[bytes], rate: float, expected: int) -> tuple[bool, int, float]:
    """A fresh daemon fed ``frames`` at ``rate``: (sustained, estimates received, lag s)."""
    listen, answer = free_port(), free_port()
    loop = asyncio.get_running_loop()
    transport, answers = await loop.create_datagram_endpoint(
        Answers, local_addr=("127.0.0.1", answer)
    )
    command = daemon_command(listen, answer)
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        await asyncio.sleep(START_UP_S)
        with udp_socket() as sock:
            sent = await send_paced(sock, frames, listen, rate)
        await asyncio.sleep(max(1.0, 4 * LAG_S))
    finally:
        proc.terminate()
        proc.wait(5)
        transport.close()
    got = len(answers.lines)
    lag = (answers.arrival_s[-1] if got else np.inf) - sent[-1]
    return got == expected and lag <= LAG_S, got, lag


async def max_rate(frames: list[bytes]) -> tuple[float, list[str]]:
    """The highest rate (msg/s) the daemon keeps up with, and a line per rate tried."""
    after = estimates_after_each(frames)
    lines: list[str] = []

    async def trial(rate: float) -> bool:
        n = min(len(frames), int(rate * TRIAL_S))
        ok, got, lag = await keeps_up(frames[:n], rate, int(after[n - 1]))
        lines.append(
            f"    {rate:8.0f} msg/s, {n} frames: {got} of {after[n - 1]} estimates, the last "
            f"{1000 * lag:+.0f} ms after the last send: {'kept up' if ok else 'behind'}"
        )
        return ok

    good, bad = 0.0, 2000.0
    while await trial(bad):
        good, bad = bad, 2 * bad
        if bad > 256_000:
            return good, lines
    for _ in range(3):
        mid = (good + bad) / 2
        good, bad = (mid, bad) if await trial(mid) else (good, mid)
    return good, lines


def processing_times_ms(frames: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Per-datagram CPU path without sockets: a pymavlink parse of every frame (baseline) vs
    the daemon's filter + parse + decode + pipeline + JSON line, for the frames that
    produced an estimate."""
    from pymavlink.dialects.v20 import common as mavlink

    decoder, pipeline = TelemetryDecoder(), Pipeline(load_vehicle(VEHICLE))
    base, full = [], []
    for frame in frames:
        t0 = time.perf_counter()
        codec = mavlink.MAVLink(None)
        codec.robust_parsing = True
        codec.parse_buffer(frame)
        t1 = time.perf_counter()
        produced = False
        for msg in FrameParser(USED_MESSAGE_IDS).feed(frame):
            for sample in decoder.decode(msg):
                if (estimate := pipeline.process(sample)) is not None:
                    json_line(estimate)
                    produced = True
        t2 = time.perf_counter()
        base.append(t1 - t0)
        if produced:
            full.append(t2 - t1)
    return 1000 * np.array(base), 1000 * np.array(full)


def percentiles(name: str, values_ms: np.ndarray) -> str:
    p50, p99 = np.percentile(values_ms, [50, 99])
    return f"{name} p50 {p50:.3f} ms p99 {p99:.3f} ms"


async def bench(seconds: float) -> None:
    frames = list(tlog_frames(TLOG))
    used = sum(frame_id(f) in USED_MESSAGE_IDS for f in frames) / len(frames)
    window = frames[: int((WARMUP_S + seconds) * RATE_MSG_S)]
    print(
        f"stream: {TLOG.relative_to(REPO)} ({len(frames)} frames, {100 * used:.0f} % of ids "
        f"the daemon uses); {RATE_MSG_S:.0f} msg/s over loopback UDP for {seconds:.0f} s"
    )
    listen, answer = free_port(), free_port()
    base = await at_50_msg_s(
        [sys.executable, "-c", BASELINE, str(listen), str(answer)], listen, answer, window
    )
    listen, answer = free_port(), free_port()
    empty = await at_50_msg_s(
        [sys.executable, "-c", EMPTY_ENDPOINT, str(listen)], listen, answer, window
    )
    listen, answer = free_port(), free_port()
    daemon = await at_50_msg_s(daemon_command(listen, answer), listen, answer, window)
    runs = ((empty, "empty asyncio sink"), (base, "bare pymavlink loop"), (daemon, "daemon"))
    for run, label in runs:
        print(
            f"  {label:19s} CPU {100 * run.cpu_share:5.2f} % of one core  RSS idle "
            f"{run.idle_rss_mb:5.1f} MB, after the stream {run.rss_mb:5.1f} MB"
        )
    same = sorted(set(daemon.latency_ms) & set(base.latency_ms))
    print(f"  latency over the same {len(same)} datagrams (those that closed an estimate):")
    for run, label in ((base, "bare pymavlink loop"), (daemon, "daemon")):
        print("    " + percentiles(f"{label:19s}", np.array([run.latency_ms[i] for i in same])))
    base_ms, full_ms = processing_times_ms(frames)
    print(
        "  in process, no sockets: "
        + percentiles("pymavlink parse of one frame", base_ms)
        + "; "
        + percentiles("frame → estimate → JSON", full_ms)
    )
    rss = max(daemon.idle_rss_mb, daemon.rss_mb)
    print(
        f"  goals: RSS ≤ {RSS_GOAL_MB:.0f} MB {'met' if rss <= RSS_GOAL_MB else 'NOT met'}; "
        f"CPU ≤ {100 * CPU_GOAL:.0f} % of a core at 50 msg/s "
        f"{'met' if daemon.cpu_share <= CPU_GOAL else 'NOT met'}"
    )
    rate, lines = await max_rate(frames)
    print(f"  highest sustainable rate: {rate:.0f} msg/s (a fresh daemon at each rate)")
    print("\n".join(lines))


def main() -> int:
    numbers = [a for a in sys.argv[1:] if a.replace(".", "", 1).isdigit()]
    seconds = float(numbers[0]) if numbers else 60.0
    asyncio.run(bench(seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
