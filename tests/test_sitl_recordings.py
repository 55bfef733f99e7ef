"""The committed ArduCopter SITL recordings (``replay/sitl/<scenario>/``, made by
``uav-energy sitl-record all``): one per scenario, each with a truth that matches its flight,
and every tlog and DataFlash log replays. Also the command's answers to user mistakes."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from types import SimpleNamespace

import pytest
from pymavlink.dialects.v20 import common as mavlink
from script_loader import load_script

from estimator.analysis.replay import FlightReplay, replay_log, summarize
from estimator.cli import main
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.pilot import State
from estimator.sitl.recorder import Flight, Truth
from estimator.sitl.scenarios import SCENARIOS, Grip, SetWind

REPO = Path(__file__).resolve().parent.parent
RECORDINGS = REPO / "replay/sitl"
VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
THIS_FILE = "tests/test_sitl_recordings.py"
#: What the recordings may weigh together (they are committed), bytes.
MAX_TOTAL_BYTES = 25 * 2**20


def _truth(name: str) -> dict:
    return json.loads((RECORDINGS / name / "truth.json").read_text())


def test_every_scenario_is_recorded_and_the_recordings_stay_small() -> None:
    scenarios = [p.name for p in RECORDINGS.iterdir() if p.is_dir() and p.name != "missions"]
    assert sorted(scenarios) == sorted(SCENARIOS)
    total = sum(f.stat().st_size for f in RECORDINGS.rglob("*") if f.is_file())
    assert total <= MAX_TOTAL_BYTES
    with_dataflash = [s for s in SCENARIOS if (RECORDINGS / s / "flight.BIN").is_file()]
    assert len(with_dataflash) >= 2
    assert with_dataflash == [s.name for s in SCENARIOS.values() if s.dataflash]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_truth_names_the_effects_of_the_scenario_within_the_flight(name: str) -> None:
    truth, scenario = _truth(name), SCENARIOS[name]
    ev = truth["events"]
    assert ev["armed_s"] <= ev["takeoff_s"] < ev["landed_s"] <= ev["disarmed_s"]
    assert 180.0 <= ev["landed_s"] - ev["takeoff_s"] <= 360.0  # 3–6 min flights
    winds = [e for e in truth["effects"] if e["effect"] == "wind"]
    set_winds = [s for s in scenario.steps if isinstance(s, SetWind) and s.speed_mps > 0]
    assert [(w["speed_mps"], w["from_deg"]) for w in winds] == [
        (s.speed_mps, s.from_deg) for s in set_winds
    ]
    payloads = [e for e in truth["effects"] if e["effect"] == "payload"]
    assert len(payloads) == int(any(isinstance(s, Grip) and s.grab for s in scenario.steps))
    for effect in truth["effects"]:
        assert effect["start_s"] < effect["end_s"] <= ev["disarmed_s"] + 5.0
    for p in payloads:  # weighs from 2 m up: just after take-off
        assert p["start_s"] - ev["takeoff_s"] < 5.0
    assert truth["mass_kg"] == (scenario.model_json or {}).get("mass", 3.0)
    if "battCapacityAh" in (scenario.model_json or {}):
        assert truth["battery"]["drains"] and ev["reserve_s"] < ev["landed_s"]


@cache
def replayed(log: Path) -> FlightReplay:
    return replay_log(log, load_vehicle(VEHICLE))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_recording_replays_with_its_airborne_time(name: str) -> None:
    ev = _truth(name)["events"]
    logs = [RECORDINGS / name / "flight.tlog"]
    if (RECORDINGS / name / "flight.BIN").is_file():
        logs.append(RECORDINGS / name / "flight.BIN")
    for log in logs:
        flight = replayed(log)
        summary = summarize([flight])
        assert flight.bad_frames == 0
        assert summary.airborne_s == pytest.approx(ev["landed_s"] - ev["takeoff_s"], abs=5.0)
        assert summary.energy_measured_wh > 10.0


def test_the_docs_give_the_replays_as_measured() -> None:
    """docs/sitl.md's table of the recordings and docs/residuals.md's of the wind in use on
    them are what they replay to now (``make figures`` writes them from
    ``scripts/figures.py``)."""
    figures = load_script("figures")
    flights = {n: replayed(RECORDINGS / n / "flight.tlog") for n in figures.sitl.recordings()}
    with_wind = {n: f.estimates for n, f in flights.items()}
    now = {
        "sitl-recordings-table": figures.sitl.recordings_table(flights),
        "sitl-hexa-energy": figures.sitl.hexa_energy(flights),
        "sitl-wind-cost": figures.sitl.wind_cost(flights),
        "tracked-wind-sitl": "\n".join(
            figures.script_module("tracked_wind_sitl").table_lines(with_wind)
        ),
    }
    assert {n for n, test in figures.CHECKED_BY.items() if test == THIS_FILE} == set(now)
    blocks = [b for b in figures.all_blocks() if b.name in now]
    assert {b.name for b in blocks} == set(now)
    stale = [b.name for b in blocks if b.text != now[b.name]]
    assert not stale, f"{stale}: run `make figures` and review the diff"


def test_sitl_record_answers_user_mistakes_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for argv, says in (
        (["nope"], "unknown scenario 'nope'"),
        (["clean_legs", "--speedup", "fast"], "--speedup needs a number"),
        (["clean_legs", "--speedup", "0"], "--speedup must be in (0, 100]"),
        (["clean_legs", "--binary", str(tmp_path / "none")], "is not a file"),
    ):
        assert main(["sitl-record", *argv, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err
        assert says in err and err.count("\n") == 1


def test_the_recorder_sees_a_release_the_mission_commands() -> None:
    """The gripper load stops weighing when the autopilot says it released it, also when the
    mission's own DO_GRIPPER released it (no Grip step: release_wind2's truth, recorded
    before, keeps the 1 kg until landing)."""
    pilot = SimpleNamespace(listeners=[], state=State(boot_s=10.0, armed=True, alt_m=5.0))
    truth = Truth("release", "", "quad", None, {}, 10.0)
    flight = Flight(pilot, SCENARIOS["clean_legs"], truth)  # type: ignore[arg-type]
    flight.gripped = True
    position = mavlink.MAVLink_global_position_int_message(0, 0, 0, 0, 5000, 0, 0, 0, 0)
    released = mavlink.MAVLink_statustext_message(6, b"Gripper load released", 0, 0)
    watch = pilot.listeners[0]
    watch(position)
    pilot.state.boot_s = 20.0
    watch(released)
    watch(position)
    assert truth.effects == [{"effect": "payload", "mass_kg": 1.0, "start_s": 10.0, "end_s": 20.0}]
