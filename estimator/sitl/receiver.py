"""Receiving from a simulated autopilot, for the SITL pilots (ArduCopter and PX4): one
message at a time, a stall when the simulator says nothing for too long (wall clock), the
autopilot's own messages folded into the pilot's state and handed to its listeners, and
waits on the autopilot's clock."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from estimator.errors import UserError


class Receiver:
    """Set by the pilot: ``conn`` (a pymavlink connection), ``source`` (the autopilot's
    system and component ids), ``quiet_s`` (wall seconds a receive waits),
    ``stall_wall_s`` and ``stall_text`` (the error after that long without a message from
    it), ``state`` (with ``boot_s``, the autopilot's clock, s); :meth:`_update` folds one of
    its messages into the pilot's state."""

    conn: Any
    state: Any
    source: tuple[int, int]
    quiet_s: float
    stall_wall_s: float
    stall_text: str

    def __init__(self) -> None:
        self.listeners: list[Callable[[Any], None]] = []
        self._last_wall = time.monotonic()

    def pump(self) -> Any:
        """Receive one message (None after ``quiet_s`` of quiet) and update the state."""
        msg = self.conn.recv_match(blocking=True, timeout=self.quiet_s)
        now = time.monotonic()
        if msg is None:
            if now - self._last_wall > self.stall_wall_s:
                raise UserError(self.stall_text)
            self._quiet()
            return None
        if msg.get_type() == "BAD_DATA":
            return msg
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self.source:
            return msg
        self._last_wall = now
        self._update(msg)
        for listener in self.listeners:
            listener(msg)
        return msg

    def wait_for(
        self,
        done: Callable[[], bool],
        sim_timeout_s: float,
        what: str,
        tick: Callable[[], None] | None = None,
    ) -> None:
        """Pump until ``done()``; ``tick()`` after every message from the autopilot; a
        UserError (:meth:`_not_done_text`) after ``sim_timeout_s`` of the autopilot's clock."""
        deadline = self.state.boot_s + sim_timeout_s
        while not done():
            if self.state.boot_s > deadline:
                raise UserError(self._not_done_text(what, sim_timeout_s))
            if self.pump() is not None and tick is not None:
                tick()

    def hold(self, sim_s: float, tick: Callable[[], None] | None = None) -> None:
        """Let ``sim_s`` seconds of the autopilot's clock pass (ticking)."""
        end = self.state.boot_s + sim_s
        self.wait_for(lambda: self.state.boot_s >= end, sim_s + 30.0, "hold", tick)

    def _not_done_text(self, what: str, sim_timeout_s: float) -> str:
        raise NotImplementedError

    def _quiet(self) -> None:
        """A receive timed out (the stall not yet reached)."""

    def _update(self, msg: Any) -> None:
        raise NotImplementedError
