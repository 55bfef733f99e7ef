"""Climbs and descents at several rates in ArduCopter SITL (``replay/sitl_axial/``, its
SOURCE.md) against the vertical effects: ``climb`` (axial flight, :mod:`estimator.physics.axial`)
and ``heave`` (the thrust of a vertical acceleration, :class:`~estimator.physics.effects.Heave`).

SITL's multicopter has no rotor inflow physics: each motor's electrical power is a constant
times its thrust (libraries/SITL/SIM_Motor.cpp), and the thrust a steady climb needs is the
weight plus the airframe's vertical drag (SIM_Frame.cpp). So its climb power is a drag,
antisymmetric in the climb rate and below the potential-energy rate m g v_c: these flights
cannot test momentum theory, only that the effect moves the prediction the right way on
physics the project did not write. Its thrust does follow the vertical acceleration, which
``heave`` models. Each effect is fitted on one flight and held out on the other, both ways,
against the vehicle file's level-flight model; the file's own vertical effects were fitted on
both flights (its header) and are checked against each flight's fit.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
import vertical_fit

from estimator.physics.effects import Climb, Effect, Heave
from estimator.physics.model import G_MPS2
from estimator.physics.vehicle import Vehicle, load_vehicle

REPO = Path(__file__).resolve().parent.parent
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
FLIGHTS = vertical_fit.AXIAL_FLIGHTS
#: Vertical speed (m/s) beyond which a sample is a climb or a descent.
MOVING_MPS = 0.5
#: Vertical acceleration (m/s²) beyond which a sample starts or stops a climb or descent.
ACCELERATING_MPS2 = 0.5


@cache
def sitl_vehicle() -> Vehicle:
    return load_vehicle(VEHICLE)


samples = vertical_fit.axial_samples


def residual_w(name: str, extra: tuple[Effect, ...] = ()) -> np.ndarray:
    """Measured minus predicted power (W) on the flight's analysed samples, with the
    level-flight model and ``extra``."""
    return vertical_fit.residual_w(samples(name), sitl_vehicle(), extra)


def rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2)))


def fitted_climb(name: str) -> Climb:
    return vertical_fit.fitted_climb(samples(name), sitl_vehicle())


def fitted_heave(name: str, climb: Climb) -> Heave:
    return vertical_fit.fitted_heave(samples(name), sitl_vehicle(), climb)


def file_effect(name: str) -> Effect:
    return vertical_fit.file_effect(sitl_vehicle(), name)


def vertical_response(name: str) -> np.ndarray:
    """SITL's vertical law on one flight (:func:`vertical_fit.vertical_response`)."""
    return vertical_fit.vertical_response([samples(name)], sitl_vehicle())


@pytest.mark.parametrize("name", FLIGHTS)
def test_the_flight_climbs_and_descends_at_several_rates(name: str) -> None:
    climb = -samples(name).state.vd_mps
    up, down = climb[climb > MOVING_MPS], climb[climb < -MOVING_MPS]
    assert len(up) >= 30 and len(down) >= 40
    assert np.percentile(up, 90) - np.percentile(up, 10) > 1.5  # more than one rate each way
    assert np.percentile(down, 90) - np.percentile(down, 10) > 1.0


@pytest.mark.parametrize("name", FLIGHTS)
def test_sitl_climb_power_is_a_drag_not_momentum_theory(name: str) -> None:
    """Antisymmetric in the climb rate, and a steady 3 m/s climb costs less than its
    potential energy: what SITL cannot test."""
    per_mps, per_mps2, per_accel = vertical_response(name)
    v = sitl_vehicle()
    thrust_power_w_per_n = v.model.hover_power_w / (v.mass_kg * G_MPS2)
    # a vertical acceleration costs power × thrust share, as SITL's current is linear in thrust
    assert per_accel == pytest.approx(thrust_power_w_per_n * v.mass_kg, rel=0.25)
    rise_3mps_w = 3.0 * per_mps + 9.0 * per_mps2
    assert 0 < rise_3mps_w < 0.6 * v.mass_kg * G_MPS2 * 3.0
    # both flights see the same law (drag, not a property of one flight)
    other = vertical_response(FLIGHTS[1 - FLIGHTS.index(name)])
    assert per_mps == pytest.approx(other[0], rel=0.25)


@pytest.mark.parametrize(("fit_on", "held_out"), [FLIGHTS, FLIGHTS[::-1]])
def test_the_axial_effect_fitted_on_one_flight_lowers_the_others_error(
    fit_on: str, held_out: str
) -> None:
    effect = fitted_climb(fit_on)
    # SITL climbs for less than momentum theory at any efficiency: the fit sits at the bound
    assert effect.efficiency == pytest.approx(Climb.bounds["efficiency"][1], abs=0.01)
    climb = -samples(held_out).state.vd_mps
    moving = np.abs(climb) > MOVING_MPS
    before, after = residual_w(held_out), residual_w(held_out, (effect,))
    assert rms(after[moving]) < 0.8 * rms(before[moving])
    assert rms(after) < 0.8 * rms(before)
    # the climb bias goes; level flight is untouched
    assert abs(after[climb > MOVING_MPS].mean()) < 0.5 * abs(before[climb > MOVING_MPS].mean())
    assert rms(after[~moving]) == pytest.approx(rms(before[~moving]), rel=0.05)


@pytest.mark.parametrize(("fit_on", "held_out"), [FLIGHTS, FLIGHTS[::-1]])
def test_heave_fitted_on_one_flight_lowers_the_others_error_where_it_accelerates(
    fit_on: str, held_out: str
) -> None:
    climb = fitted_climb(fit_on)
    heave = fitted_heave(fit_on, climb)
    # SITL's current is linear in thrust: near hover the gain is its hover power over 1.5 × its
    # induced share (P_i ∝ n^1.5), what it draws beyond a rotor whose profile power is fixed
    v = sitl_vehicle()
    assert heave.gain == pytest.approx(v.model.hover_power_w / (1.5 * v.model.c3), rel=0.25)
    s = samples(held_out)
    accel_up = -s.state.ad_mps2
    assert accel_up is not None
    accelerating = np.abs(accel_up) > ACCELERATING_MPS2
    assert accelerating.sum() >= 20
    before, after = residual_w(held_out, (climb,)), residual_w(held_out, (climb, heave))
    assert rms(after[accelerating]) < 0.6 * rms(before[accelerating])
    assert rms(after) < 0.8 * rms(before)
    # a steady climb, descent or hover is no worse
    assert rms(after[~accelerating]) < 1.05 * rms(before[~accelerating])


@pytest.mark.parametrize("name", FLIGHTS)
def test_the_files_vertical_effects_agree_with_each_flights_fit(name: str) -> None:
    """The file's heave gain (fitted on both flights) lies within 10 % of each one's, and its
    vertical effects bring each flight within three noise floors (level-flight model:
    more than seven)."""
    climb, file_climb = fitted_climb(name), file_effect("climb")
    assert isinstance(file_climb, Climb)
    assert climb.efficiency == pytest.approx(file_climb.efficiency, abs=0.01)
    heave = file_effect("heave")
    assert isinstance(heave, Heave)
    assert heave.gain == pytest.approx(fitted_heave(name, climb).gain, rel=0.1)
    floor_w = 3.3  # the noise floor of `uav-energy residuals` on these flights (file header)
    after = residual_w(name, (file_climb, heave))
    assert rms(after - after.mean()) < 3.0 * floor_w
    before = residual_w(name)
    assert rms(before - before.mean()) > 7.0 * floor_w
