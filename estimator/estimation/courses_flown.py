"""The speeds and courses flown lately: what the endurance averages its steady power over.

At a steady speed in wind, the power depends on the course: into the wind it is higher than
with it. A vehicle flying a pattern (a survey, a box, an orbit) changes course every few tens
of seconds, and the time it has left follows the mean over its courses, not the leg it is
on. Endurance stays the figure of the present flight (speed, effects, turn held); only the
course is averaged, over those flown in the last :data:`WINDOW_S` at a speed within
:data:`SPEED_TOLERANCE_MPS` or :data:`SPEED_TOLERANCE_FRACTION` of the present one. A
vehicle that has just changed speed has flown no other course at the new one yet: its
present course alone.

A pattern may also change speed: legs it cannot fly at the set speed into a strong wind,
hovers between legs, a dash. When the ground velocity of the last period repeats the period
before it (:meth:`CoursesFlown.pattern`: a period of :data:`PERIOD_MIN_S` to
:data:`PERIOD_MAX_S`, the velocities a period apart differing by at most
:data:`PATTERN_MISMATCH` of their spread over both), the figure is the mean over the last
period as flown, whatever the vehicle does at the moment.

Frames and units: course over ground in rad from north, speeds horizontal (m/s), times on
the autopilot's clock (s).
"""

from __future__ import annotations

import itertools
import math
from collections import deque

import numpy as np

#: How far back (s) courses count, and how often (s) one is kept.
WINDOW_S = 120.0
RECORD_PERIOD_S = 1.0
#: A course counts when it was flown within this much of the present speed (m/s, or this
#: fraction of it, whichever is larger).
SPEED_TOLERANCE_MPS = 1.0
SPEED_TOLERANCE_FRACTION = 0.15
#: Courses are counted in sectors this wide (rad): a handful of rows to predict, not one per
#: second flown.
SECTOR_RAD = math.radians(10.0)
_SECTORS_HALF = round(math.pi / SECTOR_RAD)  # a course in (−π, π] lies within ± this many
#: Periods (s) a repeated pattern is looked for at, in steps of :data:`PERIOD_STEP_S`: the
#: last period against the one before (a flight seen once is no pattern), within the last
#: :data:`PATTERN_WINDOW_S`.
PERIOD_MIN_S, PERIOD_MAX_S, PERIOD_STEP_S = 20.0, 90.0, 2.0
PATTERN_WINDOW_S = 2 * PERIOD_MAX_S + 20.0
#: How often (s) a pattern is looked for: it changes over periods, not seconds.
SEARCH_PERIOD_S = 2.0
#: The flight repeats itself when its ground velocities one period apart differ (mean
#: squared) by at most this fraction of twice their variance over the two periods (1 for
#: unrelated velocities)...
PATTERN_MISMATCH = 0.2
#: ... and that variance is at least this (m²/s²): a steady flight is no pattern.
PATTERN_SPREAD_MIN_M2PS2 = 1.0
#: A pattern's speeds are counted in bins this wide (m/s).
SPEED_BIN_MPS = 0.5


#: Speeds (m/s), courses (rad) and the fraction of a period at each.
Pattern = tuple[np.ndarray, np.ndarray, np.ndarray]


class CoursesFlown:
    """Courses over ground with the speed each was flown at, over the last
    :data:`PATTERN_WINDOW_S`."""

    def __init__(self) -> None:
        #: (time s, speed m/s, course rad, held: a speed the vehicle held, not one it passed)
        self._flown: deque[tuple[float, float, float, bool]] = deque()
        self._pattern: Pattern | None = None  # found at the last search
        self._searched_s = -math.inf  # time of the newest record at the last search, s

    def record(self, time_s: float, speed_mps: float, course_rad: float, held: bool) -> None:
        """The vehicle flies ``course_rad`` at ``speed_mps`` at ``time_s``, a speed it holds
        or (``held`` False) one it passes through; kept at most once per
        :data:`RECORD_PERIOD_S`."""
        flown = self._flown
        if flown and time_s < flown[-1][0]:
            flown.clear()  # the autopilot's clock went back: a new flight
            self._searched_s = -math.inf
        if flown and time_s - flown[-1][0] < RECORD_PERIOD_S:
            return
        flown.append((time_s, speed_mps, course_rad, held))
        while flown[0][0] < time_s - PATTERN_WINDOW_S:
            flown.popleft()

    def pattern(self) -> Pattern | None:
        """When the flight repeats itself (its last period against the period before, at the
        period that matches best), the speeds (m/s, bin centres) and courses (rad, sector
        centres) of its last period and the fraction of the period at each (summing to 1);
        None when it does not. Looked for every :data:`SEARCH_PERIOD_S` of records."""
        if self._flown and self._flown[-1][0] >= self._searched_s + SEARCH_PERIOD_S:
            self._pattern, self._searched_s = self._find_pattern(), self._flown[-1][0]
        return self._pattern

    def _find_pattern(self) -> Pattern | None:
        flown = self._flown
        if not flown or flown[-1][0] - flown[0][0] < 2 * PERIOD_MIN_S:
            return None
        records = itertools.chain.from_iterable(flown)
        time_s, speed_mps, course_rad, _ = (
            np.fromiter(records, float, 4 * len(flown)).reshape(-1, 4).T
        )
        # the ground velocity on a grid of PERIOD_STEP_S, so that a period is a shift
        grid_s = np.arange(time_s[0], time_s[-1] + 1e-9, PERIOD_STEP_S)
        north = np.interp(grid_s, time_s, speed_mps * np.cos(course_rad))
        east = np.interp(grid_s, time_s, speed_mps * np.sin(course_rad))
        # the last period against the one before, at every period k that fits (in grid steps):
        # the mean |v(t) − v(t − k)|² over the last k against twice the variance of v over 2k
        n = len(grid_s)
        shifts = np.arange(
            round(PERIOD_MIN_S / PERIOD_STEP_S),
            min(round(PERIOD_MAX_S / PERIOD_STEP_S), n // 2) + 1,
        )
        if not len(shifts):
            return None
        back = np.empty((2, n))  # newest first
        back[0], back[1] = north[::-1], east[::-1]
        sums = np.concatenate((np.zeros((2, 1)), np.cumsum(back, axis=1)), axis=1)
        squares = np.concatenate(([0.0], np.cumsum((back**2).sum(axis=0))))
        mean = sums[:, 2 * shifts] / (2 * shifts)
        spread = 2.0 * (squares[2 * shifts] / (2 * shifts) - (mean**2).sum(axis=0))
        if not (spread >= PATTERN_SPREAD_MIN_M2PS2).any():
            return None  # steady at every period: the products below would find nothing
        longest = shifts[-1]  # 2 × longest ≤ n
        steps = np.arange(longest)[:, None]  # i < k: the last period's i-th newest step
        inside = steps < shifts[None, :]
        later = back[:, :longest, None]
        # back[:, i + k] at step i and period k (a view: the periods are consecutive)
        step_bytes = back.strides[1]
        earlier = np.ndarray(
            (2, longest, len(shifts)),
            float,
            back,
            int(shifts[0]) * step_bytes,
            (back.strides[0], step_bytes, step_bytes),
        )
        products = later[0] * earlier[0] + later[1] * earlier[1]
        cross = np.where(inside, products, 0.0).sum(axis=0)
        mismatch = (squares[2 * shifts] - 2.0 * cross) / shifts
        ratio = np.where(
            spread >= PATTERN_SPREAD_MIN_M2PS2,  # a steady flight is no pattern
            mismatch / np.maximum(spread, PATTERN_SPREAD_MIN_M2PS2),
            np.inf,
        )
        best = int(np.argmin(ratio))
        if not ratio[best] <= PATTERN_MISMATCH:
            return None
        period_s = float(shifts[best] * PERIOD_STEP_S)
        last = time_s > time_s[-1] - period_s
        # one integer key per (speed bin, course sector): sectors lie within ±_SECTORS_HALF
        speed_bin = np.round(speed_mps[last] / SPEED_BIN_MPS)
        sector = np.round(course_rad[last] / SECTOR_RAD)
        keys, counts = np.unique(speed_bin * (2 * _SECTORS_HALF + 1) + sector, return_counts=True)
        speed_bin = np.round(keys / (2 * _SECTORS_HALF + 1))
        sector = keys - speed_bin * (2 * _SECTORS_HALF + 1)
        return speed_bin * SPEED_BIN_MPS, sector * SECTOR_RAD, counts / counts.sum()

    def near(self, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """Courses (rad, sector centres) flown at about ``speed_mps`` and the fraction of
        them in each sector (summing to 1); empty when none was."""
        tolerance = max(SPEED_TOLERANCE_MPS, SPEED_TOLERANCE_FRACTION * speed_mps)
        counts: dict[int, int] = {}
        since_s = self._flown[-1][0] - WINDOW_S if self._flown else 0.0
        for time_s, flown_mps, course_rad, held in self._flown:
            if time_s >= since_s and held and abs(flown_mps - speed_mps) <= tolerance:
                sector = round(course_rad / SECTOR_RAD)
                counts[sector] = counts.get(sector, 0) + 1
        if not counts:
            return np.empty(0), np.empty(0)
        sectors = np.array(list(counts), dtype=float)
        weights = np.array(list(counts.values()), dtype=float)
        return sectors * SECTOR_RAD, weights / weights.sum()
