"""What the daemon asks the autopilot for: telemetry rates, the ArduPilot way and the PX4
way, and single messages (:func:`request_message`; HOME_POSITION while positions come
without it, :class:`HomeRequest`).

ArduPilot (:func:`ardupilot_requests`): REQUEST_DATA_STREAM for the POSITION and
EXTENDED_STATUS groups, one MAV_CMD_SET_MESSAGE_INTERVAL per message of
:data:`ARDUPILOT_MESSAGES` (the velocity and battery messages, and the autopilot's wind for
the return figures); once locked, and after each reboot, its AUTOPILOT_VERSION
(:func:`version_request`: which way up a Copter sends vz).

PX4 (:func:`px4_requests`) ignores REQUEST_DATA_STREAM; it sets each message's rate on the
link the command came in on. Its defaults on the onboard link (v1.16, SITL) are enough for
everything but the battery: BATTERY_STATUS comes at 0.5 Hz. So the daemon asks, of the
messages :data:`~estimator.telemetry.decode.USED_MESSAGE_IDS` holds, for:

- GLOBAL_POSITION_INT and LOCAL_POSITION_NED at the velocity rate (the position, height over
  home; the velocity from whichever the decoder believes first; PX4 sends 50 and 30 Hz);
- BATTERY_STATUS at the battery rate (SYS_STATUS, 5 Hz by default, stays the fallback);
- WIND_COV at the battery rate (sent only when PX4's estimator has wind);
- EXTENDED_SYS_STATE at :data:`LANDED_RATE_HZ` (PX4's landed detector: in the air or not);
- HOME_POSITION at :data:`HOME_RATE_HZ` (the return-home figures).

ATTITUDE (its clock only) and MISSION_CURRENT keep PX4's rates. Nothing else is sent to PX4
but reads (mission download, MAV_CMD_REQUEST_MESSAGE).
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.decode import ARDUPILOT_WIND_ID

#: Wall seconds after the first position without HOME_POSITION before it is requested, and
#: between requests.
HOME_REQUEST_AFTER_S = 3.0
HOME_REQUEST_RETRY_S = 10.0
#: Hz of HOME_POSITION (PX4's own default on its onboard link: home moves only on arming).
HOME_RATE_HZ = 0.5
#: Hz of EXTENDED_SYS_STATE (PX4's own default on its onboard link).
LANDED_RATE_HZ = 5.0
#: ArduPilot: message id → the configured rate it takes ("velocity", "battery").
ARDUPILOT_MESSAGES: tuple[tuple[int, str], ...] = (
    (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, "velocity"),
    (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, "velocity"),
    (mavlink.MAVLINK_MSG_ID_SYS_STATUS, "battery"),
    (mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, "battery"),
    (ARDUPILOT_WIND_ID, "battery"),  # the autopilot's wind, for the return (WIND)
    (mavlink.MAVLINK_MSG_ID_WIND_COV, "battery"),  # PX4's (an autopilot not known as PX4)
)
#: PX4: message id → which configured rate it takes ("velocity", "battery") or a fixed rate
#: (Hz).
PX4_MESSAGES: tuple[tuple[int, str | float], ...] = (
    (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, "velocity"),
    (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, "velocity"),
    (mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, "battery"),
    (mavlink.MAVLINK_MSG_ID_WIND_COV, "battery"),
    (mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, LANDED_RATE_HZ),
    (mavlink.MAVLINK_MSG_ID_HOME_POSITION, HOME_RATE_HZ),
)


def ardupilot_requests(
    mav: mavlink.MAVLink,
    target: tuple[int, int],
    velocity_rate_hz: float,
    battery_rate_hz: float,
) -> list[mavlink.MAVLink_message]:
    """REQUEST_DATA_STREAM (POSITION, EXTENDED_STATUS) and a SET_MESSAGE_INTERVAL for each of
    :data:`ARDUPILOT_MESSAGES` to ``target`` (system, component), encoded with ``mav``; rates
    in Hz (> 0)."""
    rates = {"velocity": velocity_rate_hz, "battery": battery_rate_hz}
    streams = [
        mav.request_data_stream_encode(*target, stream, round(rate_hz), 1)
        for stream, rate_hz in (
            (mavlink.MAV_DATA_STREAM_POSITION, velocity_rate_hz),
            (mavlink.MAV_DATA_STREAM_EXTENDED_STATUS, battery_rate_hz),
        )
    ]
    return streams + [
        _interval(mav, target, msg_id, rates[kind]) for msg_id, kind in ARDUPILOT_MESSAGES
    ]


def version_request(mav: mavlink.MAVLink, target: tuple[int, int]) -> mavlink.MAVLink_message:
    """COMMAND_LONG MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES to ``target``: its AUTOPILOT_VERSION,
    whose version says which way up a Copter sends vz (before 3.6: positive up). ArduCopter
    3.x answers it (its GCS_Mavlink.cpp), as 4.x does."""
    return mav.command_long_encode(
        *target, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 0, 1, 0, 0, 0, 0, 0, 0
    )


def px4_requests(
    mav: mavlink.MAVLink,
    target: tuple[int, int],
    velocity_rate_hz: float,
    battery_rate_hz: float,
) -> list[mavlink.MAVLink_message]:
    """A SET_MESSAGE_INTERVAL for each of :data:`PX4_MESSAGES` to ``target`` (system,
    component), encoded with ``mav``; rates in Hz (> 0)."""
    rates = {"velocity": velocity_rate_hz, "battery": battery_rate_hz}
    return [
        _interval(mav, target, msg_id, rates[rate] if isinstance(rate, str) else rate)
        for msg_id, rate in PX4_MESSAGES
    ]


def _interval(
    mav: mavlink.MAVLink, target: tuple[int, int], msg_id: int, rate_hz: float
) -> mavlink.MAVLink_message:
    """COMMAND_LONG MAV_CMD_SET_MESSAGE_INTERVAL: ``msg_id`` at ``rate_hz`` (interval in µs)."""
    return mav.command_long_encode(
        *target, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, 1e6 / rate_hz, 0, 0, 0, 0, 0
    )


def request_message(
    mav: mavlink.MAVLink, target: tuple[int, int], msg_id: int
) -> mavlink.MAVLink_message:
    """COMMAND_LONG MAV_CMD_REQUEST_MESSAGE: one ``msg_id`` from ``target``, now."""
    return mav.command_long_encode(
        *target, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, 0, 0, 0, 0, 0, 0
    )


class HomeRequest:
    """When to ask for HOME_POSITION: while positions come and no home does,
    :data:`HOME_REQUEST_AFTER_S` after the first position, then at most once per
    :data:`HOME_REQUEST_RETRY_S` (wall s)."""

    def __init__(self) -> None:
        self._first_position_s: float | None = None
        self._sent_s = -math.inf
        self.sent = 0

    def due(self, now_s: float, has_position: bool, has_home: bool) -> float | None:
        """Seconds waited since the first position when a request should go now, else None."""
        if not has_position or has_home:
            return None
        if self._first_position_s is None:
            self._first_position_s = now_s
        waited_s = now_s - self._first_position_s
        if waited_s < HOME_REQUEST_AFTER_S or now_s - self._sent_s < HOME_REQUEST_RETRY_S:
            return None
        return waited_s

    def message(
        self, mav: mavlink.MAVLink, target: tuple[int, int], now_s: float
    ) -> mavlink.MAVLink_message:
        """The request, sent now (counted)."""
        self._sent_s = now_s
        self.sent += 1
        return request_message(mav, target, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
