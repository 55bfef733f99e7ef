"""What a new user runs into: a log given as a mission, a flag out of range, a payload the
vehicle cannot lift, an output folder that does not exist, and warnings said once per run."""

from __future__ import annotations

import copy
import logging
from dataclasses import replace
from pathlib import Path

import pytest
from test_service import flight, play, running, wait_for  # noqa: F401 (flight: a fixture)
from tlog_builder import without_firmware_text

from estimator.cli import main
from estimator.logs import iter_samples, load_flights
from estimator.logs.sanity import VERTICAL_VELOCITY, flight_warnings, vertical_velocity_problem
from estimator.mavlink.config import ServiceConfig

REPO = Path(__file__).resolve().parent.parent
TLOG = REPO / "tests/data/arducopter_guided.tlog"
BIN = REPO / "tests/data/arducopter_guided.bin"
SITL_QUAD = REPO / "config/vehicles/ardupilot_sitl_quad.toml"  # 3.0 kg
MISSION = REPO / "replay/sitl/missions/tall_wind4/mission.plan"
#: IRIS+ logs of APM:Copter 3.3, whose GLOBAL_POSITION_INT.vz is positive up.
IRIS = sorted((REPO / "replay/iris").rglob("*.log"))


def _error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    """Run the CLI; it must fail with exit 2 and one line on stderr, which is returned."""
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    return line


@pytest.mark.parametrize(("log", "fmt"), [(TLOG, "tlog"), (BIN, "dataflash")])
def test_plan_of_a_flight_log_says_it_is_a_log_not_a_mission(
    capsys: pytest.CaptureFixture[str], log: Path, fmt: str
) -> None:
    line = _error(capsys, ["plan", str(log), "--vehicle", str(SITL_QUAD)])
    assert f"is a flight log ({fmt}), not a mission" in line
    assert "codec" not in line


def test_plan_with_a_payload_beyond_twice_the_mass_cannot_lift_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = ["plan", str(MISSION), "--vehicle", str(SITL_QUAD), "--json"]
    line = _error(capsys, [*argv, "--payload", "50"])
    assert "--payload 50 kg: the vehicle cannot lift it (53 kg is 17.7×" in line
    assert _error(capsys, [*argv, "--payload", "3.1"]).startswith("uav-energy plan: error: --pay")
    assert main([*argv, "--payload", "2.9"]) == 0


def test_run_names_the_flag_not_the_config_key(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    line = _error(capsys, ["run", "--rate", "-1"])
    assert line == "uav-energy run: error: --rate must be in [0, 100] Hz (0: every estimate)"
    config = tmp_path / "c.toml"
    config.write_text("[publish]\nrate_hz = -1\n")
    assert "config 'publish_rate_hz' must be" in _error(capsys, ["run", "--config", str(config)])


def test_fit_refuses_an_output_folder_that_does_not_exist(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "missing" / "x.toml"
    argv = ["fit", str(TLOG), "--mass-kg", "3", "--capacity-ah", "2.2", "--out", str(out)]
    assert f"folder {out.parent} does not exist" in _error(capsys, argv)
    assert not out.parent.exists()


def test_sitl_record_without_a_binary_mentions_binary(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("ARDUPILOT_SITL_BINARY", str(tmp_path / "no-arducopter"))
    line = _error(capsys, ["sitl-record", "clean_legs", "--out", str(tmp_path / "out")])
    assert "give --binary FILE" in line


@pytest.fixture
def unnamed_iris(tmp_path: Path) -> list[Path]:
    """The IRIS+ logs without their firmware text: each sends vz positive up unannounced."""
    return [without_firmware_text(log, tmp_path / f"{i}-{log.name}") for i, log in enumerate(IRIS)]


def test_vertical_velocity_warning_is_one_line_per_run() -> None:
    """``fit`` and ``residuals`` check the flights as read: a vertical velocity the readers
    cannot turn (here the IRIS+ flights' turned over after reading, as a log's other source
    would have it) is one line for the run."""
    flights = [replace(f, vd_mps=-f.vd_mps) for f in load_flights(IRIS)]
    wrong = [f for f in flights if vertical_velocity_problem(f.time_s, f.vd_mps, f.alt_m)]
    assert len(wrong) >= 3
    (warning,) = flight_warnings(flights)
    assert warning.startswith(f"{wrong[0].flight_id}: vertical velocity disagrees in sign")
    assert warning.endswith(f"(and in {len(wrong) - 1} more of the {len(flights)} flights)")


def test_replay_says_each_warning_once_with_a_count(
    capsys: pytest.CaptureFixture[str], unnamed_iris: list[Path]
) -> None:
    wrong = 0
    for log in unnamed_iris:
        stream = iter_samples(log)
        list(stream)
        wrong += any(cause == VERTICAL_VELOCITY for cause, _ in stream.problems())
    assert wrong >= 3
    assert main(["replay", *map(str, unnamed_iris), "--vehicle", str(SITL_QUAD)]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert sum("disagrees in sign" in line for line in lines) == 1
    assert lines[-1] == (
        "uav-energy replay: warning: the vertical velocity warning above holds for "
        f"{wrong - 1} more logs too"
    )


async def test_daemon_logs_the_estimating_mode_once_per_change(
    flight: list,  # noqa: F811 (the fixture)
    caplog: pytest.LogCaptureFixture,
) -> None:
    """No current on the ground (−1: not measured), then a current sensor: "model only" is
    said when telemetry flows, "fused" once when the current appears."""
    messages = [copy.copy(m) for _, m in flight[:800]]
    for m in messages[:300]:
        if m.get_type() in ("SYS_STATUS", "BATTERY_STATUS"):
            m.current_battery = -1
    caplog.set_level(logging.INFO, logger="uav_energy")
    async with running(ServiceConfig(stale_after_s=30.0)) as (service, sender):
        await play(sender, messages[:300])
        await wait_for(lambda: service.out.latest is not None)
        await play(sender, messages[300:])
        await wait_for(lambda: service.out.latest is not None and not service.out.latest.model_only)
    modes = [r.getMessage() for r in caplog.records if "estimating" in r.getMessage()]
    assert modes == [
        "telemetry flowing: estimating, model only (no current measured)",
        "estimating, fused with the measured current",
    ]
