"""``uav-energy residuals`` on the ArduCopter SITL recordings, scored against their truth.

SITL's physics is not the model's (current linear in thrust, no translational lift, wind as
drag on the airframe), so these flights test the residual analysis on physics the project did
not write. The vehicle file is the one fitted to SITL's clean flights, with its acceleration
effect. Every flight whose first named effect is right stays right; the flights it gets wrong
today are strict expected failures, each with its cause (docs/residuals.md, "ArduPilot SITL").
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest
from script_loader import load_script

from estimator.analysis.slow_error import slow_error_fraction
from estimator.logs import iter_samples
from estimator.physics.vehicle import Vehicle, load_vehicle
from estimator.sitl.truth_check import (
    FlightScore,
    FlightTruth,
    RecordingCheck,
    score_recording,
    score_summary,
)
from estimator.telemetry.samples import GripperSample

REPO = Path(__file__).resolve().parent.parent
RECORDINGS = REPO / "replay" / "sitl"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
THIS_FILE = "tests/test_sitl_effects.py"
#: Flown for the endurance to the reserve, not for effects; AUTO missions (their own test).
NOT_SCORED = {"battery_reserve", "missions"}
KNOWN_WRONG = {
    "heavy_quad": "SITL scales the whole hover current with mass; the model's mass law scales "
    "the induced part only, so +1 kg reads as +1.64 kg",
}
SCENARIOS = sorted(p.name for p in RECORDINGS.iterdir() if p.is_dir() and p.name not in NOT_SCORED)


@cache
def sitl_vehicle() -> Vehicle:
    return load_vehicle(VEHICLE)


@cache
def checked(scenario: str) -> RecordingCheck:
    return score_recording(RECORDINGS / scenario, sitl_vehicle())


def scored(scenario: str) -> FlightScore:
    return checked(scenario).score


def test_enough_recordings_of_each_kind_are_scored() -> None:
    kinds = {s: {e.kind for e in scored(s).truth.effects} for s in SCENARIOS}
    assert len(SCENARIOS) >= 12
    assert sum(not k for k in kinds.values()) >= 3  # clean flights
    assert sum("wind" in k for k in kinds.values()) >= 4
    assert sum("payload" in k for k in kinds.values()) >= 3


@pytest.mark.parametrize(
    "scenario",
    [
        pytest.param(s, marks=pytest.mark.xfail(reason=KNOWN_WRONG[s], strict=True))
        if s in KNOWN_WRONG
        else s
        for s in SCENARIOS
    ],
)
def test_the_first_named_effect_is_the_true_one(scenario: str) -> None:
    score = scored(scenario)
    named = [(m.label, m.params, m.misses) for m in score.matches]
    assert score.first_right, named


def test_clean_flights_name_nothing() -> None:
    clean = [s for s in SCENARIOS if not scored(s).truth.effects]
    assert clean
    for scenario in clean:
        assert not scored(scenario).matches, scenario


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_the_held_out_error_ends_within_twice_the_noise_floor(scenario: str) -> None:
    score = scored(scenario)
    assert score.rmse_to_floor <= 2.0, [(m.label, m.params) for m in score.matches]


def test_the_vehicle_files_slow_error_is_the_one_its_fit_flights_show() -> None:
    """``[model] slow_error_fraction`` of the SITL vehicle file: the 1σ of the residual's 10 s
    means on the three clean flights it was fitted on, over its hover power, to 0.001."""
    vehicle = sitl_vehicle()
    flights = []
    for name in ("clean_legs", "clean_circles", "clean_mission"):
        result = checked(name).result
        assert not result.selected  # the vehicle file describes them: nothing to add
        residual_w = result.samples.power_w - result.predicted_final_w
        flights.append((result.samples.state.time_s, residual_w))
    measured = slow_error_fraction(flights, vehicle.model.hover_power_w)
    assert vehicle.slow_error_fraction == pytest.approx(measured, abs=0.0005)


def test_the_docs_give_the_results_as_measured() -> None:
    """The SITL effect blocks of README.md and docs/residuals.md are what these recordings
    give now (``scripts/figures.py`` writes them: ``make figures``)."""
    figures = load_script("figures")
    assert figures.sitl.effect_scenarios() == SCENARIOS
    checks = {s: checked(s) for s in SCENARIOS}
    now = {
        "sitl-effects-table": figures.sitl.effects_table(checks),
        "sitl-effects-right": figures.sitl.effects_right(checks),
        "sitl-effects-floors": figures.sitl.effects_floors(checks),
        "sitl-effects-clean": figures.sitl.effects_clean(checks),
        "sitl-effects-wind": figures.sitl.effects_wind(checks),
        "sitl-effects-payload": figures.sitl.effects_payload(checks),
        "sitl-effects-turn": figures.sitl.effects_turn(checks),
        "sitl-effects-heavy": figures.sitl.effects_heavy(checks),
        "sitl-effects-onset-circles": figures.sitl.effects_onset_circles(checks),
    }
    assert set(now) == {n for n, test in figures.CHECKED_BY.items() if test == THIS_FILE}
    blocks = [b for b in figures.all_blocks() if b.name in now]
    assert {b.name for b in blocks} == set(now)
    stale = [b.name for b in blocks if b.text != now[b.name]]
    assert not stale, f"{stale}: run `make figures` and review the diff"


def test_a_release_is_timed_by_the_autopilots_gripper_report() -> None:
    """payload_release: the release sits inside a held-out chunk, where the training data
    cannot place a step; ArduPilot's "Gripper load released" text places it (tlog and
    DataFlash alike)."""
    folder = RECORDINGS / "payload_release"
    reports = {
        log: [s.time_s for s in iter_samples(folder / log) if isinstance(s, GripperSample)]
        for log in ("flight.tlog", "flight.BIN")
    }
    assert len(reports["flight.tlog"]) == len(reports["flight.BIN"]) == 1
    assert reports["flight.tlog"][0] == pytest.approx(reports["flight.BIN"][0], abs=0.1)
    first = scored("payload_release").matches[0]
    assert first.label == "mass (gripper)"
    assert first.params["until_s"] == pytest.approx(reports["flight.tlog"][0], abs=1.0)


def test_the_scorer_rejects_a_wrong_value_time_or_kind(tmp_path: Path) -> None:
    (tmp_path / "truth.json").write_text(
        '{"scenario": "t", "mass_kg": 3.0, "events": {"takeoff_s": 50, "landed_s": 300},'
        ' "effects": [{"effect": "wind", "speed_mps": 6, "from_deg": 350,'
        ' "start_s": 150, "end_s": 400}]}'
    )
    truth = FlightTruth.load(tmp_path / "truth.json", vehicle_mass_kg=3.0)

    def first(name: str, **params: object) -> FlightScore:
        summary = {"effects": [{"name": name, "params": params}]}
        return score_summary(
            truth, summary | {"rmse_before_w": 9, "rmse_after_w": 4, "noise_floor_w": 3}
        )

    assert first("wind", speed_mps=5.2, from_deg=10.0, at_s=155.0, until_s=None).first_right
    assert not first("wind", speed_mps=4.0, from_deg=10.0, at_s=155.0, until_s=None).first_right
    assert not first("wind", speed_mps=6.0, from_deg=30.0, at_s=155.0, until_s=None).first_right
    assert not first("wind", speed_mps=6.0, from_deg=350.0, at_s=None, until_s=None).first_right
    assert not first("mass", delta_kg=0.5, at_s=None, until_s=None).first_right


def test_a_heavier_vehicle_than_the_file_is_a_payload_all_flight(tmp_path: Path) -> None:
    (tmp_path / "truth.json").write_text(
        '{"scenario": "t", "mass_kg": 4.0, "events": {"takeoff_s": 50, "landed_s": 300},'
        ' "effects": []}'
    )
    truth = FlightTruth.load(tmp_path / "truth.json", vehicle_mass_kg=3.0)
    nothing = score_summary(
        truth, {"effects": [], "rmse_before_w": 1, "rmse_after_w": 1, "noise_floor_w": 1}
    )
    assert not nothing.first_right
    mass = {"name": "mass", "params": {"delta_kg": 1.1, "at_s": None, "until_s": None}}
    assert score_summary(
        truth, {"effects": [mass], "rmse_before_w": 1, "rmse_after_w": 1, "noise_floor_w": 1}
    ).first_right
