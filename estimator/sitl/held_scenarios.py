"""The held-out effect flights of ``replay/sitl_held`` (``uav-energy sitl-record held``,
``held2`` … ``held6``; ``held7`` … on fast legs and through wind changes are
:mod:`estimator.sitl.fast_held_scenarios`, :mod:`estimator.sitl.change_held_scenarios` and
:mod:`estimator.sitl.episode_held_scenarios`, and every set by name :data:`HELD_SETS` in the
last; the development flights of wind episodes are :mod:`estimator.sitl.episode_scenarios`).

Each held-out set was recorded right after the commit that defined it froze the residual
analysis, the online tracker, the SITL vehicle file and the scoring of
:mod:`estimator.sitl.truth_check` (the first after 870ed85, the second after 7e98e75); none of
it was tuned on (docs/residuals.md, "Held-out SITL flights"); the third after the
vertical effects were added to the SITL vehicle file; the fourth after the online tracker's
1σ took in what the model's form leaves unknown; the fifth after its wind 1σ took in the
autopilot's lag and gap; the sixth after its step left out whole where the vertical gates
left out most of its readings. Vertical legs at 1-9 m/s over
10-60 m of altitude, wind episodes of 30-90 s inside longer flights, and both with the
gripper's payload. Every flight takes off to 20 m and stays between 10 and 65 m; steps as in
:mod:`estimator.sitl.scenarios` (positions and velocities NED, m and m/s; durations s).
"""

from __future__ import annotations

from estimator.sitl.scenarios import (
    CIRCLES,
    LEGS,
    Circle,
    Grip,
    Hover,
    Leg,
    Scenario,
    SetWind,
    Step,
    Takeoff,
    by_name,
    out_and_back,
)

#: Climbs up to 9 m/s and descents up to 6 m/s in GUIDED (ArduCopter's defaults stop at 2.5
#: up and 1.5 down), reached within about a second.
VERTICAL_PARAMS: dict[str, float] = {
    "WPNAV_SPEED_UP": 1000, "WPNAV_SPEED_DN": 600, "PILOT_SPEED_UP": 1000,
    "PILOT_SPEED_DN": 600, "WPNAV_ACCEL_Z": 500, "PILOT_ACCEL_Z": 500,
}  # fmt: skip


def up_and_down(up_mps: float, down_mps: float, height_m: float) -> tuple[Step, ...]:
    """A climb of ``height_m`` at ``up_mps`` in place, a 5 s hover, the descent back at
    ``down_mps``, a 5 s hover."""
    return (
        Leg(0, 0, height_m / up_mps, -up_mps),
        Hover(5),
        Leg(0, 0, height_m / down_mps, down_mps),
        Hover(5),
    )


def vertical_scenario(name: str, description: str, *steps: Step) -> Scenario:
    """A GUIDED scenario with the vertical speeds and accelerations of ``VERTICAL_PARAMS``."""
    return Scenario(name, description, steps, params=VERTICAL_PARAMS)


# fmt: off
#: The first held-out set (recorded after commit 870ed85).
HELD_SCENARIOS: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held_clean_vertical",
        "no effect; climbs at 2, 5 and 9 m/s and descents at 1, 3 and 6 m/s over 20-40 m",
        Takeoff(), Hover(20), *up_and_down(2, 1, 20), *up_and_down(5, 3, 30),
        *up_and_down(9, 6, 40), *LEGS[1:4], Hover(10),
    ),
    vertical_scenario(
        "held_clean_climbing_legs",
        "no effect; legs at 4-8 m/s climbing or descending at 1-3 m/s",
        Takeoff(), Hover(20), Leg(6, 0, 10, -2), Leg(-6, 0, 10, 2), Leg(0, 8, 8, -3),
        Hover(5), Leg(0, -8, 8, 3), Leg(4, 4, 15, -1), Leg(-4, -4, 15, 1), Circle(20, 5, 1),
        *LEGS[1:6], Hover(10),
    ),
    vertical_scenario(
        "held_wind_vertical",
        "wind 5 m/s from 045° throughout; climbs and descents at 2-6 m/s between legs",
        SetWind(5, 45), Takeoff(), Hover(20), *up_and_down(3, 2, 30), *LEGS[1:6],
        *up_and_down(6, 4, 40), *LEGS[6:],
    ),
    vertical_scenario(
        "held_gust_60s",
        "wind 8 m/s from 270° for about 65 s of legs, then still air",
        Takeoff(), *LEGS[:6], SetWind(8, 270), *LEGS[1:5], SetWind(0), *LEGS[6:],
    ),
    vertical_scenario(
        "held_gust_30s_hover",
        "wind 6 m/s from 150° for 30 s while hovering, legs before and after",
        Takeoff(), *LEGS[:6], SetWind(6, 150), Hover(30), SetWind(0), *LEGS[6:],
    ),
    vertical_scenario(
        "held_gust_90s_circles",
        "wind 7 m/s from 010° for about 90 s of circles",
        Takeoff(), *CIRCLES[:2], SetWind(7, 10), *CIRCLES[2:5], SetWind(0), *CIRCLES[5:],
    ),
    vertical_scenario(
        "held_payload_vertical",
        "1 kg gripper payload from take-off; climbs at 2 and 4 m/s, descents at 1.5 and 3 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), *up_and_down(2, 1.5, 20),
        *up_and_down(4, 3, 30), *LEGS[1:6], Hover(10),
    ),
    vertical_scenario(
        "held_release_aloft",
        "1 kg gripper payload released in a hover at 50 m after a climb at 3 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), *LEGS[1:4], Leg(0, 0, 10, -3), Hover(20),
        Grip(False), Hover(20), Leg(0, 0, 15, 2), *LEGS[4:],
    ),
    vertical_scenario(
        "held_payload_gust",
        "1 kg gripper payload from take-off; wind 7 m/s from 300° for about 70 s of legs",
        Grip(True), Hover(3), Takeoff(), Hover(30), *LEGS[1:4], SetWind(7, 300), *LEGS[4:8],
        SetWind(0), *LEGS[8:],
    ),
    vertical_scenario(
        "held_wind_climb_payload",
        "1 kg gripper payload and wind 4 m/s from 200° from take-off; climbs and climbing legs",
        SetWind(4, 200), Grip(True), Hover(3), Takeoff(), Hover(30), *up_and_down(3, 2, 25),
        Leg(6, 0, 10, -2), Leg(-6, 0, 10, 2), *LEGS[4:8], *up_and_down(5, 3, 30), Hover(10),
    ),
    vertical_scenario(
        "held_onset_vertical",
        "wind 5 m/s from 100° switched on mid-flight, then climbs at 5 m/s and legs",
        Takeoff(), Hover(20), *up_and_down(2, 1, 20), *LEGS[1:4], SetWind(5, 100), Hover(20),
        *up_and_down(5, 3, 30), *LEGS[4:8], Hover(10),
    ),
    vertical_scenario(
        "held_gust_vertical",
        "wind 6 m/s from 060° for about 50 s of climbs, descents and a leg",
        Takeoff(), *LEGS[:4], SetWind(6, 60), *up_and_down(4, 3, 30), *out_and_back(5, 10),
        SetWind(0), *LEGS[4:],
    ),
    vertical_scenario(
        "held_tall_legs",
        "wind 3 m/s from 330° throughout; a climb at 1 m/s to 50 m, legs there, a descent at "
        "2 m/s to 20 m, legs",
        SetWind(3, 330), Takeoff(), Hover(10), Leg(0, 0, 30, -1), *LEGS[1:5],
        Leg(0, 0, 15, 2), *LEGS[5:],
    ),
    vertical_scenario(
        "held_two_gusts",
        "wind 6 m/s from 090° for about 40 s, still air, then 5 m/s from 240° for about 60 s",
        Takeoff(), *LEGS[:3], SetWind(6, 90), Hover(10), *out_and_back(5, 15), SetWind(0),
        *LEGS[4:8], SetWind(5, 240), *LEGS[1:5], SetWind(0), *LEGS[8:],
    ),
)



#: The second held-out set (recorded after the SITL vehicle file's slow model error was
#: frozen in the commit that added this set; none of it tuned on): other rates, heights,
#: winds and episode lengths than the first.
HELD_SCENARIOS_2: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held2_clean_slow_climbs",
        "no effect; climbs at 1 and 3 m/s, descents at 1 and 2 m/s over 15-30 m, legs",
        Takeoff(), Hover(20), *up_and_down(1, 1, 15), *LEGS[1:5], *up_and_down(3, 2, 30),
        *LEGS[5:], Hover(10),
    ),
    vertical_scenario(
        "held2_clean_fast_vertical",
        "no effect; climbs at 7 and 8 m/s, descents at 4 and 5 m/s over 35-40 m",
        Takeoff(), Hover(20), *up_and_down(7, 4, 35), *LEGS[1:4], *up_and_down(8, 5, 40),
        *LEGS[4:8], Hover(10),
    ),
    vertical_scenario(
        "held2_onset_climbing_legs",
        "wind 6 m/s from 170° switched on mid-flight; legs climbing and descending at 1-2 m/s",
        Takeoff(), *LEGS[:6], SetWind(6, 170), Hover(20), Leg(5, 0, 10, -2), Leg(-5, 0, 10, 2),
        Leg(0, 7, 10, -1), Leg(0, -7, 10, 1), *LEGS[6:],
    ),
    vertical_scenario(
        "held2_gust_85s_legs",
        "wind 6 m/s from 320° for about 85 s of legs, still air before and after",
        Takeoff(), *LEGS[:4], SetWind(6, 320), *LEGS[4:7], *LEGS[1:2], SetWind(0), *LEGS[7:],
        *LEGS[1:6],
    ),
    vertical_scenario(
        "held2_gust_70s_circles",
        "wind 5 m/s from 060° for about 70 s of circles",
        Takeoff(), *CIRCLES[:3], SetWind(5, 60), Circle(25, 6, 1.5), Circle(15, -5, 1),
        Hover(10), SetWind(0), *CIRCLES[3:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held2_payload_climbing_legs",
        "1 kg gripper payload from take-off; legs climbing and descending at 1-3 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), Leg(6, 0, 10, -3), Leg(-6, 0, 10, 3),
        Leg(0, 5, 15, -1), Leg(0, -5, 15, 1), *LEGS[1:6], Hover(10),
    ),
    vertical_scenario(
        "held2_release_low",
        "1 kg gripper payload released in a hover at 12 m after a descent at 2 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), *LEGS[1:5], Leg(0, 0, 4, 2), Hover(20),
        Grip(False), Hover(20), Leg(0, 0, 4, -2), *LEGS[5:],
    ),
    vertical_scenario(
        "held2_wind_stop_vertical",
        "wind 7 m/s from 250° from before take-off that stops mid-flight; climbs at 2-6 m/s "
        "after",
        SetWind(7, 250), Takeoff(), *LEGS[:6], SetWind(0), Hover(20), *up_and_down(6, 3, 30),
        *LEGS[6:], *up_and_down(2, 2, 20),
    ),
    vertical_scenario(
        "held2_payload_wind_vertical",
        "1 kg gripper payload and wind 5 m/s from 090° from take-off; climbs at 2-7 m/s",
        SetWind(5, 90), Grip(True), Hover(3), Takeoff(), Hover(30), *up_and_down(2, 1.5, 20),
        *LEGS[1:6], *up_and_down(7, 4, 35), Hover(10),
    ),
    vertical_scenario(
        "held2_gust_payload_circles",
        "1 kg gripper payload from take-off; wind 6 m/s from 280° for about 80 s of circles",
        Grip(True), Hover(3), Takeoff(), *CIRCLES[:2], SetWind(6, 280), *CIRCLES[2:6],
        SetWind(0), *CIRCLES[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held2_turn_climbs",
        "wind 5 m/s from 000° turning to 090° mid-flight; climbs at 3 and 5 m/s",
        SetWind(5, 0), Takeoff(), Hover(20), *up_and_down(3, 2, 25), *LEGS[1:5],
        SetWind(5, 90), Hover(20), *up_and_down(5, 3, 30), *LEGS[5:],
    ),
    vertical_scenario(
        "held2_gust_90s_hovers",
        "wind 8 m/s from 135° for about 90 s of hovers and legs",
        Takeoff(), *LEGS[:4], SetWind(8, 135), Hover(15), *LEGS[4:6], Hover(15), *LEGS[6:7],
        SetWind(0), *LEGS[7:], *LEGS[1:4],
    ),
)

#: The third held-out set (recorded after the commit that added it froze the vertical
#: effects ``climb`` and ``heave`` in the SITL vehicle file, fitted on replay/sitl_axial; none
#: of it tuned on): other rates, heights, winds and episodes than the first two.
HELD_SCENARIOS_3: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held3_clean_mixed_vertical",
        "no effect; climbs at 4 and 6 m/s, descents at 2 and 5 m/s over 25-45 m",
        Takeoff(), Hover(20), *up_and_down(4, 2, 25), *LEGS[1:4], *up_and_down(6, 5, 45),
        *LEGS[4:8], Hover(10),
    ),
    vertical_scenario(
        "held3_clean_tall_slow",
        "no effect; a climb at 1.5 m/s and a descent at 1 m/s over 40 m, legs between",
        Takeoff(), Hover(20), Leg(0, 0, 40 / 1.5, -1.5), Hover(5), *LEGS[1:6],
        Leg(0, 0, 40, 1), *LEGS[6:], Hover(10),
    ),
    vertical_scenario(
        "held3_wind_climbs",
        "wind 6 m/s from 210° throughout; climbs at 4 and 8 m/s, descents at 3 and 4 m/s",
        SetWind(6, 210), Takeoff(), Hover(20), *up_and_down(4, 3, 30), *LEGS[1:6],
        *up_and_down(8, 4, 40), *LEGS[6:],
    ),
    vertical_scenario(
        "held3_payload_fast_vertical",
        "1 kg gripper payload from take-off; climbs at 5 and 8 m/s, descents at 3 and 5 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), *up_and_down(5, 3, 30), *LEGS[1:5],
        *up_and_down(8, 5, 40), *LEGS[5:8], Hover(10),
    ),
    vertical_scenario(
        "held3_gust_75s_vertical",
        "wind 7 m/s from 300° for about 75 s of climbs, descents and legs",
        Takeoff(), *LEGS[:4], SetWind(7, 300), *up_and_down(3, 2, 25), Leg(4, 0, 25),
        Hover(20), SetWind(0), *LEGS[2:], *up_and_down(5, 3, 30),
    ),
    vertical_scenario(
        "held3_onset_climbing_circles",
        "wind 6 m/s from 020° switched on mid-flight; circles, then climbs at 3 m/s",
        Takeoff(), *CIRCLES[:3], SetWind(6, 20), Hover(20), *CIRCLES[3:],
        *up_and_down(3, 2, 30), *LEGS[1:4],
    ),
    vertical_scenario(
        "held3_release_high",
        "1 kg gripper payload released in a hover at 50 m after a climb at 4 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(30), *LEGS[1:5], Leg(0, 0, 7.5, -4), Hover(20),
        Grip(False), Hover(20), Leg(0, 0, 10, 3), *LEGS[5:],
    ),
    vertical_scenario(
        "held3_gust_payload_vertical",
        "1 kg gripper payload from take-off; wind 5 m/s from 160° for about 80 s of climbs and "
        "legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(5, 160), *up_and_down(2, 2, 20),
        *LEGS[4:6], Hover(20), SetWind(0), *LEGS[6:], *up_and_down(6, 3, 30),
    ),
    vertical_scenario(
        "held3_wind_stop_climbing_legs",
        "wind 6 m/s from 100° from before take-off that stops mid-flight; legs climbing and "
        "descending at 2-4 m/s after",
        SetWind(6, 100), Takeoff(), *LEGS[:6], SetWind(0), Hover(20), Leg(6, 0, 10, -4),
        Leg(-6, 0, 10, 4), Leg(0, 6, 10, -2), Leg(0, -6, 10, 2), *LEGS[6:],
    ),
    vertical_scenario(
        "held3_gust_45s_legs",
        "wind 8 m/s from 040° for about 45 s of legs, still air before and after",
        Takeoff(), *LEGS[:6], SetWind(8, 40), *LEGS[6:8], Hover(10), SetWind(0), *LEGS[8:],
        *LEGS[1:6],
    ),
    vertical_scenario(
        "held3_payload_wind_climbing_legs",
        "1 kg gripper payload and wind 4 m/s from 330° from take-off; legs climbing and "
        "descending at 2 m/s",
        SetWind(4, 330), Grip(True), Hover(3), Takeoff(), Hover(30), Leg(5, 0, 10, -2),
        Leg(-5, 0, 10, 2), Leg(0, 5, 10, -2), Leg(0, -5, 10, 2), *LEGS[1:6], Hover(10),
    ),
    vertical_scenario(
        "held3_two_turns_vertical",
        "wind 5 m/s from 270° turning to 180° mid-flight; climbs at 2 and 7 m/s",
        SetWind(5, 270), Takeoff(), Hover(20), *up_and_down(2, 1.5, 20), *LEGS[1:5],
        SetWind(5, 180), Hover(20), *up_and_down(7, 4, 35), *LEGS[5:],
    ),
)

#: The fourth held-out set (recorded after the commit that added it froze the online
#: tracker's model-form 1σ, set on replay/sitl; none of it tuned on): payloads in still air
#: and in wind, steady winds light and strong, and a wind that sets in, stops or turns, over
#: other patterns than before.
HELD_SCENARIOS_4: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held4_payload_wind_circles",
        "1 kg gripper payload from take-off; wind 5 m/s from 045° throughout; circles",
        SetWind(5, 45), Grip(True), Hover(3), Takeoff(), *CIRCLES, *up_and_down(3, 2, 20),
        *CIRCLES[1:4],
    ),
    vertical_scenario(
        "held4_payload_calm_climbing_legs",
        "1 kg gripper payload from take-off in still air; legs, climbs at 3 m/s",
        Grip(True), Hover(3), Takeoff(), Hover(20), *LEGS[1:6], *up_and_down(3, 2, 25),
        *LEGS[6:], Hover(10),
    ),
    vertical_scenario(
        "held4_release_wind_legs",
        "1 kg gripper payload released in a hover mid-flight; wind 4 m/s from 250° throughout",
        SetWind(4, 250), Grip(True), Hover(3), Takeoff(), *LEGS[:7], Hover(15), Grip(False),
        Hover(15), *LEGS[1:7],
    ),
    vertical_scenario(
        "held4_clean_circles_vertical",
        "no effect; circles, climbs at 2 and 3 m/s over 15-30 m",
        Takeoff(), *CIRCLES, *up_and_down(2, 1.5, 15), *CIRCLES[1:4], *up_and_down(3, 2, 30),
    ),
    vertical_scenario(
        "held4_wind_strong_legs",
        "wind 8 m/s from 170° throughout; legs",
        SetWind(8, 170), Takeoff(), *LEGS, *LEGS[1:6],
    ),
    vertical_scenario(
        "held4_wind_light_mixed",
        "wind 2 m/s from 300° throughout; legs and circles",
        SetWind(2, 300), Takeoff(), *LEGS[:6], *CIRCLES[1:6], *LEGS[6:],
    ),
    vertical_scenario(
        "held4_onset_legs",
        "wind 6 m/s from 250° switched on mid-flight during legs",
        Takeoff(), *LEGS[:6], SetWind(6, 250), *LEGS[6:], *LEGS[1:7],
    ),
    vertical_scenario(
        "held4_payload_gust_80s",
        "1 kg gripper payload from take-off; wind 6 m/s from 100° for about 80 s of legs",
        Grip(True), Hover(3), Takeoff(), Hover(20), *LEGS[1:4], SetWind(6, 100), *LEGS[4:9],
        SetWind(0), *LEGS[9:], *LEGS[1:5],
    ),
)

#: The fifth held-out set (recorded after the commit that added it froze the online
#: tracker's wind 1σ with the autopilot's lag and gap, set on replay/sitl and every earlier
#: held-out set; none of it tuned on): winds that set in, stop or turn in a hover (where
#: ArduCopter's EKF holds its wind) and on legs, steady winds, payloads with a wind change.
HELD_SCENARIOS_5: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held5_gust_hover_legs",
        "wind 7 m/s from 030° for about 70 s from a hover into legs, still air around it",
        Takeoff(), *LEGS[:4], SetWind(7, 30), Hover(25), *LEGS[4:7], SetWind(0), *LEGS[7:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held5_stop_in_hover",
        "wind 6 m/s from 200° from before take-off that stops in a 30 s hover; legs after",
        SetWind(6, 200), Takeoff(), *LEGS[:6], Hover(5), SetWind(0), Hover(30), *LEGS[6:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held5_onset_in_hover",
        "wind 5 m/s from 100° switched on in a 30 s hover mid-flight; circles after",
        Takeoff(), *LEGS[:6], Hover(5), SetWind(5, 100), Hover(30), *CIRCLES[1:6], *LEGS[6:],
    ),
    vertical_scenario(
        "held5_turn_legs",
        "wind 6 m/s from 330° turning to 6 m/s from 060° during legs",
        SetWind(6, 330), Takeoff(), *LEGS[:6], SetWind(6, 60), *LEGS[6:], *LEGS[1:6],
    ),
    vertical_scenario(
        "held5_wind_steady_circles",
        "wind 6 m/s from 120° throughout; circles and legs",
        SetWind(6, 120), Takeoff(), *CIRCLES, *LEGS[1:7],
    ),
    vertical_scenario(
        "held5_payload_onset_legs",
        "1 kg gripper payload from take-off; wind 5 m/s from 280° switched on mid-flight",
        Grip(True), Hover(3), Takeoff(), Hover(20), *LEGS[1:6], SetWind(5, 280), *LEGS[6:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held5_clean_legs_climbs",
        "no effect; legs, a climb at 4 m/s and a descent at 3 m/s over 25 m",
        Takeoff(), *LEGS[:6], *up_and_down(4, 3, 25), *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held5_release_then_gust",
        "1 kg gripper payload released in a hover; then wind 6 m/s from 160° for about 70 s",
        Grip(True), Hover(3), Takeoff(), *LEGS[:5], Hover(10), Grip(False), Hover(10),
        SetWind(6, 160), *LEGS[5:9], SetWind(0), *LEGS[9:], *LEGS[1:5],
    ),
)

#: The sixth held-out set (recorded after the commit that added it froze the online tracker's
#: skipping of a step whose readings the vertical gates mostly left out; none of it tuned on):
#: climbs and descents starting and stopping with and without the payload, releases near
#: vertical legs, landings with a payload and in wind.
HELD_SCENARIOS_6: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held6_payload_descents",
        "1 kg gripper payload from take-off; legs, a climb at 3 m/s and a descent at 2 m/s "
        "over 25 m, landed with it",
        Grip(True), Hover(3), Takeoff(), Hover(20), *LEGS[1:5], *up_and_down(3, 2, 25),
        *LEGS[5:],
    ),
    vertical_scenario(
        "held6_release_then_climbs",
        "1 kg gripper payload released in a hover, then a climb at 5 m/s and a descent at 3 m/s "
        "over 30 m",
        Grip(True), Hover(3), Takeoff(), *LEGS[:5], Hover(10), Grip(False), Hover(10),
        *up_and_down(5, 3, 30), *LEGS[5:],
    ),
    vertical_scenario(
        "held6_wind_payload_circles",
        "1 kg gripper payload from take-off; wind 4 m/s from 010° throughout; circles, a climb "
        "at 2 m/s",
        SetWind(4, 10), Grip(True), Hover(3), Takeoff(), *CIRCLES, *up_and_down(2, 1.5, 20),
        *CIRCLES[1:4],
    ),
    vertical_scenario(
        "held6_clean_fast_climbs",
        "no effect; climbs at 6 and 8 m/s, descents at 4 and 5 m/s over 30-40 m, legs",
        Takeoff(), Hover(15), *up_and_down(6, 4, 30), *LEGS[1:6], *up_and_down(8, 5, 40),
        *LEGS[6:],
    ),
    vertical_scenario(
        "held6_gust_payload_climbs",
        "1 kg gripper payload from take-off; wind 6 m/s from 220° for about 60 s over legs and "
        "a climb at 3 m/s",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 220), *up_and_down(3, 2, 20),
        *LEGS[4:6], SetWind(0), *LEGS[6:],
    ),
    vertical_scenario(
        "held6_wind_vertical_legs",
        "wind 5 m/s from 290° throughout; legs, climbs at 2 and 4 m/s",
        SetWind(5, 290), Takeoff(), *LEGS[:6], *up_and_down(2, 1.5, 20), *LEGS[6:],
        *up_and_down(4, 3, 25),
    ),
    vertical_scenario(
        "held6_release_wind_descent",
        "1 kg gripper payload released in a hover after a descent at 2 m/s; wind 3 m/s from 150°",
        SetWind(3, 150), Grip(True), Hover(3), Takeoff(), *LEGS[:5], Leg(0, 0, 4, 2), Hover(15),
        Grip(False), Hover(15), Leg(0, 0, 4, -2), *LEGS[5:],
    ),
    vertical_scenario(
        "held6_onset_payload_climbs",
        "1 kg gripper payload from take-off; wind 6 m/s from 040° switched on mid-flight; "
        "climbs at 2-4 m/s",
        Grip(True), Hover(3), Takeoff(), *LEGS[:5], SetWind(6, 40), *up_and_down(4, 2, 25),
        *LEGS[5:], *up_and_down(2, 2, 15),
    ),
)

# fmt: on
