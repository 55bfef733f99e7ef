"""Which way up GLOBAL_POSITION_INT.vz is sent, judged from the height in the same messages
(:mod:`estimator.telemetry.vz_sense`), alone and in the daemon over UDP."""

from __future__ import annotations

import copy
import logging
import math

import pytest
from test_service import flight, play, running, wait_for  # noqa: F401 (flight: a fixture)

from estimator.mavlink.config import ServiceConfig
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


async def test_a_daemon_that_missed_the_firmware_text_reads_the_climb_up(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A daemon started after an old Copter's boot never sees its firmware text. The simulated
    flight over UDP with GLOBAL_POSITION_INT.vz sent positive up, as Copter 3.3 sends it, and
    no other velocity: its take-off climb (2 m/s, 3–12 s) is read as a climb within three
    judged pairs, and the daemon says so once."""
    caplog.set_level(logging.WARNING, logger="uav_energy")
    messages = []
    for _, msg in flight:
        if msg.get_type() == "LOCAL_POSITION_NED":
            continue  # GLOBAL_POSITION_INT is the velocity
        if msg.get_type() == "GLOBAL_POSITION_INT":
            msg = copy.copy(msg)
            msg.vz = -msg.vz
        if getattr(msg, "time_boot_ms", 0) > 10_000:
            break
        messages.append(msg)
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: (e := service.out.latest) is not None and e.time_s >= 9.0)
        sense = service.decoder.vz_sense
        assert (sense.down_sign, sense.decided_by) == (-1, "height")
        assert sense.note is not None
        assert service.out.latest.climb_mps == pytest.approx(2.0, abs=0.3)
    said = [r.getMessage() for r in caplog.records if "read positive up" in r.getMessage()]
    assert said == [sense.note]
