"""State that survives a daemon restart mid-flight: the state file, over real sockets."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import signal
import socket
import sys
import time
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import (
    Messages,
    flight,  # noqa: F401 (fixture)
    play,
    replay,
    running,
    wait_for,
)

from estimator.estimation.pipeline import Estimate, Pipeline
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.state_file import SavedState, read_state, write_state
from estimator.physics.vehicle import default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder

EXE = Path(sys.executable).with_name("uav-energy")


def snapshot_at(messages: Messages, until_s: float) -> tuple[dict, float]:  # type: ignore[type-arg]
    """The pipeline's snapshot after the messages up to ``until_s`` (and its clock, s)."""
    decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle())
    for t, msg in messages:
        if t > until_s:
            break
        for sample in decoder.decode(msg):
            pipeline.process(sample)
    snapshot = pipeline.snapshot()
    assert snapshot is not None
    return json.loads(json.dumps(snapshot)), float(snapshot["energy"]["time_s"])


class _Json(asyncio.DatagramProtocol):
    def __init__(self) -> None:
        self.estimates: list[dict] = []  # type: ignore[type-arg]

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.estimates.append(json.loads(data))


async def test_daemon_killed_mid_flight_continues_from_its_state_file(tmp_path: Path) -> None:
    """``uav-energy run`` (a process) listens to an autopilot flying in real time over UDP,
    writes its state file every second, is killed (SIGKILL) 24 s into the flight and started
    again: it continues from the state file (endurance valid at once, the learned bias kept)
    and its energy stays within 0.3 % of an uninterrupted replay of the whole flight."""
    flight_s, kill_s = 38.0, 24.0
    messages = simulate(SimConfig(plan="hover-cruise", duration_s=flight_s, seed=3)).messages
    reference = {round(e.time_s, 3): e for e in replay(m for _, m in messages)}
    loop = asyncio.get_running_loop()
    json_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    json_sock.bind(("127.0.0.1", 0))
    out_transport, out = await loop.create_datagram_endpoint(_Json, sock=json_sock)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    state = tmp_path / "state.json"
    conf = tmp_path / "config.toml"
    conf.write_text('[state]\nfile = "state.json"\nperiod_s = 1.0\n')  # relative to conf
    args = [str(EXE), "run", "--config", str(conf), "--connect", f"udpin:127.0.0.1:{port}"]
    args += ["--json", f"udp:127.0.0.1:{json_sock.getsockname()[1]}"]

    async def start(log: Path) -> asyncio.subprocess.Process:
        with log.open("wb") as err:
            proc = await asyncio.create_subprocess_exec(*args, stderr=err)
        async with asyncio.timeout(60):
            while "started:" not in log.read_text():
                await asyncio.sleep(0.05)
        return proc

    first = await start(tmp_path / "first.log")
    second: asyncio.subprocess.Process | None = None
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as autopilot:
            t0 = loop.time()
            for t, msg in messages:  # in real time: the autopilot clock runs with the wall's
                if t >= kill_s and second is None:
                    first.send_signal(signal.SIGKILL)
                    await first.wait()
                    assert isinstance(read_state(state, 60.0, time.time()), SavedState)
                    before = len(out.estimates)
                    second = await start(tmp_path / "second.log")
                if (delay := t0 + t - loop.time()) > 0:
                    await asyncio.sleep(delay)
                autopilot.sendto(msg.pack(codec), ("127.0.0.1", port))
        await asyncio.sleep(1.5)
    finally:
        for proc in (first, second):
            if proc is not None and proc.returncode is None:
                proc.send_signal(signal.SIGTERM)
                await asyncio.wait_for(proc.wait(), 15)
        out_transport.close()
    assert second is not None and second.returncode == 0
    log = (tmp_path / "second.log").read_text()
    assert "continuing the flight from" in log, log
    # the estimates of whole periods (not the one the exit flushes) against the reference
    resumed = [e for e in out.estimates[before:] if round(e["time_s"], 3) in reference]
    assert len(resumed) >= 5
    assert resumed[0]["endurance_valid"] and resumed[0]["bias_sigma"] < 0.05
    errors = []
    for est in resumed:
        ref: Estimate = reference[round(est["time_s"], 3)]
        errors.append(est["energy_remaining_wh"] / ref.energy_remaining_wh - 1.0)
    assert max(abs(e) for e in errors) < 0.003, errors
    saved = read_state(state, 60.0, time.time())
    assert isinstance(saved, SavedState) and saved.clock_s > kill_s
    assert os.stat(state).st_mode & 0o077 == 0


@pytest.mark.parametrize(
    ("case", "line"),
    [
        ("fits", "continuing the flight from"),
        ("stale", "ignored: 1000 s old (at most 120 s)"),
        ("corrupt", "ignored: corrupt"),
        ("truncated", "ignored: corrupt"),
        ("bad values", "ignored: not a pipeline snapshot"),
        ("other autopilot", "ignored: written for system 5 component 1"),
        ("rebooted", "rebooted or another flight"),
    ],
)
async def test_state_file_is_used_only_when_it_fits(
    flight: Messages,  # noqa: F811
    tmp_path: Path,
    caplog: pytest.LogCaptureFixture,
    case: str,
    line: str,
) -> None:
    """A state file written 10 s into the flight; the daemon starts and hears the flight from
    10.5 s on. Used when it fits; a stale, corrupt, foreign or pre-reboot one is ignored with
    one line and the daemon starts from the voltage as if there were none."""
    caplog.set_level(logging.INFO)
    snapshot, clock_s = snapshot_at(flight, 10.0)
    path = tmp_path / "state.json"
    system, wall_s = (5 if case == "other autopilot" else 1), time.time()
    if case == "stale":
        wall_s -= 1000
    if case == "rebooted":  # the saved clock is ahead of the autopilot's: it rebooted since
        clock_s += 600
    if case == "bad values":
        snapshot["energy"]["x"] = [float("nan"), 1.0]
    write_state(path, SavedState(system, 1, wall_s, clock_s, snapshot))
    if case == "corrupt":
        path.write_bytes(b"\x00{not json")
    if case == "truncated":
        path.write_bytes(path.read_bytes()[:100])
    config = ServiceConfig(state_file=str(path), stale_after_s=30.0)
    async with running(config) as (service, sender):
        await play(sender, [m for t, m in flight if t >= 10.5 or m.get_type() == "HEARTBEAT"])
        await wait_for(lambda: service.latest is not None and service.latest.time_s > 30)
    assert sum(line in r.getMessage() for r in caplog.records) == 1, caplog.text
    counts = service.pipeline.counts
    assert (counts["resumed"], counts["energy_initialized"]) == (
        (1, 0) if case == "fits" else (0, 1)
    )
    assert service.state is not None and service.state.writes >= 1  # at exit at least
    assert "Traceback" not in caplog.text
