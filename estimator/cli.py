"""The ``uav-energy`` command: one subcommand per module in :mod:`estimator.commands`.

Each command module defines ``register(subparsers)`` and a ``run(args) -> int``. Only the
module of the command being run is imported (the daemon does not pay for matplotlib and
scikit-learn); ``--help`` without a command imports them all to list them. A
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
COMMANDS = ("demo", "run", "replay", "sim", "fit", "residuals", "experiments", "sitl-record")


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every command, or with just ``only``."""
    parser = argparse.ArgumentParser(
        prog="uav-energy",
        description="Onboard energy and endurance estimation for multirotor UAVs.",
    )
    parser.add_argument("--version", action="version", version=f"uav-energy {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in (only,) if only else COMMANDS:
        importlib.import_module(f"estimator.commands.{name.replace('-', '_')}").register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = argv[0] if argv and argv[0] in COMMANDS else None
    args = build_parser(command).parse_args(argv)
    try:
        return int(args.func(args))
    except UserError as exc:
        print(f"uav-energy {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
