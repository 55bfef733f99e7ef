"""The airspeed limit off the nose (:mod:`estimator.physics.lean_limit`): the per-axis drag law,
the vehicle file's ``[drag]`` table, and the planner's RTL leg against ArduCopter SITL's."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from tlog_builder import flight_frames, write_tlog

from estimator.analysis.mission_energy import mission_energy
from estimator.analysis.mission_validation import (
    check_recording,
    item_ground_speeds_mps,
    leg_checks,
    mission_item_starts,
    truth_conditions,
)
from estimator.errors import UserError
from estimator.logs.mission_files import load_mission
from estimator.physics.lean_limit import DragLaw, airspeed_reach_mps, along_track_limit_mps
from estimator.physics.vehicle import default_vehicle, load_vehicle, vehicle_from_toml

REPO = Path(__file__).resolve().parent.parent
SITL_VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
TALL = REPO / "replay/sitl/missions/tall_wind4"
#: The drag law of the SITL recordings (their truth.json's EK3_DRAG_* parameters).
SITL_DRAG = DragLaw(17.209, 17.209, 0.209)


def test_the_limit_is_the_straight_one_with_the_nose_on_the_track_in_still_air() -> None:
    for track in (0.0, 73.0, 250.0):
        assert along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 0.0), track, track) == pytest.approx(
            10.2, abs=1e-9
        )
    backwards = along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 0.0), 0.0, 180.0)
    assert backwards == pytest.approx(10.2, abs=1e-9)  # the law is symmetric


def test_off_the_nose_the_vehicle_flies_faster_and_a_crosswind_costs_headway() -> None:
    straight = along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 0.0), 0.0, 0.0)
    diagonal = along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 0.0), 0.0, 45.0)
    assert diagonal > 1.05 * straight  # the quadratic drag of 45° off the nose is 1/√2 of it
    crossed = along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 7.0), 0.0, 0.0)
    assert 8.0 < crossed < straight  # the drag across the nose uses some of the lean
    assert along_track_limit_mps(SITL_DRAG, 10.2, (0.0, 13.0), 0.0, 0.0) == -math.inf
    # a tailwind adds no airspeed limit of its own: the airspeed along the track is the same
    tail = along_track_limit_mps(SITL_DRAG, 10.2, (5.0, 0.0), 0.0, 0.0)
    assert tail == pytest.approx(straight, abs=1e-9)


def test_the_reach_in_any_direction_is_at_45_degrees_off_the_nose_for_equal_axes() -> None:
    """Quadratic drag alike on both axes: 45° off the nose meets 1/√2 of it, so the airspeed
    at the same lean is 2^¼ times the straight one; momentum drag (linear, round) takes some
    of that; without a drag law the reach is the straight limit."""
    quadratic = DragLaw(17.209, 17.209, 0.0)
    assert airspeed_reach_mps(quadratic, 10.2) == pytest.approx(10.2 * 2**0.25, rel=1e-4)
    reach = airspeed_reach_mps(SITL_DRAG, 10.2)
    assert 10.2 < reach < 10.2 * 2**0.25
    assert reach == pytest.approx(along_track_limit_mps(SITL_DRAG, 10.2, (0, 0), 0, 45), rel=1e-3)
    assert airspeed_reach_mps(None, 10.2) == 10.2


def test_a_payload_lets_the_same_lean_balance_more_drag() -> None:
    """Ballistic coefficients grow with the mass, momentum drag per kg falls with its root."""
    assert SITL_DRAG.at_mass_ratio(1.0) == SITL_DRAG
    heavy = SITL_DRAG.at_mass_ratio(4.0 / 3.0)
    assert heavy.deceleration_mps2(10.0, 0.0) < SITL_DRAG.deceleration_mps2(10.0, 0.0)
    light = along_track_limit_mps(SITL_DRAG, 10.2, (-4.0, 0.0), 0.0, 0.0)
    loaded = along_track_limit_mps(SITL_DRAG, 10.2, (-4.0, 0.0), 0.0, 0.0, 4.0 / 3.0)
    assert 10.8 < loaded < 11.8 and light == pytest.approx(10.2, abs=1e-9)


def test_the_vehicle_files_drag_table_is_checked_and_written_back() -> None:
    doc = default_vehicle().to_toml()
    law = {"bcoef_x_kgpm2": 20.0, "bcoef_y_kgpm2": 25.0, "mcoef_per_s": 0.2}
    vehicle = vehicle_from_toml({**doc, "drag": law})
    assert vehicle.drag == DragLaw(20.0, 25.0, 0.2)
    assert vehicle_from_toml(vehicle.to_toml()).drag == vehicle.drag
    assert load_vehicle(SITL_VEHICLE).drag == SITL_DRAG
    for bad, says in (
        ({"bcoef_x_kgpm2": 20.0}, "must hold exactly"),
        ({**law, "extra": 1.0}, "must hold exactly"),
        ({**law, "mcoef_per_s": 5.0}, "mcoef_per_s"),
        ({**law, "bcoef_y_kgpm2": "fast"}, "bcoef_y_kgpm2"),
        ("17", "drag"),
    ):
        with pytest.raises(UserError, match=says):
            vehicle_from_toml({**doc, "drag": bad})


def _steady_ground_speed_mps(tlog: Path, seq: int) -> float:
    """The median ground speed (m/s) of item ``seq``'s steady part: its readings above 90 % of
    their 95th percentile (the flight home, not the pause, the ramps or the landing)."""
    speeds = np.sort(item_ground_speeds_mps(tlog, seq))
    steady = speeds[speeds > 0.9 * speeds[int(0.95 * len(speeds))]]
    return float(steady[len(steady) // 2])


def test_the_planned_rtl_speed_off_the_nose_is_the_speed_sitl_flew() -> None:
    """tall_wind4's return flies 8.0 m/s over the ground with the nose 119° off its track
    (RTL keeps the last leg's heading); the along-track limit alone planned 6.9 m/s. A
    development figure: this flight is where the law was traced (docs/plan.md)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    legs = load_mission(TALL / "mission.plan").legs()
    told = truth_conditions(json.loads((TALL / "truth.json").read_text()))
    plan = mission_energy(legs, vehicle, told)
    planned = plan.legs[-1].energy.ground_speed_mps
    flown = _steady_ground_speed_mps(TALL / "flight.tlog", plan.legs[-1].leg.seq)
    assert planned == pytest.approx(flown, rel=0.03)


MISSIONS = REPO / "replay/sitl/missions"
#: Held-out missions (flown after the lean limit was frozen) whose energy misses by more than
#: 3 %, with the cause.
MISSES: dict[str, str] = {}


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(d.name, marks=pytest.mark.xfail(strict=True, reason=MISSES[d.name]))
        if d.name in MISSES
        else d.name
        for d in sorted(MISSIONS.iterdir())
        if (d / "truth.json").is_file()
    ],
)
def test_each_recorded_missions_energy_is_planned_within_3_percent(name: str) -> None:
    """Told the wind and payload SITL flew (docs/plan.md: the nine before the lean limit are
    development figures for it, the rtl_* missions held out)."""
    check = check_recording(MISSIONS / name, load_vehicle(SITL_VEHICLE))
    assert abs(check.error_pct) <= 3.0, round(check.error_pct, 2)


def test_the_legs_planned_and_flown_add_up_to_the_mission(tmp_path: Path) -> None:
    """Per-leg checks split the mission at each item's first MISSION_CURRENT: their planned
    energies sum to the plan's, their flown ones to the measured energy (the stretches meet
    at the item changes, so only the trapezoids across them differ)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    for name in ("tall_wind4", "outback_wind8", "lean2_payload_back4"):
        legs = leg_checks(MISSIONS / name, vehicle)
        whole = check_recording(MISSIONS / name, vehicle)
        assert sum(c.planned_wh for c in legs) == pytest.approx(whole.predicted_wh, rel=1e-9)
        assert sum(c.flown_wh for c in legs) == pytest.approx(whole.measured_wh, rel=0.005)
        assert legs[0].kind == "takeoff" and legs[-1].kind in ("rtl", "land")
    guided = write_tlog(tmp_path / "no_mission.tlog", flight_frames(10.0))
    with pytest.raises(UserError, match="no MISSION_CURRENT"):
        mission_item_starts(guided)
