"""State that survives a daemon restart mid-flight: the state file, over real sockets."""

from __future__ import annotations

import asyncio
import functools
import json
import logging
import math
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from test_service import (
    Messages,
    flight,  # noqa: F401 (fixture)
    play,
    replay,
    running,
    wait_for,
)

from estimator.estimation.estimate import Estimate
from estimator.estimation.fusion import BIAS_RANGE, MAX_CAPACITY_PER_LABEL
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.state_file import (
    SavedState,
    StateKeeper,
    read_state,
    vehicle_identity,
    write_state,
)
from estimator.physics.vehicle import default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import BatterySample

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
        ("energy 1e6 Wh", "ignored: not a pipeline snapshot"),
        ("bias -3", "ignored: not a pipeline snapshot"),
        ("negative covariance", "ignored: not a pipeline snapshot"),
        ("other vehicle file", "ignored: written under another vehicle file"),
        ("nested 400 KB", "ignored: larger than 65536 bytes"),
        ("nested 60 KB", "ignored: corrupt (nested 30000 deep, at most 16)"),
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
    10.5 s on. Used when it fits; a stale, corrupt, out-of-range, nested, oversized, foreign
    (autopilot or vehicle file) or pre-reboot one is ignored with one line and the daemon
    starts from the voltage as if there were none."""
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
    if case == "energy 1e6 Wh":
        snapshot["energy"]["x"][0] = 1e6
    if case == "bias -3":
        snapshot["energy"]["x"][1] = -3.0
    if case == "negative covariance":
        snapshot["energy"]["P"][0][0] = -1.0
    vehicle = default_vehicle()
    if case == "other vehicle file":
        vehicle = replace(vehicle, mass_kg=vehicle.mass_kg + 0.5)
    write_state(path, SavedState(system, 1, wall_s, clock_s, snapshot, vehicle_identity(vehicle)))
    if case.startswith("nested"):
        depth = 200_000 if case == "nested 400 KB" else 30_000
        path.write_bytes(b"[" * depth + b"]" * depth)
    if case == "corrupt":
        path.write_bytes(b"\x00{not json")
    if case == "truncated":
        path.write_bytes(path.read_bytes()[:100])
    config = ServiceConfig(state_file=str(path), stale_after_s=30.0)
    async with running(config) as (service, sender):
        await play(sender, [m for t, m in flight if t >= 10.5 or m.get_type() == "HEARTBEAT"])
        await wait_for(lambda: service.out.latest is not None and service.out.latest.time_s > 30)
    assert sum(line in r.getMessage() for r in caplog.records) == 1, caplog.text
    counts = service.pipeline.counts
    assert (counts["resumed"], counts["energy_initialized"]) == (
        (1, 0) if case == "fits" else (0, 1)
    )
    assert service.state is not None and service.state.writes >= 1  # at exit at least
    assert "Traceback" not in caplog.text


def test_run_starts_fresh_on_a_400_kb_nested_state_file(tmp_path: Path) -> None:
    """``uav-energy run`` with a state file of 200,000 nested arrays (400 KB): one line says
    it is ignored, the daemon runs, and SIGTERM stops it with exit code 0 (it used to die at
    start with a RecursionError: a restart loop under systemd)."""
    state = tmp_path / "state.json"
    state.write_bytes(b"[" * 200_000 + b"]" * 200_000)
    conf = tmp_path / "config.toml"
    conf.write_text('[state]\nfile = "state.json"\n')
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    log = tmp_path / "daemon.log"
    args = ["run", "--config", str(conf), "--connect", f"udpin:127.0.0.1:{port}"]
    with log.open("wb") as err:
        proc = subprocess.Popen([str(EXE), *args], stderr=err)
    try:
        deadline = time.monotonic() + 60
        while "started:" not in log.read_text() and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        proc.wait(15)
    text = log.read_text()
    assert proc.returncode == 0, text
    assert text.count("state file") == 1 and "ignored: larger than 65536 bytes" in text, text
    assert "Traceback" not in text


@functools.cache
def _valid_state() -> SavedState:
    """A state written 10 s into a simulated flight (with the pack filter's state)."""
    messages = simulate(SimConfig(plan="hover-cruise", duration_s=12.0, seed=4)).messages
    snapshot, clock_s = snapshot_at(messages, 10.0)
    assert snapshot["pack"] is not None
    return SavedState(1, 1, time.time(), clock_s, snapshot, vehicle_identity(default_vehicle()))


def _leaves(doc: object, path: tuple = ()) -> list[tuple]:  # type: ignore[type-arg]
    """Paths (keys and indices) to every scalar of a JSON document."""
    if isinstance(doc, dict):
        return [p for k, v in doc.items() for p in _leaves(v, (*path, k))]
    if isinstance(doc, list):
        return [p for i, v in enumerate(doc) for p in _leaves(v, (*path, i))]
    return [path]


_JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=3), inner),
    max_leaves=6,
)


def _assert_in_schema(pipeline: Pipeline) -> None:
    """The restored state's values in their ranges (tests the restore, not the flight)."""
    snapshot = pipeline.snapshot()
    assert snapshot is not None
    energy = snapshot["energy"]
    full_wh = float(pipeline.pack.energy_wh(1.0))
    x, p = np.array(energy["x"]), np.array(energy["P"])
    assert np.isfinite(x).all() and np.isfinite(p).all()
    assert -MAX_CAPACITY_PER_LABEL * full_wh <= x[0] <= MAX_CAPACITY_PER_LABEL * full_wh
    assert BIAS_RANGE[0] <= x[1] <= BIAS_RANGE[1]
    assert np.allclose(p, p.T) and np.linalg.eigvalsh(p).min() >= -1e-9 * np.abs(p).max()
    assert 0.0 <= energy["soc_ref"] <= 1.0
    estimate = pipeline.last
    assert estimate is not None
    assert 0.0 <= estimate.energy_remaining_wh <= MAX_CAPACITY_PER_LABEL * full_wh
    assert math.isfinite(estimate.energy_remaining_sigma_wh)


@settings(
    max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
@given(data=st.data())
def test_mutated_state_files_never_raise_nor_restore_out_of_range(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    """A valid state file with one value replaced by any JSON value (of any type and size),
    scaled, or its bytes flipped or cut: loading and resuming never raise, and a state that
    is used restores within the schema; the pipeline's next estimate is finite and in range."""
    state, path = _valid_state(), tmp_path_factory.mktemp("state") / "state.json"
    doc = json.loads(state.to_json())
    kind = data.draw(st.sampled_from(["replace", "scale", "bytes"]))
    if kind == "bytes":
        raw = bytearray(state.to_json().encode())
        for at in data.draw(st.lists(st.integers(0, len(raw) - 1), min_size=1, max_size=4)):
            raw[at] = data.draw(st.integers(0, 255))
        raw = raw[: data.draw(st.integers(1, len(raw)))]
        path.write_bytes(bytes(raw))
    else:
        *parents, last = data.draw(st.sampled_from(_leaves(doc)))
        parent = doc
        for key in parents:
            parent = parent[key]
        if kind == "replace":
            parent[last] = data.draw(_JSON_VALUES)
        elif isinstance(parent[last], int | float) and not isinstance(parent[last], bool):
            parent[last] *= data.draw(st.sampled_from([-1.0, 0.0, 1e-6, 10.0, 1e6, 1e300]))
        path.write_text(json.dumps(doc))
    pipeline = Pipeline(default_vehicle())
    keeper = StateKeeper(str(path), 3600.0, 1.0, pipeline)
    keeper.load()
    keeper.resume((1, 1), state.clock_s + 0.5)
    pipeline.process(BatterySample(state.clock_s + 0.5, 24.0, 20.0, 1_000.0))
    pipeline.process(BatterySample(state.clock_s + 1.6, 24.0, 20.0, 1_010.0))
    _assert_in_schema(pipeline)
