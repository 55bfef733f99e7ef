"""Receiving from a simulated autopilot, for the SITL pilots (ArduCopter and PX4): one
message at a time, a stall when the simulator says nothing for too long (wall clock), and
the autopilot's own messages folded into the pilot's state and handed to its listeners."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from estimator.errors import UserError


class Receiver:
    """Set by the pilot: ``conn`` (a pymavlink connection), ``source`` (the autopilot's
    system and component ids), ``quiet_s`` (wall seconds a receive waits),
    ``stall_wall_s`` and ``stall_text`` (the error after that long without a message from
    it); :meth:`_update` folds one of its messages into the pilot's state."""

    conn: Any
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

    def _quiet(self) -> None:
        """A receive timed out (the stall not yet reached)."""

    def _update(self, msg: Any) -> None:
        raise NotImplementedError
