"""Sanity checks of a whole log, each giving one warning sentence (never an error):

- vertical velocity against the altitude rate: on every pair of successive velocity samples
  (at most :data:`MAX_PAIR_GAP_S` apart) where the height changes by at least
  :data:`MIN_RATE_MPS` and the logged climb rate is as large, their signs should agree; a log
  where they disagree on most such pairs has its vertical velocity the wrong way up, and the
  climb power is predicted with the wrong sign (a Copter before 3.6 sends
  GLOBAL_POSITION_INT.vz positive up: the tlog reader reads it so once the firmware text or
  the messages' own height says so, :mod:`estimator.telemetry.vz_sense`, and its word on that
  is this check's warning; this finds what it cannot: other sources, too few climbs to tell);
- pack voltage against the vehicle file's cell count: the 95th percentile of the logged pack
  voltage (the pack near rest) per cell must lie where a lithium cell can
  (:func:`estimator.telemetry.plausibility.pack_voltage_problem`); else the energy figures are wrong
  (a 6-cell file on a 3-cell pack reads an empty pack: 0 Wh);
- the readers' own words on the file: a repair they undid before reading it
  (:mod:`estimator.logs.line_endings`), and an autopilot that flies no multirotor
  (:mod:`estimator.telemetry.vehicle_kind`).

:class:`SanityRecorder` collects what the checks need from a stream of samples (replay);
:func:`flight_warnings` runs them on :class:`~estimator.logs.FlightSeries` (fit, residuals).
A run over many logs says each cause once, with the number of logs it holds for
(:func:`flight_warnings`; :class:`RunWarnings` for replay, which warns as it reads).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from itertools import compress, repeat
from operator import attrgetter, is_
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from estimator.telemetry.plausibility import pack_voltage_problem
from estimator.telemetry.samples import BatterySample, RebootSample, Sample, VelocitySample
from estimator.telemetry.vz_sense import MAX_PAIR_GAP_S, MIN_RATE_MPS

if TYPE_CHECKING:  # the package imports this module
    from estimator.logs import FlightSeries

#: Fewest judged pairs for a verdict.
MIN_PAIRS = 5
#: Share of judged pairs whose signs disagree above which the log is warned about.
MAX_DISAGREEMENT = 0.5
#: Percentile of the pack voltage compared with the cell count (the pack near rest).
VOLTAGE_PERCENTILE = 95.0
_VELOCITY_FIELDS = attrgetter("time_s", "vd_mps", "alt_m")
_VOLTAGE = attrgetter("voltage_v")
#: The causes a warning is about (what :class:`RunWarnings` counts).
VERTICAL_VELOCITY, PACK_VOLTAGE = "vertical velocity", "pack voltage"
REPAIRED_FILE, VEHICLE = "repaired file", "vehicle"


def vertical_velocity_problem(
    time_s: ArrayLike, vd_mps: ArrayLike, alt_m: ArrayLike, source: str = "vertical velocity"
) -> str | None:
    """A sentence when the logged down-velocity (m/s, NED) disagrees in sign with the rate of
    the height over home (m) on most climbing or descending pairs, else None."""
    return _vertical_verdict(*rate_pairs(time_s, vd_mps, alt_m), source)


def rate_pairs(
    time_s: ArrayLike, vd_mps: ArrayLike, alt_m: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """(height rate, logged climb rate) in m/s of the successive sample pairs judged."""
    t = np.asarray(time_s, dtype=float)
    vd = np.asarray(vd_mps, dtype=float)
    alt = np.asarray(alt_m, dtype=float)
    if len(t) < 2:
        return np.empty(0), np.empty(0)
    dt = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.diff(alt) / dt
    climb = -0.5 * (vd[1:] + vd[:-1])
    judged = (
        (dt > 0)
        & (dt <= MAX_PAIR_GAP_S)
        & np.isfinite(rate)
        & np.isfinite(climb)
        & (np.abs(rate) >= MIN_RATE_MPS)
        & (np.abs(climb) >= MIN_RATE_MPS)
    )
    return rate[judged], climb[judged]


def _vertical_verdict(rate: np.ndarray, climb: np.ndarray, source: str) -> str | None:
    n = len(rate)
    if n < MIN_PAIRS:
        return None
    disagree = int(np.count_nonzero(np.sign(rate) != np.sign(climb)))
    if disagree <= MAX_DISAGREEMENT * n:
        return None
    corr = float(np.corrcoef(rate, climb)[0, 1])
    return (
        f"{source} disagrees in sign with the altitude rate on {disagree} of {n} climbing or "
        f"descending samples (correlation {corr:+.2f}): the log's vertical velocity looks "
        "positive up, so climb power is predicted with the wrong sign"
    )


def voltage_problem(voltage_v: ArrayLike, cells: int) -> str | None:
    """A sentence when the pack voltages (V) do not fit ``cells`` series cells, else None."""
    v = np.asarray(voltage_v, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    if not len(v):
        return None
    return pack_voltage_problem(float(np.percentile(v, VOLTAGE_PERCENTILE)), cells)


def flight_warnings(flights: Sequence[FlightSeries], cells: int | None = None) -> list[str]:
    """Warnings of :func:`vertical_velocity_problem` (one line for all flights, naming the
    first and counting the others) and of :func:`voltage_problem` over all flights (when
    ``cells`` is known)."""
    wrong_way = [
        (f.flight_id, problem)
        for f in flights
        if (problem := vertical_velocity_problem(f.time_s, f.vd_mps, f.alt_m)) is not None
    ]
    out = []
    if wrong_way:
        flight_id, problem = wrong_way[0]
        more = len(wrong_way) - 1
        out.append(
            f"{flight_id}: {problem}"
            + (f" (and in {more} more of the {len(flights)} flights)" if more else "")
        )
    if cells is not None and flights:
        voltages = np.concatenate([f.voltage_v for f in flights])
        if (problem := voltage_problem(voltages, cells)) is not None:
            out.append(problem)
    return out


class RunWarnings:
    """Which causes a run has warned about, over its logs (or flights): the first warning of
    a cause is said, the later ones counted."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def first(self, cause: str) -> bool:
        """Count a warning of ``cause``; True when it is the run's first (to be said)."""
        self.counts[cause] += 1
        return self.counts[cause] == 1

    def repeats(self, what: str = "logs") -> list[str]:
        """One line per cause warned about more than once: for how many more ``what`` (logs,
        attempts) it held."""
        return [
            f"the {cause} warning above holds for {n - 1} more {what} too"
            for cause, n in self.counts.items()
            if n > 1
        ]


class SanityRecorder:
    """Collects velocity and voltage from samples as they stream past (per autopilot boot)."""

    def __init__(self) -> None:
        self._velocity: list[list[tuple[float, float, float | None]]] = [[]]
        self._voltage_v: list[float] = []
        #: The reader's words on a vertical velocity it found sent the wrong way up and read
        #: right from then on, one for each time (:mod:`estimator.telemetry.vz_sense`).
        self.vertical_notes: list[str] = []
        #: The reader's word on damage to the file it undid before reading, else None.
        self.repair_note: str | None = None
        #: The reader's word on an autopilot that flies no multirotor
        #: (:mod:`estimator.telemetry.vehicle_kind`), else None.
        self.vehicle_note: str | None = None

    def observe(self, sample: Sample) -> None:
        if isinstance(sample, VelocitySample):
            alt = np.nan if sample.alt_m is None else sample.alt_m
            self._velocity[-1].append((sample.time_s, sample.vd_mps, alt))
        elif isinstance(sample, BatterySample):
            self._voltage_v.append(sample.voltage_v)
        elif isinstance(sample, RebootSample):
            self._velocity.append([])

    def observe_many(self, samples: list[Sample]) -> None:
        """:meth:`observe` each of ``samples`` in turn, in C loops over its fields."""
        types = list(map(type, samples))
        reboots = compress(range(len(samples)), map(is_, types, repeat(RebootSample)))
        start = 0
        for end in [*reboots, len(samples)]:
            boot = compress(samples[start:end], map(is_, types[start:end], repeat(VelocitySample)))
            self._velocity[-1].extend(map(_VELOCITY_FIELDS, boot))  # alt None: NaN when judged
            if end < len(samples):
                self._velocity.append([])
            start = end + 1
        batteries = compress(samples, map(is_, types, repeat(BatterySample)))
        self._voltage_v.extend(map(_VOLTAGE, batteries))

    def judged_pairs(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(height rate, logged climb rate) in m/s of the velocity sample pairs the vertical
        check judges (no pair spans a reboot); None before two samples of one boot."""
        pairs = [
            rate_pairs(*np.array(boot, dtype=float).T) for boot in self._velocity if len(boot) > 1
        ]
        if not pairs:
            return None
        rate, climb = (np.concatenate(column) for column in zip(*pairs, strict=True))
        return rate, climb

    def problems(
        self, cells: int | None = None, source: str = "vertical velocity"
    ) -> list[tuple[str, str]]:
        """The checks' (cause, warning) over what was observed (voltage only when ``cells``
        is known); no pair of velocity samples spans a reboot."""
        out = [] if self.repair_note is None else [(REPAIRED_FILE, self.repair_note)]
        if self.vehicle_note is not None:
            out.append((VEHICLE, self.vehicle_note))
        pairs = self.judged_pairs()
        if self.vertical_notes:  # the samples before the reader knew are wrong; one warning
            out.append((VERTICAL_VELOCITY, "; then ".join(self.vertical_notes)))
        elif pairs is not None and (problem := _vertical_verdict(*pairs, source)) is not None:
            out.append((VERTICAL_VELOCITY, problem))
        if cells is not None and (problem := voltage_problem(self._voltage_v, cells)):
            out.append((PACK_VOLTAGE, problem))
        return out

    def warnings(self, cells: int | None = None, source: str = "vertical velocity") -> list[str]:
        """The warnings of :meth:`problems`."""
        return [warning for _, warning in self.problems(cells, source)]
