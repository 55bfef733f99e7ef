"""The result figures of README.md and docs/*.md, generated from the committed data.

Each ``<!-- figures:NAME -->`` … ``<!-- /figures:NAME -->`` block of those documents
(:mod:`estimator.reports.doc_blocks`) has one generator that prints its text. The generators
live in the topic modules of this folder, whose docstrings say what each block is; this script
loads them, registers their blocks (with the data outside the repository a block reads, and
the test that checks a slow one) and rewrites or checks the documents:

- ``iris_figures.py``: ``iris-replay-*`` (the IRIS+ flights of
  ``../shared/data/iris_quadcopter_logs`` replayed, each period with its vehicle file, and
  with the built-in vehicle), ``replay-regression-march``, ``fleet-iris-file-masses``;
- ``replay_figures.py``: ``sim-mixed-*``, ``sitl-run1-*``, ``replay-arducopter-bin`` (single
  flights replayed with the built-in vehicle), ``iris-vz-sign``, ``sitl-vz-sign`` (the
  vertical velocity check);
- ``plan_figures.py``: ``plan-*`` (``uav-energy plan`` against the SITL missions of
  ``replay/sitl/missions``) and ``replay-mission`` (one of them given to a replay);
- ``fit_figures.py``: ``fit-*`` (``uav-energy fit`` of the real logs as ``make fit-real`` runs
  it, and variants), ``sitl-quad-fit*``, ``pack-fit-sitl-*``; ``experiments_figures.py``:
  ``experiments-*`` (``uav-energy experiments``, seed 0);
- ``residual_figures.py``: ``residuals-sim-*`` (simulated flights, each with an effect hidden
  from the built-in vehicle; ``residuals-sim-changing*``, checked by
  ``tests/test_residual_figures.py``), ``residuals-iris-table``, ``residuals-iris-summer``;
  ``real_residual_figures.py``: the other ``residuals-iris-*`` and ``residuals-cmu-*``;
  ``vertical_figures.py``: ``residuals-sitl-*``; ``online_figures.py``: ``online-sim-*``;
- ``sitl_figures.py``: ``sitl-recordings-table``, ``sitl-hexa-energy``, ``sitl-wind-cost``,
  ``sitl-effects-*``, ``sitl-held-*``, ``sitl-payload-hover-current``, ``sitl-hover-power-*``,
  ``sitl-slow-error`` (the recordings of ``replay/sitl`` and ``replay/sitl_held``);
- ``tracker_figures.py``: ``tracker-sitl*``, ``tracker-cmu*`` (the online tracker),
  ``tracked-wind-sitl``;
- ``pack_figures.py``: ``pack-sitl-*``; ``ensemble_figures.py``: ``pack-ensemble-*``,
  ``hover-cruise-*``;
  ``endurance_figures.py``: the prose figures around them (``pack-sitl-curve*``,
  ``pack-sitl-unscored``, ``pack-sitl-sigma-left``, ``pack-sitl-restarts-tuning``,
  ``hover-cruise-px4-*``, ``period-end-apart``) and ``state-restart-table``;
- ``fleet_figures.py``: the other ``fleet-iris-*`` (``uav-energy fleet fit`` and ``fleet
  trends`` of the IRIS+ logs).

A block whose results another test computes anyway is checked by that test
(:data:`CHECKED_BY`), every other one by ``tests/test_figures.py``.

Run: ``python scripts/figures.py`` rewrites the blocks (``make figures``);
``python scripts/figures.py --check`` prints the stale ones and exits 1 (``make
figures-check``; ``tests/test_figures.py`` runs the same check). Every generator is
deterministic: the check compares text exactly.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import os
import sys
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path
from types import ModuleType

from estimator import cli
from estimator.errors import UserError
from estimator.reports.doc_blocks import Block, blocks_in, rewrite

REPO = Path(__file__).resolve().parent.parent
DOCUMENTS = (REPO / "README.md", *sorted((REPO / "docs").glob("*.md")))
SHARED_DATA = REPO.parent / "shared" / "data"
IRIS = SHARED_DATA / "iris_quadcopter_logs"
SITL_RUN1 = SHARED_DATA / "ardupilot_sitl" / "run1_default_quad.tlog"


def script_module(name: str, folder: Path = REPO / "scripts") -> ModuleType:
    """Another script of this folder (or of ``folder``), loaded as a module."""
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GENERATORS: dict[str, Callable[[], str]] = {}
#: The blocks whose generator reads data outside the repository, and that data.
OUTSIDE_DATA: dict[str, Path] = {}
#: The blocks whose results another test computes anyway (a minute or more of CPU), and that
#: test: it checks them, ``tests/test_figures.py`` does not.
CHECKED_BY: dict[str, str] = {}


def register(
    blocks: Mapping[str, Callable[[], str]],
    reads: Path | None = None,
    checked_by: str | None = None,
) -> None:
    """Register ``blocks`` (block name → the function that prints it) as the generators of the
    blocks of those names; ``reads``: the data outside the repository they need;
    ``checked_by``: the test that checks slow ones."""
    for name, fn in blocks.items():
        assert name not in GENERATORS, f"two generators for block {name}"
        GENERATORS[name] = fn
        if reads is not None:
            OUTSIDE_DATA[name] = reads
        if checked_by is not None:
            CHECKED_BY[name] = checked_by


def run_cli(*argv: str) -> str:
    """What ``uav-energy ARGV…`` prints on stdout (run in this process)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = cli.main(list(argv))
    if code != 0:
        raise UserError(f"uav-energy {' '.join(argv)} ended with exit code {code}")
    return out.getvalue()


# --- the generators, by topic ---------------------------------------------------------------------

SITL_RECORDINGS_TEST = "tests/test_sitl_recordings.py"
SITL_HELD_TEST = "tests/test_sitl_held_out.py"

fits = script_module("fit_figures")
sitl = script_module("sitl_figures")
iris = script_module("iris_figures")
replays = script_module("replay_figures")
plans = script_module("plan_figures")
residual_figures = script_module("residual_figures")
vertical_figures = script_module("vertical_figures")
vertical_fit = script_module("vertical_fit", REPO / "tests")
trackers = script_module("tracker_figures")
tracker_sitl = script_module("tracker_sitl")
tracker_cmu = script_module("tracker_cmu")
pack_figures = script_module("pack_figures")
ensemble_figures = script_module("ensemble_figures")

register(iris.iris_generators(IRIS, fits), reads=IRIS)
register(iris.generators())
register(replays.generators(run_cli))
register(replays.iris_generators(IRIS, fits), reads=IRIS)
register(replays.run1_generators(run_cli, SITL_RUN1), reads=SITL_RUN1.parent)
register(plans.generators(run_cli, fits, vertical_fit))

register(fits.real_generators(run_cli, SHARED_DATA), reads=SHARED_DATA)
register(fits.run1_generators(run_cli, SITL_RUN1), reads=SITL_RUN1.parent)
register(fits.sitl_generators(run_cli, sitl, script_module("pack_fit_sitl")))
register(script_module("experiments_figures").generators(fits))

register(residual_figures.generators(run_cli))
register(residual_figures.changing_generators(run_cli), checked_by="tests/test_residual_figures.py")
register(residual_figures.iris_generators(run_cli, IRIS), reads=IRIS)
register(
    script_module("real_residual_figures").generators(
        run_cli,
        IRIS,
        tracker_cmu.DATA,
        lambda: residual_figures.iris_runs(run_cli, IRIS)["June–August"],
    ),
    reads=SHARED_DATA,
)
register(vertical_figures.generators(run_cli, vertical_fit))
register(script_module("online_figures").generators())

register(sitl.generators())
register(sitl.recordings_generators(), checked_by=SITL_RECORDINGS_TEST)
register(sitl.effects_generators(), checked_by="tests/test_sitl_effects.py")
register(sitl.held_generators(), checked_by=SITL_HELD_TEST)
register(trackers.sitl_generators(tracker_sitl), checked_by="tests/test_tracker_sitl.py")
register(trackers.held_generators(tracker_sitl, sitl.HELD_RECORDINGS), checked_by=SITL_HELD_TEST)
register(trackers.cmu_generators(tracker_cmu), reads=tracker_cmu.DATA)
register(
    trackers.wind_generators(script_module("tracked_wind_sitl")), checked_by=SITL_RECORDINGS_TEST
)

register(pack_figures.generators(script_module("pack_state_sitl")))
register(ensemble_figures.generators())
register(
    script_module("endurance_figures").generators(
        pack_figures,
        ensemble_figures,
        script_module("period_ends", REPO / "tests"),
        script_module("trust", REPO / "bench"),
    )
)
register(
    script_module("fleet_figures").generators(
        IRIS,
        {title: pattern for title, (pattern, _) in iris.PERIODS.items()},
        partial(fits.iris_pooled_hover_w, run_cli, SHARED_DATA),
    ),
    reads=SHARED_DATA,
)


# --- the documents ----------------------------------------------------------------------------


def all_blocks() -> list[Block]:
    return [b for path in DOCUMENTS for b in blocks_in(path)]


def generated(names: set[str]) -> dict[str, str]:
    """Each named block's text now; UserError for a block without a generator or data."""
    unknown = names - GENERATORS.keys()
    if unknown:
        raise UserError(f"no generator for block(s) {', '.join(sorted(unknown))}")
    for name in sorted(names & OUTSIDE_DATA.keys()):
        if not OUTSIDE_DATA[name].is_dir():
            raise UserError(f"block {name} needs {OUTSIDE_DATA[name]}, which is not there")
    return {name: GENERATORS[name]() for name in sorted(names)}


def stale(blocks: Sequence[Block]) -> list[tuple[Block, str]]:
    """The blocks whose text differs from what their generator prints now, with that text."""
    now = generated({b.name for b in blocks})
    return [(b, now[b.name]) for b in blocks if b.text != now[b.name]]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a block is stale")
    parser.add_argument("names", nargs="*", help="only these blocks (default: all)")
    args = parser.parse_args(argv)
    try:
        blocks = [b for b in all_blocks() if not args.names or b.name in args.names]
        if args.check:
            differ = stale(blocks)
            for block, text in differ:
                print(f"{os.path.relpath(block.path)}: {block.name} is stale; now:\n{text}\n")
            return 1 if differ else 0
        now = generated({b.name for b in blocks})
        for path in DOCUMENTS:
            if rewrite(path, now):
                print(f"rewrote {os.path.relpath(path)}")
    except UserError as exc:
        print(f"figures: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
