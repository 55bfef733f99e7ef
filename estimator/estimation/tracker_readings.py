"""Which power readings a step of the online tracker
(:mod:`estimator.estimation.online_effects`) takes.

A reading is a measured electrical power (W) with the filtered flight state then (NED m/s and
m/s², s of the autopilot's clock) and the battery voltage (V). Left out, each counted: readings
that are not finite or go back in time before the tracker's last step (``rejected``); in fast
vertical motion (|v_z| above ``max_vertical_speed_mps``) or vertical acceleration (|a_z|
above the tracker's limit) (``vertical``); below ``min_power_fraction_of_hover`` of the model's
hover power, idling motors (``idle``). And when the vertical gates left out more than
``max_vertical_share`` of a step's readings, the rest too (``vertical``): a climb or descent
starts or ends within the step, the power leads the filtered state by about half a second, and
the readings the gates kept are the transition's.

:func:`step_data` then makes of the kept readings what a filter step needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from estimator.estimation.form_error import form_power_w
from estimator.estimation.online_settings import OnlineSettings
from estimator.physics.kinematics import KinematicState

#: A kept reading's motion: time (s), velocity north, east, down (m/s), acceleration north
#: and east (m/s²).
Motion = tuple[float, float, float, float, float, float]


class TrackerReading(NamedTuple):
    """One measured power (W) with the filtered flight state then and the battery voltage
    (V, NaN unknown)."""

    state: KinematicState
    measured_power_w: float
    voltage_v: float = math.nan


class Selection(NamedTuple):
    """A step's readings the tracker takes, each with its motion, in time order; and how many
    were left out, by cause."""

    kept: list[tuple[TrackerReading, Motion]]
    rejected: int
    vertical: int
    idle: int


def select_readings(
    readings: Sequence[TrackerReading],
    settings: OnlineSettings,
    last_time_s: float | None,
    max_vertical_accel_mps2: float,
    hover_power_w: float,
) -> Selection:
    """The readings of one step the tracker takes. ``last_time_s``: the tracker's last step
    (s; None before the first)."""
    s = settings
    kept = []
    rejected = vertical = idle = 0
    for r in readings:
        st = r.state
        motion = (st.time_s, st.vn_mps, st.ve_mps, st.vd_mps, st.an_mps2, st.ae_mps2)
        if not all(math.isfinite(v) for v in (*motion, r.measured_power_w)) or (
            last_time_s is not None and st.time_s < last_time_s
        ):
            rejected += 1
        elif abs(st.vd_mps) > s.max_vertical_speed_mps or abs(st.ad_mps2) > max_vertical_accel_mps2:
            vertical += 1
        elif r.measured_power_w < s.min_power_fraction_of_hover * hover_power_w:
            idle += 1
        else:
            kept.append((r, motion))
    if vertical > s.max_vertical_share * len(readings):
        return Selection([], rejected, vertical + len(kept), idle)
    return Selection(kept, rejected, vertical, idle)


class StepData(NamedTuple):
    """One filter step's data: readings' flight-state rows (k × 9, the FlightState fields),
    their mean measured power (W) and its noise variance (W²), whether the vehicle moves
    (else hovers), and the model form's power error h there (W, 1σ:
    :mod:`~estimator.estimation.form_error`)."""

    rows: np.ndarray
    measured_w: float
    noise_var_w2: float
    moving: bool
    form_w: float


def step_data(
    kept: Sequence[tuple[TrackerReading, Motion]],
    settings: OnlineSettings,
    mass_kg: float,
    extra_noise_var_w2: float,
    wind_ne_mps: np.ndarray,
    hover_power_w: float,
) -> StepData:
    """A step's data from its ``kept`` readings (not empty): the noise of their mean power is
    each reading's (a floor, a fraction of the power, the kinetic term's m·V·σ_a with
    ``mass_kg``) over the count squared plus the learnt ``extra_noise_var_w2`` (W², not
    divided: model error does not average out); the form error at the estimate's wind
    ``wind_ne_mps`` (m/s, north and east)."""
    s = settings
    n = len(kept)
    rows = np.array(
        [(*motion, 0.0, r.voltage_v, r.state.ad_mps2) for r, motion in kept], dtype=float
    )
    measured, speed, accel_sigma = np.array(
        [(r.measured_power_w, r.state.speed_mps, r.state.accel_sigma_mps2) for r, _ in kept]
    ).T
    kinetic_sd = mass_kg * (speed * accel_sigma)
    r_each = s.power_noise_w**2 + (s.power_noise_fraction * measured) ** 2 + kinetic_sd**2
    # means as sum / n: numpy's mean, the same float, without its cost per call
    return StepData(
        rows,
        float(measured.sum()) / n,
        float(r_each.sum()) / n**2 + extra_noise_var_w2,
        float(speed.sum()) / n > s.moving_speed_mps,
        form_power_w(
            rows,
            wind_ne_mps,
            hover_power_w,
            s.speed_form_sigma_fraction,
            s.speed_form_reference_mps,
        ),
    )
