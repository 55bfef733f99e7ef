"""Where a replay's pipeline time goes, per 1 s period (``python -m bench.periods [LOG
[VEHICLE]]``; part of ``make bench``).

The pipeline does most of its work once per period of sample clock
(:meth:`~estimator.estimation.pipeline.Pipeline._close_period`): the power after each
queued sample (and, in the same prediction, the endurance's mean power), the energy filter,
the fusion and the pack filter, the online tracker every ``track_period_s``, and the estimate
with its endurance and return figures. This bench replays one log twice (the first run warms
up), timing the stages below with a wall clock around each call, and prints each stage's time
per period (µs) and its share of the pipeline. Stages nest (a stage's time includes the stages
it calls); the wrappers cost about 0.3 µs per call.

Default log: the largest IRIS+ tlog with its fitted vehicle file (as ``bench.replay``).
Skips with a message when ``../shared`` is absent.
"""

from __future__ import annotations

import functools
import importlib
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from estimator.analysis.replay import replay_log
from estimator.physics.vehicle import default_vehicle, load_vehicle

REPO = Path(__file__).resolve().parent.parent
IRIS = REPO.parent / "shared" / "data" / "iris_quadcopter_logs"
IRIS_VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"

#: (module, class, method, label): the stages timed, outermost first.
STAGES = (
    ("estimator.estimation.pipeline", "Pipeline", "process", "process (every sample)"),
    ("estimator.estimation.pipeline", "Pipeline", "_close_period", "  a period's close"),
    ("estimator.estimation.pipeline", "Pipeline", "_event_powers_w", "    model power, all rows"),
    ("estimator.estimation.pipeline", "Pipeline", "_integrate", "    energy predict"),
    ("estimator.estimation.pipeline", "Pipeline", "_fuse", "    fusion"),
    ("estimator.estimation.pack_learning", "PackLearning", "period_end", "      pack filter"),
    ("estimator.estimation.pipeline", "Pipeline", "_track_effects", "      online tracker"),
    ("estimator.estimation.pipeline", "Pipeline", "_emit", "    the estimate"),
    ("estimator.estimation.pipeline", "Pipeline", "_endurance_power_w", "      endurance power"),
    ("estimator.estimation.fusion", "EnergyFilter", "endurance_s", "      endurance times"),
    ("estimator.estimation.return_home", "ReturnHome", "figures", "      return figures"),
    ("estimator.physics.effects", None, "predict_context", "  every power prediction"),
)


@contextmanager
def timed(totals: dict[str, float], counts: dict[str, int]) -> Iterator[None]:
    """While open, every stage of :data:`STAGES` adds its calls' wall time (s) to
    ``totals`` and their number to ``counts``, by label."""
    restore: list[tuple[Any, str, Callable[..., Any]]] = []

    def wrap(owner: Any, name: str, label: str) -> None:
        original = getattr(owner, name)

        @functools.wraps(original)
        def stage(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                totals[label] += time.perf_counter() - start
                counts[label] += 1

        setattr(owner, name, stage)
        restore.append((owner, name, original))

    for module_name, class_name, method, label in STAGES:
        module = importlib.import_module(module_name)
        wrap(module if class_name is None else getattr(module, class_name), method, label)
    try:
        yield
    finally:
        for owner, name, original in reversed(restore):
            setattr(owner, name, original)


def main(argv: list[str]) -> int:
    if argv:
        log = Path(argv[0])
        vehicle_file = Path(argv[1]) if len(argv) > 1 else None
    elif IRIS.is_dir():
        log = max(IRIS.rglob("*.log"), key=lambda p: p.stat().st_size)
        vehicle_file = IRIS_VEHICLE
    else:
        print(f"bench periods: skipped: {IRIS} is absent (needs ../shared next to the repo)")
        return 0
    vehicle = default_vehicle() if vehicle_file is None else load_vehicle(vehicle_file)
    replay_log(log, vehicle)  # warm-up: imports, caches
    totals: dict[str, float] = defaultdict(float)
    counts: dict[str, int] = defaultdict(int)
    with timed(totals, counts):
        flight = replay_log(log, vehicle)
    periods = counts["  a period's close"] or 1
    pipeline_s = totals["process (every sample)"]
    print(
        f"bench periods: {log.name}, {flight.samples} samples, {periods} periods, pipeline "
        f"{pipeline_s:.3f} s ({pipeline_s / max(flight.samples, 1) * 1e6:.1f} µs per sample, "
        f"timed)"
    )
    print(f"  {'stage':36s} {'calls':>7s} {'µs/period':>10s} {'share':>6s}")
    for _, _, _, label in STAGES:
        total_s = totals[label]
        print(
            f"  {label:36s} {counts[label]:7d} {total_s / periods * 1e6:10.1f} "
            f"{100 * total_s / pipeline_s:5.0f} %"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
