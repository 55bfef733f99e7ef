"""The ``uav-energy`` command: one subcommand per module in :mod:`estimator.commands`.

Each command module defines ``register(subparsers)`` and a ``run(args) -> int``. Only the
module of the command being run is imported (the daemon does not pay for matplotlib and
scikit-learn); ``--help`` without a command lists the one-line summaries below and imports
no command module (numpy, pymavlink and scipy stay unloaded). A
:class:`~estimator.errors.UserError` anywhere ends the process with its one-line message and
exit code 2, an :class:`~estimator.errors.Unavailable` (a missing or busy serial device) with
exit code 75 (``EXIT_UNAVAILABLE``: systemd restarts the daemon). When the reader of stdout
leaves early (``uav-energy plan ... --json | head -1``), the command stops without a word,
as Unix tools do, with exit code 1 (what rich's console does when its table meets the closed
pipe). A command that imports a package of an extra that is not installed (``pip install
uav-energy`` is the daemon and replay only) says which extra in one line, exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import select
import sys
from collections.abc import Sequence

from estimator import __version__
from estimator.errors import EXIT_UNAVAILABLE, Unavailable, UserError

#: Subcommands with their one-line summaries, in the order ``--help`` lists them; the module
#: of ``a-b`` is ``estimator/commands/a_b.py``.
COMMANDS = {
    "demo": "simulated flight with a hidden wind, live into the daemon",
    "run": "run the onboard daemon on a MAVLink link",
    "replay": "replay recorded flights through the estimator pipeline",
    "sim": "fly a simulated multirotor over MAVLink (hidden effects optional)",
    "fit": "fit the power model to flight logs",
    "residuals": "find the effects the power model lacks from flight logs",
    "fleet": "replay, fit or residuals over many logs on a dask cluster; trends by date",
    "experiments": "reproduce the paper's experiments on the built-in vehicle",
    "sitl-record": "fly scenarios in ArduCopter SITL and record tlog, DataFlash and truth",
    "plan": "energy of a mission file per leg, totals and feasibility, in wind and payload",
}

#: The extra of pyproject.toml's ``[project.optional-dependencies]`` that installs each
#: optional top-level module.
EXTRA_OF_MODULE = {
    "scipy": "analysis",
    "sklearn": "analysis",
    "matplotlib": "analysis",
    "dask": "fleet",
    "distributed": "fleet",
    "pyarrow": "fleet",
}


#: Exit code when stdout's reader has gone (rich's console, printing a table, gives the same).
EXIT_STDOUT_CLOSED = 1


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
    try:
        args = build_parser(command).parse_args(argv)
    except ModuleNotFoundError as exc:
        return _missing_extra(command, exc)
    try:
        code = int(args.func(args))
        if not sys.stdout.closed:  # the daemon closes it on a signal
            sys.stdout.flush()  # a reader gone shows here, not at the interpreter's exit
        return code
    except BrokenPipeError:
        if not _stdout_closed():
            raise  # a socket or another pipe of the command: not the reader of its output
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the final flush
        return EXIT_STDOUT_CLOSED
    except ModuleNotFoundError as exc:
        return _missing_extra(args.command, exc)
    except UserError as exc:
        print(f"uav-energy {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except Unavailable as exc:
        print(f"uav-energy {args.command}: unavailable: {exc}", file=sys.stderr)
        return EXIT_UNAVAILABLE
    except KeyboardInterrupt:
        return 130


def _stdout_closed() -> bool:
    """Whether stdout is a pipe or socket whose reader has closed it (poll says POLLERR)."""
    poller = select.poll()
    poller.register(sys.stdout.fileno(), select.POLLOUT)
    return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))


def _missing_extra(command: str | None, exc: ModuleNotFoundError) -> int:
    """Exit code 2 and the one line naming the extra that installs the missing module; ``exc``
    again for a module of no extra (a broken install, not a choice of extras)."""
    module = (exc.name or "").split(".")[0]
    if module not in EXTRA_OF_MODULE:
        raise exc
    extra = EXTRA_OF_MODULE[module]
    print(
        f"uav-energy {command}: error: this needs {module}, which the '{extra}' extra "
        f"installs: pip install 'uav-energy[{extra}]'",
        file=sys.stderr,
    )
    return 2


if __name__ == "__main__":
    sys.exit(main())
