"""Page's two-sided CUSUM on a filter's normalised innovations: the online tracker's test
for a step (a payload picked up or released, a wind setting in).

Each step's normalised innovation ν = y/√S (unit variance while the filter is right) feeds
g⁺ ← max(0, g⁺ + ν − k), g⁻ ← max(0, g⁻ − ν − k), with drift k and threshold h: the
sequential test for a shift of the innovations' mean (E. S. Page, "Continuous inspection
schemes", Biometrika 41, 1954). With k = 0.5, h = 7 a filter that is right raises a false
alarm about once in 3 500 steps, two hours of the pipeline's 2 s steps; a shift of 3σ is
caught in about three steps, one of 7.5σ, like a 1 kg release, in one. Unitless (ν in σ).

A sum that grows beyond half the threshold (:meth:`ChangeDetector.half_way`) says the
innovations lean one way by more than the drift, still, and for long enough that a change may
be under way: with k = 0.5 one innovation of 4σ from rest gets there, or three of 2σ in a
row; after a lone outlier the sum stands high but falls.
"""

from __future__ import annotations


class ChangeDetector:
    """Two-sided CUSUM with drift ``drift_sigma`` (k) and threshold ``threshold_sigma`` (h)."""

    def __init__(self, drift_sigma: float, threshold_sigma: float) -> None:
        self.drift_sigma, self.threshold_sigma = drift_sigma, threshold_sigma
        self._up = self._down = 0.0
        self._last_nu = 0.0

    def alarm(self, nu: float) -> bool:
        """Fold in one normalised innovation; True on an alarm, which clears the sums."""
        k = self.drift_sigma
        self._last_nu = nu
        self._up, self._down = max(0.0, self._up + nu - k), max(0.0, self._down - nu - k)
        if max(self._up, self._down) <= self.threshold_sigma:
            return False
        self._up = self._down = 0.0
        return True

    def half_way(self) -> bool:
        """Whether a sum grew at the last innovation to beyond half the threshold (no alarm
        yet)."""
        half, k = 0.5 * self.threshold_sigma, self.drift_sigma
        return (self._up > half and self._last_nu > k) or (self._down > half and -self._last_nu > k)
