"""The daemon end to end on loopback with real sockets, and its bad-input behaviour.

A sender plays a simulated flight into ``Service`` over UDP; an independent pymavlink client
(a plain socket + the generated codec) and a MAVSDK 4.x ``mavsdk.asyncio`` client receive
what it publishes. Values must equal what :class:`Pipeline` gives for the same messages.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import socket
from collections.abc import AsyncIterator, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fixtures.held_voltage import held_voltage_flight, own_curve_vehicle
from pymavlink.dialects.v20 import common as mavlink

from estimator.cli import main as cli_main
from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.link import MavlinkLink, open_link
from estimator.mavlink.service import Service
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import BatterySample

Messages = list[tuple[float, mavlink.MAVLink_message]]


@pytest.fixture(scope="module")
def flight() -> Messages:
    return simulate(SimConfig(plan="hover-cruise", duration_s=40.0, seed=3)).messages


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def replay(
    messages: Iterable[mavlink.MAVLink_message], vehicle: Vehicle | None = None
) -> list[Estimate]:
    vehicle = vehicle or default_vehicle()
    decoder = TelemetryDecoder(limits=vehicle.input_limits())
    pipeline = Pipeline(vehicle)
    out = []
    for msg in messages:
        for sample in decoder.decode(msg):
            estimate = pipeline.process(sample)
            if estimate is not None:
                out.append(estimate)
    return out


class PymavlinkClient(asyncio.DatagramProtocol):
    """Independent ground station: a UDP socket parsed with pymavlink's generated codec."""

    def __init__(self) -> None:
        self.codec = mavlink.MAVLink(None)
        self.codec.robust_parsing = True
        self.messages: list[mavlink.MAVLink_message] = []

    def datagram_received(self, data: bytes, addr: object) -> None:
        for msg in self.codec.parse_buffer(data) or []:
            if not isinstance(msg, mavlink.MAVLink_bad_data):
                self.messages.append(msg)

    def of_type(self, kind: str) -> list[mavlink.MAVLink_message]:
        return [m for m in self.messages if m.get_type() == kind]

    def named(self, name: str) -> dict[int, float]:
        """Last value of a NAMED_VALUE_FLOAT per time_boot_ms."""
        return {
            m.time_boot_ms: m.value for m in self.of_type("NAMED_VALUE_FLOAT") if m.name == name
        }


@contextlib.asynccontextmanager
async def running(
    config: ServiceConfig, vehicle: Vehicle | None = None
) -> AsyncIterator[tuple[Service, MavlinkLink]]:
    """A Service on udpin:127.0.0.1:<free> (default vehicle unless given), and a sender link
    (system 1, component 1)."""
    port = free_udp_port()
    connect = f"udpin:127.0.0.1:{port}"
    service = Service(replace(config, connect=connect), vehicle or default_vehicle())
    stop = asyncio.Event()
    task = asyncio.create_task(service.run(stop))
    while service.link is None:
        await asyncio.sleep(0.01)
    sender = await open_link(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    try:
        yield service, sender
    finally:
        await sender.close()
        stop.set()
        assert await asyncio.wait_for(task, 5) == 0


async def play(sender: MavlinkLink, messages: Iterable[mavlink.MAVLink_message]) -> None:
    for i, msg in enumerate(messages):
        sender.send(msg)
        if i % 5 == 4:
            await asyncio.sleep(0.004)


async def wait_for(condition, timeout_s: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    async with asyncio.timeout(timeout_s):
        while not condition():
            await asyncio.sleep(0.02)


async def first_mavsdk_system(sdk: Any) -> Any:
    """The first system a MAVSDK client sees (within 10 s)."""
    async with asyncio.timeout(10):
        while not (systems := await sdk.get_systems()):
            await asyncio.sleep(0.05)
    return systems[0]


async def listen() -> tuple[PymavlinkClient, int, asyncio.DatagramTransport]:
    loop = asyncio.get_running_loop()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
    sock.bind(("127.0.0.1", 0))
    transport, client = await loop.create_datagram_endpoint(PymavlinkClient, sock=sock)
    return client, int(sock.getsockname()[1]), transport


async def test_published_values_match_the_pipeline_replay_for_pymavlink_and_mavsdk(
    flight: Messages,
) -> None:
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    messages = [m for _, m in flight]
    expected = replay(messages)
    client, client_port, transport = await listen()
    sdk_port = free_udp_port()
    config = ServiceConfig(
        publish=(f"udpout:127.0.0.1:{client_port}", f"udpout:127.0.0.1:{sdk_port}"),
        publish_rate_hz=0.0,
        stale_after_s=30.0,
    )
    sdk_config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(sdk_config) as sdk, running(config) as (_service, sender):
        await sdk.add_any_connection(f"udpin://127.0.0.1:{sdk_port}")
        half = len(messages) // 2
        await play(sender, messages[:half])
        await wait_for(lambda: len(client.of_type("HEARTBEAT")) > 0)
        system = await first_mavsdk_system(sdk)
        direct = MavlinkDirectAsync(system)
        telemetry = TelemetryAsync(system)
        sdk_named: list[dict] = []
        sdk_battery: list = []

        async def collect_named() -> None:
            import json

            async for msg in direct.subscribe_message("NAMED_VALUE_FLOAT"):
                sdk_named.append(json.loads(msg.fields_json) | {"component": msg.component_id})

        async def collect_battery() -> None:
            async for battery in telemetry.subscribe_battery():
                sdk_battery.append(battery)

        tasks = [asyncio.create_task(collect_named()), asyncio.create_task(collect_battery())]
        await asyncio.sleep(0.5)
        await play(sender, messages[half:])
        await wait_for(lambda: _service.pipeline.counts["estimates"] == len(expected))
        await asyncio.sleep(0.3)
        await wait_for(lambda: len(sdk_named) > 0 and len(sdk_battery) > 0)
        await asyncio.sleep(0.3)
        for task in tasks:
            task.cancel()
        assert sdk_port and system is not None and not await system.has_autopilot()
    transport.close()

    by_ms: dict[int, Estimate] = {round(e.time_s * 1000): e for e in expected}
    # pymavlink client: heartbeat, every named value, BATTERY_STATUS.time_remaining
    heartbeat = client.of_type("HEARTBEAT")[-1]
    assert (heartbeat.type, heartbeat.autopilot) == (
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_AUTOPILOT_INVALID,
    )
    assert heartbeat.get_srcComponent() == 191
    endurance = client.named("ENDUR_S")
    assert len(endurance) > 0.8 * len(by_ms)
    last_ms = max(endurance)
    last = by_ms[last_ms]
    for ms, value in endurance.items():
        est = by_ms[ms]  # not yet valid (start-up): published as NaN
        want = est.endurance_s if est.endurance_valid else math.nan
        assert value == pytest.approx(want, rel=1e-6, nan_ok=True)
    assert last.endurance_valid
    for name, value in (
        ("PWR_MODEL", last.power_model_w),
        ("ENERGY_WH", last.energy_remaining_wh),
        ("ENDUR_SIG", last.endurance_sigma_s),
        ("ENDUR_HOV", last.hover_endurance_s),
        ("BIAS", last.bias),
        ("RANGE_VMR", last.range_vmr_m),
    ):
        assert client.named(name)[last_ms] == pytest.approx(value, rel=1e-6)
    battery = client.of_type("BATTERY_STATUS")[-1]
    assert battery.id == 9
    assert battery.time_remaining == int(expected[-1].endurance_s)
    assert 0 < battery.battery_remaining <= 100
    # MAVSDK: sees component 191's NAMED_VALUE_FLOAT (mavlink_direct) and our battery
    endurance_sdk = [m for m in sdk_named if m["name"] == "ENDUR_S"]
    assert endurance_sdk and all(m["component"] == 191 for m in endurance_sdk)
    all_by_ms: dict[int, list[float]] = {}
    for e in expected:
        value = e.endurance_s if e.endurance_valid else math.nan
        all_by_ms.setdefault(round(e.time_s * 1000), []).append(value)
    for m in endurance_sdk:  # same time_boot_ms can carry several estimates: match one
        candidates = all_by_ms[m["time_boot_ms"]]
        if math.isnan(m["value"]):
            assert any(math.isnan(c) for c in candidates)
        else:
            assert min(abs(m["value"] - c) / c for c in candidates) < 1e-6
    valid_remaining = {
        int(e.endurance_s) if e.endurance_valid and np.isfinite(e.endurance_s) else 0
        for e in expected
    }
    assert sdk_battery[-1].id == 9
    assert int(sdk_battery[-1].time_remaining_s) in valid_remaining


async def test_garbage_datagrams_and_a_flood_do_not_stop_the_daemon(flight: Messages) -> None:
    messages = [m for _, m in flight]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        await play(sender, messages[:300])
        for i in range(200):
            sender.send_bytes(bytes((i * 7 + k) % 256 for k in range(64)))
            sender.send_bytes(b"\xfd\x20" + b"\x00" * 5)
        flood = sender.mav.named_value_float_encode(0, b"FLOOD", 1.0)
        for _ in range(20_000):
            sender.send(flood)
        await asyncio.sleep(0.2)
        before = service.pipeline.counts["estimates"]
        await play(sender, messages[300:600])
        await wait_for(lambda: service.pipeline.counts["estimates"] > before + 5)  # 1 a second
        assert service.link is not None and service.link.bad_frames > 0
        assert service.link.counts["skipped_frames"] > 0  # dropped by header, unparsed


async def test_silent_link_marks_estimates_stale_then_resumes(
    flight: Messages, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="uav_energy.service")
    messages = [m for _, m in flight]
    client, port, transport = await listen()
    config = ServiceConfig(publish=(f"udpout:127.0.0.1:{port}",), stale_after_s=0.5)
    async with running(config) as (service, sender):
        await play(sender, messages[:400])
        await wait_for(lambda: service.out.latest is not None)
        await wait_for(lambda: service.out.stale, timeout_s=5)
        await wait_for(lambda: any(int(v) & 2 for v in client.named("FLAGS").values()), 5)
        stale_count = len(client.of_type("NAMED_VALUE_FLOAT"))

        async def keep_talking() -> None:  # telemetry back, at about 40 msg/s
            for msg in messages[400:]:
                sender.send(msg)
                await asyncio.sleep(0.025)

        talking = asyncio.create_task(keep_talking())
        try:
            await wait_for(lambda: not service.out.stale)

            def live_flags_after_resume() -> bool:
                named = client.of_type("NAMED_VALUE_FLOAT")[stale_count:]
                return any(m.name == "FLAGS" and int(m.value) & 2 == 0 for m in named)

            await wait_for(live_flags_after_resume, 5)
        finally:
            talking.cancel()
    transport.close()
    text = caplog.text
    assert "link silent" in text and "telemetry resumed" in text


async def test_autopilot_reboot_keeps_the_energy_state(flight: Messages) -> None:
    messages = [m for _, m in flight]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: service.pipeline.counts["velocity"] > 300)
        await asyncio.sleep(0.3)
        assert service.out.latest is not None
        energy_before = service.out.latest.energy_remaining_wh
        # the autopilot reboots: the same stream again, its clock starting from 0
        await play(sender, messages[: len(messages) // 3])
        await wait_for(lambda: service.decoder.counts["reboots"] == 1)
        await asyncio.sleep(0.3)
        assert service.pipeline.counts["reboot"] == 1
        latest = service.out.latest
        assert latest is not None and latest.time_s < 20
        assert latest.energy_remaining_wh <= energy_before + 0.5
        assert np.isfinite(latest.endurance_s)


def test_broken_config_is_one_line_and_exit_code_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[link]\nconnect = "udp:nowhere"\n')
    assert cli_main(["run", "--config", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "connection string" in err
    bad.write_text("[link]\nvelocity_rate_hz = -3\n")
    assert cli_main(["run", "--config", str(bad)]) == 2
    assert "velocity_rate_hz" in capsys.readouterr().err
    bad.write_text("[nonsense]\nkey = 1\n")
    assert cli_main(["run", "--config", str(bad)]) == 2
    assert "unknown key" in capsys.readouterr().err
    assert cli_main(["run", "--config", str(tmp_path / "missing.toml")]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
async def test_cli_daemon_streams_json_and_stops_cleanly_on_signals(
    flight: Messages, sig: str
) -> None:
    """``uav-energy run`` as a real process: JSON lines on stdout, exit 0 on the signal."""
    import json
    import signal
    import sys

    port = free_udp_port()
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "estimator.cli",
        "run",
        "--connect",
        f"udpin:127.0.0.1:{port}",
        "--json",
        "-",
        "--log-level",
        "info",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    assert proc.stdout is not None and proc.stderr is not None
    sender = await open_link(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    try:
        lines: list[dict] = []
        async with asyncio.timeout(30):
            while not lines:
                await play(sender, [m for _, m in flight[:200]])
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(1.0):
                        lines.append(json.loads(await proc.stdout.readline()))
        assert {"time_s", "endurance_s", "energy_remaining_wh", "model_only"} <= set(lines[0])
    finally:
        await sender.close()
        proc.send_signal(getattr(signal, sig))
        code = await asyncio.wait_for(proc.wait(), 10)
    log_text = (await proc.stderr.read()).decode()
    assert code == 0
    assert "autopilot found" in log_text and "stopped:" in log_text
    assert "Traceback" not in log_text


async def test_configured_target_ignores_other_autopilots(flight: Messages) -> None:
    messages = [m for _, m in flight[:600]]
    config = ServiceConfig(target_system=7, target_component=1, stale_after_s=30.0)
    async with running(config) as (service, sender):
        await play(sender, messages)  # system 1 is not ours to watch
        impostor = await open_link(
            f"udpout:127.0.0.1:{service.link.local_address[1]}",  # type: ignore[union-attr]
            source_system=7,
            source_component=1,
        )
        await play(impostor, messages)
        await wait_for(lambda: service.out.latest is not None)
        await impostor.close()
        assert service.decoder.target == (7, 1)
        assert service.link is not None
        skipped = service.link.counts["skipped_frames"]  # unused ids: dropped by header
        assert service.decoder.counts["other_source"] + skipped >= len(messages) - 5


async def test_an_exception_on_one_message_is_logged_and_skipped(
    flight: Messages, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    messages = [m for _, m in flight[:600]]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        real = service.pipeline.process
        calls = {"n": 0}

        def flaky(sample):  # type: ignore[no-untyped-def]
            calls["n"] += 1
            if calls["n"] == 50:
                raise ValueError("unexpected")
            return real(sample)

        monkeypatch.setattr(service.pipeline, "process", flaky)
        await play(sender, messages)
        await wait_for(lambda: calls["n"] > 120)
        assert service.internal_errors == 1
        assert service.out.latest is not None
    assert "internal error #1" in caplog.text


async def test_daemon_as_tcp_client_like_ardupilot_sitl(flight: Messages) -> None:
    """The autopilot listens on TCP (SITL's tcp:127.0.0.1:5760 style); the daemon connects,
    requests streams, and estimates; no HEARTBEAT towards the autopilot unless configured."""
    autopilot = await open_link("tcpin:127.0.0.1:0", source_system=1, source_component=1)
    assert autopilot.local_address is not None
    config = ServiceConfig(connect=f"tcp:127.0.0.1:{autopilot.local_address[1]}")
    service = Service(config, default_vehicle())
    stop = asyncio.Event()
    task = asyncio.create_task(service.run(stop))
    try:
        requests: list[mavlink.MAVLink_message] = []
        messages = [m for _, m in flight[:400]]
        async with asyncio.timeout(15):
            while service.out.latest is None:
                await play(autopilot, messages[:100])
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(0.2):
                        requests.extend(await autopilot.recv())
            await play(autopilot, messages[100:])
            while "COMMAND_LONG" not in {m.get_type() for m in requests}:
                requests.extend(await autopilot.recv())
            with contextlib.suppress(TimeoutError):  # 1.5 heartbeat periods
                async with asyncio.timeout(1.5):
                    while True:
                        requests.extend(await autopilot.recv())
        kinds = {m.get_type() for m in requests}
        assert {"REQUEST_DATA_STREAM", "COMMAND_LONG"} <= kinds
        assert "HEARTBEAT" not in kinds
        commands = [m for m in requests if m.get_type() == "COMMAND_LONG"]
        home = (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
        version = (mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)
        assert version in {(m.command, int(m.param1)) for m in commands}
        intervals = [m for m in commands if (m.command, int(m.param1)) not in (home, version)]
        assert all(m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL for m in intervals)
        assert {int(m.param1) for m in intervals} >= {
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
            mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,
        }
        assert all(m.get_srcComponent() == 191 for m in requests)
    finally:
        stop.set()
        await asyncio.wait_for(task, 5)
        await autopilot.close()


def test_shipped_default_config_matches_the_built_in_defaults() -> None:
    from estimator.mavlink.config import build_config, load_config_file

    path = Path(__file__).resolve().parent.parent / "config" / "default.toml"
    assert build_config(load_config_file(path), {}) == ServiceConfig()


def test_flags_override_the_config_file(tmp_path: Path) -> None:
    from estimator.cli import build_parser
    from estimator.commands.run import config_from_args

    conf = tmp_path / "c.toml"
    conf.write_text('[publish]\nrate_hz = 5.0\nurls = ["udpout:127.0.0.1:14551"]\n')
    args = build_parser("run").parse_args(
        ["run", "--config", str(conf), "--rate", "2", "--target", "3:1", "--connect", "tcp:h:5760"]
    )
    config = config_from_args(args)
    assert config.publish_rate_hz == 2.0 and config.publish == ("udpout:127.0.0.1:14551",)
    assert (config.target_system, config.target_component) == (3, 1)
    assert config.connect == "tcp:h:5760"


def test_named_value_names_fit_mavlink_and_are_documented() -> None:
    from estimator.mavlink.publish import NAMED_VALUES

    doc = (Path(__file__).resolve().parent.parent / "docs" / "daemon.md").read_text()
    for name in NAMED_VALUES:
        assert 0 < len(name) <= 10 and name.isupper()
        assert f"`{name}`" in doc


@pytest.mark.parametrize("battery_to_autopilot", [False, True])
async def test_battery_status_goes_towards_the_autopilot_only_when_configured(
    flight: Messages, battery_to_autopilot: bool
) -> None:
    config = ServiceConfig(
        values_to_autopilot=True,
        battery_status_to_autopilot=battery_to_autopilot,
        publish_rate_hz=20.0,
        stale_after_s=30.0,
    )
    async with running(config) as (service, sender):
        await play(sender, [m for _, m in flight[:400]])
        await wait_for(lambda: service.out.latest is not None)
        received: list[mavlink.MAVLink_message] = []
        async with asyncio.timeout(5):
            while sum(m.get_type() == "NAMED_VALUE_FLOAT" for m in received) < 32:
                received.extend(await sender.recv())
        kinds = {m.get_type() for m in received if m.get_srcComponent() == 191}
        assert "NAMED_VALUE_FLOAT" in kinds
        assert ("BATTERY_STATUS" in kinds) == battery_to_autopilot


def test_fusion_table_sets_the_noise_figures_and_rejects_unknown_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from estimator.mavlink.config import build_config, load_config_file

    conf = tmp_path / "c.toml"
    conf.write_text("[fusion]\ninternal_resistance_ohm = 0.03\ncapacity_sigma_fraction = 0\n")
    config = build_config(load_config_file(conf), {})
    service = Service(config, default_vehicle())
    settings = service.pipeline.energy.settings
    assert settings.internal_resistance_ohm == 0.03 and settings.capacity_sigma_fraction == 0.0
    conf.write_text("[fusion]\nresistence = 0.03\n")
    assert cli_main(["run", "--config", str(conf)]) == 2
    assert "no setting 'resistence'" in capsys.readouterr().err
    conf.write_text("[fusion]\nbias_prior_sigma = -1\n")
    assert cli_main(["run", "--config", str(conf)]) == 2
    assert "'bias_prior_sigma' must be a number from 0 to 1" in capsys.readouterr().err


async def test_forged_reboots_from_the_autopilots_address_are_dropped(
    flight: Messages, caplog: pytest.LogCaptureFixture
) -> None:
    """Ten forged reboots from the autopilot's own address (five agreeing frames of an
    earlier clock each, its real clock back after each): none is believed, since the old
    clock never stops; the frames are dropped and counted, the estimates equal a replay of
    the flight without them, and no stream request goes out for them."""
    caplog.set_level(logging.INFO, logger="uav_energy.service")
    messages = [m for _, m in flight]
    half = len(messages) // 2
    step = (len(messages) - half) // 10
    received: list[mavlink.MAVLink_message] = []
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):

        async def collect() -> None:
            while batch := await sender.recv():
                received.extend(batch)

        collector = asyncio.create_task(collect())
        await play(sender, messages[:half])
        await wait_for(lambda: service.out.latest is not None and service._streams_ok)
        requests_before = sum(m.get_type() == "REQUEST_DATA_STREAM" for m in received)
        for k in range(10):
            for j in range(5):  # an earlier clock, five agreeing frames
                sender.send(sender.mav.attitude_encode(1_000 + 100 * j, 0, 0, 0, 0, 0, 0))
            await play(sender, messages[half + k * step : half + (k + 1) * step])
        expected = replay(messages[: half + 10 * step])[-1]
        await wait_for(lambda: service.out.latest == expected)
        collector.cancel()
    assert service.lock.counts["off_clock_frames"] == 50
    assert service.decoder.counts["reboots"] == service.decoder.counts["clock_jumps"] == 0
    requests_after = sum(m.get_type() == "REQUEST_DATA_STREAM" for m in received)
    assert requests_after == requests_before
    assert "autopilot rebooted" not in caplog.text
    assert "autopilot_off_clock_frames=50" in caplog.text  # the counters at exit


def test_battery_status_replaces_sys_status_after_three_and_falls_back_when_it_stops() -> None:
    """One BATTERY_STATUS does not switch SYS_STATUS off; three in a row do; SYS_STATUS is
    used again 3 s (autopilot clock) after the last BATTERY_STATUS."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser = FrameParser()

    def frames(t_ms: int, battery_status: bool) -> list[mavlink.MAVLink_message]:
        msgs = [
            codec.heartbeat_encode(2, 3, 0, 0, 4),
            codec.attitude_encode(t_ms, 0, 0, 0, 0, 0, 0),
            codec.sys_status_encode(0, 0, 0, 500, 22_000, 1_000, 80, 0, 0, 0, 0, 0, 0),
        ]
        if battery_status:
            cells = [22_100] + [65_535] * 9
            msgs.append(codec.battery_status_encode(0, 0, 0, 2_500, cells, 1_000, 100, -1, 80))
        return [m for msg in msgs for m in parser.feed(msg.pack(codec))]

    decoder = TelemetryDecoder()

    def sources(t_ms: int, battery_status: bool) -> list[float]:
        samples = decoder.decode_all(frames(t_ms, battery_status))
        return [s.voltage_v for s in samples if isinstance(s, BatterySample)]

    for t_ms in range(1_000, 2_000, 200):  # the clock starts
        sources(t_ms, False)
    assert sources(2_000, True) == [22.0]  # one BATTERY_STATUS: SYS_STATUS still used
    assert sources(2_200, False) == [22.0]
    assert sources(2_400, True) == [22.0]
    assert sources(2_600, True) == [22.0, 22.1]  # the third in a row takes over
    assert sources(2_800, True) == [22.1]
    assert sources(4_000, False) == []  # 1.2 s without: still BATTERY_STATUS's turn
    assert sources(6_000, False) == [22.0]  # 3.2 s without: SYS_STATUS again
    assert decoder.counts["battery_status_stopped"] == 1


async def test_a_pack_voltage_that_holds_as_charge_is_drawn_is_said_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A vehicle with the pack's own curve, its pack's voltage held at rest less I·R over
    UDP (the charge drawn never shows): the daemon says once that the capacity is not learnt
    and the energy is counted against the label, and publishes no capacity after."""
    caplog.set_level(logging.INFO, logger="uav_energy.service")
    messages = [m for _, m in held_voltage_flight(150.0)]
    async with running(ServiceConfig(stale_after_s=30.0), own_curve_vehicle()) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: service.pipeline.packs.refuted, timeout_s=20)
        await wait_for(lambda: "does not follow the charge drawn" in caplog.text)
        latest = service.out.latest
        assert latest is not None and math.isnan(latest.capacity_ah)
    assert caplog.text.count("does not follow the charge drawn") == 1
