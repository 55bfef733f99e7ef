"""The onboard daemon: autopilot link in, :class:`Pipeline`, estimates out (asyncio, one thread).

Messages are handled in the link's receive callback as their datagram arrives (decode →
pipeline → JSON lines; no queue, no task switch); frames of ids the decoder does not use are
dropped by their header before pymavlink parses them; the estimates go out through
:class:`~estimator.mavlink.outlet.EstimateOutlet`. Tasks: publish (NAMED_VALUE_FLOAT and
BATTERY_STATUS at the configured rate), heartbeat + watchdog (1 Hz: our HEARTBEAT, stale
detection, stream requests until telemetry flows, counters of bad input), and a drain per
output link. Wall clock is used only for these timers; the estimates run on the autopilot's
clock.
The autopilot is chosen by :class:`~estimator.mavlink.autopilot_lock.AutopilotLock`
(the sender, at its address, whose own telemetry proves it; with the configured ids when
set); a ``udpin`` link answers nobody before and then only the address it speaks from.
Links sign and check frames when a signing key is configured
(:mod:`estimator.mavlink.signing`). With a state file (:mod:`estimator.mavlink.state_file`)
the flight state is written every ``state_period_s`` and on exit, and a restarted daemon
continues from it when it fits the autopilot's boot.

Return home and mission (:mod:`estimator.estimation.return_home` computes them in the pipeline):
HOME_POSITION is requested (MAV_CMD_REQUEST_MESSAGE) while positions come without it
(:class:`~estimator.mavlink.streams.HomeRequest`); the mission is read
(:mod:`estimator.mavlink.mission_download`) and handed to the pipeline as a
:class:`MissionSample`; margin crossings become STATUSTEXT
(:mod:`estimator.mavlink.margin_alerts`) on the ``--publish`` links.
A pack voltage the vehicle file's cell count cannot be, before any estimate, that is a pack
above its reserve for exactly one other count: the daemon takes that count, once a run
(:meth:`Service._infer_cells`); otherwise no reading is believed and one line says which
counts the voltage fits.
The pack flown (:mod:`estimator.estimation.pack_identity`): with ``[pack] dir``, the configured
``[pack] id``, else the serial number of the autopilot's SMART_BATTERY_INFO for the decoded
battery (asked for once with each stream request, MAV_CMD_REQUEST_MESSAGE), names the pack
whose memory starts the pack filter and receives what it learns (every
:data:`PACK_MEMORY_PERIOD_S` and at the end).
One log line per event: autopilot found, streams requested, energy initialized (with a
warning when the pack voltage does not fit the vehicle file's cell count), model-only mode,
a pack voltage that does not follow the load (a warning), or not the charge drawn (a
warning: the energy is counted against the label),
reboot or clock jump, link silent (stale) / resumed, bad frames, floods and input skipped as
implausible (at most one line per 10 s each), a pack voltage no reading of which is believed
(the cell counts it fits against the vehicle file's; also as STATUSTEXT), a failed mission
download (once per cause; the repeats counted in one line when the daemon stops). Reboots are
throttled: stream requests go out at most once per :data:`REQUEST_RETRY_S`, however often the
clock is re-referenced. A PX4 autopilot (its HEARTBEAT says so) is asked for its message
rates with MAV_CMD_SET_MESSAGE_INTERVAL only (:mod:`estimator.mavlink.streams`).
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import signal
import time
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.pack_identity import FlightPack
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.estimation.return_home import MissionEnergyFn, MissionSample
from estimator.estimation.rtl_profiles import rtl_settings
from estimator.logs.mission_files import MissionItem
from estimator.mavlink.autopilot_lock import AutopilotLock, Source
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.daemon_warnings import ThrottledLog, format_counts, warn_input_counts
from estimator.mavlink.link import MavlinkLink, open_link
from estimator.mavlink.mission_download import MESSAGE_IDS as MISSION_MESSAGE_IDS
from estimator.mavlink.mission_download import MESSAGE_TYPES as MISSION_MESSAGES
from estimator.mavlink.mission_download import MissionDownload
from estimator.mavlink.outlet import EstimateOutlet
from estimator.mavlink.pack_cells import inferred_cells, pack_mismatch_text
from estimator.mavlink.signing import LinkSigning, load_key
from estimator.mavlink.state_file import StateKeeper
from estimator.mavlink.streams import (
    HomeRequest,
    ardupilot_requests,
    px4_requests,
    request_message,
    version_request,
)
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.decode import (
    USED_MESSAGE_IDS,
    TelemetryDecoder,
    message_source,
)
from estimator.telemetry.plausibility import pack_voltage_problem
from estimator.telemetry.samples import BatterySample, LandedSample
from estimator.telemetry.vehicle_kind import frame_note

log = logging.getLogger("uav_energy.service")

OWN_COMPONENT = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER
#: Seconds between stream requests while telemetry is missing.
REQUEST_RETRY_S = 5.0
#: Seconds between "bad input" log lines.
COUNTER_LOG_S = 10.0
#: Seconds between repeats of the line naming a pack voltage that fits no reading of the
#: vehicle file's cells (the first comes at once).
PACK_MISMATCH_LOG_S = 60.0
#: Seconds (event loop) between writes of the pack's memory (and one at the end).
PACK_MEMORY_PERIOD_S = 30.0
#: SMART_BATTERY_INFO: its serial number names the pack when none is configured.
PACK_INFO_ID = mavlink.MAVLINK_MSG_ID_SMART_BATTERY_INFO


class Service:
    """One daemon instance. ``await run(stop)`` until ``stop`` is set (or a signal arrives)."""

    def __init__(
        self,
        config: ServiceConfig,
        vehicle: Vehicle,
        settings: PipelineSettings | None = None,
        mission_energy: MissionEnergyFn | None = None,
    ) -> None:
        self.config = config
        target = None
        if config.target_system:
            target = (config.target_system, config.target_component or 1)
        self.decoder = TelemetryDecoder(target=target, own=(config.system_id, OWN_COMPONENT))
        self._rtl = "ardupilot"  # whose RTL the return figures follow
        self.state: StateKeeper | None = None
        self._mission_energy = mission_energy
        self.out = EstimateOutlet(config)
        self._use_vehicle(vehicle, settings or config.pipeline_settings())
        if config.return_autopilot != "auto":
            self._follow_rtl(config.return_autopilot)
        self._cells_checked = False  # a pack voltage of other cells looked at (once a run)
        self._vz_note_said: str | None = None
        self._version_said: tuple[int, int, int] | None = None
        self._frame_said: Source | None = None  # the autopilot told it flies no multirotor
        self.lock = AutopilotLock(target, (config.system_id, OWN_COMPONENT))
        self.internal_errors = 0
        self.link: MavlinkLink | None = None
        self._last_rx_s: float | None = None
        self._last_request_s = -1e9
        self._streams_ok = False
        self._model_only_said: bool | None = None  # the estimating mode last logged
        self._dead_voltage_said = False  # a voltage that does not follow the load, logged
        self._refuted_pack_said = False  # a voltage that does not follow the charge, logged
        self._throttled = ThrottledLog(log, COUNTER_LOG_S)
        self.mission: MissionDownload | None = None
        self._home_first = True  # ArduPilot's mission item 0 is home; PX4's is not
        self._px4 = False  # the locked autopilot's HEARTBEAT says PX4: intervals, no streams
        self.home_request = HomeRequest()

    def _use_vehicle(self, vehicle: Vehicle, settings: PipelineSettings) -> None:
        """The pipeline for ``vehicle`` and what rests on it: the RTL followed, the pack's
        memory (this run is one flight: its row of the pack's history starts now), the
        decoder's limits, the state file, the full pack's usable energy and the alerts."""
        cfg = self.config
        self.pipeline = Pipeline(vehicle, settings, self._mission_energy)
        self.pipeline.returning.settings = rtl_settings(self._rtl, settings.return_home)
        pack_dir = Path(cfg.pack_dir) if cfg.pack_dir else None
        self.flight_pack = FlightPack(self.pipeline, pack_dir, cfg.pack_id or None, time.time())
        if (prior := self.pipeline.pack_prior) is not None:
            log.info("pack %s: its memory says %.2f Ah", cfg.pack_id, prior.capacity_ah)
        self.decoder.limits = vehicle.input_limits()
        if self.state is not None:
            self.state.attach(self.pipeline)
        elif cfg.state_file:
            self.state = StateKeeper(
                cfg.state_file, cfg.state_max_age_s, cfg.state_period_s, self.pipeline
            )
        self.out.use_pack(self.pipeline)

    def _infer_cells(self) -> None:
        """Before any estimate, the first pack voltage the vehicle file's cell count cannot
        be: when it is a pack above its reserve for exactly one other count
        (:meth:`Vehicle.flyable_cells`), the daemon takes that count (one warning, and a
        STATUSTEXT on the ``--publish`` links); otherwise every reading stays skipped and the
        mismatch line says which counts it fits. Once a run: a later reading, forged or not,
        never changes the pack again."""
        if self._cells_checked or self.decoder.implausible_voltage is None:
            return
        self._cells_checked = True
        inferred = inferred_cells(self.decoder, self.pipeline.vehicle)
        if inferred is None or self.pipeline.energy.initialized:
            return
        vehicle, line, text = inferred
        log.warning("%s", line)
        self._use_vehicle(vehicle, self.pipeline.settings)
        self.decoder.implausible_voltage = None
        self.out.statustext(mavlink.MAV_SEVERITY_WARNING, text)  # never towards the autopilot

    # -- lifecycle --------------------------------------------------------------------------

    async def run(self, stop: asyncio.Event | None = None) -> int:
        """Open the links, run until ``stop`` (or SIGINT/SIGTERM), close everything."""
        stop = stop or asyncio.Event()
        loop = asyncio.get_running_loop()
        installed = []
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, stop.set)
                installed.append(sig)
        cfg = self.config
        key = load_key(cfg.signing_key_file) if cfg.signing_key_file else None

        def signing(link_id: int) -> LinkSigning | None:
            return None if key is None else LinkSigning(key, link_id, cfg.require_signing)

        self.link = await open_link(
            cfg.connect,
            source_system=cfg.system_id,
            message_ids=USED_MESSAGE_IDS | MISSION_MESSAGE_IDS | {PACK_INFO_ID},
            signing=signing(0),
        )
        self.out.autopilot = self.link
        self.link.answer_only(None)  # a shared link answers nobody until an autopilot is locked
        if self.state is not None:
            self.state.load()
        try:
            for i, url in enumerate(cfg.publish, start=1):
                self.out.outputs.append(
                    await open_link(
                        url, source_system=cfg.system_id, signing=signing(i), listen=False
                    )
                )
            await self.out.json.open()
            log.info(
                "started: autopilot link %s, %d output(s), vehicle %s, signing %s",
                cfg.connect,
                len(self.out.outputs),
                self.pipeline.vehicle.name,
                "off" if key is None else "required" if cfg.require_signing else "on",
            )
            self.link.set_listener(self._on_messages)
            gc.freeze()  # start-up objects (modules, codecs) leave the collector's scans
            tasks = [
                loop.create_task(self.out.publish_loop()),
                loop.create_task(self._heartbeat_loop()),
                *(loop.create_task(_drain(out)) for out in self.out.outputs),
            ]
            if self.state is not None:
                tasks.append(loop.create_task(self.state.run(lambda: self.decoder.target)))
            if self.flight_pack.directory is not None:
                tasks.append(loop.create_task(self._pack_memory_loop()))
            await stop.wait()
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError):
                    await task
            if (last := self.pipeline.flush()) is not None:  # the samples of the open period
                self.out.deliver(last, loop.time())
            if self.state is not None:
                self.state.save(self.decoder.target)
            self._remember_pack()
            if (note := self.flight_pack.unnamed()) is not None:
                log.info("pack memory: %s", note)
        finally:
            for link in [self.link, *self.out.outputs]:
                await link.close()
            self.out.json.close()
            for sig in installed:
                loop.remove_signal_handler(sig)
        if self.mission is not None:
            for line in self.mission.warned.repeats("download attempts"):
                log.warning(line)
        log.info("stopped: %s", format_counts(self.counters()))
        return 0

    def counters(self) -> dict[str, int]:
        """Everything counted so far: link, decoder and pipeline counters."""
        out: dict[str, int] = {}
        if self.link is not None:
            out.update({f"link_{k}": v for k, v in self.link.counts.items()})
            if self.link.signing is not None:
                out.update({f"signing_{k}": v for k, v in self.link.signing.rejected.items()})
        out.update({f"autopilot_{k}": v for k, v in self.lock.counts.items()})
        out.update({f"decode_{k}": v for k, v in self.decoder.counts.items()})
        out.update({f"pipeline_{k}": v for k, v in self.pipeline.counts.items()})
        if self.mission is not None:
            out.update({f"mission_{k}": v for k, v in self.mission.counts.items()})
        out.update(internal_errors=self.internal_errors, json_dropped=self.out.json.dropped)
        if self.state is not None:
            out.update(state_writes=self.state.writes, state_write_errors=self.state.write_errors)
        out.update(home_requests=self.home_request.sent, alerts_sent=self.out.alerts.sent)
        out.update(pack_alerts_sent=self.out.pack_alert.sent)
        if self.flight_pack.directory is not None:
            out.update(pack_memory_errors=self.flight_pack.errors)
        return out

    # -- the pack's memory -------------------------------------------------------------------

    async def _pack_memory_loop(self) -> None:
        """Store what the pack was learnt to hold every :data:`PACK_MEMORY_PERIOD_S`."""
        while True:
            await asyncio.sleep(PACK_MEMORY_PERIOD_S)
            self._remember_pack()

    def _remember_pack(self) -> None:
        if (note := self.flight_pack.remember()) is not None:
            log.warning("%s", note)

    def _pack_info(self, msg: mavlink.MAVLink_message) -> None:
        """SMART_BATTERY_INFO of the autopilot's battery (the one decoded): its serial number
        may name the pack (:class:`FlightPack`)."""
        if message_source(msg) != self.decoder.target or msg.id != self.decoder.battery_id:
            return
        if (note := self.flight_pack.reported(str(msg.serial_number))) is not None:
            log.info("%s", note)

    # -- receive ----------------------------------------------------------------------------

    def _on_messages(self, messages: list[mavlink.MAVLink_message]) -> None:
        """Link listener: handle each message as its datagram arrives."""
        now_s = asyncio.get_running_loop().time()
        assert self.link is not None
        peer = self.link.peer
        lock = self.lock
        for received in messages:
            before = (lock.locked, lock.peer)
            admitted = lock.admit(received, now_s, peer)
            if (lock.locked, lock.peer) != before:
                self._note_autopilot(admitted)
                self._autopilot_changed(now_s)
            self._handle_each(admitted, now_s)

    def _handle_each(self, messages: list[mavlink.MAVLink_message], now_s: float) -> None:
        for msg in messages:
            try:
                self._handle(msg, now_s)
            except Exception as exc:  # never die on one message: log it, count, go on
                self.internal_errors += 1
                if self.internal_errors <= 10 or self.internal_errors % 1000 == 0:
                    log.error(
                        "internal error #%d on %s skipped: %r",
                        self.internal_errors,
                        msg.get_type(),
                        exc,
                    )

    def _say_vertical_sense(self) -> None:
        """Once per autopilot: its firmware version when it tells it (and which way up its vz
        is read); and each time its height turns the sign over (vz found sent positive up,
        or after a reboot positive down again)."""
        decoder = self.decoder
        version = decoder.vz_sense.firmware_version
        if version is not None and version != self._version_said:
            self._version_said = version
            up = "up" if decoder.vz_sense.down_sign < 0 else "down"
            log.info(
                "autopilot firmware %d.%d.%d (its AUTOPILOT_VERSION): GLOBAL_POSITION_INT.vz "
                "read positive %s",
                *version,
                up,
            )
        note = decoder.vz_sense.note
        if note is not None and note != self._vz_note_said:
            self._vz_note_said = note  # the height turned the sign over: said once
            log.warning("%s", note)

    def _note_autopilot(self, messages: list[mavlink.MAVLink_message]) -> None:
        """Which autopilot stack the locked sender is, from its HEARTBEAT among ``messages``
        (kept when there is none); a frame that is no multirotor is said once an autopilot."""
        for msg in messages:
            if msg.get_type() == "HEARTBEAT" and message_source(msg) == self.lock.locked:
                self._px4 = msg.autopilot == mavlink.MAV_AUTOPILOT_PX4
                note = frame_note(int(msg.type))
                if note is not None and self._frame_said != self.lock.locked:
                    self._frame_said = self.lock.locked
                    log.warning("%s", note)

    def _autopilot_changed(self, now_s: float) -> None:
        """The autopilot locked (or found at another address): answer only it, ask it for
        telemetry."""
        locked = self.lock.locked
        assert locked is not None and self.link is not None
        if self.decoder.retarget(locked):
            self._vz_note_said = None  # another autopilot's vz is judged and said anew
            self._version_said = None
        self.link.answer_only(self.lock.peer)
        self._request_streams(now_s)
        self._request_version(locked)
        self._start_mission(locked)

    def _handle(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        counts = self.decoder.counts
        reboots, jumps = counts["reboots"], counts["clock_jumps"]
        samples = self.decoder.decode(msg)
        self._infer_cells()
        self._say_vertical_sense()
        if msg.get_type() == "HEARTBEAT" and message_source(msg) == self.decoder.target:
            self._home_first = msg.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
            self._px4 = msg.autopilot == mavlink.MAV_AUTOPILOT_PX4
            if self.config.return_autopilot == "auto":
                self._follow_rtl("px4" if self._px4 else "ardupilot")
        if self.mission is not None and msg.get_type() in MISSION_MESSAGES:
            self.mission.on_message(msg, now_s)
        if msg.get_msgId() == PACK_INFO_ID:
            self._pack_info(msg)
        if counts["reboots"] != reboots:
            self._throttled.event(
                "reboots",
                now_s,
                "autopilot rebooted (clock went back to %.1f s; %d reboot(s) so far)",
                self.decoder.clock_s,
                counts["reboots"],
            )
            self._streams_ok = False
            self._request_streams(now_s)
            if self.decoder.target is not None:
                self._request_version(self.decoder.target)  # reflashed, perhaps
        if counts["clock_jumps"] != jumps:
            self._throttled.event(
                "clock_jumps",
                now_s,
                "autopilot clock jumped to %.1f s: re-referenced (%d jump(s) so far)",
                self.decoder.clock_s,
                counts["clock_jumps"],
            )
        if not samples:
            return
        if self.state is not None and self.state.saved is not None:
            assert self.decoder.target is not None
            self.state.resume(self.decoder.target, self.decoder.clock_s)
        self._last_rx_s = now_s
        if self.out.stale:
            self.out.stale = False
            log.info("telemetry resumed: estimates live again")
        was_initialized = self.pipeline.energy.initialized
        for sample in samples:
            if isinstance(sample, LandedSample):
                where = "on the ground" if sample.on_ground else "off the ground"
                log.info("landed detector: %s at %.2f s autopilot time", where, sample.time_s)
            estimate = self.pipeline.process(sample)
            if estimate is not None:
                self.out.deliver(estimate, now_s)
        if not was_initialized and self.pipeline.energy.initialized:
            how = "continued" if self.pipeline.counts["resumed"] else "initialized"
            log.info("energy %s: SoC %.0f %%", how, 100 * self.pipeline.energy.soc)
            battery = next(s for s in samples if isinstance(s, BatterySample))
            cells = self.pipeline.vehicle.battery.cells
            if (problem := pack_voltage_problem(battery.voltage_v, cells)) is not None:
                log.warning("%s", problem)
        latest = self.out.latest
        if (
            latest is not None
            and not self._streams_ok
            and self.pipeline.counts["velocity"]
            and self.pipeline.counts["battery"]
        ):
            self._streams_ok = True
            self._model_only_said = latest.model_only
            log.info("telemetry flowing: estimating, %s", _mode(latest.model_only))
        if latest is not None and self._model_only_said not in (None, latest.model_only):
            self._model_only_said = latest.model_only  # said once per change
            log.info("estimating, %s", _mode(latest.model_only))
        voltage = self.pipeline.energy.voltage
        if voltage is not None and voltage.load.unresponsive and not self._dead_voltage_said:
            self._dead_voltage_said = True  # said once
            log.warning("%s", voltage.load.describe())
        if self.pipeline.packs.refuted and not self._refuted_pack_said:
            self._refuted_pack_said = True  # said once
            log.warning("%s", self.pipeline.packs.refuted_note())

    def _follow_rtl(self, autopilot: str) -> None:
        """Return figures modelled on ``autopilot``'s RTL (said once per change)."""
        if autopilot == self._rtl:
            return
        self._rtl = autopilot
        returning = self.pipeline.returning
        returning.settings = rtl_settings(autopilot, self.pipeline.settings.return_home)
        log.info(
            "return figures follow %s's RTL", {"px4": "PX4", "ardupilot": "ArduCopter"}[autopilot]
        )

    def _start_mission(self, target: tuple[int, int]) -> None:
        """The mission download for this autopilot (read-only; off by configuration)."""
        link = self.link
        if not self.config.download_mission or link is None:
            return
        if self.mission is not None and self.mission.target == target:
            return
        own = (self.config.system_id, OWN_COMPONENT)
        self.mission = MissionDownload(link.send, link.mav, own, target, self._mission_read)

    def _mission_read(self, items: tuple[MissionItem, ...]) -> None:
        """A downloaded mission into the pipeline, on the autopilot's clock (item 0 is home:
        a placeholder goes first for autopilots whose missions start with a real item)."""
        if not self._home_first:
            nan = float("nan")
            items = (MissionItem(-1, 16, 0, (0.0,) * 4, nan, nan, 0.0, "home"), *items)
        self.pipeline.process(MissionSample(self.decoder.clock_s or 0.0, items))

    def _request_home(self, now_s: float) -> None:
        """HOME_POSITION asked for while positions come and no home does (:class:`HomeRequest`)."""
        returning = self.pipeline.returning
        has_position, has_home = returning.position is not None, returning.home is not None
        waited_s = self.home_request.due(now_s, has_position, has_home)
        if waited_s is None or self.link is None or self.decoder.target is None:
            return
        self.link.send(self.home_request.message(self.link.mav, self.decoder.target, now_s))
        if self.home_request.sent == 1:
            log.info("no HOME_POSITION %.0f s after the first position: requested", waited_s)

    def _request_streams(self, now_s: float) -> None:
        """REQUEST_DATA_STREAM (ArduPilot) and SET_MESSAGE_INTERVAL (both stacks) to the
        locked autopilot — before the lock, on a point-to-point link only, to the configured
        ids or the latest autopilot HEARTBEAT's — at most once per REQUEST_RETRY_S whatever
        asks (locks, reboots). To PX4 (its HEARTBEAT says so), SET_MESSAGE_INTERVAL only
        (:mod:`estimator.mavlink.streams`)."""
        target = self.lock.locked
        if target is None and self.link is not None and not self.link.shared:
            target = self.lock.configured or self.lock.heard_autopilot
        if (
            not self.config.request_streams
            or self.link is None
            or target is None
            or now_s - self._last_request_s < REQUEST_RETRY_S
        ):
            return
        self._last_request_s = now_s
        cfg = self.config
        build = px4_requests if self._px4 else ardupilot_requests
        for request in build(self.link.mav, target, cfg.velocity_rate_hz, cfg.battery_rate_hz):
            self.link.send(request)
        self._request_pack_info(target)
        log.info(
            "%s: velocity %.0f Hz, battery %.1f Hz",
            "message intervals requested (PX4)" if self._px4 else "streams requested",
            cfg.velocity_rate_hz,
            cfg.battery_rate_hz,
        )

    def _request_version(self, target: tuple[int, int]) -> None:
        """An ArduPilot autopilot's AUTOPILOT_VERSION (which way up it sends vz), asked once it
        is locked and after each reboot (an answer before the lock is not taken)."""
        if self.config.request_streams and self.link is not None and not self._px4:
            self.link.send(version_request(self.link.mav, target))

    def _request_pack_info(self, target: tuple[int, int]) -> None:
        """Once with the streams: the pack's serial number (MAV_CMD_REQUEST_MESSAGE)."""
        if self.flight_pack.wants_serial and self.link is not None:
            self.link.send(request_message(self.link.mav, target, PACK_INFO_ID))

    # -- heartbeat and watchdog -----------------------------------------------------------

    async def _heartbeat_loop(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            self.out.heartbeat()
            self._watchdog(loop.time())
            await asyncio.sleep(1.0)

    def _watchdog(self, now_s: float) -> None:
        silent_s = None if self._last_rx_s is None else now_s - self._last_rx_s
        if silent_s is not None and silent_s > self.config.stale_after_s and not self.out.stale:
            log.warning("link silent for %.1f s: estimates marked stale", silent_s)
            self.out.mark_stale()
        self._handle_each(self.lock.tick(now_s), now_s)
        if not self._streams_ok:
            self._request_streams(now_s)
        self._request_home(now_s)
        if self.mission is not None:
            self.mission.tick(now_s)
        warn_input_counts(self._throttled, now_s, self.decoder, self.link, self.lock)
        self._log_pack_mismatch(now_s)

    def _log_pack_mismatch(self, now_s: float) -> None:
        """Say which cell count the skipped pack voltage fits, when no battery reading has been
        believed: at once, then at most once per :data:`PACK_MISMATCH_LOG_S` (in the log, and
        a STATUSTEXT on the ``--publish`` links)."""
        mismatch = pack_mismatch_text(self.decoder, self.pipeline.vehicle.battery.cells)
        if mismatch is None or self.pipeline.energy.initialized:
            return
        if not self._throttled.due("pack_mismatch", now_s, PACK_MISMATCH_LOG_S):
            return
        line, text = mismatch
        log.warning("%s", line)
        self.out.statustext(mavlink.MAV_SEVERITY_WARNING, text)  # never towards the autopilot


async def _drain(link: MavlinkLink) -> None:
    """Consume what an output link receives (GCS heartbeats), so its queue stays empty."""
    while await link.recv():
        pass


def _mode(model_only: bool) -> str:
    """How the estimate is made, for the log."""
    return "model only (no current measured)" if model_only else "fused with the measured current"
