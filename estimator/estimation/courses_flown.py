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
hovers between legs, a dash. When the present speed was flown before in the window, left for
at least :data:`PATTERN_GAP_S` and taken up again, the flight repeats itself, and the figure
is the mean over one period of it (:meth:`CoursesFlown.pattern`): every speed and course
flown from the start of the earlier visit to the start of the present one.

Frames and units: course over ground in rad from north, speeds horizontal (m/s), times on
the autopilot's clock (s).
"""

from __future__ import annotations

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
#: The present speed taken up again after at least this long (s) at other speeds, within
#: the window, marks a repeated pattern; shorter dips (a corner) belong to the visit.
PATTERN_GAP_S = 10.0
#: A pattern's speeds are counted in bins this wide (m/s).
SPEED_BIN_MPS = 0.5


class CoursesFlown:
    """Courses over ground with the speed each was flown at, over the last :data:`WINDOW_S`."""

    def __init__(self) -> None:
        self._flown: deque[tuple[float, float, float]] = deque()  # (time s, speed m/s, rad)

    def record(self, time_s: float, speed_mps: float, course_rad: float) -> None:
        """The vehicle flies ``course_rad`` at ``speed_mps`` at ``time_s`` (kept at most once
        per :data:`RECORD_PERIOD_S`)."""
        flown = self._flown
        if flown and time_s < flown[-1][0]:
            flown.clear()  # the autopilot's clock went back: a new flight
        if flown and time_s - flown[-1][0] < RECORD_PERIOD_S:
            return
        flown.append((time_s, speed_mps, course_rad))
        while flown[0][0] < time_s - WINDOW_S:
            flown.popleft()

    def pattern(self, speed_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """When the present speed was flown before within the window, left for at least
        :data:`PATTERN_GAP_S` and taken up again, the flight repeats a pattern: the speeds
        (m/s, bin centres) and courses (rad, sector centres) of one period of it (from the
        start of the last earlier visit to the start of the present one) and the fraction of
        the period at each (summing to 1). None when the present speed is new."""
        tolerance = max(SPEED_TOLERANCE_MPS, SPEED_TOLERANCE_FRACTION * speed_mps)
        flown = self._flown
        if not flown or abs(flown[-1][1] - speed_mps) > tolerance:
            return None  # the last second was flown at another speed
        visit_start_s = period_start_s = math.nan
        later_s = math.inf  # the time of the last record at the present speed seen (going back)
        for time_s, flown_mps, _ in reversed(flown):
            if abs(flown_mps - speed_mps) > tolerance:
                continue
            if later_s - time_s >= PATTERN_GAP_S and not math.isinf(later_s):
                if not math.isnan(period_start_s):
                    break  # a visit before the earlier one
                visit_start_s = later_s
            if not math.isnan(visit_start_s):
                period_start_s = time_s
            later_s = time_s
        if math.isnan(period_start_s):
            return None
        counts: dict[tuple[int, int], int] = {}
        for time_s, flown_mps, course_rad in flown:
            if period_start_s <= time_s < visit_start_s:
                key = (round(flown_mps / SPEED_BIN_MPS), round(course_rad / SECTOR_RAD))
                counts[key] = counts.get(key, 0) + 1
        bins = np.array(list(counts), dtype=float)
        weights = np.array(list(counts.values()), dtype=float)
        return bins[:, 0] * SPEED_BIN_MPS, bins[:, 1] * SECTOR_RAD, weights / weights.sum()

    def near(self, speed_mps: float) -> tuple[np.ndarray, np.ndarray]:
        """Courses (rad, sector centres) flown at about ``speed_mps`` and the fraction of
        them in each sector (summing to 1); empty when none was."""
        tolerance = max(SPEED_TOLERANCE_MPS, SPEED_TOLERANCE_FRACTION * speed_mps)
        counts: dict[int, int] = {}
        for _, flown_mps, course_rad in self._flown:
            if abs(flown_mps - speed_mps) <= tolerance:
                sector = round(course_rad / SECTOR_RAD)
                counts[sector] = counts.get(sector, 0) + 1
        if not counts:
            return np.empty(0), np.empty(0)
        sectors = np.array(list(counts), dtype=float)
        weights = np.array(list(counts.values()), dtype=float)
        return sectors * SECTOR_RAD, weights / weights.sum()
