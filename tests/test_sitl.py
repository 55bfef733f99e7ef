"""End to end over loopback sockets: simulator → daemon → an independent ground station.

The simulator (:mod:`estimator.sim.link`) serves a flight on an ephemeral TCP port of
127.0.0.1 like ArduPilot SITL does on tcp:5760; the daemon connects to it — either
``uav-energy run`` as a real subprocess, or :class:`~estimator.mavlink.service.Service` in this
process (:func:`estimator.sim.demo.fly_live`) — and publishes towards a ground station that is a
plain UDP socket decoded with pymavlink's own codec (none of our link or decode code), and
JSON lines of every estimate. Each plan is flown clean and with hidden effects the daemon is
not told about. Checked: what the ground station receives (our HEARTBEAT as component 191,
NAMED_VALUE_FLOAT, BATTERY_STATUS.time_remaining), that the live estimates equal a replay of
the tlog the simulator wrote, and that they are sane against the simulator's truth.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import socket
import sys
import threading
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator.analysis.replay import replay_log
from estimator.mavlink.link import MavlinkLink, open_link
from estimator.mavlink.publish import NAMED_VALUES, json_line
from estimator.physics.effects import AirDensity, Avionics, Effect, Mass, Voltage, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.demo import fly_live, serve_flight
from estimator.sim.run import SimConfig, SimRun
from estimator.sim.simulator import simulate

EXE = Path(sys.executable).with_name("uav-energy")
GCS_SYSTEM, OUR_COMPONENT = 1, mavlink.MAV_COMP_ID_ONBOARD_COMPUTER
#: Wall seconds any one flight may take before the test gives up.
FLIGHT_TIMEOUT_S = 90.0
#: The daemon's NAMED_VALUE_FLOAT/BATTERY_STATUS rate in these tests (wall Hz).
PUBLISH_HZ = 50.0
#: Wall seconds without a new estimate that mean a subprocess daemon has stopped estimating.
QUIET_S = 5.0


@dataclass(frozen=True)
class Case:
    """One flight: plan, simulated seconds (None: the whole plan, landing included), hidden
    effects, whether the daemon is a subprocess, and the playback speedup."""

    plan: str
    duration_s: float | None
    effects: tuple[Effect, ...]
    subprocess: bool
    speedup: float

    @property
    def id(self) -> str:
        effects = "+".join(e.name for e in self.effects) or "clean"
        return f"{self.plan}-{effects}-{'subprocess' if self.subprocess else 'inprocess'}"


FULL_FLIGHT = pytest.mark.slow  # a whole plan, take-off to landing: ~450 s of flight each
#: In-process the simulator and the daemon share one event loop and pace each other, so the
#: speedup is "as fast as they go"; a subprocess daemon must keep up on its own core.
FAST, SUBPROCESS = 200.0, 100.0
CASES = [
    pytest.param(Case("straight", 240.0, (), False, FAST)),
    pytest.param(Case("straight", 240.0, (Wind(5.0, 0.0),), False, FAST)),
    pytest.param(Case("circles", None, (), False, FAST), marks=FULL_FLIGHT),
    pytest.param(
        Case("circles", None, (Mass(0.8, at_s=100.0), AirDensity(1.10)), False, FAST),
        marks=FULL_FLIGHT,
    ),
    pytest.param(Case("mixed", None, (), True, SUBPROCESS), marks=FULL_FLIGHT),
    pytest.param(
        Case("mixed", None, (Wind(6.0, 135.0), Avionics(20.0, at_s=200.0)), False, FAST),
        marks=FULL_FLIGHT,
    ),
    pytest.param(Case("hover-cruise", 200.0, (), False, FAST)),
    pytest.param(
        Case(
            "hover-cruise",
            200.0,
            (Wind(6.0, 30.0), Mass(0.5, at_s=60.0), Voltage(0.15, 25.2)),
            True,
            SUBPROCESS,
        )
    ),
]


@dataclass
class Flown:
    """What one end-to-end flight gave."""

    case: Case
    run: SimRun
    tlog: Path
    #: The daemon's JSON lines (every estimate), parsed, in order.
    estimates: list[dict]
    #: Everything the ground station received from our component.
    gcs: list[mavlink.MAVLink_message]
    #: A replay of the tlog the simulator wrote, as the daemon's JSON lines would give it.
    replayed: list[dict] = field(default_factory=list)
    #: The daemon's counters (in-process) or its log on stderr (subprocess).
    counters: dict[str, int] = field(default_factory=dict)
    daemon_log: str = ""

    def of_type(self, kind: str) -> list[mavlink.MAVLink_message]:
        return [m for m in self.gcs if m.get_type() == kind]


class GroundStation(threading.Thread):
    """A UDP socket on 127.0.0.1 read by its own thread with pymavlink's generated codec;
    keeps what component 191 of system 1 sends."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port: int = self.sock.getsockname()[1]
        self.codec = mavlink.MAVLink(None)
        self.codec.robust_parsing = True
        self.messages: list[mavlink.MAVLink_message] = []
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            for msg in self.codec.parse_buffer(data) or []:
                if (msg.get_srcSystem(), msg.get_srcComponent()) == (GCS_SYSTEM, OUR_COMPONENT):
                    self.messages.append(msg)

    def close(self) -> None:
        self.done.set()
        self.join(5)
        self.sock.close()


def _replay(tlog: Path) -> list[dict]:
    """The tlog through ``replay`` (the daemon's pipeline), as the daemon's JSON lines."""
    return [json.loads(json_line(e)) for e in replay_log(tlog, default_vehicle()).estimates]


async def daemon_subprocess(
    serve: Callable[[MavlinkLink], Awaitable[None]],
    replay: Callable[[], list[dict]],
    workdir: Path,
    *daemon_args: str,
) -> tuple[list[dict], list[dict], str]:
    """``uav-energy run`` as a subprocess, connected over TCP to a link served on an ephemeral
    port of 127.0.0.1 (system 1 component 1) that ``serve`` plays into (after waiting for the
    daemon's HEARTBEAT). Returns (the daemon's JSON estimates, ``replay()`` run after ``serve``,
    the daemon's log); waits for the daemon to catch up with the replay's count. Its stdout
    is a regular file in ``workdir``: written with blocking writes, nothing is ever dropped."""
    link = await open_link("tcpin:127.0.0.1:0", source_system=1, source_component=1)
    assert link.local_address is not None
    args = ["run", "--connect", f"tcp:127.0.0.1:{link.local_address[1]}", "--json", "-"]
    out_path, log_path = workdir / "daemon.jsonl", workdir / "daemon.log"
    with out_path.open("wb") as out, log_path.open("wb") as err:
        proc = await asyncio.create_subprocess_exec(
            str(EXE), *args, *daemon_args, stdout=out, stderr=err
        )
    try:
        await serve(link)
        replayed = await asyncio.to_thread(replay)
        seen, quiet_s = -1, 0.0
        # the daemon catching up (or, if it lost input, going quiet)
        while (lines := out_path.read_bytes().count(b"\n")) < len(replayed) and quiet_s < QUIET_S:
            quiet_s = 0.0 if lines != seen else quiet_s + 0.1
            seen = lines
            await asyncio.sleep(0.1)
    finally:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        await asyncio.wait_for(proc.wait(), 15)
        await link.close()
    log = log_path.read_text()
    assert proc.returncode == 0, log
    estimates = [json.loads(line) for line in out_path.read_text().splitlines()]
    return estimates, replayed, log


async def _fly(case: Case, tmp_path: Path) -> Flown:
    run = simulate(SimConfig(plan=case.plan, effects=case.effects, duration_s=case.duration_s))
    tlog = tmp_path / "flight.tlog"
    gcs = GroundStation()
    gcs.start()
    try:
        async with asyncio.timeout(FLIGHT_TIMEOUT_S):
            if case.subprocess:

                async def serve(link: MavlinkLink) -> None:
                    await serve_flight(run, link, case.speedup, tlog)

                estimates, replayed, log = await daemon_subprocess(
                    serve,
                    lambda: _replay(tlog),
                    tmp_path,
                    *("--publish", f"udpout:127.0.0.1:{gcs.port}", "--rate", str(PUBLISH_HZ)),
                )
                flown = Flown(case, run, tlog, estimates, [], replayed, daemon_log=log)
            else:
                live = await fly_live(
                    run,
                    case.speedup,
                    tlog=tlog,
                    publish=(f"udpout:127.0.0.1:{gcs.port}",),
                    publish_rate_hz=PUBLISH_HZ,
                )
                replayed = _replay(tlog)
                flown = Flown(case, run, tlog, live.estimates, [], replayed, live.counters)
        await asyncio.sleep(0.2)  # the last datagrams
    finally:
        gcs.close()
    flown.gcs = gcs.messages
    return flown


@pytest.fixture(scope="module", params=CASES, ids=[p.values[0].id for p in CASES])
def flown(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Flown:
    case: Case = request.param
    return asyncio.run(_fly(case, tmp_path_factory.mktemp(case.id)))


def _truth_index(flown: Flown, time_s: np.ndarray) -> np.ndarray:
    return np.asarray(flown.run.truth.at(time_s))


def _column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([np.nan if r[key] is None else r[key] for r in rows], dtype=float)


# -- the daemon's outputs reach the ground station ------------------------------------------------


def test_ground_station_gets_our_heartbeat_as_an_active_onboard_controller(flown: Flown) -> None:
    beats = flown.of_type("HEARTBEAT")
    assert beats, f"no HEARTBEAT from component 191 ({flown.case.id})"
    assert {(b.type, b.autopilot) for b in beats} == {
        (mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID)
    }
    assert any(b.system_status == mavlink.MAV_STATE_ACTIVE for b in beats)


def test_named_values_carry_the_estimates_the_daemon_computed(flown: Flown) -> None:
    """Every NAMED_VALUE_FLOAT name arrives, stamped with the autopilot clock, and carries
    (as float32) the estimate the daemon computed at that time_boot_ms."""
    values = flown.of_type("NAMED_VALUE_FLOAT")
    names = {m.name for m in values}
    assert names == set(NAMED_VALUES), names ^ set(NAMED_VALUES)
    by_ms: dict[int, list[float]] = {}
    for r in flown.estimates:  # several estimates may share a millisecond
        by_ms.setdefault(round(r["time_s"] * 1000), []).append(r["energy_remaining_wh"])
    energy = [m for m in values if m.name == "ENERGY_WH"]
    assert len(energy) >= 5
    for m in energy:
        candidates = by_ms[m.time_boot_ms]
        assert any(m.value == pytest.approx(wh, rel=1e-6) for wh in candidates), candidates
    duration_ms = 1000 * flown.run.duration_s
    assert all(0 <= m.time_boot_ms <= duration_ms + 1 for m in values)


def test_battery_status_time_remaining_and_pack_readings_are_sane(flown: Flown) -> None:
    ours = [b for b in flown.of_type("BATTERY_STATUS") if b.id == 9]
    assert ours, "no BATTERY_STATUS with our battery id 9"
    truth = flown.run.truth
    for b in ours:
        assert 0 <= b.battery_remaining <= 100
        assert b.time_remaining >= 0
        assert 20_000 < b.voltages[0] < 26_000  # 6S pack, mV
    flying = [b for b in ours if b.current_battery > 1_000]  # > 10 A: in the air
    assert flying
    left = np.array([b.time_remaining for b in flying], dtype=float)
    # steady endurance of a 3 kg quad on 10 Ah 6S: some ten to thirty minutes. Compared over
    # the second half of the flight (messages arrive in time order): before that come the
    # take-off transient and, on some cases, a hidden payload step the estimate cannot know
    late_truth_s = truth.time_to_reserve_s[truth.flying > 0]
    late_truth_s = late_truth_s[len(late_truth_s) // 2 :]
    assert np.median(left[len(left) // 2 :]) == pytest.approx(np.median(late_truth_s), rel=0.5)


# -- same pipeline, same numbers -----------------------------------------------------------------


def test_live_estimates_equal_a_replay_of_the_tlog_the_simulator_wrote(flown: Flown) -> None:
    assert flown.replayed, "the replay gave no estimate"
    assert len(flown.estimates) == len(flown.replayed)
    assert flown.estimates == flown.replayed


def test_the_daemon_dropped_nothing_and_stopped_cleanly(flown: Flown) -> None:
    if flown.case.subprocess:
        assert "stopped:" in flown.daemon_log
        for counter in ("link_dropped=", "link_bad_frames=", "json_dropped=", "internal_errors="):
            assert counter not in flown.daemon_log
    else:
        for counter in ("link_dropped", "link_bad_frames", "json_dropped", "internal_errors"):
            assert flown.counters.get(counter, 0) == 0


# -- sane against the truth ----------------------------------------------------------------------


def test_remaining_energy_stays_within_its_sigma_band_of_the_truth(flown: Flown) -> None:
    rows = flown.estimates
    k = _truth_index(flown, _column(rows, "time_s"))
    error = _column(rows, "energy_remaining_wh") - flown.run.truth.energy_remaining_wh[k]
    sigma = _column(rows, "energy_remaining_sigma_wh")
    assert np.all(sigma > 0)
    assert np.mean(np.abs(error) <= sigma) >= 0.9
    assert np.mean(np.abs(error) <= 2 * sigma) >= 0.99


def test_fused_power_follows_the_hidden_effects_and_only_them(flown: Flown) -> None:
    """In steady level flight the fused power (bias × model, the model with the wind and mass
    tracked online) follows the true power, whether hidden effects push it away from the
    vehicle file's model or not; without hidden effects nothing moves (bias near 1)."""
    rows = flown.estimates
    tr = flown.run.truth
    k = _truth_index(flown, _column(rows, "time_s"))
    level = tr.flying[k] & (tr.alt_m[k] > 15.0) & (np.abs(tr.vd_mps[k]) < 0.2)
    later = slice(int(level.sum()) // 3, None)  # after the filters have had time to learn
    fused = (_column(rows, "bias") * _column(rows, "power_model_w"))[level][later]
    measured = _column(rows, "power_measured_w")[level][later]
    true_w, plain_w = tr.power_w[k][level][later], tr.power_model_w[k][level][later]
    truth_scale = np.median(true_w / plain_w)
    assert np.median(fused / true_w) == pytest.approx(1.0, abs=0.04)
    if not flown.case.effects:
        assert truth_scale == pytest.approx(1.0, abs=0.01)
        assert np.median(_column(rows, "bias")[level][later]) == pytest.approx(1.0, abs=0.04)
    else:
        assert abs(truth_scale - 1.0) > 0.04
        fused_rmse = np.sqrt(np.nanmean((fused - measured) ** 2))
        plain_rmse = np.sqrt(np.nanmean((plain_w - measured) ** 2))
        assert fused_rmse < plain_rmse


def test_cruise_endurance_is_within_five_percent_of_the_truth(flown: Flown) -> None:
    if flown.case.plan != "hover-cruise":
        pytest.skip("steady endurance is scored on the cruise plan")
    rows = flown.estimates
    tr = flown.run.truth
    t = _column(rows, "time_s")
    cruise_start = float(tr.time_s[np.nonzero(tr.speed_mps > 9.7)[0][0]])
    late = t > cruise_start + 40.0
    assert late.sum() > 60  # one a second
    k = _truth_index(flown, t[late])
    error = _column(rows, "endurance_s")[late] / tr.time_to_reserve_s[k] - 1.0
    assert np.max(np.abs(error)) < 0.05
    assert not math.isinf(rows[-1]["endurance_sigma_s"])
