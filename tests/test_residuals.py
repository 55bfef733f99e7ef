"""Residual analysis on simulated flights: each hidden effect is found first with its
parameters, the held-out error falls to the noise level, clean flights give no effect, and an
effect no candidate covers is reported with the channel that predicts it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from estimator.analysis.residuals import (
    ResidualOptions,
    ResidualResult,
    Samples,
    _block_gain_z,
    analyze,
    prepare,
)
from estimator.logs import FlightSeries, load_flights
from estimator.physics.effects import (
    Acceleration,
    AirDensity,
    Avionics,
    Climb,
    Effect,
    Mass,
    Turn,
    Voltage,
    Wind,
    effects_to_tables,
    predict_power_w,
)
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

VEHICLE = default_vehicle()
DURATION_S = {"mixed": 600.0, "straight": 420.0, "circles": None}


def flights_of(tmp_path: Path, plan: str, seed: int, effects: tuple[Effect, ...] = (), **kw):
    """Simulate, write a tlog and read it back the way the command does."""
    config = SimConfig(plan=plan, duration_s=DURATION_S[plan], seed=seed, effects=effects, **kw)
    path = write_tlog(simulate(config), tmp_path / f"{plan}-{seed}.tlog", truth_csv=False)
    return load_flights([path])


def noise_rmse_w(flights: list[FlightSeries], effects: tuple[Effect, ...]) -> float:
    """RMSE of the true model (hidden effects declared) on the analysed samples: the floor."""
    samples = prepare(flights)
    truth = predict_power_w(VEHICLE.model, VEHICLE.mass_kg, samples.state, list(effects))
    return float(np.sqrt(np.mean((samples.power_w - truth) ** 2)))


def angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize(("plan", "seed"), [("mixed", 1), ("circles", 2), ("straight", 3)])
def test_clean_flights_yield_no_effect(tmp_path: Path, plan: str, seed: int) -> None:
    result = analyze(flights_of(tmp_path, plan, seed), VEHICLE)
    assert result.selected == []
    assert result.rmse_w(True) == result.rmse_w(False)
    assert "no candidate effect" in result.verdict()


@pytest.mark.parametrize(
    ("plan", "seed", "wind"),
    [("mixed", 4, Wind(5.0, 60.0)), ("circles", 5, Wind(4.0, 250.0))],
)
def test_hidden_wind_is_named_first_and_recovered(
    tmp_path: Path, plan: str, seed: int, wind: Wind
) -> None:
    flights = flights_of(tmp_path, plan, seed, (wind,))
    result = analyze(flights, VEHICLE)
    first = result.selected[0]
    assert first.name == "wind"
    assert isinstance(first.effect, Wind)
    assert abs(first.effect.speed_mps - wind.speed_mps) < 1.0
    assert angle_diff_deg(first.effect.from_deg, wind.from_deg) < 20.0
    assert result.rmse_w(True) < 1.15 * noise_rmse_w(flights, (wind,)) + 0.5
    assert result.rmse_w(True) < 0.3 * result.rmse_w(False)


@pytest.mark.parametrize(("plan", "seed", "delta_kg"), [("mixed", 6, 0.5), ("straight", 7, -0.3)])
def test_hidden_constant_mass_is_named_first_and_recovered(
    tmp_path: Path, plan: str, seed: int, delta_kg: float
) -> None:
    mass = Mass(delta_kg)
    flights = flights_of(tmp_path, plan, seed, (mass,))
    result = analyze(flights, VEHICLE)
    first = result.selected[0]
    assert first.name == "mass"
    assert isinstance(first.effect, Mass)
    assert abs(first.effect.delta_kg - delta_kg) < 0.1
    assert first.effect.at_s is None
    assert result.rmse_w(True) < 1.15 * noise_rmse_w(flights, (mass,)) + 0.5


def test_payload_picked_up_mid_flight_is_a_mass_step(tmp_path: Path) -> None:
    mass = Mass(0.6, at_s=250.0)
    flights = flights_of(tmp_path, "mixed", 8, (mass,))
    result = analyze(flights, VEHICLE)
    first = result.selected[0]
    assert first.name == "mass"
    assert isinstance(first.effect, Mass)
    assert abs(first.effect.delta_kg - 0.6) < 0.1
    assert first.effect.at_s is not None and abs(first.effect.at_s - 250.0) < 5.0
    # held out, the chunk holding the step cannot know when it happened and keeps some error;
    # the final fit on all data is at the noise level
    assert result.rmse_w(True) < 0.5 * result.rmse_w(False)
    samples = prepare(flights)
    fitted = predict_power_w(VEHICLE.model, VEHICLE.mass_kg, samples.state, result.effects)
    rmse_fitted = float(np.sqrt(np.mean((samples.power_w - fitted) ** 2)))
    assert rmse_fitted < 1.15 * noise_rmse_w(flights, (mass,)) + 0.5


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "plan", "seed", "effect", "kw"),
    [
        ("avionics", "circles", 9, Avionics(30.0), {}),
        ("air_density", "straight", 10, AirDensity(1.0), {}),
        ("climb", "mixed", 11, Climb(0.6), {"climb_legs": True}),
        ("voltage", "mixed", 12, Voltage(0.3, 25.2), {}),
        ("turn", "circles", 13, Turn(500.0), {}),
        ("acceleration", "mixed", 14, Acceleration(0.6, 0.2), {}),
    ],
)
def test_other_hidden_effects_are_named_first(
    tmp_path: Path, name: str, plan: str, seed: int, effect: Effect, kw: dict
) -> None:
    flights = flights_of(tmp_path, plan, seed, (effect,), **kw)
    result = analyze(flights, VEHICLE)
    first = result.selected[0]
    assert first.name == name
    for key, true_value in effect.params.items():
        got = first.effect.params[key]
        if true_value is None:
            assert got is None
        else:
            assert got == pytest.approx(true_value, rel=0.2, abs=0.05), key
    assert result.rmse_w(True) < 1.15 * noise_rmse_w(flights, (effect,)) + 0.5


def test_declared_effect_is_not_a_candidate_and_leaves_nothing(tmp_path: Path) -> None:
    wind = Wind(5.0, 60.0)
    flights = flights_of(tmp_path, "mixed", 4, (wind,))
    declared = Vehicle(
        VEHICLE.name,
        VEHICLE.mass_kg,
        VEHICLE.model,
        VEHICLE.battery,
        effects=effects_to_tables([wind]),
    )
    result = analyze(flights, declared)
    assert result.selected == []
    assert all(row.label != "wind" for row in result.table)


def test_unexplained_residual_points_at_the_channel_that_predicts_it(tmp_path: Path) -> None:
    # an electrical load switched on at 300 s, but avionics/mass are not candidates: the
    # residual steps with time, so time (or energy drawn, or voltage) predicts it
    flights = flights_of(tmp_path, "mixed", 15, (Avionics(40.0, at_s=300.0),))
    options = ResidualOptions(candidates=("wind", "turn", "climb"))
    result = analyze(flights, VEHICLE, options)
    assert result.selected == []
    assert "no candidate effect explains the residual" in result.verdict()
    assert result.attribution[0].channel in ("time_s", "energy_used_wh", "voltage_v")
    assert result.attribution[0].r2 > 0.5


def test_held_out_rows_never_train_and_guard_is_kept(tmp_path: Path) -> None:
    samples = prepare(flights_of(tmp_path, "circles", 2))
    opt = ResidualOptions()
    for j in range(opt.folds):
        train = samples.train_rows(j, opt.guard_s)
        held = samples.fold == j
        assert not (train & held).any()
        t_held = samples.state.time_s[held]
        t_train = samples.state.time_s[train]
        gap = np.min(np.abs(t_train[:, None] - t_held[None, :]))
        assert gap > opt.guard_s
        # folds are contiguous time chunks
        assert np.all(np.diff(samples.fold) >= 0)


def _fake_samples(blocks: np.ndarray) -> Samples:
    from estimator.physics.effects import FlightState

    n = len(blocks)
    z = np.zeros(n)
    return Samples(
        flight_ids=["f"],
        flight=np.zeros(n, dtype=np.int64),
        state=FlightState(np.arange(n, dtype=float), z, z, z, z, z, z, z),
        power_w=np.ones(n),
        fold=np.zeros(n, dtype=np.int64),
        block=blocks.astype(np.int64),
        channels={},
    )


def test_block_test_is_zero_for_equal_errors_and_large_for_consistent_gains() -> None:
    rng = np.random.default_rng(0)
    samples = _fake_samples(np.repeat(np.arange(30), 20))
    err = rng.normal(0, 5, 600)
    assert _block_gain_z(samples, err, err) == 0.0
    assert _block_gain_z(samples, err + 3.0, err) > 5.0
    assert _block_gain_z(samples, err, err + 3.0) < -5.0
    noise_only = _block_gain_z(samples, err, rng.normal(0, 5, 600))
    assert abs(noise_only) < 3.0


def test_json_summary_has_the_issue_keys(tmp_path: Path) -> None:
    result: ResidualResult = analyze(
        flights_of(tmp_path, "circles", 5, (Wind(4.0, 250.0),)), VEHICLE
    )
    s = result.summary()
    for key in ("rmse_before_w", "rmse_after_w", "mape_before_pct", "mape_after_pct"):
        assert math.isfinite(s[key])
    assert s["mape_after_pct"] < s["mape_before_pct"]
    assert s["effects"][0]["name"] == "wind"
    assert set(s["effects"][0]["params"]) == {"speed_mps", "from_deg"}
