"""The daemon's online tracker on the ArduCopter SITL recordings of ``replay/sitl`` (wind and
payload known from ``truth.json``), step by step from take-off to landing
(:mod:`estimator.analysis.tracker_truth`, ``scripts/tracker_sitl.py``): the aim of ≥ 90 % of
the steps within 2σ and none beyond 3σ, for the mass and the wind, per flight and pooled, and
the block ``tracker-sitl`` of docs/residuals.md."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from estimator.analysis.sitl_truth import RecordingTruth, load_truth
from estimator.analysis.tracker_truth import TrackerRun
from estimator.errors import UserError
from estimator.reports.doc_blocks import blocks_in

ROOT = Path(__file__).resolve().parent.parent


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "tracker_sitl", ROOT / "scripts" / "tracker_sitl.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SCRIPT = _script()
Flights = list[tuple[RecordingTruth, TrackerRun]]


@pytest.fixture(scope="module")
def flights() -> Flights:
    return SCRIPT.runs()


def _run(flights: Flights, name: str) -> TrackerRun:
    return next(r for _, r in flights if r.name == name)


def _meets_the_aim(runs: list[TrackerRun]) -> bool:
    z = np.vstack([r.z() for r in runs])
    return min(SCRIPT.pooled(runs, 2.0)) >= 0.90 and float(z.max()) <= 3.0


#: The flights the SITL vehicle file was fitted on (the others are held out from the fit; all
#: scenarios, not the missions, are the ones the tracker's settings were tuned on).
FITTED_ON = SCRIPT.FITTED_ON
#: Why each flight misses the aim. Mass: the SITL vehicle file states no slow model error, so
#: the mass's 1σ shrinks to 0.014-0.04 kg while the fitted model reads SITL's mass 0.03-0.13 kg
#: off; and the first step after the airborne gate (the take-off climb's end) and the start of
#: a descent read a mass drop of 0.2-0.5 kg: the power falls as the vehicle accelerates
#: downwards below the 1 m/s vertical gate. Wind (medians from 30 s after take-off): the power
#: channel pulls the wind 2-5 times farther off than the autopilot's WIND it takes, and a
#: change arrives with the EKF's ~10 s lag plus the three-step change test.
SHORT = {
    "clean_circles": "mass 56 % within 2σ (-0.035 kg at 1σ 0.014 kg); first step 5.1σ",
    "clean_legs": "wind 79 % within 2σ (still air read 0.75 m/s off, the autopilot's WIND "
    "0.33 m/s, at 1σ 0.41 m/s); first step's mass 4.6σ",
    "clean_mission": "mass 89 % within 2σ (-0.033 kg at 1σ 0.014 kg); first step 5.1σ",
    "payload_release": "mass 71 % within 2σ (1 kg read 0.05 kg heavy at 1σ 0.017 kg); "
    "wind 79 % (still air read 0.76 m/s off, the autopilot's WIND 0.15 m/s)",
    "payload_takeoff": "mass 31 % within 2σ (1 kg read 0.04 kg heavy at 1σ 0.015 kg); "
    "wind 59 % (still air read 0.92 m/s off, the autopilot's WIND 0.18 m/s)",
    "payload_wind": "wind 11σ after the onset (4.9 m/s off), 1.23 m/s off in the median (the "
    "autopilot's WIND 0.27 m/s); mass 46 % within 2σ (0.05 kg heavy at 1σ 0.019 kg)",
    "wind_constant": "wind 62 % within 2σ (0.83 m/s off, the autopilot's WIND 0.49 m/s, at "
    "1σ 0.40 m/s); first step's mass 4.2σ",
    "wind_onset": "wind 13σ 4 s after the onset (5.5 m/s off); first step's mass 4.9σ",
    "wind_onset_circles": "wind 25 % within 2σ: 29 steps behind the onset, then 1.24 m/s "
    "off (the autopilot's WIND 0.43 m/s) at 1σ 0.35 m/s",
    "wind_stop": "wind 18σ 6 s after the stop (6.6 m/s off); mass 14 steps beyond 2σ after it",
    "wind_turn": "wind 21σ 4 s after the turn (7.9 m/s off), 77 % within 2σ",
    "climbs_wind6": "mass 3 % within 2σ (-0.08 kg at 1σ 0.025 kg); wind 39 % (1.41 m/s off, "
    "the autopilot's WIND 0.60 m/s)",
    "fast_wind3": "mass 82 % within 2σ (-0.07 kg at 1σ 0.023 kg)",
    "outback_wind8": "mass 86 % within 2σ; the landing descent's start read as -0.42 kg (5.5σ)",
    "payload_wind4": "mass 30 % within 2σ (1 kg read 0.05 kg heavy at 1σ 0.017 kg)",
    "release_wind2": "mass 8.5σ for 4 s after the mission's release: an alarm moves 1.06 to "
    "0.51 kg at 1σ 0.060 kg, the next step is gated out, a second alarm reaches 0.03 kg",
    "square_wind5": "mass 71 % within 2σ (-0.036 kg at 1σ 0.017 kg)",
    "tall_wind4": "mass 50 % within 2σ (-0.04 kg at 1σ 0.019 kg); wind 74 %",
    "zigzag_wind7": "mass 85 % within 2σ; the landing descent's start read as -0.48 kg (5.8σ)",
}
SCENARIOS = [
    "clean_circles", "clean_legs", "clean_mission", "payload_release", "payload_takeoff",
    "payload_wind", "wind_constant", "wind_onset", "wind_onset_circles", "wind_stop",
    "wind_turn",
]  # fmt: skip
MISSIONS = [
    "climbs_wind6", "fast_wind3", "loiter_wind1", "outback_wind8", "payload_wind4",
    "release_wind2", "square_wind5", "tall_wind4", "zigzag_wind7",
]  # fmt: skip


def test_every_stock_quad_recording_is_scored_and_the_fit_flights_are_named(
    flights: Flights,
) -> None:
    assert [r.name for _, r in flights] == SCENARIOS + MISSIONS
    assert "replay/sitl/clean_{legs,circles,mission}/flight.tlog" in SCRIPT.VEHICLE.read_text()
    assert [t.scenario for t, _ in flights if SCRIPT.flight_set(t) == "fit"] == list(FITTED_ON)


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(
            n,
            id=f"{n}-{'fit' if n in FITTED_ON else 'held-out'}",
            marks=[pytest.mark.xfail(strict=True, reason=SHORT[n])] if n in SHORT else [],
        )
        for n in SCENARIOS + MISSIONS
    ],
)
def test_the_running_mass_and_wind_hold_90_percent_within_2_sigma_and_3_sigma_always(
    flights: Flights, name: str
) -> None:
    assert _meets_the_aim([_run(flights, name)])


@pytest.mark.xfail(
    strict=True,
    reason="pooled mass 73 % within 2σ, wind 79 %: with no slow model error stated the mass's "
    "1σ shrinks to 0.5 % of the vehicle's and the power pulls the wind off the autopilot's",
)
@pytest.mark.parametrize("group", ["all", "held out"])
def test_pooled_the_steps_hold_90_percent_within_2_sigma_and_3_sigma_always(
    flights: Flights, group: str
) -> None:
    runs = [r for t, r in flights if group == "all" or SCRIPT.flight_set(t) == group]
    assert _meets_the_aim(runs)


def test_told_the_model_error_is_slow_the_mass_holds_its_sigma_and_the_wind_gains() -> None:
    """The cause named for the mass misses: the same flights with ``[model]
    slow_error_fraction = 0.02`` (``scripts/tracker_sitl.py --slow-error-fraction 0.02``) hold
    the mass within 2σ on 99 % of the steps pooled and the wind on 87 % (73 % and 79 % as
    committed); what is left beyond 3σ is the transients above and the wind changes."""
    runs = [r for _, r in SCRIPT.runs(slow_error_fraction=0.02)]
    mass_2, wind_2 = SCRIPT.pooled(runs, 2.0)
    assert mass_2 >= 0.95 and wind_2 >= 0.85


def test_every_flight_ends_with_its_mass_and_wind(flights: Flights) -> None:
    """What the tracker does get right: at the landing the mass is within 0.15 kg and the
    wind within 2 m/s of the truth on every flight (0.13 kg and 1.7 m/s at worst)."""
    for _, run in flights:
        error = run.estimate[-1] - run.truth[-1]
        assert abs(error[2]) <= 0.15 and float(np.hypot(*error[:2])) <= 2.0, run.name


def test_a_release_the_mission_commanded_ends_the_payload_in_the_truth(
    flights: Flights,
) -> None:
    """release_wind2's truth.json holds the load to the landing; the autopilot reported its
    DO_GRIPPER release 47 s after take-off, and the steps across a change are left out."""
    truth = next(t for t, r in flights if r.name == "release_wind2")
    recorded = load_truth(SCRIPT.RECORDINGS / "missions" / "release_wind2" / "truth.json", 3.0)
    assert recorded.payloads[0].end_s - recorded.takeoff_s > 150
    assert 46 < truth.payloads[0].end_s - truth.takeoff_s < 48
    run = _run(flights, "release_wind2")
    assert run.across_changes == 1 and set(run.truth[:, 2]) == {0.0, 1.0}


def test_the_doc_block_is_what_the_script_prints(flights: Flights) -> None:
    """docs/residuals.md's block "tracker-sitl" (``make figures`` writes it)."""
    [block] = [b for b in blocks_in(ROOT / "docs" / "residuals.md") if b.name == "tracker-sitl"]
    assert block.text == SCRIPT.report(flights), "run `make figures` and review the diff"


def test_a_malformed_truth_or_no_recording_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert SCRIPT.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    folder = tmp_path / "forged"
    folder.mkdir()
    good = json.loads((SCRIPT.RECORDINGS / "wind_turn" / "truth.json").read_text())
    for forged in (
        "{not json",
        json.dumps({**good, "events": {}}),
        json.dumps({**good, "effects": [{"effect": "wind", "speed_mps": "fast"}]}),
        json.dumps({**good, "effects": [{**good["effects"][0], "start_s": float("nan")}]}),
    ):
        (folder / "truth.json").write_text(forged)
        with pytest.raises(UserError, match="not a SITL recording's truth"):
            load_truth(folder / "truth.json", 3.0)
        assert SCRIPT.main([str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "forged" in err
