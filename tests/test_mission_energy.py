"""Mission energy before flight: route energy (physics), mission files, the plan, ``uav-energy
plan``, and the prediction against the recorded ArduCopter SITL missions
(``replay/sitl/missions/``)."""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from estimator.analysis.mission_energy import FlightSettings, mission_energy
from estimator.analysis.mission_validation import check_recording
from estimator.errors import UserError
from estimator.logs.mission_files import M_PER_DEG, MissionLeg, load_mission
from estimator.physics.model import COEFFICIENT_NAMES, G_MPS2, PowerModel
from estimator.physics.route_energy import (
    UNCERTAINTY_SOURCES,
    Conditions,
    InfeasibleTrack,
    RouteVehicle,
    optimal_ground_speed_mps,
    optimal_speed,
    steady_power_w,
)
from estimator.physics.route_segments import (
    Kinematics,
    hover_energy,
    landing_energy,
    leg_energy,
    reachable_ground_speed_mps,
    sum_energies,
    vertical_energy,
)
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.sitl.launch import sitl_binary
from estimator.sitl.recorder import record
from estimator.sitl.scenarios import mission_scenario

REPO = Path(__file__).resolve().parent.parent
SITL_VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
MISSIONS = REPO / "replay/sitl/missions"
RECORDED = sorted(p for p in MISSIONS.iterdir() if (p / "truth.json").is_file())
#: Home of the test files (ArduPilot's SITL default location), deg and m above sea level.
HOME = (-35.363261, 149.165230, 584.0)


def _rv() -> RouteVehicle:
    return RouteVehicle.from_vehicle(default_vehicle())


# -- route energy ------------------------------------------------------------------------------


def test_still_air_optimum_is_the_models_max_range_speed() -> None:
    vehicle = load_vehicle(SITL_VEHICLE)
    rv = RouteVehicle.from_vehicle(vehicle)
    best = optimal_speed(rv, Conditions(), 37.0, max_ground_speed_mps=30, max_airspeed_mps=30)
    assert best.ground_speed_mps == pytest.approx(vehicle.model.max_range_speed_mps(), abs=0.01)
    assert best.airspeed_mps == pytest.approx(best.ground_speed_mps)


def test_the_speed_alone_is_the_optimal_speeds_ground_speed() -> None:
    rv = _rv()
    for wind, track_deg, along in (
        (Conditions(), 37.0, False),
        (Conditions(6.0, 200.0), 10.0, True),
    ):
        limits = {"max_ground_speed_mps": 18.0, "max_airspeed_mps": 14.0, "along_track": along}
        best = optimal_speed(rv, wind, track_deg, **limits)  # type: ignore[arg-type]
        alone = optimal_ground_speed_mps(rv, wind, track_deg, **limits)  # type: ignore[arg-type]
        assert alone == best.ground_speed_mps


def test_headwind_raises_the_optimal_airspeed_and_the_energy_per_metre() -> None:
    rv = _rv()
    calm = optimal_speed(rv, Conditions(), 0.0)
    head = optimal_speed(rv, Conditions(wind_speed_mps=6.0, wind_from_deg=0.0), 0.0)
    tail = optimal_speed(rv, Conditions(wind_speed_mps=6.0, wind_from_deg=180.0), 0.0)
    assert head.airspeed_mps > calm.airspeed_mps > tail.airspeed_mps
    assert head.energy_per_m_j > calm.energy_per_m_j > tail.energy_per_m_j
    assert head.ground_speed_mps == pytest.approx(head.airspeed_mps - 6.0, abs=1e-6)


def test_climb_costs_at_least_its_potential_energy_and_descent_less_than_hover() -> None:
    rv, c = _rv(), Conditions()
    climb = vertical_energy(rv, c, 30.0, 2.5)
    hover = hover_energy(rv, c, climb.time_s)
    potential_wh = default_vehicle().mass_kg * G_MPS2 * 30.0 / 3600.0
    assert climb.energy_wh >= potential_wh
    assert climb.energy_wh > hover.energy_wh
    assert vertical_energy(rv, c, -30.0, 2.5).energy_wh < hover.energy_wh


def test_payload_and_climb_add_energy_to_a_leg() -> None:
    rv = _rv()
    leg = {"distance_m": 500.0, "track_deg": 90.0, "ground_speed_mps": 10.0}
    base = leg_energy(rv, Conditions(), **leg)
    assert base.time_s == pytest.approx(50.0)
    assert leg_energy(rv, Conditions(payload_kg=0.5), **leg).energy_wh > base.energy_wh
    assert leg_energy(rv, Conditions(), climb_m=40.0, **leg).energy_wh > base.energy_wh


def test_sigma_comes_from_the_sources_and_adds_per_source_along_a_route() -> None:
    rv = _rv()
    exact = replace(rv, model_stderr=(0.0,) * 5)
    leg = {"distance_m": 300.0, "track_deg": 45.0, "ground_speed_mps": 8.0}
    assert leg_energy(exact, Conditions(wind_speed_mps=4), **leg).energy_sigma_wh == 0.0
    windy = Conditions(wind_speed_mps=4, wind_sigma_mps=1.0, payload_sigma_kg=0.2)
    one = leg_energy(exact, windy, **leg)
    assert one.energy_sigma_wh > 0
    both = sum_energies([one, one])
    assert both.energy_wh == pytest.approx(2 * one.energy_wh)
    assert both.energy_sigma_wh == pytest.approx(2 * one.energy_sigma_wh)  # correlated
    fitted = RouteVehicle.from_vehicle(load_vehicle(SITL_VEHICLE))
    model_only = leg_energy(fitted, Conditions(), **leg)
    assert model_only.energy_sigma_wh > 0


def test_energy_and_sensitivities_equal_the_steady_power_of_each_stepped_condition() -> None:
    """The wind and payload steps are predicted together with the nominal (one call over
    phases × conditions); each must equal the steady power under its own conditions."""
    fitted = RouteVehicle.from_vehicle(load_vehicle(SITL_VEHICLE))
    c = Conditions(wind_speed_mps=5.0, wind_from_deg=30.0, payload_kg=0.4, wind_sigma_mps=1.0,
                   payload_sigma_kg=0.1)  # fmt: skip
    leg = leg_energy(fitted, c, distance_m=400.0, track_deg=100.0, ground_speed_mps=9.0)

    def energy_wh(v: RouteVehicle, cond: Conditions) -> float:
        vn, ve = 9.0 * math.cos(math.radians(100.0)), 9.0 * math.sin(math.radians(100.0))
        return float(steady_power_w(v, cond, vn, ve)[0]) * leg.time_s / 3600.0

    assert leg.energy_wh == pytest.approx(energy_wh(fitted, c), rel=1e-12)
    wn, we = c.wind_ne_mps()

    def wind_ne(n: float, e: float) -> Conditions:
        from_deg = math.degrees(math.atan2(-e, -n)) % 360.0
        return replace(c, wind_speed_mps=math.hypot(n, e), wind_from_deg=from_deg)

    h = 0.05  # route_energy's central-difference step, in σ
    steps = {  # source: (conditions h σ up, h σ down)
        "wind_n": (wind_ne(wn + h, we), wind_ne(wn - h, we)),
        "wind_e": (wind_ne(wn, we + h), wind_ne(wn, we - h)),
        "payload": (replace(c, payload_kg=0.4 + h * 0.1), replace(c, payload_kg=0.4 - h * 0.1)),
    }
    sens = dict(zip(UNCERTAINTY_SOURCES, leg.sensitivity_wh, strict=True))
    for source, (up, down) in steps.items():
        expected = (energy_wh(fitted, up) - energy_wh(fitted, down)) / (2.0 * h)
        assert sens[source] == pytest.approx(expected, rel=1e-6)
    k = COEFFICIENT_NAMES.index("c3")
    bump = np.eye(5)[k] * h * fitted.model_stderr[k]
    up_c, down_c = (
        replace(fitted, model=PowerModel.from_array(fitted.model.as_array() + d))
        for d in (bump, -bump)
    )
    expected_c3 = (energy_wh(up_c, c) - energy_wh(down_c, c)) / (2.0 * h)
    assert sens["c3"] == pytest.approx(expected_c3, rel=1e-6)


def test_a_wind_beyond_the_airspeed_limit_is_infeasible_and_caps_the_ground_speed() -> None:
    rv, storm = _rv(), Conditions(wind_speed_mps=12.0, wind_from_deg=0.0)
    assert reachable_ground_speed_mps(storm, 0.0, 10.0) == 0.0
    with pytest.raises(InfeasibleTrack):
        leg_energy(rv, storm, distance_m=100, track_deg=0, ground_speed_mps=5, max_airspeed_mps=10)
    breeze = Conditions(wind_speed_mps=4.0, wind_from_deg=0.0)
    capped = leg_energy(
        rv, breeze, distance_m=100, track_deg=0, ground_speed_mps=15, max_airspeed_mps=10
    )
    assert capped.ground_speed_mps == pytest.approx(6.0)


def test_speed_changes_lengthen_a_leg_and_a_short_leg_never_reaches_cruise() -> None:
    rv, kin = _rv(), Kinematics(accel_mps2=2.5, jerk_mps3=1.0, vertical_accel_mps2=1.0)
    steady = leg_energy(rv, Conditions(), distance_m=150, track_deg=0, ground_speed_mps=10)
    ramped = leg_energy(
        rv, Conditions(), distance_m=150, track_deg=0, ground_speed_mps=10, kinematics=kin
    )
    # a jerk-limited stop-to-stop leg loses Δv/a + a/j = 6.5 s against cruising all the way
    assert ramped.time_s == pytest.approx(steady.time_s + 6.5, abs=0.01)
    short = leg_energy(
        rv, Conditions(), distance_m=10, track_deg=0, ground_speed_mps=10, kinematics=kin
    )
    # below a²/j = 6.25 m/s the ramps are jerk-only: 2 v^1.5 / sqrt(j) = 10 m, v = 2.92 m/s
    peak_mps = 5.0 ** (2 / 3)
    assert short.time_s == pytest.approx(2 * 2 * math.sqrt(peak_mps / 1.0), rel=1e-6)
    landing = landing_energy(rv, Conditions(), 30, 1.5, final_height_m=10, final_rate_mps=0.5)
    assert landing.time_s == pytest.approx(20 / 1.5 + 10 / 0.5)


# -- mission files --------------------------------------------------------------------------------


def _latlon(north_m: float, east_m: float) -> tuple[float, float]:
    lat = HOME[0] + north_m / M_PER_DEG
    return lat, HOME[1] + east_m / (M_PER_DEG * math.cos(math.radians(HOME[0])))


def _waypoints(path: Path, rows: list[str]) -> Path:
    home = f"0\t1\t0\t16\t0\t0\t0\t0\t{HOME[0]}\t{HOME[1]}\t{HOME[2]}\t1"
    path.write_text("\n".join(["QGC WPL 110", home, *rows]) + "\n")
    return path


def _row(seq: int, cmd: int, frame: int, north: float, east: float, alt: float, p1: float = 0):
    lat, lon = _latlon(north, east) if (north, east) != (0, 0) else (0.0, 0.0)
    return f"{seq}\t0\t{frame}\t{cmd}\t{p1}\t0\t0\t0\t{lat}\t{lon}\t{alt}\t1"


def _plan(path: Path, items: list[dict], home: list[float] | None = None) -> Path:
    mission = {"items": items, "plannedHomePosition": home or list(HOME)}
    path.write_text(json.dumps({"fileType": "Plan", "mission": mission}))
    return path


def _simple(command: int, frame: int, params: list) -> dict:
    return {"type": "SimpleItem", "command": command, "frame": frame, "params": params}


def test_waypoints_file_becomes_local_legs_with_frames_speeds_and_the_payload(
    tmp_path: Path,
) -> None:
    rows = [
        _row(1, 22, 3, 0, 0, 20),
        "2\t0\t2\t178\t1\t8\t-1\t0\t0\t0\t0\t1",  # DO_CHANGE_SPEED ground 8 m/s
        _row(3, 16, 3, 100, 0, 20, p1=5),  # hold 5 s
        _row(4, 16, 0, 100, 100, HOME[2] + 30),  # absolute: 30 m above home
        "5\t0\t2\t211\t1\t0\t0\t0\t0\t0\t0\t1",  # DO_GRIPPER release
        "6\t0\t2\t206\t0\t0\t0\t0\t0\t0\t0\t1",  # DO_SET_CAM_TRIGG_DIST: ignored
        _row(7, 19, 3, 0, 0, 0, p1=10),  # loiter 10 s where it is, at its height
        _row(8, 21, 3, 0, 0, 0),
    ]
    mission = load_mission(_waypoints(tmp_path / "m.waypoints", rows))
    legs = mission.legs()
    assert [leg.kind for leg in legs] == ["takeoff", "waypoint", "waypoint", "loiter_time", "land"]
    assert legs[0].end_ned_m == (0.0, 0.0, -20.0)
    assert legs[1].end_ned_m == pytest.approx((100, 0, -20), abs=0.01)
    assert legs[1].hold_s == 5 and legs[1].speed_mps == 8
    assert legs[2].end_ned_m == pytest.approx((100, 100, -30), abs=0.01)
    assert legs[3].end_ned_m == pytest.approx((100, 100, -30), abs=0.01)
    assert legs[2].payload and not legs[3].payload
    assert legs[4].end_ned_m == pytest.approx((100, 100, 0), abs=0.01)
    assert mission.ignored == (f"{tmp_path / 'm.waypoints'}: line 8: command 206",)


def test_plan_and_waypoints_of_the_same_mission_give_the_same_legs(tmp_path: Path) -> None:
    lat, lon = _latlon(200, -50)
    plan = _plan(
        tmp_path / "m.plan",
        [
            _simple(22, 3, [0, 0, 0, None, 0, 0, 25]),
            _simple(16, 3, [0, 0, 0, None, lat, lon, 25]),
            _simple(20, 2, [0, 0, 0, 0, 0, 0, 0]),
        ],
    )
    wpl = _waypoints(
        tmp_path / "m.waypoints",
        [_row(1, 22, 3, 0, 0, 25), _row(2, 16, 3, 200, -50, 25), _row(3, 20, 2, 0, 0, 0)],
    )
    a, b = load_mission(plan).legs(), load_mission(wpl).legs()
    assert [leg.kind for leg in a] == ["takeoff", "waypoint", "rtl"]
    for x, y in zip(a, b, strict=True):
        assert x.end_ned_m == pytest.approx(y.end_ned_m, abs=1e-6)


@pytest.mark.parametrize(
    ("name", "text", "says"),
    [
        ("a.plan", "{not json", "a.plan: not valid JSON: line 1"),
        ("b.plan", '{"mission": {"items": []}}', "plannedHomePosition"),
        ("c.txt", "hello", "not a mission file"),
        ("d.waypoints", "QGC WPL 120\n", "line 1: expected 'QGC WPL 110'"),
        ("e.waypoints", "QGC WPL 110\n0\t1\t0\t16\t0\n", "line 2: expected 12"),
        ("f.waypoints", "QGC WPL 110\n", "no items"),
    ],
)
def test_broken_files_are_one_line_errors_naming_file_and_place(
    tmp_path: Path, name: str, text: str, says: str
) -> None:
    (tmp_path / name).write_text(text)
    with pytest.raises(UserError) as err:
        load_mission(tmp_path / name)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_complex_items_terrain_frames_and_unknown_commands_are_refused(tmp_path: Path) -> None:
    survey = {"type": "ComplexItem", "complexItemType": "survey"}
    cases = [
        ([_simple(22, 3, [0, 0, 0, 0, 0, 0, 20]), survey], "item 2: ComplexItem 'survey'"),
        ([_simple(16, 10, [0, 0, 0, 0, *_latlon(10, 0), 20])], "terrain-relative"),
        ([_simple(17, 3, [0, 0, 0, 0, *_latlon(10, 0), 20])], "command 17 is not supported"),
        ([_simple(177, 2, [1, 3, 0, 0, 0, 0, 0])], "DO_JUMP loops are not supported"),
        ([_simple(16, 3, [0, 0, 0, 0, 95.0, 0, 20])], "is not on Earth"),
        ([_simple(16, 3, [0, 0, 0])], "7 values"),
    ]
    for items, says in cases:
        with pytest.raises(UserError) as err:
            load_mission(_plan(tmp_path / "x.plan", items))
        assert says in str(err.value), str(err.value)
    with pytest.raises(UserError, match="no navigation item"):
        load_mission(_plan(tmp_path / "y.plan", [])).legs()


# -- the plan --------------------------------------------------------------------------------------


def _leg(kind: str, start: tuple, end: tuple, payload: bool = True) -> MissionLeg:
    return MissionLeg(kind, 1, start, end, payload=payload)


def test_a_mission_ending_in_the_air_gets_a_return_and_payload_release_saves_energy() -> None:
    vehicle = default_vehicle()
    out = [_leg("takeoff", (0, 0, 0), (0, 0, -20)), _leg("waypoint", (0, 0, -20), (300, 0, -20))]
    plan = mission_energy(out, vehicle, Conditions(payload_kg=0.5))
    assert [r.name for r in plan.legs] == ["takeoff", "waypoint", "rtl (added)"]
    assert plan.total.distance_m == pytest.approx(600.0)
    dropped = [out[0], replace(out[1], payload=False)]
    lighter = mission_energy(dropped, vehicle, Conditions(payload_kg=0.5))
    assert lighter.legs[1].energy.energy_wh < plan.legs[1].energy.energy_wh
    assert lighter.legs[0].energy.energy_wh == pytest.approx(plan.legs[0].energy.energy_wh)
    assert plan.usable_wh > 0 and plan.feasible == (plan.margin_wh >= 0)
    distance, left, sigma = plan.profile()
    assert distance[-1] == pytest.approx(600.0) and left[-1] == pytest.approx(plan.margin_wh)
    assert sigma[-1] == pytest.approx(plan.total.energy_sigma_wh)


def test_corners_are_rounded_between_waypoints_and_reversals_stop() -> None:
    s = FlightSettings()
    assert s.corner_mps(90.0) == pytest.approx(s.corner_speed_mps)
    assert s.corner_mps(30.0) > s.corner_mps(90.0) > s.corner_mps(150.0) > s.corner_mps(180.0)
    assert s.corner_mps(180.0) == pytest.approx(0.0, abs=1e-6)


# -- recorded SITL missions ----------------------------------------------------------------------


def test_predicted_mission_energy_is_within_5_percent_of_sitl_in_the_median() -> None:
    vehicle = load_vehicle(SITL_VEHICLE)
    checks = [check_recording(d, vehicle) for d in RECORDED]
    assert len(checks) >= 5
    errors = [abs(c.error_pct) for c in checks]
    px4 = [abs(c.px4_error_pct) for c in checks]
    assert statistics.median(errors) <= 5.0, [(c.name, round(c.error_pct, 1)) for c in checks]
    assert statistics.median(errors) < statistics.median(px4)
    effects = [json.loads((d / "truth.json").read_text())["effects"] for d in RECORDED]
    winds = {e["from_deg"] for fx in effects for e in fx if e["effect"] == "wind"}
    assert len(winds) >= 5  # different wind directions
    assert any(e["effect"] == "payload" for fx in effects for e in fx)


def test_recorded_missions_stay_small() -> None:
    for directory in RECORDED:
        assert sum(f.stat().st_size for f in directory.iterdir()) <= 1.6 * 2**20


@pytest.mark.needs(sitl_binary() is not None, "no ArduCopter SITL binary")
def test_a_live_sitl_mission_from_a_plan_file_uses_the_predicted_energy(tmp_path: Path) -> None:
    """A .plan uploaded with MISSION_ITEM_INT and flown in AUTO (take-off, a 45° corner, LAND)
    in a 4 m/s wind: the battery energy from mission start to disarm is the plan's within 8 %."""
    lat1, lon1 = _latlon(80, 0)
    lat2, lon2 = _latlon(140, 60)
    plan = _plan(
        tmp_path / "live.plan",
        [
            _simple(22, 3, [0, 0, 0, None, 0, 0, 10]),
            _simple(16, 3, [0, 0, 0, None, lat1, lon1, 10]),
            _simple(16, 3, [0, 0, 0, None, lat2, lon2, 10]),
            _simple(21, 3, [0, 0, 0, None, lat2, lon2, 0]),
        ],
    )
    speedup = float(os.environ.get("ARDUPILOT_SITL_SPEEDUP", "10"))
    record(mission_scenario(str(plan), wind=(4.0, 200.0)), tmp_path / "live", speedup)
    assert (tmp_path / "live" / "mission.plan").read_text() == plan.read_text()
    check = check_recording(tmp_path / "live", load_vehicle(SITL_VEHICLE))
    assert abs(check.error_pct) <= 8.0, check


# -- the command -----------------------------------------------------------------------------------


def _plan_cli(*argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "160"}
    return subprocess.run(
        [sys.executable, "-m", "estimator.cli", "plan", *argv],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
    )


def test_plan_prints_the_leg_table_totals_feasibility_and_the_px4_style_estimate() -> None:
    mission = MISSIONS / "square_wind5" / "mission.waypoints"
    out = _plan_cli(str(mission), "--vehicle", str(SITL_VEHICLE), "--wind", "5@300")
    assert out.returncode == 0, out.stderr
    for word in ("takeoff", "waypoint", "rtl", "total", "feasible", "PX4-style", "± "):
        assert word in out.stdout


def test_plan_json_has_legs_totals_and_feasibility(tmp_path: Path) -> None:
    mission = MISSIONS / "climbs_wind6" / "mission.plan"
    out = _plan_cli(
        str(mission), "--vehicle", str(SITL_VEHICLE), "--wind", "6@135", "--payload", "0.5",
        "--json", "--report", str(tmp_path / "rep"),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    assert set(doc) >= {"mission", "vehicle", "conditions", "legs", "total", "usable_wh"}
    assert set(doc) >= {"margin_wh", "feasible", "px4_style"}
    assert doc["conditions"]["payload_kg"] == 0.5
    assert [leg["kind"] for leg in doc["legs"]] == [
        "takeoff", "waypoint", "waypoint", "loiter_turns", "rtl",
    ]  # fmt: skip
    total = sum(leg["energy_wh"] for leg in doc["legs"])
    assert doc["total"]["energy_wh"] == pytest.approx(total, abs=0.01)
    assert doc["legs"][1]["recommended_ground_speed_mps"] > 0
    assert doc["feasible"] == (doc["margin_wh"] >= 0)
    for name in ("route.png", "energy.png", "summary.md"):
        assert (tmp_path / "rep" / name).stat().st_size > 500


def test_plan_answers_a_bad_mission_file_with_exit_2_and_one_line(tmp_path: Path) -> None:
    bad = _plan(tmp_path / "bad.plan", [{"type": "ComplexItem", "complexItemType": "survey"}])
    out = _plan_cli(str(bad), "--vehicle", str(SITL_VEHICLE))
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "ComplexItem 'survey'" in out.stderr
    out = _plan_cli(str(bad), "--vehicle", str(SITL_VEHICLE), "--wind", "fast")
    assert out.returncode == 2 and out.stderr.count("\n") == 1
