"""The held-out ArduCopter SITL flights of ``replay/sitl_held``, recorded after the rules
were frozen (``held_*`` after commit 870ed85, ``held2_*`` after 7e98e75, ``held3_*`` after
0882b25, ``held4_*`` after a89bc67, ``held5_*`` after 4c0a20c, ``held6_*`` after 58b857a,
``held7_*`` after 85c501c, ``held8_*`` after 6c86e16, ``held9_*`` after 267e25a,
``held10_*`` after f1c5f35, ``held11_*`` after 6843aff, ``held12_*`` after daa503a,
``held13_*`` after c695f88, ``held14_*`` after 83546f5, ``held15_*`` (clean, with vertical
legs) after 63ab45b, ``held16_*`` (wind turns and reversals) after de19c8e, which made the
autopilot report's lag term widen both wind components, ``held17_*`` (wind changes just
before or across hovers) after 72fe3f3, which held that term while the vehicle hovers,
``held18_*`` (wind changes the report shows late, payload releases near them) after 3b44bad,
whose rule (the mass learnt since taken back when the report shows a change) they refuted and
which was reverted, so that they are held out for the rules before it as well, ``held19_*``
(changes in hovers, mostly payload releases) after 818e6a9, which reports the step after a
change alarm's step with a changed state's 1σ, ``held20_*`` (short wind episodes, climbs,
strong winds, releases in wind) after the commit that kept the residual loop's winds within
the vehicle's airspeed, ``held21_*`` after 070d1ee, ``held22_*`` after 9cd5407 (two tracker
rules) and ``held23_*`` (short wind episodes) after 95ff584, which made the residual loop's
rank test sum 2.5 s blocks and try the autopilot's wind in a window; docs/residuals.md,
"Held-out SITL flights"):
what ``uav-energy residuals`` names against their truth, and the online tracker step by step.

Nothing was tuned on these flights; the first two sets were looked at before the vertical
effects of 0882b25 were chosen, and the first three before the tracker's model-form 1σ of
a89bc67, the first four before the tracker's wind 1σ of 4c0a20c, the first five before its
vertical transitions of 58b857a, the first six before its consider term for the P(V) shape
of 85c501c, the first seven before its lag term that decays where the report stalls, the
first eight before its mixture of an undecided duel of 267e25a, and the first nine before
its change test on the autopilot's report at χ²₂ at 1 % and its step after an alarm of
f1c5f35, the first ten before its report's gap weighed by the probability of a
disagreement of 6843aff, and the first eleven before its changed state's 1σ after a step the
gate refused of daa503a, and the first twelve before it also after a step that raised a
change alarm of c695f88, and the first thirteen before it also after a step that grew the
CUSUM past half its threshold of 83546f5, and all fifteen before its lag term to both wind
components, all sixteen before its lag term held in a hover, and all eighteen before its
changed state's 1σ on the step after an alarm's step, and all nineteen before the residual
loop's bound on a wind's airspeed, and all twenty-two before its 2.5 s blocks: for the
residual analysis ``held23_*`` are held out, for the tracker ``held22_*`` and ``held23_*``,
for the heave gain fitted through the accelerations'
filter ``held15_*`` to ``held20_*``. Each flight
is held to the issue's aims: the first named effect is a true one, the held-out RMSE after
ends within 2.5 noise floors, and the running mass and wind hold 90 % of the steps within 2σ
and all within 3σ. A flight that misses stays here as a strict xfail with its cause, read off
its candidates.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest
import vertical_fit
from script_loader import load_script

from estimator.analysis.residual_samples import prepare
from estimator.analysis.sitl_truth import RecordingTruth
from estimator.analysis.tracker_truth import TrackerRun
from estimator.logs import load_flights
from estimator.physics.effects import Climb
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.episode_held_scenarios import HELD_SETS
from estimator.sitl.truth_check import FlightScore

REPO = Path(__file__).resolve().parent.parent
THIS_FILE = "tests/test_sitl_held_out.py"
#: The first test to ask for a flight's score runs the residual analysis of every held-out
#: recording (``SITL.held_checks``, cached for the rest: about 1.7 s of CPU each, 142 of them
#: at 0350f68, so 4 min alone and more under load), within its own timeout.
pytestmark = pytest.mark.timeout(1200)


FIGURES = load_script("figures")
SITL = FIGURES.sitl
TRACKER = FIGURES.script_module("tracker_sitl")
FLIGHTS = sorted(name for held in HELD_SETS.values() for name in held)
#: The windowed rank test: n blocks that all gain reach z = sqrt(3n(n+1)/(2(2n+1))) at most,
#: below 3 for fewer than 12 (tests/test_residuals.py): a minute of 5 s blocks before 95ff584,
#: 30 s of 2.5 s blocks since.
SHORT_EPISODE = "too short an episode for z 3 in the windowed rank test"
#: Flights whose first named effect is wrong, and why (each read off its candidates under the
#: rules its set was held out for: the gains and z of sets recorded before 95ff584 are over
#: 5 s blocks; over 2.5 s blocks the same gains read higher, and these flights still miss).
NOT_RIGHT = {
    "held_gust_30s_hover": "30 s of wind in a hover changes SITL's power little; no "
    "candidate gains at z above 1.7",
    "held_gust_60s": "the windowed wind is right and gains 15 %, at z 0.9; a windowed load "
    "gains as much at z 1.8",
    "held_gust_90s_circles": "the windowed wind gains 13 % at z 2.1; a windowed load as well",
    "held_gust_vertical": "a 50 s episode among climbs: the best candidate, a steady wind of "
    f"1.5 m/s, gains 4.8 % at z 2.4 ({SHORT_EPISODE})",
    "held_two_gusts": "two episodes from opposite directions: no candidate gains",
    "held2_gust_70s_circles": "the autopilot's wind gains 38 % at z 0.6 (it lags the gust), "
    "the windowed wind (right) 11 % at z 1.3",
    "held2_gust_90s_hovers": "the windowed wind is right and gains 43 %, at z 2.6 (18 blocks: "
    "z 3.6 at most)",
    "held3_gust_45s_legs": f"no candidate gains more than 9.4 % nor reaches z 1.7 "
    f"({SHORT_EPISODE})",
    "held3_gust_75s_vertical": "the windowed wind gains 25 % at z 2.2 (its start 20 s early, "
    "its speed 5.4 of 7 m/s), the autopilot's wind 23 % at z 0.7",
    "held7_payload_wind_fast": "mass -0.45 kg, as good held out as a constant load, then the "
    "wind, a load of +175 W and the air density: flown fast with a payload, SITL's power grows "
    "with the thrust at every speed, the model's mass law only in the induced power",
    "held8_gust_legs": "the autopilot's wind × 0.88 gains 28 % at z 0.07; the windowed wind "
    "5.4 m/s from 247° spans 120-226 s of the 129-195 s gust and gains 9.4 % at z 1.53",
    "held8_two_gusts_legs": "the windowed wind is right for the first gust (5.1 m/s from 103°, "
    "121-164 s of 119-159 s) but gains 21 % at z 1.09; the autopilot's wind × 0.79 29 % at "
    "z 2.09",
    "held9_reversal_fast_legs": "the autopilot's wind × 0.87 is right in speed and direction "
    "(4.7 m/s from 271°, then 4.6 m/s from 91°) but switches at 226 s, 40 s after the truth's "
    "186 s: ArduCopter's WIND kept the old wind that long, then flipped within 4 s",
    "held10_onset_slow_legs": "a wind change from 1.0 m/s from 34° (truth: still air; the "
    "model's P(V) shape reads as up to 1 m/s of wind in still air) to 3.4 m/s from 152° at "
    "256 s (truth 4 m/s from 160° at 255 s): the onset is right, the still air before it not",
    "held10_turn_fast_legs": "the autopilot's wind × 0.88 is right in speed and direction "
    "(5.7 m/s from 121°, then 5.6 m/s from 200°) but switches at 198 s, 12 s after the truth's "
    "186 s, beyond the 10 s the check allows: the report it scales lags the turn",
    "held16_gust_40s_legs": "no candidate gains more than 1.4 %: the windowed wind (3.6 m/s "
    f"from 18°, 150-239 s; truth 7 m/s from 240° for 40 s) loses 2.5 % ({SHORT_EPISODE})",
    "held16_reversal_legs": "the wind and its reversal are right in speed and direction (4.4 m/s "
    "from 15°, then from 189°; truth 5 m/s from 10°, then 190°), but the change is placed at "
    "241 s, 14 s before the truth's 255 s (its 1σ over the folds 9.5 s), beyond the 10 s the "
    "check allows",
    "held16_turn_payload_legs": "the payload is named first, as a mass of +1.12 kg; the load "
    "named third (+122 W, all flight) then takes it over in the joint fit (mass -0.04 kg at the "
    "end): with a payload SITL's power grows with the thrust at every speed, which a constant "
    "load fits as well (held7_payload_wind_fast)",
    "held13_gust_hovers": "the windowed wind is right (6.0 m/s from 80°, 121-173 s of the "
    "119-174 s gust of 6 m/s from 80°) and gains 29 %, at z 1.22; the autopilot's wind × 0.93 "
    f"gains 58 % at z 1.34 ({SHORT_EPISODE})",
    "held17_reversal_before_hover": "the autopilot's wind × 0.82 is right in speed and "
    "direction (4.5 m/s from 91°, then 4.4 m/s from 271°) but switches at 185 s, 26 s after the "
    "truth's 159 s: the reversal came as a 25 s hover began, where ArduCopter's EKF holds its "
    "wind",
    "held17_turn_fast_hover": "the autopilot's wind × 0.89 is right in speed and direction "
    "(5.7 m/s from 303°, then from 29°) but switches at 118 s, 17 s after the truth's 101 s: "
    "the turn came as a 20 s hover began, where ArduCopter's EKF holds its wind",
    "held18_gust_hover_to_legs": "the autopilot's wind × 0.87 gains 39 % at z 1.76; the "
    "windowed wind (6.4 m/s from 251°, 121-203 s; truth 7 m/s from 300°, 129-215 s) loses 32 %: "
    "short of z 3",
    "held18_reversal_mid_legs": "the wind and its reversal are right in speed and direction "
    "(4.8 m/s from 196°, then 4.4 m/s from 4°; truth 5 m/s from 180°, then from 0°), but the "
    "change is placed at 133 s, 16 s before the truth's 149 s, beyond the 10 s the check allows",
    "held19_gust_in_hover": "no candidate qualifies: the all-flight wind (1.7 m/s) gains 15 % "
    "at z 2.3; the windowed wind (2.8 m/s from 94°, until 166 s; truth 6 m/s from 170°, "
    "129-204 s) loses 63 %, and so does the autopilot's wind × 0.82 (54 %), which holds its "
    "old value through the hover the gust set in during",
    "held20_gust_40s_hover_legs": "a 40 s episode setting in during a 10 s hover: the windowed "
    "wind (6.5 m/s from 65°, from 153 s; truth 7 m/s from 60°, 149-199 s) loses 150 %, the "
    "autopilot's wind × 0.93 gains 48 % at z 0.45 (its report lags the onset and holds after "
    f"the end) ({SHORT_EPISODE})",
    "held20_gust_75s_legs": "the window search does not find the gust: from the all-flight "
    "wind (1.3 m/s from 8°) and the two halves' (the gust, 129-205 s, sits across the middle) "
    "it settles on 1.7 m/s from 5° until 267 s (truth 7 m/s from 200°), which loses 28 %; the "
    "autopilot's wind × 0.80 gains 39 % at z 1.25",
    "held20_gust_circles": "the windowed wind is right (5.7 m/s from 98°, 121-187 s; truth "
    "6 m/s from 100°, 119-186 s) but gains 21 % at z 1.96, the autopilot's wind × 0.88 42 % at "
    "z 0.24: short of z 3",
    "held21_gust_50s_circles_climb": "the windowed wind is right (5.6 m/s from 248°, 122-182 s; "
    f"truth 6 m/s from 250°) but gains 25 % at z 1.91: short of z 3 ({SHORT_EPISODE})",
    "held21_gust_climb_hover": "a 55 s episode over a climb, a 15 s hover, legs and a descent: "
    "nothing gains at z above 0 (the autopilot's wind × 0.81, 6 % at z -0.86) "
    f"({SHORT_EPISODE})",
    "held21_payload_takeoff_wind7": "a 1 kg payload from take-off in a 7 m/s wind: a constant "
    "load (avionics, 127 W) gains 88.6 % at the first step, the mass 88.3 %, the wind not yet "
    "explained; after the wind the mass reads +0.06 kg and the load 112 W",
    "held22_gust_45s_climb_legs": "the windowed wind (7.1 m/s from 115°, 122-157 s; truth "
    f"7 m/s from 120°) gains 8 % at z 1.18 ({SHORT_EPISODE})",
    "held22_stop_fast_legs": "a 7 m/s wind from take-off stopped during fast legs: the windowed "
    "wind (6.2 m/s from 154°, until 103 s; truth 7 m/s from 200°, until 113 s) gains 54 % at "
    "z 2.80, the autopilot's wind × 0.72 43 % at z 1.14: short of z 3",
    "held22_turn_diagonal_legs": "the autopilot's wind is named with its turn at 178 s, 25 s "
    "after the truth's 153 s (the report follows the turn late), beyond the 10 s the check "
    "allows",
    "held11_payload_gust_circles": "the payload is named first (mass +1.06 kg, 91 % at z 8.9) "
    "and the autopilot's wind second, but over 2.5 s blocks a constant load of about 110 W "
    "qualifies third and takes the payload over in the joint refit (mass -0.05 kg at the end), "
    "as on held16_turn_payload_legs",
    "held20_stop_climbing_legs": "the autopilot's wind, all flight (one number), qualifies "
    "(45 % at z 3.41) and the windowed wind (right, until 172 s; 50.5 % at z 5.4) cuts its "
    "held-out error by 9.7 %, short of the 10 % a richer form needs; the report's summary "
    "ends at 193 s, 14 s after the truth's 179 s, beyond the 10 s the check allows",
    "held23_gust_30s_legs": "the windowed wind places the 30 s gust right (129-161 s) but "
    "from 128° (truth 045°) and loses 38 % held out; the autopilot's wind gains 25 % at z 0.72 "
    "(it lags the onset and holds after the end): nothing qualifies",
    "held23_gust_40s_fast_legs": "nothing gains at z above 0.4: the windowed wind settles on "
    "1.1 m/s from 162° (truth 8 m/s from 250° over 40 s of 8-9 m/s legs) and the autopilot's "
    "wind fits a scale of 0",
    "held23_gust_50s_climb_descent": "the windowed wind is right in speed and direction "
    "(7.3 m/s from 107°, 132-167 s; truth 7 m/s from 090°, 129-174 s) but gains 5 % at z 0.91; "
    "the autopilot's wind in a window 43 % at z -0.25 (it holds after the gust)",
    "held23_gust_55s_slow_legs": "over 2-3 m/s legs the 6 m/s gust shows little: nothing "
    "gains at z above 2 (the windowed wind 1.0 m/s, 6 % at z 1.96)",
    "held23_gust_65s_circles": "the windowed wind is right (5.4 m/s from 297°, truth 6 m/s "
    "from 300°) and qualifies (41 % at z 4.08), but the fit on all data starts it at 107 s, "
    "12 s before the truth's 119 s, beyond the 10 s the check allows",
    "held23_gust_70s_diagonal_legs": "a windowed load gains 25.3 % at z 3.51, the autopilot's "
    "windowed wind (right: 149-221 s) 24.9 % at z 3.95: the lowest held-out RMSE is the "
    "load's, named first (about 17 W over the gust)",
    "held23_stop_slow_legs": "the autopilot's wind all flight (one number) gains 52.4 % at "
    "z 4.24, the windowed wind (right, until 169 s) 52.3 %: the simpler form is kept, and as "
    "ArduCopter's report holds the old wind 26 s after the stop in the 2 m/s legs its summary "
    "ends at 195 s (truth 169 s)",
}
#: Flights whose held-out RMSE after ends above 2.5 noise floors, and why.
ABOVE_FLOOR = {
    "held_gust_60s": "the wind episode not named (above): 3.5 floors",
    "held_gust_90s_circles": "the wind episode not named (above): 4.2 floors",
    "held_two_gusts": "the wind episodes not named (above): 2.8 floors",
    "held3_gust_45s_legs": "the wind episode not named (above): 3.8 floors",
    "held4_payload_gust_80s": "2.53 floors: the gust is named right (121-212 s of 119-215 s), "
    "then 20 s of the autopilot's wind that holds after its end (3.0 m/s until 232 s)",
    "held8_gust_legs": "the wind episode not named (above): 2.99 floors",
    "held13_gust_hovers": "the wind episode not named (above): 4.29 floors",
    "held16_gust_40s_legs": "the wind episode not named (above): 2.56 floors",
    "held17_reversal_before_hover": "the reversal placed 26 s late (above): 2.83 floors",
    "held18_gust_hover_to_legs": "the wind episode not named (above): 2.65 floors",
    "held20_gust_40s_hover_legs": "the wind episode not named (above): 3.86 floors",
    "held20_gust_75s_legs": "the wind episode not named (above): 2.96 floors",
    "held20_gust_circles": "the wind episode not named (above): 3.00 floors",
    "held21_gust_50s_circles_climb": "the wind episode not named (above): 2.83 floors",
    "held22_gust_45s_climb_legs": "the wind episode not named (above): 4.25 floors",
    "held22_payload_gust_60s_circles": "3.28 floors: the payload is named, the gust is not (its "
    "windowed wind, 5.2 m/s from 57° over 103-187 s, truth 6 m/s from 60°, gains 16 % at "
    "z 1.14)",
    "held22_turn_diagonal_legs": "the turn placed 25 s late (above): 3.05 floors",
    "held21_payload_gust_85s_legs": "3.78 floors: the payload is named, the gust is not (its "
    "windowed wind, 5.8 m/s from 94° over 130-164 s of the truth's 85 s from 90°, gains 37 % at "
    "z 1.58)",
    "held23_gust_30s_legs": "nothing named (4.47 floors)",
    "held23_gust_40s_fast_legs": "nothing named (3.92 floors)",
    "held23_gust_50s_climb_descent": "nothing named (2.87 floors)",
    "held23_gust_55s_slow_legs": "nothing named (2.73 floors)",
    "held23_two_gusts_legs": "the autopilot's wind all flight is named (42 % at z 3.66); the "
    "second gust's 5 m/s from 270° is left to its report's tail (2.53 floors)",
}
#: Flights whose running mass or wind misses the tracker's aim, and why (times from take-off). The
#: wind follows the autopilot's WIND, which lags a gust's start by ~30 s and holds after its end (in
#: a hover ArduCopter's EKF holds its wind): the steps before it moves are beyond 3σ; once it moves,
#: its lag (to both components) and gap widen the 1σ (the lag decaying at the EKF's own pace where
#: the report stalls, and not while the vehicle hovers), and after a stop the old wind can stay
#: until the report is χ²₂ 1 % apart for three steps. A release in a hover reads half way for the
#: step that straddles it (the step after, beyond the gate, completes it; a landing descent's start
#: did too, until a step the vertical gates mostly left out was left out whole), and that step and
#: one the gate refused are reported with a changed state's 1σ, as are steps whose innovations lean
#: towards a change (the CUSUM grown past half its threshold: a release the alarm takes two steps
#: late, held10_release_after_stop, held2_release_low). The payloads read a few percent heavy lie
#: within the reported 1σ (``OnlineSettings.mass_form_sigma_fraction``), and so, with the P(V)
#: shape's error carried as a consider term (``estimation/form_error.py``), do most flights without
#: a payload read 0.03 kg light when flown fast; a mass learnt in a hover in a wind not yet known
#: carries that wind's uncertainty (``estimation/reported_sigma.py``: the take-off hovers of
#: held4_wind_strong_legs and held20_strong_wind_hovers, 3.1σ and 4.8σ before); and the report's
#: lag term, measured at every report, widens the wind's 1σ from the first report that moves
#: after a change (``AutopilotWind.lag_mps``: seven flights of held7_* to held18_*, 3.1-3.7σ
#: before).
TRACKER_SHORT = {
    "held10_turn_fast_legs": "wind 8.0σ (8.2 m/s off) at 158 s; mass 89 % within 2σ (median "
    "-0.040 kg at 1σ 0.029 kg)",
    "held13_release_fast_leg": "mass 4.2σ (-0.74 kg) at 197 s: the landing descent's start, "
    "partly in the step's readings past the vertical gates, read as a mass drop (an alarm and "
    "a duel)",
    "held16_reversal_legs": "wind 6.0σ (8.3 m/s off) at 234 s: reversed at the end of a hover, "
    "where ArduCopter's EKF holds its wind and SITL's power does not show it; mass 6.4σ "
    "(+0.29 kg) at 246 s: once the vehicle moves, the change read in part as a mass step",
    "held2_wind_stop_vertical": "wind 5.3σ (6.8 m/s off) at 114 s",
    "held3_gust_45s_legs": "wind 91 % within 2σ, 8.6σ (7.4 m/s off) at 188 s; mass 92 % "
    "within 2σ, 3.4σ (+0.19 kg) at 126 s",
    "held3_gust_75s_vertical": "wind 3.1σ (7.0 m/s off) at 160 s",
    "held5_turn_legs": "wind 99 % within 2σ, 6.3σ (7.5 m/s off) at 116 s: the two steps right "
    "after the turn, before the report moved (its east then held its old value for 30 s, "
    "through a hover where the lag term holds)",
    "held8_turn_legs": "wind 5.8σ (7.4 m/s off) at 234 s",
    "held9_reversal_fast_legs": "wind 86 % within 2σ, 11.2σ (9.6 m/s off) at 178 s",
    "held17_gust_across_hover": "mass 98 % within 2σ, 4.5σ (+0.26 kg) at 72 s: 8-14 s into "
    "the gust's onset on a leg, read in part as a mass step before the report moved",
    "held17_reversal_before_hover": "wind 94 % within 2σ, 7.8σ (10.4 m/s off) at 116 s: the "
    "first steps after the reversal, before the report moved; 3.0-3.3σ 22-24 s after it, at the "
    "hover's end",
    "held17_stop_before_hover": "wind 3.0σ (7.1 m/s off) at 114 s: the step after the stop, "
    "before the report moved",
    "held18_reversal_mid_legs": "wind 87 % within 2σ, 4.6σ (9.7 m/s off) at 114 s: a north "
    "wind reversed as an east-west leg began, where the power hardly tells the two apart (the "
    "first three steps blind); from 110 s the power's evidence for it passed 2 nats at about 1σ "
    "a step, while the report held its old value for 12 s, and the tracker did not follow it",
    "held_gust_60s": "wind 93 % within 2σ, 4.9σ (8.1 m/s off) at 138 s; mass 4.2σ (+0.15 kg) at "
    "148 s",
    "held20_gust_40s_hover_legs": "wind 3.7σ (7.4 m/s off) at 104-106 s: the onset came in a "
    "10 s hover, its first steps blind; 3.1σ at 154 s, the step after its end",
    "held20_gust_75s_legs": "wind 89 % within 2σ, 4.7σ at 84 s (the onset's step, blind) and "
    "5.3σ (5.9 m/s off) at 190 s: after the gust's end at 158 s the estimate kept its wind, "
    "and its 1σ shrank back within 30 s while the autopilot's report held the old wind",
    "held21_gust_50s_circles_climb": "mass 89 % within 2σ (-0.06 to -0.08 kg at 1σ 0.03 kg "
    "for 30 s after the gust's end, circling)",
    "held22_onset_then_stop_legs": "mass 3.0σ (-0.27 kg at 1σ 0.09 kg) at 252 s, 64 s after "
    "the wind stopped: the estimate still held 2.6 m/s of it, and the mass took the rest",
    "held22_reversal_circles": "wind 94 % within 2σ, 3.2-4.8σ (9.5-10.1 m/s off) at 144-156 s: "
    "a 5 m/s wind reversed during circles, the first steps after it blind",
    "held22_stop_fast_legs": "mass 90 % within 2σ, 3.1σ (-0.16 kg at 1σ 0.05 kg) at 84-90 s: "
    "after a 7 m/s wind stopped on a 9 m/s leg the estimate kept 6 m/s of it, and once its 1σ "
    "widened the mass took part of the power; wind 3.0σ (6.6 m/s off) at 78 s",
    "held22_turn_diagonal_legs": "wind 95 % within 2σ, 3.8-4.7σ (9.4-9.7 m/s off) at 114-118 s: "
    "a 6 m/s wind turning 100° during a diagonal leg, before the report moved",
    "held21_payload_gust_85s_legs": "wind 91 % within 2σ, 6.8σ (4.9 m/s off) at 197 s: after "
    "the gust's end the autopilot's report held the old wind (4.8 m/s from the east) for 30 s on a "
    "north leg where the power hardly shows it, and the estimate's 1σ shrank back with it",
    "held23_gust_30s_legs": "mass 3.0σ (-0.16 kg at 1σ 0.05 kg) 6 s after a 30 s gust ended: "
    "the estimate still held about 6 m/s of it (2.2σ) and the mass took the rest",
    "held23_gust_50s_climb_descent": "mass 85 % within 2σ: for 60 s after the gust ended the "
    "estimate held 6.2 m/s of it (2.1σ) and the mass read 2.0-2.8σ light, 3.3σ once in a climb",
    "held23_gust_55s_slow_legs": "wind 3.1σ (4.6 m/s off) 2 s after a 55 s gust over 2-3 m/s "
    "legs ended, before the report fell",
    "held23_stop_slow_legs": "wind 3.7-4.3σ (6.1 m/s off) for 20 s after a 7 m/s wind stopped "
    "during 2 m/s legs: the autopilot's report held it too, and the power at 2 m/s barely "
    "shows it",
}


def _cases(misses: dict[str, str]) -> list[object]:
    return [
        pytest.param(f, marks=pytest.mark.xfail(strict=True, reason=misses[f]))
        if f in misses
        else f
        for f in FLIGHTS
    ]


def scored(flight: str) -> FlightScore:
    return SITL.held_checks()[flight].score


def test_every_held_out_flight_is_recorded_with_its_truth() -> None:
    assert SITL.recordings(SITL.HELD_RECORDINGS) == FLIGHTS
    assert all(len(HELD_SETS[name]) >= 12 for name in ("held", "held2", "held3"))
    assert all(len(held) >= 8 for held in HELD_SETS.values())
    kinds = [{e.kind for e in scored(f).truth.effects} for f in FLIGHTS]
    assert sum(not k for k in kinds) >= 4
    assert sum("wind" in k for k in kinds) >= 16
    assert sum("payload" in k for k in kinds) >= 8
    assert set(NOT_RIGHT) | set(ABOVE_FLOOR) | set(TRACKER_SHORT) <= set(FLIGHTS)


@pytest.mark.parametrize("flight", _cases(NOT_RIGHT))
def test_the_first_named_effect_is_a_true_one(flight: str) -> None:
    score = scored(flight)
    assert score.first_right, [(m.label, m.params, m.misses) for m in score.matches]


@pytest.mark.parametrize("flight", _cases(ABOVE_FLOOR))
def test_the_held_out_error_ends_within_two_and_a_half_noise_floors(flight: str) -> None:
    assert scored(flight).rmse_to_floor <= SITL.HELD_FLOOR_LIMIT


@pytest.fixture(scope="module")
def tracked() -> dict[str, tuple[RecordingTruth, TrackerRun]]:
    return {run.name: (truth, run) for truth, run in TRACKER.runs(SITL.HELD_RECORDINGS)}


@pytest.mark.parametrize("flight", _cases(TRACKER_SHORT))
def test_the_running_mass_and_wind_hold_90_percent_within_2_sigma_and_3_sigma_always(
    tracked: dict[str, tuple[RecordingTruth, TrackerRun]], flight: str
) -> None:
    assert TRACKER.meets_aim([tracked[flight][1]])


def test_the_docs_give_the_results_as_measured(
    tracked: dict[str, tuple[RecordingTruth, TrackerRun]],
) -> None:
    """docs/residuals.md's held-out blocks are what these flights give now (``make
    figures`` writes them)."""
    checks = SITL.held_checks()
    now = {
        "sitl-held-table": SITL.effects_table(checks, SITL.HELD_RECORDINGS),
        "sitl-held-summary": SITL.held_summary(checks),
        "sitl-held-floors": SITL.effects_floors(checks),
        "tracker-sitl-held": TRACKER.report(list(tracked.values())),
        "tracker-sitl-held-blind": TRACKER.blind(list(tracked.values())),
        "tracker-sitl-held-wind-worst": TRACKER.worst_wind(list(tracked.values())),
        "tracker-sitl-held-mass-step": TRACKER.mass_step(
            list(tracked.values()), FIGURES.trackers.TRACKER_MASS_STEP
        ),
        "tracker-sitl-held-unloaded": TRACKER.unloaded_mass(
            list(tracked.values()), FIGURES.trackers.TRACKER_UNLOADED_SET
        ),
    }
    # the misses' candidates: their generators read the same checks (SITL.held_checks)
    misses = (
        "sitl-held-windows",
        "sitl-held-autopilot-wind",
        "sitl-held-short-onset",
        "sitl-held-no-gain-held-gust-30s-hover",
        "sitl-held-no-gain-held3-gust-45s-legs",
        "sitl-held-no-gain-held-two-gusts",
    )
    now |= {name: FIGURES.GENERATORS[name]() for name in misses}
    assert set(now) == {n for n, test in FIGURES.CHECKED_BY.items() if test == THIS_FILE}
    blocks = [b for b in FIGURES.all_blocks() if b.name in now]
    assert {b.name for b in blocks} == set(now)
    stale = [b.name for b in blocks if b.text != now[b.name]]
    assert not stale, f"{stale}: run `make figures` and review the diff"


#: The clean held-out flights with vertical legs; docs/residuals.md gives their heave gains
#: (``residuals-sitl-held-heave``).
CLEAN_VERTICAL = FIGURES.vertical_figures.CLEAN_VERTICAL
#: Why a flight's vertical parameters are still apart from those of the pure vertical legs.
#: The first two: the filtered heave gain beyond 2σ on the sharpest vertical transients (GUIDED
#: at WPNAV_ACCEL_Z 500: up to 5 m/s² for about a second, against 1 m/s² on the axial
#: flights), which 2 Hz telemetry resolves least; the filter matches a linear term, and the
#: heave term is not linear at 5 m/s² (n^1.5). The third (held out for the filter): the climb
#: efficiency. SITL's vertical power is a drag law, not momentum theory (docs/residuals.md),
#: so the efficiency that fits it depends on the rates flown: a 54 m climb at 9 m/s weighs the
#: fast end, where the two differ most.
VERTICAL_APART = {
    "held_clean_vertical": "filtered gain 1.323 ± 0.037, 3.5σ above the axial flights'",
    "held2_clean_fast_vertical": "filtered gain 1.279 ± 0.039, 2.2σ above the axial flights'",
    "held15_clean_tall_fast": "climb efficiency 0.83 against the file's 1.0 (heave gain 0.3σ)",
}


@cache
def axial_heave() -> vertical_fit.GainFit:
    """The filtered heave gain of the pure vertical legs (``replay/sitl_axial``)."""
    vehicle = load_vehicle(SITL.SITL_VEHICLE)
    return vertical_fit.filtered_heave_gain(
        [vertical_fit.axial_samples(n) for n in vertical_fit.AXIAL_FLIGHTS], vehicle
    )


@pytest.mark.parametrize(
    "flight",
    [
        pytest.param(f, marks=pytest.mark.xfail(strict=True, reason=VERTICAL_APART[f]))
        if f in VERTICAL_APART
        else f
        for f in CLEAN_VERTICAL
    ],
)
def test_the_vertical_parameters_agree_with_a_fit_on_pure_vertical_legs(flight: str) -> None:
    """The issue's aim for the climb and descent parameters, on each clean held-out flight:
    the climb efficiency within 0.1 of the vehicle file's (fitted on the axial flights); the
    heave gain, the power through the accelerations' filter on both sides, within 2σ of the
    axial flights' (each fit's jackknife 1σ, combined). On the raw power the gain also takes up
    how much the filter flattens a flight's transients, so it is the file's only for flights
    that accelerate as gently as the axial ones (docs/residuals.md)."""
    vehicle = load_vehicle(SITL.SITL_VEHICLE)
    samples = prepare(load_flights([SITL.HELD_RECORDINGS / flight / "flight.tlog"], "tlog"))
    climb = vertical_fit.fitted_climb(samples, vehicle)
    file_climb = vertical_fit.file_effect(vehicle, "climb")
    assert isinstance(file_climb, Climb)
    assert climb.efficiency == pytest.approx(file_climb.efficiency, abs=0.1)
    heave = vertical_fit.filtered_heave_gain([samples], vehicle)
    z = FIGURES.vertical_figures.heave_z(heave, axial_heave())
    assert abs(z) <= FIGURES.vertical_figures.HEAVE_Z, f"{heave}, {z:+.2f}σ"
