"""Per-pack memory (estimator.estimation.pack_memory): what a pack was learnt to hold starts
its next flight; memory files are read as hostile input; ``replay --pack`` over two flights
with the same pack (ArduCopter SITL, replay/sitl_packs)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from estimator.errors import UserError
from estimator.estimation.pack_memory import (
    BETWEEN_FLIGHTS_FRACTION,
    check_pack_id,
    load_prior,
    load_record,
    remember,
)
from estimator.estimation.pack_state import PackEstimate
from estimator.telemetry.samples import BatterySample

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
LEARNT = PackEstimate(
    soc=0.3, soc_sigma=0.01, capacity_ah=3.2, capacity_sigma_ah=0.05, resistance_ohm=0.03,
    resistance_sigma_ohm=0.001, energy_wh=5.0, energy_sigma_wh=0.2,
)  # fmt: skip


def test_what_a_flight_learnt_is_the_next_flights_prior(tmp_path: Path) -> None:
    assert load_prior(tmp_path, "pack-7", 5.0) is None  # no memory yet
    remember(tmp_path, "pack-7", 5.0, LEARNT, when_s=1000.0)
    prior = load_prior(tmp_path, "pack-7", 5.0)
    assert prior is not None
    assert prior.capacity_ah == 3.2 and prior.resistance_ohm == 0.03
    widened = (0.05**2 + (BETWEEN_FLIGHTS_FRACTION * 3.2) ** 2) ** 0.5
    assert prior.capacity_sigma_ah == pytest.approx(widened)
    assert load_prior(tmp_path, "pack-7", 4.0) is None  # flown under another label
    assert load_prior(None, "pack-7", 5.0) is None and load_prior(tmp_path, None, 5.0) is None


def test_a_flight_keeps_one_row_of_history_and_a_new_flight_adds_one(tmp_path: Path) -> None:
    remember(tmp_path, "p", 5.0, LEARNT, when_s=1000.0)
    remember(tmp_path, "p", 5.0, LEARNT, when_s=1000.0)  # the same flight, later
    remember(tmp_path, "p", 5.0, LEARNT, when_s=2000.0)
    record = load_record(tmp_path, "p")
    assert record is not None and [row[0] for row in record.history] == [1000.0, 2000.0]


@pytest.mark.parametrize("pack_id", ["", ".hidden", "a/b", "../x", "x" * 65, "a b", "é"])
def test_a_pack_id_that_is_no_file_name_is_refused(pack_id: str) -> None:
    with pytest.raises(UserError):
        check_pack_id(pack_id)


@pytest.mark.parametrize(
    "content",
    [
        "not json",
        "[" * 100_000 + "]" * 100_000,
        json.dumps({"pack_id": "other", "label_ah": 5, "capacity_ah": 3}),
        json.dumps({"pack_id": "p", "label_ah": 5, "capacity_ah": 1e300, "capacity_sigma_ah": 0,
                    "resistance_ohm": 0.01, "resistance_sigma_ohm": 0}),
        json.dumps({"pack_id": "p", "label_ah": 5, "capacity_ah": 3, "capacity_sigma_ah": -1,
                    "resistance_ohm": 0.01, "resistance_sigma_ohm": 0}),
        json.dumps({"pack_id": "p", "label_ah": 5, "capacity_ah": 3, "capacity_sigma_ah": 0.1,
                    "resistance_ohm": "0.01", "resistance_sigma_ohm": 0}),
        json.dumps({"pack_id": "p", "label_ah": 5, "capacity_ah": 3, "capacity_sigma_ah": 0.1,
                    "resistance_ohm": 0.01, "resistance_sigma_ohm": 0, "history": [[1, 2]]}),
        " " * 300_000,
    ],
)  # fmt: skip
def test_a_forged_or_broken_memory_is_one_sentence_never_a_prior(
    tmp_path: Path, content: str
) -> None:
    (tmp_path / "p.json").write_text(content)
    with pytest.raises(UserError, match=r"pack memory .* is not usable"):
        load_prior(tmp_path, "p", 5.0)


def _replay(*args: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-m", "estimator.cli", "replay", *args, "--json"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    return json.loads(out.stdout)


def test_the_second_flight_with_a_pack_starts_from_what_the_first_learnt(tmp_path: Path) -> None:
    """Two SITL flights with a 3S pack that holds 3.25 Ah, labelled 5.0 Ah, replayed one after
    the other with ``--pack``: the first learns the pack; the second starts from it (its first
    estimate within 5 % of 3.25 Ah instead of the label's 5.0)."""
    labelled = tmp_path / "labelled.toml"
    doc = (ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml").read_text()
    labelled.write_text(doc.replace("capacity_ah = 2.2", "capacity_ah = 5.0"))
    common = ["--vehicle", str(labelled), "--pack", "pack-A", "--pack-dir", str(tmp_path)]
    first, second = FLIGHTS / "pack_c65_r1", FLIGHTS / "pack_c65_r3_soc75"
    _replay(str(first / "flight.tlog"), *common, "--out", str(tmp_path / "first.csv"))
    record = load_record(tmp_path, "pack-A")
    assert record is not None and record.capacity_ah == pytest.approx(3.25, rel=0.03)
    _replay(str(second / "flight.tlog"), *common, "--out", str(tmp_path / "second.csv"))
    rows = (tmp_path / "second.csv").read_text().splitlines()
    header = rows[0].split(",")
    first_capacity = float(rows[1].split(",")[header.index("capacity_ah")])
    assert first_capacity == pytest.approx(3.25, rel=0.05)
    record = load_record(tmp_path, "pack-A")
    assert record is not None and len(record.history) == 2


def test_pack_without_a_directory_is_a_user_mistake(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "estimator.cli", "replay", str(FLIGHTS / "pack_c65_r1" /
         "flight.tlog"), "--pack", "x"],
        capture_output=True, text=True, cwd=ROOT,
    )  # fmt: skip
    assert out.returncode == 2 and "--pack ID needs --pack-dir DIR" in out.stderr


def test_the_daemon_starts_from_the_packs_memory_and_stores_what_it_learns(
    tmp_path: Path,
) -> None:
    """``[pack] id`` and ``dir``: the pipeline's prior is the memory; what the pack filter
    holds is written back under this run's row."""
    from estimator.mavlink.config import ServiceConfig, validate
    from estimator.mavlink.service import Service
    from estimator.physics.vehicle import default_vehicle

    vehicle = default_vehicle()
    remember(tmp_path, "pack-A", vehicle.battery.capacity_ah, LEARNT, when_s=1000.0)
    config = ServiceConfig(pack_id="pack-A", pack_dir=str(tmp_path))
    validate(config)
    service = Service(config, vehicle)
    assert service.pipeline.pack_prior is not None
    assert service.pipeline.pack_prior.capacity_ah == 3.2
    for time_s, consumed_mah in ((1.0, 0.0), (2.1, 3.0), (3.2, 6.0)):
        # the third closes the second's period: the pack filter runs
        service.pipeline.process(BatterySample(time_s, 24.0, 10.0, consumed_mah))
    assert service.pipeline.pack_state is not None
    service._remember_pack()
    record = load_record(tmp_path, "pack-A")
    assert record is not None and len(record.history) == 2
    assert record.capacity_ah == pytest.approx(3.2, rel=0.05)
    with pytest.raises(UserError, match="needs"):
        validate(ServiceConfig(pack_id="pack-A"))
    validate(ServiceConfig(pack_dir=str(tmp_path)))  # the autopilot's serial will name it


def test_a_plan_with_the_pack_uses_its_learnt_capacity(tmp_path: Path) -> None:
    """``plan --pack``: the usable energy of a pack learnt to hold 3.2 Ah, not its label."""
    vehicle = ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
    mission = ROOT / "replay" / "sitl" / "missions" / "square_wind5" / "mission.waypoints"
    remember(tmp_path, "pack-A", 2.2, LEARNT, when_s=1000.0)

    def usable_wh(*extra: str) -> float:
        out = subprocess.run(
            [sys.executable, "-m", "estimator.cli", "plan", str(mission), "--vehicle",
             str(vehicle), "--json", *extra],
            capture_output=True, text=True, check=True, cwd=ROOT,
        )  # fmt: skip
        return float(json.loads(out.stdout)["usable_wh"])

    label = usable_wh()
    learnt = usable_wh("--pack", "pack-A", "--pack-dir", str(tmp_path))
    assert learnt == pytest.approx(label * 3.2 / 2.2, rel=1e-3)
