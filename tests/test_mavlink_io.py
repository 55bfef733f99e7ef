"""asyncio MAVLink transport: real sockets on 127.0.0.1 and a pseudo-terminal for serial."""

from __future__ import annotations

import asyncio
import os
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import Unavailable, UserError
from estimator.mavlink.link import MavlinkLink, open_link, parse_url


def heartbeat(link: MavlinkLink) -> mavlink.MAVLink_message:
    return link.mav.heartbeat_encode(
        mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4
    )


async def recv_n(link: MavlinkLink, n: int, timeout_s: float = 5.0) -> list:
    out: list = []
    async with asyncio.timeout(timeout_s):
        while len(out) < n:
            out.extend(await link.recv())
    return out


def test_parse_url_accepts_ardupilot_forms() -> None:
    assert parse_url("udpin:0.0.0.0:14550").kind == "udpin"
    assert parse_url("udpout:127.0.0.1:14550").port == 14550
    assert parse_url("tcp:127.0.0.1:5760").host == "127.0.0.1"
    assert parse_url("/dev/ttyACM0").baud == 115200
    serial = parse_url("/dev/ttyAMA0:921600")
    assert (serial.kind, serial.device, serial.baud) == ("serial", "/dev/ttyAMA0", 921600)


@pytest.mark.parametrize(
    "url", ["udp:1.2.3.4", "udpin:127.0.0.1", "tcp:host:notaport", "ttyUSB0", "/dev/tty:123"]
)
def test_parse_url_rejects_malformed_strings_with_user_error(url: str) -> None:
    with pytest.raises(UserError):
        parse_url(url)


async def test_udpin_receives_from_udpout_and_replies_to_the_peer() -> None:
    server = await open_link("udpin:127.0.0.1:0", source_system=1, source_component=191)
    assert server.local_address is not None
    port = server.local_address[1]
    client = await open_link(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    try:
        client.send(heartbeat(client))
        (msg,) = await recv_n(server, 1)
        assert msg.get_type() == "HEARTBEAT"
        assert (msg.get_srcSystem(), msg.get_srcComponent()) == (1, 1)
        server.send(server.mav.named_value_float_encode(1, b"ENERGY_WH", 42.5))
        (reply,) = await recv_n(client, 1)
        assert reply.get_srcComponent() == 191
        assert reply.value == pytest.approx(42.5)
    finally:
        await client.close()
        await server.close()


async def test_udp_garbage_is_counted_and_does_not_swallow_the_next_datagram() -> None:
    server = await open_link("udpin:127.0.0.1:0")
    assert server.local_address is not None
    client = await open_link(f"udpout:127.0.0.1:{server.local_address[1]}", source_component=1)
    try:
        good = heartbeat(client).pack(client.mav)
        client.send_bytes(b"\xfd\x09" + b"garbage")  # a truncated MAVLink 2 frame
        client.send_bytes(good[:-1] + bytes([good[-1] ^ 0xFF]))  # bad CRC
        client.send_bytes(bytes(b for b in range(256) if b not in (0xFD, 0xFE)))
        client.send(heartbeat(client))
        (msg,) = await recv_n(server, 1)
        assert msg.get_type() == "HEARTBEAT"
        assert server.bad_frames >= 1
    finally:
        await client.close()
        await server.close()


async def test_flood_beyond_max_pending_drops_oldest_and_counts() -> None:
    server = await open_link("udpin:127.0.0.1:0", max_pending=50)
    assert server.local_address is not None
    client = await open_link(f"udpout:127.0.0.1:{server.local_address[1]}", source_component=1)
    try:
        for i in range(200):
            client.send(client.mav.named_value_float_encode(i, b"X", float(i)))
        await asyncio.sleep(0.3)
        got = await server.recv()
        assert len(got) == 50
        assert got[-1].time_boot_ms == 199
        assert server.counts["dropped"] == 150
    finally:
        await client.close()
        await server.close()


async def send_until_received(sender: MavlinkLink, receiver: MavlinkLink) -> None:
    """Send heartbeats every 50 ms until the receiver has one (connection set-up is async)."""
    async with asyncio.timeout(8):
        while True:
            sender.send(heartbeat(sender))
            try:
                async with asyncio.timeout(0.05):
                    if await receiver.recv():
                        return
            except TimeoutError:
                continue


async def test_tcp_client_reconnects_after_the_server_restarts() -> None:
    server = await open_link("tcpin:127.0.0.1:0", source_component=1)
    assert server.local_address is not None
    port = server.local_address[1]
    client = await open_link(f"tcp:127.0.0.1:{port}")
    try:
        await send_until_received(server, client)
        await server.close()
        server = await open_link(f"tcpin:127.0.0.1:{port}", source_component=1)
        await send_until_received(server, client)
        assert client.counts["reconnects"] == 1
    finally:
        await client.close()
        await server.close()


async def test_serial_link_over_a_pseudo_terminal() -> None:
    controller, worker = os.openpty()
    path = os.ttyname(worker)
    link = await open_link(f"{path}:57600", source_component=191)
    try:
        encoder = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        frame = heartbeat(link).pack(encoder)
        os.write(controller, b"\x00junk" + frame)
        msgs = await recv_n(link, 1)
        assert msgs[0].get_srcComponent() == 1
        link.send(link.mav.named_value_float_encode(5, b"BIAS", 1.25))
        await asyncio.sleep(0.05)
        echoed = mavlink.MAVLink(None)
        parsed = echoed.parse_buffer(os.read(controller, 1024))
        assert parsed and parsed[0].value == pytest.approx(1.25)
    finally:
        await link.close()
        os.close(controller)
        os.close(worker)


async def test_opening_a_missing_serial_device_is_unavailable_not_a_user_error(
    tmp_path: Path,
) -> None:
    """A missing USB device may come back (exit 75, systemd restarts); a missing on-board
    port, or one that is not a serial port: a mistake."""
    with pytest.raises(Unavailable, match="cannot open"):
        await open_link("/dev/serial/by-id/usb-does-not-exist-uav:115200")
    with pytest.raises(UserError, match="serial device /dev/does-not-exist-uav does not exist"):
        await open_link("/dev/does-not-exist-uav:115200")
    (tmp_path / "plain").write_text("")
    with pytest.raises(UserError, match="not a serial port"):
        await open_link(f"{tmp_path / 'plain'}:115200")


async def test_serial_device_that_disappears_is_reopened(tmp_path: Path) -> None:
    """A USB autopilot reboots: the device hangs up, then comes back (here: a symlink moved
    to a new pseudo-terminal)."""
    device = tmp_path / "ttyAP"
    first_controller, first_worker = os.openpty()
    device.symlink_to(os.ttyname(first_worker))
    link = await open_link(f"{device}:115200")
    encoder = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    try:
        os.write(first_controller, heartbeat(link).pack(encoder))
        assert (await recv_n(link, 1))[0].get_type() == "HEARTBEAT"
        os.close(first_controller)  # the device hangs up
        os.close(first_worker)
        async with asyncio.timeout(5):
            while link.counts["socket_errors"] == 0:
                await asyncio.sleep(0.02)
        controller, worker = os.openpty()
        device.unlink()
        device.symlink_to(os.ttyname(worker))
        async with asyncio.timeout(5):
            while link.counts["reconnects"] == 0:
                await asyncio.sleep(0.05)
        os.write(controller, heartbeat(link).pack(encoder))
        assert (await recv_n(link, 1))[0].get_srcComponent() == 1
        os.close(controller)
        os.close(worker)
    finally:
        await link.close()


async def test_listener_receives_messages_as_they_arrive_instead_of_the_queue() -> None:
    server = await open_link("udpin:127.0.0.1:0")
    assert server.local_address is not None
    client = await open_link(f"udpout:127.0.0.1:{server.local_address[1]}", source_component=1)
    got: list = []
    server.set_listener(got.extend)
    try:
        client.send(heartbeat(client))
        async with asyncio.timeout(5):
            while not got:
                await asyncio.sleep(0.01)
        assert got[0].get_type() == "HEARTBEAT"
        server.set_listener(None)
        client.send(heartbeat(client))
        assert (await recv_n(server, 1))[0].get_type() == "HEARTBEAT"
        assert len(got) == 1
    finally:
        await client.close()
        await server.close()
