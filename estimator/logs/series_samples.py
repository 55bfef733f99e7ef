"""A flight already read into aligned rows (:class:`~estimator.logs.FlightSeries`) as the
sample stream the daemon would have received, row by row: the autopilot's wind report when the
row has one, the arming state when it changes, the velocity, then the battery.

The battery reading is the row's voltage and current; where the source has only their product
(CMU: ``voltage_v`` and ``current_a`` NaN), ``voltage_v`` is the pack's nominal voltage given
and the current the power over it (power exact, V and I nominal). Rows without a finite
velocity or power are left out.

Units: s (the log's clock), m/s (NED), m, V, A, W.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from estimator.logs import FlightSeries
from estimator.physics.effects import Wind
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    Sample,
    VelocitySample,
    WindSample,
)


def series_samples(series: FlightSeries, nominal_voltage_v: float) -> Iterator[Sample]:
    """The samples of ``series`` in row order (module docstring)."""
    nan = [math.nan] * len(series)
    extras = series.extras
    armed_col = extras.get("armed", nan)
    wind_col = extras.get("autopilot_wind_speed_mps", nan)
    wind_from_col = extras.get("autopilot_wind_from_deg", nan)
    armed: bool | None = None
    for j in range(len(series)):
        t = float(series.time_s[j])
        vn, ve, power_w = float(series.vn_mps[j]), float(series.ve_mps[j]), float(series.power_w[j])
        if not (math.isfinite(vn) and math.isfinite(ve) and math.isfinite(power_w)):
            continue
        if math.isfinite(wind_col[j]):
            wind = Wind(float(wind_col[j]), float(wind_from_col[j]))
            yield WindSample(t, *wind.vector_ne_mps())
        if math.isfinite(armed_col[j]) and bool(armed_col[j]) is not armed:
            armed = bool(armed_col[j])
            yield ArmedSample(t, armed)
        vd, alt = float(series.vd_mps[j]), float(series.alt_m[j])
        yield VelocitySample(
            t, vn, ve, vd if math.isfinite(vd) else 0.0, alt if math.isfinite(alt) else None
        )
        voltage_v, current_a = float(series.voltage_v[j]), float(series.current_a[j])
        if not (math.isfinite(voltage_v) and math.isfinite(current_a)):
            voltage_v, current_a = nominal_voltage_v, power_w / nominal_voltage_v
        yield BatterySample(t, voltage_v, current_a)
