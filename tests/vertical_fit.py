"""Least-squares fits of the vertical effects (``climb``, ``heave``) on one flight's analysed
samples, against a vehicle file's level-flight model: shared by the SITL tests that check the
file's vertical effects (``tests/test_sitl_axial.py``, ``tests/test_sitl_held_out.py``)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from estimator.analysis.residual_samples import Samples
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Climb, Effect, Heave, predict_power_w
from estimator.physics.vehicle import Vehicle

#: The vehicle file's effects for vertical flight.
VERTICAL = ("climb", "heave")


def level_effects(vehicle: Vehicle) -> list[Effect]:
    """The vehicle file's effects but its vertical ones: its level-flight model."""
    return effects_from_tables({k: v for k, v in vehicle.effects.items() if k not in VERTICAL})


def file_effect(vehicle: Vehicle, name: str) -> Effect:
    """The vehicle file's effect ``name``."""
    (effect,) = [e for e in effects_from_tables(vehicle.effects) if e.name == name]
    return effect


def residual_w(samples: Samples, vehicle: Vehicle, extra: tuple[Effect, ...] = ()) -> np.ndarray:
    """Measured minus predicted power (W) on ``samples``, with the level-flight model and
    ``extra``."""
    effects = [*level_effects(vehicle), *extra]
    return np.asarray(
        samples.power_w - predict_power_w(vehicle.model, vehicle.mass_kg, samples.state, effects)
    )


def fitted_climb(samples: Samples, vehicle: Vehicle) -> Climb:
    """The climb efficiency of least squares on ``samples``, within the loop's bounds."""
    lo, hi = Climb.bounds["efficiency"]
    fit = minimize_scalar(
        lambda eff: float(np.mean(residual_w(samples, vehicle, (Climb(eff),)) ** 2)),
        bounds=(lo, hi),
        method="bounded",
    )
    return Climb(float(fit.x))


def fitted_heave(samples: Samples, vehicle: Vehicle, climb: Climb) -> Heave:
    """The heave gain of least squares on ``samples`` with ``climb``, within its bounds."""
    lo, hi = Heave.bounds["gain"]
    fit = minimize_scalar(
        lambda gain: float(np.mean(residual_w(samples, vehicle, (climb, Heave(gain))) ** 2)),
        bounds=(lo, hi),
        method="bounded",
    )
    return Heave(float(fit.x))
