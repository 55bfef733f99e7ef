"""A pymavlink ground station that flies ArduCopter SITL by the autopilot's own clock.

SITL runs in lockstep at a speedup the host may not keep, so every wait here is in the
autopilot's seconds (``time_boot_ms`` of its messages), never a wall-clock sleep; the wall
clock only detects a SITL that stopped talking. Setpoints are re-sent as messages arrive
(GUIDED drops a velocity target after 3 s without one). Positions are local NED metres from
the EKF origin (the take-off point), velocities m/s NED, altitudes m above home.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from estimator.errors import UserError
from estimator.logs.mission_files import MissionItem
from estimator.sitl.receiver import Receiver

#: Wall seconds without any message from the autopilot that mean SITL has stopped.
STALL_WALL_S = 60.0
#: Streams a ground station normally asks for, and their rates (Hz of the autopilot's clock):
#: SYS_STATUS/GPS, positions, ATTITUDE, VFR_HUD, and BATTERY_STATUS/WIND/SYSTEM_TIME.
STREAM_RATES_HZ = {
    mavlink.MAV_DATA_STREAM_RAW_SENSORS: 0,
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: 2,
    mavlink.MAV_DATA_STREAM_RC_CHANNELS: 0,
    mavlink.MAV_DATA_STREAM_POSITION: 4,
    mavlink.MAV_DATA_STREAM_EXTRA1: 4,
    mavlink.MAV_DATA_STREAM_EXTRA2: 1,
    mavlink.MAV_DATA_STREAM_EXTRA3: 2,
}
#: SET_POSITION_TARGET_LOCAL_NED type masks: velocity only; position + velocity + accel.
VELOCITY_MASK = 0b0000_1101_1100_0111
POS_VEL_ACCEL_MASK = 0b0000_1100_0000_0000
AUTOPILOT = (1, 1)
#: MAV_CMD_COMPONENT_ARM_DISARM param2 that forces it.
FORCE = 21196
#: ArduCopter flight modes by name.
COPTER_MODES = {name: number for number, name in mavutil.mode_mapping_acm.items()}


@dataclass
class State:
    """What the autopilot last said (its clock in s since boot)."""

    boot_s: float = 0.0
    armed: bool = False
    mode: int = -1
    alt_m: float = 0.0
    north_m: float = 0.0
    east_m: float = 0.0
    vn_mps: float = 0.0
    ve_mps: float = 0.0
    consumed_mah: float = 0.0
    consumed_wh: float = 0.0
    voltage_v: float = 0.0
    current_a: float = 0.0
    mission_reached: int = -1


class Pilot(Receiver):
    """One MAVLink connection to SITL (``tcp:127.0.0.1:PORT``); ``tlog`` records every
    message received, as pymavlink writes it (8-byte big-endian µs stamp + frame)."""

    source = AUTOPILOT
    quiet_s = 1.0
    stall_wall_s = STALL_WALL_S
    stall_text = f"SITL sent nothing for {STALL_WALL_S:.0f} s (see sitl.log)"

    def __init__(self, url: str, tlog: Path | None = None, source_system: int = 255) -> None:
        super().__init__()
        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=source_system, source_component=190, retries=30
        )
        if tlog is not None:
            self.conn.setup_logfile(str(tlog))
        self.state = State()
        self.said: list[tuple[float, str]] = []
        self.params: dict[str, float] = {}
        self.acks: dict[int, int] = {}
        self.mission_requests: list[int] = []
        self.mission_ack: int | None = None

    def close(self) -> None:
        self.conn.close()
        if self.conn.logfile is not None:
            self.conn.logfile.close()

    # -- receiving ---------------------------------------------------------------------------

    def _update(self, msg: Any) -> None:
        s, kind = self.state, msg.get_type()
        boot_ms = getattr(msg, "time_boot_ms", None)
        if boot_ms is not None:
            s.boot_s = max(s.boot_s, boot_ms / 1000.0)
        if kind == "HEARTBEAT":
            s.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            s.mode = msg.custom_mode
        elif kind == "GLOBAL_POSITION_INT":
            s.alt_m = msg.relative_alt / 1000.0
        elif kind == "LOCAL_POSITION_NED":
            s.north_m, s.east_m, s.vn_mps, s.ve_mps = msg.x, msg.y, msg.vx, msg.vy
        elif kind == "BATTERY_STATUS" and msg.id == 0:
            s.consumed_mah = float(msg.current_consumed)
            if msg.energy_consumed >= 0:  # hJ: the autopilot's own ∫V·I
                s.consumed_wh = msg.energy_consumed / 36.0
            s.current_a = msg.current_battery / 100.0
        elif kind == "SYS_STATUS":
            s.voltage_v = msg.voltage_battery / 1000.0
        elif kind == "STATUSTEXT":
            self.said.append((s.boot_s, msg.text))
        elif kind == "PARAM_VALUE":
            self.params[msg.param_id] = msg.param_value
        elif kind == "COMMAND_ACK":
            self.acks[msg.command] = msg.result
        elif kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            self.mission_requests.append(msg.seq)
        elif kind == "MISSION_ACK":
            self.mission_ack = msg.type
        elif kind == "MISSION_ITEM_REACHED":
            s.mission_reached = msg.seq

    def _not_done_text(self, what: str, sim_timeout_s: float) -> str:
        recent = "; ".join(t for _, t in self.said[-4:])
        return f"SITL: {what} not done in {sim_timeout_s:.0f} s ({recent})"

    def every(self, period_s: float, send: Callable[[], None]) -> Callable[[], None]:
        """A tick that calls ``send`` at most once per ``period_s`` of the autopilot's clock."""
        last = [-math.inf]

        def tick() -> None:
            if self.state.boot_s - last[0] >= period_s:
                last[0] = self.state.boot_s
                send()

        return tick

    # -- commands ----------------------------------------------------------------------------

    def connect(self) -> None:
        """Wait for the autopilot's HEARTBEAT and ask for the usual streams."""
        self.wait_for(lambda: self.state.mode >= 0, 60.0, "first HEARTBEAT")
        for stream, rate in STREAM_RATES_HZ.items():
            self.conn.mav.request_data_stream_send(*AUTOPILOT, stream, rate, int(rate > 0))

    def set_param(self, name: str, value: float) -> None:
        """PARAM_SET, re-sent until the autopilot echoes the value."""
        self.params.pop(name, None)
        send = self.every(
            1.0,
            lambda: self.conn.mav.param_set_send(
                *AUTOPILOT, name.encode(), value, mavlink.MAV_PARAM_TYPE_REAL32
            ),
        )
        send()
        self.wait_for(
            lambda: math.isclose(self.params.get(name, math.nan), value, abs_tol=1e-4),
            10.0,
            f"set {name}",
            send,
        )

    def command(self, cmd: int, *params: float, timeout_s: float = 10.0) -> None:
        """COMMAND_LONG, re-sent until ACCEPTED."""
        values = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        self.acks.pop(cmd, None)

        def send() -> None:
            if self.acks.get(cmd, mavlink.MAV_RESULT_ACCEPTED) != mavlink.MAV_RESULT_ACCEPTED:
                self.acks.pop(cmd, None)
            if cmd not in self.acks:
                self.conn.mav.command_long_send(*AUTOPILOT, cmd, 0, *values)

        tick = self.every(1.0, send)
        tick()
        self.wait_for(
            lambda: self.acks.get(cmd) == mavlink.MAV_RESULT_ACCEPTED,
            timeout_s,
            f"command {cmd}",
            tick,
        )

    def send_mode(self, name: str) -> None:
        self.conn.mav.set_mode_send(
            AUTOPILOT[0], mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, COPTER_MODES[name]
        )

    def set_mode(self, name: str) -> None:
        tick = self.every(1.0, lambda: self.send_mode(name))
        tick()
        self.wait_for(lambda: self.state.mode == COPTER_MODES[name], 10.0, f"mode {name}", tick)

    def arm_guided(self, timeout_s: float = 150.0) -> None:
        """GUIDED and arm, retried until the EKF and GPS let it (PreArm texts in the error)."""

        def attempt() -> None:
            if self.state.mode != COPTER_MODES["GUIDED"]:
                self.send_mode("GUIDED")
            else:
                self.conn.mav.command_long_send(
                    *AUTOPILOT, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
                )

        tick = self.every(2.0, attempt)
        tick()
        self.wait_for(lambda: self.state.armed, timeout_s, "arming", tick)

    def takeoff(self, alt_m: float) -> None:
        self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt_m)
        self.wait_for(lambda: self.state.alt_m >= alt_m - 0.5, 60.0, "take-off")

    def send_velocity(self, vn_mps: float, ve_mps: float, vd_mps: float = 0.0) -> None:
        self.conn.mav.set_position_target_local_ned_send(
            0, *AUTOPILOT, mavlink.MAV_FRAME_LOCAL_NED, VELOCITY_MASK,
            0, 0, 0, vn_mps, ve_mps, vd_mps, 0, 0, 0, 0, 0,
        )  # fmt: skip

    def send_target(
        self,
        ned_m: Sequence[float],
        vel_mps: Sequence[float] = (0.0, 0.0, 0.0),
        accel_mps2: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.conn.mav.set_position_target_local_ned_send(
            0, *AUTOPILOT, mavlink.MAV_FRAME_LOCAL_NED, POS_VEL_ACCEL_MASK,
            *ned_m, *vel_mps, *accel_mps2, 0, 0,
        )  # fmt: skip

    def upload_mission(
        self, items: Sequence[tuple[int, int, float, float, float, float, float]]
    ) -> None:
        """Upload a mission: (command, frame, param1, param2, lat_deg, lon_deg, alt_m) per
        item; item 0 is home (ArduPilot overwrites it)."""
        self.upload_items(
            [
                MissionItem(seq, cmd, frame, (p1, p2, 0.0, 0.0), lat, lon, alt, f"item {seq}")
                for seq, (cmd, frame, p1, p2, lat, lon, alt) in enumerate(items)
            ]
        )

    def upload_items(self, items: Sequence[MissionItem], attempts: int = 10) -> None:
        """Upload mission items with the MISSION_ITEM_INT protocol (item 0 is home). NaN
        params (a .plan's nulls) go as NaN, MAVLink's "unset"; a NaN position as 0, 0. An
        autopilot still starting answers MAV_MISSION_NO_SPACE: retried every 2 s of its
        clock."""
        for _ in range(attempts):
            if self._upload_once(items) != mavlink.MAV_MISSION_NO_SPACE:
                return
            self.hold(2.0)
        raise UserError(f"SITL refused the mission (MISSION_ACK type {self.mission_ack})")

    def _upload_once(self, items: Sequence[MissionItem]) -> int | None:
        """One upload; the MISSION_ACK type when it is NO_SPACE, else UserError if refused."""
        self.mission_requests.clear()
        self.mission_ack = None
        self.conn.mav.mission_count_send(*AUTOPILOT, len(items), 0)
        sent: set[int] = set()

        def serve() -> None:
            while self.mission_requests:
                item = items[self.mission_requests.pop(0)]
                self.conn.mav.mission_item_int_send(
                    *AUTOPILOT, item.seq, item.frame, item.command, 0, 1, *item.params,
                    _e7(item.lat_deg), _e7(item.lon_deg), item.alt_m, 0,
                )  # fmt: skip
                sent.add(item.seq)

        self.wait_for(lambda: self.mission_ack is not None, 30.0, "mission upload", serve)
        if self.mission_ack == mavlink.MAV_MISSION_NO_SPACE and not sent:
            return self.mission_ack
        if self.mission_ack != mavlink.MAV_MISSION_ACCEPTED or len(sent) != len(items):
            raise UserError(f"SITL refused the mission (MISSION_ACK type {self.mission_ack})")
        return self.mission_ack

    def land(self, timeout_s: float = 120.0) -> None:
        """LAND and wait until the autopilot disarms on the ground; after 5 s on the ground
        disarm it (ArduCopter's land detector may not see a landing in SITL's wind)."""
        self.set_mode("LAND")
        self.wait_for(lambda: self.state.alt_m < 0.3, timeout_s, "landing")
        self.wait_disarmed()

    def wait_disarmed(self) -> None:
        """Wait until the autopilot, on the ground, disarms; force it after 5 s there."""
        on_ground_s = self.state.boot_s

        def force() -> None:
            if self.state.boot_s - on_ground_s > 5.0:
                self.conn.mav.command_long_send(
                    *AUTOPILOT, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, FORCE, 0, 0, 0, 0, 0
                )

        self.wait_for(lambda: not self.state.armed, 30.0, "disarming", self.every(1.0, force))


def _e7(deg: float) -> int:
    """Degrees as MISSION_ITEM_INT's 1e-7 degree integers (NaN: 0, "here")."""
    return round(deg * 1e7) if math.isfinite(deg) else 0
