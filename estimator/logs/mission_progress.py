"""When a flown AUTO mission reached each of its items, from a MAVLink telemetry log (.tlog).

ArduCopter and PX4 send MISSION_CURRENT with the item they fly towards; its first report of
each item, on the autopilot's clock (s since boot: the latest ``time_boot_ms`` of the same
sender before it), marks where that item's leg starts. Only the sender of the first HEARTBEAT
with an autopilot type is read (a ground station's own messages are not the vehicle's).
"""

from __future__ import annotations

from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import UserError


def mission_item_starts(tlog: Path) -> list[tuple[int, float]]:
    """(item sequence number, autopilot time in s) of each item's first MISSION_CURRENT, in
    the order reported; UserError when the log reports no mission progress."""
    try:
        conn = mavutil.mavlink_connection(str(tlog), robust_parsing=True)
    except OSError as exc:
        raise UserError(f"{tlog}: cannot be read ({exc.strerror})") from None
    sender: tuple[int, int] | None = None
    clock_s: float | None = None
    starts: list[tuple[int, float]] = []
    seen: set[int] = set()
    while (msg := conn.recv_match(blocking=False)) is not None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if sender is None:
            if msg.get_type() == "HEARTBEAT" and msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                sender = source
            continue
        if source != sender:
            continue
        if (boot_ms := getattr(msg, "time_boot_ms", None)) is not None:
            clock_s = boot_ms / 1000.0
        if msg.get_type() == "MISSION_CURRENT" and clock_s is not None and msg.seq not in seen:
            seen.add(msg.seq)
            starts.append((int(msg.seq), clock_s))
    if not starts:
        raise UserError(f"{tlog}: no MISSION_CURRENT from the autopilot (not an AUTO mission?)")
    return starts
