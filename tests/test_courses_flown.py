"""The endurance's steady power over the courses flown lately at about the present speed
(estimator/estimation/courses_flown.py, FlightPower.course_mean_w): a box in wind is judged
by its legs together, a pattern that comes back to the present speed by one period of it, a
new speed by its own course, a change of speed by the present flight, and the courses fade
out after the window."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.estimation.courses_flown import WINDOW_S, CoursesFlown
from estimator.estimation.flight_power import FlightPower
from estimator.physics.effects import Wind
from estimator.physics.kinematics import KinematicState
from estimator.physics.vehicle import default_vehicle

#: The legs of a box flown at 6 m/s: north, east, south, west (course rad, ground velocity).
BOX = [
    (0.0, (6.0, 0.0)),
    (math.pi / 2, (0.0, 6.0)),
    (math.pi, (-6.0, 0.0)),
    (-math.pi / 2, (0.0, -6.0)),
]


def _fly(
    power: FlightPower, legs: list[tuple[float, tuple[float, float]]], start_s: float
) -> float:
    """Each leg for 15 s at 10 Hz; returns the time after the last."""
    t = start_s
    for _, (vn, ve) in legs:
        for _ in range(150):
            power.follow_track(KinematicState.of_motion(t, (vn, ve, 0.0), (0.0, 0.0)))
            t += 0.1
    return t


def test_courses_at_other_speeds_and_outside_the_window_do_not_count() -> None:
    courses = CoursesFlown()
    for i in range(60):
        courses.record(float(i), 6.0, 0.0, True)  # north at 6 m/s
    for i in range(60, 90):
        courses.record(float(i), 10.0, math.pi, True)  # south at 10 m/s
    tracks, weights = courses.near(6.0)
    assert np.allclose(tracks, [0.0]) and np.allclose(weights, [1.0])
    tracks, _ = courses.near(10.0)
    assert np.allclose(tracks, [math.pi])
    for i in range(90, 90 + int(WINDOW_S)):
        courses.record(float(i), 10.0, math.pi, True)
    assert not len(courses.near(6.0)[0])  # the northbound leg left the window


def test_courses_are_kept_once_a_second_and_a_clock_that_goes_back_starts_afresh() -> None:
    courses = CoursesFlown()
    for i in range(100):
        courses.record(0.1 * i, 6.0, 0.5 * math.pi if i < 50 else 0.0, True)
    tracks, weights = courses.near(6.0)
    assert np.isclose(weights.sum(), 1.0) and len(tracks) == 2
    assert np.allclose(sorted(weights), [0.5, 0.5])
    courses.record(1.0, 6.0, math.pi, True)
    tracks, weights = courses.near(6.0)
    assert np.allclose(tracks, [math.pi]) and np.allclose(weights, [1.0])


@pytest.fixture()
def windy() -> FlightPower:
    vehicle = default_vehicle()
    return FlightPower(vehicle, (Wind(speed_mps=6.0, from_deg=0.0),))


def test_a_box_in_wind_is_judged_by_its_legs_together(windy: FlightPower) -> None:
    """Upwind legs cost more than downwind ones; after a box the figure is their mean,
    whichever leg the vehicle is on."""
    v = 22.0
    per_leg = []
    for course_rad, _ in BOX:
        windy.track_rad = course_rad
        per_leg.append(windy.steady_w(6.0, 0.0, v))
    assert max(per_leg) > 1.05 * min(per_leg)  # the wind matters to the leg's power
    _fly(windy, BOX, 0.0)
    mean_w = windy.course_mean_w(6.0, 0.0, v)
    assert mean_w == pytest.approx(np.mean(per_leg), rel=0.01)
    assert windy.steady_w(6.0, 0.0, v) != pytest.approx(mean_w, rel=0.01)


def test_a_new_speed_is_judged_by_its_own_course(windy: FlightPower) -> None:
    """Right after a change of speed no other course was flown at it: the present one
    alone, as the steady power."""
    v = 22.0
    t = _fly(windy, BOX, 0.0)
    for _ in range(30):  # 3 s east at 12 m/s
        windy.follow_track(KinematicState.of_motion(t, (0.0, 12.0, 0.0), (0.0, 0.0)))
        t += 0.1
    assert windy.course_mean_w(12.0, t, v) == pytest.approx(windy.steady_w(12.0, t, v))


def test_without_courses_flown_the_steady_power_holds(windy: FlightPower) -> None:
    assert windy.course_mean_w(0.0, 0.0, 22.0) is None
    assert windy.course_mean_w(6.0, 0.0, 22.0) is None


def test_the_mean_does_not_depend_on_the_leg_flown_now(windy: FlightPower) -> None:
    """Round a corner the mean stays what it was; in still air it is the steady power."""
    v = 22.0
    t = _fly(windy, BOX, 0.0)  # ends on the westbound leg
    west = windy.course_mean_w(6.0, t, v)
    windy.track_rad = 0.0  # northbound, into the wind
    assert windy.course_mean_w(6.0, t, v) == pytest.approx(west)
    assert west is not None and west < windy.steady_w(6.0, t, v)
    windy.effects = ()
    assert windy.course_mean_w(6.0, t, v) == pytest.approx(windy.steady_w(6.0, t, v))


def _record(
    courses: CoursesFlown, start_s: float, seconds: int, speed_mps: float, course_rad: float
) -> float:
    """``seconds`` at ``speed_mps`` on ``course_rad``, one record a second; the time after."""
    for i in range(seconds):
        courses.record(start_s + i, speed_mps, course_rad, True)
    return start_s + seconds


def test_a_flight_that_repeats_itself_is_judged_by_its_last_period() -> None:
    """Hover 20 s, 6 m/s north for 30 s, 3 m/s back south for 30 s, three times: one period
    is 80 s, in its parts' proportions, whichever part the vehicle is in."""
    courses = CoursesFlown()
    t = 0.0
    for _ in range(3):
        t = _record(courses, t, 20, 0.0, 0.0)
        t = _record(courses, t, 30, 6.0, 0.0)
        t = _record(courses, t, 30, 3.0, math.pi)
    pattern = courses.pattern()
    assert pattern is not None
    speeds, _, weights = pattern
    share = {float(v): float(w) for v, w in zip(speeds, weights, strict=True)}
    assert share == pytest.approx({0.0: 0.25, 6.0: 0.375, 3.0: 0.375})


def test_a_steady_flight_or_a_new_speed_is_no_pattern() -> None:
    courses = CoursesFlown()
    t = _record(courses, 0.0, 100, 8.0, 0.0)  # a straight cruise
    assert courses.pattern() is None
    t = _record(courses, t, 60, 0.0, 0.0)  # then a hover
    assert courses.pattern() is None
    _record(courses, t, 30, 8.0, 0.0)  # and a cruise again: seen once, no pattern
    assert courses.pattern() is None


def test_a_change_of_speed_is_judged_by_the_present_flight(windy: FlightPower) -> None:
    """While the vehicle speeds up or slows down (here at 2 m/s²) its speed is not one it
    holds: the present steady power, not the courses' mean, with the distance from the
    figure before the change as a spread."""
    v = 22.0
    t = _fly(windy, BOX, 0.0)
    state = KinematicState.of_motion(t, (0.0, 6.0, 0.0), (0.0, 0.0))
    held_w = windy.endurance_w(state, windy.steady_w(6.0, t, v), t, v)
    assert held_w == windy.course_mean_w(6.0, t, v) and windy.change_spread == 0.0
    state = KinematicState.of_motion(t, (0.0, 5.5, 0.0), (0.0, 2.0))
    windy.follow_track(state)
    steady_w = windy.steady_w(5.5, t, v)
    assert windy.endurance_w(state, steady_w, t, v) == steady_w
    assert windy.change_spread == pytest.approx(abs(steady_w - held_w) / steady_w)
