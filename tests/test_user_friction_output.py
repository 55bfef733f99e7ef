"""What a new user meets in the output: a pipe closed early (``| head -1``), a skipped log's
path said once, fleet's sanity warnings once per cause, ``make fit-real`` leaving the tracked
vehicle files alone, a residual plot of many flights with gaps, and two logs of one stem."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from itertools import pairwise
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pyarrow.parquet as pq
import pytest
from tlog_builder import without_firmware_text

from estimator.analysis.fleet_flight import FleetJob, file_sha256, flight_row
from estimator.analysis.replay import MAX_GAP_S
from estimator.analysis.residual_samples import ResidualOptions
from estimator.analysis.residuals import ResidualResult, analyze
from estimator.cli import EXIT_STDOUT_CLOSED, main
from estimator.logs import load_flights
from estimator.logs.sanity import PACK_VOLTAGE, VERTICAL_VELOCITY
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.reports import residuals_report
from estimator.reports.residuals_report import draw_time

REPO = Path(__file__).resolve().parent.parent
IRIS = sorted((REPO / "replay/iris").rglob("*.log"))
IRIS_VEHICLE = REPO / "replay/vehicle.toml"  # 3S, as the IRIS+ packs
SITL_QUAD = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
MISSION = REPO / "replay/sitl/missions/tall_wind4/mission.plan"
TLOG = REPO / "tests/data/arducopter_guided.tlog"
BIN = REPO / "tests/data/arducopter_guided.bin"
CMU_CRUISE = REPO.parent / "shared/data/cmu_m100_subset/flights_validation_data_clean_cruise.csv"
#: Lines of the CMU cruise file the fit-real run reads (a few of its flights).
CMU_LINES = 1000


def _cli(argv: list[str], cwd: Path, **kwargs: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "estimator.cli", *argv],
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        timeout=120,
        check=False,
        **kwargs,  # type: ignore[call-overload]
    )


@pytest.mark.parametrize(
    "argv",
    [
        ["plan", str(MISSION), "--vehicle", str(SITL_QUAD), "--json"],
        ["plan", str(MISSION), "--vehicle", str(SITL_QUAD)],  # a rich table
        ["replay", str(TLOG), "--vehicle", str(SITL_QUAD), "--json"],
        ["replay", str(TLOG), "--vehicle", str(SITL_QUAD)],
        ["residuals", *map(str, IRIS), "--vehicle", str(IRIS_VEHICLE), "--json"],
    ],
    ids=["plan-json", "plan-table", "replay-json", "replay-table", "residuals"],
)
def test_a_reader_gone_ends_the_command_quietly(argv: list[str], tmp_path: Path) -> None:
    """``uav-energy ... | head -1``. fleet: below."""
    _quiet(_closed_stdout_cli(argv, tmp_path))


def _closed_stdout_cli(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run the CLI with its stdout a pipe whose reader closed it before the output came."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return _cli(argv, cwd, stdout=write_end)
    finally:
        os.close(write_end)


def _quiet(done: subprocess.CompletedProcess[str]) -> None:
    assert done.returncode == EXIT_STDOUT_CLOSED, done.stderr
    for word in ("Traceback", "BrokenPipe", "Broken pipe", "Exception", "error"):
        assert word not in done.stderr


def test_replay_names_a_skipped_log_once(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    junk = tmp_path / "notes.tlog"
    junk.write_text("not a log\n")
    assert main(["replay", str(junk), str(TLOG), "--vehicle", str(SITL_QUAD), "--json"]) == 0
    err = capsys.readouterr().err
    (line,) = [line for line in err.splitlines() if "skipped" in line]
    assert line == f"uav-energy replay: skipped: {junk} is not a recognised log " + (
        "(expected a MAVLink tlog, a CMU CSV, a DataFlash .bin or a PX4 .ulg)"
    )


def test_fleet_without_the_vehicle_warns_once_per_cause_with_a_count(tmp_path: Path) -> None:
    """The built-in 6S vehicle on the 3S IRIS+ logs, two of them without their firmware
    text: the pack voltage warning once, the vertical velocity one once, each with how many
    more logs it holds for; the warnings in
    the results; a log that fails is named once. Its output read by ``| head -1``."""
    junk = tmp_path / "notes.log"
    junk.write_text("not a log\n")
    out = tmp_path / "r.parquet"
    # two of the logs without their firmware text: they send vz positive up unannounced
    logs = [*(without_firmware_text(p, tmp_path / p.name) for p in IRIS[:2]), *IRIS[2:]]
    argv = ["fleet", "replay", *map(str, logs), str(junk), "--workers", "1", "--out", str(out)]
    done = _closed_stdout_cli(argv, tmp_path)
    _quiet(done)
    rows = [r for r in pq.read_table(out).to_pylist() if r["status"] == "ok"]
    assert len(rows) == len(IRIS)
    assert all(PACK_VOLTAGE in dict(r["warnings"]) for r in rows)
    wrong_way = sum(VERTICAL_VELOCITY in dict(r["warnings"]) for r in rows)
    assert wrong_way == 2
    lines = done.stderr.splitlines()
    assert sum("per cell for the vehicle file's 6 cells" in line for line in lines) == 1
    assert sum("disagrees in sign" in line for line in lines) == 1
    assert (
        "uav-energy fleet: warning: the pack voltage warning above holds for "
        f"{len(rows) - 1} more logs too"
    ) in lines
    assert (
        "uav-energy fleet: warning: the vertical velocity warning above holds for "
        f"{wrong_way - 1} more logs too"
    ) in lines
    assert done.stderr.count(str(junk)) == 1


def test_fleet_resistance_is_wrong_with_the_wrong_pack_and_says_so() -> None:
    log = IRIS[1]
    wrong = flight_row(str(log), file_sha256(log), FleetJob("replay", default_vehicle()))
    right = flight_row(str(log), file_sha256(log), FleetJob("replay", load_vehicle(IRIS_VEHICLE)))
    assert wrong["status"] == right["status"] == "ok"
    assert wrong["resistance_ohm"] > 10 * right["resistance_ohm"]
    assert {cause for cause, _ in wrong["warnings"]} == {PACK_VOLTAGE}
    assert right["warnings"] == []


@pytest.mark.needs(CMU_CRUISE.exists(), f"{CMU_CRUISE} is not there (shared data)")
def test_fit_real_writes_its_vehicles_beside_the_tracked_ones(tmp_path: Path) -> None:
    """scripts/fit_real.sh (``make fit-real``) on the small IRIS+ logs and part of a CMU file:
    the fitted vehicle files go to out/fit/vehicles; config/vehicles is only compared."""
    data = tmp_path / "data"
    iris = data / "iris_quadcopter_logs"
    iris.mkdir(parents=True)
    for day in sorted((REPO / "replay/iris").glob("2016-*")):
        (iris / day.name).symlink_to(day)
    cmu = data / "cmu_m100_subset"
    cmu.mkdir()
    with CMU_CRUISE.open() as src, (cmu / "cruise.csv").open("w") as dst:
        dst.writelines(line for _, line in zip(range(CMU_LINES), src, strict=False))
    work = tmp_path / "work"
    shutil.copytree(REPO / "config/vehicles", work / "config/vehicles")
    tracked = {p.name: p.read_bytes() for p in (work / "config/vehicles").glob("*.toml")}
    done = subprocess.run(
        ["sh", str(REPO / "scripts/fit_real.sh"), str(data)],
        cwd=work,
        env={**os.environ, "UAV_ENERGY": str(Path(sys.executable).parent / "uav-energy")},
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert {p.name: p.read_bytes() for p in (work / "config/vehicles").glob("*.toml")} == tracked
    fitted = sorted(p.name for p in (work / "out/fit/vehicles").glob("*.toml"))
    assert fitted == ["dji_m100_cmu.toml", "iris_plus_2016_03.toml", "iris_plus_2016_06_08.toml"]
    for name in fitted:  # fits of a few flights: not the tracked files' figures
        assert f"out/fit/vehicles/{name}: differs from config/vehicles/{name}" in done.stdout
        assert load_vehicle(work / "out/fit/vehicles" / name).model.hover_power_w > 0


@pytest.fixture(scope="module")
def holed_result() -> ResidualResult:
    """The residual analysis of the IRIS+ flights, 20 s cut out of the middle of each one's
    time aloft."""
    flights = []
    for flight in load_flights(IRIS):
        aloft_s = flight.time_s[flight.alt_m > 2.0]
        if not len(aloft_s):
            continue  # 009.2 stays on the ground
        mid = np.median(aloft_s)
        flights.append(flight.subset(np.abs(flight.time_s - mid) > 10.0))
    return analyze(flights, load_vehicle(IRIS_VEHICLE), ResidualOptions())


def test_residual_time_lines_stop_at_gaps(holed_result: ResidualResult) -> None:
    fig, ax = plt.subplots()
    draw_time(ax, holed_result)
    xs = (np.asarray(line.get_xdata(), dtype=float) for line in ax.get_lines())
    traces = [x for x in xs if len(x) > 2]  # not the axhline
    assert len(traces) == 2 * len(holed_result.samples.flight_ids)
    breaks = 0
    for x in traces:
        steps = np.diff(x)  # NaN across a break
        assert np.all(steps[np.isfinite(steps)] <= MAX_GAP_S)
        breaks += int(np.isnan(x).sum())
    assert breaks >= len(traces)  # every flight has its 20 s hole
    plt.close(fig)


def test_residual_time_names_only_flights_that_stay_clear(
    holed_result: ResidualResult, monkeypatch: pytest.MonkeyPatch
) -> None:
    ids = holed_result.samples.flight_ids
    assert len(ids) == 3
    monkeypatch.setattr(residuals_report, "MAX_FLIGHT_LABELS", 2)  # room for two names
    fig, ax = plt.subplots()
    draw_time(ax, holed_result)
    named = [t for t in ax.texts if t.get_text().strip() in ids]
    assert 1 <= len(named) < len(ids)
    assert f"{len(named)} of {len(ids)} flights named" in ax.get_xlabel()
    last_s = max(np.nanmax(np.asarray(line.get_xdata(), dtype=float)) for line in ax.get_lines())
    room_s = (last_s + residuals_report.FLIGHT_SPACING_S) / 2
    starts = [t.get_position()[0] for t in named]
    assert all(b - a >= room_s for a, b in pairwise(starts))
    plt.close(fig)


def test_two_logs_of_one_stem_are_told_apart_by_their_suffix(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    (tmp_path / "flight.BIN").write_bytes(BIN.read_bytes())
    (tmp_path / "flight.tlog").write_bytes(TLOG.read_bytes())
    logs = [str(tmp_path / "flight.BIN"), str(tmp_path / "flight.tlog")]
    assert [f.flight_id for f in load_flights(logs)] == ["flight.BIN", "flight.tlog"]
    report = tmp_path / "report"
    argv = ["replay", *logs, "--vehicle", str(SITL_QUAD), "--json", "--report", str(report)]
    assert main(argv) == 0
    flights = json.loads(capsys.readouterr().out)["flights"]
    assert [f["flight"] for f in flights] == ["flight.BIN", "flight.tlog"]
    assert len(list(report.glob("flight.*-power.png"))) == 2


def test_sitl_record_help_names_the_binary_flag(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["sitl-record", "--help"])
    assert stop.value.code == 0
    assert "--binary FILE" in capsys.readouterr().out
