"""Endurance on packs that are not what their label says: the ArduCopter SITL pack flights of
replay/sitl_packs (a 5.0 Ah label; the real pack 65–100 % of it, 10 or 30 mΩ, 50–100 %
charged at power-up, some with wind and payload) replayed with the LABELLED capacity
(:mod:`estimator.analysis.pack_flights`): scored from 60 s after take-off until 60 s before
the true reserve. Six flights were the tuning half, seven held out (split.json, fixed before
any run); ``python scripts/pack_state_sitl.py`` prints the table of docs/pack.md."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from estimator.analysis.pack_flights import PackFlight, replay_pack_flight
from estimator.analysis.replay import run
from estimator.estimation.pipeline import Pipeline
from estimator.logs import iter_samples
from estimator.physics.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
SPLIT = json.loads((FLIGHTS / "split.json").read_text())
VEHICLE = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
SCRIPT = ROOT / "scripts" / "pack_state_sitl.py"
#: Flights too short to score: the pack reaches its reserve within 120 s of take-off.
UNSCORED = {"pack_c80_r3_soc50"}
NAMES = [n for half in ("tuning", "held_out") for n in SPLIT[half]]
SCORED = [n for n in NAMES if n not in UNSCORED]
#: Flights that miss 3 % median / 8 % worst, and why (measured with the rules frozen).
MISSES = {
    "pack_c80_r1_wind": "worst −9.4 % 75 s before the reserve: the steady power in the wind "
    "the model predicts there (403 W at 4.4 m/s) runs 5 % above the measured (382 W)",
    "pack_c65_r3_soc75": "median 3.9 %, worst +8.4 % at 69 s after take-off: powered up at "
    "75 %, the first minute narrows the capacity to 3.42 ± 0.21 Ah only (truth 3.25)",
    "pack_c80_r3_soc75_wind_payload": "median 3.04 %: a steady +3 % with the capacity right "
    "(4.01 Ah); not traced yet",
}


def _accuracy_param(name: str) -> Any:
    if name in MISSES:
        return pytest.param(
            name, id=_id(name), marks=pytest.mark.xfail(strict=True, reason=MISSES[name])
        )
    return pytest.param(name, id=_id(name))


@pytest.fixture(scope="module")
def flights() -> dict[str, PackFlight]:
    return {name: replay_pack_flight(FLIGHTS / name, VEHICLE) for name in NAMES}


def _id(name: str) -> str:
    return f"{name}-{'tuning' if name in SPLIT['tuning'] else 'held-out'}"


@pytest.mark.parametrize("name", sorted(UNSCORED))
def test_a_flight_too_short_to_score_has_no_scored_estimate(
    flights: dict[str, PackFlight], name: str
) -> None:
    assert len(flights[name].errors) == 0


@pytest.mark.parametrize("name", SCORED, ids=_id)
def test_no_endurance_is_more_than_3_sigma_above_the_truth(
    flights: dict[str, PackFlight], name: str
) -> None:
    flight = flights[name]
    assert len(flight.z) > 30
    assert np.nanmax(flight.z) <= 3.0


@pytest.mark.parametrize("name", [_accuracy_param(n) for n in SCORED])
def test_endurance_within_3_percent_median_and_8_percent_worst(
    flights: dict[str, PackFlight], name: str
) -> None:
    errors = np.abs(flights[name].errors)
    assert np.median(errors) <= 0.03 and errors.max() <= 0.08, (
        np.median(errors),
        errors.max(),
    )


@pytest.mark.parametrize("name", SCORED, ids=_id)
def test_the_autopilots_own_figures_miss_a_mislabelled_pack(
    flights: dict[str, PackFlight], name: str
) -> None:
    """Where the label is wrong, PX4-style and ArduPilot's own figures (both count against
    the label) are further off than ours at the median."""
    flight = flights[name]
    battery = flight.truth["battery"]
    if battery["capacity_ah"] >= battery["labelled_capacity_ah"]:
        pytest.skip("the label is right")
    ours = np.median(np.abs(flight.errors))
    assert ours < np.nanmedian(np.abs(flight.ardupilot_errors))
    assert ours < np.nanmedian(np.abs(flight.px4_errors))


def test_three_sigma_pooled_over_the_pack_flights_holds_97_percent(
    flights: dict[str, PackFlight],
) -> None:
    z = np.concatenate([flights[n].z for n in SCORED])
    assert np.mean(np.abs(z) <= 3.0) >= 0.97


@pytest.mark.xfail(
    strict=True,
    reason="94 % inside ±1σ: σ too wide on SITL, whose pack has no temperature drift, no "
    "ripple and this exact curve; the filter keeps a real pack's resistance walk and the "
    "model scale's state-change uncertainty",
)
def test_one_sigma_pooled_over_the_pack_flights_holds_55_to_80_percent(
    flights: dict[str, PackFlight],
) -> None:
    z = np.concatenate([flights[n].z for n in SCORED])
    assert 0.55 <= np.mean(np.abs(z) <= 1.0) <= 0.80


def test_the_table_of_docs_pack_md_is_what_the_script_prints(
    flights: dict[str, PackFlight],
) -> None:
    """docs/pack.md's table comes from ``python scripts/pack_state_sitl.py``: a figure that
    drifts fails here."""
    spec = importlib.util.spec_from_file_location("pack_state_sitl", SCRIPT)
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    doc = (ROOT / "docs" / "pack.md").read_text()
    for half in ("tuning", "held_out"):
        for name in SPLIT[half]:
            assert script.table_row(flights[name], half.replace("_", "-")) in doc, name


#: A daemon started mid-flight without a state file: why it does not converge in 60 s.
RESTART_MISS = (
    "under a steady load the start's charge and the resistance are one unknown (30 mΩ "
    "against a 12 ± 12 mΩ prior), and the filter settles on a wrong pair too surely "
    "(pack_c80_r3: −58 % at 9σ; pack_c65_r1: +66 %, the capacity still 4.27 ± 0.71 Ah)"
)


@pytest.mark.parametrize(
    "name",
    [
        pytest.param("pack_c65_r1", marks=pytest.mark.xfail(strict=True, reason=RESTART_MISS)),
        "pack_c100_r1",
        pytest.param("pack_c80_r3", marks=pytest.mark.xfail(strict=True, reason=RESTART_MISS)),
    ],
)
def test_a_daemon_started_mid_flight_without_state_converges_within_60_s(name: str) -> None:
    """The pipeline fed from 90 s after take-off on (as a daemon restarted then, with no
    state file): 60 s later, the endurance within 8 % of the truth and within 3σ."""
    truth = json.loads((FLIGHTS / name / "truth.json").read_text())
    labelled = replace(VEHICLE, battery=replace(VEHICLE.battery, capacity_ah=5.0))
    start_s = truth["events"]["takeoff_s"] + 90.0
    samples = [
        s
        for s in iter_samples(FLIGHTS / name / "flight.tlog", "auto", labelled.input_limits())
        if getattr(s, "time_s", 0.0) >= start_s
    ]
    estimates, _, _ = run(samples, Pipeline(labelled))
    at = min(estimates, key=lambda e: abs(e.time_s - start_s - 60.0))
    left_s = truth["events"]["reserve_s"] - at.time_s
    assert abs(at.endurance_s - left_s) <= 0.08 * left_s
    assert abs(at.endurance_s - left_s) <= 3 * at.endurance_sigma_s
