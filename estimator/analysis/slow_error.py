"""The power model's slow error on flights it describes: how far its prediction stays off over
tens of seconds, which no averaging of the telemetry removes. A vehicle file states it as
``[model] slow_error_fraction`` (1σ as a fraction of the model's hover power); the online
tracker takes it as a correlated error (:mod:`estimator.estimation.online_effects`) so that its
mass and wind do not claim a precision the model does not have.

Measured here as the standard deviation of the residual's (measured − predicted power, W)
means over consecutive windows of :data:`WINDOW_S` seconds of each flight (windows with fewer
than :data:`MIN_SAMPLES` samples are left out), pooled over the flights.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from estimator.physics.model import FloatArray

#: The window (s): several times the telemetry noise's 1-2 s correlation, so its mean is
#: nearly free of the noise, short beside a flight.
WINDOW_S = 10.0
MIN_SAMPLES = 5


def window_means_w(
    time_s: FloatArray, residual_w: FloatArray, window_s: float = WINDOW_S
) -> FloatArray:
    """Means of ``residual_w`` (W) over consecutive windows of ``window_s`` from the first
    time (s), for windows with at least :data:`MIN_SAMPLES` samples."""
    t = np.asarray(time_s, dtype=float)
    window = np.floor((t - t.min()) / window_s).astype(np.int64)
    counts = np.bincount(window)
    sums = np.bincount(window, weights=np.asarray(residual_w, dtype=float))
    full = counts >= MIN_SAMPLES
    return np.asarray(sums[full] / counts[full], dtype=float)


def slow_error_fraction(
    flights: Sequence[tuple[FloatArray, FloatArray]], hover_power_w: float
) -> float:
    """1σ of the window means of each flight's (time s, residual W), pooled, over the hover
    power (W)."""
    means = np.concatenate([window_means_w(t, r) for t, r in flights])
    if len(means) < 2 or hover_power_w <= 0:
        raise ValueError("need at least two windows and a positive hover power")
    return float(np.std(means, ddof=1)) / hover_power_w
