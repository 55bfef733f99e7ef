"""The ``uav-energy`` command: one subcommand per module in :mod:`estimator.commands`.

Each command module defines ``register(subparsers)`` and a ``run(args) -> int``. A
:class:`~estimator.errors.UserError` anywhere ends the process with its one-line message and
exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from estimator import __version__
from estimator.errors import UserError

#: Subcommand modules under estimator/commands, in the order ``--help`` lists them.
COMMANDS = ("demo", "fit", "run", "replay", "sim", "residuals")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="uav-energy",
        description="Onboard energy and endurance estimation for multirotor UAVs.",
    )
    parser.add_argument("--version", action="version", version=f"uav-energy {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"estimator.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"estimator.commands.{name}":
                continue  # command not built yet
            raise
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except UserError as exc:
        print(f"uav-energy {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
