"""Properties of the power model (eq. 1/2), its parametrizations and the a⊥ treatment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from estimator.physics.kinematics import centripetal_accel_mps2
from estimator.physics.model import (
    G_MPS2,
    HoverParameters,
    PowerModel,
    RotorcraftPhysics,
    kinetic_power_w,
)
from estimator.physics.vehicle import default_vehicle

models = st.builds(
    PowerModel,
    c1=st.floats(10, 500),
    c2=st.floats(1e-5, 1e-3),
    c3=st.floats(20, 800),
    c4=st.floats(5, 200),
    c5=st.floats(1e-3, 0.5),
)


@given(models)
def test_hover_power_is_c1_plus_c3(model: PowerModel) -> None:
    assert model.power_w(0.0) == pytest.approx(model.c1 + model.c3)
    assert model.hover_power_w == pytest.approx(model.c1 + model.c3)


def test_paper_vehicle_curve_falls_then_rises() -> None:
    model = default_vehicle().model
    v = np.linspace(0, 25, 2501)
    p = model.power_w(v)
    i = int(np.argmin(p))
    assert 0 < i < len(v) - 1
    assert np.all(np.diff(p[: i + 1]) <= 1e-9)
    assert np.all(np.diff(p[i:]) >= -1e-9)
    assert p[i] < p[0] - 20.0


@settings(max_examples=40, deadline=None)
@given(models)
def test_characteristic_speeds_match_brute_force(model: PowerModel) -> None:
    v = np.linspace(1e-3, 30, 300_001)
    p = model.power_w(v)
    v_me_brute = v[np.argmin(p)]
    v_mr_brute = v[np.argmin(p / v)]
    assert model.power_w(model.max_endurance_speed_mps()) <= p.min() + 1e-6
    assert model.max_endurance_speed_mps() == pytest.approx(v_me_brute, abs=2e-3)
    assert model.max_range_speed_mps() == pytest.approx(v_mr_brute, abs=2e-3)
    assert model.max_range_speed_mps() >= model.max_endurance_speed_mps() - 1e-6


@given(models, st.floats(0.5, 2.0), st.floats(0.7, 1.3))
def test_rescaling_follows_the_physical_laws(model: PowerModel, mass: float, rho: float) -> None:
    r = model.rescaled(mass_ratio=mass, density_ratio=rho)
    assert r.c1 == pytest.approx(model.c1 * rho)
    assert r.c2 == pytest.approx(model.c2)
    assert r.c3 == pytest.approx(model.c3 * mass**1.5 / math.sqrt(rho))
    assert r.c4 == pytest.approx(model.c4 * mass / rho)
    assert r.c5 == pytest.approx(model.c5 * rho)


def test_rescaling_agrees_with_the_physical_parameters() -> None:
    base = RotorcraftPhysics(mass_kg=3.0, rotor_radius_m=0.18)
    heavier = RotorcraftPhysics(mass_kg=3.6, rotor_radius_m=0.18, air_density_kgpm3=1.1)
    expected = heavier.to_model().as_array()
    got = base.to_model().rescaled(mass_ratio=1.2, density_ratio=1.1 / 1.225).as_array()
    np.testing.assert_allclose(got, expected, rtol=1e-12)


@given(models)
def test_hover_parametrization_round_trip(model: PowerModel) -> None:
    back = model.hover_parameters().to_model()
    np.testing.assert_allclose(back.as_array(), model.as_array(), rtol=1e-9)


def test_hover_parameters_have_physical_meaning() -> None:
    h = HoverParameters(400.0, 0.3, 100.0, 5.0, 0.08)
    m = h.to_model()
    assert m.hover_power_w == pytest.approx(400.0)
    assert m.c2 == pytest.approx(3.0 / 100.0**2)
    assert m.c4 == pytest.approx(2 * 5.0**2)


def test_eq2_reduces_to_eq1_without_centripetal_acceleration() -> None:
    model = default_vehicle().model
    v = np.linspace(0, 14, 50)
    np.testing.assert_allclose(model.power_w(v, 0.0), model.power_w(v))


def test_turning_costs_power_and_the_load_factor_is_exact_in_hover() -> None:
    model = default_vehicle().model
    assert np.all(model.power_w(5.0, 3.0) > model.power_w(5.0))
    # at V = 0 the induced term is c3 · n^{3/2} with load factor n² = 1 + a⊥²/g²
    n2 = 1 + (3.0 / G_MPS2) ** 2
    expected = model.c1 + model.c3 * n2**0.75
    assert model.power_w(0.0, 3.0) == pytest.approx(expected)


def test_centripetal_acceleration_is_continuous_at_zero_speed() -> None:
    a = np.array([0.3, -0.2])
    speeds = np.array([1e-6, 1e-4, 1e-2, 0.1])
    values = centripetal_accel_mps2(speeds, 0.0 * speeds, a[0], a[1])
    assert values[0] < 1e-5
    assert np.all(np.diff(values) > 0)
    # fast enough, it is the exact |v × a| / |v| of a circle: V²/r
    v, r = 8.0, 20.0
    exact = v**2 / r
    assert centripetal_accel_mps2(v, 0.0, 0.0, exact) == pytest.approx(exact, rel=0.01)


def test_kinetic_power_is_m_v_dot_a() -> None:
    assert kinetic_power_w(3.0, [4.0, 0.0], [0.5, 2.0]) == pytest.approx(6.0)
    assert kinetic_power_w(3.0, [[0.0, 5.0]], [[1.0, 0.0]])[0] == pytest.approx(0.0)
