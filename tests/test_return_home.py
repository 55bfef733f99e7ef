"""The return-home figures (estimation layer): flags for missing inputs, the wind's sign, the
speed limits, the autopilot's speed ramps, σ and the point of no return."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from estimator.estimation.return_home import (
    FLAG_MISSION_UNUSABLE,
    FLAG_NO_HOME,
    FLAG_NO_MISSION,
    FLAG_NO_POSITION,
    FLAG_NOT_FLYING,
    MissionSample,
    ReturnHome,
    ReturnInputs,
    ReturnSettings,
    distance_bearing,
)
from estimator.estimation.rtl_profiles import px4_rtl
from estimator.logs.mission_files import MissionItem
from estimator.physics.effects import Mass, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.telemetry.samples import (
    HomeSample,
    MissionCurrentSample,
    PositionSample,
    WindSample,
)

HOME = HomeSample(0.0, 47.0, 8.0, 400.0)
M_PER_DEG = 111_195.0  # mean Earth radius


def inputs(**changes: object) -> ReturnInputs:
    base = ReturnInputs(
        time_s=10.0,
        velocity_ne_mps=(0.0, 0.0),
        effects=(),
        wind_sigma_ne_mps=(0.5, 0.5),
        mass_sigma_kg=0.05,
        bias=1.0,
        bias_sigma=0.02,
        energy_wh=100.0,
        energy_sigma_wh=2.0,
        loss_factor=1.05,
        steady_power_w=400.0,
        flying=True,
    )
    return replace(base, **changes)  # type: ignore[arg-type]


def at(north_m: float, east_m: float = 0.0, alt_m: float = 20.0) -> PositionSample:
    lat = HOME.lat_deg + north_m / M_PER_DEG
    lon = HOME.lon_deg + east_m / (M_PER_DEG * math.cos(math.radians(HOME.lat_deg)))
    return PositionSample(0.0, lat, lon, alt_m)


def returning(position: PositionSample | None, settings: ReturnSettings | None = None):  # type: ignore[no-untyped-def]
    r = ReturnHome(default_vehicle(), settings)
    if position is not None:
        r.take(position)
    r.take(HOME)
    return r


def test_distance_and_bearing_on_the_sphere() -> None:
    d, b = distance_bearing(47.0, 8.0, 47.0 + 1000.0 / M_PER_DEG, 8.0)
    assert d == pytest.approx(1000.0, rel=1e-3) and b == pytest.approx(0.0, abs=1e-9)
    d, b = distance_bearing(47.0, 8.0, 47.0, 7.99)
    assert math.degrees(b) == pytest.approx(-90.0, abs=0.01)


def test_missing_home_or_position_gives_nan_figures_with_flags_not_an_exception() -> None:
    no_home = ReturnHome(default_vehicle())
    no_home.take(at(500.0))
    figures = no_home.figures(10.0, inputs())
    assert math.isnan(figures.energy_wh) and math.isnan(figures.margin_wh)
    assert figures.flags == FLAG_NO_HOME | FLAG_NO_MISSION
    no_position = returning(None).figures(10.0, inputs(flying=False))
    assert math.isnan(no_position.energy_wh)
    assert no_position.flags == FLAG_NO_POSITION | FLAG_NO_MISSION | FLAG_NOT_FLYING


def test_return_energy_grows_with_distance_and_the_margin_is_what_is_left() -> None:
    near = returning(at(200.0)).figures(10.0, inputs())
    far = returning(at(2000.0)).figures(10.0, inputs())
    assert 0 < near.energy_wh < far.energy_wh
    assert far.home_distance_m == pytest.approx(2000.0, rel=1e-3)
    assert far.margin_wh == pytest.approx(100.0 - far.energy_wh * 1.05)
    assert far.margin_sigma_wh > 2.0 and far.flags == FLAG_NO_MISSION


def test_a_head_wind_home_costs_more_than_a_tail_wind() -> None:
    north_wind = (Wind(speed_mps=6.0, from_deg=0.0),)  # blows towards the south
    # north of home, the way home is south: a tail wind; south of home: a head wind
    tail = returning(at(1000.0)).figures(10.0, inputs(effects=north_wind))
    head = returning(at(-1000.0)).figures(10.0, inputs(effects=north_wind))
    assert head.energy_wh > 1.2 * tail.energy_wh
    assert head.speed_mps < tail.speed_mps
    assert tail.wind_mps == 6.0 and tail.wind_from_deg == 0.0


def test_the_wind_optimal_speed_stays_within_the_airspeed_limit() -> None:
    settings = ReturnSettings(max_airspeed_mps=8.0)
    north_wind = (Wind(speed_mps=5.0, from_deg=0.0),)
    head = returning(at(-1000.0), settings).figures(10.0, inputs(effects=north_wind))
    assert head.speed_mps <= 3.0 + 1e-6  # 8 m/s through the air into 5 m/s
    fixed = returning(at(-1000.0), ReturnSettings(return_speed_mps=4.0)).figures(
        10.0, inputs(effects=north_wind)
    )
    assert fixed.speed_mps == 4.0


def test_wind_and_bias_uncertainty_widen_the_sigma() -> None:
    r = returning(at(1500.0))
    narrow = r.figures(10.0, inputs(wind_sigma_ne_mps=(0.1, 0.1), bias_sigma=0.0))
    wide = returning(at(1500.0)).figures(10.0, inputs(wind_sigma_ne_mps=(2.0, 2.0)))
    assert 0 < narrow.sigma_wh < wide.sigma_wh


def test_the_autopilot_wind_is_used_when_asked_and_fresh() -> None:
    settings = ReturnSettings(wind_source="autopilot", autopilot_wind_max_age_s=5.0)
    r = returning(at(-1000.0), settings)
    still = r.figures(10.0, inputs())
    r.take(WindSample(8.0, -6.0, 0.0))  # blowing south: a head wind home
    fresh = r.figures(10.0, inputs())
    assert fresh.wind_mps == pytest.approx(6.0) and fresh.wind_from_deg == pytest.approx(0.0)
    assert fresh.energy_wh > still.energy_wh
    stale = r.figures(20.0, inputs(time_s=20.0))
    assert stale.wind_mps == 0.0


def test_stopping_a_flight_away_from_home_adds_its_time_and_distance() -> None:
    resting = returning(at(500.0)).figures(10.0, inputs())
    fleeing = returning(at(500.0)).figures(10.0, inputs(velocity_ne_mps=(10.0, 0.0)))
    stop_s = 10.0 / 2.5 + 2.5 / 1.0  # WPNAV_ACCEL, WPNAV_JERK
    extra_s = stop_s + 10.0 * stop_s / 2 / resting.speed_mps
    assert fleeing.time_s == pytest.approx(resting.time_s + extra_s, rel=0.02)
    assert fleeing.energy_wh > resting.energy_wh
    towards = returning(at(500.0)).figures(10.0, inputs(velocity_ne_mps=(-10.0, 0.0)))
    assert towards.time_s == pytest.approx(resting.time_s + stop_s, rel=0.02)


def test_kept_segments_and_powers_give_the_figures_of_a_fresh_return_bit_for_bit() -> None:
    """One return asked along a flight (its hover, vertical and landing segments kept per
    conditions and settings, a new wind's powers predicted with the states asked before)
    gives exactly what a fresh return computes at each step: heights below and above the
    return height, a wind and payload that move and come back, a stop, other settings."""
    wind = (Wind(speed_mps=4.0, from_deg=30.0),)
    steps = [
        (at(400.0, alt_m=10.0), inputs()),
        (at(400.0, alt_m=10.0), inputs()),  # all kept
        (at(380.0, alt_m=10.5), inputs(velocity_ne_mps=(-3.0, 1.0))),
        (at(380.0, alt_m=25.0), inputs(effects=wind)),
        (at(360.0, alt_m=25.0), inputs(effects=wind, mass_sigma_kg=0.2)),
        (at(360.0, alt_m=25.25), inputs(effects=wind, wind_sigma_ne_mps=(0.9, 0.5))),
        (at(340.0, alt_m=30.0), inputs(effects=(*wind, Mass(delta_kg=0.4)))),
        (at(340.0, alt_m=10.0), inputs()),  # back to the first conditions
    ]
    kept = ReturnHome(default_vehicle())
    slower = ReturnSettings(land_speed_mps=0.7, touchdown_s=1.0)  # only the landing differs
    for settings in (ReturnSettings(), slower, px4_rtl(ReturnSettings())):
        kept.settings = settings
        for position, given in steps:
            fresh = returning(position, settings).figures(10.0, given)
            kept.take(position)
            kept.take(HOME)
            figures = kept.figures(10.0, given)
            assert (figures.energy_wh, figures.sigma_wh, figures.time_s, figures.speed_mps) == (
                fresh.energy_wh,
                fresh.sigma_wh,
                fresh.time_s,
                fresh.speed_mps,
            )


def test_point_of_no_return_from_the_drain_and_the_growth_of_the_return() -> None:
    r = returning(at(1000.0))
    first = r.figures(10.0, inputs())
    assert first.pnr_s == pytest.approx(first.margin_wh / (400.0 / 3600.0 * 1.05), rel=1e-6)
    r.take(at(1100.0))  # flying away: the return grows, the point of no return comes sooner
    away = r.figures(20.0, inputs(time_s=20.0))
    assert away.pnr_s < away.margin_wh / (400.0 / 3600.0 * 1.05)
    gone = r.figures(21.0, inputs(time_s=21.0, energy_wh=1.0))
    assert gone.margin_wh < 0 and gone.pnr_s == 0.0
    grounded = returning(at(1000.0)).figures(10.0, inputs(flying=False))
    assert math.isnan(grounded.pnr_s) and grounded.flags & FLAG_NOT_FLYING


def _mission(*north_m: float) -> MissionSample:
    """ArduPilot-style: item 0 home, take-off to 20 m, waypoints north of home, RTL."""
    items = [MissionItem(0, 16, 0, (0.0,) * 4, HOME.lat_deg, HOME.lon_deg, 400.0, "item 0")]
    items.append(MissionItem(1, 22, 3, (0.0,) * 4, 0.0, 0.0, 20.0, "item 1"))
    for i, n in enumerate(north_m, start=2):
        p = at(n)
        items.append(MissionItem(i, 16, 3, (0.0,) * 4, p.lat_deg, p.lon_deg, 20.0, f"item {i}"))
    items.append(MissionItem(len(items), 20, 3, (0.0,) * 4, 0.0, 0.0, 0.0, "rtl"))
    return MissionSample(0.0, tuple(items))


def test_remaining_mission_energy_falls_as_the_mission_goes_on_and_includes_the_return() -> None:
    from estimator.analysis.mission_energy import mission_energy

    vehicle = default_vehicle()
    r = ReturnHome(vehicle, mission_energy=lambda legs, c: mission_energy(legs, vehicle, c).total)
    r.take(HOME)
    r.take(at(0.0))
    r.take(_mission(500.0, 1000.0, 1500.0))
    r.take(MissionCurrentSample(0.0, 2))
    start = r.figures(10.0, inputs())
    r.take(at(1000.0))
    r.take(MissionCurrentSample(20.0, 4))
    later = r.figures(20.0, inputs(time_s=20.0))
    assert start.mission_energy_wh > later.mission_energy_wh > later.energy_wh
    assert start.mission_sigma_wh > 0 and start.mission_feasible is True
    assert not start.flags & FLAG_NO_MISSION
    poor = r.figures(30.0, inputs(time_s=30.0, energy_wh=1.0))
    assert poor.mission_feasible is False


def test_a_mission_without_navigation_items_is_flagged_not_raised() -> None:
    from estimator.analysis.mission_energy import mission_energy

    vehicle = default_vehicle()
    r = ReturnHome(vehicle, mission_energy=lambda legs, c: mission_energy(legs, vehicle, c).total)
    r.take(HOME)
    r.take(at(300.0))
    only_home = MissionItem(0, 16, 0, (0.0,) * 4, HOME.lat_deg, HOME.lon_deg, 400.0, "item 0")
    r.take(MissionSample(0.0, (only_home, replace(only_home, seq=1, command=178))))
    figures = r.figures(10.0, inputs())
    assert figures.flags & FLAG_MISSION_UNUSABLE and math.isnan(figures.mission_energy_wh)
    assert figures.mission_feasible is None and figures.energy_wh > 0
