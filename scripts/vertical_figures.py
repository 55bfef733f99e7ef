"""The figures of docs/residuals.md on SITL's vertical effects (``climb``, ``heave``):

- the SITL vehicle file's vertical effects as ``uav-energy residuals
  replay/sitl_axial/*/flight.tlog --vehicle <the file without them> --candidates climb,heave
  --json`` fits them (the command its header gives), and the heave gain of least squares on
  each axial flight alone (``tests/vertical_fit.py``, as ``tests/test_sitl_axial.py`` fits it);
- the heave gain of least squares on each clean held-out flight with vertical legs
  (:data:`CLEAN_VERTICAL`, ``replay/sitl_held``): on the raw power against the file's, and
  with the power through the accelerations' filter against the same fit on the axial flights,
  the issue's aim, which ``tests/test_sitl_held_out.py`` holds each flight to (a strict xfail
  on those beyond it).

``scripts/figures.py`` registers the blocks (:func:`generators`); ≈ 5 s of CPU in all.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Callable
from dataclasses import replace
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

from estimator.analysis.residual_samples import prepare
from estimator.logs import load_flights
from estimator.physics.effects import Heave
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
HELD_RECORDINGS = REPO / "replay" / "sitl_held"
#: The clean held-out flights with vertical legs (``tests/test_sitl_held_out.py`` holds the
#: file's vertical effects to a fit on each).
CLEAN_VERTICAL = (
    "held_clean_climbing_legs", "held_clean_vertical", "held2_clean_fast_vertical",
    "held2_clean_slow_climbs", "held3_clean_mixed_vertical", "held3_clean_tall_slow",
    "held4_clean_circles_vertical", "held5_clean_legs_climbs", "held6_clean_fast_climbs",
    "held14_clean_climbs_legs", "held15_clean_steps_legs", "held15_clean_slow_climbs",
    "held15_clean_circles_climbs", "held15_clean_stairs", "held15_clean_tall_fast",
    "held15_clean_climbing_legs", "held15_clean_staged_descents", "held15_clean_short_climbs",
)  # fmt: skip
#: The issue's aim: a flight's heave gain, the power through the accelerations' filter, within
#: this many σ (the two fits' jackknife 1σ combined) of the same fit on the axial flights.
HEAVE_Z = 2.0
#: The set of clean vertical flights recorded after the filtered heave fit was frozen.
FILTER_HELD_OUT = "held15"

Cli = Callable[..., str]


def axial_fit(cli: Cli, vertical_fit: ModuleType) -> dict[str, Any]:
    """``uav-energy residuals`` of the axial flights against the SITL vehicle file without its
    vertical effects, ``--candidates climb,heave --json``."""
    vehicle = load_vehicle(SITL_VEHICLE)
    level = {k: v for k, v in vehicle.effects.items() if k not in vertical_fit.VERTICAL}
    logs = [
        str(vertical_fit.AXIAL_RECORDINGS / n / "flight.tlog") for n in vertical_fit.AXIAL_FLIGHTS
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "level.toml"
        replace(vehicle, effects=level).save(path)
        out = cli(
            "residuals", *logs, "--vehicle", str(path), "--candidates", "climb,heave", "--json"
        )
    return dict(json.loads(out))


def _gain(vertical_fit: ModuleType, samples: Any) -> float:
    """The heave gain of least squares on ``samples`` with their own climb efficiency."""
    vehicle = load_vehicle(SITL_VEHICLE)
    climb = vertical_fit.fitted_climb(samples, vehicle)
    heave = vertical_fit.fitted_heave(samples, vehicle, climb)
    assert isinstance(heave, Heave)
    return float(heave.gain)


def axial_effects(fit: dict[str, Any], vertical_fit: ModuleType) -> str:
    """The climb efficiency and heave gain the command fits (with the gain's fold sd), and the
    gain on each axial flight alone."""
    effects = {e["name"]: e for e in fit["effects"]}
    climb, heave = effects["climb"], effects["heave"]
    alone = sorted(
        _gain(vertical_fit, vertical_fit.axial_samples(n)) for n in vertical_fit.AXIAL_FLIGHTS
    )
    return (
        f"climb efficiency at its bound {climb['params']['efficiency']:.1f} and heave gain "
        f"{heave['params']['gain']:.3f} (fold sd {heave['params_fold_sd']['gain']:.3f}; "
        f"{' and '.join(f'{g:.3f}' for g in alone)} by least squares on each flight alone, "
        "`tests/test_sitl_axial.py`)"
    )


def heave_z(flight: Any, axial: Any) -> float:
    """A flight's filtered heave gain against the axial flights', in their combined 1σ
    (``vertical_fit.GainFit`` each)."""
    return float((flight.gain - axial.gain) / math.hypot(flight.sigma, axial.sigma))


def held_gains(vertical_fit: ModuleType) -> str:
    """The heave gain fitted on each clean held-out flight with vertical legs: on the raw power
    (range, how many beyond 10 % of the file's) and through the accelerations' filter (range,
    how many beyond :data:`HEAVE_Z` of the axial flights'), the flights the filter was
    developed on apart from those recorded after it (:data:`FILTER_HELD_OUT`)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    file_gain = vertical_fit.file_effect(vehicle, "heave").gain
    flights = {
        f: prepare(load_flights([HELD_RECORDINGS / f / "flight.tlog"], "tlog"))
        for f in CLEAN_VERTICAL
    }
    raw = [_gain(vertical_fit, samples) for samples in flights.values()]
    file_efficiency = vertical_fit.file_effect(vehicle, "climb").efficiency
    efficiency_apart = sum(
        abs(vertical_fit.fitted_climb(samples, vehicle).efficiency - file_efficiency) > 0.1
        for samples in flights.values()
    )
    axial = vertical_fit.filtered_heave_gain(
        [vertical_fit.axial_samples(n) for n in vertical_fit.AXIAL_FLIGHTS], vehicle
    )

    def filtered(held_out: bool, what: str) -> str:
        fits = [
            vertical_fit.filtered_heave_gain([samples], vehicle)
            for f, samples in flights.items()
            if f.startswith(FILTER_HELD_OUT) == held_out
        ]
        gains = [fit.gain for fit in fits]
        apart = sum(abs(heave_z(fit, axial)) > HEAVE_Z for fit in fits)
        return f"{min(gains):.2f}–{max(gains):.2f} on the {len(fits)} {what}, {apart} beyond"

    return (
        f"the climb efficiency of each of the {len(raw)} clean held-out flights with vertical "
        f"legs is within 0.1 of the file's on {len(raw) - efficiency_apart}; "
        f"fitted on the raw power, the heave gain of each is {min(raw):.2f}–{max(raw):.2f}, "
        f"{sum(abs(g / file_gain - 1) > 0.1 for g in raw)} of them more than 10 % from the "
        f"file's; with the power through the accelerations' filter it is "
        f"{filtered(False, 'flights the filter was developed on')} {HEAVE_Z:.0f}σ of the "
        f"axial flights' {axial.gain:.3f} ± {axial.sigma:.3f}, and "
        f"{filtered(True, f'recorded after it ({FILTER_HELD_OUT}_*)')} "
        "(`tests/test_sitl_held_out.py`, strict xfails)"
    )


def generators(cli: Cli, vertical_fit: ModuleType) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it (``scripts/figures.py`` registers them)."""
    fit = cache(lambda: axial_fit(cli, vertical_fit))
    return {
        "residuals-sitl-axial-effects": lambda: axial_effects(fit(), vertical_fit),
        "residuals-sitl-held-heave": lambda: held_gains(vertical_fit),
    }
