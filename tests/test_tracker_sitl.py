"""The daemon's online tracker on the ArduCopter SITL recordings of ``replay/sitl`` (wind and
payload known from ``truth.json``), step by step from take-off to landing
(:mod:`estimator.analysis.tracker_truth`, ``scripts/tracker_sitl.py``): the aim of ≥ 90 % of
the steps within 2σ and none beyond 3σ, for the mass and the wind, per flight and pooled, and
the block ``tracker-sitl`` of docs/residuals.md."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from script_loader import load_script

from estimator.analysis.sitl_truth import RecordingTruth, load_truth
from estimator.analysis.tracker_truth import TrackerRun
from estimator.errors import UserError
from estimator.reports.doc_blocks import blocks_in

ROOT = Path(__file__).resolve().parent.parent


SCRIPT = load_script("tracker_sitl")
Flights = list[tuple[RecordingTruth, TrackerRun]]


@pytest.fixture(scope="module")
def flights() -> Flights:
    return SCRIPT.runs()


def _run(flights: Flights, name: str) -> TrackerRun:
    return next(r for _, r in flights if r.name == name)


#: The flights the SITL vehicle file was fitted on (the others are held out from the fit; all
#: scenarios, not the missions, are the ones the tracker's settings were tuned on).
FITTED_ON = SCRIPT.FITTED_ON
#: Every flight meets the aim. With SITL's vertical power in the vehicle file (``climb`` and
#: ``heave``) and readings in vertical acceleration left out, the take-off climb's end and the
#: landing no longer read as a mass drop; with the model's form in the reported 1σ
#: (``OnlineSettings.mass_form_sigma_fraction``, ``wind_form_sigma_mps``) a payload read a few
#: percent heavy and a still air read as 1 m/s of wind lie within it; with the P(V) shape's error
#: carried as a consider term (``estimation/form_error.py``) most flights without a payload,
#: read 0.03-0.05 kg light when flown fast, do too; a step the gate refused is reported with a
#: changed state's 1σ until the next step tells an outlier from a change (release_wind2's
#: release in hover, 18.3σ before); a mass learnt in a hover in a wind not yet known carries that
#: wind's uncertainty (``estimation/reported_sigma.py``: lean2_clean_diag7, outback_wind8 and
#: rtl_cross_wind7, 2.5-5.3σ at most before); and the autopilot report's lag term, measured at
#: every report, widens the wind's 1σ from the first report that moves after a change
#: (``AutopilotWind.lag_mps``: wind_stop and wind_turn, 4.8σ and 3.9σ before).
SCENARIOS = [
    "clean_circles", "clean_legs", "clean_mission", "payload_release", "payload_takeoff",
    "payload_wind", "wind_constant", "wind_onset", "wind_onset_circles", "wind_stop",
    "wind_turn",
]  # fmt: skip
MISSIONS = [
    "climbs_wind6", "fast_wind3", "lean2_clean_diag7", "lean2_payload_back4",
    "lean2_payload_climb3", "lean2_payload_cross5", "lean2_payload_headwind6", "loiter_wind1",
    "outback_wind8", "payload_wind4", "release_wind2", "rtl_back_wind3", "rtl_climb_wind2",
    "rtl_cross_wind7", "rtl_diag_wind6", "rtl_payload_wind4", "rtl_side_wind5", "square_wind5",
    "tall_wind4", "zigzag_wind7",
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
        pytest.param(n, id=f"{n}-{'fit' if n in FITTED_ON else 'held-out'}")
        for n in SCENARIOS + MISSIONS
    ],
)
def test_the_running_mass_and_wind_hold_90_percent_within_2_sigma_and_3_sigma_always(
    flights: Flights, name: str
) -> None:
    assert SCRIPT.meets_aim([_run(flights, name)])


@pytest.mark.parametrize("group", ["all", "held out"])
def test_pooled_the_steps_hold_90_percent_within_2_sigma_and_3_sigma_always(
    flights: Flights, group: str
) -> None:
    runs = [r for t, r in flights if group == "all" or SCRIPT.flight_set(t) == group]
    assert SCRIPT.meets_aim(runs)


def test_the_mass_sigma_is_not_too_wide_either(flights: Flights) -> None:
    """Two-sided, pooled over the steps: the mass lies within 1σ on 60-80 % of them (68 % for
    a right 1σ; 69 % measured), so the 3σ aim is not bought with a 1σ too wide."""
    assert 0.60 <= SCRIPT.pooled([r for _, r in flights], 1.0)[0] <= 0.80


@pytest.mark.xfail(
    strict=True,
    reason="the wind's 1σ is about twice too wide in the bulk: both components within 1σ on "
    "92 % of the steps, against 47 % for a right 1σ. The filter's own 1σ (about 0.5 m/s, its "
    "random walk kept for changes) and the model form's 0.5 m/s add to about 0.7 m/s where "
    "the error is about 0.35 m/s; narrowed uniformly (× 0.9, on all 163 SITL flights) it "
    "met the tracker aim on 10 fewer flights; the report's lag to both components (de19c8e) "
    "widened it further (85 → 89 %) and met the aim on 12 more of 165",
)
def test_the_wind_sigma_is_not_too_wide_either(flights: Flights) -> None:
    """Two-sided, pooled over the steps: both wind components lie within 1σ on 35-60 % of
    them (47 % for a right 1σ, the two independent)."""
    assert 0.35 <= SCRIPT.pooled([r for _, r in flights], 1.0)[1] <= 0.60


def test_told_the_model_error_is_slow_the_mass_holds_its_sigma_and_the_wind_gains() -> None:
    """The cause named for the mass misses left (no payload, read 0.04 kg light): the same
    flights with ``[model] slow_error_fraction = 0.02`` (``scripts/tracker_sitl.py
    --slow-error-fraction 0.02``) hold the mass within 2σ on 100 % of the steps pooled and the
    wind on 96 % (96 % and 95 % with the 0.6 % the file states, measured on its fit flights:
    the slow error that would cover these flights is not the one the fit flights show); what
    is left beyond 3σ is the wind changes."""
    flights = SCRIPT.runs(slow_error_fraction=0.02)
    mass_2, wind_2 = SCRIPT.pooled([r for _, r in flights], 2.0)
    assert mass_2 >= 0.99 and wind_2 >= 0.95
    # docs/residuals.md gives these shares (``make figures`` writes the block)
    assert _block("tracker-sitl-slow-2pct") == SCRIPT.slow_error_share(flights)


def test_every_flight_ends_with_its_mass_and_wind(flights: Flights) -> None:
    """What the tracker does get right: at the landing the mass is within 0.15 kg and the
    wind within 2 m/s of the truth on every flight (0.11 kg and 1.6 m/s at worst)."""
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


def _block(name: str) -> str:
    """The text of docs/residuals.md's block ``name``."""
    [block] = [b for b in blocks_in(ROOT / "docs" / "residuals.md") if b.name == name]
    return block.text


def test_the_doc_blocks_are_what_the_script_prints(flights: Flights) -> None:
    """docs/residuals.md's blocks "tracker-sitl" and "tracker-sitl-shows" (``make figures``
    writes them)."""
    assert _block("tracker-sitl") == SCRIPT.report(flights), "run `make figures`"
    assert _block("tracker-sitl-shows") == SCRIPT.shows(flights), "run `make figures`"
    assert _block("tracker-sitl-blind") == SCRIPT.blind(flights), "run `make figures`"


def test_a_step_beyond_3_sigma_is_blind_only_while_neither_the_readings_nor_the_report_told() -> (
    None
):
    """Six steps, one truth change after the third; the mass beyond 3σ on the first two
    (the readings 1σ and 1.5σ apart: ½(1 + 2.25) = 1.6 nats), the wind on the last three
    (0.5σ each: 0.4 nats by the fifth step; the report 3 m/s off, then 1 m/s)."""
    truth = np.array([[0.0, 0.0, 0.0]] * 3 + [[5.0, 0.0, 0.0]] * 3)
    estimate = truth.copy()
    estimate[:2, 2] = 0.5
    estimate[3:, 0] = 0.0
    sigma = np.full((6, 3), 0.1)
    sigma[:, :2] = 1.0
    told = np.array([[1.0, 0.5], [1.5, 0.5], [0.2, 0.5], [0.5, 3.0], [0.5, 3.0], [0.5, 1.0]])
    run = TrackerRun("synthetic", np.arange(6.0), estimate, sigma, truth, np.ones(6, bool), 0, told)
    assert SCRIPT.blind_steps(run).tolist() == [True, True, False, True, True, False]
    told[1, 0] = 2.0  # ½(1 + 4) = 2.5 nats by the second step
    assert SCRIPT.blind_steps(run).tolist() == [True, False, False, True, True, False]


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
