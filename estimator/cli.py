"""The ``uav-energy`` command: one subcommand per module in :mod:`estimator.commands`.

Each command module defines ``register(subparsers)`` and a ``run(args) -> int``. Only the
module of the command being run is imported (the daemon does not pay for matplotlib and
scikit-learn); ``--help`` without a command lists the one-line summaries below and imports
no command module (numpy, pymavlink and scipy stay unloaded). A
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

#: Subcommands with their one-line summaries, in the order ``--help`` lists them; the module
#: of ``a-b`` is ``estimator/commands/a_b.py``.
COMMANDS = {
    "demo": "simulated flight with a hidden wind, live into the daemon",
    "run": "run the onboard daemon on a MAVLink link",
    "replay": "replay recorded flights through the estimator pipeline",
    "sim": "fly a simulated multirotor over MAVLink (hidden effects optional)",
    "fit": "fit the power model to flight logs",
    "residuals": "find the effects the power model lacks from flight logs",
    "experiments": "reproduce the paper's experiments on the built-in vehicle",
    "sitl-record": "fly scenarios in ArduCopter SITL and record tlog, DataFlash and truth",
    "plan": "energy of a mission file per leg, totals and feasibility, in wind and payload",
}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser of ``only`` with its arguments, or the list of every command."""
    parser = argparse.ArgumentParser(
        prog="uav-energy",
        description="Onboard energy and endurance estimation for multirotor UAVs.",
    )
    parser.add_argument("--version", action="version", version=f"uav-energy {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    if only is None:
        for name, summary in COMMANDS.items():
            subparsers.add_parser(name, help=summary)
    else:
        module = only.replace("-", "_")
        importlib.import_module(f"estimator.commands.{module}").register(subparsers)
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
