"""Read the autopilot's mission with the MAVLink mission protocol, read-only.

MISSION_REQUEST_LIST → MISSION_COUNT → (MISSION_REQUEST_INT → MISSION_ITEM_INT) × count →
MISSION_ACK, as our own system/component (191), so a ground station's transfers on other
links are not disturbed: we never upload, clear or set anything. Each request waits
:data:`ITEM_TIMEOUT_S` (wall clock) and is resent up to :data:`RETRIES` times; a failed
download (no answer, an error MISSION_ACK to us) is counted and retried after
:data:`RETRY_AFTER_S`; the first failure of each cause is a warning, the later ones are
counted (:attr:`MissionDownload.warned`: the daemon sums them up when it stops). The
mission is read again when it changes: MISSION_CURRENT's item count changes or disagrees
with the mission read (ArduPilot's count leaves out its home item 0), or the autopilot
acknowledges a transfer to someone else (an upload finished).

Event-driven, no task of its own: the daemon hands it the autopilot's messages
(:meth:`MissionDownload.on_message`) and calls :meth:`MissionDownload.tick` once a second.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable

from pymavlink.dialects.v20 import common as mavlink

from estimator.logs.mission_files import MissionItem
from estimator.logs.sanity import RunWarnings

log = logging.getLogger("uav_energy.mission")

#: Wall seconds to wait for an answer before a request is resent.
ITEM_TIMEOUT_S = 1.5
#: Resends of one request before the download is given up.
RETRIES = 5
#: Wall seconds after a failed download before the next attempt.
RETRY_AFTER_S = 30.0
#: Messages the download reads.
MESSAGE_TYPES = frozenset({"MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ACK", "MISSION_CURRENT"})
#: Their message ids (the daemon's link must let them through its header filter).
MESSAGE_IDS = frozenset(getattr(mavlink, f"MAVLINK_MSG_ID_{name}") for name in MESSAGE_TYPES)
_FRAMES_WITHOUT_POSITION = frozenset({mavlink.MAV_FRAME_MISSION})
#: Items the log line of a completed download spells out (the count is always given).
LOGGED_ITEMS = 10


class MissionDownload:
    """One autopilot's mission. ``send`` queues a message on the autopilot link (encoded with
    our ids), ``mav`` is that link's encoder, ``own`` our (system, component), ``target`` the
    autopilot's. ``done`` is called with the items of each completed download."""

    def __init__(
        self,
        send: Callable[[mavlink.MAVLink_message], None],
        mav: mavlink.MAVLink,
        own: tuple[int, int],
        target: tuple[int, int],
        done: Callable[[tuple[MissionItem, ...]], None],
    ) -> None:
        self._send, self._mav, self._own, self._target, self._done = send, mav, own, target, done
        self.counts: Counter[str] = Counter()
        self.warned = RunWarnings()  # failures by cause: the first of each is a warning
        self._count: int | None = None  # items announced by MISSION_COUNT (None: listing)
        self._items: dict[int, MissionItem] = {}
        self._active = False
        self._sent_s = -math.inf
        self._tries = 0
        self._next_start_s = -math.inf  # wall clock of the next (re)download
        self._total: int | None = None  # MISSION_CURRENT.total last seen
        self.items: tuple[MissionItem, ...] | None = None  # the last mission read

    @property
    def active(self) -> bool:
        return self._active

    def request(self, now_s: float) -> None:
        """(Re)read the mission now, unless a download is running."""
        if self._active:
            return
        self._active, self._count, self._items, self._tries = True, None, {}, 0
        self.counts["downloads_started"] += 1
        self._ask(now_s)

    def tick(self, now_s: float) -> None:
        """Once a second: start a due download; resend a request that went unanswered."""
        if not self._active:
            if now_s >= self._next_start_s and self.items is None:
                self.request(now_s)
            return
        if now_s - self._sent_s < ITEM_TIMEOUT_S:
            return
        if self._tries >= RETRIES:
            self._fail(now_s, "no answer")
            return
        self._tries += 1
        self.counts["resends"] += 1
        self._ask(now_s)

    @property
    def target(self) -> tuple[int, int]:
        """The autopilot's (system, component)."""
        return self._target

    def on_message(self, msg: mavlink.MAVLink_message, now_s: float) -> None:
        """A message (any of :data:`MESSAGE_TYPES`; others' and other sources' are ignored)."""
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self._target:
            return
        kind = msg.get_type()
        if kind == "MISSION_CURRENT":
            total = getattr(msg, "total", 0)
            if total == 0:  # the autopilot does not say
                return
            total = 0 if total == 0xFFFF else total  # UINT16_MAX: no mission
            changed = self._total is not None and total != self._total
            # the count read: ArduPilot's total leaves out its home item 0, PX4's has none
            stale = self.items is not None and len(self.items) not in (total, total + 1)
            self._total = total
            if (changed or stale) and not self._active:
                self._changed(now_s, f"{total} items now")
            return
        if getattr(msg, "mission_type", 0) != mavlink.MAV_MISSION_TYPE_MISSION:
            return
        to_us = (msg.target_system, msg.target_component) == self._own
        if kind == "MISSION_ACK" and not to_us:
            self._changed(now_s, "the autopilot acknowledged another system's transfer")
            return
        if not (to_us and self._active):
            return
        if kind == "MISSION_ACK":
            if msg.type != mavlink.MAV_MISSION_ACCEPTED:
                self._fail(now_s, f"refused: {_result_name(msg.type)}")
        elif kind == "MISSION_COUNT" and self._count is None:
            self._count, self._tries = int(msg.count), 0
            self._ask(now_s) if self._count else self._finish()
        elif kind == "MISSION_ITEM_INT" and self._count is not None:
            if msg.seq != len(self._items):
                return  # a duplicate or an answer to an old request
            self._items[msg.seq] = _item(msg)
            self._tries = 0
            if len(self._items) == self._count:
                self._finish()
            else:
                self._ask(now_s)

    def _ask(self, now_s: float) -> None:
        sysid, compid = self._target
        if self._count is None:
            msg = self._mav.mission_request_list_encode(
                sysid, compid, mavlink.MAV_MISSION_TYPE_MISSION
            )
        else:
            msg = self._mav.mission_request_int_encode(
                sysid, compid, len(self._items), mavlink.MAV_MISSION_TYPE_MISSION
            )
        self._send(msg)
        self._sent_s = now_s

    def _finish(self) -> None:
        sysid, compid = self._target
        self._send(
            self._mav.mission_ack_encode(
                sysid, compid, mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_TYPE_MISSION
            )
        )
        self._active = False
        self.items = tuple(self._items[i] for i in range(len(self._items)))
        self.counts["downloads"] += 1
        shown = "; ".join(item_text(item) for item in self.items[:LOGGED_ITEMS])
        more = " …" if len(self.items) > LOGGED_ITEMS else ""
        failed = self.counts["downloads_failed"]
        after = f" (after {failed} failed download(s))" if failed else ""
        log.info(
            "mission read from the autopilot%s: %d items: %s%s", after, len(self.items), shown, more
        )
        self._done(self.items)

    def _fail(self, now_s: float, why: str) -> None:
        self._active = False
        self._next_start_s = now_s + RETRY_AFTER_S
        self.items = None
        self.counts["downloads_failed"] += 1
        if self.warned.first(f"mission download ({why})"):
            log.warning(
                "mission download failed (%s): retrying every %.0f s; further failures are "
                "counted (mission_downloads_failed)",
                why,
                RETRY_AFTER_S,
            )

    def _changed(self, now_s: float, why: str) -> None:
        self.counts["mission_changes"] += 1
        log.info("mission changed (%s): reading it again", why)
        self.items = None
        self._next_start_s = now_s
        self._active = False  # a transfer under way reads the old mission: start again
        self.request(now_s)


def _item(msg: mavlink.MAVLink_message) -> MissionItem:
    """MISSION_ITEM_INT → :class:`MissionItem` (degE7 → deg; NaN without a position)."""
    positioned = msg.frame not in _FRAMES_WITHOUT_POSITION and (msg.x, msg.y) != (0, 0)
    return MissionItem(
        seq=int(msg.seq),
        command=int(msg.command),
        frame=int(msg.frame),
        params=(float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4)),
        lat_deg=msg.x / 1e7 if positioned else math.nan,
        lon_deg=msg.y / 1e7 if positioned else math.nan,
        alt_m=float(msg.z),
        where=f"item {msg.seq}",
    )


def _result_name(result: int) -> str:
    """A MISSION_ACK's MAV_MISSION_RESULT by name (its number when the dialect has none)."""
    entry = mavlink.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name if entry is not None else f"MAV_MISSION_RESULT {result}"


def item_text(item: MissionItem) -> str:
    """An item as the log gives it: ``command/frame lat,lon altm`` (degrees to 1e-7, metres
    to the centimetre; ``nan,nan`` without a position)."""
    return f"{item.command}/{item.frame} {item.lat_deg:.7f},{item.lon_deg:.7f} {item.alt_m:.2f}m"
