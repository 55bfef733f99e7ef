"""Whose RTL the return figures follow: PX4's (v1.16 defaults) against ArduCopter's, the
landing's blended rate, the configuration key, and the mission's log line."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator.errors import UserError
from estimator.estimation.return_home import ReturnHome, ReturnSettings
from estimator.estimation.rtl_profiles import (
    PX4_FLOWN_ACCEL_MPS2,
    PX4_TOUCHDOWN_S,
    px4_rtl,
    rtl_settings,
)
from estimator.logs.mission_files import MissionItem
from estimator.mavlink.config import ServiceConfig, build_config
from estimator.mavlink.mission_download import item_text
from estimator.physics.route_energy import Conditions, RouteVehicle
from estimator.physics.route_segments import landing_energy
from estimator.physics.vehicle import default_vehicle


def route_time_s(settings: ReturnSettings, distance_m: float, alt_m: float) -> float:
    """The return's time (s) from ``distance_m`` out at ``alt_m`` over home, at rest."""
    energy, _ = ReturnHome(default_vehicle(), settings).route(distance_m, 0.0, alt_m, Conditions())
    return energy.time_s


def test_the_blended_landing_rate_takes_the_closed_form_time() -> None:
    """PX4's landing slows linearly with height from 1.5 m/s at 10 m to 0.7 m/s at 5 m: that
    stretch takes 5/0.8 · ln(1.5/0.7) s, then 5 m at 0.7 m/s."""
    rv = RouteVehicle.from_vehicle(default_vehicle())
    landing = landing_energy(
        rv, Conditions(), 10.0, 1.5, final_height_m=5.0, final_rate_mps=0.7, blend_height_m=10.0
    )
    assert landing.time_s == pytest.approx(5.0 / 0.8 * math.log(1.5 / 0.7) + 5.0 / 0.7)
    stepped = landing_energy(rv, Conditions(), 10.0, 1.5, final_height_m=5.0, final_rate_mps=0.7)
    assert stepped.time_s == pytest.approx(5.0 / 1.5 + 5.0 / 0.7)
    assert landing.energy_wh > stepped.energy_wh  # longer, at about hover power


def test_px4_rtl_flies_its_cruise_speed_and_lands_from_its_return_height() -> None:
    """Under PX4's RTL: 100 m more take 100 m / MPC_XY_CRUISE (5 m/s); 10 m above
    RTL_RETURN_ALT (30 m) take 10 m / MPC_Z_V_AUTO_DN (1.5 m/s) more; below it the climb is
    at MPC_Z_V_AUTO_UP (3 m/s). From 200 m out at 30 m the return is the leg (200 m at 5 m/s
    plus one ramp of 5/a + a/4 s: PX4's ramp as flown, a, and MPC_JERK_AUTO) and the landing:
    20 m at 1.5 m/s after a start of 2·sqrt(1.5/4) s (MPC_JERK_AUTO bounds it), the blend from
    10 m to 5 m, 5 m at 0.7 m/s (no crawl without a distance sensor) and the touchdown to
    ON_GROUND as flown."""
    px4 = px4_rtl(ReturnSettings())
    at_30_s = route_time_s(px4, 200.0, 30.0)
    assert route_time_s(px4, 300.0, 30.0) - at_30_s == pytest.approx(100.0 / 5.0)
    assert route_time_s(px4, 200.0, 40.0) - at_30_s == pytest.approx(10.0 / 1.5)
    assert route_time_s(px4, 200.0, 0.0) - route_time_s(px4, 200.0, 15.0) == pytest.approx(
        15.0 / 3.0
    )
    a = PX4_FLOWN_ACCEL_MPS2
    leg_s = 200.0 / 5.0 + 5.0 / a + a / 4.0
    start_s = 2.0 * math.sqrt(1.5 / 4.0)
    landing_s = start_s + (20.0 - 1.5 * start_s / 2) / 1.5 + 5.0 / 0.8 * math.log(1.5 / 0.7)
    landing_s += 5.0 / 0.7 + PX4_TOUCHDOWN_S
    assert at_30_s == pytest.approx(leg_s + landing_s, abs=0.01)


def test_ardupilot_settings_are_kept_and_px4_keeps_a_set_speed_and_the_wind() -> None:
    given = ReturnSettings(return_speed_mps=7.0, wind_source="autopilot")
    assert rtl_settings("ardupilot", given) is given
    px4 = rtl_settings("px4", given)
    assert (px4.return_speed_mps, px4.wind_source, px4.return_alt_m) == (7.0, "autopilot", 30.0)
    assert rtl_settings("px4", ReturnSettings()).return_speed_mps == 5.0
    with pytest.raises(ValueError, match="no RTL model"):
        rtl_settings("inav", given)


def test_the_config_key_takes_auto_ardupilot_or_px4_and_refuses_the_rest() -> None:
    assert ServiceConfig().return_autopilot == "auto"
    assert build_config({"return_autopilot": "px4"}, {}).return_autopilot == "px4"
    with pytest.raises(UserError, match="'return_autopilot' must be 'auto', 'ardupilot' or"):
        build_config({"return_autopilot": "PX4 please"}, {})


def test_the_mission_log_line_spells_each_item() -> None:
    nan = math.nan
    waypoint = MissionItem(1, 16, 6, (0.0,) * 4, 47.3982, 8.5461, 15.0, "item 1")
    rtl = MissionItem(2, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 2, (0.0,) * 4, nan, nan, 0.0, "")
    assert item_text(waypoint) == "16/6 47.3982000,8.5461000 15.00m"
    assert item_text(rtl) == "20/2 nan,nan 0.00m"


def test_the_daemon_follows_the_configured_rtl_from_the_start() -> None:
    from estimator.mavlink.service import Service

    px4 = Service(ServiceConfig(return_autopilot="px4"), default_vehicle())
    assert px4.pipeline.returning.settings == px4_rtl(ReturnSettings())
    auto = Service(ServiceConfig(), default_vehicle())  # ArduCopter's until a PX4 HEARTBEAT
    assert auto.pipeline.returning.settings == ReturnSettings()
