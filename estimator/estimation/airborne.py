"""Whether a power reading comes from flight: ground, take-off transient, or flying.

Readings on the ground (disarmed; on the ground by the autopilot's landed detector where it
reports one, PX4's EXTENDED_SYS_STATE, else below :data:`AIRBORNE_ALT_M` over home; or drawing
less than the idle share of the model's hover power: motors spinning up at arming while the
barometer drifts) and in the take-off transient (the first ``settle_s`` of flight and the
climb after it, until the vertical speed first falls to ``level_mps``: spool-up, ground
effect, and the climb term, the least certain part of the model, at its largest) carry no
information on the model's error in level flight, the figure the endurance is built on.
The fusion's bias and the online wind/mass tracker learn only from ``flying`` readings
(:class:`~estimator.estimation.pipeline.Pipeline`,
:func:`~estimator.estimation.track_runner.track_samples`);
before, the pipeline draws the measured power from the energy state, untied to the bias.
"""

from __future__ import annotations

import math
from enum import Enum

#: Above this height over home (m) an armed vehicle may be airborne.
AIRBORNE_ALT_M = 1.0
#: Power below this fraction of the model's hover power is not flight (idle motors).
IDLE_FRACTION_OF_HOVER = 0.3
#: Readings in the first this-many seconds after leaving the ground are take-off transient.
TAKEOFF_SETTLE_S = 5.0
#: ... and those of the take-off climb, until the vertical speed first falls to this (m/s).
LEVEL_MPS = 1.0


class Phase(Enum):
    GROUND = "ground"
    TAKEOFF = "takeoff"
    FLYING = "flying"


class AirborneGate:
    """Classifies readings in time order; ``since_s`` is when the current flight left the
    ground (sample clock, s; None on the ground). An unknown armed state, height or vertical
    speed (None) does not count against flight: a log without them is judged on the rest; a
    known landed state (the autopilot's detector) replaces the height test."""

    def __init__(
        self,
        hover_power_w: float,
        settle_s: float = TAKEOFF_SETTLE_S,
        level_mps: float = LEVEL_MPS,
    ) -> None:
        self.idle_below_w = IDLE_FRACTION_OF_HOVER * hover_power_w
        self.settle_s, self.level_mps = settle_s, level_mps
        self.since_s: float | None = None
        self._flying = False

    def phase(
        self,
        time_s: float,
        armed: bool | None,
        alt_m: float | None,
        power_w: float | None,
        vd_mps: float | None = None,
        on_ground: bool | None = None,
    ) -> Phase:
        """The phase of a reading at ``time_s`` (s) with the armed state, height over home
        (m), measured power (W, None without a current sensor), vertical speed (m/s NED,
        down positive) and the autopilot's landed state (None: it reports none) then."""
        if on_ground is None:
            on_ground = alt_m is not None and not alt_m > AIRBORNE_ALT_M
        ground = (
            armed is False
            or on_ground
            or (power_w is not None and not power_w >= self.idle_below_w)
        )
        if ground or not math.isfinite(time_s):
            self.reset()
            return Phase.GROUND
        if self.since_s is None or time_s < self.since_s:
            self.since_s, self._flying = time_s, False
        level = vd_mps is None or not abs(vd_mps) > self.level_mps
        self._flying |= time_s - self.since_s >= self.settle_s and level
        return Phase.FLYING if self._flying else Phase.TAKEOFF

    def reset(self) -> None:
        """On the ground, or a new clock (reboot): the next airborne reading starts a new
        take-off."""
        self.since_s, self._flying = None, False
