"""What the autopilots would say is left, on the same battery readings (for comparison).

- **PX4-style**: the charge counted against the configured capacity, blended each reading
  with a charge read off the voltage (linear between 3.5 and 4.05 V per cell, the voltage
  raised by I·R first) by the weight 0.03·(1 − SoC_voltage), as PX4's battery library does
  (``Battery::estimateStateOfCharge``); time left = charge above the reserve / the current
  averaged over the last 50 s.
- **ArduPilot**: its own ``battery_remaining`` (BATTERY_STATUS, % of BATT_CAPACITY counted
  down by the consumed charge); time left = charge above the reserve / the same 50 s current.

Both count against the label: that is the point of the comparison. Times in s, charges as
fractions of the configured capacity.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

from estimator.physics.vehicle import BatterySpec
from estimator.telemetry.samples import BatterySample

#: PX4's defaults: empty and full cell voltage under no load (BAT_V_EMPTY, BAT_V_CHARGED, V).
PX4_V_EMPTY = 3.5
PX4_V_CHARGED = 4.05
#: Weight of the voltage-based charge per reading, times (1 − that charge).
PX4_VOLTAGE_WEIGHT = 0.03
#: Window of the current average (s).
AVERAGE_S = 50.0


def peer_endurance_s(
    samples: Iterable[BatterySample], spec: BatterySpec, resistance_ohm: float
) -> list[tuple[float, float, float]]:
    """(time s, PX4-style endurance s, ArduPilot's endurance s) at each reading with a
    current; ``resistance_ohm``: the pack resistance PX4 would have estimated (Ω)."""
    out: list[tuple[float, float, float]] = []
    window: deque[tuple[float, float]] = deque()
    px4_soc: float | None = None
    last: BatterySample | None = None
    for s in samples:
        if s.current_a is None:
            continue
        window.append((s.time_s, s.current_a))
        while window[0][0] < s.time_s - AVERAGE_S:
            window.popleft()
        mean_a = sum(a for _, a in window) / len(window)
        cell_v = (s.voltage_v + s.current_a * resistance_ohm) / spec.cells
        soc_v = min(max((cell_v - PX4_V_EMPTY) / (PX4_V_CHARGED - PX4_V_EMPTY), 0.0), 1.0)
        if px4_soc is None or last is None:
            px4_soc = soc_v
        else:
            drawn_ah = s.current_a * max(s.time_s - last.time_s, 0.0) / 3600.0
            px4_soc -= drawn_ah / spec.capacity_ah
            weight = PX4_VOLTAGE_WEIGHT * (1.0 - soc_v)
            px4_soc = (1.0 - weight) * px4_soc + weight * soc_v
        last = s
        ardupilot_soc = None if s.remaining_pct is None else s.remaining_pct / 100.0
        out.append(
            (
                s.time_s,
                _time_left_s(px4_soc, spec, mean_a),
                float("nan")
                if ardupilot_soc is None
                else _time_left_s(ardupilot_soc, spec, mean_a),
            )
        )
    return out


def _time_left_s(soc: float, spec: BatterySpec, mean_a: float) -> float:
    """Charge above the reserve (of the configured capacity) over the mean current (s)."""
    if mean_a <= 0.5:
        return float("inf")
    return max(soc - spec.reserve_fraction, 0.0) * spec.capacity_ah * 3600.0 / mean_a
