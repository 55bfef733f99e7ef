"""MAVLink messages → typed telemetry samples, shared by the daemon and every log reader.

Messages (parsed from bytes by :mod:`estimator.telemetry.frames`) become
:mod:`estimator.telemetry.samples` samples:

- time is the autopilot's ``time_boot_ms``, judged by an
  :class:`~estimator.telemetry.clock.AutopilotClock` (a stamp far from the clock is skipped
  until several frames confirm a reboot or a gap); messages without a stamp (SYS_STATUS,
  BATTERY_STATUS, HEARTBEAT) take the latest believed autopilot time, so a replay and a live
  run of the same byte stream give the same samples;
- unknown-value sentinels (current −1 cA, and PX4's −1 A = −100 cA of a battery without a
  current sensor; voltage UINT16_MAX, cell voltage UINT16_MAX or 0, consumed −1, remaining −1)
  become ``None`` or drop the sample; without a measured current the consumed charge is
  ``None`` too (PX4 reports 0 mAh counted from no current); values beyond
  :class:`~estimator.telemetry.plausibility.InputLimits` (NaN, ±inf, 1e30, a current no pack gives)
  drop the frame, counted under the reason (the last voltage skipped as implausible is kept in
  :attr:`TelemetryDecoder.implausible_voltage`, so a vehicle file for another pack is named);
- the battery comes from BATTERY_STATUS (our ``battery_id``) once :data:`BATTERY_STATUS_CONFIRM`
  of them arrived, each within :data:`BATTERY_STATUS_TIMEOUT_S` of the last, else from
  SYS_STATUS — also again when BATTERY_STATUS stops for that long; an autopilot that numbers
  its only battery otherwise (PX4 republishes a battery fed to it over MAVLink as id 255)
  has that id taken as ours once :data:`BATTERY_STATUS_CONFIRM` of its frames came in a row
  and none of ours ever did (counted as ``battery_id_adopted``);
- a velocity that no multirotor reaches from the one before (a single 190 m/s frame) is an
  outlier, counted and skipped, until several agree
  (:class:`~estimator.telemetry.plausibility.VelocityJumps`, on the believed clock);
- the autopilot's wind estimate (ArduPilot WIND, id 168, outside the common dialect: its
  payload is read by hand; PX4 WIND_COV) becomes a :class:`WindSample`, implausible values
  (a direction or speed not finite, a direction beyond ±360°, faster than
  :data:`~estimator.telemetry.plausibility.MAX_WIND_MPS`) are counted and skipped;
- the position (GLOBAL_POSITION_INT latitude/longitude, whatever the velocity source) becomes a
  :class:`PositionSample`, the autopilot's home (HOME_POSITION) a :class:`HomeSample`, the
  mission item flown (MISSION_CURRENT) a :class:`MissionCurrentSample`; latitude/longitude
  0/0 (no fix, home not set) and values off the globe are counted and skipped;
- EXTENDED_SYS_STATE's landed state (PX4's landed detector) becomes a :class:`LandedSample`
  at each change (UNDEFINED is no sample);
- a Copter older than 3.6, named by its firmware STATUSTEXT ("APM:Copter V3.3 (…)") or its
  AUTOPILOT_VERSION, has its GLOBAL_POSITION_INT.vz taken as it was sent, positive up
  (:mod:`estimator.telemetry.firmware`), from then on; without either, from when the messages'
  own height has shown it (:mod:`estimator.telemetry.vz_sense`; judged anew after a reboot; an
  autopilot whose HEARTBEAT names another stack than ArduPilot, never);
- ArduPilot's gripper texts (STATUSTEXT "Gripper load released"/"grabbed", "Gripper
  Released"/"Grabbed" from a mission; :data:`GRIPPER_TEXT`) become a :class:`GripperSample`;
- only the selected autopilot is decoded (default: the first autopilot HEARTBEAT);
  our own component's messages and everyone else's are counted and skipped.

Every skip is counted in :attr:`TelemetryDecoder.counts` (see
:data:`~estimator.telemetry.skip_counters.SKIP_COUNTERS`).
"""

from __future__ import annotations

import math
import re
import struct
from collections import Counter
from collections.abc import Iterable

from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.clock import ClockFilter, ClockSettings, ClockVerdict
from estimator.telemetry.firmware import copter_vz_up, firmware_named
from estimator.telemetry.frames import frame_payload, frame_source
from estimator.telemetry.plausibility import (
    MAX_WIND_MPS,
    InputLimits,
    VelocityJumps,
    battery_problem,
    velocity_problem,
    wind_problem,
)
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    HomeSample,
    LandedSample,
    MissionCurrentSample,
    PositionSample,
    Sample,
    VelocitySample,
    WindSample,
)
from estimator.telemetry.vehicle_kind import COPTER_TYPES
from estimator.telemetry.vz_sense import VerticalSense

UINT16_MAX = 65535
#: Battery currents that mean "not measured" (cA): MAVLink's −1, and −1 A, which PX4 reports
#: for a battery without a current sensor (its simulated one included).
CURRENT_UNKNOWN_CA = frozenset({-1, -100})
#: BATTERY_STATUS frames in a row (each within the timeout) before they replace SYS_STATUS.
BATTERY_STATUS_CONFIRM = 3
#: Seconds of autopilot clock without BATTERY_STATUS after which SYS_STATUS is used again.
BATTERY_STATUS_TIMEOUT_S = 3.0
#: A position stamp this close (s) to the believed clock is taken when the velocity comes from
#: another message (LOCAL_POSITION_NED), so GLOBAL_POSITION_INT's stamp is not judged itself.
POSITION_STAMP_TOLERANCE_S = 1.0
#: Message types the decoder uses; every other type is skipped (and may be skipped unparsed).
USED_MESSAGE_IDS = frozenset(
    {
        mavlink.MAVLINK_MSG_ID_HEARTBEAT,
        mavlink.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,
        mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
        mavlink.MAVLINK_MSG_ID_ATTITUDE,
        mavlink.MAVLINK_MSG_ID_WIND_COV,
        mavlink.MAVLINK_MSG_ID_HOME_POSITION,
        mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
        mavlink.MAVLINK_MSG_ID_STATUSTEXT,
        mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
        mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
        168,  # ArduPilot WIND (ardupilotmega dialect)
    }
)
#: ArduPilot's WIND message: id, payload layout (direction the wind comes from in degrees,
#: speed m/s, vertical speed m/s; float32 little-endian).
ARDUPILOT_WIND_ID = 168
_ARDUPILOT_WIND = struct.Struct("<fff")
#: ArduPilot's texts for a finished gripper action (libraries/AP_Gripper, and the mission's
#: DO_GRIPPER in libraries/AP_Mission): group 1 is "released" or "grabbed".
GRIPPER_TEXT = re.compile(r"^gripper (?:load )?(released|grabbed)\b", re.IGNORECASE)
#: The velocity message types by id (the decoder uses the one of the first believed frame).
_VELOCITY_TYPES = {
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: "GLOBAL_POSITION_INT",
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: "LOCAL_POSITION_NED",
}
#: STATUSTEXTs kept from before the first autopilot HEARTBEAT (an autopilot's boot texts).
_EARLY_TEXTS = 16
_NOT_AUTOPILOTS = frozenset(
    {
        mavlink.MAV_TYPE_GCS,
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_TYPE_GIMBAL,
        mavlink.MAV_TYPE_ADSB,
        mavlink.MAV_TYPE_CAMERA,
    }
)


class TelemetryDecoder:
    """Turns the selected autopilot's messages into samples, with counters for what it skips.

    ``target`` is ``(system_id, component_id)`` of the autopilot, or ``None`` to lock onto the
    first autopilot HEARTBEAT. ``own`` is our own ``(system_id, component_id)``. ``limits``:
    the values believed (default: any multirotor's); ``clock``: the time checks.
    """

    def __init__(
        self,
        target: tuple[int, int] | None = None,
        own: tuple[int, int] = (1, mavlink.MAV_COMP_ID_ONBOARD_COMPUTER),
        battery_id: int = 0,
        limits: InputLimits | None = None,
        clock: ClockSettings | None = None,
    ) -> None:
        self.target = target
        self.own = own
        self.battery_id = battery_id
        self.limits = limits or InputLimits()
        self.counts: Counter[str] = Counter()
        # a new clock (a reboot, another autopilot) is found and announced by these
        self._time = ClockFilter(self.counts, clock)
        self._jumps = VelocityJumps(self.counts)
        self._start_autopilot()
        self._early_texts: list[mavlink.MAVLink_message] = []
        #: The message type and pack voltage (V) of the latest battery reading skipped as
        #: ``voltage_implausible``; None before the first.
        self.implausible_voltage: tuple[str, float] | None = None

    def _start_autopilot(self) -> None:
        """What the decoder learns of one autopilot's telemetry, as before its first message."""
        # BATTERY_STATUS of one other id in a row while none of ours has come (see above)
        self._own_battery_seen = False
        self._other_battery: tuple[int, int] | None = None  # (id, frames in a row)
        self._velocity_type: str | None = None
        self._last_velocity_s: float | None = None
        # BATTERY_STATUS in a row and the clock of the last one (SYS_STATUS fallback)
        self._battery_status_frames = 0
        self._battery_status_s = -math.inf
        self._armed: bool | None = None
        self._on_ground: bool | None = None
        #: Which way up GLOBAL_POSITION_INT.vz is sent (its firmware text or version, else
        #: its height), and the firmware version.
        self.vz_sense = VerticalSense()
        #: The first STATUSTEXT naming the firmware (:func:`firmware_named`), else None; the
        #: HEARTBEAT's ``type`` (MAV_TYPE), else None.
        self.firmware_text: str | None = None
        self.frame_type: int | None = None

    def retarget(self, target: tuple[int, int]) -> bool:
        """Decode the autopilot ``target`` (system, component) from now on; whether it is
        another autopilot than the one decoded so far. That one starts afresh: its velocity
        message type, battery id and which way up it sends vz are its own (a sign decided on
        the last one is not carried over). Its clock is judged as a new clock of the last
        one's (a reboot or a jump, so the pipeline moves to it); the counters go on."""
        other = target != self.target
        if other and self.target is not None:
            self._start_autopilot()
        self.target = target
        return other

    @property
    def clock_s(self) -> float | None:
        """Latest believed autopilot time (s since its boot), None before the first stamp."""
        return self._time.clock.time_s

    @property
    def velocity_type(self) -> str | None:
        """The message type velocity is taken from, None before the first one."""
        return self._velocity_type

    def flush(self) -> list[Sample]:
        """End of input (a log): samples still held for a stamp never confirmed."""
        out = self._time.flush()
        self._note_velocity(out)
        return self._jumps.filter(out)

    def discards(self, msgid: int, system: int, component: int) -> bool:
        """Whether :meth:`decode` would drop a message with this id from this source without
        reading it, so a log reader may skip its frame by the header: any message from another
        source once the autopilot is known, and a second velocity message type."""
        if self.target is not None and (system, component) != self.target:
            return True
        kind = _VELOCITY_TYPES.get(msgid)
        return kind is not None and self._velocity_type not in (None, kind)

    def decode_all(self, messages: Iterable[mavlink.MAVLink_message]) -> list[Sample]:
        """Decode several messages in order."""
        out: list[Sample] = []
        for msg in messages:
            out.extend(self.decode(msg))
        return out

    def decode(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        """Decode one message into zero or more samples."""
        source = message_source(msg)
        if source == self.own:
            self.counts["own"] += 1
            return []
        kind = msg.get_type()
        if self.target is None:
            if kind == "HEARTBEAT" and is_autopilot(msg):
                self.target = source
                for text in (t for t in self._early_texts if message_source(t) == source):
                    self._statustext(text)  # before any stamp: what it says of the firmware
                self._early_texts.clear()
            else:
                if kind == "STATUSTEXT" and len(self._early_texts) < _EARLY_TEXTS:
                    self._early_texts.append(msg)  # a firmware's boot text, before its HEARTBEAT
                self.counts["before_autopilot"] += 1
                return []
        if source != self.target:
            self.counts["other_source"] += 1
            return []
        if kind == f"UNKNOWN_{ARDUPILOT_WIND_ID}":
            kind = "WIND"
        handler = _HANDLERS.get(kind)
        if handler is None:
            self.counts["unused"] += 1
            return []
        self.counts[kind] += 1
        samples = handler(self, msg)
        return self._jumps.filter([*self._time.take_pending(), *samples])

    # -- clock -------------------------------------------------------------------------------

    def _stamp(
        self, time_s: float, sample: VelocitySample | None = None, kind: str | None = None
    ) -> list[Sample] | None:
        """Judge a frame's stamp (s) with the clock filter: None skips the frame (``sample``
        is held until the stamp is confirmed or refuted); else the samples to deliver before
        the frame's own. A re-referenced clock restarts what belongs to the old one."""
        out = self._time.stamped(time_s, sample, kind)
        verdict = self._time.verdict
        if out is not None and verdict in (ClockVerdict.REBOOT, ClockVerdict.JUMP):
            self._last_velocity_s = None
            self._battery_status_frames, self._battery_status_s = 0, -math.inf
            if verdict is ClockVerdict.REBOOT:
                self._armed = self._on_ground = None
                self.vz_sense.rebooted()
        self._note_velocity(out or [])
        return out

    def _note_velocity(self, released: list[Sample]) -> None:
        for sample in released:
            if isinstance(sample, VelocitySample):
                self._last_velocity_s = sample.time_s

    def _skip(self, reason: str) -> list[Sample]:
        self.counts[reason] += 1
        return []

    # -- handlers ----------------------------------------------------------------------------

    def _clock_s(self) -> float | None:
        """Time for a message without a stamp: the clock, or before it starts the stamp of the
        first frames (the sample is then held until they are confirmed)."""
        clock = self._time.clock
        if clock.time_s is None and clock.candidates:
            return max(clock.candidates, key=lambda c: c.frames).last_s
        return clock.time_s

    def _heartbeat(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        ardupilot = msg.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
        self.frame_type = int(msg.type)
        self.vz_sense.heartbeat(ardupilot, msg.type in COPTER_TYPES)
        armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        clock_s = self._clock_s()
        if clock_s is None or armed == self._armed:
            return []
        self._armed = armed
        return self._time.clocked(ArmedSample(clock_s, armed))

    def _extended_sys_state(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        state = msg.landed_state
        clock_s = self._clock_s()
        if clock_s is None or state == mavlink.MAV_LANDED_STATE_UNDEFINED:
            return []
        on_ground = state == mavlink.MAV_LANDED_STATE_ON_GROUND
        if on_ground == self._on_ground:
            return []
        self._on_ground = on_ground
        return self._time.clocked(LandedSample(clock_s, on_ground))

    def _attitude(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        return self._stamp(msg.time_boot_ms / 1000.0) or []

    def _velocity(
        self, msg: mavlink.MAVLink_message, v_ned: tuple[float, float, float], alt_m: float
    ) -> list[Sample]:
        kind = msg.get_type()
        if self._velocity_type not in (None, kind):
            return self._skip("duplicate_velocity_source")
        t = msg.time_boot_ms / 1000.0
        sample = VelocitySample(t, v_ned[0], v_ned[1], v_ned[2], alt_m)
        problem = velocity_problem(sample, self.limits)
        if problem is not None:
            return self._skip(problem)
        out = self._stamp(t, sample, kind)
        if out is None:
            return []
        if self._velocity_type is None:  # the source of the first believed velocity
            joined = self._time.clock.joined
            self._velocity_type = kind if joined is None or joined.tag is None else joined.tag
        if kind != self._velocity_type:
            self.counts["duplicate_velocity_source"] += 1
            return out
        if self._last_velocity_s is not None and t <= self._last_velocity_s:
            self.counts["out_of_order"] += 1
            return out
        self._last_velocity_s = t
        out.append(sample)
        return out

    def _global_position(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        alt_m = msg.relative_alt / 1000.0
        t = msg.time_boot_ms / 1000.0
        sense = self.vz_sense
        sense.observe(t, msg.vz / 100.0, alt_m)
        v = (msg.vx / 100.0, msg.vy / 100.0, sense.down_sign * msg.vz / 100.0)
        out = self._velocity(msg, v, alt_m)
        if self._velocity_type == "GLOBAL_POSITION_INT" or self._velocity_type is None:
            # the frame's stamp was judged with its velocity: its position goes with it
            if not any(isinstance(s, VelocitySample) and s.time_s == t for s in out):
                return out
        elif (
            (clock_s := self._time.clock.time_s) is None
            or abs(t - clock_s) > POSITION_STAMP_TOLERANCE_S
            or velocity_problem(VelocitySample(t, *v, alt_m), self.limits) is not None
        ):  # counted as duplicate_velocity_source: its stamp and values must be believable
            return out
        position = self._lat_lon(msg.lat, msg.lon, "position")
        if position is not None:
            sample = PositionSample(t, *position, alt_m)
            out.extend([sample] if out else self._time.clocked(sample))
        return out

    def _home_position(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        clock_s = self._clock_s()
        position = self._lat_lon(msg.latitude, msg.longitude, "home")
        if clock_s is None or position is None:
            return []
        alt_m = msg.altitude / 1000.0
        if not abs(alt_m) <= self.limits.max_abs_alt_m:
            return self._skip("home_implausible")
        return self._time.clocked(HomeSample(clock_s, *position, alt_m))

    def _mission_current(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        clock_s = self._clock_s()
        if clock_s is None:
            return []
        total = getattr(msg, "total", 0)
        sample = MissionCurrentSample(
            clock_s, int(msg.seq), None if total in (0, 0xFFFF) else total
        )
        return self._time.clocked(sample)

    def _statustext(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        text = str(msg.text)
        self.firmware_text = self.firmware_text or firmware_named(text)
        vz_up = copter_vz_up(text)
        if vz_up is not None:
            self.vz_sense.firmware(vz_up)
        released = gripper_released(text)
        clock_s = self._clock_s()
        if released is None or clock_s is None:
            return []
        return self._time.clocked(GripperSample(clock_s, released))

    def _autopilot_version(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        """AUTOPILOT_VERSION (the daemon asks for it; a ground station's log may hold it): an
        ArduCopter's version says which way up it sends vz, as its firmware text does."""
        self.vz_sense.version(int(msg.flight_sw_version))
        return []

    def _lat_lon(self, lat_e7: int, lon_e7: int, what: str) -> tuple[float, float] | None:
        """WGS84 degrees from MAVLink's degE7, or None (counted: ``<what>_unknown`` for the
        0/0 sentinel, ``<what>_implausible`` off the globe)."""
        if lat_e7 == 0 and lon_e7 == 0:
            self.counts[f"{what}_unknown"] += 1
            return None
        lat, lon = lat_e7 / 1e7, lon_e7 / 1e7
        if not (abs(lat) <= 90.0 and abs(lon) <= 180.0):
            self.counts[f"{what}_implausible"] += 1
            return None
        return lat, lon

    def _local_position(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        return self._velocity(msg, (msg.vx, msg.vy, msg.vz), -msg.z)

    def _sys_status(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        clock_s = self._time.clock.time_s
        if self._battery_status_frames >= BATTERY_STATUS_CONFIRM:
            if clock_s is not None and clock_s - self._battery_status_s <= BATTERY_STATUS_TIMEOUT_S:
                return []  # BATTERY_STATUS is flowing: it is the battery source
            self._battery_status_frames = 0
            self.counts["battery_status_stopped"] += 1
        voltage_mv = msg.voltage_battery
        if voltage_mv in (0, UINT16_MAX):
            self.counts["battery_voltage_unknown"] += 1
            return []
        sample = self._battery(
            "SYS_STATUS",
            voltage_mv / 1000.0,
            _current_a(msg.current_battery),
            None,
            _remaining_pct(msg.battery_remaining),
        )
        return [] if sample is None else self._time.clocked(sample)

    def _adopt_battery(self, battery_id: int) -> bool:
        """Whether ``battery_id`` (not ours) is the autopilot's only battery: none of ours
        came, and :data:`BATTERY_STATUS_CONFIRM` frames of this one did in a row; it is ours
        from then on."""
        if self._own_battery_seen:
            return False
        last_id, frames = self._other_battery or (battery_id, 0)
        frames = frames + 1 if last_id == battery_id else 1
        self._other_battery = (battery_id, frames)
        if frames < BATTERY_STATUS_CONFIRM:
            return False
        self.battery_id = battery_id
        self.counts["battery_id_adopted"] += 1
        return True

    def _battery_status(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        if msg.id == self.battery_id:
            self._own_battery_seen = True
        elif not self._adopt_battery(msg.id):
            self.counts["other_battery"] += 1
            return []
        cells_mv = list(msg.voltages) + list(getattr(msg, "voltages_ext", []) or [])
        known = [mv for mv in cells_mv if mv not in (0, UINT16_MAX)]
        if not known:
            self.counts["battery_voltage_unknown"] += 1
            return []
        current_a = _current_a(msg.current_battery)
        consumed = None
        if current_a is not None and msg.current_consumed != -1:
            consumed = float(msg.current_consumed)
        sample = self._battery(
            "BATTERY_STATUS",
            sum(known) / 1000.0,
            current_a,
            consumed,
            _remaining_pct(msg.battery_remaining),
        )
        if sample is None:
            return []
        if sample.time_s - self._battery_status_s > BATTERY_STATUS_TIMEOUT_S:
            self._battery_status_frames = 0
        self._battery_status_frames += 1
        self._battery_status_s = sample.time_s
        if self._battery_status_frames < BATTERY_STATUS_CONFIRM:
            self.counts["battery_status_unconfirmed"] += 1
            return []
        return self._time.clocked(sample)

    def _ardupilot_wind(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        if hasattr(msg, "direction"):  # decoded by a dialect that knows WIND
            direction_deg, speed_mps = float(msg.direction), float(msg.speed)
        else:
            payload = frame_payload(bytes(msg.get_msgbuf()))
            direction_deg, speed_mps, _ = _ARDUPILOT_WIND.unpack(
                payload[: _ARDUPILOT_WIND.size].ljust(_ARDUPILOT_WIND.size, b"\0")
            )
        if not (abs(direction_deg) <= 360.0 and 0.0 <= speed_mps <= MAX_WIND_MPS):
            return self._skip("wind_implausible")  # NaN fails every comparison
        rad = math.radians(direction_deg)
        return self._wind(-speed_mps * math.cos(rad), -speed_mps * math.sin(rad))

    def _wind_cov(self, msg: mavlink.MAVLink_message) -> list[Sample]:
        # time_usec may be boot or Unix time: the latest autopilot clock stamps it
        return self._wind(float(msg.wind_x), float(msg.wind_y))

    def _wind(self, wind_n_mps: float, wind_e_mps: float) -> list[Sample]:
        clock_s = self._clock_s()
        if clock_s is None:
            self.counts["wind_before_clock"] += 1
            return []
        sample = WindSample(clock_s, wind_n_mps, wind_e_mps)
        if (problem := wind_problem(sample)) is not None:
            return self._skip(problem)
        return self._time.clocked(sample)

    def _battery(
        self,
        kind: str,
        voltage_v: float,
        current_a: float | None,
        consumed_mah: float | None,
        remaining_pct: float | None,
    ) -> BatterySample | None:
        """A pack reading of a ``kind`` message on the clock, or None when there is no clock
        yet or it is not plausible (counted)."""
        clock_s = self._clock_s()
        if clock_s is None:
            self.counts["battery_before_clock"] += 1
            return None
        sample = BatterySample(clock_s, voltage_v, current_a, consumed_mah, remaining_pct)
        problem = battery_problem(sample, self.limits)
        if problem is not None:
            self.counts[problem] += 1
            if problem == "voltage_implausible":
                self.implausible_voltage = (kind, voltage_v)
            return None
        return sample


def gripper_released(text: str) -> bool | None:
    """True for ArduPilot's text of a finished gripper release, False for a grab, else None."""
    match = GRIPPER_TEXT.match(text)
    return None if match is None else match.group(1).lower() == "released"


def is_autopilot(msg: mavlink.MAVLink_message) -> bool:
    """A HEARTBEAT of an autopilot (not MAV_AUTOPILOT_INVALID) of a vehicle type (not a
    ground station, companion computer, gimbal, ADS-B receiver or camera)."""
    return bool(msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID and msg.type not in _NOT_AUTOPILOTS)


def message_source(msg: mavlink.MAVLink_message) -> tuple[int, int]:
    """(system, component) that sent ``msg`` (also for a message of an unknown type, whose
    header pymavlink leaves unset)."""
    if isinstance(msg, mavlink.MAVLink_unknown):
        return frame_source(bytes(msg.get_msgbuf()))
    return msg.get_srcSystem(), msg.get_srcComponent()


def _current_a(centiamps: int) -> float | None:
    """A battery current in A from MAVLink's cA, None when not measured."""
    return None if centiamps in CURRENT_UNKNOWN_CA else centiamps / 100.0


def _remaining_pct(pct: int) -> float | None:
    return None if pct < 0 else float(pct)


_HANDLERS = {
    "HEARTBEAT": TelemetryDecoder._heartbeat,
    "EXTENDED_SYS_STATE": TelemetryDecoder._extended_sys_state,
    "ATTITUDE": TelemetryDecoder._attitude,
    "GLOBAL_POSITION_INT": TelemetryDecoder._global_position,
    "LOCAL_POSITION_NED": TelemetryDecoder._local_position,
    "SYS_STATUS": TelemetryDecoder._sys_status,
    "BATTERY_STATUS": TelemetryDecoder._battery_status,
    "WIND": TelemetryDecoder._ardupilot_wind,
    "WIND_COV": TelemetryDecoder._wind_cov,
    "HOME_POSITION": TelemetryDecoder._home_position,
    "MISSION_CURRENT": TelemetryDecoder._mission_current,
    "STATUSTEXT": TelemetryDecoder._statustext,
    "AUTOPILOT_VERSION": TelemetryDecoder._autopilot_version,
}
