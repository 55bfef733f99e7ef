"""The public log corpus (tests/data/corpus, docs/logs.md) and what the readers say of logs
they cannot estimate from.

The committed fixtures must still give the outcome the docs table shows (the table is written
by ``python scripts/log_corpus.py``); the table itself must hold no traceback and no log
without a named reason. The readers' reasons are checked on logs built for the purpose: a
battery monitor on one of two instances, a current of 0 A throughout, PX4's landed detector.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest
from fixtures.dataflash_writer import DataFlashWriter
from fixtures.ulog_writer import ULogWriter
from script_loader import load_script

from estimator.analysis.log_corpus import (
    TRACEBACK,
    CorpusLog,
    FlightWatch,
    load_manifest,
    log_outcome,
)
from estimator.errors import UserError
from estimator.logs import flights_from_stream, iter_samples
from estimator.telemetry.samples import ArmedSample, BatterySample, LandedSample, VelocitySample

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / "tests" / "data" / "corpus"
DOC = ROOT / "docs" / "logs.md"
LOGS = load_manifest(CORPUS / "manifest.toml")
FIXTURES = [log for log in LOGS if log.fixture]
#: Licences that allow the logs to be redistributed here (with their notice, SOURCE.md).
REDISTRIBUTABLE = {"Apache-2.0", "BSD-2-Clause", "BSD-3-Clause", "MIT", "MPL-2.0"}


SCRIPT = load_script("log_corpus")


def _table_rows() -> list[str]:
    block = DOC.read_text().split(SCRIPT.BEGIN, 1)[1].split(SCRIPT.END, 1)[0]
    return [line for line in block.splitlines() if line.startswith("| `")]


def test_manifest_has_50_logs_from_5_sources_each_with_its_licence_and_kind() -> None:
    assert len(LOGS) >= 50
    assert len({log.repo for log in LOGS}) >= 5
    assert len({(log.repo, log.path) for log in LOGS}) == len(LOGS)
    assert len({log.sha256 for log in LOGS}) == len(LOGS)
    for log in LOGS:
        assert re.fullmatch(r"[0-9a-f]{40}", log.commit) and re.fullmatch(
            r"[0-9a-f]{64}", log.sha256
        )
        assert log.licence and log.kind


@pytest.mark.parametrize("log", FIXTURES, ids=lambda log: log.fixture)
def test_fixture_is_the_manifest_file_under_a_licence_that_allows_it(log: CorpusLog) -> None:
    assert log.fixture is not None
    path = CORPUS / log.fixture
    assert hashlib.sha256(path.read_bytes()).hexdigest() == log.sha256
    assert log.licence in REDISTRIBUTABLE
    assert log.fixture in (CORPUS / "SOURCE.md").read_text()


@pytest.mark.parametrize("log", FIXTURES, ids=lambda log: log.fixture)
def test_fixture_still_gives_the_outcome_of_the_docs_table(log: CorpusLog) -> None:
    assert log.fixture is not None
    outcome = log_outcome(CORPUS / log.fixture)
    assert SCRIPT.table_row(log, outcome) in _table_rows()


def test_docs_table_lists_every_log_with_no_traceback_and_a_named_reason() -> None:
    rows = _table_rows()
    assert len(rows) == len(LOGS)
    assert not [row for row in rows if TRACEBACK in row or SCRIPT.NOT_FETCHED in row]
    outcomes = [row.rsplit(" | ", 1)[1] for row in rows]
    for outcome in outcomes:
        assert outcome.startswith("airborne ") or "; it has " in outcome, outcome
    assert any(outcome.startswith("airborne ") for outcome in outcomes)
    summary = DOC.read_text()
    assert "0 tracebacks, 0 without a named reason" in summary
    assert "with a measured current: 0 of those not airborne." in summary


def test_flight_watch_counts_armed_time_above_home_and_distrusts_heights_astray() -> None:
    watch = FlightWatch()
    samples = [VelocitySample(0.0, 0.0, 0.0, 0.0, 5.0), ArmedSample(0.5, True)]
    samples += [VelocitySample(1.0 + k, 0.0, 0.0, 0.0, 0.5 if k == 3 else 5.0) for k in range(8)]
    samples += [ArmedSample(9.5, False), VelocitySample(10.0, 0.0, 0.0, 0.0, 5.0)]
    samples += [VelocitySample(17.0, 0.0, 0.0, 0.0, 5.0), VelocitySample(18.0, 0.0, 0.0, 0.0, 5.0)]
    assert list(watch.watched(samples)) == samples
    # arming unknown at 0 s, armed 1-8 s, 4 s below 1 m: pairs 0-1, 1-2, 2-3, 5-6, 6-7, 7-8;
    # disarmed from 9.5 s (17-18 s), and 10-17 s is a gap
    assert (watch.flew_s, watch.astray) == (6.0, False)
    watch.observe(VelocitySample(19.0, 0.0, 0.0, 0.0, -600.0))
    assert watch.astray


def _bat_log(path: Path, first_a: float, second_a: tuple[float, float]) -> Path:
    """XKF1 and two BAT instances, 2 s at 10 Hz: the first's current ``first_a``, the
    second's the two of ``second_a`` in turn (A)."""
    log = DataFlashWriter()
    for name in ("XKF1", "BAT"):
        log.define(name)
    for k in range(20):
        t_us = 1_000_000 + 100_000 * k
        log.write("XKF1", TimeUS=t_us, VN=1.0, PD=-5.0)
        log.write("BAT", TimeUS=t_us + 1, Inst=0, Volt=16.0, Curr=first_a)
        log.write("BAT", TimeUS=t_us + 2, Inst=1, Volt=16.1, Curr=second_a[k % 2])
    return log.save(path)


def test_dataflash_takes_the_battery_instance_that_measures_the_current(tmp_path: Path) -> None:
    stream = iter_samples(_bat_log(tmp_path / "two.bin", float("nan"), (12.0, 13.0)))
    batteries = [s for s in stream if isinstance(s, BatterySample)]
    assert {round(b.voltage_v, 3) for b in batteries} == {16.1}
    assert {b.current_a for b in batteries} == {12.0, 13.0}
    assert stream.missing is None


def test_a_current_of_0_a_throughout_is_named_as_no_current_sensor(tmp_path: Path) -> None:
    path = _bat_log(tmp_path / "zero.bin", 0.0, (0.0, 0.0))
    with pytest.raises(UserError, match="0 A throughout"):
        flights_from_stream(iter_samples(path), "zero")
    stream = iter_samples(path)
    assert [s.current_a for s in stream if isinstance(s, BatterySample)][:2] == [0.0, 0.0]
    assert stream.missing == (
        "the battery current is 0 A throughout (BAT or CURR: no current sensor); it has BAT, XKF1"
    )


def test_a_tlog_committed_converted_to_crlf_is_read_repaired_and_names_its_firmware() -> None:
    """A real flight whose repository holds its tlog converted to CRLF line endings: read with
    the conversion undone (the table's row: airborne), said once, its firmware from its text.
    The conversion left the log's own CR LF pairs alone (the file holds no CR CR LF): the 2
    frames that held one lose their CR and stay bad (781 were bad before the repair)."""
    data = (CORPUS / "lucagemma_copter33_crlf.tlog").read_bytes()
    assert data.count(b"\r\n") == data.count(b"\n") > 1000 and b"\r\r\n" not in data
    stream = iter_samples(CORPUS / "lucagemma_copter33_crlf.tlog")
    list(stream)
    assert [cause for cause, _ in stream.problems()] == ["repaired file"]
    assert stream.bad_frames == 2 and stream.firmware == "APM:Copter V3.3 (d6053245)"


def test_tlog_fixture_names_the_messages_it_has() -> None:
    stream = iter_samples(CORPUS / "adgfuzz_sitl_copter.tlog")
    list(stream)
    assert stream.missing is not None
    assert stream.missing.startswith("the battery current is 0 A throughout (BATTERY_STATUS")
    assert {"BATTERY_STATUS", "SYS_STATUS", "GLOBAL_POSITION_INT"} <= stream.message_types


def test_ulog_firmware_and_landed_detector(tmp_path: Path) -> None:
    stream = iter_samples(CORPUS / "roboto_px4_v1_12.ulg")
    list(stream)
    assert stream.firmware == "PX4 v1.12.3 (development build)"
    log = ULogWriter()
    log.add_format("vehicle_land_detected", [("uint64_t", "timestamp"), ("bool", "landed")])
    log.subscribe("vehicle_land_detected")
    for t_us, landed in ((1_000_000, True), (2_000_000, True), (3_000_000, False)):
        log.write("vehicle_land_detected", timestamp=t_us, landed=landed)
    landed_stream = iter_samples(log.save(tmp_path / "land.ulg"))
    assert list(landed_stream) == [LandedSample(1.0, True), LandedSample(3.0, False)]
    assert landed_stream.missing == (
        "no battery reading with a voltage (battery_status); it has vehicle_land_detected"
    )
