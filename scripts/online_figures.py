"""docs/residuals.md's figures of the online tracker on simulated flights: two of the flights
``tests/test_online_effects.py`` flies (the built-in vehicle, plan ``mixed``, 600 s), replayed
the daemon's way (tlog → samples → causal kinematics → tracker): a hidden wind, and a payload
picked up in forward flight.

``scripts/figures.py`` registers the blocks (:func:`generators`; ≈ 6 s of CPU);
``tests/test_figures.py`` checks them.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.track_runner import TrackPoint, track_samples
from estimator.logs import iter_samples
from estimator.physics.effects import Effect, Mass, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

#: ``tests/test_online_effects.py``'s flights: (seed, hidden effect) on plan ``mixed``.
WIND_FLIGHT = (41, Wind(5.0, 60.0))
PICKUP_S = 250.0
PICKUP_FLIGHT = (44, Mass(0.6, at_s=PICKUP_S))
#: How long after the pick-up (s) its mass is read.
PICKUP_READ_AFTER_S = 1.0


def track(seed: int, effect: Effect) -> list[TrackPoint]:
    """The tracker's points on a 600 s ``mixed`` flight with ``effect`` hidden."""
    run = simulate(SimConfig(plan="mixed", duration_s=600.0, seed=seed, effects=(effect,)))
    with tempfile.TemporaryDirectory() as tmp:
        path = write_tlog(run, Path(tmp) / "flight.tlog", truth_csv=False)
        return track_samples(iter_samples(path), OnlineEffects.from_vehicle(default_vehicle()))


def wind() -> str:
    """The wind tracked at the end of :data:`WIND_FLIGHT`."""
    end = track(*WIND_FLIGHT)[-1]
    return f"{end.wind_speed_mps:.1f} m/s from {end.wind_from_deg:.0f}°"


def pickup() -> str:
    """The mass tracked :data:`PICKUP_READ_AFTER_S` after the pick-up and at the end."""
    points = track(*PICKUP_FLIGHT)
    times = np.array([p.time_s for p in points])
    after = points[int(np.searchsorted(times, PICKUP_S + PICKUP_READ_AFTER_S))]
    return (
        f"{after.mass_delta_kg:.2f} kg {PICKUP_READ_AFTER_S:.0f} s after it, "
        f"{points[-1].mass_delta_kg:.2f} kg at the end"
    )


def generators() -> dict[str, Callable[[], str]]:
    return {"online-sim-wind": wind, "online-sim-pickup": pickup}
