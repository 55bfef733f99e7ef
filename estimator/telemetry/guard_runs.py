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
from itertools import repeat
from operator import attrgetter, is_not
from typing import TYPE_CHECKING

import numpy as np

from estimator.telemetry import samples as sample_types
from estimator.telemetry.samples import BatterySample, Sample, VelocitySample, WindSample

if TYPE_CHECKING:
    from estimator.telemetry.plausibility import ClockSettings, InputLimits

#: Relative margin by which a numpy norm must be within its limit to be decided here.
NORM_MARGIN = 1e-9

_ALT = attrgetter("alt_m")
_CURRENT = attrgetter("current_a")
_CONSUMED = attrgetter("consumed_mah")
#: Sample types a run may hold, by code: those with value checks, and those without
#: (any other type, a RebootSample among them, ends a run).
_OTHER = -1
_KINDS = {
    VelocitySample: 1,
    BatterySample: 2,
    WindSample: 3,
    **dict.fromkeys(
        (
            sample_types.ArmedSample,
            sample_types.LandedSample,
            sample_types.GripperSample,
            sample_types.PositionSample,
            sample_types.HomeSample,
            sample_types.MissionCurrentSample,
        ),
        0,
    ),
}


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
    samples: list[Sample],
    clock_s: float,
    believed: VelocitySample | None,
    limits: GuardLimits,
) -> int:
    """The number of leading ``samples`` each of which passes the value checks, is stamped
    within the clock's window (the clock at ``clock_s`` s, moving forward with each stamp)
    and, if a velocity, is reachable from the velocity before it (``believed`` for the
    first; None: any). A sample of another type than those of :data:`_KINDS` ends the run."""
    n = len(samples)
    kinds = np.fromiter(map(_KINDS.get, map(type, samples), repeat(_OTHER)), np.int8, n)
    ok = (kinds != _OTHER) & _stamps_in_window(_column(samples, "time_s"), clock_s, limits.clock)
    for kind, check in _VALUE_CHECKS.items():
        rows = np.flatnonzero(kinds == kind)
        if len(rows):
            ok[rows] &= check([samples[i] for i in rows], limits)
    rows = np.flatnonzero(kinds == _KINDS[VelocitySample])
    if len(rows):
        chain = [samples[i] for i in rows]
        if believed is not None:
            chain.insert(0, believed)
        reachable = _reachable(chain, limits)
        ok[rows[len(rows) - len(reachable) :]] &= reachable
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if len(bad) else n


def _column(samples: list[Sample], name: str) -> np.ndarray:
    """The float field ``name`` of each sample."""
    return np.fromiter(map(attrgetter(name), samples), dtype=np.float64, count=len(samples))


def _velocity(samples: list[Sample]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return _column(samples, "vn_mps"), _column(samples, "ve_mps"), _column(samples, "vd_mps")


def _stamps_in_window(time_s: np.ndarray, clock_s: float, clock: ClockSettings) -> np.ndarray:
    """Each stamp within [clock − backstep, clock + max step] of the clock before it."""
    before = np.maximum.accumulate(np.concatenate([[clock_s], time_s[:-1]]))
    return (before - clock.backstep_s <= time_s) & (time_s <= before + clock.max_step_s)


def _velocities_plausible(samples: list[Sample], limits: GuardLimits) -> np.ndarray:
    vn, ve, vd = _velocity(samples)
    has_alt, alt_m = _optional(list(map(_ALT, samples)))
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


def _batteries_plausible(samples: list[Sample], limits: GuardLimits) -> np.ndarray:
    lim = limits.values
    volt = _column(samples, "voltage_v")
    has_i, amp = _optional(list(map(_CURRENT, samples)))
    has_q, mah = _optional(list(map(_CONSUMED, samples)))
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


def _optional(values: list[float | None]) -> tuple[np.ndarray, np.ndarray]:
    """(known, value): which of ``values`` are not None, and the values (0 where None)."""
    known = np.fromiter(map(is_not, values, repeat(None)), dtype=bool, count=len(values))
    if known.all():
        return known, np.array(values, dtype=np.float64)
    return known, np.array([0.0 if x is None else x for x in values], dtype=np.float64)


def _winds_plausible(samples: list[Sample], limits: GuardLimits) -> np.ndarray:
    n, e = _column(samples, "wind_n_mps"), _column(samples, "wind_e_mps")
    with np.errstate(all="ignore"):
        return (
            np.isfinite(n)
            & np.isfinite(e)
            & (np.hypot(n, e) * (1 + NORM_MARGIN) <= limits.max_wind_mps)
        )


def _reachable(chain: list[Sample], limits: GuardLimits) -> np.ndarray:
    """For each velocity of ``chain`` after the first, whether it is reachable from the one
    before it: a step no larger than the floor plus the acceleration limit over the time
    between them."""
    vn, ve, vd = _velocity(chain)
    t = _column(chain, "time_s")
    with np.errstate(all="ignore"):
        step_mps = np.sqrt(np.diff(vn) ** 2 + np.diff(ve) ** 2 + np.diff(vd) ** 2)
        reach_mps = limits.step_floor_mps + limits.max_acceleration_mps2 * np.maximum(
            t[1:] - t[:-1], 0.0
        )
        return np.asarray(step_mps * (1 + NORM_MARGIN) <= reach_mps)


_VALUE_CHECKS = {
    _KINDS[VelocitySample]: _velocities_plausible,
    _KINDS[BatterySample]: _batteries_plausible,
    _KINDS[WindSample]: _winds_plausible,
}
