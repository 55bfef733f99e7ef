"""The held-out flights of ``replay/sitl_held`` through short wind episodes (``uav-energy
sitl-record held23``), and every held-out set by name (:data:`HELD_SETS`; the earlier sets are
:mod:`estimator.sitl.held_scenarios`, :mod:`estimator.sitl.fast_held_scenarios` and
:mod:`estimator.sitl.change_held_scenarios`).

The twenty-third set was recorded right after the commit that defined it froze the residual
loop's test blocks of 2.5 s and its windowed autopilot wind (docs/residuals.md, "Held-out SITL
flights"); none of it was tuned on. Steps as in :mod:`estimator.sitl.scenarios` (positions and
velocities NED, m and m/s; durations s).
"""

from __future__ import annotations

from estimator.sitl.change_held_scenarios import (
    HELD_SCENARIOS_16,
    HELD_SCENARIOS_17,
    HELD_SCENARIOS_18,
    HELD_SCENARIOS_19,
    HELD_SCENARIOS_20,
    HELD_SCENARIOS_21,
    HELD_SCENARIOS_22,
)
from estimator.sitl.fast_held_scenarios import (
    FAST_LEGS,
    HELD_SCENARIOS_7,
    HELD_SCENARIOS_8,
    HELD_SCENARIOS_9,
    HELD_SCENARIOS_10,
    HELD_SCENARIOS_11,
    HELD_SCENARIOS_12,
    HELD_SCENARIOS_13,
    HELD_SCENARIOS_14,
    HELD_SCENARIOS_15,
)
from estimator.sitl.held_scenarios import (
    HELD_SCENARIOS,
    HELD_SCENARIOS_2,
    HELD_SCENARIOS_3,
    HELD_SCENARIOS_4,
    HELD_SCENARIOS_5,
    HELD_SCENARIOS_6,
    up_and_down,
    vertical_scenario,
)
from estimator.sitl.scenarios import (
    CIRCLES,
    LEGS,
    Grip,
    Hover,
    Leg,
    Scenario,
    SetWind,
    Takeoff,
    by_name,
)

# fmt: off
#: The twenty-third held-out set, for the residual loop whose rank test sums 2.5 s blocks and
#: whose candidates hold the autopilot's wind in a window: wind episodes of 30-90 s over slow,
#: fast and diagonal legs, circles, a climb and a descent, with the payload and with a release
#: inside one; a wind stopped during slow legs; two episodes in one flight; and two clean
#: flights with hovers, circles and climbs (nothing may be named there).
HELD_SCENARIOS_23: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held23_gust_30s_legs",
        "wind 7 m/s from 045° for about 30 s of legs; legs",
        Takeoff(), *LEGS[:4], SetWind(7, 45), *LEGS[4:6], SetWind(0), *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_gust_40s_fast_legs",
        "wind 8 m/s from 250° for about 40 s of 8-9 m/s legs; fast legs and legs",
        Takeoff(), *FAST_LEGS[:3], SetWind(8, 250), *FAST_LEGS[3:7], SetWind(0), *FAST_LEGS[7:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_gust_55s_slow_legs",
        "wind 6 m/s from 160° for about 55 s of 2-3 m/s legs; legs",
        Takeoff(), *LEGS[:6], SetWind(6, 160), *LEGS[6:8], Leg(0, 3, 20), SetWind(0),
        Leg(0, 3, 10), *LEGS[9:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_gust_65s_circles",
        "wind 6 m/s from 300° for about 65 s of circles; legs",
        Takeoff(), *LEGS[:3], SetWind(6, 300), *CIRCLES[1:3], SetWind(0), *CIRCLES[3:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held23_gust_50s_climb_descent",
        "wind 7 m/s from 090° for about 50 s: a climb at 3 m/s by 15 m, legs there and the "
        "descent back; legs",
        Takeoff(), *LEGS[:4], SetWind(7, 90), Leg(0, 0, 5, -3), *LEGS[4:6], Leg(0, 0, 5, 3),
        Hover(5), SetWind(0), *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held23_payload_gust_45s_legs",
        "1 kg gripper payload from take-off; wind 6 m/s from 200° for about 45 s of legs; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 200), *LEGS[4:6], Leg(2, 0, 15),
        SetWind(0), Leg(2, 0, 15), *LEGS[7:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held23_stop_slow_legs",
        "wind 7 m/s from 010° from take-off, stopped during a 2 m/s leg; legs",
        SetWind(7, 10), Takeoff(), *LEGS[:6], Leg(2, 0, 10), SetWind(0), Leg(2, 0, 20),
        *LEGS[7:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_gust_70s_diagonal_legs",
        "wind 7 m/s from 135° for about 70 s of diagonal legs with a hover; fast legs and legs",
        Takeoff(), *FAST_LEGS[:9], SetWind(7, 135), *FAST_LEGS[9:], Leg(6, 6, 15),
        Leg(-6, -6, 15), SetWind(0), Hover(10), *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_two_gusts_legs",
        "wind 6 m/s from 090° for about 60 s of legs, still air for about 65 s, then 5 m/s from "
        "270° for about 50 s of legs; legs",
        Takeoff(), *LEGS[:4], SetWind(6, 90), *LEGS[4:7], SetWind(0), *LEGS[7:],
        SetWind(5, 270), *LEGS[1:4], SetWind(0), *LEGS[4:7],
    ),
    vertical_scenario(
        "held23_release_in_gust",
        "1 kg gripper payload from take-off, released in a hover inside a wind of 6 m/s from "
        "330° that blows for about 85 s of legs; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 330), *LEGS[4:6], Hover(10),
        Grip(False), Hover(10), *LEGS[6:8], SetWind(0), *LEGS[8:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held23_clean_legs_hovers",
        "no effect; legs, fast legs and 30 s hovers",
        Takeoff(), *LEGS, Hover(30), *FAST_LEGS[1:5], Hover(30), *LEGS[1:5],
    ),
    vertical_scenario(
        "held23_clean_circles_climbs",
        "no effect; circles, a climb at 3 m/s by 15 m and its descent at 2 m/s, legs",
        Takeoff(), *CIRCLES, *up_and_down(3, 2, 15), *LEGS[1:6],
    ),
)

#: Every held-out set by the name ``uav-energy sitl-record`` records it under.
HELD_SETS: dict[str, dict[str, Scenario]] = {
    "held": HELD_SCENARIOS,
    "held2": HELD_SCENARIOS_2,
    "held3": HELD_SCENARIOS_3,
    "held4": HELD_SCENARIOS_4,
    "held5": HELD_SCENARIOS_5,
    "held6": HELD_SCENARIOS_6,
    "held7": HELD_SCENARIOS_7,
    "held8": HELD_SCENARIOS_8,
    "held9": HELD_SCENARIOS_9,
    "held10": HELD_SCENARIOS_10,
    "held11": HELD_SCENARIOS_11,
    "held12": HELD_SCENARIOS_12,
    "held13": HELD_SCENARIOS_13,
    "held14": HELD_SCENARIOS_14,
    "held15": HELD_SCENARIOS_15,
    "held16": HELD_SCENARIOS_16,
    "held17": HELD_SCENARIOS_17,
    "held18": HELD_SCENARIOS_18,
    "held19": HELD_SCENARIOS_19,
    "held20": HELD_SCENARIOS_20,
    "held21": HELD_SCENARIOS_21,
    "held22": HELD_SCENARIOS_22,
    "held23": HELD_SCENARIOS_23,
}
# fmt: on
