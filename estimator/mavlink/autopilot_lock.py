"""Which autopilot the daemon listens to: the sender whose own telemetry proves it, at the address
it speaks from, kept while it keeps talking.

A *sender* is a (system, component) at a peer address (a ``udpin`` link's UDP address; None
on point-to-point links). Up to :data:`MAX_CANDIDATES` senders are evaluated at once, each
with its :class:`~estimator.mavlink.sender_evidence.SenderEvidence` (a running
``time_boot_ms`` clock, agreeing position, attitude and battery) and its messages held
(:data:`MAX_HELD` at most, from its latest autopilot HEARTBEAT on). Only a stamped frame
makes a sender a candidate, and a full table gives way only to it, and only where a
candidate has shown at most one stamped frame or fell silent for
:data:`CANDIDATE_TIMEOUT_S`: HEARTBEATs alone never lock and never evict. The first candidate
that has sent an autopilot HEARTBEAT (:func:`~estimator.telemetry.decode.is_autopilot`) and
whose evidence is confirmed is **locked**: its held messages are handed over in order, so
the daemon's estimates equal a replay of the same bytes. With a configured
(system, component), only senders with those ids are candidates.

The lock is kept while the locked sender keeps talking: the same ids from another address
are dropped (``counts['foreign_peer']``); another confirmed candidate takes over only after
the locked sender has been silent for :data:`REPIN_AFTER_S` (an autopilot restarted on
another port; one warning line).

The locked autopilot's clock must prove any change: a stamp off it (a reboot, a link gap, a
forged or corrupt frame) holds the sender's messages until the new clock is confirmed by
several of the sender's frames *and* has run alone — no frame of the old clock —
for :data:`REBOOT_CONFIRM_WALL_S` of wall time (:class:`ClockSettings.confirm_wall_s`).
Then everything held is handed over in order; the decoder sees the reboot as a replay
would. A frame of the old clock refutes it: the off-clock frames are dropped
(``counts['off_clock_frames']``), the rest handed over. A HEARTBEAT of another vehicle type
or autopilot than the locked one's is dropped (``counts['heartbeat_mismatch']``), except
among the frames of a proven clock change (a reboot: what it says it is now). A sender that has
signed a frame with our key is held to it: its unsigned frames are dropped
(``counts['unsigned_frames']``) and never count.

Other autopilots (an autopilot HEARTBEAT from other ids) are counted
(``other_autopilot_frames``) and logged in one aggregated line at most every
:data:`OTHER_LOG_S`, however many they are.
"""

from __future__ import annotations

import logging
import math
from collections import Counter, OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

from estimator.mavlink.sender_evidence import SenderEvidence, frame_stamp_s
from estimator.telemetry.clock import AutopilotClock, ClockSettings, ClockVerdict
from estimator.telemetry.decode import is_autopilot, message_source

log = logging.getLogger("uav_energy.autopilot")

#: Senders evaluated at once, and the messages held for each at most (the oldest beyond are
#: dropped, counted in ``held_dropped``).
MAX_CANDIDATES = 8
MAX_HELD = 5000
#: Wall seconds after which a silent candidate may be replaced.
CANDIDATE_TIMEOUT_S = 10.0
#: Wall seconds the locked sender must be silent before another sender may take its place.
REPIN_AFTER_S = 3.0
#: Wall seconds a new clock of the locked autopilot must run alone to be believed.
REBOOT_CONFIRM_WALL_S = 1.0
#: Wall seconds between log lines about other autopilots.
OTHER_LOG_S = 60.0
#: Senders remembered by their latest autopilot HEARTBEAT, and other autopilots remembered.
MAX_REMEMBERED = 64

Source = tuple[int, int]
Sender = tuple[Source, Hashable]


@dataclass(eq=False)
class _Candidate:
    """A sender being evaluated: its evidence, held messages, stamped frames seen, whether an
    autopilot HEARTBEAT came, the wall time it was last heard (s), its vehicle kind."""

    evidence: SenderEvidence
    held: list[mavlink.MAVLink_message] = field(default_factory=list)
    stamped: int = 0
    heartbeat: bool = False
    heard_s: float = -math.inf
    kind: tuple[int, int] | None = None  # (type, autopilot) of its latest autopilot HEARTBEAT


class AutopilotLock:
    """Selects the autopilot. ``configured``: fixed (system, component), or None for any.

    :meth:`admit` takes every received message with the peer it came from and returns those
    to decode now, in order; :meth:`tick` (about once a second) those a proven clock change
    releases. :attr:`locked` and :attr:`peer`: the autopilot's ids and address."""

    def __init__(self, configured: Source | None, own: Source) -> None:
        self.configured = configured
        self.own = own
        self.locked: Source | None = None
        self.peer: Hashable = None
        self.counts: Counter[str] = Counter()
        self._candidates: dict[Sender, _Candidate] = {}
        self._heartbeats: OrderedDict[Sender, mavlink.MAVLink_message] = OrderedDict()
        self._signers: OrderedDict[Sender, None] = OrderedDict()
        self._clock = AutopilotClock(ClockSettings(confirm_wall_s=REBOOT_CONFIRM_WALL_S))
        self._pending: list[tuple[mavlink.MAVLink_message, int | None]] = []
        self._kind: tuple[int, int] | None = None  # (type, autopilot) of the locked one
        self._locked_heard_s = -math.inf
        self._others: OrderedDict[Source, None] = OrderedDict()
        self._others_logged_s = -math.inf

    @property
    def heard_autopilot(self) -> Source | None:
        """The ids of the latest autopilot HEARTBEAT heard (allowed by the configuration)."""
        if not self._heartbeats:
            return None
        source, _ = next(reversed(self._heartbeats))
        return source

    def admit(
        self, msg: mavlink.MAVLink_message, now_s: float, peer: Hashable = None
    ) -> list[mavlink.MAVLink_message]:
        """Messages to hand to the decoder now (in order), given ``msg`` received from
        ``peer`` at wall time ``now_s`` (s)."""
        source = message_source(msg)
        if source == self.own:
            return [msg]  # the decoder counts our own
        sender = (source, peer)
        if not self._trusted(sender, msg):
            return []
        if self.locked is not None and sender == (self.locked, self.peer):
            self._locked_heard_s = now_s
            return self._from_locked(msg, now_s)
        if self.configured is not None and source != self.configured:
            self._other(source, msg, now_s)
            return [msg]  # the decoder counts it as another source's
        taken = self._evaluate(sender, msg, now_s)
        if taken is not None:
            return taken
        if source == self.locked:
            self.counts["foreign_peer"] += 1
            return []
        if self.locked is None:
            self.counts["before_autopilot"] += 1
            return []
        self._other(source, msg, now_s)
        return [msg]

    def tick(self, now_s: float) -> list[mavlink.MAVLink_message]:
        """About once a second: forget candidates silent for :data:`CANDIDATE_TIMEOUT_S`;
        the messages to decode when a new clock of the autopilot has proven itself meanwhile."""
        for sender, candidate in list(self._candidates.items()):
            if now_s - candidate.heard_s > CANDIDATE_TIMEOUT_S:
                del self._candidates[sender]
        if self.locked is None or self._clock.due(now_s) is None:
            return []
        assert self._clock.joined is not None
        return self._settle(self._clock.joined.ident)

    # -- the locked autopilot ---------------------------------------------------------------

    def _from_locked(
        self, msg: mavlink.MAVLink_message, now_s: float
    ) -> list[mavlink.MAVLink_message]:
        clock = self._clock
        if not clock.candidates and self._mismatch(msg):
            return []
        time_s = frame_stamp_s(msg)
        if time_s is None:
            if not clock.candidates:
                return [msg]
            return self._hold_pending(msg, None)
        verdict = clock.check(time_s, now_s)
        if verdict is ClockVerdict.ACCEPT:
            return [*self._settle(None), msg]
        if verdict is ClockVerdict.SKIP:
            assert clock.joined is not None
            return self._hold_pending(msg, clock.joined.ident)
        assert clock.joined is not None
        return [*self._settle(clock.joined.ident), msg]

    def _hold_pending(
        self, msg: mavlink.MAVLink_message, ident: int | None
    ) -> list[mavlink.MAVLink_message]:
        """Hold ``msg`` (of the candidate clock ``ident``, None: unstamped) until the pending
        clocks are settled; more than :data:`MAX_HELD` of them are a flood: refuted."""
        self._pending.append((msg, ident))
        if len(self._pending) <= MAX_HELD:
            return []
        self._clock.forget_candidates()
        return self._settle(None)

    def _settle(self, believed: int | None) -> list[mavlink.MAVLink_message]:
        """The held messages once pending clocks are settled: the frames of the candidate
        clock ``believed`` (its id; None: all refuted) are kept, every other off-clock frame
        is dropped."""
        out = [m for m, i in self._pending if i is None or i == believed]
        self.counts["off_clock_frames"] += len(self._pending) - len(out)
        self._pending = []
        if believed is None:
            return [m for m in out if not self._mismatch(m)]
        self.counts["clock_changes"] += 1
        kinds = [(m.type, m.autopilot) for m in out if m.get_type() == "HEARTBEAT"]
        self._kind = kinds[-1] if kinds else self._kind  # rebooted: what it says it is now
        return out

    def _mismatch(self, msg: mavlink.MAVLink_message) -> bool:
        """A HEARTBEAT of another type or autopilot than the locked one's (counted)."""
        if msg.get_type() != "HEARTBEAT" or (msg.type, msg.autopilot) == self._kind:
            return False
        self.counts["heartbeat_mismatch"] += 1
        return True

    # -- candidates ---------------------------------------------------------------------------

    def _evaluate(
        self, sender: Sender, msg: mavlink.MAVLink_message, now_s: float
    ) -> list[mavlink.MAVLink_message] | None:
        """Feed ``msg`` to its sender's candidate (made for a stamped frame when there is
        room); the messages to decode when this locks the sender, else None."""
        heartbeat = msg.get_type() == "HEARTBEAT" and is_autopilot(msg)
        if heartbeat:
            _remember(self._heartbeats, sender, msg)
        candidate = self._candidates.get(sender)
        stamped = frame_stamp_s(msg) is not None
        if candidate is None:
            if not stamped or not self._make_room(now_s):
                return None
            candidate = self._candidates[sender] = _Candidate(SenderEvidence())
            if (seen := self._heartbeats.get(sender)) is not None:
                candidate.held.append(seen)
                candidate.heartbeat, candidate.kind = True, (seen.type, seen.autopilot)
            self.counts["candidates"] += 1
            log.debug("candidate: system %d component %d at %s", *sender[0], sender[1])
        candidate.heard_s = now_s
        if heartbeat:
            candidate.heartbeat, candidate.kind = True, (msg.type, msg.autopilot)
        if candidate.heartbeat:
            candidate.held.append(msg)
            if len(candidate.held) > MAX_HELD:
                del candidate.held[0]
                self.counts["held_dropped"] += 1
        evidence = candidate.evidence
        inconsistent = evidence.counts["inconsistent"]
        evidence.add(msg)
        candidate.stamped += stamped and evidence.counts["inconsistent"] == inconsistent
        if not (candidate.heartbeat and evidence.confirmed):
            return None
        if self.locked is not None and now_s - self._locked_heard_s < REPIN_AFTER_S:
            return None  # the locked autopilot is still talking
        return self._lock(sender, candidate, now_s)

    def _make_room(self, now_s: float) -> bool:
        """Room for one more candidate: the weakest gives way if it showed at most one stamped
        frame or fell silent; else no room (counted)."""
        if len(self._candidates) < MAX_CANDIDATES:
            return True
        sender, weakest = min(
            self._candidates.items(), key=lambda item: (item[1].stamped, item[1].heard_s)
        )
        if weakest.stamped <= 1 or now_s - weakest.heard_s > CANDIDATE_TIMEOUT_S:
            del self._candidates[sender]
            return True
        self.counts["candidates_refused"] += 1
        return False

    def _lock(
        self, sender: Sender, candidate: _Candidate, now_s: float
    ) -> list[mavlink.MAVLink_message]:
        evidence = candidate.evidence
        source, peer = sender
        if self.locked is None:
            log.info(
                "autopilot found: system %d component %d, locked (%d stamped frames over "
                "%.1f s of its clock)",
                *source,
                evidence.frames,
                evidence.last_s - evidence.first_s,
            )
        else:
            log.warning(
                "autopilot system %d component %d silent for %.0f s: system %d component %d "
                "at %s confirmed by its telemetry, locked instead",
                *self.locked,
                now_s - self._locked_heard_s,
                *source,
                peer,
            )
            self.counts["relocked"] += 1
        self.locked, self.peer, self._locked_heard_s = source, peer, now_s
        self._kind = candidate.kind
        del self._candidates[sender]
        self._clock = AutopilotClock(ClockSettings(confirm_wall_s=REBOOT_CONFIRM_WALL_S))
        self._clock.time_s = evidence.clock.time_s
        self._pending = []
        return candidate.held

    # -- trust and others ---------------------------------------------------------------------

    def _trusted(self, sender: Sender, msg: mavlink.MAVLink_message) -> bool:
        """False for an unsigned frame of a sender that signs (counted)."""
        if msg.get_signed():
            _remember(self._signers, sender, None)
            return True
        if sender in self._signers:
            self.counts["unsigned_frames"] += 1
            return False
        return True

    def _other(self, source: Source, msg: mavlink.MAVLink_message, now_s: float) -> None:
        """A message from ids other than the autopilot's: other autopilots are counted and
        logged in aggregate."""
        if source not in self._others:
            if not (msg.get_type() == "HEARTBEAT" and is_autopilot(msg)):
                return
            _remember(self._others, source, None)
        self.counts["other_autopilot_frames"] += 1
        if now_s - self._others_logged_s < OTHER_LOG_S:
            return
        self._others_logged_s = now_s
        listening = (
            "no autopilot confirmed yet"
            if self.locked is None
            else "listening to system {} component {}".format(*self.locked)
        )
        log.warning(
            "other autopilots ignored: %d frames so far, latest from system %d component %d (%s)",
            self.counts["other_autopilot_frames"],
            *source,
            listening,
        )


def _remember(table: OrderedDict[Any, Any], key: Hashable, value: object) -> None:
    """``table[key] = value`` as its newest entry, the oldest beyond :data:`MAX_REMEMBERED`
    forgotten."""
    table[key] = value
    table.move_to_end(key)
    if len(table) > MAX_REMEMBERED:
        table.popitem(last=False)
