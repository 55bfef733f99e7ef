"""A STATUSTEXT warning to the ground stations when the pack disagrees with its label.

When the learned capacity (:attr:`Estimate.capacity_ah`) lies more than ``sigmas`` σ from the
configured (label) one, the pack is not the one in the vehicle file (aged, another pack):
one WARNING goes out, "pack holds ~3.0Ah, configured 4.0Ah". It re-arms only once the
learned capacity is back within ``rearm_sigmas`` σ of the label (hysteresis), so a capacity
hovering at the threshold warns once. Stale estimates leave it as it is.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.estimate import Estimate
from estimator.mavlink.margin_alerts import TEXT_CHARS, Alert


class PackLabelAlert:
    """The label warning for a pack labelled ``label_ah`` (Ah)."""

    def __init__(self, label_ah: float, sigmas: float = 3.0, rearm_sigmas: float = 2.0) -> None:
        self.label_ah = label_ah
        self.sigmas = sigmas
        self.rearm_sigmas = rearm_sigmas
        self.active = False
        self.sent = 0

    def update(self, estimate: Estimate) -> Alert | None:
        """The warning this estimate raises, if the pack has just left its label."""
        capacity, sigma = estimate.capacity_ah, estimate.capacity_sigma_ah
        if estimate.stale or not (math.isfinite(capacity) and math.isfinite(sigma)):
            return None
        off = abs(capacity - self.label_ah)
        if self.active:
            self.active = off > self.rearm_sigmas * sigma
            return None
        if sigma <= 0 or off <= self.sigmas * sigma:
            return None
        self.active = True
        self.sent += 1
        text = f"pack holds ~{capacity:.1f}Ah, configured {self.label_ah:.1f}Ah"
        return Alert(mavlink.MAV_SEVERITY_WARNING, text[:TEXT_CHARS])
