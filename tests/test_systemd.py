"""Running under systemd: the unit file, exit codes that decide restarts, config-relative
paths."""

from __future__ import annotations

import configparser
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from estimator.cli import build_parser
from estimator.commands.run import config_from_args
from estimator.errors import EXIT_UNAVAILABLE
from estimator.physics.vehicle import load_vehicle

ROOT = Path(__file__).resolve().parents[1]
UNIT = ROOT / "config" / "uav-energy.service"
EXE = Path(sys.executable).with_name("uav-energy")


def unit_options() -> dict[str, list[str]]:
    """The [Service] options of the unit, each with every value it is given."""
    parser = configparser.RawConfigParser(strict=False, dict_type=_MultiDict)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(UNIT.read_text())
    return {k: v.split("\n") for k, v in parser["Service"].items()}


class _MultiDict(dict):  # type: ignore[type-arg]
    """Repeated keys (DeviceAllow=…) keep every value, newline-joined."""

    def __setitem__(self, key: str, value: object) -> None:
        if isinstance(value, list) and key in self:
            self[key].extend(value)
            return
        super().__setitem__(key, value)


def test_unit_restarts_on_a_missing_device_not_on_a_bad_config_and_is_hardened() -> None:
    options = unit_options()
    one = {k: v[-1] for k, v in options.items()}
    assert one["Restart"] == "on-failure" and one["RestartPreventExitStatus"] == "2"
    assert str(EXIT_UNAVAILABLE) not in one["RestartPreventExitStatus"].split()
    assert one["User"] == "uav-energy" and one["SupplementaryGroups"] == "dialout"
    assert one["ExecStart"].startswith("/opt/uav-energy/.venv/bin/uav-energy run --config ")
    assert one["StateDirectory"] == "uav-energy"
    assert one["ReadWritePaths"] == "/var/lib/uav-energy"
    for key, value in {
        "NoNewPrivileges": "true",
        "ProtectSystem": "strict",
        "ProtectHome": "true",
        "PrivateTmp": "true",
        "DevicePolicy": "closed",
        "CapabilityBoundingSet": "",
        "UMask": "0077",
    }.items():
        assert one[key] == value, key
    assert {"char-ttyACM rw", "char-ttyUSB rw", "char-ttyAMA rw"} <= set(options["DeviceAllow"])


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_unit_passes_systemd_analyze_verify_and_security(tmp_path: Path) -> None:
    """``systemd-analyze verify`` is silent (the ExecStart pointed at this checkout), and the
    offline security review rates the unit's exposure at most 2.0 of 10 (it was 8.5)."""
    unit = tmp_path / "uav-energy.service"
    unit.write_text(UNIT.read_text().replace("/opt/uav-energy/.venv/bin/uav-energy", str(EXE)))
    verify = subprocess.run(
        ["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, check=False
    )
    assert verify.returncode == 0 and not verify.stderr.strip(), verify.stderr
    security = subprocess.run(
        ["systemd-analyze", "security", "--offline=true", "--no-pager", str(unit)],
        capture_output=True,
        text=True,
        check=False,
    )
    match = re.search(r"Overall exposure level for \S+: ([\d.]+)", security.stdout)
    assert match is not None, security.stdout + security.stderr
    assert float(match.group(1)) <= 2.0, security.stdout


def test_missing_serial_device_exits_75_and_a_bad_config_2(tmp_path: Path) -> None:
    """A real ``uav-energy run`` process: a serial device that does not exist (yet) is exit
    code 75 with one line (systemd restarts it); a file that is not a serial port, or a
    broken config, is exit code 2 (no restart)."""

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [str(EXE), "run", *args], capture_output=True, text=True, timeout=60, check=False
        )

    missing = run("--connect", str(tmp_path / "ttyACM7") + ":57600")
    assert missing.returncode == EXIT_UNAVAILABLE == 75, missing.stderr
    assert missing.stderr.strip().splitlines() == [
        f"uav-energy run: unavailable: cannot open {tmp_path}/ttyACM7:57600: "
        "No such file or directory"
    ]
    not_a_tty = tmp_path / "ttyACM8"
    not_a_tty.write_bytes(b"")
    wrong = run("--connect", f"{not_a_tty}:57600")
    assert wrong.returncode == 2 and "is not a serial port" in wrong.stderr, wrong.stderr
    conf = tmp_path / "config.toml"
    conf.write_text('[link]\nconnect = "/dev/ttyACM0:12345"\n')
    assert run("--config", str(conf)).returncode == 2


def test_paths_in_a_config_file_are_relative_to_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    etc = tmp_path / "etc" / "uav-energy"
    (etc / "vehicles").mkdir(parents=True)
    shutil.copy(ROOT / "config" / "vehicles" / "iris_plus_2016_03.toml", etc / "vehicles")
    conf = etc / "config.toml"
    conf.write_text(
        '[vehicle]\nfile = "vehicles/iris_plus_2016_03.toml"\n'
        '[signing]\nkey_file = "mavlink.key"\n'
        '[state]\nfile = "/var/lib/uav-energy/state.json"\n'
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    args = build_parser("run").parse_args(["run", "--config", str(conf)])
    config = config_from_args(args)
    assert config.vehicle == str(etc / "vehicles" / "iris_plus_2016_03.toml")
    assert config.signing_key_file == str(etc / "mavlink.key")
    assert config.state_file == "/var/lib/uav-energy/state.json"  # absolute stays
    assert load_vehicle(config.vehicle).battery.cells > 0
    # a flag is relative to the working directory, as usual for a command line
    args = build_parser("run").parse_args(["run", "--config", str(conf), "--vehicle", "v.toml"])
    assert config_from_args(args).vehicle == "v.toml"
