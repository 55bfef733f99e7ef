"""Daemon latency, CPU and memory at 50 messages/s over loopback, against a bare parse loop.

A simulated ArduCopter stream is sent to ``uav-energy run`` (a subprocess) over UDP at 50
messages/s; the daemon writes a JSON line for every estimate to a UDP port of this process.
Latency is the time from sending a GLOBAL_POSITION_INT datagram to receiving the JSON
estimate of that velocity sample (same monotonic clock). The baseline is a bare asyncio +
pymavlink loop in its own process that parses each datagram and answers GLOBAL_POSITION_INT
with a JSON line of its time: what the transport and codec alone cost. CPU share (of one
core) and resident memory (psutil) of both processes over the same window.

Run: ``python -m bench.daemon [SECONDS]`` (default 30 s per process).
"""

from __future__ import annotations

import asyncio
import json
import socket
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np
import psutil

from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

RATE_MSG_S = 50.0
WARMUP_S = 3.0

BASELINE = r"""
import asyncio, json, sys
from pymavlink.dialects.v20 import common as mavlink
LISTEN, ANSWER = int(sys.argv[1]), int(sys.argv[2])
class Bare(asyncio.DatagramProtocol):
    def connection_made(self, transport):
        self.transport = transport
    def datagram_received(self, data, addr):
        codec = mavlink.MAVLink(None)
        codec.robust_parsing = True
        for msg in codec.parse_buffer(data) or []:
            if msg.get_type() == "GLOBAL_POSITION_INT":
                line = json.dumps({"time_s": msg.time_boot_ms / 1000.0})
                self.transport.sendto(line.encode(), ("127.0.0.1", ANSWER))
async def main():
    loop = asyncio.get_running_loop()
    await loop.create_datagram_endpoint(Bare, local_addr=("127.0.0.1", LISTEN))
    await asyncio.Event().wait()
asyncio.run(main())
"""


@dataclass
class Result:
    latencies_ms: np.ndarray
    cpu_share: float
    rss_mb: float
    sent: int

    def line(self, name: str) -> str:
        p50, p99 = np.percentile(self.latencies_ms, [50, 99])
        return (
            f"  {name:9s} latency p50 {p50:6.3f} ms  p99 {p99:6.3f} ms  "
            f"CPU {100 * self.cpu_share:5.2f} % of one core  RSS {self.rss_mb:6.1f} MB  "
            f"({len(self.latencies_ms)} of {self.sent} matched)"
        )


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Answers(asyncio.DatagramProtocol):
    """Receives JSON lines; keeps the first arrival time of each estimate time."""

    def __init__(self) -> None:
        self.arrival: dict[int, float] = {}

    def datagram_received(self, data: bytes, addr: object) -> None:
        now = time.perf_counter()
        ms = round(json.loads(data)["time_s"] * 1000)
        self.arrival.setdefault(ms, now)


async def measure(command: list[str], listen_port: int, answer_port: int, seconds: float):
    """Start ``command``, stream to it at 50 msg/s for ``seconds``, return its figures."""
    loop = asyncio.get_running_loop()
    transport, answers = await loop.create_datagram_endpoint(
        Answers, local_addr=("127.0.0.1", answer_port)
    )
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ps = psutil.Process(proc.pid)
    try:
        await asyncio.sleep(1.5)  # start-up (imports)
        total_s = WARMUP_S + seconds
        n_messages = int(total_s * RATE_MSG_S)
        run = simulate(SimConfig(plan="hover-cruise", duration_s=n_messages / 30.0, seed=1))
        messages = [m for _, m in run.messages][:n_messages]
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        codec_src = [m.get_msgbuf() for m in messages]
        sent: dict[int, float] = {}
        start = time.perf_counter()
        cpu_start = None
        for i, (msg, buf) in enumerate(zip(messages, codec_src, strict=True)):
            due = start + i / RATE_MSG_S
            delay = due - time.perf_counter()
            if delay > 0:
                await asyncio.sleep(delay)
            if cpu_start is None and i >= WARMUP_S * RATE_MSG_S:
                cpu_start = (time.perf_counter(), sum(ps.cpu_times()[:2]))
                sent.clear()
            now = time.perf_counter()
            sock.sendto(bytes(buf), ("127.0.0.1", listen_port))
            if msg.get_type() == "GLOBAL_POSITION_INT":
                sent.setdefault(msg.time_boot_ms, now)
        await asyncio.sleep(0.5)
        assert cpu_start is not None
        wall = time.perf_counter() - cpu_start[0]
        cpu = sum(ps.cpu_times()[:2]) - cpu_start[1]
        rss_mb = ps.memory_info().rss / 1e6
        sock.close()
    finally:
        proc.terminate()
        proc.wait(5)
        transport.close()
    lat = [1000 * (answers.arrival[ms] - t) for ms, t in sent.items() if ms in answers.arrival]
    return Result(np.array(lat), cpu / wall, rss_mb, len(sent))


def processing_times_ms(messages: list, repeats: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Per-message CPU path without sockets: pymavlink parse of the packed bytes (baseline,
    every message) vs parse + decode + pipeline + JSON line for each message that produced
    an estimate (the daemon's work on the latency path)."""
    from pymavlink.dialects.v20 import common as mavlink

    from estimator.estimation.pipeline import Pipeline
    from estimator.mavlink.publish import json_line
    from estimator.physics.vehicle import default_vehicle
    from estimator.telemetry.decode import FrameParser, TelemetryDecoder

    buffers = [bytes(m.get_msgbuf()) for m in messages]
    base, full = [], []  # full: only messages that produced an estimate
    for _ in range(repeats):
        decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle())
        for buf in buffers:
            t0 = time.perf_counter()
            codec = mavlink.MAVLink(None)
            codec.robust_parsing = True
            codec.parse_buffer(buf)
            t1 = time.perf_counter()
            produced = False
            for msg in FrameParser().feed(buf):
                for sample in decoder.decode(msg):
                    estimate = pipeline.process(sample)
                    if estimate is not None:
                        json_line(estimate)
                        produced = True
            t2 = time.perf_counter()
            base.append(t1 - t0)
            if produced:
                full.append(t2 - t1)
    return 1000 * np.array(base), 1000 * np.array(full)


async def bench(seconds: float) -> None:
    listen, answer = free_port(), free_port()
    base = await measure(
        [sys.executable, "-c", BASELINE, str(listen), str(answer)], listen, answer, seconds
    )
    listen, answer = free_port(), free_port()
    daemon_cmd = [
        sys.executable,
        "-m",
        "estimator.cli",
        "run",
        "--connect",
        f"udpin:127.0.0.1:{listen}",
        "--json",
        f"udp:127.0.0.1:{answer}",
        "--publish",
        f"udpout:127.0.0.1:{free_port()}",
        "--log-level",
        "warning",
    ]
    daemon = await measure(daemon_cmd, listen, answer, seconds)
    print(f"daemon vs bare pymavlink loop, {RATE_MSG_S:.0f} msg/s over loopback, {seconds:.0f} s")
    print(base.line("baseline"))
    print(daemon.line("daemon"))
    p = [np.percentile(r.latencies_ms, [50, 99]) for r in (daemon, base)]
    run = simulate(SimConfig(plan="hover-cruise", duration_s=120.0, seed=1))
    base_ms, full_ms = processing_times_ms([m for _, m in run.messages])
    q_base, q_full = np.percentile(base_ms, [50, 99]), np.percentile(full_ms, [50, 99])
    print(
        f"  in-process work (no sockets): parse one message p50 {q_base[0]:.3f} ms "
        f"p99 {q_base[1]:.3f} ms; message → estimate → JSON p50 {q_full[0]:.3f} ms "
        f"p99 {q_full[1]:.3f} ms (ratio p50 {q_full[0] / q_base[0]:.0f}x)"
    )
    print(
        f"  ratios daemon/baseline: latency p50 {p[0][0] / p[1][0]:.2f}x  "
        f"p99 {p[0][1] / p[1][1]:.2f}x  CPU {daemon.cpu_share / max(base.cpu_share, 1e-9):.2f}x  "
        f"RSS {daemon.rss_mb / base.rss_mb:.2f}x"
    )


def main() -> int:
    numbers = [a for a in sys.argv[1:] if a.replace(".", "", 1).isdigit()]
    seconds = float(numbers[0]) if numbers else 30.0
    asyncio.run(bench(seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
