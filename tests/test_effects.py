"""Physics of each power effect, their composition, and their vehicle-file serialisation."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from estimator.errors import UserError
from estimator.physics.effect_tables import (
    effect_from_params,
    effects_from_tables,
    effects_to_tables,
)
from estimator.physics.effects import (
    EFFECT_TYPES,
    Acceleration,
    AirDensity,
    Avionics,
    Climb,
    FlightState,
    Heave,
    Mass,
    ReportedWind,
    Turn,
    Voltage,
    Wind,
    predict_power_w,
)
from estimator.physics.model import G_MPS2, SEA_LEVEL_DENSITY_KGPM3
from estimator.physics.vehicle import default_vehicle, load_vehicle

VEHICLE = default_vehicle()
MODEL, MASS_KG = VEHICLE.model, VEHICLE.mass_kg


def state(
    vn: float | list[float] = 0.0,
    ve: float | list[float] = 0.0,
    vd: float | list[float] = 0.0,
    an: float | list[float] = 0.0,
    ae: float | list[float] = 0.0,
    voltage: float | list[float] = 24.0,
    n: int = 1,
) -> FlightState:
    cols = [np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in (vn, ve, vd, an, ae)]
    t = np.arange(n, dtype=float)
    v = np.broadcast_to(np.asarray(voltage, dtype=float), (n,))
    return FlightState(t, cols[0], cols[1], cols[2], cols[3], cols[4], np.full(n, 20.0), v)


def power(st: FlightState, *effects: object) -> np.ndarray:
    return predict_power_w(MODEL, MASS_KG, st, list(effects))  # type: ignore[arg-type]


def test_no_effects_is_eq1_in_steady_level_flight() -> None:
    speeds = np.array([0.0, 3.0, 8.0, 14.0])
    st = state(vn=list(speeds), n=4)
    assert power(st) == pytest.approx(MODEL.power_w(speeds))


def test_kinetic_term_adds_m_v_dot_a() -> None:
    st = state(vn=10.0, an=0.5)
    assert power(st)[0] == pytest.approx(float(MODEL.power_w(10.0)) + MASS_KG * 10.0 * 0.5)


def test_turn_uses_centripetal_acceleration_in_the_load_factor() -> None:
    st = state(vn=8.0, ae=3.0)  # a ⊥ v
    expected = MODEL.power_w(8.0, 3.0 * 8.0 / math.sqrt(64.0 + 0.25))  # kinematics floor
    assert power(st)[0] == pytest.approx(float(expected))


def test_wind_from_north_makes_power_depend_on_heading() -> None:
    wind = Wind(speed_mps=5.0, from_deg=0.0)
    headings = {"north": (8.0, 0.0), "south": (-8.0, 0.0), "east": (0.0, 8.0)}
    got = {name: float(power(state(vn=vn, ve=ve), wind)[0]) for name, (vn, ve) in headings.items()}
    # flying into a north wind is a 13 m/s airspeed, with it 3 m/s, across it sqrt(8²+5²)
    assert got["north"] == pytest.approx(float(MODEL.power_w(13.0)))
    assert got["south"] == pytest.approx(float(MODEL.power_w(3.0)))
    assert got["east"] == pytest.approx(float(MODEL.power_w(math.hypot(8.0, 5.0))))
    assert got["north"] > max(got["east"], got["south"])  # 13 m/s is past the minimum


def test_wind_from_deg_is_where_it_blows_from() -> None:
    wn, we = Wind(speed_mps=4.0, from_deg=90.0).vector_ne_mps()
    assert (wn, we) == pytest.approx((0.0, -4.0))  # an east wind blows towards the west


def test_hovering_in_wind_sees_the_wind_as_airspeed() -> None:
    assert power(state(), Wind(6.0, 200.0))[0] == pytest.approx(float(MODEL.power_w(6.0)))


def test_mass_rescales_hover_induced_power_by_w_to_the_three_halves() -> None:
    ratio = (MASS_KG + 1.0) / MASS_KG
    got = power(state(), Mass(delta_kg=1.0))[0]
    assert got == pytest.approx(MODEL.c1 + MODEL.c3 * ratio**1.5)


def test_mass_step_applies_from_at_s_on() -> None:
    st = state(vn=6.0, n=10)  # times 0..9 s
    got = power(st, Mass(delta_kg=0.5, at_s=4.0))
    base = float(MODEL.power_w(6.0))
    heavier = float(MODEL.rescaled((MASS_KG + 0.5) / MASS_KG).power_w(6.0))
    assert got[:4] == pytest.approx([base] * 4)
    assert got[4:] == pytest.approx([heavier] * 6)


def test_mass_changes_kinetic_term_with_actual_mass() -> None:
    st = state(vn=10.0, an=1.0)
    heavy = MODEL.rescaled((MASS_KG + 2.0) / MASS_KG)
    expected = float(heavy.power_w(10.0)) + (MASS_KG + 2.0) * 10.0
    assert power(st, Mass(delta_kg=2.0))[0] == pytest.approx(expected)


def test_thin_air_raises_hover_power_and_lowers_profile_power() -> None:
    rho = 1.0
    r = rho / SEA_LEVEL_DENSITY_KGPM3
    got = power(state(), AirDensity(rho_kgpm3=rho))[0]
    assert got == pytest.approx(MODEL.c1 * r + MODEL.c3 / math.sqrt(r))
    assert got > MODEL.hover_power_w


def test_climb_follows_momentum_theory() -> None:
    eff = 0.6
    v0 = math.sqrt(MODEL.c4 / 2.0)
    climbs = np.array([0.0, 0.2, 2.0, 30.0])
    got = power(state(vd=list(-climbs), n=4), Climb(efficiency=eff)) - MODEL.hover_power_w
    weight = MASS_KG * G_MPS2
    exact = weight * (climbs / 2 + np.sqrt(climbs**2 / 4 + v0**2) - v0) / eff
    assert got == pytest.approx(exact)
    assert got[0] == pytest.approx(0.0)
    assert got[1] == pytest.approx(weight * 0.2 / 2 / eff, rel=0.02)  # slow: m g v_c / 2η
    assert got[3] == pytest.approx(weight * (30.0 - v0) / eff, rel=0.05)  # fast: m g (v_c − v0)/η


def test_climb_power_rises_with_climb_rate_and_descent_needs_less_than_hover() -> None:
    eff = 0.6
    v0 = math.sqrt(MODEL.c4 / 2.0)
    climbs = np.linspace(-4.0 * v0, 3.0 * v0, 701)
    got = power(state(vd=list(-climbs), n=len(climbs)), Climb(efficiency=eff))
    assert np.all(np.diff(got) >= -1e-9)
    assert np.all(np.diff(got[climbs > 0]) > 0)
    descending = got[climbs < 0]
    assert np.all(descending < MODEL.hover_power_w)
    # a descent saves at most hover's induced share m g v0 / η: v_c + v_i is held at ≥ 0
    weight_v0 = MASS_KG * G_MPS2 * v0
    assert descending.min() == pytest.approx(MODEL.hover_power_w - weight_v0 / eff)


def with_vertical_accel(st: FlightState, ad_mps2: list[float]) -> FlightState:
    return FlightState(
        *(getattr(st, k) for k in ("time_s", "vn_mps", "ve_mps", "vd_mps")),
        st.an_mps2,
        st.ae_mps2,
        st.alt_m,
        st.voltage_v,
        np.asarray(ad_mps2),
    )


def test_heave_is_the_load_factor_of_a_vertical_acceleration() -> None:
    """Hovering while accelerating up at a: the rotors carry m (g + a), so the induced term of
    eq. (2) goes as n^1.5 with n = 1 + a/g; a downward one lightens them, down to no thrust."""
    accel_up = np.array([0.0, 2.0, -2.0, -G_MPS2, -2.0 * G_MPS2])
    st = with_vertical_accel(state(n=5), list(-accel_up))
    extra = power(st, Heave(gain=1.0)) - MODEL.hover_power_w
    n = np.maximum(1.0 + accel_up / G_MPS2, 0.0)
    assert extra == pytest.approx(MODEL.c3 * (n**1.5 - 1.0))
    assert extra[0] == 0.0
    assert extra[1] > 0 > extra[2]
    assert extra[3] == extra[4] == pytest.approx(-MODEL.c3)  # free fall: no induced power
    assert power(st, Heave(gain=2.0)) - MODEL.hover_power_w == pytest.approx(2.0 * extra)


def test_heave_in_forward_flight_and_turns_uses_the_whole_load_factor() -> None:
    """At speed and in a turn the vertical acceleration adds to the thrust the turn needs:
    n² = (1 + a_up/g)² + (a⊥/g)²."""
    turn = state(vn=8.0, ae=3.0, n=2)
    st = with_vertical_accel(turn, [0.0, -1.5])
    a_perp = 3.0 * 8.0 / math.sqrt(64.0 + 0.25)  # the kinematics' low-speed floor
    got = power(st, Heave()) - power(turn)
    assert got[0] == 0.0
    load2 = (1.0 + 1.5 / G_MPS2) ** 2 + (a_perp / G_MPS2) ** 2
    level2 = 1.0 + (a_perp / G_MPS2) ** 2
    expected = MODEL.induced_w(8.0, load2) - MODEL.induced_w(8.0, level2)
    assert got[1] == pytest.approx(float(expected))
    # what eq. (2) gives at that load factor, its a⊥ standing for the whole thrust change
    # (no kinetic term: the speed does not change)
    equivalent_a = G_MPS2 * math.sqrt(load2 - 1.0)
    assert float(power(st, Heave())[1]) == pytest.approx(float(MODEL.power_w(8.0, equivalent_a)))


def test_avionics_adds_a_constant_load_from_at_s() -> None:
    st = state(vn=5.0, n=6)
    got = power(st, Avionics(power_w=25.0, at_s=3.0)) - float(MODEL.power_w(5.0))
    assert got == pytest.approx([0, 0, 0, 25, 25, 25])
    assert power(state(), Avionics(power_w=10.0))[0] == pytest.approx(MODEL.hover_power_w + 10)


def test_voltage_losses_grow_as_the_battery_sags() -> None:
    eff = Voltage(resistance_ohm=0.15, reference_v=25.2)
    volts = [25.2, 23.0, 21.0]
    got = power(state(voltage=volts, n=3), eff) - MODEL.hover_power_w
    p = MODEL.hover_power_w
    assert got == pytest.approx([0.15 * p * p * (1 / v**2 - 1 / 25.2**2) for v in volts])
    assert got[0] == pytest.approx(0.0) and 0 < got[1] < got[2]


def test_voltage_losses_ignore_unknown_voltage() -> None:
    got = power(state(voltage=float("nan")), Voltage(resistance_ohm=0.2, reference_v=25.0))
    assert got[0] == pytest.approx(MODEL.hover_power_w)


def test_acceleration_effect_makes_braking_cost_instead_of_return() -> None:
    braking = state(vn=10.0, an=-1.0)
    ideal = power(braking)[0]
    no_recovery = power(braking, Acceleration(efficiency=1.0, recovery=0.0))[0]
    assert no_recovery == pytest.approx(float(MODEL.power_w(10.0)))
    assert ideal == pytest.approx(no_recovery - MASS_KG * 10.0)
    speeding = state(vn=10.0, an=1.0)
    lossy = power(speeding, Acceleration(efficiency=0.5))[0]
    assert lossy == pytest.approx(float(MODEL.power_w(10.0)) + 2 * MASS_KG * 10.0)


def test_turn_effect_grows_with_the_square_of_centripetal_acceleration() -> None:
    turns = state(vn=[8.0, 8.0], ae=[2.0, 4.0], n=2)
    extra = power(turns, Turn(power_w_per_g2=300.0)) - power(turns)
    assert extra[1] / extra[0] == pytest.approx(4.0, rel=1e-6)


def test_effects_compose_in_any_order() -> None:
    st = state(vn=[2.0, 9.0, -4.0], ve=[1.0, 0.0, 3.0], vd=[-1.0, 0.0, 0.5], n=3)
    effects = [Wind(3.0, 45.0), Mass(0.4), AirDensity(1.1), Climb(0.7), Avionics(12.0)]
    assert power(st, *effects) == pytest.approx(power(st, *reversed(effects)))


def test_from_velocity_differentiates_velocity() -> None:
    t = np.linspace(0.0, 10.0, 101)
    st = FlightState.from_velocity(t, 0.5 * t, np.zeros_like(t), np.zeros_like(t))
    assert st.an_mps2 == pytest.approx(np.full(101, 0.5))
    assert np.isnan(st.voltage_v).all()


def test_flight_state_rejects_mismatched_arrays() -> None:
    with pytest.raises(ValueError, match="shape"):
        FlightState(*(np.zeros(3),) * 7, np.zeros(2))


def test_effects_round_trip_through_a_vehicle_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    effects = [
        Wind(4.5, 270.0, at_s=60.0),
        Mass(0.3, None, until_s=200.0),
        Avionics(15.0, 120.0, 300.0),
        Voltage(0.1, 25.2),
    ]
    tables = effects_to_tables(effects)
    assert tables["wind"] == {"speed_mps": 4.5, "from_deg": 270.0, "at_s": 60.0, "until_s": None}
    vehicle = VEHICLE.__class__(**{**VEHICLE.__dict__, "effects": tables})
    path = tmp_path / "v.toml"
    vehicle.save(path)
    assert effects_from_tables(load_vehicle(path).effects) == effects


def test_every_effect_type_round_trips_its_defaults() -> None:
    for name, cls in EFFECT_TYPES.items():
        effect = cls()
        assert effect.name == name
        assert effect_from_params(name, effect.params) == effect


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("gust", {}, "unknown effect"),
        ("wind", {"speed": 3}, "unknown parameter"),
        ("wind", {"speed_mps": "fast"}, "finite number"),
        ("air_density", {"rho_kgpm3": -1.0}, "out of range"),
        ("climb", {"efficiency": 1.5}, "out of range"),
        ("heave", {"gain": 1e6}, "out of range"),
        ("heave", {"gain": -1.0}, "out of range"),
    ],
)
def test_bad_effect_tables_are_one_line_user_errors(
    name: str, params: dict[str, object], message: str
) -> None:
    with pytest.raises(UserError, match=message) as info:
        effect_from_params(name, params)
    assert "\n" not in str(info.value)


def test_time_windows_bound_mass_wind_and_load() -> None:
    st = state(vn=5.0, n=8)
    t = st.time_s
    released = power(st, Mass(delta_kg=0.5, until_s=4.0)) - power(st)
    assert np.all(released[t < 4.0] > 0) and np.all(released[t >= 4.0] == 0)
    gust = power(st, Wind(speed_mps=4.0, from_deg=0.0, at_s=2.0, until_s=5.0)) - power(st)
    inside = (t >= 2.0) & (t < 5.0)
    assert np.all(gust[inside] != 0) and np.all(gust[~inside] == 0)
    load = power(st, Avionics(power_w=25.0, at_s=3.0, until_s=6.0)) - power(st)
    assert np.allclose(load, np.where((t >= 3.0) & (t < 6.0), 25.0, 0.0))


def test_a_window_that_ends_before_it_starts_is_a_user_error() -> None:
    with pytest.raises(UserError, match="until_s"):
        effect_from_params("mass", {"delta_kg": 1.0, "at_s": 5.0, "until_s": 3.0})
    assert effect_from_params("wind", {"speed_mps": 3.0, "until_s": 3.0}).params["at_s"] is None


def reported(
    time_s: np.ndarray, speed_mps: np.ndarray, from_deg: np.ndarray, scale: float = 1.0
) -> ReportedWind:
    rad = np.radians(from_deg)
    return ReportedWind(scale, time_s, -speed_mps * np.cos(rad), -speed_mps * np.sin(rad))


def test_a_reported_wind_acts_as_the_wind_it_reports_times_its_scale() -> None:
    st = state(vn=[8.0, -8.0, 0.0], ve=[0.0, 0.0, 8.0], n=3)
    t = np.array([-10.0, 10.0])
    got = power(st, reported(t, np.array([10.0, 10.0]), np.array([0.0, 0.0]), scale=0.5))
    assert got == pytest.approx(power(st, Wind(5.0, 0.0)))


def test_a_reported_wind_is_interpolated_between_reports() -> None:
    st = state(n=3)  # hover at t = 0, 1, 2 s
    wind = reported(np.array([0.0, 2.0]), np.array([2.0, 6.0]), np.array([90.0, 90.0]))
    assert power(st, wind)[1] == pytest.approx(float(MODEL.power_w(4.0)))


def test_the_summary_of_a_reported_wind_gives_its_onset_turn_and_stop() -> None:
    t = np.arange(0.0, 400.0, 0.5)
    speed = np.where((t >= 100.0) & (t < 300.0), 6.0, 0.2)
    from_deg = np.where(t < 200.0, 90.0, 180.0)
    first, second = reported(t, speed, from_deg, scale=0.5).steady()
    assert (first.speed_mps, first.from_deg) == pytest.approx((3.0, 90.0))
    assert (first.at_s, first.until_s) == (100.0, 200.0)
    assert (second.speed_mps, second.from_deg) == pytest.approx((3.0, 180.0))
    assert (second.at_s, second.until_s) == (200.0, 300.0)


def test_a_reported_wind_in_a_window_is_calm_outside_it_and_so_is_its_summary() -> None:
    """An estimate that decays for half a minute after the wind stopped is the wind only
    until the window's end: no power from its stale tail, and the summary ends there."""
    st = state(vn=[8.0, 8.0, 8.0], n=3)  # t = 0, 1, 2 s
    t = np.array([-10.0, 10.0])
    wind = replace(reported(t, np.array([6.0, 6.0]), np.array([0.0, 0.0])), at_s=1.0, until_s=2.0)
    got = power(st, wind)
    assert got[1] == pytest.approx(power(st, Wind(6.0, 0.0))[1])
    assert got[[0, 2]] == pytest.approx(power(st)[[0, 2]])
    times = np.arange(0.0, 400.0, 0.5)
    decaying = np.where(times < 250.0, 6.0, 6.0 * np.exp(-(times - 250.0) / 20.0))
    holding = reported(times, decaying, np.full(len(times), 90.0))
    assert holding.steady()[-1].until_s == pytest.approx(250.0 + 20.0 * np.log(6.0), abs=0.5)
    (windowed,) = replace(holding, at_s=100.0, until_s=250.0).steady()
    assert (windowed.at_s, windowed.until_s, windowed.speed_mps) == (100.0, 250.0, 6.0)


def test_the_estimates_ramp_after_an_onset_is_not_a_wind_of_its_own() -> None:
    """An EKF's estimate rises over 25 s after an onset: not steady, so the summary is one
    wind from the ramp on, not a weak wind first and the true one after it; its decay over
    40 s after a stop is split off, so the wind ends at the stop."""
    t = np.arange(0.0, 400.0, 0.5)
    ramp = np.clip((t - 100.0) / 25.0, 0.0, 1.0)
    (wind,) = reported(t, 8.0 * ramp, np.full(len(t), 330.0), scale=0.9).steady()
    assert wind.speed_mps == pytest.approx(7.2, abs=0.3)
    assert wind.at_s is not None and wind.at_s < 105.0 and wind.until_s is None
    decay = np.exp(-np.clip(t - 250.0, 0.0, None) / 40.0)
    stopped = reported(t, 8.0 * ramp * decay, np.full(len(t), 330.0), scale=0.9).steady()[0]
    assert stopped.at_s == wind.at_s and stopped.until_s == pytest.approx(250.0, abs=10.0)


def test_a_steady_or_calm_report_is_summarised_as_one_wind_or_none() -> None:
    t = np.arange(0.0, 200.0, 0.5)
    noisy = 5.0 + 0.3 * np.sin(t)
    (steady,) = reported(t, noisy, np.full(len(t), 300.0)).steady()
    assert steady.at_s is None and steady.until_s is None
    assert steady.speed_mps == pytest.approx(5.0, abs=0.1)
    assert reported(t, np.full(len(t), 0.5), np.zeros(len(t))).steady() == ()
