"""``uav-energy`` itself: the command list is cheap, each command's own help is complete."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from estimator.cli import COMMANDS, build_parser

#: Modules ``uav-energy --help`` must not load (each costs 0.1–2 s at start-up).
HEAVY = ("numpy", "scipy", "pymavlink", "sklearn", "matplotlib", "filterpy", "rich")


def test_help_lists_every_command_without_loading_numpy_pymavlink_or_scipy() -> None:
    code = (
        "import sys\nfrom estimator.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
        f"print('LOADED', sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))"
    )
    env = {**os.environ, "COLUMNS": "200"}  # one summary a line
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    )
    for name, summary in COMMANDS.items():
        assert name in out.stdout and summary in out.stdout
    assert "LOADED []" in out.stdout


@pytest.mark.parametrize("name", list(COMMANDS))
def test_each_command_registers_its_own_arguments(name: str) -> None:
    parser = build_parser(name)
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args([name, "--help"])
    assert exit_.value.code == 0
