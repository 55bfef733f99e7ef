"""A pymavlink ground station that flies PX4 SITL (SIH) by PX4's own clock, and a pack it
feeds into PX4.

The station speaks to PX4's ground-station link (``udpout`` to 18570+N: PX4 then answers
its address), so the onboard link (14540+N) is left to the daemon. Every wait is in PX4's
seconds (``time_boot_ms`` / ``time_usec`` of its messages: lockstep, so a slow host only
makes the flight slower); the wall clock only detects a PX4 that stopped talking.

The flight is the one of the SITL folder's ``example_flight.py``: GPS fix and home, arm
(retried: PX4 refuses until its estimator is ready), NAV_TAKEOFF (altitude AMSL), hover,
DO_REPOSITION (AMSL too), an OFFBOARD velocity leg, HOLD, NAV_LAND (or AUTO.RTL) until
disarmed; a mission may be uploaded first with the mission protocol (not flown).

:class:`MotorPack` is a battery for PX4 started with ``SIM_BAT_ENABLE=0``: its current
follows PX4's own motor outputs (SERVO_OUTPUT_RAW) through a motor/ESC model, its voltage a
resting curve less the sag; sent as BATTERY_STATUS from PX4's system id and a battery
component, PX4 takes it as its battery and republishes it on every link.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import UserError
from estimator.logs.mission_files import MissionItem
from estimator.sitl.receiver import Receiver

#: Wall seconds without any message from PX4 that mean it has stopped.
STALL_WALL_S = 30.0
#: PX4 custom modes (main << 16 | sub << 24): AUTO.LOITER (hold), AUTO.RTL and OFFBOARD.
HOLD_MODE = (4, 3)
RTL_MODE = (4, 5)
OFFBOARD_MODE = (6, 0)
#: SET_POSITION_TARGET_LOCAL_NED type mask: velocity only.
VELOCITY_MASK = 0b0000_1101_1100_0111
#: Seconds of PX4's clock between setpoints in OFFBOARD (PX4 wants ≥ 2 Hz).
SETPOINT_PERIOD_S = 0.1
#: Rates (Hz of PX4's clock; −1 off) asked for on the ground-station link, where PX4 streams
#: attitude, positions and outputs at 50 Hz: what the station reads, at what it needs, so a
#: Python client keeps up at a high speed factor.
GCS_RATES_HZ = {
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    mavlink.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW: 20.0,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE: -1.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: -1.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE_TARGET: -1.0,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: -1.0,
    mavlink.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED: -1.0,
    mavlink.MAVLINK_MSG_ID_RC_CHANNELS: -1.0,
}
M_PER_DEG_LAT = 111_320.0
#: The station's MAVLink (system, component).
OWN_ID = (245, 190)


@dataclass
class MotorPack:
    """A lithium pack driving the motors PX4 commands. Per motor, the electrical power is
    ``idle_w + full_w · u^1.5`` for a throttle ``u`` in [0, 1] from its PWM (1000-2000 µs;
    rotor power grows as thrust^1.5 and SIH's thrust is linear in ``u``), plus the
    avionics' ``avionics_a``; the voltage is ``cells`` × a resting curve linear in the state
    of charge (``cell_empty_v`` … ``cell_full_v``, PX4's BAT1_V_EMPTY/BAT1_V_CHARGED) less
    ``resistance_ohm`` × current. Charge (Ah) and energy (Wh) drawn are counted on PX4's
    clock (s)."""

    capacity_ah: float
    cells: int = 4
    cell_empty_v: float = 3.6
    cell_full_v: float = 4.05
    resistance_ohm: float = 0.05
    idle_w: float = 1.0
    full_w: float = 61.0
    avionics_a: float = 0.3
    used_ah: float = 0.0
    used_wh: float = 0.0
    current_a: float = 0.0
    time_s: float | None = None

    @property
    def soc(self) -> float:
        return max(0.0, 1.0 - self.used_ah / self.capacity_ah)

    @property
    def voltage_v(self) -> float:
        rest_v = self.cells * (
            self.cell_empty_v + (self.cell_full_v - self.cell_empty_v) * self.soc
        )
        return rest_v - self.resistance_ohm * self.current_a

    def drive(self, time_s: float, pwm_us: list[int], armed: bool) -> None:
        """The motors at PX4's time ``time_s`` (s) get ``pwm_us``; the charge (and energy)
        since the last call is drawn at the previous current (and voltage)."""
        if self.time_s is not None and time_s > self.time_s:
            hours = (time_s - self.time_s) / 3600.0
            self.used_wh += self.voltage_v * self.current_a * hours
            self.used_ah += self.current_a * hours
        self.time_s = time_s
        throttle = [min(max((p - 1000) / 1000.0, 0.0), 1.0) for p in pwm_us] if armed else []
        power_w = sum(self.idle_w + self.full_w * u**1.5 for u in throttle)
        rest_v = self.voltage_v + self.resistance_ohm * self.current_a
        self.current_a = self.avionics_a + power_w / rest_v

    def status(self, mav: mavlink.MAVLink) -> mavlink.MAVLink_message:
        """BATTERY_STATUS id 0 of this pack (cell voltages mV, current cA, charge mAh).
        PX4 (v1.16) does not take its ``time_remaining``: it reads 0 s left, and its
        low-flight-time failsafe fires at take-off unless COM_FLTT_LOW_ACT is 0 (warn)."""
        cell_mv = round(1000 * self.voltage_v / self.cells)
        voltages = [cell_mv] * self.cells + [65535] * (10 - self.cells)
        return mav.battery_status_encode(
            0,
            mavlink.MAV_BATTERY_FUNCTION_ALL,
            mavlink.MAV_BATTERY_TYPE_LIPO,
            32767,
            voltages,
            round(100 * self.current_a),
            round(1000 * self.used_ah),
            -1,
            round(100 * self.soc),
        )


@dataclass
class Px4State:
    """What PX4 last said: its clock (s since boot), armed, landed state
    (MAV_LANDED_STATE), height over home (m), position (degE7), home altitude AMSL (m)."""

    boot_s: float = 0.0
    heartbeat: bool = False
    armed: bool = False
    landed_state: int = 0
    alt_m: float = 0.0
    lat_e7: int = 0
    lon_e7: int = 0
    home_alt_m: float | None = None
    gps_fix: int = 0
    acks: dict[int, int] = field(default_factory=dict)
    #: (PX4 time s, MAV_LANDED_STATE) at each change of the landed state.
    landed_changes: list[tuple[float, int]] = field(default_factory=list)
    #: The last MISSION_ACK to us (MAV_MISSION_RESULT) and the item PX4 last asked for.
    mission_ack: int | None = None
    mission_request: int | None = None
    #: PX4's time (s) RTL was commanded (None: not yet).
    rtl_s: float | None = None


class Px4Pilot(Receiver):
    """One MAVLink connection to a PX4 (MAV_SYS_ID ``system_id``) on its ground-station link
    (UDP ``gcs_port`` on 127.0.0.1); ``pack`` (when given) is fed to PX4 every
    ``pack_period_s`` of its clock."""

    def __init__(
        self,
        gcs_port: int,
        system_id: int,
        pack: MotorPack | None = None,
        pack_period_s: float = 0.2,
    ) -> None:
        super().__init__()
        self.conn: Any = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{gcs_port}", source_system=OWN_ID[0], source_component=OWN_ID[1]
        )
        self.system_id = system_id
        self.source = (system_id, mavlink.MAV_COMP_ID_AUTOPILOT1)
        self.quiet_s = 0.2
        self.stall_wall_s = STALL_WALL_S
        self.stall_text = f"PX4 sent nothing for {STALL_WALL_S:.0f} s (see px4.log)"
        self.state = Px4State()
        self.pack = pack
        self.pack_period_s = pack_period_s
        self._pack_mav = mavlink.MAVLink(
            None, srcSystem=system_id, srcComponent=mavlink.MAV_COMP_ID_BATTERY
        )
        self._pack_sent_s = -math.inf
        self._heartbeat_s = -math.inf
        self._heartbeat()  # PX4 answers once it has heard us

    def close(self) -> None:
        self.conn.close()

    # -- receiving ---------------------------------------------------------------------------

    def _quiet(self) -> None:
        if not self.state.heartbeat:
            self._heartbeat()  # PX4 answers once it has heard us

    def _update(self, msg: Any) -> None:
        s, kind = self.state, msg.get_type()
        boot_ms = getattr(msg, "time_boot_ms", None)
        if boot_ms is not None:
            s.boot_s = max(s.boot_s, boot_ms / 1000.0)
        if kind == "HEARTBEAT":
            s.heartbeat = True
            s.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        elif kind == "GLOBAL_POSITION_INT":
            s.alt_m, s.lat_e7, s.lon_e7 = msg.relative_alt / 1000.0, msg.lat, msg.lon
        elif kind == "HOME_POSITION":
            s.home_alt_m = msg.altitude / 1000.0
        elif kind == "GPS_RAW_INT":
            s.gps_fix = msg.fix_type
        elif kind == "EXTENDED_SYS_STATE" and msg.landed_state != s.landed_state:
            s.landed_state = msg.landed_state
            s.landed_changes.append((s.boot_s, msg.landed_state))
        elif kind == "COMMAND_ACK":
            s.acks[msg.command] = msg.result
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and self._to_us(msg):
            s.mission_request = msg.seq
        elif kind == "MISSION_ACK" and self._to_us(msg):
            s.mission_ack = msg.type
        elif kind == "SERVO_OUTPUT_RAW" and self.pack is not None:
            pwm = [msg.servo1_raw, msg.servo2_raw, msg.servo3_raw, msg.servo4_raw]
            self.pack.drive(msg.time_usec / 1e6, pwm, s.armed)
        if s.boot_s - self._heartbeat_s >= 1.0:
            self._heartbeat_s = s.boot_s
            self._heartbeat()
        if self.pack is not None and s.boot_s - self._pack_sent_s >= self.pack_period_s:
            self._pack_sent_s = s.boot_s
            self.conn.write(self.pack.status(self._pack_mav).pack(self._pack_mav))

    def _to_us(self, msg: Any) -> bool:
        return (msg.target_system, msg.target_component) == OWN_ID

    def _heartbeat(self) -> None:
        """Our HEARTBEAT (a ground station's), once a second of PX4's clock."""
        self.conn.mav.heartbeat_send(
            mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE
        )

    def _not_done_text(self, what: str, sim_timeout_s: float) -> str:
        return f"PX4: {what} not done in {sim_timeout_s:.0f} s of its clock"

    # -- commands ----------------------------------------------------------------------------

    def command(self, cmd: int, *params: float, sim_timeout_s: float = 5.0) -> int | None:
        """COMMAND_LONG to PX4; its COMMAND_ACK result, None without one in time."""
        acks = self.state.acks
        acks.pop(cmd, None)
        values = [*params, *[0.0] * (7 - len(params))]
        self.conn.mav.command_long_send(self.system_id, 1, cmd, 0, *values)
        deadline = self.state.boot_s + sim_timeout_s
        while cmd not in acks and self.state.boot_s < deadline:
            self.pump()
        return acks.get(cmd)

    def connect(self) -> None:
        """Until PX4's HEARTBEAT (then :data:`GCS_RATES_HZ` asked for), a 3-D GPS fix and
        home."""
        self.wait_for(lambda: self.state.heartbeat, 60.0, "first HEARTBEAT")
        for msg_id, rate_hz in GCS_RATES_HZ.items():
            interval_us = -1.0 if rate_hz < 0 else 1e6 / rate_hz
            self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, interval_us)
        s = self.state
        self.wait_for(lambda: s.gps_fix >= 3 and s.home_alt_m is not None, 60.0, "GPS and home")

    def arm(self) -> None:
        """Arm, retried each second of PX4's clock until accepted (30 s at most)."""
        deadline = self.state.boot_s + 30.0
        while self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) != mavlink.MAV_RESULT_ACCEPTED:
            if self.state.boot_s > deadline:
                raise UserError("PX4 refused to arm for 30 s (see px4.log)")
            self.hold(1.0)
        self.wait_for(lambda: self.state.armed, 5.0, "armed")

    def take_off(self, alt_m: float) -> None:
        """NAV_TAKEOFF to ``alt_m`` over home, until 95 % of it is reached."""
        assert self.state.home_alt_m is not None
        nan = math.nan
        amsl_m = self.state.home_alt_m + alt_m
        self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, amsl_m)
        self.wait_for(lambda: self.state.alt_m > 0.95 * alt_m, 60.0, "take-off")

    def reposition(self, north_m: float, east_m: float, alt_m: float) -> None:
        """DO_REPOSITION by (north, east) m at ``alt_m`` over home, until within 2 m."""
        s = self.state
        assert s.home_alt_m is not None
        lat0, lon0 = s.lat_e7 / 1e7, s.lon_e7 / 1e7
        cos_lat = math.cos(math.radians(lat0))
        lat = lat0 + north_m / M_PER_DEG_LAT
        lon = lon0 + east_m / (M_PER_DEG_LAT * cos_lat)
        self.conn.mav.command_int_send(
            self.system_id, 1, mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_CMD_DO_REPOSITION,
            0, 0, -1, 1, 0, math.nan, round(lat * 1e7), round(lon * 1e7), s.home_alt_m + alt_m,
        )  # fmt: skip

        def there() -> bool:
            dn = (s.lat_e7 / 1e7 - lat) * M_PER_DEG_LAT
            de = (s.lon_e7 / 1e7 - lon) * M_PER_DEG_LAT * cos_lat
            return math.hypot(dn, de) < 2.0

        self.wait_for(there, 90.0, "reposition")

    def set_mode(self, main: int, sub: int) -> int | None:
        """DO_SET_MODE to PX4's custom mode (main, sub); its COMMAND_ACK result."""
        flag = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, flag, main, sub)

    def velocity_leg(self, vn_mps: float, sim_s: float) -> None:
        """OFFBOARD at ``vn_mps`` north for ``sim_s`` s of PX4's clock, then HOLD."""
        last = [-math.inf]

        def setpoint() -> None:
            if self.state.boot_s - last[0] >= SETPOINT_PERIOD_S:
                last[0] = self.state.boot_s
                self.conn.mav.set_position_target_local_ned_send(
                    round(1000 * self.state.boot_s), self.system_id, 1,
                    mavlink.MAV_FRAME_LOCAL_NED, VELOCITY_MASK,
                    0, 0, 0, vn_mps, 0, 0, 0, 0, 0, 0, 0,
                )  # fmt: skip

        self.hold(0.5, setpoint)  # PX4 enters OFFBOARD only with setpoints flowing
        if self.set_mode(*OFFBOARD_MODE) != mavlink.MAV_RESULT_ACCEPTED:
            raise UserError("PX4 refused OFFBOARD")
        self.hold(sim_s, setpoint)
        self.set_mode(*HOLD_MODE)

    def upload_mission(self, items: Sequence[MissionItem]) -> None:
        """Upload ``items`` (their seq in order from 0; positions in degrees, sent as degE7)
        with the mission protocol: MISSION_COUNT, each MISSION_ITEM_INT PX4 asks for, until
        its MISSION_ACK; a UserError when PX4 refuses."""
        s = self.state
        s.mission_ack, s.mission_request = None, None
        mission_type = mavlink.MAV_MISSION_TYPE_MISSION
        self.conn.mav.mission_count_send(self.system_id, 1, len(items), mission_type)
        deadline = s.boot_s + 30.0
        while s.mission_ack is None:
            if s.boot_s > deadline:
                raise UserError("PX4: mission upload not acknowledged in 30 s of its clock")
            self.pump()
            if s.mission_request is not None and s.mission_request < len(items):
                self._send_item(items[s.mission_request])
            s.mission_request = None
        if s.mission_ack != mavlink.MAV_MISSION_ACCEPTED:
            raise UserError(f"PX4 refused the mission: MISSION_ACK {s.mission_ack}")

    def _send_item(self, item: MissionItem) -> None:
        positioned = not math.isnan(item.lat_deg)
        self.conn.mav.mission_item_int_send(
            self.system_id, 1, item.seq, item.frame, item.command, 0, 1, *item.params,
            round(item.lat_deg * 1e7) if positioned else 0,
            round(item.lon_deg * 1e7) if positioned else 0,
            item.alt_m, mavlink.MAV_MISSION_TYPE_MISSION,
        )  # fmt: skip

    def return_home(self) -> None:
        """AUTO.RTL (PX4's clock noted in ``state.rtl_s``), until PX4 disarms after landing."""
        self.state.rtl_s = self.state.boot_s
        if self.set_mode(*RTL_MODE) != mavlink.MAV_RESULT_ACCEPTED:
            raise UserError("PX4 refused RTL")
        self.wait_for(lambda: not self.state.armed, 300.0, "RTL")

    def land(self) -> None:
        """NAV_LAND, until PX4 disarms (it does on its own after touching down)."""
        nan = math.nan
        self.command(mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, nan, nan, nan, nan)
        self.wait_for(lambda: not self.state.armed, 90.0, "landing")

    def fly(
        self,
        alt_m: float = 10.0,
        hover_s: float = 10.0,
        leg_mps: float = 10.0,
        leg_s: float = 15.0,
        mission: Sequence[MissionItem] = (),
        rtl: bool = False,
        ground_s: float = 0.0,
    ) -> None:
        """The whole flight: ``mission`` uploaded (when given; not flown), ``ground_s`` of
        PX4's clock on the ground, take-off, hover, a reposition, an OFFBOARD leg (``leg_s``
        of PX4's clock), hold, land (or RTL with ``rtl``)."""
        self.connect()
        if mission:
            self.upload_mission(mission)
        self.hold(ground_s)
        self.arm()
        self.take_off(alt_m)
        self.hold(hover_s)
        self.reposition(60.0, 40.0, alt_m)
        self.velocity_leg(leg_mps, leg_s)
        self.hold(5.0)
        self.return_home() if rtl else self.land()
