"""What one sender's telemetry proves about it: a running ``time_boot_ms`` clock, and position,
attitude and battery readings that agree with each other over time.

:class:`SenderEvidence` takes a sender's messages one by one. A stamped frame counts as
evidence when its stamp agrees with one running clock (the decoder's
:class:`~estimator.telemetry.clock.AutopilotClock`: a stray stamp is skipped, a new
clock confirmed by its own frames starts the count again) and its values agree with the
sender's previous ones:

- ATTITUDE: roll and pitch within ±π, yaw within ±2π, all finite;
- GLOBAL_POSITION_INT: on the globe, and within reach of the previous position at
  :data:`MAX_SPEED_MPS` over the clock between them (plus :data:`POSITION_SLACK_M`);
  latitude/longitude 0/0 (no fix) says nothing;
- SYS_STATUS (no stamp of its own): the pack voltage within :data:`MAX_VOLTAGE_CHANGE` of
  the previous reading (an unknown voltage says nothing); a sender that reports its pack is
  believed once :data:`CONFIRM_BATTERY` readings agreed with their previous one.

A value that disagrees is not evidence (``counts['inconsistent']``); after
:data:`RESET_AFTER` disagreeing values in a row the newest becomes the reference (a real
change: a GPS glitch ending, a pack swapped on the bench).
"""

from __future__ import annotations

import math
from collections import Counter

from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.clock import AutopilotClock, ClockSettings, ClockVerdict

#: Stamped frames that agree with one clock before a sender is believed, and the autopilot
#: clock (s) they must span.
CONFIRM_FRAMES = 10
CONFIRM_S = 1.0
CONFIRM_BATTERY = 2
#: Fastest a multirotor moves between two positions (m/s), and the slack (m) of GPS noise.
MAX_SPEED_MPS = 200.0
POSITION_SLACK_M = 100.0
#: Largest relative change of the pack voltage between two readings of one sender.
MAX_VOLTAGE_CHANGE = 0.25
#: Disagreeing values of one kind in a row after which the newest is the reference.
RESET_AFTER = 3
#: Metres per degree of latitude (WGS84 mean).
M_PER_DEG = 111_320.0
UINT16_MAX = 65535


def frame_stamp_s(msg: mavlink.MAVLink_message) -> float | None:
    """The frame's ``time_boot_ms`` in s, None for a message without one (or our own
    NAMED_VALUE_FLOAT, whose stamp is the estimate's)."""
    stamp_ms = getattr(msg, "time_boot_ms", None)
    if stamp_ms is None or msg.get_type() == "NAMED_VALUE_FLOAT":
        return None
    return float(stamp_ms) / 1000.0


class SenderEvidence:
    """One sender's evidence; :attr:`confirmed` once it is believed (see the module)."""

    def __init__(self, settings: ClockSettings | None = None) -> None:
        self.clock = AutopilotClock(settings)
        self.frames = 0
        self.first_s = self.last_s = math.nan
        self.counts: Counter[str] = Counter()
        self._position: tuple[float, float, float] | None = None  # lat, lon (deg), clock s
        self._voltage_v: float | None = None
        self.battery_agreeing = 0
        self._misses: Counter[str] = Counter()  # disagreeing values in a row, by kind

    @property
    def confirmed(self) -> bool:
        battery = self._voltage_v is None or self.battery_agreeing >= CONFIRM_BATTERY
        return battery and self.frames >= CONFIRM_FRAMES and self.last_s - self.first_s >= CONFIRM_S

    def add(self, msg: mavlink.MAVLink_message) -> None:
        """Take one message of the sender."""
        kind = msg.get_type()
        if kind == "SYS_STATUS":
            self.battery_agreeing += self._battery_agrees(msg.voltage_battery)
            return
        time_s = frame_stamp_s(msg)
        if time_s is None or not self._values_agree(msg, time_s):
            return
        verdict = self.clock.check(time_s)
        if verdict is ClockVerdict.SKIP:
            return
        if verdict is ClockVerdict.ACCEPT:
            if self.frames == 0:
                self.first_s = time_s
            self.frames += 1
            self.last_s = max(self.last_s, time_s)
            return
        joined = self.clock.joined  # a new clock, confirmed by its own frames: count again
        assert joined is not None
        if verdict is not ClockVerdict.START:
            self.counts["clock_restarts"] += 1
        self.frames, self.first_s, self.last_s = joined.frames, joined.first_s, joined.last_s

    def _values_agree(self, msg: mavlink.MAVLink_message, time_s: float) -> bool:
        kind = msg.get_type()
        if kind == "ATTITUDE":
            angles = (msg.roll, msg.pitch, msg.yaw)
            ok = all(math.isfinite(a) for a in angles)
            ok = ok and abs(msg.roll) <= math.pi and abs(msg.pitch) <= math.pi
            return self._agrees("attitude", ok and abs(msg.yaw) <= 2 * math.pi)
        if kind == "GLOBAL_POSITION_INT" and (msg.lat, msg.lon) != (0, 0):
            lat, lon = msg.lat / 1e7, msg.lon / 1e7
            if not (abs(lat) <= 90.0 and abs(lon) <= 180.0):
                return self._agrees("position", False)
            previous, position = self._position, (lat, lon, time_s)
            if previous is None:
                self._position = position
                return True
            north_m = (lat - previous[0]) * M_PER_DEG
            east_m = (lon - previous[1]) * M_PER_DEG * math.cos(math.radians(lat))
            reach_m = MAX_SPEED_MPS * abs(time_s - previous[2]) + POSITION_SLACK_M
            ok = math.hypot(north_m, east_m) <= reach_m
            if ok or self._misses["position"] + 1 >= RESET_AFTER:
                self._position = position
            return self._agrees("position", ok)
        return True

    def _battery_agrees(self, voltage_mv: int) -> bool:
        if voltage_mv in (0, UINT16_MAX):
            return False
        voltage_v, previous = voltage_mv / 1000.0, self._voltage_v
        if previous is None:
            self._voltage_v = voltage_v
            return False  # the first reading: nothing to agree with yet
        ok = abs(voltage_v - previous) <= MAX_VOLTAGE_CHANGE * previous
        if ok or self._misses["battery"] + 1 >= RESET_AFTER:
            self._voltage_v = voltage_v
        return self._agrees("battery", ok)

    def _agrees(self, kind: str, ok: bool) -> bool:
        """Count a value of ``kind`` that agrees (True) or not."""
        if ok:
            self._misses[kind] = 0
        else:
            self._misses[kind] += 1
            self.counts["inconsistent"] += 1
        return ok
