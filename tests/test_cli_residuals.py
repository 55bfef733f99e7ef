"""``uav-energy residuals``: JSON keys, the --write round trip through replay, the report,
and one-line errors (exit 2) for bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from estimator import cli
from estimator.analysis.replay import replay_log, summarize
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Wind
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

DEFAULT_VEHICLE = Path(cli.__file__).parent / "data" / "default_vehicle.toml"
WIND = Wind(5.0, 60.0)


@pytest.fixture(scope="module")
def windy_tlog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(SimConfig(plan="mixed", duration_s=480.0, seed=31, effects=(WIND,)))
    return write_tlog(run, tmp_path_factory.mktemp("windy") / "windy.tlog", truth_csv=False)


@pytest.fixture(scope="module")
def clean_tlog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = simulate(SimConfig(plan="circles", duration_s=300.0, seed=32))
    return write_tlog(run, tmp_path_factory.mktemp("clean") / "clean.tlog", truth_csv=False)


def run_cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(["residuals", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_has_the_issue_keys_and_effects_in_order(
    windy_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_cli(capsys, str(windy_tlog), "--vehicle", str(DEFAULT_VEHICLE), "--json")
    assert code == 0
    doc = json.loads(out)
    for key in ("rmse_before_w", "rmse_after_w", "mape_before_pct", "mape_after_pct"):
        assert isinstance(doc[key], float)
    assert doc["rmse_after_w"] < doc["rmse_before_w"]
    effect = doc["effects"][0]
    assert {"name", "label", "description", "params", "rmse_after_w"} <= set(effect)
    assert effect["description"].startswith("wind ") and "m/s from" in effect["description"]
    assert doc["rmse_to_floor"] > 0 and 0 <= doc["unexplained_share"] <= 1
    assert effect["name"] == "wind"
    assert set(effect["params"]) == {"speed_mps", "from_deg", "at_s", "until_s"}
    assert abs(effect["params"]["speed_mps"] - WIND.speed_mps) < 1.0
    channels = doc["attribution"]["channels"]
    assert doc["attribution"]["best_channel"] == channels[0]["channel"]
    assert "speed_mps" in {c["channel"] for c in channels}
    assert doc["attribution"]["verdict"].startswith("added wind")


def test_online_flag_reports_the_tracked_wind_per_flight(
    windy_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_cli(
        capsys, str(windy_tlog), "--vehicle", str(DEFAULT_VEHICLE), "--json", "--online"
    )
    assert code == 0
    (online,) = json.loads(out)["online"]
    assert online["flight"] == "windy"
    assert abs(online["wind_speed_mps"] - WIND.speed_mps) < 1.0
    assert abs((online["wind_from_deg"] - WIND.from_deg + 180) % 360 - 180) < 20.0
    assert abs(online["mass_delta_kg"]) < 0.1


def test_flight_filter_rejects_unknown_ids(
    windy_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run_cli(
        capsys, str(windy_tlog), "--vehicle", str(DEFAULT_VEHICLE), "--flight", "nope"
    )
    assert code == 2
    assert "--flight nope not in the logs (flights: windy)" in err


def test_clean_flight_gives_an_empty_effect_list(
    clean_tlog: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_cli(capsys, str(clean_tlog), "--vehicle", str(DEFAULT_VEHICLE), "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["effects"] == []
    assert doc["rmse_after_w"] == doc["rmse_before_w"]


def test_write_round_trip_lowers_the_replay_error(
    windy_tlog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    written = tmp_path / "with_wind.toml"
    report = tmp_path / "report"
    code, out, _err = run_cli(
        capsys,
        str(windy_tlog),
        "--vehicle",
        str(DEFAULT_VEHICLE),
        "--write",
        str(written),
        "--report",
        str(report),
    )
    assert code == 0
    assert "wind" in out
    vehicle = load_vehicle(written)
    (wind,) = effects_from_tables(vehicle.effects)
    assert isinstance(wind, Wind)
    assert abs(wind.speed_mps - WIND.speed_mps) < 1.0
    assert vehicle.model == default_vehicle().model
    frozen = PipelineSettings(track_effects=False)  # the vehicle files' effects alone
    before = summarize([replay_log(windy_tlog, default_vehicle(), frozen)])
    after = summarize([replay_log(windy_tlog, vehicle, frozen)])
    assert before.power_rmse_w is not None and after.power_rmse_w is not None
    assert after.power_rmse_w < 0.5 * before.power_rmse_w
    # the daemon's default tracks wind online; starting from the written wind still helps
    tracked_before = summarize([replay_log(windy_tlog, default_vehicle())]).power_rmse_w
    tracked_after = summarize([replay_log(windy_tlog, vehicle)]).power_rmse_w
    assert tracked_before is not None and tracked_after is not None
    assert tracked_after < tracked_before
    for name in ("summary.md", "residual_time.png", "residual_channels.png", "attribution.png"):
        assert (report / name).stat().st_size > 0
    assert "| 1 | wind |" in (report / "summary.md").read_text()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.tlog"], "does not exist"),
        (["{clean}", "--vehicle", "nowhere.toml"], "does not exist"),
        (["{clean}", "--candidates", "wind,gremlins"], "unknown effect"),
        (["{clean}", "--folds", "1"], "--folds"),
        (["{clean}", "--block-s", "-3"], "--block-s"),
        (["{garbage}"], "not a recognised log"),
        (["{short}"], "airborne"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    args: list[str],
    message: str,
    clean_tlog: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    garbage = tmp_path / "garbage.tlog"
    garbage.write_bytes(b"this is not a flight log\n" * 20)
    short = write_tlog(
        simulate(SimConfig(plan="mixed", duration_s=25.0, seed=1)), tmp_path / "short.tlog", False
    )
    paths = {"clean": str(clean_tlog), "garbage": str(garbage), "short": str(short)}
    argv = [a.format(**paths) for a in args]
    if "--vehicle" not in argv:
        argv += ["--vehicle", str(DEFAULT_VEHICLE)]
    code, _out, err = run_cli(capsys, *argv)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("uav-energy residuals: error:")
    assert message in lines[0]
    assert "Traceback" not in err


def test_a_turning_wind_the_autopilot_reported_is_written_as_its_first_steady_wind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """ArduPilot SITL, wind from 90° turning to 180° at 143 s: the autopilot's WIND report is
    the named effect; a vehicle file holds one wind, the one before the turn."""
    repo = Path(__file__).resolve().parent.parent
    written = tmp_path / "sitl.toml"
    code, out, err = run_cli(
        capsys,
        str(repo / "replay" / "sitl" / "wind_turn" / "flight.tlog"),
        "--vehicle",
        str(repo / "config" / "vehicles" / "ardupilot_sitl_quad.toml"),
        "--write",
        str(written),
        "--report",
        str(tmp_path / "report"),
    )
    assert code == 0
    assert "the autopilot's wind ×" in out
    assert "a second wind window is not written" in err
    wind = next(e for e in effects_from_tables(load_vehicle(written).effects) if e.name == "wind")
    assert isinstance(wind, Wind)
    assert abs(wind.from_deg - 90.0) < 25.0 and wind.at_s is None
    assert wind.until_s is not None and abs(wind.until_s - 143.3) < 10.0
