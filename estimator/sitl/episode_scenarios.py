"""The development flights of wind episodes of ``replay/sitl_episodes`` (``uav-energy
sitl-record episodes``): flown to tune the residual analysis's window search on, after the
first held-out set (:mod:`estimator.sitl.held_scenarios`) had shown the miss. Steps as in
:mod:`estimator.sitl.scenarios` (velocities NED m/s; durations s; winds m/s from degrees).
"""

from __future__ import annotations

from estimator.sitl.held_scenarios import vertical_scenario
from estimator.sitl.scenarios import CIRCLES, LEGS, Grip, Hover, Scenario, SetWind, Takeoff, by_name

# fmt: off
#: Development flights (tuned on): wind episodes of 66-90 s inside longer flights.
EPISODE_SCENARIOS: dict[str, Scenario] = by_name(
    vertical_scenario(
        "episode_legs_78s",
        "wind 7 m/s from 120° for about 78 s of legs",
        Takeoff(), *LEGS[:4], SetWind(7, 120), *LEGS[1:6], SetWind(0), *LEGS[6:],
    ),
    vertical_scenario(
        "episode_circles_70s",
        "wind 6 m/s from 200° for about 70 s of circles",
        Takeoff(), *CIRCLES[:3], SetWind(6, 200), *CIRCLES[3:6], SetWind(0), *CIRCLES[6:],
        *LEGS[1:4],
    ),
    vertical_scenario(
        "episode_legs_66s",
        "wind 8 m/s from 030° for about 66 s of legs",
        Takeoff(), *LEGS[:6], SetWind(8, 30), *LEGS[6:9], SetWind(0), *LEGS[1:6], Hover(10),
    ),
    vertical_scenario(
        "episode_payload_90s",
        "1 kg gripper payload from take-off; wind 5 m/s from 250° for about 90 s of legs",
        Grip(True), Hover(3), Takeoff(), Hover(30), *LEGS[1:4], SetWind(5, 250), *LEGS[4:10],
        SetWind(0), *LEGS[10:], *LEGS[1:4],
    ),
)
# fmt: on
