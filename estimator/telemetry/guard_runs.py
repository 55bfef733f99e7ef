"""How many leading samples of a batch a :class:`~estimator.telemetry.plausibility.SampleGuard`
would pass untouched, found column-wise.

Checked one by one, most samples of a log change nothing but the guard's clock (s since boot)
and its believed velocity: their values are within the limits, their stamp is within the
running clock's window, and a velocity (NED, m/s) is reachable from the one before. This
finds how many leading samples of a batch are all such, with numpy over the batch's columns
instead of a Python call chain per sample; the guard then moves its state past them as the
one-by-one checks would, and checks the first other sample itself.

The comparisons are the scalar checks' own float operations, so they decide alike, except
the norms: numpy's ``hypot`` and Euclidean distance may differ from ``math.hypot`` and
``math.dist`` in the last bit, so a norm within :data:`NORM_MARGIN` (relative) of its limit
ends the run and is left to the scalar check.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from estimator.telemetry.sample_columns import KINDS, OTHER, SampleColumns
from estimator.telemetry.samples import BatterySample, VelocitySample, WindSample

if TYPE_CHECKING:
    from estimator.telemetry.clock import ClockSettings
    from estimator.telemetry.plausibility import InputLimits

#: Relative margin by which a numpy norm must be within its limit to be decided here.
NORM_MARGIN = 1e-9

_VELOCITY = KINDS[VelocitySample]


@dataclass(frozen=True, slots=True)
class GuardLimits:
    """What the run is judged by: the value limits, the clock's window (s) and the velocity
    jump limits (m/s, m/s²), and the highest wind (m/s)."""

    values: InputLimits
    clock: ClockSettings
    step_floor_mps: float
    max_acceleration_mps2: float
    max_wind_mps: float


#: :class:`RunSearch`: the samples a run is looked for in, at first and at most; the run
#: worth a search (a search costs about what checking a few dozen samples one by one
#: does); the samples checked one by one after a run stops, at first and at most.
FIRST_RUN_WINDOW = 64
MAX_RUN_WINDOW = 4096
WORTHWHILE_RUN = 128
SEQUENTIAL_SPAN = 16
MAX_SEQUENTIAL_SPAN = 1024


@dataclass(slots=True)
class RunSearch:
    """Where a guard looks for clean runs: in a ``window`` of samples, doubled while it is
    clean; after a run stops, ``one_by_one`` samples (``span``, doubled after each run of
    fewer than :data:`WORTHWHILE_RUN` samples, reset after a longer one) are checked one by
    one before the next search, so a hostile stream costs about what checking every sample
    one by one does. ``clean``: the samples of the run so far (it may span searches)."""

    window: int = FIRST_RUN_WINDOW
    span: int = SEQUENTIAL_SPAN
    one_by_one: int = 0
    clean: int = 0

    def stopped(self, run: int, looked_at: int) -> None:
        """A search found ``run`` clean samples at the head of ``looked_at``."""
        self.clean += run
        if run == looked_at:
            self.window = min(2 * self.window, MAX_RUN_WINDOW)
            return
        short, self.clean, self.window = self.clean < WORTHWHILE_RUN, 0, FIRST_RUN_WINDOW
        self.span = min(2 * self.span, MAX_SEQUENTIAL_SPAN) if short else SEQUENTIAL_SPAN
        self.one_by_one = self.span


def clean_run(
    columns: SampleColumns,
    clock_s: float,
    believed: VelocitySample | None,
    limits: GuardLimits,
) -> int:
    """The number of leading samples (``columns``, one row each) each of which passes the
    value checks, is stamped within the clock's window (the clock at ``clock_s`` s, moving
    forward with each stamp) and, if a velocity, is reachable from the velocity before it
    (``believed`` for the first; None: any). A sample of another type than those of
    :data:`~estimator.telemetry.sample_columns.KINDS` ends the run."""
    kinds = columns.kinds
    ok = (kinds != OTHER) & _stamps_in_window(columns.time_s, clock_s, limits.clock)
    for kind, check in _VALUE_CHECKS.items():
        rows = np.flatnonzero(kinds == kind)
        if len(rows):
            ok[rows] &= check(columns, rows, limits)
    rows = np.flatnonzero(kinds == _VELOCITY)
    if len(rows):
        vn, ve, vd = (columns.values[name][rows] for name in ("vn_mps", "ve_mps", "vd_mps"))
        time_s = columns.time_s[rows]
        if believed is not None:
            vn, ve, vd, time_s = (
                np.concatenate(([first], column))
                for first, column in zip(
                    (believed.vn_mps, believed.ve_mps, believed.vd_mps, believed.time_s),
                    (vn, ve, vd, time_s),
                    strict=True,
                )
            )
        reachable = _reachable(vn, ve, vd, time_s, limits)
        ok[rows[len(rows) - len(reachable) :]] &= reachable
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if len(bad) else len(kinds)


def _stamps_in_window(time_s: np.ndarray, clock_s: float, clock: ClockSettings) -> np.ndarray:
    """Each stamp within [clock − backstep, clock + max step] of the clock before it."""
    before = np.maximum.accumulate(np.concatenate([[clock_s], time_s[:-1]]))
    return (before - clock.backstep_s <= time_s) & (time_s <= before + clock.max_step_s)


def _velocities_plausible(
    columns: SampleColumns, rows: np.ndarray, limits: GuardLimits
) -> np.ndarray:
    vn, ve, vd, alt_m = (
        columns.values[name][rows] for name in ("vn_mps", "ve_mps", "vd_mps", "alt_m")
    )
    has_alt = columns.known["alt_m"][rows]
    lim = limits.values
    with np.errstate(all="ignore"):
        return (
            np.isfinite(vn)
            & np.isfinite(ve)
            & np.isfinite(vd)
            & (np.hypot(vn, ve) * (1 + NORM_MARGIN) <= lim.max_speed_mps)
            & (np.abs(vd) <= lim.max_vertical_speed_mps)
            & (~has_alt | (np.isfinite(alt_m) & (np.abs(alt_m) <= lim.max_abs_alt_m)))
        )


def _batteries_plausible(
    columns: SampleColumns, rows: np.ndarray, limits: GuardLimits
) -> np.ndarray:
    lim = limits.values
    volt, amp, mah = (
        columns.values[name][rows] for name in ("voltage_v", "current_a", "consumed_mah")
    )
    has_i, has_q = (columns.known[name][rows] for name in ("current_a", "consumed_mah"))
    with np.errstate(all="ignore"):
        current_ok = (
            np.isfinite(amp)
            & (lim.min_current_a <= amp)
            & (amp <= lim.max_current_a)
            & (volt * amp <= lim.max_power_w)
        )
        return (
            np.isfinite(volt)
            & (lim.min_voltage_v < volt)
            & (volt <= lim.max_voltage_v)
            & (~has_i | current_ok)
            & (~has_q | (np.isfinite(mah) & (mah >= 0.0) & (mah <= lim.max_consumed_mah)))
        )


def _winds_plausible(columns: SampleColumns, rows: np.ndarray, limits: GuardLimits) -> np.ndarray:
    n, e = (columns.values[name][rows] for name in ("wind_n_mps", "wind_e_mps"))
    with np.errstate(all="ignore"):
        return (
            np.isfinite(n)
            & np.isfinite(e)
            & (np.hypot(n, e) * (1 + NORM_MARGIN) <= limits.max_wind_mps)
        )


def _reachable(
    vn: np.ndarray, ve: np.ndarray, vd: np.ndarray, time_s: np.ndarray, limits: GuardLimits
) -> np.ndarray:
    """For each velocity (NED m/s, stamped ``time_s`` s) after the first, whether it is
    reachable from the one before it: a step no larger than the floor plus the acceleration
    limit over the time between them."""
    with np.errstate(all="ignore"):
        step_mps = np.sqrt(np.diff(vn) ** 2 + np.diff(ve) ** 2 + np.diff(vd) ** 2)
        reach_mps = limits.step_floor_mps + limits.max_acceleration_mps2 * np.maximum(
            time_s[1:] - time_s[:-1], 0.0
        )
        return np.asarray(step_mps * (1 + NORM_MARGIN) <= reach_mps)


_VALUE_CHECKS = {
    KINDS[VelocitySample]: _velocities_plausible,
    KINDS[BatterySample]: _batteries_plausible,
    KINDS[WindSample]: _winds_plausible,
}
