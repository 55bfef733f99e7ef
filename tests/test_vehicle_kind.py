"""An autopilot that flies no multirotor (:mod:`estimator.telemetry.vehicle_kind`): each
reader and the daemon say so in one sentence, and go on."""

from __future__ import annotations

import copy
import logging
from pathlib import Path

import pytest
from fixtures.dataflash_writer import DataFlashWriter
from fixtures.ulog_writer import PX4_FORMATS, ULogWriter
from pymavlink.dialects.v20 import common as mavlink
from test_service import flight, play, running, wait_for  # noqa: F401 (flight: a fixture)
from tlog_builder import flight_frames, write_tlog

from estimator.cli import main as cli_main
from estimator.logs import iter_samples
from estimator.mavlink.config import ServiceConfig
from estimator.telemetry.vehicle_kind import (
    COPTER_TYPES,
    GENERIC_TYPE,
    firmware_note,
    frame_note,
)

NO_MULTIROTOR = "the autopilot flies no multirotor"


def test_the_rotorcraft_types_are_mavlinks_numbers() -> None:
    names = ("QUADROTOR", "COAXIAL", "HELICOPTER", "HEXAROTOR", "OCTOROTOR", "TRICOPTER")
    named = {getattr(mavlink, f"MAV_TYPE_{n}") for n in (*names, "DODECAROTOR", "DECAROTOR")}
    assert named == COPTER_TYPES and GENERIC_TYPE == mavlink.MAV_TYPE_GENERIC


def test_a_rotorcraft_or_an_unknown_frame_is_not_remarked() -> None:
    assert frame_note(mavlink.MAV_TYPE_HEXAROTOR) is None
    assert frame_note(mavlink.MAV_TYPE_GENERIC) is None and frame_note(None) is None
    note = frame_note(mavlink.MAV_TYPE_FIXED_WING)
    assert note is not None and note.startswith(f"{NO_MULTIROTOR} (MAV_TYPE_FIXED_WING)")
    assert "(MAV_TYPE 250)" in str(frame_note(250))  # a number no dialect names
    assert firmware_note("APM:Copter V3.3 (d6053245)") is None
    assert firmware_note("Gripper load released") is None
    assert "(ArduSub V4.1.0 (89639005)):" in str(firmware_note("ArduSub V4.1.0 (89639005)"))


def test_a_fixed_wing_tlog_is_replayed_with_one_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plane = write_tlog(
        tmp_path / "plane.tlog", flight_frames(30, mav_type=mavlink.MAV_TYPE_FIXED_WING)
    )
    stream = iter_samples(plane)
    list(stream)
    assert [cause for cause, _ in stream.problems()] == ["vehicle"]
    copter = iter_samples(write_tlog(tmp_path / "copter.tlog", flight_frames(30)))
    list(copter)
    assert copter.problems() == []
    assert cli_main(["replay", str(plane)]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if NO_MULTIROTOR in line]
    assert len(said) == 1 and "MAV_TYPE_FIXED_WING" in said[0]


def test_a_dataflash_log_names_its_vehicle_in_its_firmware_text(tmp_path: Path) -> None:
    def log_of(text: str) -> Path:
        log = DataFlashWriter()
        for name in ("XKF1", "BAT", "MSG"):
            log.define(name)
        log.write("MSG", TimeUS=900_000, Message=text)
        for k in range(20):
            t_us = 1_000_000 + 100_000 * k
            log.write("XKF1", TimeUS=t_us, VN=1.0, PD=-5.0)
            log.write("BAT", TimeUS=t_us + 1, Volt=16.0, Curr=10.0)
        return log.save(tmp_path / f"{text.split()[0]}.bin")

    rover = iter_samples(log_of("ArduRover V4.5.1 (1a2b3c4d)"))
    list(rover)
    [(cause, warning)] = rover.problems()
    assert cause == "vehicle" and "(ArduRover V4.5.1 (1a2b3c4d)):" in warning
    copter = iter_samples(log_of("ArduCopter V4.5.1 (1a2b3c4d)"))
    list(copter)
    assert copter.problems() == [] and copter.firmware == "ArduCopter V4.5.1 (1a2b3c4d)"


@pytest.mark.parametrize(("system_type", "said"), [(1, True), (2, False), (0, False)])
def test_a_ulog_names_its_frame_in_vehicle_status(
    tmp_path: Path, system_type: int, said: bool
) -> None:
    """``vehicle_status.system_type`` is MAV_TYPE: 1 a fixed wing, 2 a quadrotor, 0 generic."""
    log = ULogWriter()
    log.add_format(
        "vehicle_status", [*PX4_FORMATS["vehicle_status"][:-1], ("uint8_t", "system_type")]
    )
    log.subscribe("vehicle_status")
    for k in range(3):
        log.write(
            "vehicle_status", timestamp=1_000_000 * (k + 1), arming_state=2, system_type=system_type
        )
    stream = iter_samples(log.save(tmp_path / "status.ulg"))
    list(stream)
    assert (stream.sanity.vehicle_note is not None) is said


async def test_the_daemon_says_once_that_a_fixed_wing_is_no_multirotor(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The simulated flight over UDP, its HEARTBEAT a fixed wing's: the daemon locks onto it,
    estimates as ever, and warns once."""
    caplog.set_level(logging.WARNING, logger="uav_energy")
    messages = []
    for _, msg in flight[:400]:
        if msg.get_type() == "HEARTBEAT":
            msg = copy.copy(msg)
            msg.type = mavlink.MAV_TYPE_FIXED_WING
        messages.append(msg)
    async with running(ServiceConfig(stale_after_s=600.0)) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: service.pipeline.counts["estimates"] > 5)
    said = [r.getMessage() for r in caplog.records if NO_MULTIROTOR in r.getMessage()]
    assert len(said) == 1 and "MAV_TYPE_FIXED_WING" in said[0]
