"""The held-out flights of ``replay/sitl_held`` through wind turns and reversals (``uav-energy
sitl-record held16``), through changes across hovers (``held17``), through changes the
autopilot's report shows late, with releases near them (``held18``), through changes in hovers,
most of them payload releases (``held19``), through short wind episodes, climbs and strong winds
(``held20``), through hovers in strong winds (``held21``) and through wind changes during legs
and circles (``held22``); the earlier ones are :mod:`estimator.sitl.held_scenarios` and
:mod:`estimator.sitl.fast_held_scenarios`, the later ones and every set by name
:mod:`estimator.sitl.episode_held_scenarios`.

The sixteenth set was recorded right after the commit that defined it froze the online tracker
with the autopilot report's lag term widening both wind components alike
(:meth:`~estimator.estimation.autopilot_wind.AutopilotWind.lag_mps`); none of it was tuned on
(docs/residuals.md, "Held-out SITL flights"); the seventeenth after the commit that held the lag
term while the vehicle hovers; the eighteenth after the commit that took back the mass learnt
against the old wind when the report shows a change (3b44bad), a rule these flights refuted and
that was reverted (docs/residuals.md); the nineteenth after the commit that reports the step
after an alarm's step with a changed state's 1σ as well; the twentieth after the commit that
kept the residual loop's winds within the vehicle's airspeed; the twenty-first after the commit
that made the tracker's mass learnt in a hover carry the uncertainty of the wind held there; the
twenty-second after the commit that measured the autopilot report's rate at every report and
only once it estimates the wind. Steps as in :mod:`estimator.sitl.scenarios` (positions and
velocities NED, m and m/s; durations s).
"""

from __future__ import annotations

from estimator.sitl.fast_held_scenarios import FAST_LEGS
from estimator.sitl.held_scenarios import vertical_scenario
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
#: The sixteenth held-out set: winds that turn, reverse, set in and stop across the legs and
#: circles flown, with and without the payload, and a clean flight.
HELD_SCENARIOS_16: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held16_turn_circles",
        "wind 5 m/s from 200° turning to 290° mid-flight; circles, then legs",
        SetWind(5, 200), Takeoff(), *CIRCLES, SetWind(5, 290), *CIRCLES[1:], *LEGS[1:6],
    ),
    vertical_scenario(
        "held16_reversal_legs",
        "wind 5 m/s from 010° reversing to 190° mid-flight; legs",
        SetWind(5, 10), Takeoff(), *LEGS, SetWind(5, 190), *LEGS[1:],
    ),
    vertical_scenario(
        "held16_turn_payload_legs",
        "1 kg gripper payload from take-off; wind 6 m/s from 100° turning to 030° mid-flight; "
        "legs",
        SetWind(6, 100), Grip(True), Hover(3), Takeoff(), *LEGS, SetWind(6, 30), *LEGS[1:],
    ),
    vertical_scenario(
        "held16_gust_40s_legs",
        "wind 7 m/s from 240° for about 40 s of legs; legs",
        Takeoff(), *LEGS[:6], SetWind(7, 240), *LEGS[6:8], SetWind(0), *LEGS[8:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held16_onset_cross_fast",
        "wind 6 m/s from 270° switched on mid-flight; long legs at 8-9 m/s",
        Takeoff(), *FAST_LEGS, SetWind(6, 270), *FAST_LEGS[1:],
    ),
    vertical_scenario(
        "held16_stop_circles_payload",
        "1 kg gripper payload from take-off; wind 5 m/s from 150° from take-off, stopped "
        "during circles; then legs",
        SetWind(5, 150), Grip(True), Hover(3), Takeoff(), *CIRCLES[:4], SetWind(0),
        *CIRCLES[4:], *LEGS[1:6],
    ),
    vertical_scenario(
        "held16_two_turns_legs",
        "wind 4 m/s from 030° turning to 120°, then to 210°; legs",
        SetWind(4, 30), Takeoff(), *LEGS, SetWind(4, 120), *LEGS[1:7], SetWind(4, 210),
        *LEGS[7:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held16_clean_legs_circles",
        "no effect; legs, then circles",
        Takeoff(), *LEGS, *CIRCLES[1:],
    ),
)

#: The seventeenth held-out set (recorded after the commit that defined it froze the online
#: tracker with the report's lag term held while the vehicle hovers): wind changes just before
#: or across hovers, on slow and fast legs, with and without the payload, and a clean flight
#: with long hovers.
HELD_SCENARIOS_17: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held17_turn_before_hover",
        "wind 6 m/s from 330° turning to 060° as a 30 s hover starts; legs",
        SetWind(6, 330), Takeoff(), *LEGS[:3], SetWind(6, 60), Hover(30), *LEGS[4:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held17_reversal_before_hover",
        "wind 5 m/s from 090° reversing to 270° as a 25 s hover starts; legs",
        SetWind(5, 90), Takeoff(), *LEGS[:6], SetWind(5, 270), Hover(25), *LEGS[6:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held17_onset_before_hover",
        "wind 6 m/s from 200° switched on 10 s before a 30 s hover; legs",
        Takeoff(), *LEGS[:5], SetWind(6, 200), *LEGS[5:6], Hover(30), *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held17_stop_before_hover",
        "wind 7 m/s from 045° from take-off, stopped as a 30 s hover starts; legs, then circles",
        SetWind(7, 45), Takeoff(), *LEGS[:6], SetWind(0), Hover(30), *CIRCLES[1:],
    ),
    vertical_scenario(
        "held17_turn_hover_payload",
        "1 kg gripper payload from take-off; wind 5 m/s from 160° turning to 250° as a 25 s "
        "hover starts; legs",
        SetWind(5, 160), Grip(True), Hover(3), Takeoff(), *LEGS[:3], SetWind(5, 250),
        Hover(25), *LEGS[4:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held17_turn_fast_hover",
        "wind 6 m/s from 300° turning to 030° as a 20 s hover starts; long legs at 8-9 m/s",
        SetWind(6, 300), Takeoff(), *FAST_LEGS[:4], SetWind(6, 30), Hover(20), *FAST_LEGS[5:],
        *FAST_LEGS[1:4],
    ),
    vertical_scenario(
        "held17_gust_across_hover",
        "wind 7 m/s from 120° for about 60 s of legs and a 20 s hover; legs",
        Takeoff(), *LEGS[:2], SetWind(7, 120), *LEGS[2:3], Hover(20), *LEGS[4:6], SetWind(0),
        *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held17_clean_circles_hovers",
        "no effect; circles, a 30 s hover, legs",
        Takeoff(), *CIRCLES, Hover(30), *LEGS[1:6],
    ),
)

#: The eighteenth held-out set: wind changes on legs and in hovers that the autopilot's report
#: shows late (the power's change read against the old wind), a payload released shortly
#: after a wind change and one shortly before it (a mass step the report's change test must
#: not take back), and a clean flight.
HELD_SCENARIOS_18: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held18_onset_mid_legs",
        "wind 7 m/s from 150° switched on between two legs; legs",
        Takeoff(), *LEGS[:5], SetWind(7, 150), *LEGS[5:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_gust_hover_to_legs",
        "wind 7 m/s from 300° for about 70 s, setting in during a 30 s hover; legs",
        Takeoff(), *LEGS[:3], Hover(10), SetWind(7, 300), Hover(20), *LEGS[4:8], SetWind(0),
        *LEGS[8:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_release_after_onset",
        "1 kg gripper payload from take-off; wind 6 m/s from 030° switched on between legs, "
        "the payload released between legs about 30 s later; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 30), *LEGS[4:6], Grip(False),
        *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_release_then_turn",
        "1 kg gripper payload from take-off; wind 5 m/s from 240° turning to 330° 5 s after "
        "the payload is released in a hover; legs",
        SetWind(5, 240), Grip(True), Hover(3), Takeoff(), *LEGS[:6], Hover(10), Grip(False),
        Hover(5), SetWind(5, 330), *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_stop_hover_payload",
        "1 kg gripper payload from take-off; wind 6 m/s from 100° stopped 5 s into a 20 s "
        "hover; legs",
        SetWind(6, 100), Grip(True), Hover(3), Takeoff(), *LEGS[:6], Hover(5), SetWind(0),
        Hover(15), *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_onset_fast_payload",
        "1 kg gripper payload from take-off; wind 6 m/s from 200° switched on between fast "
        "legs; long legs at 8-9 m/s",
        Grip(True), Hover(3), Takeoff(), *FAST_LEGS[:5], SetWind(6, 200), *FAST_LEGS[5:],
        *FAST_LEGS[1:6],
    ),
    vertical_scenario(
        "held18_reversal_mid_legs",
        "wind 5 m/s from 180° reversing to 000° between two legs; legs",
        SetWind(5, 180), Takeoff(), *LEGS[:5], SetWind(5, 0), *LEGS[5:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held18_clean_fast_hovers",
        "no effect; long legs at 8-9 m/s, a 20 s hover, legs again",
        Takeoff(), *FAST_LEGS, Hover(20), *FAST_LEGS[1:6],
    ),
)

#: The nineteenth held-out set: changes a hover's power shows and the step after their alarm
#: reads: payload releases in short and long hovers, in wind, low and high, after legs, circles
#: and fast legs, a release and an onset in one hover, a gust setting in during a hover, and a
#: clean flight with hovers and a climb.
HELD_SCENARIOS_19: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held19_release_short_hover",
        "1 kg gripper payload from take-off; legs, the payload released 3 s into a 10 s "
        "hover; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:5], Hover(3), Grip(False), Hover(7), *LEGS[5:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held19_release_circles_wind",
        "1 kg gripper payload from take-off; wind 4 m/s from 310° from take-off; circles, the "
        "payload released in a hover after them; legs",
        SetWind(4, 310), Grip(True), Hover(3), Takeoff(), *CIRCLES[:-1], Hover(8), Grip(False),
        Hover(12), *LEGS[1:6],
    ),
    vertical_scenario(
        "held19_release_fast_hover",
        "1 kg gripper payload from take-off; long legs at 8-9 m/s, the payload released in a "
        "15 s hover; long legs",
        Grip(True), Hover(3), Takeoff(), *FAST_LEGS[:6], Hover(5), Grip(False), Hover(10),
        *FAST_LEGS[6:], *FAST_LEGS[1:4],
    ),
    vertical_scenario(
        "held19_release_low_wind",
        "1 kg gripper payload from take-off; wind 6 m/s from 060° from take-off; legs, a "
        "descent at 2 m/s to 10 m, the payload released in a hover there, the climb back at "
        "2 m/s; legs",
        SetWind(6, 60), Grip(True), Hover(3), Takeoff(), *LEGS[:4], Leg(0, 0, 5, 2), Hover(6),
        Grip(False), Hover(10), Leg(0, 0, 5, -2), *LEGS[4:], *LEGS[1:3],
    ),
    vertical_scenario(
        "held19_gust_in_hover",
        "wind 6 m/s from 170° for about 75 s, setting in 10 s into a 25 s hover; legs",
        Takeoff(), *LEGS[:3], Hover(10), SetWind(6, 170), Hover(15), *LEGS[4:7], SetWind(0),
        *LEGS[7:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held19_release_then_onset_hover",
        "1 kg gripper payload from take-off; legs, the payload released 5 s into a 25 s hover "
        "and wind 5 m/s from 250° switched on 10 s later; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:5], Hover(5), Grip(False), Hover(10),
        SetWind(5, 250), Hover(10), *LEGS[5:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held19_release_high_fast",
        "1 kg gripper payload from take-off; long legs, a climb at 6 m/s by 30 m, the payload "
        "released in a hover at the top, the descent at 3 m/s; long legs",
        Grip(True), Hover(3), Takeoff(), *FAST_LEGS[:4], Leg(0, 0, 5, -6), Hover(6),
        Grip(False), Hover(10), Leg(0, 0, 10, 3), *FAST_LEGS[4:], *FAST_LEGS[1:4],
    ),
    vertical_scenario(
        "held19_clean_hovers_climb",
        "no effect; legs, a climb at 3 m/s by 15 m, a 15 s hover, the descent; legs",
        Takeoff(), *LEGS[:5], Leg(0, 0, 5, -3), Hover(15), Leg(0, 0, 5, 3), *LEGS[5:],
        *LEGS[1:4],
    ),
)

#: The twentieth held-out set, for the residual loop with its winds bounded by the vehicle's
#: airspeed: wind episodes of 40-75 s over legs, circles and climbs, winds that stop and set
#: in among climbs, payloads released in wind after descents and climbs, winds near the
#: vehicle's reach (9 m/s) with and without a payload, and a clean flight with tall climbs.
HELD_SCENARIOS_20: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held20_gust_75s_legs",
        "wind 7 m/s from 200° for about 75 s of legs; legs",
        Takeoff(), *LEGS[:4], SetWind(7, 200), *LEGS[4:8], Hover(10), SetWind(0), *LEGS[8:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held20_gust_circles",
        "wind 6 m/s from 100° for about 70 s of circles; circles, legs",
        Takeoff(), *LEGS[:3], SetWind(6, 100), *CIRCLES[1:3], SetWind(0), *CIRCLES[3:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "held20_gust_climbs",
        "wind 6 m/s from 330° for about 75 s: a climb at 4 m/s by 20 m, legs there, a descent "
        "at 2 m/s; legs",
        Takeoff(), *LEGS[:3], SetWind(6, 330), Leg(0, 0, 5, -4), *LEGS[4:7], Leg(0, 0, 10, 2),
        SetWind(0), *LEGS[7:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held20_stop_climbing_legs",
        "wind 5 m/s from 120° from take-off, stopped mid-flight; legs, a climbing and a "
        "descending leg at 2 m/s; legs",
        SetWind(5, 120), Takeoff(), *LEGS[:6], Leg(4, 0, 10, -2), Leg(-4, 0, 10, 2), SetWind(0),
        *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held20_release_low_wind7",
        "1 kg gripper payload from take-off; wind 7 m/s from 030° from take-off; legs, a "
        "descent at 2.5 m/s to 10 m, the payload released in a hover there, the climb back; "
        "legs",
        SetWind(7, 30), Grip(True), Hover(3), Takeoff(), *LEGS[:4], Leg(0, 0, 4, 2.5),
        Hover(6), Grip(False), Hover(12), Leg(0, 0, 4, -2.5), *LEGS[4:], *LEGS[1:3],
    ),
    vertical_scenario(
        "held20_payload_strong_wind",
        "1 kg gripper payload from take-off; wind 9 m/s from 250° throughout; legs",
        SetWind(9, 250), Grip(True), Hover(3), Takeoff(), *LEGS, *LEGS[1:5],
    ),
    vertical_scenario(
        "held20_release_after_climb_wind",
        "1 kg gripper payload from take-off; wind 5 m/s from 160° from take-off; legs, a climb "
        "at 5 m/s by 40 m, the payload released in a hover at the top, the descent at 4 m/s; "
        "legs",
        SetWind(5, 160), Grip(True), Hover(3), Takeoff(), *LEGS[:4], Leg(0, 0, 8, -5),
        Hover(6), Grip(False), Hover(10), Leg(0, 0, 10, 4), *LEGS[4:], *LEGS[1:3],
    ),
    vertical_scenario(
        "held20_payload_gust_legs",
        "1 kg gripper payload from take-off; wind 6 m/s from 020° for about 75 s of legs; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 20), *LEGS[4:8], Hover(10),
        SetWind(0), *LEGS[8:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held20_clean_tall_stairs",
        "no effect; a climb at 7 m/s by 35 m, legs, a climb at 1 m/s by 10 m, a descent at "
        "5 m/s by 30 m, legs, a descent at 2 m/s by 15 m",
        Takeoff(), Hover(10), Leg(0, 0, 5, -7), *LEGS[1:4], Leg(0, 0, 10, -1), Hover(5),
        Leg(0, 0, 6, 5), *LEGS[4:8], Leg(0, 0, 7.5, 2), *LEGS[8:],
    ),
    vertical_scenario(
        "held20_strong_wind_hovers",
        "wind 9 m/s from 160° throughout; legs and 20 s hovers",
        SetWind(9, 160), Takeoff(), *LEGS[:4], Hover(20), *LEGS[4:8], Hover(20), *LEGS[8:],
    ),
    vertical_scenario(
        "held20_onset_in_climb",
        "wind 6 m/s from 280° switched on during a climb at 3 m/s by 24 m; legs",
        Takeoff(), *LEGS[:5], Leg(0, 0, 4, -3), SetWind(6, 280), Leg(0, 0, 4, -3), *LEGS[5:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held20_gust_40s_hover_legs",
        "wind 7 m/s from 060° for about 40 s: a 10 s hover and legs; legs",
        Takeoff(), *LEGS[:5], SetWind(7, 60), Hover(10), *LEGS[5:7], SetWind(0), *LEGS[7:],
        *LEGS[1:4],
    ),
)

#: The twenty-first held-out set, for the online tracker whose mass learnt in a hover carries
#: the uncertainty of the wind held there (:mod:`estimator.estimation.reported_sigma`):
#: take-offs into strong winds with long hovers, with and without the payload, winds that set
#: in and stop during hovers, a release in a hover in a strong wind, calm and light-wind
#: flights with long hovers (a 1σ no wider than it must be), and short wind episodes over
#: climbs, hovers, circles and legs for the residual loop.
HELD_SCENARIOS_21: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held21_takeoff_wind8_hovers",
        "wind 8 m/s from 070° throughout; legs, a 25 s hover; legs",
        SetWind(8, 70), Takeoff(), *LEGS[:5], Hover(25), *LEGS[5:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held21_payload_takeoff_wind7",
        "1 kg gripper payload from take-off; wind 7 m/s from 300° throughout; legs and a 20 s "
        "hover",
        SetWind(7, 300), Grip(True), Hover(3), Takeoff(), *LEGS[:6], Hover(20), *LEGS[6:],
    ),
    vertical_scenario(
        "held21_onset_in_hover",
        "wind 7 m/s from 180° set in during a 30 s hover mid-flight; legs",
        Takeoff(), *LEGS[:5], Hover(10), SetWind(7, 180), Hover(20), *LEGS[5:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held21_stop_in_hover",
        "wind 6 m/s from 045° from take-off, stopped during a 25 s hover mid-flight; legs",
        SetWind(6, 45), Takeoff(), *LEGS[:5], Hover(10), SetWind(0), Hover(15), *LEGS[5:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held21_release_strong_wind_hover",
        "1 kg gripper payload from take-off; wind 8 m/s from 120° throughout; legs, the payload "
        "released in a 20 s hover; legs",
        SetWind(8, 120), Grip(True), Hover(3), Takeoff(), *LEGS[:6], Hover(8), Grip(False),
        Hover(12), *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held21_calm_long_hovers",
        "no effect; legs and 30 s hovers",
        Takeoff(), *LEGS[:4], Hover(30), *LEGS[4:8], Hover(30), *LEGS[8:],
    ),
    vertical_scenario(
        "held21_light_wind_hovers",
        "wind 3 m/s from 210° throughout; legs and 30 s hovers",
        SetWind(3, 210), Takeoff(), *LEGS[:4], Hover(30), *LEGS[4:8], Hover(30), *LEGS[8:],
    ),
    vertical_scenario(
        "held21_payload_calm_hovers",
        "1 kg gripper payload from take-off; no wind; legs and 30 s hovers",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], Hover(30), *LEGS[4:8], Hover(30),
        *LEGS[8:],
    ),
    vertical_scenario(
        "held21_gust_climb_hover",
        "wind 7 m/s from 340° for about 60 s: a climb at 3 m/s by 15 m, a 15 s hover there, "
        "legs, the descent at 3 m/s; legs",
        Takeoff(), *LEGS[:4], SetWind(7, 340), Leg(0, 0, 5, -3), Hover(15), *LEGS[4:6],
        Leg(0, 0, 5, 3), SetWind(0), *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held21_payload_gust_85s_legs",
        "1 kg gripper payload from take-off; wind 6 m/s from 090° for about 85 s of legs; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(6, 90), *LEGS[4:8], Hover(10),
        Leg(4, 0, 10), SetWind(0), *LEGS[8:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held21_wind_tall_climb_hovers",
        "wind 8 m/s from 020° throughout; a climb at 5 m/s by 30 m, a 15 s hover, legs, a "
        "descent at 3 m/s, a 15 s hover at the bottom; legs",
        SetWind(8, 20), Takeoff(), Hover(10), Leg(0, 0, 6, -5), Hover(15), *LEGS[1:5],
        Leg(0, 0, 10, 3), Hover(15), *LEGS[5:],
    ),
    vertical_scenario(
        "held21_gust_50s_circles_climb",
        "wind 6 m/s from 250° for about 50 s: circles and a climb at 2 m/s by 10 m; legs",
        Takeoff(), *LEGS[:3], SetWind(6, 250), *CIRCLES[1:3], Leg(0, 0, 5, -2), SetWind(0),
        *CIRCLES[3:], *LEGS[1:4],
    ),
)

#: The twenty-second held-out set, for the online tracker whose autopilot-report lag is
#: measured at every report and only once the autopilot estimates the wind
#: (:meth:`~estimator.estimation.autopilot_wind.AutopilotWind.lag_mps`): winds that set in,
#: stop, turn and reverse during slow, fast and diagonal legs and circles, take-offs into
#: winds, a gust and a release with the payload, a clean flight; and wind episodes of 45-90 s
#: over legs, climbs and circles for the residual loop.
HELD_SCENARIOS_22: dict[str, Scenario] = by_name(
    vertical_scenario(
        "held22_onset_slow_legs",
        "wind 6 m/s from 030° switched on during a 3 m/s leg mid-flight; legs",
        Takeoff(), *LEGS[:8], Leg(0, 3, 12), SetWind(6, 30), Leg(0, 3, 18), *LEGS[9:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held22_stop_fast_legs",
        "wind 7 m/s from 200° from take-off, stopped during a 9 m/s leg; fast legs",
        SetWind(7, 200), Takeoff(), *FAST_LEGS[:5], Leg(0, 8, 7), SetWind(0), Leg(0, 8, 8),
        *FAST_LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held22_turn_diagonal_legs",
        "wind 6 m/s from 300°, turning to 040° during a diagonal leg; legs",
        SetWind(6, 300), Takeoff(), *FAST_LEGS[:9], Leg(6, 6, 7), SetWind(6, 40), Leg(6, 6, 8),
        *FAST_LEGS[10:], *LEGS[1:6],
    ),
    vertical_scenario(
        "held22_reversal_circles",
        "wind 5 m/s from 100°, reversed to 280° during circles; legs",
        SetWind(5, 100), Takeoff(), *LEGS[:3], *CIRCLES[1:3], SetWind(5, 280), *CIRCLES[3:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held22_takeoff_wind6_fast",
        "wind 6 m/s from 150° throughout; fast legs",
        SetWind(6, 150), Takeoff(), *FAST_LEGS, *LEGS[1:5],
    ),
    vertical_scenario(
        "held22_onset_then_stop_legs",
        "wind 8 m/s from 330° for about 90 s of legs with a 10 s hover; legs",
        Takeoff(), *LEGS[:4], SetWind(8, 330), *LEGS[4:10], SetWind(0), *LEGS[10:],
        *LEGS[1:5],
    ),
    vertical_scenario(
        "held22_gust_45s_climb_legs",
        "wind 7 m/s from 120° for about 45 s: a climb at 2 m/s by 10 m and legs there; legs",
        Takeoff(), *LEGS[:3], SetWind(7, 120), Leg(0, 0, 5, -2), *LEGS[4:6], SetWind(0),
        *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held22_payload_gust_60s_circles",
        "1 kg gripper payload from take-off; wind 6 m/s from 060° for about 60 s of circles; "
        "legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:3], SetWind(6, 60), *CIRCLES[1:3],
        SetWind(0), *CIRCLES[3:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held22_release_after_onset",
        "1 kg gripper payload from take-off; wind 5 m/s from 250° switched on during legs, the "
        "payload released in a 15 s hover 40 s later; legs",
        Grip(True), Hover(3), Takeoff(), *LEGS[:4], SetWind(5, 250), *LEGS[4:6], Hover(5),
        Grip(False), Hover(10), *LEGS[6:], *LEGS[1:4],
    ),
    vertical_scenario(
        "held22_wind_speedup_legs",
        "wind 3 m/s from 090° rising to 8 m/s from 090° mid-flight; legs",
        SetWind(3, 90), Takeoff(), *LEGS[:6], SetWind(8, 90), *LEGS[6:], *LEGS[1:5],
    ),
    vertical_scenario(
        "held22_payload_wind_climbs",
        "1 kg gripper payload from take-off; wind 5 m/s from 010° throughout; climbs at 2 and "
        "5 m/s by 20 m and their descents between legs",
        SetWind(5, 10), Grip(True), Hover(3), Takeoff(), *LEGS[:4], Leg(0, 0, 10, -2),
        *LEGS[4:6], Leg(0, 0, 10, 2), Leg(0, 0, 4, -5), *LEGS[6:], Leg(0, 0, 4, 5),
    ),
    vertical_scenario(
        "held22_clean_fast_mixed",
        "no effect; fast legs, circles and a climb at 4 m/s by 20 m",
        Takeoff(), *FAST_LEGS, *CIRCLES[1:4], Leg(0, 0, 5, -4), *LEGS[1:4], Leg(0, 0, 5, 4),
    ),
)

# fmt: on
