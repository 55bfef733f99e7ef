"""The turn the endurance figures assume continues: the centripetal acceleration the vehicle
has held for a while, not the one of this instant.

A waypoint corner lasts 1-3 s at 2-3 m/s²; counted as a steady turn it moves the steady power
by 5-10 % and the endurance with it, for the length of the corner. An orbit holds its a⊥.
:class:`HeldTurn` gives the smallest a⊥ over the last ``hold_s`` seconds (a running window
minimum over a monotonic deque, O(1) amortised per sample): an orbit's a⊥ after ``hold_s``,
about zero through a corner.
"""

from __future__ import annotations

from collections import deque

#: How long (s) a turn must be held to count as a steady one.
TURN_HOLD_S = 5.0


class HeldTurn:
    """Smallest centripetal acceleration (m/s², ≥ 0) over the last ``hold_s`` seconds of
    kinematic states (s, autopilot clock)."""

    def __init__(self, hold_s: float = TURN_HOLD_S) -> None:
        self.hold_s = hold_s
        self._window: deque[tuple[float, float]] = deque()  # (time_s, a⊥), a⊥ increasing
        self._start_s: float | None = None

    def update(self, time_s: float, accel_centripetal_mps2: float) -> float:
        """Add the state at ``time_s`` and return the held a⊥ (m/s²): zero until the window
        has been filled once."""
        window = self._window
        while window and window[-1][1] >= accel_centripetal_mps2:
            window.pop()
        window.append((time_s, accel_centripetal_mps2))
        while window[0][0] < time_s - self.hold_s:
            window.popleft()
        if self._start_s is None or time_s < self._start_s:
            self._start_s = time_s
        return window[0][1] if time_s - self._start_s >= self.hold_s else 0.0

    def reset(self) -> None:
        """Forget the states (a reboot: the clock moved)."""
        self._window.clear()
        self._start_s = None
