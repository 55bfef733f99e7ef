"""Build small MAVLink telemetry logs for tests (pymavlink codec, tlog record layout)."""

from __future__ import annotations

import struct
from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.firmware import copter_vz_up

EPOCH_US = 1_458_000_000_000_000


def _codec() -> mavlink.MAVLink:
    return mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def flight_frames(
    seconds: float = 30.0,
    current_ca: int = 1500,
    velocity: bool = True,
    speed_mps: float = 3.0,
    mavlink1: bool = True,
    vz_cmps: int = 0,
    mav_type: int = mavlink.MAV_TYPE_QUADROTOR,
) -> list[tuple[int, bytes]]:
    """(receive µs, frame) of a simple armed flight at 2 Hz: heartbeat (its frame ``mav_type``),
    position (its vz ``vz_cmps``, cm/s as sent), battery.

    Also sends VFR_HUD, which the decoder does not use (it must be skipped).
    """
    codec = _codec()
    out = []
    t_ms = 1000
    while t_ms < seconds * 1000:
        msgs = [
            codec.heartbeat_encode(
                mav_type,
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
                    t_ms, 0, 0, 10_000, 5_000, int(speed_mps * 100), 0, vz_cmps, 0
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


def smart_battery_info(serial: bytes, battery_id: int = 0) -> mavlink.MAVLink_message:
    """SMART_BATTERY_INFO of a 3S 5 Ah pack with ``serial`` (char[32], NUL-padded)."""
    return mavlink.MAVLink_smart_battery_info_message(
        battery_id, 0, 0, 5000, 5000, 3, serial, b"3S 5000", 0, 0, 0, 0, 0, 0, 0, 0, b""
    )


def with_pack(data: bytes, serial: bytes, shift_s: float = 0.0) -> bytes:
    """A tlog's bytes with a SMART_BATTERY_INFO naming ``serial`` after its first record (from
    the autopilot, system 1 component 1) and every receive stamp moved by ``shift_s``."""
    from estimator.logs.tlog import STAMP_BYTES, frame_length

    codec = _codec()
    out = bytearray()
    pos = 0
    while pos < len(data):
        header = frame_length(data, pos + STAMP_BYTES)
        assert header is not None, f"no frame at {pos + STAMP_BYTES}"
        end = pos + STAMP_BYTES + header[0]
        (stamp_us,) = struct.unpack_from(">Q", data, pos)
        stamp = struct.pack(">Q", stamp_us + round(shift_s * 1e6))
        out += stamp + data[pos + STAMP_BYTES : end]
        if pos == 0:
            out += stamp + smart_battery_info(serial).pack(codec)
        pos = end
    return bytes(out)


def without_firmware_text(log: Path, out: Path) -> Path:
    """A copy of the tlog ``log`` at ``out`` without the STATUSTEXT that names an old Copter
    (:func:`copter_vz_up`): a log that sends GLOBAL_POSITION_INT.vz positive up and does not
    say so (the IRIS+ logs without their "APM:Copter V3.3" line)."""
    records = []
    reader = mavutil.mavmmaplog(str(log))
    while (msg := reader.recv_msg()) is not None:
        if not (msg.get_type() == "STATUSTEXT" and copter_vz_up(msg.text) is not None):
            records.append(struct.pack(">Q", round(msg._timestamp * 1e6)) + msg.get_msgbuf())
    out.write_bytes(b"".join(records))
    return out
