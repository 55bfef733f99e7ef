"""A pack that reports on a cadence locked to the autopilot clock, a reading at each second,
stamped a few ms early by one transport and late by the other (a link stamps
BATTERY_STATUS, which has no time, with the newest autopilot time): the energy each
transport's pipeline ends with (``tests/test_pipeline.py``; docs/daemon.md gives how far apart
they end, ``scripts/figures.py``'s ``period-end-apart``)."""

from __future__ import annotations

from estimator.estimation.pipeline import Pipeline
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import default_vehicle
from estimator.telemetry.samples import ArmedSample, BatterySample, Sample, VelocitySample

VEHICLE = default_vehicle()
FULL_V = float(PackModel(VEHICLE.battery).ocv_v(1.0))
#: How early and how late (s) the two transports stamp the reading at each whole second.
SHIFTS_S = (-0.003, 0.003)


def stream(shift_s: float) -> list[Sample]:
    """2 min at 8 m/s, 4 readings a second with the load changing; the reading at each whole
    second stamped ``shift_s`` off."""
    samples: list[Sample] = [
        VelocitySample(0.05 + 0.1 * j, 8.0, 0.0, 0.0, 20.0) for j in range(1200)
    ]
    consumed_mah = 0.0
    for k in range(1, 480):
        current_a = 20.0 + 6.0 * ((k // 3) % 4)
        consumed_mah += current_a * 0.25 / 3.6
        voltage_v = FULL_V - 0.02 * current_a - 0.002 * k
        stamp_s = 0.25 * k + (shift_s if k % 4 == 0 else 0.0)
        samples.append(BatterySample(stamp_s, voltage_v, current_a, consumed_mah))
    samples.sort(key=lambda s: s.time_s)
    return [BatterySample(0.0, FULL_V, 0.3, 0.0), ArmedSample(0.0, True), *samples]


def energy_left_wh(shift_s: float) -> float:
    """The remaining energy (Wh) of the last estimate of :func:`stream` ``(shift_s)``."""
    pipeline = Pipeline(VEHICLE)
    estimates = [e for s in stream(shift_s) if (e := pipeline.process(s)) is not None]
    assert pipeline.pack_state is not None
    return estimates[-1].energy_remaining_wh


def apart_pct() -> float:
    """How far apart (%) the two transports' energies end, of the early one's."""
    early_wh, late_wh = (energy_left_wh(s) for s in SHIFTS_S)
    return 100 * abs(late_wh / early_wh - 1)
