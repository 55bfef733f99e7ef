"""Capacity fade per pack in ``fleet``: the first 13 ArduCopter SITL pack flights
(replay/sitl_packs, packs holding 100, 80 and 65 % of a 5.0 Ah label) as two packs that
age, each log naming its pack in SMART_BATTERY_INFO and dated so that the true capacity falls
linearly: the pack's full-capacity flights on day 0, its 80 % ones on day 40, its 65 % ones
on day 70 (−0.75 Ah per 30 days). Pack A flies the 0.01 Ω flights, pack B the 0.03 Ω ones.
A real dask LocalCluster of two worker processes runs ``fleet replay``; the learnt capacity,
its σ, the per-pack trend and the report must show the truth (truth.json). A results file
written before the learnt-capacity columns reads with them null."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from tlog_builder import with_pack

from estimator.analysis.fleet import connect, run_fleet
from estimator.analysis.fleet_flight import FleetJob
from estimator.analysis.fleet_table import SCHEMA, read_table, to_table
from estimator.analysis.fleet_trends import fleet_trends
from estimator.errors import UserError
from estimator.physics.vehicle import load_vehicle
from estimator.reports.fleet_report import write_report

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
DAY_S = 86400.0
#: Day of the flights by the share of the label the pack holds then.
DAY_OF_CAPACITY = {5.0: 0, 4.0: 40, 3.25: 70}
#: The true fade, Ah per 30 days: 5.0 → 4.0 Ah in 40 days, → 3.25 Ah in 30 more.
FADE_AH_PER_30D = -0.75
RESISTANCE_OHM = {"PACK-A": 0.01, "PACK-B": 0.03}


def truth(name: str) -> dict[str, float]:
    return json.loads((FLIGHTS / name / "truth.json").read_text())["battery"]


def test_the_learnt_capacity_shows_each_packs_fade(tmp_path: Path) -> None:
    logs, true_ah = [], {}
    split = json.loads((FLIGHTS / "split.json").read_text())
    for flight in sorted(FLIGHTS / n for n in split["tuning"] + split["held_out"]):
        battery = truth(flight.name)
        pack = "PACK-A" if battery["internal_resistance_ohm"] == 0.01 else "PACK-B"
        shift_s = DAY_OF_CAPACITY[battery["capacity_ah"]] * DAY_S
        data = with_pack((flight / "flight.tlog").read_bytes(), pack.encode(), shift_s)
        log = tmp_path / f"{flight.name}.tlog"
        log.write_bytes(data)
        logs.append(log)
        true_ah[str(log)] = battery["capacity_ah"]
    assert len(logs) == 13
    vehicle = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
    labelled = replace(vehicle, battery=replace(vehicle.battery, capacity_ah=5.0))
    out = tmp_path / "results.parquet"
    with connect(None, 2) as client:
        counts = run_fleet(client, logs, FleetJob("replay", labelled), out)
    assert (counts.ok, counts.failed) == (13, 0)

    rows = pq.read_table(out).to_pylist()
    for row in rows:
        expected = true_ah[row["path"]]
        assert row["pack_id"] in RESISTANCE_OHM
        assert row["pack_capacity_ah"] == pytest.approx(expected, rel=0.03), row["path"]
        assert 0 < row["pack_capacity_sigma_ah"] < 0.05 * expected

    trends = fleet_trends(pq.read_table(out))
    by = {(s.kind, s.group, s.metric): s for s in trends.series}
    for pack, resistance_ohm in RESISTANCE_OHM.items():
        fade = by[("pack", pack, "pack_capacity_ah")]
        days = {day: value for day, value, _ in fade.per_day()}
        assert len(days) == 3
        for (day, value), capacity_ah in zip(sorted(days.items()), (5.0, 4.0, 3.25), strict=True):
            assert value == pytest.approx(capacity_ah, rel=0.02), (pack, day)
        slope = fade.slope_per_30d()
        assert slope is not None
        assert slope[0] == pytest.approx(FADE_AH_PER_30D, rel=0.05)
        assert slope[1] < slope[0] < slope[2] < 0  # a fade, not noise
        resistance = by[("pack", pack, "resistance_ohm")]
        for _, value, _ in resistance.per_day():
            assert value == pytest.approx(resistance_ohm, rel=0.25)

    write_report(trends, tmp_path / "report", "SITL packs")
    assert (tmp_path / "report" / "trends.png").stat().st_size > 10_000
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    learnt = [
        s for s in summary["series"] if s["kind"] == "pack" and s["metric"] == "pack_capacity_ah"
    ]
    assert [s["group"] for s in learnt] == ["PACK-A", "PACK-B"]
    assert all("weighted_mean" in d for s in learnt for d in s["per_day"])


def test_a_results_file_from_before_the_learnt_capacity_reads_with_it_null(
    tmp_path: Path,
) -> None:
    old = tmp_path / "old.parquet"
    table = to_table([{"path": "/logs/a.tlog", "sha256": "a" * 64, "mode": "replay",
                       "status": "ok", "capacity_ah": 4.2}])  # fmt: skip
    pq.write_table(table.drop_columns(["pack_capacity_ah", "pack_capacity_sigma_ah"]), old)
    read = read_table(old)
    assert read is not None and read.schema.equals(SCHEMA)
    assert read.to_pylist()[0]["pack_capacity_ah"] is None
    assert read.to_pylist()[0]["capacity_ah"] == 4.2
    pq.write_table(table.drop_columns(["sha256"]), old)
    with pytest.raises(UserError, match="not a fleet results file"):
        read_table(old)
