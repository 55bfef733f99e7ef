"""Which autopilot the daemon listens to: configured, or locked after its telemetry confirms it.

Without a configured ``target_system``, the first autopilot HEARTBEAT (autopilot not
MAV_AUTOPILOT_INVALID, a vehicle type: :func:`~estimator.telemetry.decode.is_autopilot`)
makes its (system, component) a *candidate*, not the autopilot. The candidate is locked once
its own telemetry confirms it: :data:`CONFIRM_FRAMES` frames stamped with ``time_boot_ms``
that agree with one running clock (the decoder's clock checks: a stray stamp is skipped, a
new clock starts the count again), spanning at least :data:`CONFIRM_S` of that clock. Its
messages from the HEARTBEAT on are held meanwhile and handed over in order once it is locked,
so the daemon's estimates still equal a replay of the same bytes. A candidate that does not
confirm within :data:`CANDIDATE_TIMEOUT_S` (wall clock) gives way to the next autopilot
HEARTBEAT.

After a reboot of the locked autopilot (:meth:`AutopilotLock.recheck`) its messages keep
flowing, but within :data:`CANDIDATE_TIMEOUT_S` it must again send an autopilot HEARTBEAT of
the same type and autopilot as when it was locked, and confirming telemetry; else (or at once
on a HEARTBEAT of another type) the lock is released and selection starts over.

A second autopilot (an autopilot HEARTBEAT from other ids) is logged once per source, then
at most once per :data:`OTHER_LOG_S` with the count of its frames; its frames are counted
(``other_autopilot_frames``) and ignored. Counters: :attr:`AutopilotLock.counts`.
"""

from __future__ import annotations

import logging
import math
from collections import Counter

from pymavlink.dialects.v20 import common as mavlink

from estimator.telemetry.decode import is_autopilot, message_source
from estimator.telemetry.plausibility import AutopilotClock, ClockVerdict

log = logging.getLogger("uav_energy.autopilot")

#: Stamped frames of the candidate that confirm it.
CONFIRM_FRAMES = 10
#: Autopilot clock (s) those frames must span.
CONFIRM_S = 1.0
#: Wall seconds a candidate (or a rebooted autopilot) has to confirm.
CANDIDATE_TIMEOUT_S = 10.0
#: Messages of a candidate held at most (the oldest beyond are dropped, counted).
MAX_HELD = 5000
#: Wall seconds between log lines about one other autopilot.
OTHER_LOG_S = 60.0

Source = tuple[int, int]


class _Confirmation:
    """Stamped frames of one source that agree with its clock, judged by the decoder's
    :class:`~estimator.telemetry.plausibility.AutopilotClock` (a hostile stamp among them is
    skipped, not a reason to start over; a confirmed reboot or jump starts over)."""

    def __init__(self) -> None:
        self.clock = AutopilotClock()
        self.frames = 0
        self.first_s = self.last_s = math.nan

    def add(self, time_s: float) -> bool:
        """Judge a stamp (s); False when a new clock replaced the one being confirmed."""
        clock = self.clock
        verdict = clock.check(time_s)
        if verdict is ClockVerdict.SKIP:
            return True
        if verdict is ClockVerdict.ACCEPT:
            self.frames += 1
            self.last_s = max(self.last_s, time_s)
            return True
        joined = clock.joined  # a clock confirmed by its first frames
        assert joined is not None
        self.frames, self.first_s, self.last_s = joined.frames, joined.first_s, joined.last_s
        return verdict is ClockVerdict.START

    @property
    def confirmed(self) -> bool:
        return self.frames >= CONFIRM_FRAMES and self.last_s - self.first_s >= CONFIRM_S


class AutopilotLock:
    """Selects the autopilot. ``configured``: fixed (system, component), or None to select.

    :meth:`admit` takes every received message and returns those to decode (none from a
    candidate until it is confirmed, then all of its held ones)."""

    def __init__(self, configured: Source | None, own: Source) -> None:
        self.configured = configured
        self.own = own
        self.locked: Source | None = configured
        self.candidate: Source | None = None
        self.rechecking = False
        self.counts: Counter[str] = Counter()
        self._kind: tuple[int, int] | None = None  # (type, autopilot) of the locked HEARTBEAT
        self._heartbeat_seen = False
        self._confirm = _Confirmation()
        self._held: list[mavlink.MAVLink_message] = []
        self._deadline_s = math.inf
        self._others: dict[Source, float] = {}  # other autopilot → wall s last logged

    def admit(self, msg: mavlink.MAVLink_message, now_s: float) -> list[mavlink.MAVLink_message]:
        """Messages to hand to the decoder now (in order), given ``msg`` received at wall
        time ``now_s``."""
        source = message_source(msg)
        if source == self.own:
            return [msg]  # the decoder counts our own
        heartbeat = msg.get_type() == "HEARTBEAT" and is_autopilot(msg)
        if self.locked is not None:
            if source != self.locked:
                self._other(source, heartbeat, now_s)
                return [msg]  # the decoder counts it as another source's
            if self.rechecking:
                self._recheck_step(msg, heartbeat, now_s)
            if self.locked is not None:
                return [msg]
            # released by this message: selection starts over with it
        if self.candidate is not None and now_s > self._deadline_s:
            log.warning(
                "autopilot candidate system %d component %d not confirmed by its telemetry "
                "within %.0f s: selecting again",
                *self.candidate,
                CANDIDATE_TIMEOUT_S,
            )
            self.counts["candidates_dropped"] += 1
            self.candidate = None
        if self.candidate is None:
            if not heartbeat:
                self.counts["before_autopilot"] += 1
                return []
            self._start_candidate(source, msg, now_s)
        if source != self.candidate:
            self._other(source, heartbeat, now_s)
            return []
        self._hold(msg)
        if not self._confirm_step(msg):
            return []
        self.locked, self.candidate = source, None
        log.info(
            "autopilot found: system %d component %d, locked (heartbeat and %d stamped "
            "frames over %.1f s of its clock)",
            *source,
            self._confirm.frames,
            self._confirm.last_s - self._confirm.first_s,
        )
        held, self._held = self._held, []
        return held

    def recheck(self, now_s: float) -> None:
        """The locked autopilot rebooted: it has to confirm itself again (not when
        configured)."""
        if self.configured is not None or self.locked is None:
            return
        self.rechecking = True
        self._heartbeat_seen = False
        self._confirm = _Confirmation()
        self._deadline_s = now_s + CANDIDATE_TIMEOUT_S
        self.counts["rechecks"] += 1

    def tick(self, now_s: float) -> bool:
        """Called about once a second: a recheck that ran out of time releases the lock
        (True then)."""
        if self.rechecking and now_s > self._deadline_s:
            self._release("did not confirm itself after its reboot")
            return True
        return False

    # -- internals ----------------------------------------------------------------------------

    def _start_candidate(self, source: Source, msg: mavlink.MAVLink_message, now_s: float) -> None:
        self.candidate = source
        self._kind = (msg.type, msg.autopilot)
        self._confirm = _Confirmation()
        self._held = []
        self._deadline_s = now_s + CANDIDATE_TIMEOUT_S
        self.counts["candidates"] += 1
        log.info(
            "autopilot candidate: system %d component %d (type %d, autopilot %d); "
            "confirming with its telemetry",
            *source,
            msg.type,
            msg.autopilot,
        )

    def _hold(self, msg: mavlink.MAVLink_message) -> None:
        self._held.append(msg)
        if len(self._held) > MAX_HELD:
            del self._held[0]
            self.counts["held_dropped"] += 1

    def _confirm_step(self, msg: mavlink.MAVLink_message) -> bool:
        """Count a stamped frame; True once confirmed."""
        stamp_ms = getattr(msg, "time_boot_ms", None)
        if stamp_ms is None or msg.get_type() == "NAMED_VALUE_FLOAT":
            return False
        if not self._confirm.add(stamp_ms / 1000.0):
            self.counts["confirm_restarts"] += 1
        return self._confirm.confirmed

    def _recheck_step(self, msg: mavlink.MAVLink_message, heartbeat: bool, now_s: float) -> None:
        if heartbeat:
            if (msg.type, msg.autopilot) != self._kind:
                self._release(
                    f"sent a HEARTBEAT of type {msg.type}, autopilot {msg.autopilot} after "
                    "its reboot"
                )
                return
            self._heartbeat_seen = True
        if self._confirm_step(msg) and self._heartbeat_seen:
            self.rechecking = False
            self._deadline_s = math.inf
            log.info(
                "autopilot system %d component %d confirmed after its reboot", *message_source(msg)
            )
        elif now_s > self._deadline_s:
            self._release("did not confirm itself after its reboot")

    def _release(self, why: str) -> None:
        assert self.locked is not None
        log.warning(
            "autopilot system %d component %d %s: selecting the autopilot again", *self.locked, why
        )
        self.counts["released"] += 1
        self.locked = self.candidate = None
        self.rechecking = False
        self._held = []

    def _other(self, source: Source, heartbeat: bool, now_s: float) -> None:
        """A message from ids other than the autopilot's: a second autopilot is logged."""
        if source not in self._others:
            if not heartbeat:
                return
            self._others[source] = -math.inf
        self.counts["other_autopilot_frames"] += 1
        if now_s - self._others[source] >= OTHER_LOG_S:
            self._others[source] = now_s
            chosen = self.locked or self.candidate
            assert chosen is not None
            log.warning(
                "second autopilot system %d component %d ignored (%d frames so far; "
                "listening to system %d component %d)",
                *source,
                self.counts["other_autopilot_frames"],
                *chosen,
            )
