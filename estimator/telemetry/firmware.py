"""What an autopilot's firmware text says about the messages it sends.

ArduPilot names its firmware and version in a STATUSTEXT when a ground station connects and
when logging starts ("APM:Copter V3.3 (d3e14c1c)", "ArduCopter V3.6.12 (…)"), and its version
in AUTOPILOT_VERSION when asked (MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES). Copter before
3.6 sent GLOBAL_POSITION_INT.vz positive up, against MAVLink's definition (positive down);
ArduPilot changed it to NED for every vehicle in February 2018 (ArduPilot pull request 7672,
"fix velocity z-axis field in GLOBAL_POSITION_INT to be in NED format"), first released in
Copter 3.6. The IRIS+ logs of ``../shared/data`` (APM:Copter V3.3) show it: their vz and
their altitude rate disagree in sign on every climb and descent.
"""

from __future__ import annotations

import re

#: A firmware text: vehicle, major and minor version ("APM:Copter V3.3", "ArduCopter V3.5.4").
FIRMWARE_TEXT = re.compile(r"^(?:APM:|Ardu)(?P<vehicle>\w+) V?(?P<major>\d+)\.(?P<minor>\d+)")
#: The first Copter release that sends GLOBAL_POSITION_INT.vz positive down.
COPTER_VZ_DOWN_SINCE = (3, 6)


def firmware_named(text: str) -> str | None:
    """``text`` without its surrounding blanks when it names a firmware
    (:data:`FIRMWARE_TEXT`), else None: a log's or a link's name for its autopilot."""
    return text.strip() if FIRMWARE_TEXT.match(text) else None


def copter_vz_up(text: str) -> bool | None:
    """Whether the Copter firmware that sent ``text`` sends GLOBAL_POSITION_INT.vz positive up
    (a version before :data:`COPTER_VZ_DOWN_SINCE`); None when ``text`` names no Copter
    firmware (another text, another vehicle: nothing is known)."""
    match = FIRMWARE_TEXT.match(text)
    if match is None or match["vehicle"] != "Copter":
        return None
    return (int(match["major"]), int(match["minor"])) < COPTER_VZ_DOWN_SINCE


def flight_sw_version(version: tuple[int, int, int], release_type: int) -> int:
    """AUTOPILOT_VERSION's ``flight_sw_version`` of a (major, minor, patch) ``version`` and a
    FIRMWARE_VERSION_TYPE ``release_type``, as ArduPilot and PX4 fill it (the inverse of
    :func:`version_numbers`)."""
    major, minor, patch = version
    return major << 24 | minor << 16 | patch << 8 | release_type


def version_numbers(flight_sw_version: int) -> tuple[int, int, int] | None:
    """(major, minor, patch) of AUTOPILOT_VERSION's ``flight_sw_version`` (major << 24 |
    minor << 16 | patch << 8 | release type, as ArduPilot and PX4 fill it); None for 0 (not
    filled in)."""
    major, minor, patch = (flight_sw_version >> shift & 0xFF for shift in (24, 16, 8))
    return (major, minor, patch) if flight_sw_version >> 8 else None


def copter_version_vz_up(version: tuple[int, int, int]) -> bool:
    """Whether an ArduCopter of this (major, minor, patch) sends GLOBAL_POSITION_INT.vz
    positive up (before :data:`COPTER_VZ_DOWN_SINCE`)."""
    return version[:2] < COPTER_VZ_DOWN_SINCE
