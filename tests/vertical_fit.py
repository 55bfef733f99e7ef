"""Least-squares fits of the vertical effects (``climb``, ``heave``) on one flight's analysed
samples, against a vehicle file's level-flight model, and SITL's own vertical law on its climbs
and descents in place (``replay/sitl_axial/``): shared by the SITL tests that check the file's
vertical effects (``tests/test_sitl_axial.py``, ``tests/test_sitl_held_out.py``) and
``scripts/plan_figures.py`` (docs/plan.md's climb power)."""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize_scalar

from estimator.analysis.residual_samples import (
    ResidualOptions,
    Samples,
    prepare,
    through_accel_filter,
)
from estimator.logs import load_flights
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Climb, Effect, Heave, predict_power_w
from estimator.physics.vehicle import Vehicle

#: The vehicle file's effects for vertical flight.
VERTICAL = ("climb", "heave")
#: ArduCopter SITL's climbs and descents in place at several rates (its SOURCE.md).
AXIAL_RECORDINGS = Path(__file__).resolve().parent.parent / "replay" / "sitl_axial"
AXIAL_FLIGHTS = ("axial_rates", "axial_rates_held")


@cache
def axial_samples(name: str) -> Samples:
    """The analysed samples of the flight ``name`` of :data:`AXIAL_RECORDINGS`."""
    flights = load_flights([AXIAL_RECORDINGS / name / "flight.tlog"], "tlog")
    return prepare(flights, ResidualOptions())


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


class GainFit(NamedTuple):
    """A heave gain and its 1σ (a delete-one-chunk jackknife over the held-out chunks)."""

    gain: float
    sigma: float


def filtered_heave_gain(flights: Sequence[Samples], vehicle: Vehicle) -> GainFit:
    """The heave gain of least squares over ``flights`` pooled (each with its own climb
    efficiency), the residual power seen through the accelerations' filter
    (:func:`through_accel_filter`, default options: like with like), and its 1σ."""
    products, squares, chunks = [], [], []
    base = 0  # chunk ids are unique within one Samples: offset each by those before it
    for samples in flights:
        climb = fitted_climb(samples, vehicle)
        residual = residual_w(samples, vehicle, (climb,))
        heave_w = residual - residual_w(samples, vehicle, (climb, Heave(1.0)))
        products.append(heave_w * through_accel_filter(samples, residual, ResidualOptions()))
        squares.append(heave_w**2)
        chunks.append(samples.chunk + base)
        base += int(samples.chunk.max()) + 1
    product, square, chunk = map(np.concatenate, (products, squares, chunks))
    ids = np.unique(chunk)
    left_out = np.array(
        [(product.sum() - product[chunk == k].sum()) / (square.sum() - square[chunk == k].sum())
         for k in ids]
    )  # fmt: skip
    spread = float(np.sqrt((len(ids) - 1) / len(ids) * np.sum((left_out - left_out.mean()) ** 2)))
    return GainFit(float(product.sum() / square.sum()), spread)


def vertical_response(flights: Sequence[Samples], vehicle: Vehicle) -> np.ndarray:
    """The residual against the level-flight model, least squares on [v_c, v_c |v_c|, a_z, 1]
    (v_c up, m/s; a_z up, m/s²) over the samples of ``flights`` pooled: W per m/s, W per
    (m/s)², W per m/s²."""
    rows, residuals = [], []
    for samples in flights:
        climb = -samples.state.vd_mps
        accel = np.gradient(climb, samples.state.time_s)
        rows.append(np.column_stack([climb, climb * np.abs(climb), accel, np.ones_like(climb)]))
        residuals.append(residual_w(samples, vehicle))
    coef, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(residuals), rcond=None)
    return np.asarray(coef[:3])
