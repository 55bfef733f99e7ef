"""Telemetry rates the PX4 way: one MAV_CMD_SET_MESSAGE_INTERVAL per message the daemon uses.

PX4 ignores REQUEST_DATA_STREAM (ArduPilot's stream groups); it sets each message's rate on
the link the command came in on. Its defaults on the onboard link (v1.16, SITL) are enough
for everything but the battery: BATTERY_STATUS comes at 0.5 Hz. So the daemon asks, of the
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

from pymavlink.dialects.v20 import common as mavlink

#: Hz of HOME_POSITION (PX4's own default on its onboard link: home moves only on arming).
HOME_RATE_HZ = 0.5
#: Hz of EXTENDED_SYS_STATE (PX4's own default on its onboard link).
LANDED_RATE_HZ = 5.0
#: Message id → which configured rate it takes ("velocity", "battery") or a fixed rate (Hz).
MESSAGES: tuple[tuple[int, str | float], ...] = (
    (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, "velocity"),
    (mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, "velocity"),
    (mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, "battery"),
    (mavlink.MAVLINK_MSG_ID_WIND_COV, "battery"),
    (mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, LANDED_RATE_HZ),
    (mavlink.MAVLINK_MSG_ID_HOME_POSITION, HOME_RATE_HZ),
)


def interval_requests(
    mav: mavlink.MAVLink,
    target: tuple[int, int],
    velocity_rate_hz: float,
    battery_rate_hz: float,
) -> list[mavlink.MAVLink_message]:
    """COMMAND_LONG MAV_CMD_SET_MESSAGE_INTERVAL (interval in µs) for each of :data:`MESSAGES`
    to ``target`` (system, component), encoded with ``mav``; rates in Hz (> 0)."""
    rates = {"velocity": velocity_rate_hz, "battery": battery_rate_hz}
    out = []
    for msg_id, rate in MESSAGES:
        rate_hz = rates[rate] if isinstance(rate, str) else rate
        out.append(
            mav.command_long_encode(
                *target,
                mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                0,
                msg_id,
                1e6 / rate_hz,
                0,
                0,
                0,
                0,
                0,
            )
        )
    return out
