"""Connection strings as pymavlink's ``mavlink_connection`` and MAVProxy users write them."""

from __future__ import annotations

import asyncio
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import EXIT_UNAVAILABLE
from estimator.mavlink.link import LinkAddress, MavlinkLink, open_link, parse_url

EXE = Path(sys.executable).with_name("uav-energy")


@pytest.mark.parametrize(
    ("url", "listen", "address"),
    [
        ("udp:0.0.0.0:14551", True, LinkAddress("udpin", host="0.0.0.0", port=14551)),
        ("udp:127.0.0.1:14550", True, LinkAddress("udpin", host="127.0.0.1", port=14550)),
        ("udp:192.168.1.10:14550", False, LinkAddress("udpout", host="192.168.1.10", port=14550)),
        ("udpin:0.0.0.0:14550", False, LinkAddress("udpin", host="0.0.0.0", port=14550)),
        ("tcpin:0.0.0.0:5760", True, LinkAddress("tcpin", host="0.0.0.0", port=5760)),
        ("/dev/ttyAMA0,921600", True, LinkAddress("serial", device="/dev/ttyAMA0", baud=921600)),
        ("/dev/ttyAMA0:921600", True, LinkAddress("serial", device="/dev/ttyAMA0", baud=921600)),
        ("serial:/dev/ttyS1,57600", True, LinkAddress("serial", device="/dev/ttyS1", baud=57600)),
        ("/dev/ttyACM0", True, LinkAddress("serial", device="/dev/ttyACM0", baud=115200)),
    ],
)
def test_each_form_is_read_as_mavutil_reads_it(
    url: str, listen: bool, address: LinkAddress
) -> None:
    assert parse_url(url, listen) == address


async def test_udp_alias_listens_on_the_autopilot_link_and_sends_on_a_published_one() -> None:
    server = await open_link("udp:127.0.0.1:0", source_system=1, source_component=191)
    assert server.local_address is not None
    port = server.local_address[1]
    client: MavlinkLink = await open_link(f"udp:127.0.0.1:{port}", listen=False)
    try:
        client.send(
            client.mav.heartbeat_encode(
                mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4
            )
        )
        received = []
        async with asyncio.timeout(5):
            while not received:
                received = await server.recv()
        assert received[0].get_type() == "HEARTBEAT"
    finally:
        await client.close()
        await server.close()


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(EXE), "run", *args], capture_output=True, text=True, timeout=60, check=False
    )


def test_a_missing_on_board_serial_port_is_a_mistake_exit_2_in_one_sentence(
    tmp_path: Path,
) -> None:
    """MAVProxy's ``DEV,BAUD`` form: the device is DEV; missing at start, the name is wrong
    (no restart loop), unlike a USB device not plugged in yet."""
    device = tmp_path / "ttyAMA0"
    missing = _run("--connect", f"{device},921600")
    assert missing.returncode == 2, missing.stderr
    assert missing.stderr.strip().splitlines() == [
        f"uav-energy run: error: serial device {device} does not exist"
    ]
    usb = _run("--connect", f"{tmp_path / 'ttyUSB3'},921600")
    assert usb.returncode == EXIT_UNAVAILABLE, usb.stderr
