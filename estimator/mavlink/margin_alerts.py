"""STATUSTEXT warnings to the ground stations when the return margin crosses a threshold.

Levels: OK, WARNING (margin below ``warning_wh``), CRITICAL (below ``critical_wh``). A level
is entered when the margin falls below its threshold and left only when the margin rises
``hysteresis_wh`` above it, so a margin hovering at a threshold warns once. A message goes out
once per crossing into a higher level (WARNING → severity MAV_SEVERITY_WARNING, CRITICAL →
MAV_SEVERITY_CRITICAL); falling back is logged, not sent. Estimates whose margin is unknown
(no home, no position), stale, or not yet in flight (:attr:`Estimate.endurance_valid`) leave
the level as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.estimate import Estimate

OK, WARNING, CRITICAL = 0, 1, 2
SEVERITY = {WARNING: mavlink.MAV_SEVERITY_WARNING, CRITICAL: mavlink.MAV_SEVERITY_CRITICAL}
#: STATUSTEXT carries at most 50 characters in one message.
TEXT_CHARS = 50


@dataclass(frozen=True, slots=True)
class Alert:
    """A crossing to announce: MAV_SEVERITY and the text (≤ 50 characters)."""

    severity: int
    text: str


class MarginAlerts:
    """Thresholds and hysteresis in Wh of usable energy above the reserve."""

    def __init__(self, warning_wh: float, critical_wh: float, hysteresis_wh: float) -> None:
        self._thresholds_wh = {WARNING: warning_wh, CRITICAL: critical_wh}
        self._hysteresis_wh = hysteresis_wh
        self.level = OK
        self.sent = 0  # alerts raised so far

    def update(self, estimate: Estimate) -> Alert | None:
        """The alert this estimate raises, if it crosses into a higher level."""
        margin = estimate.margin_wh
        if not math.isfinite(margin) or estimate.stale or not estimate.endurance_valid:
            return None
        level = self.level
        while level > OK and margin > self._thresholds_wh[level] + self._hysteresis_wh:
            level -= 1
        while level < CRITICAL and margin < self._thresholds_wh[level + 1]:
            level += 1
        raised = level > self.level
        self.level = level
        if not raised:
            return None
        self.sent += 1
        what = "RTH CRITICAL" if level == CRITICAL else "RTH warning"
        text = f"{what}: margin {margin:.1f}Wh, home {estimate.rth_energy_wh:.1f}Wh"
        return Alert(SEVERITY[level], text[:TEXT_CHARS])
