"""``uav-energy fleet``: a real dask LocalCluster with two worker processes over the small
IRIS+ flights in ``replay/iris``, a corrupt and a truncated log; Parquet rows and schema,
failed rows with their reason, resume by content hash, trends, and the CLI as a subprocess."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from datetime import UTC, date, datetime, timedelta
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from distributed import Client
from pymavlink.dialects.v20 import common as mavlink

from estimator.analysis.fleet import connect, expand_inputs, run_fleet, tasks
from estimator.analysis.fleet_flight import FleetJob, file_sha256, flight_row
from estimator.analysis.fleet_table import SCHEMA, read_table, to_table
from estimator.analysis.fleet_trends import fleet_trends
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
REPLAY = REPO / "replay"
LOGS = sorted((REPLAY / "iris").rglob("*.log"))
EXPECTED = json.loads((REPLAY / "expected.json").read_text())["flights"]


@pytest.fixture(scope="module")
def client() -> Iterator[Client]:
    with connect(None, 2) as c:
        yield c


@pytest.fixture()
def logs(tmp_path: Path) -> list[Path]:
    """The five small IRIS+ flights, a file that is no log, and a log cut after 300 bytes."""
    corrupt = tmp_path / "corrupt.log"
    corrupt.write_bytes(b"\x00garbage, not a flight log\n" * 40)
    truncated = tmp_path / "truncated.log"
    truncated.write_bytes(LOGS[0].read_bytes()[:300])
    return [*LOGS, corrupt, truncated]


def test_two_worker_processes_give_one_row_per_log_with_the_schema(
    client: Client, logs: list[Path], tmp_path: Path
) -> None:
    workers = client.scheduler_info()["workers"]
    assert len(workers) == 2 and all(w["nthreads"] == 1 for w in workers.values())
    out = tmp_path / "results.parquet"
    vehicle = load_vehicle(REPLAY / "vehicle.toml")
    counts = run_fleet(client, logs, FleetJob("replay", vehicle), out)
    assert (counts.logs, counts.ok, counts.failed) == (7, 5, 2)
    table = pq.read_table(out)
    assert table.schema.equals(SCHEMA)
    rows = {Path(r["path"]).name: r for r in table.to_pylist()}
    assert len(rows) == 7
    for log in LOGS:
        row = rows[log.name]
        expected = EXPECTED[str(log.relative_to(REPLAY))]
        assert row["status"] == "ok" and row["error"] is None
        assert row["sha256"] == file_sha256(log)
        # the worker ran the same replay as `uav-energy replay` (replay/expected.json)
        assert row["samples"] == expected["messages"]
        assert row["airborne_s"] == pytest.approx(expected["airborne_s"], abs=1e-9)
        assert row["energy_used_wh"] == pytest.approx(expected["energy_measured_wh"], abs=1e-9)
        assert row["autopilot_sysid"] == 1 and row["vehicle"] == vehicle.name
    # start time: the first record's stamp (replay/SOURCE.md: 2016-03-14 17:47:49 UTC)
    start = rows["004-F2.log"]["start_utc"]
    assert start.replace(microsecond=0) == datetime(2016, 3, 14, 17, 47, 49, tzinfo=UTC)
    assert rows["corrupt.log"]["status"] == "failed"
    assert "not a recognised log" in rows["corrupt.log"]["error"]
    assert rows["truncated.log"]["status"] == "failed"
    assert "no battery telemetry" in rows["truncated.log"]["error"]


def test_resume_skips_logs_whose_content_is_already_in_the_results(
    client: Client, logs: list[Path], tmp_path: Path
) -> None:
    out = tmp_path / "results.parquet"
    job = FleetJob("replay", load_vehicle(REPLAY / "vehicle.toml"))
    run_fleet(client, logs[:3], job, out)
    renamed = tmp_path / "same-content-other-name.log"
    shutil.copy(logs[0], renamed)
    counts = run_fleet(client, [*logs, renamed], job, out)
    # 3 done before, the renamed copy is done too (same hash); 4 new, 2 of them failing
    errors = pq.read_table(out, columns=["error"]).column("error").to_pylist()
    assert (counts.already_done, counts.ok, counts.failed) == (4, 2, 2), errors
    assert pq.read_table(out).num_rows == 7
    again = run_fleet(client, logs, job, out, retry_failed=True)
    assert (again.already_done, again.failed, again.ok) == (5, 2, 0)
    assert pq.read_table(out).num_rows == 7  # the failed rows were replaced, not added


def test_pack_serial_from_smart_battery_info_names_the_pack(tmp_path: Path) -> None:
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    info = codec.smart_battery_info_encode(
        0, 0, 0, 5100, 4900, 42, b"PACK-0042", b"3S 5100", 0, 0, 0, 0
    )
    data = LOGS[1].read_bytes()
    stamp = data[:8]
    log = tmp_path / "with_pack.log"
    log.write_bytes(data + stamp + info.pack(codec))
    row = flight_row(
        str(log), file_sha256(log), FleetJob("replay", load_vehicle(REPLAY / "vehicle.toml"))
    )
    assert row["status"] == "ok" and row["pack_id"] == "PACK-0042"


def test_trends_give_a_slope_per_vehicle_and_per_pack_and_a_mass_ratio() -> None:
    day0 = datetime(2016, 3, 1, tzinfo=UTC)
    rows = [
        {
            "path": f"/logs/{k}.log",
            "sha256": f"{k:064x}",
            "mode": "fit",
            "vehicle": "quad",
            "status": "ok",
            "start_utc": day0 + timedelta(days=10 * k),
            "autopilot_sysid": 3,
            "pack_id": "P1",
            "hover_power_fit_w": 150.0 + 3.0 * k,  # +9 W per 30 days
            "resistance_ohm": 0.030 + 0.001 * k,
            "capacity_ah": 5.0 - 0.05 * k,
        }
        for k in range(6)
    ]
    rows.append({**rows[0], "sha256": "f" * 64, "status": "failed", "hover_power_fit_w": 1e6})
    trends = fleet_trends(to_table(rows))
    assert (trends.rows, trends.ok, trends.dated) == (7, 6, 6)
    by = {(s.kind, s.group, s.metric): s for s in trends.series}
    hover = by[("vehicle", "quad #3", "hover_power_w")]
    slope = hover.slope_per_30d()
    assert slope is not None and slope[0] == pytest.approx(9.0)
    assert by[("pack", "P1", "capacity_ah")].slope_per_30d()[0] == pytest.approx(-0.15)  # type: ignore[index]
    assert "mass ×1.066" in hover.line()  # (165/150)^(2/3)
    window = fleet_trends(to_table(rows), since=date(2016, 3, 21), until=date(2016, 4, 10))
    assert window.dated == 3  # days 20, 30 and 40


def test_every_glob_match_gets_a_row_with_its_reason_in_plain_words(
    client: Client, tmp_path: Path
) -> None:
    shutil.copy(LOGS[0], tmp_path / "good.log")
    (tmp_path / "folder.log").mkdir()
    (tmp_path / "dangling.log").symlink_to(tmp_path / "gone.log")
    (tmp_path / "loop.log").symlink_to(tmp_path / "loop.log")
    os.mkfifo(tmp_path / "fifo.log")
    found = expand_inputs([str(tmp_path / "*.log")])
    assert len(found) == 5
    out = tmp_path / "results.parquet"
    counts = run_fleet(
        client, found, FleetJob("replay", load_vehicle(REPLAY / "vehicle.toml")), out
    )
    assert (counts.logs, counts.ok, counts.failed, counts.unexpected) == (5, 1, 4, 0)
    errors = {Path(r["path"]).name: r["error"] for r in pq.read_table(out).to_pylist()}
    assert errors["good.log"] is None
    assert errors["folder.log"].endswith("folder.log is a directory")
    assert errors["dangling.log"].endswith("dangling.log is a symbolic link to a missing file")
    assert errors["loop.log"].endswith("loop.log is a symbolic link loop")
    assert errors["fifo.log"].endswith("fifo.log is a FIFO, not a regular file")


def test_small_logs_share_a_task_and_every_worker_gets_tasks() -> None:
    todo = {f"/logs/{k}.log": f"{k:064x}" for k in range(100)}
    sizes = dict.fromkeys(todo, 300_000)
    # 30 MB: tasks close at TASK_BYTES (1 MiB), four logs of 300 kB each
    assert [len(t) for t in tasks(todo, sizes, 2)] == [4] * 25
    few = dict(list(todo.items())[:10])
    # 3 MB on 2 workers: tasks of 375 kB, for TASKS_PER_WORKER = 4 tasks each at least
    assert [len(t) for t in tasks(few, sizes, 2)] == [2] * 5
    sizes["/logs/1.log"] = 50_000_000  # a large log is a task of its own
    grouped = tasks(todo, sizes, 2)
    assert grouped[0] == [("/logs/0.log", f"{0:064x}"), ("/logs/1.log", f"{1:064x}")]
    assert [log for task in grouped for log in task] == list(todo.items())


def test_inputs_expand_globs_and_reject_directories(tmp_path: Path) -> None:
    found = expand_inputs([str(REPLAY / "iris" / "**" / "*.log"), str(LOGS[0])])
    assert found == sorted(p.resolve() for p in LOGS)
    with pytest.raises(Exception, match="is a directory"):
        expand_inputs([str(REPLAY)])
    with pytest.raises(Exception, match="no file matches"):
        expand_inputs([str(tmp_path / "*.tlog")])


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "estimator.cli", "fleet", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=120,
    )


def test_cli_fit_writes_rows_and_the_trends_report(tmp_path: Path) -> None:
    out = tmp_path / "fit.parquet"
    vehicle = str(REPLAY / "vehicle.toml")
    pattern = str(REPLAY / "iris" / "**" / "*.log")
    done = _cli(
        "fit",
        pattern,
        "--workers",
        "2",
        "--vehicle",
        vehicle,
        "--out",
        str(out),
        "--report",
        str(tmp_path / "report"),
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert "5 logs: 4 ok, 1 failed" in done.stdout and "on 2 worker(s)" in done.stdout
    # the ground-only flight cannot be fitted: listed on stderr, recorded with its reason
    assert "009.2.log: only 0 usable points" in done.stderr
    table = read_table(out)
    assert table is not None
    fitted = [r for r in table.to_pylist() if r["status"] == "ok"]
    assert all(100.0 < r["hover_power_fit_w"] < 250.0 for r in fitted)
    assert (tmp_path / "report" / "trends.png").stat().st_size > 10_000
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert {s["metric"] for s in summary["series"]} == {
        "hover_power_w",
        "resistance_ohm",
        "capacity_ah",
    }
    again = _cli("trends", str(out), "--report", str(tmp_path / "again"), cwd=tmp_path)
    assert again.returncode == 0 and "hover power" in again.stdout


def test_cli_bad_scheduler_address_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = _cli("replay", str(LOGS[0]), "--scheduler", "tcp://127.0.0.1:9", cwd=tmp_path)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot reach the dask scheduler at tcp://127.0.0.1:9" in lines[0]
    bad_results = tmp_path / "not.parquet"
    bad_results.write_text("x")
    done = _cli("trends", str(bad_results), "--report", str(tmp_path / "r"), cwd=tmp_path)
    assert done.returncode == 2 and "not a readable Parquet file" in done.stderr


def test_results_table_round_trips_the_schema(tmp_path: Path) -> None:
    table = to_table([{"path": "/x.log", "sha256": "0" * 64, "mode": "fit", "status": "ok"}])
    assert table.schema.equals(SCHEMA) and table.column("fit_points").null_count == 1
    assert isinstance(table.column("start_utc").type, pa.TimestampType)
