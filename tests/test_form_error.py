"""The model form's error carried into the tracker's reported 1σ (estimation/form_error.py):
the step's error at its airspeed, the sensitivity through a Kalman update, and the claim
itself: the sensitivity the tracker carries is the error a biased model leaves in its
estimate."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from estimator.estimation.form_error import carried, form_power_w
from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.online_settings import OnlineSettings
from estimator.physics.vehicle import default_vehicle

VEHICLE = default_vehicle()


def rows_at(vn_mps: float, ve_mps: float) -> np.ndarray:
    """One reading's FlightState row (9 fields) with this ground velocity (m/s)."""
    row = np.zeros((1, 9))
    row[0, 1], row[0, 2] = vn_mps, ve_mps
    return row


def test_the_form_error_is_zero_at_rest_in_the_air_and_grows_with_airspeed_squared() -> None:
    hover_w = 300.0
    still = np.zeros(2)
    assert form_power_w(rows_at(0.0, 0.0), still, hover_w, 0.02, 10.0) == 0.0
    assert form_power_w(rows_at(10.0, 0.0), still, hover_w, 0.02, 10.0) == pytest.approx(6.0)
    assert form_power_w(rows_at(5.0, 0.0), still, hover_w, 0.02, 10.0) == pytest.approx(1.5)
    # the airspeed, not the ground speed: hovering in a 10 m/s wind, flying 5 m/s into 5 m/s
    wind = np.array([-10.0, 0.0])
    assert form_power_w(rows_at(0.0, 0.0), wind, hover_w, 0.02, 10.0) == pytest.approx(6.0)
    assert form_power_w(rows_at(5.0, 0.0), wind / 2, hover_w, 0.02, 10.0) == pytest.approx(6.0)
    # a step's error is the mean over its readings
    both = np.vstack([rows_at(0.0, 0.0), rows_at(10.0, 0.0)])
    assert form_power_w(both, still, hover_w, 0.02, 10.0) == pytest.approx(3.0)


def test_carried_is_i_minus_kh_of_a_linear_kalman_update() -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        a = rng.normal(size=(4, 4))
        p = a @ a.T + 0.1 * np.eye(4)
        h = rng.normal(size=4)
        gain = p @ h / (h @ p @ h + 0.5)
        p_after = (np.eye(4) - np.outer(gain, h)) @ p
        c = rng.normal(size=4)
        expected = (np.eye(4) - np.outer(gain, h)) @ c
        assert np.allclose(carried(c, p, p_after), expected, rtol=1e-9, atol=1e-12)
    # damaged covariances leave the sensitivity as it was
    c = np.array([0.1, -0.2, 0.03, 1.0])
    singular = np.zeros((4, 4))
    assert carried(c, singular, np.eye(4)) is c
    assert carried(c, np.eye(4), np.full((4, 4), np.nan)) is c


def fly_box(tracker: OnlineEffects, bias_w: float, fraction: float) -> None:
    """Legs north, east, south and west at 10 m/s in still air (one reading a second, 60 s
    each) with the vehicle file's mass: the measured power is the model's plus ``bias_w`` ×
    the form error's 1σ at 10 m/s (``fraction`` of the hover power)."""
    model = VEHICLE.model
    power_w = float(model.power_w(10.0)) + bias_w * fraction * model.hover_power_w
    legs = ((10.0, 0.0), (0.0, 10.0), (-10.0, 0.0), (0.0, -10.0))
    for k in range(240):
        vn, ve = legs[k // 60]
        tracker.update(float(k), vn, ve, 0.0, 0.0, 0.0, power_w)


def test_the_carried_sensitivity_is_the_error_a_biased_model_leaves_in_the_estimate() -> None:
    """Consider analysis: the same flight with the measured power off by the form error's
    1σ (θ = 1) and without; the estimates end apart by the sensitivity the tracker carries
    (the mass to 10 %), and the reported 1σ adds exactly that."""
    fraction = OnlineSettings().speed_form_sigma_fraction
    runs = {}
    for bias in (0.0, 1.0):
        tracker = OnlineEffects(VEHICLE.model, VEHICLE.mass_kg)
        fly_box(tracker, bias, fraction)
        runs[bias] = tracker
    moved = runs[1.0]._x[:3] - runs[0.0]._x[:3]
    sensitivity = runs[0.0]._form[:3]
    assert moved[2] > 0.05  # a mass error worth reporting (kg): a 1.5 % power excess
    assert sensitivity[2] == pytest.approx(moved[2], rel=0.1)
    # the wind: first order only (form_error.py), a tenth of its 0.5 m/s form term
    assert np.abs(sensitivity[:2] - moved[:2]).max() < 0.08
    without = OnlineEffects(
        VEHICLE.model,
        VEHICLE.mass_kg,
        settings=replace(OnlineSettings(), speed_form_sigma_fraction=0.0),
    )
    fly_box(without, 0.0, fraction)
    assert not without._form.any()
    grown = runs[0.0].sigma["mass_kg"] ** 2 - without.sigma["mass_kg"] ** 2
    assert grown == pytest.approx(sensitivity[2] ** 2, rel=1e-6)
