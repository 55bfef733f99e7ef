"""The MAVLink side of the return-home and mission figures, over real UDP sockets: positions,
home and mission items decoded (and their sentinels skipped), HOME_POSITION requested when it
does not come, the mission read with the mission protocol (retries, failures, changes), and
margin warnings with hysteresis."""

from __future__ import annotations

import asyncio
import logging
import math
from dataclasses import replace

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import Messages, first_mavsdk_system, running, wait_for

from estimator.estimation.estimate import Estimate
from estimator.logs.mission_files import M_PER_DEG
from estimator.mavlink import streams as streams_module
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.link import MavlinkLink
from estimator.mavlink.margin_alerts import MarginAlerts
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import (
    ArmedSample,
    HomeSample,
    MissionCurrentSample,
    PositionSample,
    VelocitySample,
)

_ENC = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


@pytest.fixture(scope="module")
def flight() -> Messages:
    """40 s of the simulator's hover → cruise flight (home at its take-off point)."""
    return simulate(SimConfig(plan="hover-cruise", duration_s=40.0, seed=3)).messages


HOME = (47.397742, 8.545594, 488.0)


def heartbeat() -> mavlink.MAVLink_message:
    return _ENC.heartbeat_encode(
        mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0
    )


def position(time_ms: int, lat_deg: float, lon_deg: float) -> mavlink.MAVLink_message:
    return _ENC.global_position_int_encode(
        time_ms, round(lat_deg * 1e7), round(lon_deg * 1e7), 500_000, 20_000, 100, 0, 0, 0
    )


def home(lat_deg: float, lon_deg: float, alt_m: float = 488.0) -> mavlink.MAVLink_message:
    return _ENC.home_position_encode(
        round(lat_deg * 1e7),
        round(lon_deg * 1e7),
        round(alt_m * 1000),
        0,
        0,
        0,
        [1, 0, 0, 0],
        0,
        0,
        0,
    )


def decoded(messages: list[mavlink.MAVLink_message]) -> tuple[TelemetryDecoder, list[object]]:
    """Decode after a HEARTBEAT and five ATTITUDE frames (600–1000 ms) that start the clock."""
    clock = [_ENC.attitude_encode(ms, 0, 0, 0, 0, 0, 0) for ms in range(600, 1001, 100)]
    sent = [heartbeat(), *clock, *messages]
    for msg in sent:  # as if from the wire: source ids set
        msg.pack(_ENC)
    decoder = TelemetryDecoder()
    samples = decoder.decode_all(sent)
    return decoder, [s for s in samples if not isinstance(s, ArmedSample)]


def test_positions_home_and_mission_item_are_decoded_on_the_autopilot_clock() -> None:
    current = _ENC.mission_current_encode(3, 7, 0, 0)
    _, samples = decoded([position(1000, 47.4, 8.55), home(*HOME), current])
    assert [type(s) for s in samples] == [
        VelocitySample,
        PositionSample,
        HomeSample,
        MissionCurrentSample,
    ]
    pos, home_s, cur = samples[1], samples[2], samples[3]
    assert isinstance(pos, PositionSample) and pos.time_s == 1.0
    assert (pos.lat_deg, pos.lon_deg, pos.alt_m) == (pytest.approx(47.4), pytest.approx(8.55), 20.0)
    assert isinstance(home_s, HomeSample) and home_s.alt_amsl_m == 488.0 and home_s.time_s == 1.0
    assert isinstance(cur, MissionCurrentSample) and (cur.seq, cur.total) == (3, 7)


def test_zero_zero_and_off_the_globe_positions_and_homes_are_counted_skips() -> None:
    decoder, samples = decoded(
        [position(1000, 0.0, 0.0), home(0.0, 0.0), position(1100, 95.0, 8.0), home(47.0, 200.0)]
    )
    assert not any(isinstance(s, PositionSample | HomeSample) for s in samples)
    assert sum(isinstance(s, VelocitySample) for s in samples) == 2  # the velocity is kept
    counts = decoder.counts
    assert counts["position_unknown"] == counts["home_unknown"] == 1
    assert counts["position_implausible"] == counts["home_implausible"] == 1


def test_position_comes_from_global_position_int_when_velocity_is_local_position_ned() -> None:
    local = _ENC.local_position_ned_encode(1000, 0, 0, -20, 1.0, 0, 0)
    _, samples = decoded([local, position(1020, 47.4, 8.55), position(9000, 47.4, 8.55)])
    kinds = [type(s) for s in samples]
    assert kinds == [VelocitySample, PositionSample]  # a stamp 8 s off the clock is not taken
    assert samples[1].time_s == 1.02  # type: ignore[attr-defined]


# -- the daemon over UDP ---------------------------------------------------------------------------


class MissionServer:
    """An autopilot's mission protocol on the test's sender link: answers MISSION_REQUEST_LIST
    and MISSION_REQUEST_INT with ``items`` waypoints, ignoring the first ``drop`` requests
    (``silent``: all of them; ``refuse``: answers each with an error MISSION_ACK); records
    everything it receives."""

    def __init__(self, link: MavlinkLink, items: int, drop: int = 0, silent: bool = False) -> None:
        self.link, self.items, self.drop, self.silent = link, items, drop, silent
        self.refuse = False
        self.received: list[mavlink.MAVLink_message] = []
        self.task = asyncio.create_task(self._serve())

    def kinds(self, kind: str) -> list[mavlink.MAVLink_message]:
        return [m for m in self.received if m.get_type() == kind]

    async def _serve(self) -> None:
        while received := await self.link.recv():
            for msg in received:
                self.received.append(msg)
                kind = msg.get_type()
                if self.silent or kind not in ("MISSION_REQUEST_LIST", "MISSION_REQUEST_INT"):
                    continue
                if self.drop > 0:
                    self.drop -= 1
                    continue
                src = (msg.get_srcSystem(), msg.get_srcComponent())
                mav = self.link.mav
                if self.refuse:
                    self.link.send(mav.mission_ack_encode(*src, mavlink.MAV_MISSION_DENIED, 0))
                elif kind == "MISSION_REQUEST_LIST":
                    self.link.send(mav.mission_count_encode(*src, self.items, 0))
                else:
                    lat, lon = HOME[0] + 0.001 * msg.seq, HOME[1]
                    self.link.send(
                        mav.mission_item_int_encode(
                            *src,
                            msg.seq,
                            mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                            mavlink.MAV_CMD_NAV_WAYPOINT,
                            0,
                            1,
                            0,
                            0,
                            0,
                            0,
                            round(lat * 1e7),
                            round(lon * 1e7),
                            20.0,
                            0,
                        )
                    )


async def test_mission_is_read_with_retries_and_read_again_when_it_changes(
    flight: Messages,
) -> None:
    messages = [m for _, m in flight]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        server = MissionServer(sender, items=4, drop=2)  # the list request and one item lost
        for msg in messages[:300]:
            sender.send(msg)
            await asyncio.sleep(0.002)
        await wait_for(lambda: service.pipeline.returning.mission is not None, 15)
        mission = service.pipeline.returning.mission
        assert mission is not None and [i.seq for i in mission] == [0, 1, 2, 3]
        assert mission[2].lat_deg == pytest.approx(HOME[0] + 0.002)
        assert mission[2].command == mavlink.MAV_CMD_NAV_WAYPOINT
        assert len(server.kinds("MISSION_ACK")) == 1
        assert service.mission is not None and service.mission.counts["resends"] >= 2
        # read-only: nothing but the download's requests and the final ACK
        mission_kinds = {m.get_type() for m in server.received if "MISSION" in m.get_type()}
        assert mission_kinds == {"MISSION_REQUEST_LIST", "MISSION_REQUEST_INT", "MISSION_ACK"}
        # another ground station uploads 6 items: MISSION_CURRENT's count changes
        server.items = 6
        for total in (4, 6):
            sender.send(sender.mav.mission_current_encode(1, total, 0, 0))
            await asyncio.sleep(0.05)
        await wait_for(lambda: len(server.kinds("MISSION_ACK")) == 2, 15)
        await wait_for(lambda: len(service.pipeline.returning.mission or ()) == 6, 5)
        assert service.mission.counts["mission_changes"] == 1
        server.task.cancel()


async def test_failed_mission_downloads_are_counted_and_warned_once_per_cause(
    flight: Messages, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A silent autopilot (as ``uav-energy sim``), then one that refuses: each cause is one
    warning however often the download is retried; the repeats are one line at the stop."""
    from estimator.mavlink import mission_download

    monkeypatch.setattr(mission_download, "ITEM_TIMEOUT_S", 0.2)
    monkeypatch.setattr(mission_download, "RETRIES", 1)
    monkeypatch.setattr(mission_download, "RETRY_AFTER_S", 0.0)
    caplog.set_level(logging.INFO, logger="uav_energy")
    messages = [m for _, m in flight]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        server = MissionServer(sender, items=3, silent=True)
        for msg in messages[:200]:
            sender.send(msg)
            await asyncio.sleep(0.002)

        def failed() -> int:
            return 0 if service.mission is None else service.mission.counts["downloads_failed"]

        await wait_for(lambda: failed() == 2, 15)
        assert len(server.kinds("MISSION_REQUEST_LIST")) == 2 * (1 + mission_download.RETRIES)
        assert service.out.latest is not None and service.out.latest.rth_flags & 4  # no mission
        server.silent, server.refuse = False, True
        await wait_for(lambda: failed() == 5, 15)
        server.task.cancel()
    warned = [r.message for r in caplog.records if r.levelno == logging.WARNING]
    assert [w for w in warned if "mission download failed" in w] == [
        "mission download failed (no answer): retrying every 0 s; further failures are "
        "counted (mission_downloads_failed)",
        "mission download failed (refused: MAV_MISSION_DENIED): retrying every 0 s; further "
        "failures are counted (mission_downloads_failed)",
    ]
    assert (
        "the mission download (no answer) warning above holds for 1 more download attempts too"
        in warned
    )
    assert (
        "the mission download (refused: MAV_MISSION_DENIED) warning above holds for 2 more "
        "download attempts too"
    ) in warned


async def test_home_is_requested_when_positions_come_without_it_then_followed(
    flight: Messages, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(streams_module, "HOME_REQUEST_AFTER_S", 0.5)
    messages = [m for _, m in flight]
    config = ServiceConfig(stale_after_s=30.0, download_mission=False)
    async with running(config) as (service, sender):
        server = MissionServer(sender, items=0, silent=True)  # records what the daemon sends

        def home_requests() -> list[mavlink.MAVLink_message]:
            return [
                m
                for m in server.kinds("COMMAND_LONG")
                if m.command == mavlink.MAV_CMD_REQUEST_MESSAGE
            ]

        async def stream(part: list[mavlink.MAVLink_message]) -> None:
            for msg in part:
                sender.send(msg)
                await asyncio.sleep(0.004)

        player = asyncio.create_task(stream(messages))
        await wait_for(lambda: home_requests(), 10)
        request = home_requests()[0]
        assert int(request.param1) == mavlink.MAVLINK_MSG_ID_HOME_POSITION
        assert (request.target_system, request.target_component) == (1, 1)
        assert service.out.latest is not None and service.out.latest.rth_flags & 1  # no home yet
        assert math.isnan(service.out.latest.rth_energy_wh)
        sender.send(
            sender.mav.home_position_encode(
                round(HOME[0] * 1e7), round(HOME[1] * 1e7), 488_000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0
            )
        )
        await wait_for(lambda: service.pipeline.returning.home is not None, 5)
        assert service.pipeline.returning.home.lat_deg == pytest.approx(HOME[0])
        moved = (HOME[0] + 0.01, HOME[1])
        sender.send(
            sender.mav.home_position_encode(
                round(moved[0] * 1e7),
                round(moved[1] * 1e7),
                488_000,
                0,
                0,
                0,
                [1, 0, 0, 0],
                0,
                0,
                0,
            )
        )
        await wait_for(
            lambda: service.pipeline.returning.home.lat_deg == pytest.approx(moved[0]), 5
        )
        sent = len(home_requests())
        await asyncio.sleep(1.5)
        assert len(home_requests()) == sent  # home known: no more requests
        player.cancel()
        server.task.cancel()
    assert service.home_request.sent == sent == 1


# -- margin warnings -----------------------------------------------------------------------------


def _estimate(margin_wh: float, **changes: object) -> Estimate:
    base = Estimate(
        time_s=0.0,
        speed_mps=0.0,
        accel_tangential_mps2=0.0,
        accel_centripetal_mps2=0.0,
        climb_mps=0.0,
        power_model_w=0.0,
        power_measured_w=None,
        energy_remaining_wh=50.0,
        energy_remaining_sigma_wh=1.0,
        endurance_s=0.0,
        endurance_sigma_s=0.0,
        hover_endurance_s=0.0,
        vme_endurance_s=0.0,
        v_me_mps=0.0,
        range_vmr_m=0.0,
        bias=1.0,
        bias_sigma=0.0,
        model_only=False,
        stale=False,
        margin_wh=margin_wh,
        rth_energy_wh=10.0,
    )
    return replace(base, **changes)  # type: ignore[arg-type]


def test_margin_warnings_are_sent_once_per_crossing_with_hysteresis() -> None:
    alerts = MarginAlerts(warning_wh=20.0, critical_wh=5.0, hysteresis_wh=2.0)
    margins = [30, 21, 19.5, 20.5, 19.0, 21.9, 19.0, 22.5, 19.9, 4.9, 6.0, 4.0, 8.0, 3.0, 30, 10]
    raised = [(m, alerts.update(_estimate(m))) for m in margins]
    got = [(m, a.severity) for m, a in raised if a is not None]
    assert got == [
        (19.5, mavlink.MAV_SEVERITY_WARNING),  # below 20
        (19.9, mavlink.MAV_SEVERITY_WARNING),  # after rising above 22 (hysteresis)
        (4.9, mavlink.MAV_SEVERITY_CRITICAL),
        (3.0, mavlink.MAV_SEVERITY_CRITICAL),  # after rising above 7
        (10, mavlink.MAV_SEVERITY_WARNING),  # all clear at 30, then below 20 again
    ]
    text = next(a for _, a in raised if a is not None).text
    assert len(text) <= 50 and "19.5" in text


def test_unknown_stale_or_grounded_margins_raise_nothing_and_keep_the_level() -> None:
    alerts = MarginAlerts(warning_wh=20.0, critical_wh=5.0, hysteresis_wh=2.0)
    assert alerts.update(_estimate(10.0)) is not None
    for quiet in (
        _estimate(math.nan),
        _estimate(1.0, stale=True),
        _estimate(1.0, endurance_valid=False),
        _estimate(30.0, stale=True),
    ):
        assert alerts.update(quiet) is None
    assert alerts.level == 1


# -- ground-station clients ------------------------------------------------------------------------


async def test_pymavlink_and_mavsdk_clients_get_the_return_values_and_the_warning(
    flight: Messages,
) -> None:
    """Home 2 km east of the flight: the return figures published as NAMED_VALUE_FLOAT equal
    the pipeline's replay of the same messages, and a margin below the warning threshold
    (here: any margin under 100 % of a full pack) reaches both clients as one STATUSTEXT
    WARNING from component 191 — on the --publish links only, never towards the autopilot."""
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
    from test_service import free_udp_port, listen, play, replay

    far_home = home(HOME[0], HOME[1] + 2000.0 / (M_PER_DEG * math.cos(math.radians(HOME[0]))))
    far_home.pack(_ENC)
    messages = [m for _, m in flight]
    messages.insert(20, far_home)
    expected = replay(messages)
    assert expected[-1].endurance_valid and expected[-1].rth_energy_wh > 0
    client, client_port, transport = await listen()
    sdk_port = free_udp_port()
    config = ServiceConfig(
        publish=(f"udpout:127.0.0.1:{client_port}", f"udpout:127.0.0.1:{sdk_port}"),
        publish_rate_hz=0.0,
        stale_after_s=30.0,
        warning_margin_pct=100.0,
        critical_margin_pct=0.0,
        download_mission=False,
    )
    sdk_config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(sdk_config) as sdk, running(config) as (service, sender):
        to_autopilot = MissionServer(sender, items=0, silent=True)  # records what it is sent
        await sdk.add_any_connection(f"udpin://127.0.0.1:{sdk_port}")
        await play(sender, messages[:20])
        system = await first_mavsdk_system(sdk)
        direct = MavlinkDirectAsync(system)
        sdk_seen: dict[str, list[dict]] = {"NAMED_VALUE_FLOAT": [], "STATUSTEXT": []}

        async def collect(kind: str) -> None:
            import json

            async for msg in direct.subscribe_message(kind):
                sdk_seen[kind].append(json.loads(msg.fields_json) | {"comp": msg.component_id})

        tasks = [asyncio.create_task(collect(kind)) for kind in sdk_seen]
        await asyncio.sleep(0.5)
        await play(sender, messages[20:])
        await wait_for(lambda: service.pipeline.counts["estimates"] == len(expected))
        await wait_for(lambda: sdk_seen["STATUSTEXT"] and len(client.of_type("STATUSTEXT")))
        await asyncio.sleep(0.3)
        for task in tasks:
            task.cancel()
        to_autopilot.task.cancel()
    transport.close()

    by_ms = {round(e.time_s * 1000): e for e in expected}
    last_ms = max(client.named("RTH_WH"))
    last = by_ms[last_ms]
    assert last.home_distance_m == pytest.approx(2000.0, rel=0.05)
    for name, value in (
        ("HOME_M", last.home_distance_m),
        ("RTH_WH", last.rth_energy_wh),
        ("RTH_SIG", last.rth_sigma_wh),
        ("RTH_VG", last.rth_speed_mps),
        ("MARGIN_WH", last.margin_wh),
        ("PNR_S", last.pnr_s),
        ("RTH_FLAGS", float(last.rth_flags)),
    ):
        assert client.named(name)[last_ms] == pytest.approx(value, rel=1e-6), name
    assert last.rth_flags == 4  # no mission (download off); home, position, flying
    texts = client.of_type("STATUSTEXT")
    assert len(texts) == 1 and texts[0].severity == mavlink.MAV_SEVERITY_WARNING
    assert texts[0].get_srcComponent() == 191 and texts[0].text.startswith("RTH warning")
    sdk_texts = sdk_seen["STATUSTEXT"]
    assert len(sdk_texts) == 1 and sdk_texts[0]["comp"] == 191
    assert sdk_texts[0]["severity"] == mavlink.MAV_SEVERITY_WARNING
    sdk_rth = [m for m in sdk_seen["NAMED_VALUE_FLOAT"] if m["name"] == "RTH_WH"]
    assert sdk_rth and sdk_rth[-1]["value"] == pytest.approx(
        by_ms[sdk_rth[-1]["time_boot_ms"]].rth_energy_wh, rel=1e-6
    )
    assert not to_autopilot.kinds("STATUSTEXT")
    assert not to_autopilot.kinds("NAMED_VALUE_FLOAT")


async def test_the_simulator_answers_a_home_request_and_logs_the_home_in_its_tlog() -> None:
    """``uav-energy sim`` (SimPlayer) answers MAV_CMD_REQUEST_MESSAGE(HOME_POSITION) with its
    take-off point and writes that HOME_POSITION into its tlog, so a replay of the tlog sees
    the home the daemon saw."""
    import io

    from test_service import free_udp_port

    from estimator.mavlink.link import open_link
    from estimator.sim.link import SimPlayer
    from estimator.telemetry.frames import FrameParser

    run = simulate(SimConfig(plan="hover-cruise", duration_s=20.0, seed=3))
    port = free_udp_port()
    gcs = await open_link(f"udpin:127.0.0.1:{port}", source_system=1)
    autopilot = await open_link(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    tlog = io.BytesIO()
    player = SimPlayer(run, autopilot, speedup=10.0, tlog=tlog)
    playing = asyncio.create_task(player.play())
    got: list[mavlink.MAVLink_message] = []
    async with asyncio.timeout(10):
        while not any(m.get_type() == "HEARTBEAT" for m in got):
            got += await gcs.recv()
        gcs.send(
            gcs.mav.command_long_encode(
                1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                mavlink.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0,
            )
        )  # fmt: skip
        while not any(m.get_type() == "HOME_POSITION" for m in got):
            got += await gcs.recv()
    playing.cancel()
    await gcs.close()
    await autopilot.close()
    home_msg = next(m for m in got if m.get_type() == "HOME_POSITION")
    config = run.config
    assert home_msg.latitude == round(config.home_lat_deg * 1e7)
    assert home_msg.altitude == round(config.home_msl_m * 1000)
    logged = FrameParser().feed(tlog.getvalue())
    assert any(m.get_type() == "HOME_POSITION" for m in logged)
    assert player.counts["home_requests"] == 1
