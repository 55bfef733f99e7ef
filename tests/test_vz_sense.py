"""Which way up GLOBAL_POSITION_INT.vz is sent, judged from the height in the same messages
(:mod:`estimator.telemetry.vz_sense`), alone and in the daemon over UDP."""

from __future__ import annotations

import asyncio
import copy
import logging
import math
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import flight, play, running, wait_for  # noqa: F401 (flight: a fixture)
from test_trust import autopilot_to, daemon_port
from tlog_builder import EPOCH_US, write_tlog

from estimator.logs import iter_samples
from estimator.mavlink import autopilot_lock
from estimator.mavlink.config import ServiceConfig
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.firmware import flight_sw_version, version_numbers
from estimator.telemetry.samples import VelocitySample
from estimator.telemetry.vz_sense import DECIDING_PAIRS, VerticalSense


def climb(sense: VerticalSense, vz_sent_mps: float, seconds: int, start_s: float = 0.0) -> None:
    """Messages every second of a climb at 1 m/s from ``start_s`` (s; the height in m is the
    time), vz as sent."""
    for i in range(seconds + 1):
        sense.observe(start_s + i, vz_sent_mps, start_s + i)


def test_a_climb_sent_positive_down_keeps_mavlinks_sign() -> None:
    sense = VerticalSense()
    climb(sense, -1.0, DECIDING_PAIRS)
    assert (sense.down_sign, sense.decided_by, sense.note) == (1, "height", None)


def test_a_climb_sent_positive_up_is_read_so_from_the_verdict_on() -> None:
    sense = VerticalSense()
    climb(sense, 1.0, DECIDING_PAIRS - 1)
    assert (sense.down_sign, sense.decided_by) == (1, None)  # one pair short
    climb(sense, 1.0, 1, start_s=DECIDING_PAIRS)
    assert (sense.down_sign, sense.decided_by) == (-1, "height")
    assert sense.note is not None and "read positive up" in sense.note


def test_level_flight_slow_rates_gaps_and_broken_stamps_decide_nothing() -> None:
    sense = VerticalSense()
    for i in range(50):
        sense.observe(float(i), 0.3, 0.3 * i)  # below the judged rate
    for i in range(50):
        sense.observe(100.0 + 6.0 * i, 1.0, 6.0 * i)  # pairs too far apart
    for t in (500.0, 400.0, 400.0, math.nan, math.inf):
        sense.observe(t, 1.0, 0.0)  # back in time, repeated, not finite
    for vz in (math.nan, math.inf):
        sense.observe(600.0, vz, 5.0)
        sense.observe(601.0, vz, 7.0)
    assert (sense.down_sign, sense.decided_by, sense.note) == (1, None, None)


def test_disagreeing_pairs_decide_only_beyond_their_share() -> None:
    sense = VerticalSense()
    sense.observe(0.0, -1.0, 0.0)
    sense.observe(1.0, -1.0, 1.0)  # agrees
    for t in range(2, DECIDING_PAIRS + 2):
        sense.observe(float(t), 1.0, float(t))  # the vz turned: disagrees
    assert sense.decided_by is None  # 1 agrees, 2 disagree: neither share reaches 0.8
    climb(sense, 1.0, 4, start_s=DECIDING_PAIRS + 2)
    assert (sense.down_sign, sense.decided_by) == (-1, "height")


@pytest.mark.parametrize("vz_up", [True, False])
def test_the_firmware_text_decides_over_the_height(vz_up: bool) -> None:
    sense = VerticalSense()
    climb(sense, -1.0 if vz_up else 1.0, DECIDING_PAIRS)  # the height says the other way
    sense.firmware(vz_up)
    assert (sense.down_sign, sense.decided_by) == (-1 if vz_up else 1, "firmware")
    climb(sense, -1.0 if vz_up else 1.0, DECIDING_PAIRS, start_s=100.0)
    assert sense.down_sign == (-1 if vz_up else 1)
    assert sense.note is None  # the height's verdict, NED, said nothing; the text's stands


def test_a_firmware_text_after_the_heights_verdict_keeps_or_takes_back_its_note() -> None:
    for vz_up in (True, False):
        sense = VerticalSense()
        climb(sense, 1.0, DECIDING_PAIRS)
        assert sense.note is not None
        sense.firmware(vz_up)
        assert (sense.note is not None) is vz_up


def test_after_a_reboot_the_heights_verdict_is_kept_and_judged_anew() -> None:
    """The same firmware after its reboot keeps vz read positive up from its first pair on;
    one reflashed to send it positive down is read so once the height has shown it."""
    for vz_sent_mps, down_sign in ((1.0, -1), (-1.0, 1)):
        sense = VerticalSense()
        climb(sense, 1.0, DECIDING_PAIRS)
        first_note = sense.note
        sense.rebooted()
        climb(sense, vz_sent_mps, DECIDING_PAIRS - 1)
        assert (sense.down_sign, sense.decided_by, sense.note) == (-1, "height", first_note)
        climb(sense, vz_sent_mps, 1, start_s=DECIDING_PAIRS)
        assert (sense.down_sign, sense.decided_by) == (down_sign, "height")
        assert (sense.note == first_note) is (down_sign < 0)
        assert sense.note is not None
        assert ("read positive down again" in sense.note) is (down_sign > 0)
        # each boot's verdict that turned the sign over is said, the reflashed one's too
        assert sense.notes == ([first_note, sense.note] if down_sign > 0 else [first_note])


def test_a_firmware_text_after_a_reboot_takes_back_only_its_own_boots_note() -> None:
    """The first boot's climb was read the wrong way until the height's verdict: a firmware
    text of the reflashed boot saying vz positive down takes back only what the height said
    of that boot."""
    sense = VerticalSense()
    climb(sense, 1.0, DECIDING_PAIRS)
    first_note = sense.note
    sense.rebooted()
    climb(sense, -1.0, DECIDING_PAIRS)
    assert sense.note is not None and len(sense.notes) == 2
    sense.firmware(False)
    assert (sense.note, sense.notes) == (None, [first_note])


def test_a_firmwares_verdict_is_not_judged_by_the_height_after_a_reboot() -> None:
    """A firmware text's sign stands over a reboot until the new firmware tells its own (its
    boot text; the daemon asks its version after each reboot)."""
    sense = VerticalSense()
    sense.firmware(True)
    sense.rebooted()
    climb(sense, -1.0, 2 * DECIDING_PAIRS)  # the height says positive down
    assert (sense.down_sign, sense.decided_by, sense.note) == (-1, "firmware", None)


def first_seconds(records: list, seconds: float, vz_sign: int) -> list:
    """The (time, message) records' messages of its first ``seconds`` (autopilot clock) without
    LOCAL_POSITION_NED (GLOBAL_POSITION_INT is the velocity), vz sent times ``vz_sign``."""
    messages = []
    for _, msg in records:
        if msg.get_type() == "LOCAL_POSITION_NED":
            continue
        if msg.get_type() == "GLOBAL_POSITION_INT":
            msg = copy.copy(msg)
            msg.vz = vz_sign * msg.vz
        if getattr(msg, "time_boot_ms", 0) > 1000 * seconds:
            break
        messages.append(msg)
    return messages


async def test_a_daemon_that_missed_the_firmware_text_reads_the_climb_up(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A daemon started after an old Copter's boot never sees its firmware text. The simulated
    flight over UDP with GLOBAL_POSITION_INT.vz sent positive up, as Copter 3.3 sends it, and
    no other velocity: its take-off climb (2 m/s, 3–12 s) is read as a climb within three
    judged pairs, and the daemon says so once."""
    caplog.set_level(logging.WARNING, logger="uav_energy")
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, sender):
        await play(sender, first_seconds(flight, 10.0, -1))
        await wait_for(lambda: (e := service.out.latest) is not None and e.time_s >= 9.0)
        sense = service.decoder.vz_sense
        assert (sense.down_sign, sense.decided_by) == (-1, "height")
        assert sense.note is not None
        assert service.out.latest.climb_mps == pytest.approx(2.0, abs=0.3)
    said = [r.getMessage() for r in caplog.records if "read positive up" in r.getMessage()]
    assert said == [sense.note]


async def test_a_daemon_reads_a_reflashed_copter_right_after_its_reboot(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Live over UDP: an old Copter without a firmware text climbs (vz read positive up), then
    reboots into a firmware that sends vz positive down and answers no version request: its
    new climb is published as a climb, and the daemon says each turn once."""
    caplog.set_level(logging.WARNING, logger="uav_energy")
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, sender):
        await play(sender, first_seconds(flight, 20.0, -1))
        await wait_for(lambda: service.decoder.vz_sense.decided_by == "height")
        await play(sender, first_seconds(flight, 10.0, 1))  # its clock back from 0
        await wait_for(lambda: service.decoder.counts["reboots"] == 1)
        await wait_for(lambda: (e := service.out.latest) is not None and 9.0 <= e.time_s <= 10.0)
        assert service.decoder.vz_sense.down_sign == 1
        assert service.out.latest.climb_mps == pytest.approx(2.0, abs=0.3)
    said = [r.getMessage() for r in caplog.records if "GLOBAL_POSITION_INT.vz" in r.getMessage()]
    assert len(said) == 2
    assert "read positive up" in said[0] and "read positive down again" in said[1]


async def test_another_autopilot_locked_after_the_first_falls_silent_has_its_own_vz_sign(
    flight: list,  # noqa: F811 (the fixture)
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An old Copter (vz sent positive up, no firmware text) climbs and falls silent; another
    autopilot (system 2, vz positive down as MAVLink defines it) takes its place over UDP. The
    sign the height decided on the first is not carried over: the second one's climb is
    published as a climb (2 m/s), not as a 2 m/s descent."""
    monkeypatch.setattr(autopilot_lock, "REPIN_AFTER_S", 0.3)  # wall s of silence
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, sender):
        await play(sender, first_seconds(flight, 10.0, -1))
        await wait_for(lambda: service.decoder.vz_sense.decided_by == "height")
        assert service.decoder.vz_sense.down_sign == -1
        await asyncio.sleep(0.5)  # the first autopilot is silent past REPIN_AFTER_S
        second = await autopilot_to(daemon_port(service), system=2)
        await second.play(first_seconds(flight, 12.0, 1))
        await wait_for(lambda: service.lock.locked == (2, 1))
        await wait_for(lambda: (e := service.out.latest) is not None and e.time_s >= 11.0)
        assert service.lock.counts["relocked"] == 1
        sense = service.decoder.vz_sense
        assert (sense.down_sign, sense.decided_by, sense.note) == (1, "height", None)
        assert service.out.latest.climb_mps == pytest.approx(2.0, abs=0.3)


def test_another_autopilot_has_its_own_velocity_message_and_vz_sign(
    flight: list,  # noqa: F811 (the fixture)
) -> None:
    """The decoder retargeted to another autopilot forgets what it learned of the last one:
    the first sent GLOBAL_POSITION_INT only, vz positive up; the second sends
    LOCAL_POSITION_NED only (without the change, its velocity would be skipped as a second
    source), and no vz sign is carried over to it."""
    decoder = TelemetryDecoder()
    decoder.decode_all(first_seconds(flight, 10.0, -1))
    assert (decoder.target, decoder.velocity_type) == ((1, 1), "GLOBAL_POSITION_INT")
    assert decoder.vz_sense.down_sign == -1
    decoder.retarget((2, 1))
    second = []
    for _, msg in flight:
        if msg.get_type() == "GLOBAL_POSITION_INT":
            continue
        if getattr(msg, "time_boot_ms", 0) > 12_000:
            break
        msg = copy.copy(msg)
        msg._header = copy.copy(msg._header)
        msg._header.srcSystem = 2
        second.append(msg)
    velocities = [s for s in decoder.decode_all(second) if isinstance(s, VelocitySample)]
    assert decoder.velocity_type == "LOCAL_POSITION_NED"
    assert (decoder.vz_sense.down_sign, decoder.vz_sense.decided_by) == (1, None)
    at_8_s = min(velocities, key=lambda s: abs(s.time_s - 8.0))
    assert at_8_s.vd_mps == pytest.approx(-2.0, abs=0.3)  # climbing at 2 m/s


@pytest.mark.parametrize("reflashed", [False, True])
def test_a_rebooted_copter_is_read_right_from_its_first_climb_or_once_its_height_shows_it(
    flight: list,  # noqa: F811 (the fixture)
    reflashed: bool,
) -> None:
    """An old Copter without a firmware text (vz sent positive up) climbs, then reboots (its
    clock back to 0) and takes off again: the same firmware has the new climb read as a climb
    from its first samples; reflashed to a Copter that sends vz positive down (no text, no
    version), its first samples at 0.5 m/s or more until the height's verdict are read the wrong
    way, the rest as a climb (before, all of them as a descent)."""
    decoder = TelemetryDecoder()
    decoder.decode_all(first_seconds(flight, 10.0, -1))
    assert decoder.vz_sense.down_sign == -1
    again = first_seconds(flight, 12.0, 1 if reflashed else -1)
    velocities = [s for s in decoder.decode_all(again) if isinstance(s, VelocitySample)]
    assert decoder.counts["reboots"] == 1
    sense = decoder.vz_sense
    assert (sense.down_sign, sense.decided_by) == (1 if reflashed else -1, "height")
    assert len(sense.notes) == (2 if reflashed else 1)
    climbing = [s.vd_mps for s in velocities if s.time_s <= 11.0 and abs(s.vd_mps) >= 0.5]
    read_down = [i for i, vd in enumerate(climbing) if vd > 0.0]  # the climb's samples
    assert len(climbing) > 60
    assert read_down == (list(range(DECIDING_PAIRS)) if reflashed else [])


def test_a_replayed_tlog_says_each_boots_verdict_in_one_warning(
    flight: list,  # noqa: F811 (the fixture)
    tmp_path: Path,
) -> None:
    """The reflashed Copter above as a tlog: one vertical-velocity warning (said once a log, as
    any cause) holding both verdicts in order, the first boot's read positive up, then the
    reflashed one's positive down again."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    boots = [*first_seconds(flight, 10.0, -1), *first_seconds(flight, 12.0, 1)]
    frames = [(EPOCH_US + 10_000 * i, msg.pack(codec)) for i, msg in enumerate(boots)]
    stream = iter_samples(write_tlog(tmp_path / "reflashed.tlog", frames))
    list(stream)
    [(cause, warning)] = stream.problems()
    assert cause == "vertical velocity"
    first, then = warning.split("; then ")
    assert "read positive up from then on" in first and "read positive down again" in then


def test_only_an_ardupilot_autopilot_is_asked_its_height() -> None:
    """Another stack never sent vz positive up: its HEARTBEAT settles MAVLink's sign, and a
    climb sent the wrong way does not turn it over (nor does it take back a firmware text)."""
    for ardupilot, down_sign in ((True, -1), (False, 1)):
        sense = VerticalSense()
        sense.heartbeat(ardupilot, copter=True)
        climb(sense, 1.0, 2 * DECIDING_PAIRS)
        assert sense.down_sign == down_sign
        assert (sense.note is not None) is ardupilot
    sense = VerticalSense()
    sense.firmware(True)
    sense.heartbeat(ardupilot=False, copter=True)
    assert (sense.down_sign, sense.decided_by) == (-1, "firmware")


def test_a_px4_heartbeat_keeps_a_flipped_stream_as_sent(
    flight: list,  # noqa: F811 (the fixture)
) -> None:
    """The simulated take-off with vz sent positive up and its HEARTBEATs naming PX4: the
    decoder reads vz as MAVLink defines it (the climb as a descent, as sent)."""
    decoder = TelemetryDecoder()
    messages = first_seconds(flight, 10.0, -1)
    for i, msg in enumerate(messages):
        if msg.get_type() == "HEARTBEAT":
            messages[i] = copy.copy(msg)
            messages[i].autopilot = mavlink.MAV_AUTOPILOT_PX4
    velocities = [s for s in decoder.decode_all(messages) if isinstance(s, VelocitySample)]
    assert (decoder.vz_sense.down_sign, decoder.vz_sense.decided_by) == (1, "autopilot")
    at_8_s = min(velocities, key=lambda s: abs(s.time_s - 8.0))
    assert at_8_s.vd_mps == pytest.approx(2.0, abs=0.3)  # as sent


def autopilot_version(major: int, minor: int, patch: int) -> mavlink.MAVLink_message:
    """AUTOPILOT_VERSION of a release (type 255) from system 1, component 1, as ArduPilot
    fills flight_sw_version."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    version = major << 24 | minor << 16 | patch << 8 | 0xFF
    msg = codec.autopilot_version_encode(
        0, version, 0, 0, 0, b"\0" * 8, b"\0" * 8, b"\0" * 8, 0, 0, 0
    )
    msg.pack(codec)
    return msg


@pytest.mark.parametrize(
    ("version", "down_sign"), [((3, 3, 0), -1), ((3, 6, 0), 1), ((4, 6, 2), 1)]
)
def test_an_arducopters_version_decides_before_its_first_climb(
    flight: list,  # noqa: F811 (the fixture)
    version: tuple[int, int, int],
    down_sign: int,
) -> None:
    """The take-off with vz sent as a Copter of ``version`` sends it and an AUTOPILOT_VERSION
    after the first HEARTBEAT: the version decides before the climb, so the climb is read as
    a climb from its first samples (the height would need three judged pairs)."""
    messages = first_seconds(flight, 10.0, down_sign)
    first_heartbeat = next(i for i, m in enumerate(messages) if m.get_type() == "HEARTBEAT")
    messages.insert(first_heartbeat + 1, autopilot_version(*version))
    decoder = TelemetryDecoder()
    velocities = [s for s in decoder.decode_all(messages) if isinstance(s, VelocitySample)]
    sense = decoder.vz_sense
    assert (sense.down_sign, sense.decided_by, sense.note) == (down_sign, "firmware", None)
    assert sense.firmware_version == version
    climbing = [s.vd_mps for s in velocities if 3.0 <= s.time_s <= 9.0]
    assert max(climbing) < 0.1 and min(climbing) < -1.5  # up all along, at 2 m/s


def test_a_version_of_another_stack_or_none_decides_nothing(
    flight: list,  # noqa: F811 (the fixture)
) -> None:
    """AUTOPILOT_VERSION 3.3 from a PX4 HEARTBEAT's autopilot is not a Copter's; a version of
    0 is none."""
    messages = [m for _, m in flight[:50]]
    first_heartbeat = next(i for i, m in enumerate(messages) if m.get_type() == "HEARTBEAT")
    px4 = copy.copy(messages[first_heartbeat])
    px4.autopilot = mavlink.MAV_AUTOPILOT_PX4
    decoder = TelemetryDecoder()
    decoder.decode_all([px4, autopilot_version(3, 3, 0)])
    assert (decoder.vz_sense.down_sign, decoder.vz_sense.decided_by) == (1, "autopilot")
    decoder = TelemetryDecoder()
    decoder.decode_all([messages[first_heartbeat], autopilot_version(0, 0, 0)])
    assert (decoder.vz_sense.decided_by, decoder.vz_sense.firmware_version) == (None, None)


async def test_the_daemon_asks_an_arducopter_its_version_and_reads_its_vz_so(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Live over UDP: the daemon asks the autopilot it locked for its AUTOPILOT_VERSION
    (MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES); an answer of Copter 3.3 has its climb, sent
    positive up, read as a climb without the height's judging, and the version said once."""
    caplog.set_level(logging.INFO, logger="uav_energy")
    messages = first_seconds(flight, 10.0, -1)
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, _):
        autopilot = await autopilot_to(daemon_port(service))
        asked = (mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1.0)
        await autopilot.play(messages[:60])
        await wait_for(
            lambda: any(
                m.get_type() == "COMMAND_LONG" and (m.command, m.param1) == asked
                for m in autopilot.received
            )
        )
        await autopilot.play([autopilot_version(3, 3, 0), *messages[60:]])
        await wait_for(lambda: (e := service.out.latest) is not None and e.time_s >= 9.0)
        sense = service.decoder.vz_sense
        assert (sense.down_sign, sense.decided_by, sense.note) == (-1, "firmware", None)
        assert service.out.latest.climb_mps == pytest.approx(2.0, abs=0.3)
    said = [r.getMessage() for r in caplog.records if "its AUTOPILOT_VERSION" in r.getMessage()]
    assert said == [
        "autopilot firmware 3.3.0 (its AUTOPILOT_VERSION): GLOBAL_POSITION_INT.vz read positive up"
    ]


def test_flight_sw_version_is_packed_as_ardupilot_fills_it_and_read_back() -> None:
    """major << 24 | minor << 16 | patch << 8 | release type, as ArduPilot fills it (the live
    SITL's 4.7.0 development build, type 0, reads 0x04070000); 0 is not a version."""
    assert flight_sw_version((4, 7, 0), 0) == 0x04070000
    assert flight_sw_version((3, 3, 1), 255) == 0x030301FF
    assert version_numbers(flight_sw_version((3, 6, 12), 255)) == (3, 6, 12)
    assert version_numbers(0) is None
