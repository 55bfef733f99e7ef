"""The SITL pack recordings (``replay/sitl_packs/<scenario>/``, made by ``uav-energy
sitl-record packs`` to ``packs5``): packs labelled 5.0 Ah that
really hold less, with more resistance or partly charged at power-up, flown to their true
20 % reserve.
Each truth's pack agrees with its scenario and with the tlog (read as a replay reads it),
and the tuning / held-out split is fixed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from estimator.logs import iter_samples
from estimator.sitl.pack import CELLS, cell_voltage_v, pack_voltage_v, resting_cell_voltage_v
from estimator.sitl.scenarios import PACK_SETS, Grip, SetWind
from estimator.telemetry.samples import BatterySample

REPO = Path(__file__).resolve().parent.parent
RECORDINGS = REPO / "replay/sitl_packs"
SCENARIOS = {name: s for pack_set in PACK_SETS.values() for name, s in pack_set.items()}
NAMES = sorted(SCENARIOS)
#: What the recordings may weigh together (they are committed), bytes.
MAX_TOTAL_BYTES = 48 * 2**20
#: The first ground voltage against SITL's table at the start charge (V per cell).
START_CELL_TOL_V = 0.05
#: The reserve's voltage against SITL's table at 20 % minus I·R (V per cell: the filter's lag).
RESERVE_CELL_TOL_V = 0.05


def _truth(name: str) -> dict:
    return json.loads((RECORDINGS / name / "truth.json").read_text())


def _battery_samples(name: str) -> list[BatterySample]:
    samples = iter_samples(RECORDINGS / name / "flight.tlog")
    return [s for s in samples if isinstance(s, BatterySample)]


def test_every_pack_scenario_is_recorded_split_once_and_small() -> None:
    recorded = sorted(p.name for p in RECORDINGS.iterdir() if p.is_dir())
    assert recorded == NAMES and len(NAMES) >= 20
    split = json.loads((RECORDINGS / "split.json").read_text())
    held_out_sets = [f"held_out_{i}" for i in range(2, len(PACK_SETS) + 1)]
    assert list(split) == ["tuning", "held_out", *held_out_sets]
    assert sorted(n for half in split.values() for n in half) == NAMES  # each in one half
    for half, pack_set in zip(held_out_sets, list(PACK_SETS.values())[1:], strict=True):
        assert sorted(split[half]) == sorted(pack_set)
    source = (RECORDINGS / "SOURCE.md").read_text()
    assert all(f"sitl-record {name} " in source for name in NAMES)
    total = sum(f.stat().st_size for f in RECORDINGS.rglob("*") if f.is_file())
    assert total <= MAX_TOTAL_BYTES
    assert not list(RECORDINGS.rglob("*.BIN"))


@pytest.mark.parametrize("name", NAMES)
def test_truth_holds_the_scenario_pack_and_flight(name: str) -> None:
    truth, scenario = _truth(name), SCENARIOS[name]
    battery, model = truth["battery"], scenario.model_json or {}
    assert battery["drains"] and battery["cells"] == CELLS
    assert battery["capacity_ah"] == model["battCapacityAh"]
    assert battery["internal_resistance_ohm"] == model["refBatRes"]
    assert battery["labelled_capacity_ah"] == 5.0 == truth["params"]["BATT_CAPACITY"] / 1000
    assert battery["start_voltage_v"] == truth["params"]["SIM_BATT_VOLTAGE"]
    assert 0.45 <= battery["start_soc"] <= 1.0
    ev = truth["events"]
    assert ev["armed_s"] <= ev["takeoff_s"] < ev["reserve_s"] < ev["landed_s"] <= ev["disarmed_s"]
    assert ev["landed_s"] - ev["reserve_s"] < 60.0  # LAND from 20 m
    winds = [(e["speed_mps"], e["from_deg"]) for e in truth["effects"] if e["effect"] == "wind"]
    set_winds = [(s.speed_mps, s.from_deg) for s in scenario.steps if isinstance(s, SetWind)]
    assert winds == set_winds
    payloads = [e for e in truth["effects"] if e["effect"] == "payload"]
    assert len(payloads) == int(any(isinstance(s, Grip) for s in scenario.steps))
    for p in payloads:  # weighs from 2 m up: just after take-off, until the landing
        assert p["start_s"] - ev["takeoff_s"] < 5.0 and p["end_s"] >= ev["reserve_s"]


@pytest.mark.parametrize("name", NAMES)
def test_tlog_starts_at_the_true_charge_and_reaches_the_true_reserve(name: str) -> None:
    """On the ground at power-up: SITL's table voltage at the start charge, nothing consumed
    yet; at the reserve: (start charge − 20 %) × true capacity consumed, and the table's 20 %
    voltage less current × resistance."""
    truth = _truth(name)
    battery, ev = truth["battery"], truth["events"]
    samples = _battery_samples(name)
    first = samples[0]
    assert first.time_s < ev["armed_s"]
    expected_cell_v = resting_cell_voltage_v(battery["start_soc"])
    assert abs(cell_voltage_v(first.voltage_v) - expected_cell_v) <= START_CELL_TOL_V
    counted = [s for s in samples if s.consumed_mah is not None]
    assert counted[0].consumed_mah == 0.0 and counted[0].time_s < ev["armed_s"]

    reserve_mah = 1000 * (battery["start_soc"] - 0.2) * battery["capacity_ah"]
    assert battery["reserve_consumed_mah"] == pytest.approx(reserve_mah, abs=10.0)
    at_reserve = min(counted, key=lambda s: abs(s.time_s - ev["reserve_s"]))
    assert at_reserve.consumed_mah == pytest.approx(battery["reserve_consumed_mah"], abs=10.0)
    assert at_reserve.current_a is not None
    sag_v = at_reserve.current_a * battery["internal_resistance_ohm"]
    expected_v = pack_voltage_v(resting_cell_voltage_v(0.2)) - sag_v
    assert abs(at_reserve.voltage_v - expected_v) / CELLS <= RESERVE_CELL_TOL_V
