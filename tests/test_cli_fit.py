"""``uav-energy fit``: bad inputs end with one sentence and exit 2; JSON, vehicle file, report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from tlog_builder import flight_frames, write_tlog

from estimator.cli import main
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import FlightState, Heave, predict_power_w
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
IRIS = [
    REPO / "replay/iris/2016-08-03/002/002.log",
    REPO / "replay/iris/2016-08-09/003/003.log",
]


def _fails_with_one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    assert "Traceback" not in err
    return err


def test_garbage_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "garbage.tlog"
    path.write_bytes(b"\x01\x02 not a log at all " * 50)
    assert "not a recognised log" in _fails_with_one_line(capsys, ["fit", str(path)])


def test_empty_file_and_directory_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty.log"
    empty.write_bytes(b"")
    assert "empty" in _fails_with_one_line(capsys, ["fit", str(empty)])
    assert "directory" in _fails_with_one_line(capsys, ["fit", str(tmp_path)])


def test_log_without_current_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_tlog(tmp_path / "a.tlog", flight_frames(20, current_ca=-1))
    assert "no battery current" in _fails_with_one_line(capsys, ["fit", str(path)])


def test_log_without_velocity_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_tlog(tmp_path / "a.tlog", flight_frames(20, velocity=False))
    assert "no velocity" in _fails_with_one_line(capsys, ["fit", str(path)])


def test_truncated_log_with_nothing_usable_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "cut.log"
    path.write_bytes(IRIS[0].read_bytes()[:3000])
    _fails_with_one_line(capsys, ["fit", str(path)])


def test_unreadable_csv_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "flights.csv"
    path.write_text(
        '"","time","twist_linear_x","orientation_w","y","flight"\n1,0.0,oops,1,500,268\n'
    )
    err = _fails_with_one_line(capsys, ["fit", str(path)])
    assert "lacks the CMU column" in err


def test_out_without_mass_exits_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    err = _fails_with_one_line(capsys, ["fit", str(IRIS[0]), "--out", str(tmp_path / "v.toml")])
    assert "--mass-kg" in err


@pytest.mark.parametrize("fraction", ["0.9", "-0.1", "nan"])
def test_a_slow_error_fraction_out_of_range_exits_2(
    capsys: pytest.CaptureFixture[str], fraction: str
) -> None:
    err = _fails_with_one_line(capsys, ["fit", str(IRIS[0]), "--slow-error-fraction", fraction])
    assert "--slow-error-fraction must be between 0 and 0.5" in err


@pytest.mark.parametrize("gain", ["3.5", "-0.1", "nan"])
def test_a_heave_gain_out_of_range_exits_2(capsys: pytest.CaptureFixture[str], gain: str) -> None:
    err = _fails_with_one_line(capsys, ["fit", str(IRIS[0]), "--heave-gain", gain])
    assert "--heave-gain must be between 0 and 3" in err


def test_a_stated_heave_gain_is_in_the_vehicle_file_and_in_its_power(tmp_path: Path) -> None:
    """``--heave-gain``: the file states the effect, and its model power follows a vertical
    acceleration by it (a climb that starts costs more than the level model says)."""
    out = tmp_path / "iris.toml"
    argv = ["fit", IRIS[0].as_posix(), "--out", str(out), "--mass-kg", "1.6"]
    assert main([*argv, "--capacity-ah", "5.1", "--folds", "2", "--heave-gain", "1.0"]) == 0
    vehicle = load_vehicle(out)
    assert vehicle.effects == {"heave": {"gain": 1.0}}
    (heave,) = effects_from_tables(vehicle.effects)
    assert isinstance(heave, Heave) and heave.gain == 1.0
    hover = np.zeros(1)
    power_w = [
        float(predict_power_w(vehicle.model, vehicle.mass_kg, state, [heave])[0])
        for state in (
            FlightState(*[hover] * 8, ad_mps2=np.full(1, -2.0)),  # 2 m/s² up: a climb starts
            FlightState(*[hover] * 8),
        )
    ]
    assert power_w[0] > power_w[1] + 0.1 * vehicle.model.hover_power_w


def test_json_report_and_vehicle_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "iris.toml"
    report = tmp_path / "report"
    argv = ["fit", *map(str, IRIS), "--json", "--out", str(out), "--report", str(report)]
    argv += ["--mass-kg", "1.6", "--capacity-ah", "5.1", "--folds", "3"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in (
        "n_points",
        "n_flights",
        "params",
        "stderr",
        "hover_power_w",
        "v_me_mps",
        "v_mr_mps",
    ):
        assert key in summary
    assert set(summary["params"]) == {"c1", "c2", "c3", "c4", "c5"}
    assert set(summary["stderr"]) == {"c1", "c2", "c3", "c4", "c5"}
    assert summary["n_flights"] == 2
    assert summary["split"] == "block"  # two flights: contiguous time blocks
    for name in ("theory", "polynomial", "dnn"):
        assert set(summary["models"][name]) == {"rmse_w", "mape_pct"}
    assert 180 < summary["hover_power_w"] < 230  # June–August configuration
    vehicle = load_vehicle(out)
    assert vehicle.mass_kg == 1.6
    assert vehicle.battery.cells == 3  # from the pack's peak voltage
    assert vehicle.model.hover_power_w == pytest.approx(summary["hover_power_w"])
    assert set(vehicle.model_stderr) == {"c1", "c2", "c3", "c4", "c5"}
    for name in ("scatter.png", "points_per_speed.png", "curves.png", "residuals.png"):
        assert (report / name).stat().st_size > 1000
    assert "Held-out errors" in (report / "summary.md").read_text()
