"""Input files as data: vehicle files, daemon configurations, missions and logs, damaged at
random (hypothesis, :mod:`fixtures.mutation`) give sane figures or one sentence and exit 2,
never a traceback or a hang; each failure once measured on mutated files, held here through
the CLI as a user meets it."""

from __future__ import annotations

import json
import os
import random
import re
from pathlib import Path

import pytest
from fixtures.mutation import KINDS, judge, mutate, seed_files, time_limit, write_cmu_csv
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tlog_builder import flight_frames, write_tlog

from estimator.analysis.fleet_flight import UNEXPECTED, failure_reason
from estimator.cli import main
from estimator.errors import UserError
from estimator.file_checks import MAX_NESTING, check_nesting, regular_file
from estimator.mavlink.config import FUSION_RANGES
from estimator.physics.vehicle import COEFFICIENT_RANGES

REPO = Path(__file__).resolve().parent.parent
VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_03.toml"
PLAN = REPO / "replay" / "sitl" / "missions" / "tall_wind4" / "mission.plan"
#: A read still running after this long (s) is a hang.
HANG_S = 20.0


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Path]]:
    return seed_files(tmp_path_factory.mktemp("seeds"))


@pytest.mark.parametrize("kind", KINDS)
@settings(
    max_examples=150,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_a_damaged_file_gives_sane_figures_or_one_sentence(
    kind: str, data: st.DataObject, seeds: dict[str, list[Path]], tmp_path: Path
) -> None:
    seed = data.draw(st.sampled_from(seeds[kind]), label="seed file")
    draw = data.draw(st.integers(0, 2**32 - 1), label="mutation seed")
    text = kind != "log" or seed.suffix == ".csv"
    path = tmp_path / f"mutated{seed.suffix}"
    path.write_bytes(mutate(seed.read_bytes(), random.Random(draw), text))
    with time_limit(HANG_S):
        outcome = judge(kind, path, seeds["log"][2], seeds["mission"][0])
    assert outcome in ("ok", "user-error")


def test_the_valid_seed_files_give_sane_figures(seeds: dict[str, list[Path]]) -> None:
    for kind, paths in seeds.items():
        for path in paths:
            assert judge(kind, path, seeds["log"][2], seeds["mission"][0]) == "ok", path


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    with time_limit(HANG_S):
        code = main(argv)
    err = capsys.readouterr().err.strip()
    return code, err


def _vehicle_with(tmp_path: Path, old: str, new: str) -> Path:
    text = VEHICLE.read_text()
    assert re.search(old, text, re.MULTILINE)
    path = tmp_path / "vehicle.toml"
    path.write_text(re.sub(old, new, text, count=1, flags=re.MULTILINE))
    return path


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (r"^cells = 3", "cells = 0.5", "'cells' must be an integer from 1 to 24, got 0.5"),
        (r"^cells = 3", "cells = 1e6", "'cells' must be an integer from 1 to 24"),
        (r"^capacity_ah = 5.1", "capacity_ah = 1e300", "'capacity_ah' must be a number from"),
        (r"^c1 = 24.9\d*", "c1 = 0", "[model.stderr] 'c1' must be a number from 1e-09"),
        (r"^c1 = 24.9\d*", "c1 = -3", "[model.stderr] 'c1' must be a number from 1e-09"),
        (r"^c4 = 59.1\d*", "c4 = 1e-300", "[model] 'c4' must be a number from 0.1 to 10000"),
        (r"^mass_kg = 1.282", "mass_kg = 1e300", "'mass_kg' must be a number from 0.01"),
    ],
)
def test_a_vehicle_file_out_of_range_is_one_sentence_naming_file_key_and_range(
    old: str, new: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    vehicle = _vehicle_with(tmp_path, old, new)
    code, err = _run(["plan", str(PLAN), "--vehicle", str(vehicle)], capsys)
    assert code == 2 and "\n" not in err
    assert str(vehicle) in err and message in err


@pytest.mark.parametrize("key", ["capacity_sigma_fraction", "bias_prior_sigma"])
def test_a_fusion_figure_of_1e300_is_refused_with_its_range(
    key: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "config.toml"
    config.write_text(f"[fusion]\n{key} = 1e300\n")
    log = write_cmu_csv(tmp_path / "flight.csv")
    code, err = _run(["replay", str(log), "--config", str(config)], capsys)
    lo, hi = FUSION_RANGES[key]
    assert code == 2 and "\n" not in err
    assert f"config [fusion] '{key}' must be a number from {lo:g} to {hi:g}" in err


def test_every_fusion_figure_and_model_coefficient_has_a_range() -> None:
    from dataclasses import fields

    from estimator.estimation.fusion import FusionSettings
    from estimator.physics.model import COEFFICIENT_NAMES

    assert set(FUSION_RANGES) == {f.name for f in fields(FusionSettings)}
    assert set(COEFFICIENT_RANGES) == set(COEFFICIENT_NAMES)


@pytest.mark.parametrize(
    ("command", "altitude_m", "message"),
    [
        (16, 60.0, None),  # as committed: planned
        (21, -1e6, "NAV_LAND altitude must be a number from -10000 to 10000 m, got -1000000.0"),
        (16, 1e300, "NAV_WAYPOINT altitude must be a number from -10000 to 10000 m, got 1e+300"),
        (21, -30.0, "NAV_LAND starts 30 m below home"),
    ],
)
def test_a_mission_altitude_out_of_range_is_one_sentence(
    command: int,
    altitude_m: float,
    message: str | None,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    doc = json.loads(PLAN.read_text())
    item = doc["mission"]["items"][2]
    item["command"], item["params"][6] = command, altitude_m
    if altitude_m == -30.0:  # the waypoint before the landing below home
        doc["mission"]["items"][1]["params"][6] = altitude_m
    plan = tmp_path / "mission.plan"
    plan.write_text(json.dumps(doc))
    code, err = _run(["plan", str(plan), "--vehicle", str(VEHICLE)], capsys)
    if message is None:
        assert code == 0
        return
    assert code == 2 and "\n" not in err and message in err


@pytest.mark.parametrize("suffix", [".plan", ".toml"])
def test_nesting_thousands_deep_is_refused_before_parsing(
    suffix: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deep = "[" * 5000 + "1" + "]" * 5000
    path = tmp_path / f"deep{suffix}"
    if suffix == ".plan":
        path.write_text('{"mission": {"items": ' + deep + "}}")
        argv = ["plan", str(path), "--vehicle", str(VEHICLE)]
    else:
        path.write_text(VEHICLE.read_text() + f"\n[effects.wind]\nspeed_mps = {deep}\n")
        argv = ["plan", str(PLAN), "--vehicle", str(path)]
    code, err = _run(argv, capsys)
    assert code == 2 and f"nests deeper than {MAX_NESTING} levels" in err


def test_nesting_counts_brackets_outside_strings_and_comments_only() -> None:
    check_nesting('a = "' + "[" * 100 + '"  # ' + "{" * 100 + "\n", "x.toml", comment="#")
    check_nesting('{"a": "' + "[" * 100 + '\\" ["}', "x.plan")
    with pytest.raises(UserError, match=r"x\.plan nests deeper"):
        check_nesting("[" * (MAX_NESTING + 1), "x.plan")


def test_a_fifo_given_to_replay_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "flight.tlog"
    os.mkfifo(fifo)
    code, err = _run(["replay", str(fifo)], capsys)
    assert code == 2 and err.endswith(f"log {fifo} is a FIFO, not a regular file")


def test_links_directories_and_devices_are_named_for_what_they_are(tmp_path: Path) -> None:
    dangling, loop = tmp_path / "dangling.tlog", tmp_path / "loop.tlog"
    dangling.symlink_to(tmp_path / "gone.tlog")
    loop.symlink_to(loop)
    cases = {
        dangling: "is a symbolic link to a missing file",
        loop: "is a symbolic link loop",
        tmp_path: "is a directory",
        Path("/dev/null"): "is a device, not a regular file",
        tmp_path / "none.tlog": "does not exist",
    }
    for path, message in cases.items():
        with pytest.raises(UserError, match=message):
            regular_file(path, "log")


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("a" * 200_000, "is not a readable CSV file (field larger than field limit"),
        ("1e300", "has a value beyond ±1e+09"),
        ("-1e300", "has a value beyond ±1e+09"),
    ],
)
def test_a_cmu_csv_with_a_huge_cell_is_one_sentence(
    row: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = write_cmu_csv(tmp_path / "flight.csv")
    lines = log.read_text().splitlines()
    cells = lines[5].split(",")
    cells[9] = row  # twist_linear_x
    lines[5] = ",".join(cells)
    log.write_text("\n".join(lines) + "\n")
    code, err = _run(["replay", str(log)], capsys)
    assert code == 2 and "\n" not in err and message in err


def test_a_cell_count_that_rejects_every_voltage_says_so(
    seeds: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    one_cell = _vehicle_with(tmp_path, r"^cells = 3", "cells = 1")
    bin_log = seeds["log"][1]  # the fixture flight: a 6-cell pack, 22.8-25.0 V
    code, err = _run(["replay", str(bin_log), "--vehicle", str(one_cell)], capsys)
    assert code == 2 and "\n" not in err
    found = re.search(
        r"every battery voltage \(([\d.]+)–([\d.]+) V\) is outside the window of a 1-cell pack", err
    )
    assert found is not None and "is `cells` right?" in err
    assert (float(found[1]), float(found[2])) == (22.8, 25.0)


def test_a_reversed_current_sensor_says_so_not_that_the_voltage_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every reading of a pack whose current sensor is wired the wrong way round (−11.2 A,
    as on a public ArduSub log) is refused: the sentence names the current, not a voltage."""
    log = write_tlog(tmp_path / "reversed.tlog", flight_frames(20, current_ca=-1120))
    code, err = _run(["replay", str(log)], capsys)
    assert code == 2 and "\n" not in err
    assert "every battery current (-11.2 to -11.2 A) is outside what the vehicle draws" in err
    assert err.endswith("is the current sensor reversed?")


@pytest.mark.parametrize(
    ("exc", "reason"),
    [
        (ValueError("math domain error"), "beyond what the analysis can compute"),
        (OverflowError("math range error"), "beyond what the analysis can compute"),
        (MemoryError(), "too large for the worker's memory"),
        (RecursionError(), "nests too deeply"),
    ],
)
def test_fleet_reasons_are_plain_words_for_known_causes(exc: Exception, reason: str) -> None:
    text = failure_reason(exc)
    assert reason in text and type(exc).__name__ not in text and not text.startswith(UNEXPECTED)


def test_an_unexpected_fleet_failure_keeps_its_class_name() -> None:
    class Strange(Exception):
        pass

    assert failure_reason(Strange("odd")) == f"{UNEXPECTED} (Strange: odd)"
