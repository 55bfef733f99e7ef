"""CPU time of the pipeline alone and of its return figures (``python -m bench.pipeline_cpu
LOG [VEHICLE] [--repeats N]``), the method of docs/speed.md's issue-20 sections.

The log's samples are read once into a list; each run feeds them to a fresh ``Pipeline``
(:func:`estimator.analysis.replay.run`), timed with ``time.process_time()`` (CPU time, so the
figures hold at a machine's load). ``ReturnHome.figures`` is timed inside the same runs. Prints
one JSON line: samples, estimates, estimates with a return, the best run's µs per sample and
the best run's return figures' µs per estimate. Compare two commits by running this file with
``PYTHONPATH`` set to each checkout in turn (it imports only the estimator's public names).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from estimator.analysis.replay import run
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.return_home import ReturnHome
from estimator.logs import iter_samples
from estimator.physics.vehicle import default_vehicle, load_vehicle


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("log", type=Path)
    parser.add_argument("vehicle", type=Path, nargs="?")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    vehicle = load_vehicle(args.vehicle) if args.vehicle else default_vehicle()
    samples = list(iter_samples(args.log, "auto", vehicle.input_limits()))
    figures = ReturnHome.figures
    spent_s = [0.0, 0]

    def timed(self: ReturnHome, *a: object, **k: object) -> object:
        start = time.process_time()
        out = figures(self, *a, **k)  # type: ignore[arg-type]
        spent_s[0] += time.process_time() - start
        spent_s[1] += 1
        return out

    best_s, best_figures_s, estimates, returns = float("inf"), float("inf"), 0, 0
    for _ in range(args.repeats):
        ReturnHome.figures = figures  # type: ignore[method-assign]
        start = time.process_time()
        out, _, _ = run(samples, Pipeline(vehicle))
        best_s = min(best_s, time.process_time() - start)
        estimates = len(out)
        ReturnHome.figures = timed  # type: ignore[method-assign,assignment]
        spent_s[:] = [0.0, 0]
        run(samples, Pipeline(vehicle))
        best_figures_s = min(best_figures_s, spent_s[0])
        returns = sum(e.rth_energy_wh == e.rth_energy_wh for e in out)  # not NaN
    ReturnHome.figures = figures  # type: ignore[method-assign]
    calls = int(spent_s[1])
    print(
        json.dumps(
            {
                "log": args.log.name,
                "samples": len(samples),
                "estimates": estimates,
                "figures_calls": calls,
                "estimates_with_return": returns,
                "pipeline_us_per_sample": round(best_s / len(samples) * 1e6, 2),
                "figures_us_per_call": round(best_figures_s / max(calls, 1) * 1e6, 1),
            }
        )
    )


if __name__ == "__main__":
    main()
