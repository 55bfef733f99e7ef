"""``pip install uav-energy`` is the daemon and replay; the rest comes with extras.

pyproject.toml's core dependencies name no package of an extra, and a command run without
its extra's package ends with one line naming the extra and exit code 2. A package is made
missing in a real ``uav-energy`` process by ``sys.modules[name] = None`` (what an install
without it gives: ModuleNotFoundError at the import).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from importlib.metadata import packages_distributions, requires
from pathlib import Path

import pytest

from estimator.cli import EXTRA_OF_MODULE

REPO = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
GUIDED_TLOG = REPO / "tests/data/arducopter_guided.tlog"
#: A SITL flight to the pack's reserve with its truth: replay scores its endurance.
RESERVE_TLOG = REPO / "replay/sitl/battery_reserve/flight.tlog"
SITL_VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"

WITHOUT = """
import sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None
from estimator.cli import main
sys.exit(main(sys.argv[2:]))
"""


def without(modules: list[str], *argv: str) -> subprocess.CompletedProcess[str]:
    """``uav-energy ARGV...`` in a process where ``modules`` cannot be imported."""
    command = [sys.executable, "-c", WITHOUT, ",".join(modules), *argv]
    return subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=REPO)


def requirement_names(requirements: list[str]) -> set[str]:
    """Distribution names of PEP 508 requirements, normalized (extras, versions dropped)."""
    names = (re.match(r"[A-Za-z0-9._-]+", r) for r in requirements)
    return {re.sub(r"[-_.]+", "-", m.group(0)).lower() for m in names if m}


def test_the_core_install_names_no_package_of_an_extra() -> None:
    extras = PYPROJECT["optional-dependencies"]
    core = requirement_names(PYPROJECT["dependencies"])
    assert core == {"numpy", "pymavlink", "rich", "tomli-w", "pyulog"}
    for extra in ("analysis", "fleet", "mavsdk"):
        assert not core & requirement_names(extras[extra]), extra
    assert "uav-energy[analysis,fleet,mavsdk]" in extras["dev"]  # CI installs .[dev]


@pytest.mark.parametrize("module", sorted(EXTRA_OF_MODULE))
def test_each_optional_module_comes_with_the_extra_the_cli_names(module: str) -> None:
    listed = requirement_names(PYPROJECT["optional-dependencies"][EXTRA_OF_MODULE[module]])
    # one level down too: distributed comes with dask[distributed]
    provided = listed | {n for d in listed for n in requirement_names(requires(d) or [])}
    assert set(requirement_names(packages_distributions()[module])) <= provided


ALL_EXTRAS = sorted(EXTRA_OF_MODULE)
ANALYSIS = ["scipy", "sklearn", "matplotlib"]
FLEET = ["dask", "distributed", "pyarrow"]


@pytest.mark.parametrize(
    ("missing", "argv", "extra"),
    [
        (ANALYSIS, ["fit", str(GUIDED_TLOG)], "analysis"),
        (ANALYSIS, ["residuals", str(GUIDED_TLOG)], "analysis"),
        (ANALYSIS, ["sim", "--help"], "analysis"),
        (["matplotlib"], ["replay", str(GUIDED_TLOG), "--report", "{tmp}/report"], "analysis"),
        (FLEET, ["fleet", "replay", str(GUIDED_TLOG), "--out", "{tmp}/fleet.parquet"], "fleet"),
    ],
    ids=["fit", "residuals", "sim", "replay-plots", "fleet"],
)
def test_a_command_without_its_extra_names_it_in_one_line(
    missing: list[str], argv: list[str], extra: str, tmp_path: Path
) -> None:
    out = without(missing, *(a.replace("{tmp}", str(tmp_path)) for a in argv))
    assert out.returncode == 2, out.stderr
    last = out.stderr.splitlines()[-1]
    assert last.startswith(f"uav-energy {argv[0]}: error: this needs ")
    assert last.endswith(f"which the '{extra}' extra installs: pip install 'uav-energy[{extra}]'")
    assert "Traceback" not in out.stderr


def test_replay_and_the_daemon_need_no_extra() -> None:
    out = without(ALL_EXTRAS, "replay", str(RESERVE_TLOG), "--vehicle", str(SITL_VEHICLE), "--json")
    assert out.returncode == 0, out.stderr
    truth = json.loads(out.stdout)["endurance_truth"]  # the σ scored against the truth
    assert truth["estimates"] > 50 and len(truth["reliability"]) > 5
    assert without(ALL_EXTRAS, "run", "--help").returncode == 0


def test_a_missing_module_of_no_extra_is_a_broken_install_not_a_sentence() -> None:
    out = without(["pymavlink"], "replay", str(GUIDED_TLOG))
    assert out.returncode == 1
    assert "Traceback" in out.stderr and "pymavlink" in out.stderr
