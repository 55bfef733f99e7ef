"""Links that can be trusted, over real UDP sockets: MAVLink 2 signing with pymavlink on the
other end, the autopilot lock, and a ``udpin`` link that answers only the autopilot."""

from __future__ import annotations

import asyncio
import copy
import hashlib
import logging
from dataclasses import replace
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import (
    Messages,
    flight,  # noqa: F401 (fixture)
    listen,
    play,
    replay,
    running,
    wait_for,
)

from estimator.cli import main as cli_main
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.signing import load_key, signing_timestamp
from estimator.telemetry.decode import USED_MESSAGE_IDS

KEY = bytes(range(32))


def key_file(tmp_path: Path, key: bytes = KEY, mode: int = 0o600) -> Path:
    path = tmp_path / "mavlink.key"
    path.write_bytes(key)
    path.chmod(mode)
    return path


class Autopilot(asyncio.DatagramProtocol):
    """An autopilot on a plain UDP socket with pymavlink's codec, signing like
    ``mavutil.mavfile.setup_signing`` (secret key, link id, timestamp since 2015 in 10 µs)
    when given a key; what it receives is parsed with the same codec (signatures checked)."""

    def __init__(self, system: int = 1, key: bytes | None = None, link_id: int = 0) -> None:
        self.codec = mavlink.MAVLink(None, srcSystem=system, srcComponent=1)
        self.codec.robust_parsing = True
        if key is not None:
            signing = self.codec.signing
            signing.secret_key, signing.sign_outgoing, signing.link_id = key, True, link_id
            signing.timestamp = signing_timestamp()
        self.received: list[mavlink.MAVLink_message] = []
        self.datagrams = 0
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.DatagramTransport)
        self.transport = transport

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.datagrams += 1
        self.received += [
            m
            for m in self.codec.parse_buffer(data) or []
            if not isinstance(m, mavlink.MAVLink_bad_data)
        ]

    def pack(self, msg: mavlink.MAVLink_message) -> bytes:
        """Encode with our ids and signing (a copy: packing rewrites a message's header)."""
        return copy.copy(msg).pack(self.codec)

    def send_raw(self, data: bytes) -> None:
        assert self.transport is not None
        self.transport.sendto(data)

    async def play(self, messages: list[mavlink.MAVLink_message]) -> list[bytes]:
        sent = []
        for i, msg in enumerate(messages):
            sent.append(self.pack(msg))
            self.send_raw(sent[-1])
            if i % 5 == 4:
                await asyncio.sleep(0.004)
        return sent


async def autopilot_to(
    port: int, system: int = 1, key: bytes | None = None, link_id: int = 0
) -> Autopilot:
    loop = asyncio.get_running_loop()
    transport, protocol = await loop.create_datagram_endpoint(
        lambda: Autopilot(system, key, link_id), remote_addr=("127.0.0.1", port)
    )
    protocol.transport = transport
    return protocol


def daemon_port(service) -> int:  # type: ignore[no-untyped-def]
    return int(service.link.local_address[1])


# -- signing ------------------------------------------------------------------------------------


async def test_signed_link_rejects_wrong_key_unsigned_and_replayed_frames(
    flight: Messages,  # noqa: F811
    tmp_path: Path,
) -> None:
    """pymavlink signs the autopilot's frames with the key; the daemon (key file, signing
    required) estimates from them, counts and ignores frames signed with another key, unsigned
    ones and replayed ones (a forged frame with a far-future timestamp does not lock the
    real stream out), and what it sends verifies with the key on the receiving side."""
    messages = [m for _, m in flight]
    gcs, gcs_port, gcs_transport = await listen()
    gcs.codec.signing.secret_key = KEY  # verify the daemon's outputs; unsigned would fail
    config = ServiceConfig(
        signing_key_file=str(key_file(tmp_path)),
        require_signing=True,
        publish=(f"udpout:127.0.0.1:{gcs_port}",),
        stale_after_s=30.0,
    )
    async with running(config) as (service, _sender):
        port = daemon_port(service)
        autopilot = await autopilot_to(port, key=KEY)
        first = await autopilot.play(messages[:300])
        await wait_for(lambda: service.out.latest is not None)
        await asyncio.sleep(0.3)
        velocity = service.pipeline.counts["velocity"]
        signing = service.link.signing  # type: ignore[union-attr]
        assert signing is not None and not signing.rejected

        # frames of ids the daemon does not use are dropped by their header, unchecked
        extra = [m for m in messages[300:] if m.get_msgId() in USED_MESSAGE_IDS][:50]
        wrong = await autopilot_to(port, key=bytes(32 * [7]))
        await wrong.play(extra)
        unsigned = await autopilot_to(port)
        await unsigned.play(extra)
        used = [f for f in first if (f[7] | f[8] << 8 | f[9] << 16) in USED_MESSAGE_IDS]
        for data in used[-50:]:  # replayed: genuine frames, sent again
            autopilot.send_raw(data)
        forged = bytearray(used[-1])  # a far-future timestamp with a signature not ours
        forged[-12:-6] = (2**48 - 1).to_bytes(6, "little")
        autopilot.send_raw(bytes(forged))
        await wait_for(lambda: sum(signing.rejected.values()) >= 151)
        assert dict(signing.rejected) == {"bad_signature": 51, "unsigned": 50, "replayed": 50}
        assert service.pipeline.counts["velocity"] == velocity  # none of them was used

        await autopilot.play(messages[300:])  # the real stream goes on
        expected = replay(messages)[-1]
        await wait_for(lambda: service.out.latest == expected)
        await asyncio.sleep(1.2)  # a HEARTBEAT and a publish period
        assert service.link.counts["bad_frames"] == 0  # type: ignore[union-attr]
        assert service.counters()["signing_bad_signature"] == 51
    gcs_transport.close()
    # what the daemon sent verifies with the key, on both links
    assert gcs.codec.signing.goodsig_count > 0 and gcs.codec.signing.badsig_count == 0
    assert {"HEARTBEAT", "NAMED_VALUE_FLOAT", "BATTERY_STATUS"} <= {
        m.get_type() for m in gcs.messages
    }
    requests = [m for m in autopilot.received if m.get_type() == "REQUEST_DATA_STREAM"]
    assert requests and autopilot.codec.signing.goodsig_count == len(autopilot.received)
    assert autopilot.codec.signing.badsig_count == 0
    stamps = [int.from_bytes(m.get_msgbuf()[-12:-6], "little") for m in autopilot.received]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    assert abs(stamps[0] - signing_timestamp()) < 60 * 100_000  # 10 µs since 2015, not 0


async def test_without_require_signing_unsigned_frames_are_accepted(
    flight: Messages,  # noqa: F811
    tmp_path: Path,
) -> None:
    config = ServiceConfig(signing_key_file=str(key_file(tmp_path)), stale_after_s=30.0)
    async with running(config) as (service, sender):  # the sender does not sign
        await play(sender, [m for _, m in flight[:400]])
        await wait_for(lambda: service.out.latest is not None)
        signing = service.link.signing  # type: ignore[union-attr]
        used = sum(m.get_msgId() in USED_MESSAGE_IDS for _, m in flight[:400])
        assert signing is not None and signing.unsigned_count >= used
        wrong = await autopilot_to(daemon_port(service), key=bytes(32 * [7]))
        wrong_frames = [m for _, m in flight[400:] if m.get_msgId() in USED_MESSAGE_IDS][:20]
        await wrong.play(wrong_frames)
        await wait_for(lambda: signing.rejected["bad_signature"] == 20)


def test_key_file_readable_by_others_is_refused_like_ssh(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = key_file(tmp_path, mode=0o644)
    code = cli_main(["run", "--connect", "udpin:127.0.0.1:0", "--config", str(_conf(tmp_path))])
    assert code == 2
    err = capsys.readouterr().err
    assert "accessible by group or others (mode 0644): run chmod 600" in err
    assert len(err.strip().splitlines()) == 1
    path.chmod(0o600)
    assert load_key(path) == KEY
    path.write_text((KEY.hex() + "\n").upper())
    assert load_key(path) == KEY
    path.write_text("correct horse battery staple\n")  # a passphrase: its SHA-256
    assert load_key(path) == hashlib.sha256(b"correct horse battery staple").digest()


def _conf(tmp_path: Path) -> Path:
    conf = tmp_path / "conf" / "config.toml"
    conf.parent.mkdir(exist_ok=True)
    conf.write_text('[signing]\nkey_file = "../mavlink.key"\nrequire_signing = true\n')
    return conf


# -- autopilot lock -----------------------------------------------------------------------------


async def test_autopilot_is_locked_after_its_telemetry_confirms_it_not_first_speaker(
    flight: Messages,  # noqa: F811
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A forger's autopilot HEARTBEAT comes first but no telemetry: it is no candidate; the
    real autopilot (second to speak) is locked, its held frames decoded, so the estimates
    equal a replay; the forger, now a second autopilot sending telemetry, is logged once and
    ignored; the locked autopilot rebooting (its old clock stopped) is believed and keeps the
    lock."""
    caplog.set_level(logging.INFO)
    messages = [m for _, m in flight]
    expected = replay(messages)[-1]  # nothing lost, nothing of the forger's
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        forger = await autopilot_to(daemon_port(service), system=7)
        forger.send_raw(forger.pack(messages[0]))  # HEARTBEAT of a quadrotor, nothing more
        await play(sender, messages[:200])
        await wait_for(lambda: service.lock.locked == (1, 1))
        for _ in range(3):  # the forger now plays a whole flight
            await forger.play(messages[:200])
        await play(sender, messages[200:])
        await wait_for(lambda: service.out.latest == expected)
        assert service.lock.counts["candidates"] >= 1
        used = sum(m.get_msgId() in USED_MESSAGE_IDS for m in messages[:200])
        assert service.lock.counts["other_autopilot_frames"] >= 3 * used
        assert service.decoder.counts["other_source"] >= 3 * used
        # the autopilot reboots: its new clock runs alone, and is believed
        await play(sender, messages[: len(messages) // 3])
        await wait_for(lambda: service.decoder.counts["reboots"] == 1)
        assert service.lock.locked == (1, 1) and service.lock.counts["off_clock_frames"] == 0
    log = caplog.text
    assert "autopilot found: system 1 component 1, locked" in log
    assert log.count("other autopilots ignored") == 1
    assert "latest from system 7 component 1 (listening to system 1 component 1)" in log


async def test_a_reboot_is_believed_when_the_old_clock_stops_and_no_heartbeat_releases_it(
    flight: Messages,  # noqa: F811
) -> None:
    """Five frames of an earlier clock and then silence: after REBOOT_CONFIRM_WALL_S of the
    new clock alone, a reboot. A HEARTBEAT of another vehicle type with the autopilot's ids
    while its clock runs is dropped: the lock stays."""
    messages = [m for _, m in flight[:300]]
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: service.lock.locked == (1, 1))
        for j in range(5):  # five frames of an earlier clock, and then silence
            sender.send(sender.mav.attitude_encode(1_000 + 100 * j, 0, 0, 0, 0, 0, 0))
        await wait_for(lambda: service.decoder.counts["reboots"] == 1, timeout_s=5)
        assert service.lock.counts["clock_changes"] == 1
        sender.send(
            sender.mav.heartbeat_encode(
                mavlink.MAV_TYPE_FIXED_WING, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3
            )
        )
        await play(sender, messages)  # its clock runs on from the reboot
        await wait_for(lambda: service.lock.counts["heartbeat_mismatch"] == 1)
        assert service.lock.locked == (1, 1) and service.decoder.target == (1, 1)
        assert service.decoder.counts["reboots"] == 1


# -- udpin answers only the autopilot -----------------------------------------------------------


async def test_udpin_answers_only_the_locked_autopilot(
    flight: Messages,  # noqa: F811
) -> None:
    """A forger on another port using the autopilot's ids, and a second autopilot, get nothing
    back; the autopilot gets the stream requests, our HEARTBEAT (configured on) and values."""
    messages = [m for _, m in flight[:400]]
    config = ServiceConfig(heartbeat_to_autopilot=True, values_to_autopilot=True)
    async with running(replace(config, stale_after_s=30.0)) as (service, _sender):
        port = daemon_port(service)
        autopilot = await autopilot_to(port, system=1)
        await autopilot.play(messages)
        await wait_for(lambda: service.lock.locked == (1, 1))
        forger = await autopilot_to(port, system=1)  # same ids, another port
        other = await autopilot_to(port, system=9)
        for _ in range(2):
            await forger.play(messages[:100])
            await other.play(messages[:100])
            await asyncio.sleep(1.0)  # a HEARTBEAT period and a publish period each
        # datagrams of unused ids only are dropped by their header before the peer check
        used = sum(m.get_msgId() in USED_MESSAGE_IDS for m in messages[:100])
        await wait_for(lambda: service.lock.counts["foreign_peer"] >= 2 * used)
        assert service.pipeline.counts["velocity"] < 400  # the forger's frames were dropped
    kinds = {m.get_type() for m in autopilot.received}
    assert {"REQUEST_DATA_STREAM", "COMMAND_LONG", "HEARTBEAT", "NAMED_VALUE_FLOAT"} <= kinds
    assert forger.datagrams == 0 and other.datagrams == 0


async def test_autopilot_heartbeats_of_thirty_systems_are_never_asked_or_answered(
    flight: Messages,  # noqa: F811
) -> None:
    """30 autopilot HEARTBEATs of new systems: none is a candidate (a HEARTBEAT alone is no
    evidence), none gets a stream request or anything else."""
    heartbeat = next(m for _, m in flight if m.get_type() == "HEARTBEAT")
    config = ServiceConfig(stale_after_s=30.0, heartbeat_to_autopilot=True)
    async with running(config) as (service, _sender):
        forgers = [await autopilot_to(daemon_port(service), system=10 + k) for k in range(30)]
        for forger in forgers:
            forger.send_raw(forger.pack(heartbeat))
        await wait_for(lambda: service.lock.counts["before_autopilot"] == 30)
        await asyncio.sleep(1.1)  # a HEARTBEAT period and a stream request round
    assert service.lock.counts["candidates"] == 0
    assert sum(f.datagrams for f in forgers) == 0
