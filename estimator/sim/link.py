"""Live playback of a simulated flight over a MAVLink link, in (sped-up) real time.

The messages of a :class:`~estimator.sim.run.SimRun` are sent at their autopilot times divided
by ``speedup`` (``time_boot_ms`` stays on the simulated clock), as system 1 component 1.
Requests from the other side are answered while playing:

- ``REQUEST_DATA_STREAM``: ArduPilot's stream groups (POSITION → GLOBAL_POSITION_INT and
  LOCAL_POSITION_NED, EXTRA1 → ATTITUDE, EXTRA2 → VFR_HUD, EXTENDED_STATUS → SYS_STATUS,
  EXTRA3 → BATTERY_STATUS, ALL → every one) at the requested rate, or off;
- ``COMMAND_LONG`` ``MAV_CMD_SET_MESSAGE_INTERVAL`` (interval µs; 0 = default, −1 = off),
  acknowledged with ``COMMAND_ACK``;
- ``COMMAND_LONG`` ``MAV_CMD_REQUEST_MESSAGE`` for HOME_POSITION: the run's home (the
  take-off point), acknowledged;
- ``COMMAND_LONG`` ``MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES``: AUTOPILOT_VERSION with
  :data:`FIRMWARE_VERSION`, acknowledged.

Rates are honoured by decimation of the simulated streams: a stream can be slowed down or
switched off, not sped up beyond the rate it was simulated at (``SimConfig.rates_hz``).
HEARTBEAT always goes out at its simulated rate, as ArduPilot's does.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
from collections import Counter
from collections.abc import Callable
from typing import BinaryIO

from pymavlink.dialects.v20 import common as mavlink

from estimator.mavlink.link import MavlinkLink
from estimator.sim.files import TLOG_EPOCH_S
from estimator.sim.run import SimRun
from estimator.telemetry.firmware import flight_sw_version

#: ArduPilot's REQUEST_DATA_STREAM groups, restricted to what the simulator sends.
STREAM_GROUPS: dict[int, tuple[str, ...]] = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: ("SYS_STATUS",),
    mavlink.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    mavlink.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    mavlink.MAV_DATA_STREAM_EXTRA2: ("VFR_HUD",),
    mavlink.MAV_DATA_STREAM_EXTRA3: ("BATTERY_STATUS",),
}
_SYSTEM_ID, _COMPONENT_ID = 1, 1
#: The ArduCopter release whose MAVLink conventions the simulator follows (major, minor, patch):
#: GLOBAL_POSITION_INT.vz positive down, as every Copter since 3.6 sends it. Its HEARTBEAT
#: names ArduPilot and a quadrotor, so a peer reads its vz by this version.
FIRMWARE_VERSION = (4, 5, 0)


class SimPlayer:
    """Plays ``run`` on ``link`` (opened with source system 1, component 1)."""

    def __init__(
        self,
        run: SimRun,
        link: MavlinkLink,
        speedup: float = 1.0,
        tlog: BinaryIO | None = None,
        on_progress: Callable[[float], None] | None = None,
    ) -> None:
        if speedup <= 0:
            raise ValueError("speedup must be > 0")
        self.run, self.link, self.speedup, self.tlog = run, link, speedup, tlog
        self.on_progress = on_progress
        self.simulated_hz = {name: float(hz) for name, hz in run.config.rates_hz.items()}
        #: Current rate per message name (Hz), changed by the peer's requests.
        self.rates_hz = dict(self.simulated_hz)
        self._last_sent: dict[str, float] = {}
        self._now_s: float | None = None  # simulated time of the last message sent
        self.counts: Counter[str] = Counter()

    # -- requests -----------------------------------------------------------------------------

    def handle(self, msg: mavlink.MAVLink_message) -> None:
        """Apply one received message (the requests of the module docstring; everything else
        is ignored)."""
        kind = msg.get_type()
        if kind == "REQUEST_DATA_STREAM" and self._for_us(msg):
            names = (
                tuple(n for group in STREAM_GROUPS.values() for n in group)
                if msg.req_stream_id == mavlink.MAV_DATA_STREAM_ALL
                else STREAM_GROUPS.get(msg.req_stream_id, ())
            )
            for name in names:
                self._set_rate(name, float(msg.req_message_rate) if msg.start_stop else 0.0)
            self.counts["request_data_stream"] += 1
        elif (
            kind == "COMMAND_LONG"
            and self._for_us(msg)
            and msg.command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
        ):
            self._set_interval(msg)
        elif (
            kind == "COMMAND_LONG"
            and self._for_us(msg)
            and msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE
            and int(msg.param1) == mavlink.MAVLINK_MSG_ID_HOME_POSITION
        ):
            self._send_home(msg)
        elif (
            kind == "COMMAND_LONG"
            and self._for_us(msg)
            and msg.command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES
        ):
            self._send_version(msg)

    def _ack(self, msg: mavlink.MAVLink_message, result: int = mavlink.MAV_RESULT_ACCEPTED) -> None:
        """COMMAND_ACK of the command ``msg`` (its ``result``, a MAV_RESULT) to its sender."""
        ack = self.link.mav.command_ack_encode(
            msg.command,
            result,
            0,
            0,
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        )
        self._send(ack, None)

    def _send_version(self, msg: mavlink.MAVLink_message) -> None:
        """AUTOPILOT_VERSION (:data:`FIRMWARE_VERSION`, MAVLink 2) and the COMMAND_ACK of its
        request."""
        self.counts["version_requests"] += 1
        version = self.link.mav.autopilot_version_encode(
            mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2,
            flight_sw_version(FIRMWARE_VERSION, mavlink.FIRMWARE_VERSION_TYPE_OFFICIAL),
            0,
            0,
            0,
            [0] * 8,
            [0] * 8,
            [0] * 8,
            0,
            0,
            0,
        )
        self._send(version, self._now_s)  # in the tlog too, as the home
        self._ack(msg)

    def _send_home(self, msg: mavlink.MAVLink_message) -> None:
        """HOME_POSITION (the run's home, local origin) and the COMMAND_ACK of its request."""
        c = self.run.config
        self.counts["home_requests"] += 1
        mav = self.link.mav
        home = mav.home_position_encode(
            round(c.home_lat_deg * 1e7),
            round(c.home_lon_deg * 1e7),
            round(c.home_msl_m * 1000),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
        )
        self._send(home, self._now_s)  # in the tlog too: a replay sees the home the peer saw
        self._ack(msg)

    def _for_us(self, msg: mavlink.MAVLink_message) -> bool:
        return msg.target_system in (0, _SYSTEM_ID) and msg.target_component in (0, _COMPONENT_ID)

    def _set_rate(self, name: str, hz: float) -> None:
        if name in self.simulated_hz:
            self.rates_hz[name] = max(0.0, hz)

    def _set_interval(self, msg: mavlink.MAVLink_message) -> None:
        entry = mavlink.mavlink_map.get(int(msg.param1))
        name = entry.msgname if entry is not None else None
        interval_us = msg.param2
        if name is None or name not in self.simulated_hz or name == "HEARTBEAT":
            result = mavlink.MAV_RESULT_DENIED
        else:
            if interval_us == 0:
                hz = self.simulated_hz[name]
            elif interval_us < 0:
                hz = 0.0
            else:
                hz = 1e6 / interval_us
            self._set_rate(name, hz)
            result = mavlink.MAV_RESULT_ACCEPTED
        self.counts["set_message_interval"] += 1
        self._ack(msg, result)

    async def _serve_requests(self) -> None:
        while True:
            received = await self.link.recv()
            if not received:
                return
            for msg in received:
                self.handle(msg)

    # -- playback -----------------------------------------------------------------------------

    def _due(self, name: str, time_s: float) -> bool:
        """Decimation: send when at least one requested period has passed (half a simulated
        period of tolerance, so a rate equal to the simulated one keeps every message)."""
        hz = self.rates_hz.get(name, 0.0)
        if name == "HEARTBEAT":
            return True
        if hz <= 0:
            return False
        last = self._last_sent.get(name)
        slack = 0.5 / self.simulated_hz[name]
        return last is None or time_s - last >= 1.0 / hz - slack

    def _send(self, msg: mavlink.MAVLink_message, time_s: float | None) -> None:
        frame = msg.pack(self.link.mav)
        self.link.send_bytes(frame)
        if self.tlog is not None and time_s is not None:
            self.tlog.write(struct.pack(">Q", round((TLOG_EPOCH_S + time_s) * 1e6)) + frame)

    async def play(self) -> int:
        """Send every due message at its (sped-up) time; returns how many were sent."""
        loop = asyncio.get_running_loop()
        server = asyncio.create_task(self._serve_requests())
        try:
            start_wall = loop.time()
            start_sim = self.run.messages[0][0] if self.run.messages else 0.0
            for time_s, msg in self.run.messages:
                delay = start_wall + (time_s - start_sim) / self.speedup - loop.time()
                if delay > 0:
                    await asyncio.sleep(delay)
                    if self.on_progress is not None:
                        self.on_progress(time_s)
                name = msg.get_type()
                if not self._due(name, time_s):
                    self.counts["decimated"] += 1
                    continue
                self._last_sent[name] = time_s
                self._now_s = time_s
                self._send(msg, time_s)
                self.counts["sent"] += 1
            # let the last datagrams leave before the caller closes the link
            await asyncio.sleep(0)
        finally:
            server.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await server
        return self.counts["sent"]
