"""Whether a log's or a link's autopilot flies a rotorcraft: the power model is a multirotor's.

An autopilot says what it flies in its HEARTBEAT ``type`` (MAV_TYPE; a PX4 ULog's
``vehicle_status.system_type`` holds the same number) and, for ArduPilot, in the firmware
text it writes at boot ("ArduPlane V4.5.0", "APM:Copter V3.3"). The power model, the fusion's
figures and the return home are a multirotor's: on a fixed wing, a VTOL, a rover or a
submarine they describe another vehicle. The readers and the daemon say so in one sentence
(:func:`frame_note`, :func:`firmware_note`); they do not refuse the log or the link.
"""

from __future__ import annotations

from estimator.telemetry.firmware import FIRMWARE_TEXT

#: MAV_TYPE of a frame not told (MAV_TYPE_GENERIC).
GENERIC_TYPE = 0
#: HEARTBEAT ``type`` of the frames ArduCopter flies (its ``autopilot`` ArduPilot): the
#: rotorcraft the power model describes. MAVLink's numbers (common.xml's MAV_TYPE), written
#: out so that a ULog replay, which reads no MAVLink, does not import pymavlink for them.
COPTER_TYPES = frozenset(
    {
        2,  # QUADROTOR
        3,  # COAXIAL
        4,  # HELICOPTER
        13,  # HEXAROTOR
        14,  # OCTOROTOR
        15,  # TRICOPTER
        29,  # DODECAROTOR
        35,  # DECAROTOR
    }
)


def frame_note(mav_type: int | None) -> str | None:
    """A sentence for an autopilot whose MAV_TYPE is not a rotorcraft's; None for a rotorcraft
    or an unknown frame (none seen, or MAV_TYPE_GENERIC)."""
    if mav_type is None or mav_type == GENERIC_TYPE or mav_type in COPTER_TYPES:
        return None
    # named by pymavlink's dialect, imported only for a frame to name (module docstring)
    from pymavlink.dialects.v20 import common as mavlink

    entry = mavlink.enums["MAV_TYPE"].get(mav_type)
    return _not_a_multirotor(f"MAV_TYPE {mav_type}" if entry is None else entry.name)


def firmware_note(text: str) -> str | None:
    """A sentence for an ArduPilot firmware text that names another vehicle than Copter; None
    for Copter or a text that names no firmware."""
    match = FIRMWARE_TEXT.match(text)
    if match is None or match["vehicle"] == "Copter":
        return None
    return _not_a_multirotor(text.strip())


def _not_a_multirotor(frame: str) -> str:
    return (
        f"the autopilot flies no multirotor ({frame}): the power model is a multirotor's, so "
        "its power, energy and endurance figures do not describe this vehicle"
    )
