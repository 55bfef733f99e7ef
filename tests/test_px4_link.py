"""PX4 on the daemon's link, on loopback with real sockets: its "not measured" battery current,
message rates asked for the PX4 way, and a pack the vehicle file does not describe.

The simulated flight of tests/test_service.py plays the autopilot; its HEARTBEATs say
MAV_AUTOPILOT_PX4 and its battery messages carry PX4's sentinels where a case needs them.
The live PX4 flights are in tests/test_px4_sitl.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import copy
import logging
import re
from dataclasses import replace

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import Messages, listen, play, running, wait_for

from estimator.estimation.airborne import AirborneGate, Phase
from estimator.estimation.rtl_profiles import px4_rtl
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.streams import PX4_MESSAGES
from estimator.physics.vehicle import default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import BatterySample, LandedSample

#: PX4's battery current of a pack without a current sensor (cA): −1 A.
PX4_NO_CURRENT_CA = -100


@pytest.fixture(scope="module")
def flight() -> Messages:
    return simulate(SimConfig(plan="hover-cruise", duration_s=40.0, seed=3)).messages


def as_px4(messages: Messages, current_ca: int | None = None) -> list[mavlink.MAVLink_message]:
    """The flight with PX4's HEARTBEATs; with ``current_ca``, every battery current replaced
    by it and the charge counted as PX4 counts it from such a current (0 mAh). Copies: the
    flight's messages stay as they are."""
    out = []
    for _, original in messages:
        msg, kind = copy.copy(original), original.get_type()
        if kind == "HEARTBEAT":
            msg.autopilot = mavlink.MAV_AUTOPILOT_PX4
        elif current_ca is not None and kind in ("BATTERY_STATUS", "SYS_STATUS"):
            msg.current_battery = current_ca
            if kind == "BATTERY_STATUS":
                msg.current_consumed = 0
        out.append(msg)
    return out


def test_px4_unknown_current_is_not_measured(flight: Messages) -> None:
    """PX4's −1 A (−100 cA) in BATTERY_STATUS and SYS_STATUS is no current, and the 0 mAh
    counted from it no charge: the samples carry None, not −1 A."""
    decoder = TelemetryDecoder(limits=default_vehicle().input_limits())
    samples = decoder.decode_all(as_px4(flight, PX4_NO_CURRENT_CA))
    batteries = [s for s in samples if isinstance(s, BatterySample)]
    assert len(batteries) > 50
    assert all(s.current_a is None and s.consumed_mah is None for s in batteries)
    measured = TelemetryDecoder(limits=default_vehicle().input_limits())
    real = [s for s in measured.decode_all(as_px4(flight)) if isinstance(s, BatterySample)]
    assert all(s.current_a is not None for s in real)
    assert any(s.consumed_mah is not None for s in real)


def _battery_ids(
    messages: list[mavlink.MAVLink_message], ids: tuple[int, ...]
) -> list[mavlink.MAVLink_message]:
    """``messages`` with each BATTERY_STATUS sent once per id of ``ids`` (copies)."""
    out = []
    for msg in messages:
        if msg.get_type() != "BATTERY_STATUS":
            out.append(msg)
            continue
        for battery_id in ids:
            twin = copy.copy(msg)
            twin.id = battery_id
            out.append(twin)
    return out


def test_the_only_battery_of_another_id_is_taken_but_not_a_second_one(flight: Messages) -> None:
    """PX4 republishes a battery fed to it over MAVLink as id 255: an autopilot's only
    battery is the one decoded, whatever its id, with its charge counter (SYS_STATUS has
    none); beside a battery 0 another id stays another battery."""
    px4 = as_px4(flight)
    decoder = TelemetryDecoder(limits=default_vehicle().input_limits())
    samples = decoder.decode_all(_battery_ids(px4, (255,)))
    assert decoder.battery_id == 255 and decoder.counts["battery_id_adopted"] == 1
    assert any(isinstance(s, BatterySample) and s.consumed_mah is not None for s in samples)
    both = TelemetryDecoder(limits=default_vehicle().input_limits())
    both.decode_all(_battery_ids(px4, (0, 1)))
    assert both.battery_id == 0 and both.counts["battery_id_adopted"] == 0
    assert both.counts["other_battery"] > 50


async def test_daemon_asks_px4_for_message_intervals_only(flight: Messages) -> None:
    """To PX4: SET_MESSAGE_INTERVAL for the messages it uses (and reads), never
    REQUEST_DATA_STREAM; estimates flow model-only on PX4's unknown current; the return
    figures follow PX4's RTL (its HEARTBEAT says PX4)."""
    messages = as_px4(flight, PX4_NO_CURRENT_CA)
    async with running(ServiceConfig()) as (service, sender):
        received: list[mavlink.MAVLink_message] = []
        async with asyncio.timeout(15):
            while service.out.latest is None:
                await play(sender, messages[:200])
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(0.2):
                        received.extend(await sender.recv())
            await play(sender, messages[200:])
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(0.5):
                while True:
                    received.extend(await sender.recv())
        assert service.out.latest is not None and service.out.latest.model_only
        assert service.out.latest.power_measured_w is None
        given = ServiceConfig().pipeline_settings().return_home
        assert service.pipeline.returning.settings == px4_rtl(given)
    kinds = {m.get_type() for m in received}
    assert "REQUEST_DATA_STREAM" not in kinds
    commands = [m for m in received if m.get_type() == "COMMAND_LONG"]
    intervals = [m for m in commands if m.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL]
    assert {int(m.param1) for m in intervals} == {msg_id for msg_id, _ in PX4_MESSAGES}
    battery = [m for m in intervals if int(m.param1) == mavlink.MAVLINK_MSG_ID_BATTERY_STATUS]
    assert battery[0].param2 == pytest.approx(1e6 / ServiceConfig().battery_rate_hz)
    reads = {mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL}
    assert {m.command for m in commands} <= reads


async def test_a_pack_of_one_other_cell_count_is_taken_in_one_line(
    flight: Messages, caplog: pytest.LogCaptureFixture
) -> None:
    """A 6S pack on a 3S vehicle file: 25.2 V is a LiPo pack above its reserve at 6 cells and
    at no other count, so the daemon says so in one warning line and a STATUSTEXT, and
    estimates with 6 cells."""
    caplog.set_level(logging.INFO, logger="uav_energy.service")
    base = default_vehicle()
    vehicle = replace(base, battery=replace(base.battery, cells=3))
    client, port, transport = await listen()
    config = ServiceConfig(publish=(f"udpout:127.0.0.1:{port}",))
    try:
        async with running(config, vehicle) as (service, sender):
            await play(sender, as_px4(flight)[:1500])
            await wait_for(lambda: service.out.latest is not None, timeout_s=5.0)
            await wait_for(lambda: client.of_type("STATUSTEXT"), timeout_s=5.0)
            assert service.pipeline.vehicle.battery.cells == base.battery.cells == 6
            assert service.decoder.counts["voltage_implausible"] == 1  # the first, only
    finally:
        transport.close()
    lines = [r.getMessage() for r in caplog.records if " pack above its reserve" in r.getMessage()]
    assert len(lines) == 1, lines
    assert re.match(r"(BATTERY_STATUS|SYS_STATUS) 2\d\.\d\d V is a 6S pack above its "
                    r"reserve, not the vehicle file's 3S", lines[0]), lines[0]  # fmt: skip
    assert not [r for r in caplog.records if " fits " in r.getMessage()]
    texts = {m.text for m in client.of_type("STATUSTEXT")}
    assert any("is 6S, not 3S: using 6S" in t for t in texts), texts


async def test_a_pack_of_several_possible_cell_counts_is_named_and_not_used(
    flight: Messages, caplog: pytest.LogCaptureFixture
) -> None:
    """The same pack on a 3S Li-ion vehicle file (a deeper usable range: 25.2 V is a Li-ion
    pack above its reserve at 6 or 7 cells): no count is taken, no reading is believed, one
    log line says which cell counts the voltage fits and what the file says, and a
    STATUSTEXT says so to the ground."""
    caplog.set_level(logging.INFO, logger="uav_energy.service")
    base = default_vehicle()
    liion = replace(base.battery, cells=3, chemistry="liion", cell_ocv_v=None)
    vehicle = replace(base, battery=liion)
    client, port, transport = await listen()
    config = ServiceConfig(publish=(f"udpout:127.0.0.1:{port}",))
    try:
        async with running(config, vehicle) as (service, sender):
            await play(sender, as_px4(flight)[:1500])
            await wait_for(lambda: "fits" in caplog.text, timeout_s=5.0)
            await play(sender, as_px4(flight)[1500:])
            await wait_for(lambda: client.of_type("STATUSTEXT"), timeout_s=5.0)
            assert service.out.latest is None
            assert service.pipeline.vehicle.battery.cells == 3
            assert service.decoder.counts["voltage_implausible"] > 10
    finally:
        transport.close()
    lines = [r.getMessage() for r in caplog.records if " fits " in r.getMessage()]
    assert len(lines) == 1, lines
    assert re.match(r"(BATTERY_STATUS|SYS_STATUS) 2\d\.\d\d V fits 6, 7 or 8 cells, "
                    r"the vehicle file says 3 ", lines[0]), lines[0]  # fmt: skip
    texts = {m.text for m in client.of_type("STATUSTEXT")}
    assert any("is not 3S" in t for t in texts), texts


def landed_state(state: int) -> mavlink.MAVLink_message:
    """PX4's EXTENDED_SYS_STATE (system 1, component 1) with ``state`` (MAV_LANDED_STATE)."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frame = codec.extended_sys_state_encode(mavlink.MAV_VTOL_STATE_UNDEFINED, state).pack(codec)
    return FrameParser().feed(frame)[0]


def test_px4_landed_state_becomes_a_sample_at_each_change(flight: Messages) -> None:
    """EXTENDED_SYS_STATE at PX4's 5 Hz: one LandedSample per change of its landed state, on
    the autopilot's clock; UNDEFINED says nothing."""
    states = [mavlink.MAV_LANDED_STATE_UNDEFINED, mavlink.MAV_LANDED_STATE_ON_GROUND]
    states += [mavlink.MAV_LANDED_STATE_TAKEOFF, mavlink.MAV_LANDED_STATE_IN_AIR]
    states += [mavlink.MAV_LANDED_STATE_LANDING, mavlink.MAV_LANDED_STATE_ON_GROUND]
    messages = as_px4(flight)
    mixed: list[mavlink.MAVLink_message] = []
    per_state = len(messages) // len(states)
    for i, msg in enumerate(messages):
        mixed.append(msg)
        if i % 20 == 19:
            mixed.append(landed_state(states[min(i // per_state, len(states) - 1)]))
    decoder = TelemetryDecoder(limits=default_vehicle().input_limits())
    samples = decoder.decode_all(mixed)
    landed = [s for s in samples if isinstance(s, LandedSample)]
    assert [s.on_ground for s in landed] == [True, False, True]
    times = [s.time_s for s in landed]
    assert times == sorted(times) and 0.0 < times[0] < times[-1] <= flight[-1][0] + 1.0


def test_the_landed_detector_replaces_the_height_test() -> None:
    """A reading at 0.5 m with PX4 in the air is a take-off; at 3 m (a barometer's drift) with
    PX4 on the ground it is ground; without a landed state the height decides."""
    gate = AirborneGate(hover_power_w=100.0)
    assert gate.phase(10.0, True, 0.5, 150.0, 0.0, on_ground=False) is Phase.TAKEOFF
    assert gate.phase(10.5, True, 3.0, 150.0, 0.0, on_ground=True) is Phase.GROUND
    assert gate.phase(11.0, True, 0.5, 150.0, 0.0) is Phase.GROUND
    assert gate.phase(11.5, True, 3.0, 150.0, 0.0) is Phase.TAKEOFF
