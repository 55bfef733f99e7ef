"""docs/residuals.md's figures of the online tracker and of the wind the pipeline uses, as the
scripts that print them give them:

- ``tracker-sitl*``: ``python scripts/tracker_sitl.py [RECORDINGS] [--slow-error-fraction
  F]`` (the online tracker on the ArduCopter SITL recordings of ``replay/sitl``, against their
  wind and payload; ``tracker-sitl-held*``: on the held-out flights of ``replay/sitl_held``,
  with a flight's worst mass step and the unloaded flights' mass; ``*-blind``: how many of
  the steps beyond 3σ nothing the tracker read could have told from the truth);
- ``tracker-cmu``, ``tracker-cmu-shows``: ``python scripts/tracker_cmu.py`` (the online
  tracker on the CMU M100 flights against their payload and anemometer);
- ``tracked-wind-sitl``: ``python scripts/tracked_wind_sitl.py`` (the wind the pipeline uses
  on the recordings of ``replay/sitl``, against their truth).

``scripts/figures.py`` registers the blocks (:func:`sitl_generators`,
:func:`held_generators`, :func:`cmu_generators`, :func:`wind_generators`); the tests that run
the same scripts check them (``tests/test_tracker_sitl.py``, ``tests/test_sitl_held_out.py``,
``tests/test_sitl_recordings.py``), ``tests/test_figures.py`` the CMU ones.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

#: The slow model error (fraction of the hover power) docs/residuals.md's counterfactual tries.
TRACKER_SITL_SLOW_ERROR = 0.02
#: The held-out flight docs/residuals.md quotes a mass step of, and the set whose unloaded
#: flights it gives the mass of.
TRACKER_MASS_STEP, TRACKER_UNLOADED_SET = "held4_release_wind_legs", "held4_"


@cache
def sitl_tracker_runs(
    tracker_sitl: ModuleType,
    recordings: Path | None = None,
    slow_error_fraction: float | None = None,
) -> list[Any]:
    """``python scripts/tracker_sitl.py [RECORDINGS] [--slow-error-fraction F]``'s runs (10 s
    of CPU for replay/sitl, its default; their checks share the runs of the tests that name
    them); ``tracker_sitl``: that script as a module."""
    return list(tracker_sitl.runs(recordings or tracker_sitl.RECORDINGS, slow_error_fraction))


def sitl_generators(tracker_sitl: ModuleType) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the recordings of ``replay/sitl``."""
    return {
        "tracker-sitl": lambda: str(tracker_sitl.report(sitl_tracker_runs(tracker_sitl))),
        "tracker-sitl-shows": lambda: str(tracker_sitl.shows(sitl_tracker_runs(tracker_sitl))),
        "tracker-sitl-blind": lambda: str(tracker_sitl.blind(sitl_tracker_runs(tracker_sitl))),
        "tracker-sitl-slow-2pct": lambda: str(
            tracker_sitl.slow_error_share(
                sitl_tracker_runs(tracker_sitl, slow_error_fraction=TRACKER_SITL_SLOW_ERROR)
            )
        ),
    }


def held_generators(tracker_sitl: ModuleType, held: Path) -> dict[str, Callable[[], str]]:
    """The blocks of the held-out flights (under ``held``)."""

    def runs() -> list[Any]:
        return sitl_tracker_runs(tracker_sitl, held)

    return {
        "tracker-sitl-held": lambda: str(tracker_sitl.report(runs())),
        "tracker-sitl-held-blind": lambda: str(tracker_sitl.blind(runs())),
        "tracker-sitl-held-wind-worst": lambda: str(tracker_sitl.worst_wind(runs())),
        "tracker-sitl-held-mass-step": lambda: str(
            tracker_sitl.mass_step(runs(), TRACKER_MASS_STEP)
        ),
        "tracker-sitl-held-unloaded": lambda: str(
            tracker_sitl.unloaded_mass(runs(), TRACKER_UNLOADED_SET)
        ),
    }


def cmu_generators(tracker_cmu: ModuleType) -> dict[str, Callable[[], str]]:
    """The blocks of the CMU flights (``tracker_cmu``: ``scripts/tracker_cmu.py``, whose
    ``DATA`` they read): its table, and docs/residuals.md's reading of it."""
    return {
        "tracker-cmu": lambda: tracker_cmu.report(*tracker_cmu.both()),
        "tracker-cmu-shows": lambda: str(tracker_cmu.shows(*tracker_cmu.both())),
    }


def wind_generators(tracked_wind_sitl: ModuleType) -> dict[str, Callable[[], str]]:
    """The table of ``scripts/tracked_wind_sitl.py`` (20 s of CPU; its check shares the
    replays with WIND of ``tests/test_sitl_recordings.py``)."""
    return {"tracked-wind-sitl": lambda: "\n".join(tracked_wind_sitl.table_lines())}
