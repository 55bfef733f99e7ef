"""``uav-energy replay``: same estimates as the pipeline, CSV/JSON contents, formats, bad input."""

from __future__ import annotations

import argparse
import asyncio
import csv
import json
import os
import random
import socket
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import pytest
from fixtures.dataflash_writer import DataFlashWriter
from fixtures.flight import write_bin, write_ulg
from fixtures.held_voltage import held_voltage_flight, write_vehicle
from fixtures.held_voltage import write_tlog as write_held_tlog
from pymavlink.dialects.v20 import common as mavlink
from script_loader import load_script

from estimator.analysis.replay import replay_log, summarize
from estimator.cli import main
from estimator.commands.replay import CSV_COLUMNS, flight_names, parse_speed
from estimator.estimation.estimate import Estimate
from estimator.estimation.fusion import FusionSettings
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.logs import iter_samples
from estimator.mavlink.config import ServiceConfig
from estimator.mavlink.publish import json_line
from estimator.mavlink.service import Service
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.sim.files import tlog_records, write_tlog
from estimator.sim.run import SimConfig, SimRun
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import Sample

REPO = Path(__file__).resolve().parent.parent
CMU_CRUISE = REPO.parent / "shared/data/cmu_m100_subset/flights_validation_data_clean_cruise.csv"
IRIS_LOG = REPO / "replay" / "iris" / "2016-08-03" / "002" / "002.log"
IRIS_LOG_2 = REPO / "replay" / "iris" / "2016-03-21" / "010" / "010.log"
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
PLANS = load_script("plan_figures")


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same synthetic flight as DataFlash and ULog, and a real IRIS+ tlog."""
    d = tmp_path_factory.mktemp("logs")
    return {
        "bin": write_bin(d / "flight.bin"),
        "ulg": write_ulg(d / "flight.ulg"),
        "tlog": IRIS_LOG,
    }


@pytest.fixture(scope="module")
def sim_run() -> SimRun:
    """A minute of the simulator's mixed plan; its truth power is the built-in model's."""
    return simulate(SimConfig(plan="mixed", duration_s=60.0))


def _replay_cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["replay", *args])
    out, err = capsys.readouterr()
    return code, out, err


# -- same numbers as the pipeline ---------------------------------------------------------------


def _fed(pipeline: Pipeline, samples: Iterable[Sample]) -> list[Estimate]:
    """What a pipeline publishes for these samples, the period open at the end included."""
    estimates = [e for s in samples if (e := pipeline.process(s)) is not None]
    last = pipeline.flush()
    return estimates if last is None else [*estimates, last]


@pytest.mark.parametrize("kind", ["tlog", "bin", "ulg"])
def test_replay_equals_feeding_the_same_samples_through_pipeline(
    logs: dict[str, Path], kind: str
) -> None:
    vehicle = default_vehicle()
    direct = _fed(Pipeline(vehicle), iter_samples(logs[kind]))
    replayed = replay_log(logs[kind], vehicle).estimates
    assert direct and replayed == direct


def test_replay_of_a_sim_tlog_equals_the_daemons_path_over_the_same_frames(
    sim_run: SimRun, tmp_path: Path
) -> None:
    vehicle = default_vehicle()
    # the daemon's path: frames as they arrive → FrameParser → TelemetryDecoder → Pipeline
    parser, decoder = FrameParser(), TelemetryDecoder()
    samples = (
        sample
        for _, frame in tlog_records(sim_run)
        for sample in decoder.decode_all(parser.feed(frame))
    )
    live = _fed(Pipeline(vehicle), samples)
    tlog = write_tlog(sim_run, tmp_path / "sim.tlog", truth_csv=False)
    assert live and replay_log(tlog, vehicle).estimates == live


class _Lines(asyncio.DatagramProtocol):
    """Collects the daemon's JSON-lines datagrams."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def datagram_received(self, data: bytes, addr: object) -> None:
        self.lines.append(data.decode())


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _with_clock_gaps(frames: list[bytes]) -> list[tuple[bytes, bool]]:
    """Each frame, and whether the autopilot's clock (time_boot_ms) moved more than 5 s
    or back since the last stamped frame: a gap in the recording, where a live link is
    silent for as long."""
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    out, last_ms = [], None
    for frame in frames:
        stamps = [
            m.time_boot_ms for m in parser.parse_buffer(frame) or [] if hasattr(m, "time_boot_ms")
        ]
        gap = bool(stamps) and last_ms is not None and not 0 <= stamps[0] - last_ms <= 5000
        last_ms = stamps[-1] if stamps else last_ms
        out.append((frame, gap))
    return out


def _tlog_frames(path: Path) -> list[bytes]:
    """The MAVLink frames of a tlog, in order (each record: 8-byte stamp + frame)."""
    data, frames, pos = path.read_bytes(), [], 0
    while pos + 8 < len(data):
        stx = data[pos + 8]
        length = data[pos + 9] + (8 if stx == 0xFE else 12 + 13 * (data[pos + 10] & 1))
        frames.append(data[pos + 8 : pos + 8 + length])
        pos += 8 + length
    return frames


async def test_the_daemon_fed_a_logs_bytes_over_udp_publishes_the_replays_estimates() -> None:
    """A live run of a recorded IRIS+ flight through the daemon (real UDP sockets on
    127.0.0.1) gives the same estimates as its replay: every JSON line, byte for byte."""
    expected = [json_line(e) for e in replay_log(IRIS_LOG, default_vehicle()).estimates]
    loop = asyncio.get_running_loop()
    json_port, daemon_port = _free_udp_port(), _free_udp_port()
    listener, protocol = await loop.create_datagram_endpoint(
        _Lines, local_addr=("127.0.0.1", json_port)
    )
    config = replace(
        ServiceConfig(),
        connect=f"udpin:127.0.0.1:{daemon_port}",
        json=f"udp:127.0.0.1:{json_port}",
        request_streams=False,
        publish_rate_hz=0.0,
    )
    service = Service(config, default_vehicle())
    stop = asyncio.Event()
    task = asyncio.create_task(service.run(stop))
    while service.link is None:
        await asyncio.sleep(0.01)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as autopilot:
        for i, (frame, gap) in enumerate(_with_clock_gaps(_tlog_frames(IRIS_LOG))):
            if gap:  # the link was silent there (the daemon proves a new clock by silence)
                await asyncio.sleep(1.2)
            autopilot.sendto(frame, ("127.0.0.1", daemon_port))
            if i % 5 == 4:  # paced: no datagram may be lost
                await asyncio.sleep(0.002)
        async with asyncio.timeout(20):
            while len(protocol.lines) < len(expected) - 1:
                await asyncio.sleep(0.02)
    stop.set()  # the daemon closes the open period on the way out: the last line
    assert await asyncio.wait_for(task, 5) == 0
    async with asyncio.timeout(5):
        while len(protocol.lines) < len(expected):
            await asyncio.sleep(0.02)
    listener.close()
    assert service.link.counts["dropped"] == 0
    assert protocol.lines == expected


def test_sim_flight_with_the_vehicles_own_power_replays_with_small_error(
    sim_run: SimRun, tmp_path: Path
) -> None:
    tlog = write_tlog(sim_run, tmp_path / "sim.tlog", truth_csv=False)
    s = summarize([replay_log(tlog, default_vehicle())])
    assert s.power_points > 100 and s.airborne_s > 40
    assert s.power_mape_pct is not None and s.power_mape_pct < 5.0
    assert s.energy_predicted_wh == pytest.approx(s.energy_measured_wh, rel=0.03)


def test_dataflash_and_ulog_of_one_flight_replay_alike_and_match_its_power(
    logs: dict[str, Path],
) -> None:
    vehicle = default_vehicle()
    s_bin = summarize([replay_log(logs["bin"], vehicle)])
    s_ulg = summarize([replay_log(logs["ulg"], vehicle)])
    # the fixture's measured power is the vehicle's own model: errors are the filter's lag
    for s in (s_bin, s_ulg):
        assert s.power_points > 200 and s.airborne_s == pytest.approx(46.6, abs=0.5)
        assert s.power_mape_pct is not None and s.power_mape_pct < 3.0
        assert s.energy_predicted_wh == pytest.approx(s.energy_measured_wh, rel=0.02)
    assert s_bin.energy_measured_wh == pytest.approx(s_ulg.energy_measured_wh, rel=1e-3)
    assert s_bin.power_rmse_w == pytest.approx(s_ulg.power_rmse_w, rel=0.1)


@pytest.mark.needs(CMU_CRUISE.is_file(), "../shared/data is absent")
def test_cmu_csv_replays_through_the_pipeline(tmp_path: Path) -> None:
    head = tmp_path / "cmu.csv"  # the first 3000 rows: a few flights
    with CMU_CRUISE.open() as src:
        head.write_text("".join(line for _, line in zip(range(3001), src, strict=False)))
    flight = replay_log(head, default_vehicle())
    assert flight.format == "cmu-csv" and len(flight.estimates) > 400  # one a second
    assert not flight.estimates[-1].model_only  # the dataset's power is fused
    assert summarize([flight]).power_points > 500


def test_replay_with_the_daemons_config_uses_its_fusion_settings_and_vehicle(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    vehicle_file = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"
    config = tmp_path / "daemon.toml"
    config.write_text(f'[fusion]\nbias_prior_sigma = 0.3\n\n[vehicle]\nfile = "{vehicle_file}"\n')
    out = tmp_path / "est.csv"
    code, _, _ = _replay_cli(capsys, str(IRIS_LOG), "--config", str(config), "--out", str(out))
    assert code == 0
    with out.open() as f:
        sigma = [float(r["bias_sigma"]) for r in csv.DictReader(f)]
    vehicle = load_vehicle(vehicle_file)
    settings = PipelineSettings(fusion=FusionSettings(bias_prior_sigma=0.3))
    direct = _fed(Pipeline(vehicle, settings), iter_samples(IRIS_LOG))
    assert sigma == pytest.approx([e.bias_sigma for e in direct], rel=1e-9)
    default = replay_log(IRIS_LOG, vehicle).estimates
    assert sigma[0] != pytest.approx(default[0].bias_sigma)


def test_paced_replay_gives_the_same_estimates_as_max_speed(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fast, paced = tmp_path / "fast.csv", tmp_path / "paced.csv"
    assert _replay_cli(capsys, str(logs["bin"]), "--out", str(fast))[0] == 0
    # 60 s of log at 3000× real time: 20 ms
    assert _replay_cli(capsys, str(logs["bin"]), "--speed", "3000", "--out", str(paced))[0] == 0
    assert fast.read_text() == paced.read_text()


# -- outputs ------------------------------------------------------------------------------------


def test_csv_has_the_required_columns_and_one_row_per_estimate(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "est.csv"
    code, stdout, _ = _replay_cli(capsys, str(logs["ulg"]), "--out", str(out))
    assert code == 0 and "flight" in stdout
    with out.open() as f:
        rows = list(csv.DictReader(f))
    header = list(rows[0])
    assert header[: len(CSV_COLUMNS) + 1] == ["flight", *CSV_COLUMNS]
    estimates = replay_log(logs["ulg"], default_vehicle()).estimates
    assert len(rows) == len(estimates)
    for row, est in zip(rows, estimates, strict=True):
        assert float(row["time_s"]) == pytest.approx(est.time_s)
        assert float(row["power_model_w"]) == pytest.approx(est.power_model_w)
        assert float(row["endurance_sigma_s"]) == pytest.approx(est.endurance_sigma_s)
    measured = [r["power_measured_w"] for r in rows]
    assert all(m != "" for m in measured)  # the fixture has a current sensor throughout


def test_json_has_the_totals_and_a_row_per_flight(
    logs: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = _replay_cli(capsys, str(logs["tlog"]), str(IRIS_LOG_2), "--json")
    assert code == 0
    result = json.loads(out)
    for key in (
        "messages",
        "duration_s",
        "wall_s",
        "power_rmse_w",
        "power_mape_pct",
        "energy_measured_wh",
        "energy_predicted_wh",
    ):
        assert isinstance(result[key], int | float), key
    rows = result["flights"]
    assert [r["flight"] for r in rows] == ["2016-08-03/002/002", "2016-03-21/010/010"]
    assert result["messages"] == sum(r["messages"] for r in rows)
    assert result["energy_measured_wh"] == pytest.approx(sum(r["energy_measured_wh"] for r in rows))
    # pooled RMSE lies between the flights' RMSEs
    rmse = sorted(r["power_rmse_w"] for r in rows)
    assert rmse[0] <= result["power_rmse_w"] <= rmse[1]
    # IRIS+ hovers at 130–220 W: the measured energy is that power over the airborne time
    mean_power_w = result["energy_measured_wh"] * 3600 / result["airborne_s"]
    assert 100 < mean_power_w < 250


def test_report_writes_the_plots_and_a_summary(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "report"
    assert _replay_cli(capsys, str(logs["bin"]), "--report", str(report))[0] == 0
    pngs = sorted(p.name for p in report.glob("*.png"))
    assert pngs == ["flight-energy.png", "flight-kinematics.png", "flight-power.png"]
    assert all((report / p).read_bytes().startswith(b"\x89PNG") for p in pngs)
    summary = (report / "summary.md").read_text()
    assert "| flight |" in summary and "flight-power.png" in summary


def test_a_log_without_battery_telemetry_is_reported_not_fatal(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = DataFlashWriter()
    log.define("XKF1")
    for k in range(50):
        log.write("XKF1", TimeUS=100_000 * k, C=0, VN=1.0)
    path = log.save(tmp_path / "velocity_only.bin")
    report = tmp_path / "report"
    code, out, err = _replay_cli(capsys, str(path), "--json", "--report", str(report))
    result = json.loads(out)
    assert code == 0 and "gave no estimates" in err
    assert result["messages"] == 50 and result["power_points"] == 0
    assert result["power_rmse_w"] is None and result["power_mape_pct"] is None
    assert "No estimates" in (report / "summary.md").read_text()
    assert not list(report.glob("*.png"))


def test_flight_names_are_the_paths_below_the_common_folder() -> None:
    paths = [Path("/d/2016-03-14/002/002.log"), Path("/d/2016-06-01/002/002.log")]
    assert flight_names(paths) == ["2016-03-14/002/002", "2016-06-01/002/002"]
    assert flight_names([Path("/d/x/one.tlog")]) == ["one"]


# -- bad input ----------------------------------------------------------------------------------


def _bad_inputs(tmp: Path) -> dict[str, Path]:
    data = IRIS_LOG.read_bytes()
    files = {
        "random bytes": os.urandom(20_000),
        "empty file": b"",
        # a CMU header without time, position or the other velocity components
        "csv missing columns": b'"","twist_linear_x","orientation_w","y","flight"\n'
        b'"1",0.1,1,200,3\n',
        "text": b"hello, this is not a log\n",
    }
    paths = {}
    for name, blob in files.items():
        p = tmp / name.replace(" ", "_")
        p.write_bytes(blob)
        paths[name] = p
    paths["directory"] = tmp
    paths["missing file"] = tmp / "nope.tlog"
    paths["truncated tlog"] = tmp / "cut.tlog"
    paths["truncated tlog"].write_bytes(data[: len(data) // 2 + 5])
    return paths


@pytest.mark.parametrize(
    "name",
    ["random bytes", "empty file", "csv missing columns", "text", "directory", "missing file"],
)
def test_bad_input_is_a_one_line_error_with_exit_2(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _replay_cli(capsys, str(_bad_inputs(tmp_path)[name]))
    assert code == 2 and out == ""
    assert err.startswith("uav-energy replay: error:") and err.count("\n") == 1, err
    assert "Traceback" not in err


def test_truncated_tlog_replays_up_to_the_damage_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _bad_inputs(tmp_path)["truncated tlog"]
    code, out, _ = _replay_cli(capsys, str(path), "--json")
    result = json.loads(out)
    assert code == 0 and result["truncated"] == 1
    whole = summarize([replay_log(IRIS_LOG, default_vehicle())])
    assert 0.3 * whole.messages < result["messages"] < 0.7 * whole.messages


def test_damaged_tlogs_replay_or_fail_with_one_line_never_a_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = IRIS_LOG.read_bytes()
    rng = random.Random(5)
    for case in range(12):
        b = bytearray(data)
        at = rng.randrange(9, len(b))
        if case % 3 == 0:
            b = b[:at]
        elif case % 3 == 1:
            for _ in range(40):
                b[rng.randrange(9, len(b))] = rng.randrange(256)
        else:
            b[at:at] = os.urandom(rng.randrange(1, 400))
        path = tmp_path / f"damaged{case}.tlog"
        path.write_bytes(bytes(b))
        code, out, err = _replay_cli(capsys, str(path), "--json")
        assert code in (0, 2), case
        if code == 0:
            assert json.loads(out)["messages"] > 0
        else:
            assert err.count("\n") == 1


def test_a_bad_log_among_several_is_skipped_and_counted(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _bad_inputs(tmp_path)["random bytes"]
    code, out, err = _replay_cli(capsys, str(logs["bin"]), str(bad), "--json")
    result = json.loads(out)
    assert code == 0 and result["logs"] == 1
    assert [s["log"] for s in result["logs_skipped"]] == [str(bad)]
    assert "skipped" in err and "Traceback" not in err


def test_all_logs_bad_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = _bad_inputs(tmp_path)
    code, _, err = _replay_cli(capsys, str(bad["empty file"]), str(bad["text"]))
    assert code == 2 and "no log could be replayed" in err


def test_bad_vehicle_file_is_a_one_line_error(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    vehicle = tmp_path / "v.toml"
    vehicle.write_text("[vehicle]\nname = 'x'\n")
    code, _, err = _replay_cli(capsys, str(logs["bin"]), "--vehicle", str(vehicle))
    assert code == 2 and err.count("\n") == 1


@pytest.mark.parametrize("text", ["0", "-2", "fast", "nan"])
def test_speed_must_be_max_or_a_positive_number(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=r"speed|expected"):
        parse_speed(text)
    assert parse_speed("max") is None and parse_speed("10") == 10.0


def test_a_mission_given_to_the_replay_gives_the_daemons_mission_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """SITL AUTO mission in a 5 m/s wind: the tlog has no mission items (the recorder's upload
    is not in it), so without ``--mission`` there are no MIS_* figures; with the mission file
    the rest of the mission from 30 s after take-off is within 10 % of the energy the vehicle
    drew from there to the disarm (its own V·I; docs/replay.md gives the figures,
    ``scripts/plan_figures.py`` reads them the same way)."""
    flight = PLANS.MISSION_REPLAYED
    common = [str(flight / "flight.tlog"), "--vehicle", str(SITL_VEHICLE)]

    def mission_column(*extra: str) -> list[dict[str, str]]:
        out = tmp_path / f"estimates{len(extra)}.csv"
        code, _, _ = _replay_cli(capsys, *common, "--out", str(out), *extra)
        assert code == 0
        with out.open() as fh:
            return list(csv.DictReader(fh))

    assert all(r["mission_energy_wh"] == "nan" for r in mission_column())
    rows = mission_column("--mission", str(flight / "mission.waypoints"))
    predicted_wh, sigma_wh, drawn_wh = PLANS.mission_figure(flight, rows)
    assert abs(predicted_wh / drawn_wh - 1.0) < 0.10, (predicted_wh, drawn_wh)
    assert sigma_wh > 0


def test_a_broken_mission_file_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    broken = tmp_path / "broken.plan"
    broken.write_text("{not json")
    code, out, err = _replay_cli(capsys, str(IRIS_LOG), "--mission", str(broken))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "broken.plan" in err


def test_replay_says_what_the_daemon_says_of_a_voltage_that_does_not_follow_the_pack(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One warning each, as the daemon logs them: a SITL battery that holds 12.6 V at any
    load, and a voltage that follows the load but not the charge drawn."""
    sitl = REPO / "replay" / "sitl" / "clean_legs" / "flight.tlog"
    code, _, err = _replay_cli(capsys, str(sitl), "--vehicle", str(SITL_VEHICLE))
    assert code == 0 and err.count("does not follow the load") == 1, err
    held = write_held_tlog(held_voltage_flight(150.0), tmp_path / "held.tlog")
    vehicle = write_vehicle(tmp_path / "own_curve.toml")
    code, _, err = _replay_cli(capsys, str(held), "--vehicle", str(vehicle))
    assert code == 0 and err.count("does not follow the charge drawn") == 1, err
    assert "does not follow the load" not in err
