"""Build small MAVLink telemetry logs for tests (pymavlink codec, tlog record layout)."""

from __future__ import annotations

import struct
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

EPOCH_US = 1_458_000_000_000_000


def _codec() -> mavlink.MAVLink:
    return mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def flight_frames(
    seconds: float = 30.0,
    current_ca: int = 1500,
    velocity: bool = True,
    speed_mps: float = 3.0,
    mavlink1: bool = True,
) -> list[tuple[int, bytes]]:
    """(receive µs, frame) of a simple armed flight at 2 Hz: heartbeat, position, battery.

    Also sends VFR_HUD, which the decoder does not use (it must be skipped).
    """
    codec = _codec()
    out = []
    t_ms = 1000
    while t_ms < seconds * 1000:
        msgs = [
            codec.heartbeat_encode(
                mavlink.MAV_TYPE_QUADROTOR,
                mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                0,
                mavlink.MAV_STATE_ACTIVE,
            ),
            codec.vfr_hud_encode(speed_mps, speed_mps, 0, 50, 5.0, 0.0),
        ]
        msgs.append(codec.attitude_encode(t_ms, 0, 0, 0, 0, 0, 0))
        if velocity:
            msgs.append(
                codec.global_position_int_encode(
                    t_ms, 0, 0, 10_000, 5_000, int(speed_mps * 100), 0, 0, 0
                )
            )
        msgs.append(codec.sys_status_encode(0, 0, 0, 500, 11_800, current_ca, 80, 0, 0, 0, 0, 0, 0))
        for m in msgs:
            out.append((EPOCH_US + t_ms * 1000, m.pack(codec, force_mavlink1=mavlink1)))
        t_ms += 500
    return out


def write_tlog(path: Path, frames: list[tuple[int, bytes]]) -> Path:
    path.write_bytes(b"".join(struct.pack(">Q", us) + frame for us, frame in frames))
    return path
