"""The names under which input that was not believed is counted and skipped: by the value
and time checks (:mod:`estimator.telemetry.plausibility`) and the telemetry decoder
(:mod:`estimator.telemetry.decode`: positions and home too). The daemon logs them, a log's
``checks`` holds them. No imports: the log readers take it without pymavlink.
"""

from __future__ import annotations

SKIP_COUNTERS = (
    "velocity_not_finite",
    "velocity_beyond_limits",
    "velocity_jump",
    "altitude_implausible",
    "voltage_implausible",
    "current_implausible",
    "consumed_implausible",
    "wind_implausible",
    "position_implausible",
    "home_implausible",
    "time_jump",
)
