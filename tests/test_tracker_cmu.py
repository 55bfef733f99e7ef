"""The daemon's online tracker on the CMU M100 flights (payload and anemometer known), step by
step over each whole airborne flight (:mod:`estimator.analysis.tracker_truth`,
``scripts/tracker_cmu.py``): with the vehicle file's slow model error it is not confidently
wrong where, with the model's errors taken as white, it was."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from script_loader import load_script

from estimator.analysis.tracker_truth import TrackerRun
from estimator.commands.residuals import online_summary
from estimator.logs import cmu
from estimator.physics.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "cmu_m100_subset"
pytestmark = pytest.mark.needs(DATA.is_dir(), "the CMU M100 flights (../shared/data)")


SCRIPT = load_script("tracker_cmu")


@pytest.fixture(scope="module")
def runs() -> tuple[list[TrackerRun], list[TrackerRun]]:
    return SCRIPT.both(DATA)


def test_with_the_slow_error_the_mass_is_within_2_sigma_for_90_percent_of_the_steps(
    runs: tuple[list[TrackerRun], list[TrackerRun]],
) -> None:
    with_error, white = runs
    mass_2, _ = SCRIPT.pooled(with_error, 2.0)
    mass_3, wind_3 = SCRIPT.pooled(with_error, 3.0)
    assert mass_2 >= 0.90 and mass_3 >= 0.97 and wind_3 >= 0.97
    # the same filter taking the model's errors as white is confidently wrong: one step in
    # seven or more beyond 3σ (86 %, docs/residuals.md), against 0.3 % for a right 1σ
    assert SCRIPT.pooled(white, 3.0)[0] < 0.90


def test_with_the_slow_error_every_flight_ends_with_its_payload_within_2_sigma(
    runs: tuple[list[TrackerRun], list[TrackerRun]],
) -> None:
    for run in runs[0]:
        assert run.z()[-1, 2] <= 2.0, run.name


def test_no_flight_is_more_than_6_sigma_off_at_any_step(
    runs: tuple[list[TrackerRun], list[TrackerRun]],
) -> None:
    worst = max(float(run.z().max()) for run in runs[0])
    assert worst <= 6.0
    assert max(float(run.z().max()) for run in runs[1]) > 2 * worst


#: Flights short of the aim for the live tracker (≥ 90 % of the steps within 2σ, none beyond
#: 3σ, for the mass and for the wind), and why.
SHORT = {
    "cmu-269": "wind 48 % within 2σ: its north component read 3 m/s off (−1.3 against +1.7 m/s "
    "at 1σ 1.2) over the first legs, 42–94 s",
    "cmu-270": "wind 37 % within 2σ, 3.3σ at worst: its east component read with the wrong sign "
    "(+2.3 against −3.7 m/s) from the first turnaround on",
    "cmu-273": "wind 87 % within 2σ: its north component read 4 m/s low on the last legs",
}
FLIGHTS = [f"cmu-{n}" for n in (268, 269, 270, 271, 272, 273, 276, 277)]


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=SHORT[n])) if n in SHORT else n
        for n in FLIGHTS
    ],
)
def test_the_running_mass_and_wind_hold_90_percent_within_2_sigma_and_3_sigma_always(
    runs: tuple[list[TrackerRun], list[TrackerRun]], name: str
) -> None:
    run = next(r for r in runs[0] if r.name == name)
    assert min(run.within(2.0)) >= 0.90
    assert float(np.max(run.z())) <= 3.0


def test_the_mass_sigma_is_not_too_wide_either(
    runs: tuple[list[TrackerRun], list[TrackerRun]],
) -> None:
    """Two-sided: pooled over the flights' steps, the mass lies within 1σ for 55-80 % of
    them (59 % measured), so the slow error does not buy its coverage with a σ too wide."""
    assert 0.55 <= SCRIPT.pooled(runs[0], 1.0)[0] <= 0.80


def test_residuals_online_ends_where_the_daemons_tracker_ends(
    runs: tuple[list[TrackerRun], list[TrackerRun]],
) -> None:
    """``uav-energy residuals --online`` runs the daemon's pipeline over each flight's rows:
    its final wind and mass are the last step of the table's runs (the tracker alone, stepped
    on every reading, ended flight 273 at −1.64 kg and 11.6 m/s where these end at +0.08 kg)."""
    vehicle = load_vehicle(SCRIPT.VEHICLE)
    flights = cmu.load_flights(sorted(DATA.glob("*.csv")))
    online = {o["flight"]: o for o in online_summary(flights, vehicle)}
    for run in runs[0]:
        wind_n, wind_e, mass_kg = run.estimate[-1]
        got = online[run.name]
        assert got["mass_delta_kg"] == pytest.approx(mass_kg, abs=1e-3), run.name
        assert got["mass_sigma_kg"] == pytest.approx(run.sigma[-1, 2], abs=1e-3), run.name
        assert got["wind_speed_mps"] == pytest.approx(np.hypot(wind_n, wind_e), abs=1e-2)
