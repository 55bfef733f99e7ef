"""Endurance on packs that are not what their label says: the ArduCopter SITL pack flights of
replay/sitl_packs (a 5.0 Ah label; the real pack 65–100 % of it, 10 or 30 mΩ, 50–100 %
charged at power-up, some with wind and payload) replayed with the LABELLED capacity
(:mod:`estimator.analysis.pack_flights`): scored from 60 s after take-off until 60 s before
the true reserve. Six flights were the tuning half, seven held out (split.json, fixed before
any run), and six more sets held out were recorded after the rules were frozen
(``held_out_2`` at commit 2190ac9, ``held_out_3`` at a8aa701, ``held_out_4`` at 2359ce0,
``held_out_5`` at 37b4158, ``held_out_6`` scored first at 3fd730e, the fourteen flights of
``held_out_7`` at 19b3e8c); ``python
scripts/pack_state_sitl.py`` prints the tables of docs/pack.md, which ``make figures`` writes
there and ``tests/test_figures.py`` checks."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from estimator.analysis.pack_flights import (
    PackFlight,
    Restart,
    replay_pack_flight,
    replay_restarted,
)
from estimator.physics.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
SPLIT = json.loads((FLIGHTS / "split.json").read_text())
VEHICLE = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
#: Flights too short to score: the pack reaches its reserve within 120 s of take-off.
UNSCORED = {"pack_c80_r3_soc50"}
HALVES = tuple(SPLIT)
NAMES = [n for half in HALVES for n in SPLIT[half]]
SCORED = [n for n in NAMES if n not in UNSCORED]


#: Flights that miss 3 % median / 8 % worst, and why.
MISSES = {
    "pack_c90_r1_wind": "worst 9.2 %, median 2.0 % (held-out 4, rescored after a period came "
    "to end with the readings held over its last 50 ms; 7.9 % and 1.6 % before): this "
    "recording's readings sit within 50 ms of the second, so the pack filter takes each "
    "blended with the one before it, and the worst estimate, the same one as before, moved "
    "by 0.3 % (to 8.2 %) with that rule and 1.0 % more since, not traced; why that estimate "
    "is the worst was not traced",
    "pack_c100_r3": "worst 8.6 %, median 2.5 % (held out; 7.9 % and 2.5 % before the SITL "
    "vehicle file stated SITL's vertical power, climb and heave): the worst estimates are "
    "one-period spikes as a leg starts, one of which moved from 7.7 to 8.6 % while another "
    "fell from 7.9 to 7.3 %; the spikes themselves were not traced",
}


def _params(names: Sequence[str], misses: Mapping[str, str]) -> list[Any]:
    """``names`` as test parameters (with their set in the id), each of ``misses`` a strict
    xfail whose reason is the miss's cause."""
    return [
        pytest.param(
            n,
            id=_id(n),
            marks=[pytest.mark.xfail(strict=True, reason=misses[n])] if n in misses else [],
        )
        for n in names
    ]


@pytest.fixture(scope="module")
def flights() -> dict[str, PackFlight]:
    return {name: replay_pack_flight(FLIGHTS / name, VEHICLE) for name in NAMES}


def _half(name: str) -> str:
    return next(half for half in HALVES if name in SPLIT[half])


def _id(name: str) -> str:
    return f"{name}-{_half(name).replace('_', '-')}"


@pytest.mark.parametrize("name", sorted(UNSCORED))
def test_a_flight_too_short_to_score_has_no_scored_estimate(
    flights: dict[str, PackFlight], name: str
) -> None:
    assert len(flights[name].errors) == 0


#: Flights with an endurance more than 3σ above the truth, and why.
OVERCONFIDENT = {
    "pack_c95_r3_wind": "+3.3σ (+5.5 %) from 104 to 122 s after take-off (held-out 6, as "
    "first scored): the 6 m/s wind starts 88 s after take-off; until the online tracker has "
    "learnt it the endurance holds the windless flight's power, and its σ (1.8 %) does not "
    "allow for a change of wind",
}


@pytest.mark.parametrize("name", _params(SCORED, OVERCONFIDENT))
def test_no_endurance_is_more_than_3_sigma_above_the_truth(
    flights: dict[str, PackFlight], name: str
) -> None:
    flight = flights[name]
    assert len(flight.z) >= 20  # a second a score: the shortest scored flight gives 22
    assert np.nanmax(flight.z) <= 3.0


@pytest.mark.parametrize("name", _params(SCORED, MISSES))
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


#: Sets of flights outside 55-80 % within 1σ, and why.
ONE_SIGMA_MISSES = {
    "tuning": "80.3 % within 1σ, at the edge since the readings of a period were held over its "
    "last 50 ms (83 % before, 80 % after) and past it since SITL's vertical power is in its "
    "vehicle file: the errors shrank, the σ (mostly the remaining energy's) did not",
    "held_out_2": "86 % within 1σ, since the endurance follows the pattern as flown: the "
    "leg-to-leg swings it removed were errors the σ had covered; what is left of the σ is "
    "mostly the remaining energy's (the charge from the OCV curve's ±10 mV/cell and the "
    "capacity, 1.3-1.5 % of the energy left), where SITL's curve and current are exact and "
    "the errors left are 0.5-1 %",
    "held_out": "50 % within 1σ: pack_c100_r3's persistent +2.5-4 % (capacity 5.06 ± 0.05 Ah "
    "learnt by 75 s, the truth 5.00) and pack_c65_r1_payload's steady +2.8 % lie outside 1σ",
}


@pytest.mark.parametrize(
    "half",
    [
        pytest.param(
            half,
            marks=[pytest.mark.xfail(strict=True, reason=ONE_SIGMA_MISSES[half])]
            if half in ONE_SIGMA_MISSES
            else [],
        )
        for half in HALVES
    ],
)
def test_one_sigma_pooled_over_each_half_holds_55_to_80_percent(
    flights: dict[str, PackFlight], half: str
) -> None:
    z = np.concatenate([flights[n].z for n in SPLIT[half] if n in SCORED])
    assert 0.55 <= np.mean(np.abs(z) <= 1.0) <= 0.80


@pytest.mark.parametrize("half", HALVES)
def test_three_sigma_pooled_over_each_half_holds_97_percent(
    flights: dict[str, PackFlight], half: str
) -> None:
    z = np.concatenate([flights[n].z for n in SPLIT[half] if n in SCORED])
    assert np.mean(np.abs(z) <= 3.0) >= 0.97


def test_one_sigma_pooled_over_every_pack_flight_holds_55_to_80_percent(
    flights: dict[str, PackFlight],
) -> None:
    z = np.concatenate([flights[n].z for n in SCORED])
    assert 0.55 <= np.mean(np.abs(z) <= 1.0) <= 0.80


#: Tuning flights restarted mid-flight (under load, no state file).
RESTARTED = ("pack_c65_r1", "pack_c100_r1", "pack_c80_r3")


@pytest.fixture(scope="module")
def restarts() -> dict[str, Restart | None]:
    return {name: replay_restarted(FLIGHTS / name, VEHICLE) for name in NAMES}


#: Restarted tuning flights short of 8 % at 60 s, and why.
SLOW_RESTARTS = {
    "pack_c100_r1": "−10.4 % at 60 s, at −0.6σ (−7.6 % before the bank's weights were "
    "tempered): a pack restarted under a steady current, whose charge and capacity separate "
    "only at the first 10 m/s leg",
}


@pytest.mark.parametrize("name", _params(RESTARTED, SLOW_RESTARTS))
def test_a_daemon_started_mid_flight_without_state_converges_within_60_s(
    restarts: dict[str, Restart | None], name: str
) -> None:
    """60 s after a restart 90 s after take-off, the endurance within 8 % of the truth and
    within 3σ."""
    restart = restarts[name]
    assert restart is not None
    assert abs(restart.error_at) <= 0.08 and abs(restart.z_at) <= 3.0


#: Every flight restarted (those whose reserve comes more than 130 s after the restart).
RESTARTED_ALL = (
    *RESTARTED,
    "pack_c100_r1_soc75", "pack_c80_r1_wind", "pack_c80_r1", "pack_c100_r3", "pack_c65_r3",
    "pack_c90_r2", "pack_c70_r1_soc85", "pack_c90_r3_wind", "pack_c100_r2_payload",
    "pack_c80_r2_soc85_wind", "pack_c75_r4", "pack_c85_r1_soc90", "pack_c75_r2_wind",
    "pack_c60_r1", "pack_c90_r1_wind", "pack_c70_r2_wind", "pack_c100_r3_soc80_wind",
    "pack_c65_r2", "pack_c75_r3_soc90_wind", "pack_c65_r3_wind", "pack_c85_r2_wind",
    "pack_c90_r1_soc75_wind", "pack_c75_r2_soc85", "pack_c100_r1_wind_payload", "pack_c60_r2",
    "pack_c70_r1_wind", "pack_c95_r3_wind", "pack_c80_r1_soc80", "pack_c65_r2_soc90_wind",
    "pack_c90_r2_payload", "pack_c100_r2_soc70_wind", "pack_c75_r1_wind",
    "pack_c80_r1_soc75_wind", "pack_c80_r3_wind", "pack_c95_r1_wind_payload", "pack_c85_r2_soc90",
    "pack_c100_r1_soc75_wind", "pack_c65_r2_wind", "pack_c80_r2_wind_payload",
    "pack_c100_r3_soc75_wind", "pack_c70_r1_soc90", "pack_c75_r3_wind",
)  # fmt: skip
#: Restarted flights surer than right, and why.
OVERCONFIDENT_RESTARTS = {
    "pack_c65_r2_wind": "held-out 7, as first scored: −15 % at −3.0σ (3.15σ at worst) 85-115 s "
    "after the restart, on the safe side: in its 6 m/s wind the bank's weight settles on a "
    "start at 14 mΩ (truth 20) with 3.63 ± 0.13 Ah (3.25), holding 8.2 ± 0.6 Wh to the "
    "reserve where the uninterrupted replay holds 10.2",
}


@pytest.mark.parametrize("name", _params(RESTARTED_ALL, OVERCONFIDENT_RESTARTS))
def test_a_daemon_started_mid_flight_is_never_surer_than_it_is_right(
    restarts: dict[str, Restart | None], name: str
) -> None:
    """From 10 s after the restart until 60 s before the reserve, the truth is inside 3σ of
    every endurance (one filter started under load was 9σ off: pack_c80_r3, −58 %)."""
    restart = restarts[name]
    assert restart is not None and restart.scored > 30
    assert restart.worst_abs_z <= 3.0


def test_every_flight_long_enough_after_a_restart_is_judged(
    restarts: dict[str, Restart | None],
) -> None:
    assert sorted(n for n, r in restarts.items() if r is not None) == sorted(RESTARTED_ALL)
