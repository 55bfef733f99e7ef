"""Plausibility of telemetry: physical limits on values, and the checks a log reader's samples
go through.

A value outside :class:`InputLimits` (NaN, ±inf, a velocity no multirotor flies, a voltage or
current no pack of the vehicle gives) is a *reason* string; the caller counts it under that
name and skips the sample: it never reaches the filters. :class:`VelocityJumps` holds back a
velocity no airframe could reach from the last believed one until later samples confirm it.
:class:`SampleGuard` applies the value checks, the autopilot clock
(:mod:`estimator.telemetry.clock`) and the velocity jumps to a log reader's samples.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from estimator.telemetry.clock import ClockFilter, ClockVerdict
from estimator.telemetry.guard_runs import GuardLimits, RunSearch, clean_run
from estimator.telemetry.sample_columns import KINDS, SampleColumns
from estimator.telemetry.samples import (
    BatterySample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
)

#: Highest resting voltage of a charged lithium cell (LiHV 4.35 V) with margin, V per cell.
MAX_CELL_VOLTAGE_V = 4.5
#: Lowest voltage of a loaded lithium cell (a Li-ion cell's 2.5 V cut-off, sagging), V per cell.
MIN_CELL_VOLTAGE_V = 2.0
#: Range of a LiPo/Li-ion cell's voltage at rest or under moderate load (pack sanity), V.
CELL_VOLTAGE_RANGE_V = (3.0, 4.35)
#: Nominal cell voltage used to suggest a cell count, V.
NOMINAL_CELL_VOLTAGE_V = 3.8
#: Highest plausible electrical power as a multiple of the vehicle's hover power.
MAX_POWER_PER_HOVER = 10.0
#: The pack voltage believed goes down to the lowest voltage of this share of the vehicle
#: file's cells: a file with twice the pack's cells (6S for a 3S pack) stays a warning
#: (:func:`pack_voltage_problem`), not a daemon that believes no reading.
MIN_CELLS_FRACTION = 0.5
#: Charge current believed (A, negative): a current sensor's offset at rest, a brief
#: regenerative braking; at least this, or this share of the hover current.
MIN_CHARGE_ALLOWANCE_A = 1.0
CHARGE_ALLOWANCE_PER_HOVER = 0.1
#: Strongest wind (m/s) a multirotor flies in: blowing from behind, it adds to the airspeed
#: over ground (a gale, Beaufort 9, ends at 24.4 m/s).
MAX_TAILWIND_MPS = 30.0
#: Highest acceleration of a multirotor (m/s², about 3 g: racing quadrotors; the committed
#: flights reach 4.6 m/s²), and the velocity change (m/s) believed between two samples
#: whatever their spacing (GPS velocity noise, the autopilot's estimator resets).
MAX_ACCELERATION_MPS2 = 30.0
VELOCITY_STEP_FLOOR_MPS = 5.0
#: Velocity samples in a row that agree with each other but not with the believed velocity
#: after which the change is real (the last of them is believed).
JUMP_CONFIRM_SAMPLES = 3
#: A wind estimate above this (m/s) is not plausible and is skipped.
MAX_WIND_MPS = 60.0


@dataclass(frozen=True, slots=True)
class InputLimits:
    """Physical limits of a telemetry sample; beyond them a value is not believed.

    Defaults hold for any multirotor: horizontal ground speed ≤ 200 m/s (the fastest
    quadrotors fly about 160 m/s), |vertical speed| ≤ 100 m/s, |height over home| ≤ 20 km,
    pack voltage in (0, 150] V, current in [−20, 1000] A (a small negative current is a sensor
    offset), electrical power V·I ≤ 200 kW, consumed charge in [0, 10⁶] mAh. :meth:`for_pack`
    narrows voltage, current, power and speed to one vehicle; :meth:`any_current` opens
    current, power and consumed charge to any finite value (to say why a log's were refused).
    """

    max_speed_mps: float = 200.0
    max_vertical_speed_mps: float = 100.0
    max_abs_alt_m: float = 20_000.0
    min_voltage_v: float = 0.0
    max_voltage_v: float = 150.0
    min_current_a: float = -20.0
    max_current_a: float = 1000.0
    max_power_w: float = 200_000.0
    min_consumed_mah: float = 0.0
    max_consumed_mah: float = 1e6

    @classmethod
    def any_current(cls) -> InputLimits:
        """The default limits with any finite current, power and consumed charge believed."""
        return cls(
            min_current_a=-math.inf,
            max_current_a=math.inf,
            max_power_w=math.inf,
            min_consumed_mah=-math.inf,
            max_consumed_mah=math.inf,
        )

    @classmethod
    def for_pack(
        cls,
        cells: int,
        hover_power_w: float,
        cell_window_v: tuple[float, float] = (MIN_CELL_VOLTAGE_V, MAX_CELL_VOLTAGE_V),
        max_airspeed_mps: float | None = None,
    ) -> InputLimits:
        """Limits for a pack of ``cells`` lithium cells in series, each within
        ``cell_window_v`` (V, loaded to charged), feeding a vehicle that hovers at
        ``hover_power_w`` (W) and flies at most ``max_airspeed_mps`` (m/s; None: any
        multirotor's speed):

        - voltage from the lowest of :data:`MIN_CELLS_FRACTION` of the cells up to the
          highest of all of them;
        - power V·I at most :data:`MAX_POWER_PER_HOVER` × hover power, current at most that
          power at the lowest voltage, and down to minus the charge allowance
          (:data:`MIN_CHARGE_ALLOWANCE_A`, :data:`CHARGE_ALLOWANCE_PER_HOVER`);
        - ground speed at most the airspeed plus :data:`MAX_TAILWIND_MPS`.
        """
        limits = cls()
        if cells > 0:
            low_v, high_v = cell_window_v
            limits = replace(
                limits,
                min_voltage_v=MIN_CELLS_FRACTION * cells * low_v,
                max_voltage_v=cells * high_v,
            )
        if math.isfinite(hover_power_w) and hover_power_w > 0:
            max_power_w = MAX_POWER_PER_HOVER * hover_power_w
            limits = replace(limits, max_power_w=max_power_w)
            if cells > 0:
                hover_a = hover_power_w / (cells * NOMINAL_CELL_VOLTAGE_V)
                charge_a = max(MIN_CHARGE_ALLOWANCE_A, CHARGE_ALLOWANCE_PER_HOVER * hover_a)
                limits = replace(
                    limits,
                    min_current_a=-charge_a,
                    max_current_a=max_power_w / limits.min_voltage_v,
                )
        if max_airspeed_mps is not None and math.isfinite(max_airspeed_mps):
            limits = replace(limits, max_speed_mps=max_airspeed_mps + MAX_TAILWIND_MPS)
        return limits


def velocity_problem(sample: VelocitySample, limits: InputLimits) -> str | None:
    """Why ``sample`` is not believed (a counter name), or None when it is plausible."""
    v = (sample.vn_mps, sample.ve_mps, sample.vd_mps)
    if not all(math.isfinite(x) for x in v):
        return "velocity_not_finite"
    if math.hypot(v[0], v[1]) > limits.max_speed_mps or abs(v[2]) > limits.max_vertical_speed_mps:
        return "velocity_beyond_limits"
    alt = sample.alt_m
    if alt is not None and not (math.isfinite(alt) and abs(alt) <= limits.max_abs_alt_m):
        return "altitude_implausible"
    return None


def battery_problem(sample: BatterySample, limits: InputLimits) -> str | None:
    """Why ``sample`` is not believed (a counter name), or None when it is plausible."""
    v = sample.voltage_v
    if not (math.isfinite(v) and limits.min_voltage_v < v <= limits.max_voltage_v):
        return "voltage_implausible"
    i = sample.current_a
    if i is not None and not (
        math.isfinite(i)
        and limits.min_current_a <= i <= limits.max_current_a
        and v * i <= limits.max_power_w
    ):
        return "current_implausible"
    q = sample.consumed_mah
    if q is not None and not (
        math.isfinite(q) and limits.min_consumed_mah <= q <= limits.max_consumed_mah
    ):
        return "consumed_implausible"
    return None


def wind_problem(sample: WindSample) -> str | None:
    """Why ``sample`` is not believed (a counter name), or None when it is plausible."""
    n, e = sample.wind_n_mps, sample.wind_e_mps
    if not (math.isfinite(n) and math.isfinite(e) and math.hypot(n, e) <= MAX_WIND_MPS):
        return "wind_implausible"
    return None


class VelocityJumps:
    """Jump limits between consecutive velocity samples of one clock: a sample further from
    the believed velocity than :data:`MAX_ACCELERATION_MPS2` over the time between them
    (plus :data:`VELOCITY_STEP_FLOOR_MPS`) is an outlier, counted as ``velocity_jump`` and
    skipped; :data:`JUMP_CONFIRM_SAMPLES` outliers in a row that agree with each other by the
    same limits are a real change, the last of them believed. A RebootSample (a new clock)
    starts over."""

    def __init__(self, counts: Counter[str]) -> None:
        self.counts = counts
        self._believed: VelocitySample | None = None
        self._outliers: list[VelocitySample] = []

    def filter(self, samples: list[Sample]) -> list[Sample]:
        """``samples`` without the velocity outliers, in order."""
        out: list[Sample] = []
        for sample in samples:
            if isinstance(sample, RebootSample):
                self._believed, self._outliers = None, []
            elif isinstance(sample, VelocitySample) and not self._believe(sample):
                continue
            out.append(sample)
        return out

    def _believe(self, sample: VelocitySample) -> bool:
        believed = self._believed
        if believed is None or _reachable(believed, sample):
            self._believed, self._outliers = sample, []
            return True
        outliers = self._outliers
        if outliers and not _reachable(outliers[-1], sample):
            outliers.clear()
        outliers.append(sample)
        if len(outliers) >= JUMP_CONFIRM_SAMPLES:
            self._believed, self._outliers = sample, []
            return True
        self.counts["velocity_jump"] += 1
        return False


def _reachable(before: VelocitySample, after: VelocitySample) -> bool:
    """Whether a multirotor flying at ``before`` can fly at ``after`` (see
    :class:`VelocityJumps`)."""
    step_mps = math.dist(
        (before.vn_mps, before.ve_mps, before.vd_mps), (after.vn_mps, after.ve_mps, after.vd_mps)
    )
    dt_s = max(after.time_s - before.time_s, 0.0)
    return step_mps <= VELOCITY_STEP_FLOOR_MPS + MAX_ACCELERATION_MPS2 * dt_s


def fitting_cells(voltage_v: float) -> str:
    """The lithium cell counts a pack voltage (V) fits, each cell within
    :data:`CELL_VOLTAGE_RANGE_V`, in words: "4 cells", "4 or 5 cells", "no cell count"."""
    low, high = CELL_VOLTAGE_RANGE_V
    if not (math.isfinite(voltage_v) and voltage_v > 0):
        return "no cell count"
    counts = range(max(1, math.ceil(voltage_v / high)), math.floor(voltage_v / low) + 1)
    if not counts:
        return "no cell count"
    if len(counts) == 1:
        return f"{counts[0]} cell{'s' if counts[0] > 1 else ''}"
    return f"{', '.join(str(n) for n in counts[:-1])} or {counts[-1]} cells"


def pack_voltage_problem(voltage_v: float, cells: int) -> str | None:
    """A sentence when a pack voltage (V, at rest or light load) does not fit ``cells`` lithium
    cells in series — the vehicle file is for another pack — else None."""
    if cells <= 0 or not math.isfinite(voltage_v) or voltage_v <= 0:
        return None
    per_cell = voltage_v / cells
    low, high = CELL_VOLTAGE_RANGE_V
    if low <= per_cell <= high:
        return None
    fits = max(1, round(voltage_v / NOMINAL_CELL_VOLTAGE_V))
    return (
        f"pack voltage {voltage_v:.2f} V is {per_cell:.2f} V per cell for the vehicle file's "
        f"{cells} cells (a lithium cell holds {low:.2f}-{high:.2f} V): the energy estimates are "
        f"wrong; is [battery] cells right? ({fits} cells would fit)"
    )


class SampleGuard:
    """Value and time checks on a log reader's samples, each stamped with its own time: a
    sample beyond ``limits`` is dropped and counted under the reason; times go through a
    :class:`ClockFilter`, then velocities through :class:`VelocityJumps`. A RebootSample
    from the reader (a new flight) restarts the clock."""

    def __init__(self, limits: InputLimits | None = None) -> None:
        self.limits = limits or InputLimits()
        self.counts: Counter[str] = Counter()
        self._time = ClockFilter(self.counts)
        self._jumps = VelocityJumps(self.counts)
        self._run_limits = GuardLimits(
            self.limits,
            self._time.clock.settings,
            VELOCITY_STEP_FLOOR_MPS,
            MAX_ACCELERATION_MPS2,
            MAX_WIND_MPS,
        )
        self._search = RunSearch()

    def check(self, sample: Sample) -> list[Sample]:
        """The samples to deliver for ``sample`` (none, it, or held ones before it)."""
        if isinstance(sample, RebootSample):
            pending = self._time.take_pending()
            self._time = ClockFilter(self.counts)
            return self._jumps.filter([*pending, sample])
        problem = None
        if isinstance(sample, VelocitySample):
            problem = velocity_problem(sample, self.limits)
        elif isinstance(sample, BatterySample):
            problem = battery_problem(sample, self.limits)
        elif isinstance(sample, WindSample):
            problem = wind_problem(sample)
        if problem is not None:
            self.counts[problem] += 1
            return self._jumps.filter(self._time.take_pending())
        out = self._time.stamped(sample.time_s, sample)
        return [] if out is None else self._jumps.filter([*out, sample])

    def check_many(
        self, samples: list[Sample], columns: SampleColumns | None = None
    ) -> list[Sample]:
        """The samples to deliver for ``samples`` in turn, as :meth:`check` one by one would
        give them. Runs of samples that change nothing but the clock and the believed
        velocity are found column-wise (:func:`~estimator.telemetry.guard_runs.clean_run`,
        on ``columns`` when the reader gives the samples' columns, else on columns read from
        the samples), the other samples checked one by one;
        :class:`~estimator.telemetry.guard_runs.RunSearch` says where to look for a run and
        how many samples to check one by one."""
        out: list[Sample] = []
        start, search = 0, self._search
        while start < len(samples):
            if search.one_by_one:
                part = samples[start : start + search.one_by_one]
                for sample in part:
                    out += self.check(sample)
                start, search.one_by_one = start + len(part), search.one_by_one - len(part)
                continue
            window = samples[start : start + search.window]
            rows = None if columns is None else columns.rows(slice(start, start + len(window)))
            run = self._clean_run(window, rows)
            out += window[:run]
            start += run
            search.stopped(run, len(window))
        return out

    def _clean_run(self, samples: list[Sample], columns: SampleColumns | None) -> int:
        """How many leading ``samples`` are a clean run (moving the clock and velocity on)."""
        time, clock = self._time, self._time.clock
        if clock.time_s is None or clock.candidates or time.holding:
            return 0
        columns = SampleColumns.of_samples(samples) if columns is None else columns
        run = clean_run(columns, clock.time_s, self._jumps._believed, self._run_limits)
        if run:
            self._passed(samples, columns.rows(slice(0, run)))
        return run

    def _passed(self, samples: list[Sample], columns: SampleColumns) -> None:
        """Move the clock and the believed velocity past the clean run ``columns``."""
        clock = self._time.clock
        clock.advance(float(columns.time_s.max()))
        clock.joined = None
        self._time.verdict = ClockVerdict.ACCEPT
        velocities = np.flatnonzero(columns.kinds == KINDS[VelocitySample])
        if len(velocities):
            last = samples[int(velocities[-1])]
            assert isinstance(last, VelocitySample)
            self._jumps._believed, self._jumps._outliers = last, []

    def flush(self) -> list[Sample]:
        """End of the log: what is still held (see :meth:`ClockFilter.flush`)."""
        return self._jumps.filter(self._time.flush())
