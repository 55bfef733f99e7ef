"""Replay regression: the real IRIS+ flights in replay/ give the frozen figures of expected.json.

Regenerate after an intended pipeline change (then review the diff):
``UAV_ENERGY_UPDATE_EXPECTED=1 .venv/bin/pytest -q tests/test_replay_regression.py``.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pytest

from estimator.analysis.replay import FlightReplay, replay_log, summarize
from estimator.physics.vehicle import load_vehicle

REPLAY_DIR = Path(__file__).resolve().parent.parent / "replay"
EXPECTED = REPLAY_DIR / "expected.json"
VEHICLE = REPLAY_DIR / "vehicle.toml"
LOGS = sorted((REPLAY_DIR / "iris").rglob("*.log"))
#: Relative tolerance: the replay is deterministic; this only absorbs floating-point noise
#: across machines and library versions.
REL_TOL = 1e-6


def figures(flight: FlightReplay) -> dict[str, Any]:
    """The frozen figures of one flight: its summary and its last estimate."""
    out: dict[str, Any] = dict(summarize([flight]).as_dict())
    out["estimates"] = len(flight.estimates)
    if flight.estimates:
        last = flight.estimates[-1]
        for name in ("time_s", "energy_remaining_wh", "endurance_s", "bias"):
            out[f"last_{name}"] = getattr(last, name)
    return out


def _replay_all() -> dict[str, dict[str, Any]]:
    vehicle = load_vehicle(VEHICLE)
    return {str(p.relative_to(REPLAY_DIR)): figures(replay_log(p, vehicle)) for p in LOGS}


@pytest.mark.skipif(
    os.environ.get("UAV_ENERGY_UPDATE_EXPECTED") != "1", reason="regeneration not asked for"
)
def test_regenerate_expected_figures() -> None:
    EXPECTED.write_text(
        json.dumps(
            {
                "vehicle": str(VEHICLE.relative_to(REPLAY_DIR)),
                "command": "UAV_ENERGY_UPDATE_EXPECTED=1 pytest tests/test_replay_regression.py",
                "flights": _replay_all(),
            },
            indent=2,
        )
        + "\n"
    )


def test_replay_dir_holds_the_flights_listed_in_expected() -> None:
    expected = json.loads(EXPECTED.read_text())
    assert LOGS, "no logs under replay/iris"
    assert sorted(expected["flights"]) == [str(p.relative_to(REPLAY_DIR)) for p in LOGS]


def test_replayed_flights_match_the_frozen_figures() -> None:
    expected = json.loads(EXPECTED.read_text())["flights"]
    actual = _replay_all()
    for flight, want in expected.items():
        got = actual[flight]
        assert sorted(got) == sorted(want), flight
        for key, value in want.items():
            if value is None or isinstance(value, int):
                assert got[key] == value, f"{flight} {key}"
            else:
                assert math.isclose(got[key], value, rel_tol=REL_TOL, abs_tol=1e-9), (
                    f"{flight} {key}: {got[key]} != {value}"
                )


def test_flying_flights_have_power_error_and_the_ground_only_one_has_none() -> None:
    expected = json.loads(EXPECTED.read_text())["flights"]
    for flight, want in expected.items():
        if "009.2" in flight:
            assert want["power_points"] == 0 and want["power_rmse_w"] is None
        else:
            assert want["power_points"] > 30 and want["power_rmse_w"] > 0


@pytest.mark.parametrize("flight", ["2016-08-03/002/002.log", "2016-08-09/003/003.log"])
def test_the_fitted_vehicle_follows_the_measured_power_of_its_own_period(flight: str) -> None:
    """The June–August IRIS+ model on August flights: about 12–16 W RMSE (MAPE 5–6 %) when
    frozen; anything far above means the pipeline's model power went wrong."""
    summary = summarize([replay_log(REPLAY_DIR / "iris" / flight, load_vehicle(VEHICLE))])
    assert summary.power_rmse_w is not None and summary.power_rmse_w < 25.0
    assert summary.energy_predicted_wh == pytest.approx(summary.energy_measured_wh, rel=0.1)
