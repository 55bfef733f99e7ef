"""``uav-energy fit`` on the IRIS+ June–August flights (53 logs, 16.6k kept points): where the
time goes, and the held-out error of the three models.

Prints the wall and CPU time of each phase in this process — reading the logs
(``load_flights``, in one process, then in one per CPU as ``uav-energy fit`` does),
preprocessing, ``fit_all`` (5-fold held-out scoring of least squares theory, cubic polynomial
and the 3 × 10 network, then the final fits) — and the whole ``uav-energy fit … --json``
process (interpreter start and imports included). The network's held-out RMSE is printed at
its mini-batch size (1/8 of the points) and, with ``--batch-200``, also at scikit-learn's
default of 200 (the reference the batch size was chosen against; that run alone takes ~10 s of
CPU). Skips with a message when ``../shared`` is absent. Run: ``python -m bench.fit
[--batch-200]``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from estimator.analysis.baselines import NetworkModel
from estimator.analysis.fit import FitOptions, cross_validate, fit_all
from estimator.analysis.fit_points import preprocess
from estimator.logs import load_flights

REPO = Path(__file__).resolve().parent.parent
IRIS = REPO.parent / "shared" / "data" / "iris_quadcopter_logs"
UAV_ENERGY = Path(sys.executable).parent / "uav-energy"
#: The fitted June–August vehicle's command line (scripts/fit_real.sh).
MASS_KG, CAPACITY_AH, CELLS = 1.58, 5.1, 3

T = TypeVar("T")


def timed(label: str, fn: Callable[[], T]) -> T:
    """Run ``fn`` and print its wall and CPU seconds."""
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    print(
        f"  {label:28s} {time.perf_counter() - wall:6.2f} s wall  "
        f"{time.process_time() - cpu:6.2f} s CPU",
        flush=True,
    )
    return out


def main(argv: list[str]) -> int:
    logs = sorted(IRIS.glob("2016-0[678]-*/*/*.log"))
    if not logs:
        print(f"bench fit: skipped: no IRIS+ June–August logs under {IRIS}")
        return 0
    print(f"bench fit: {len(logs)} IRIS+ June–August logs")
    flights = timed("read (load_flights)", lambda: load_flights(logs))
    jobs = os.cpu_count() or 1
    timed(f"read in {jobs} processes", lambda: load_flights(logs, workers=jobs))
    options = FitOptions()
    points = timed("preprocess", lambda: preprocess(flights, options.preprocess, None, MASS_KG))
    report = timed("fit_all (3 models, 5 folds)", lambda: fit_all(points, options))
    start = time.perf_counter()
    vehicle_args = ["--mass-kg", str(MASS_KG), "--capacity-ah", str(CAPACITY_AH)]
    subprocess.run(
        [str(UAV_ENERGY), "fit", *map(str, logs), *vehicle_args, "--cells", str(CELLS), "--json"],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    print(f"  whole `uav-energy fit` process {time.perf_counter() - start:6.2f} s wall")
    kept = points.kept()
    print(f"  {len(kept)} points kept; held-out RMSE / MAPE per model:")
    for name, score in report.scores.items():
        print(f"    {name:10s} {score.rmse_w:7.3f} W  {score.mape_pct:6.3f} %")
    if "--batch-200" in argv:
        with_mass = kept.varying_mass
        scores, _ = timed(
            "network, batches of 200",
            lambda: cross_validate(
                kept,
                {"dnn": lambda: NetworkModel(with_mass, options.seed, batch_size=200)},
                options.folds,
                options.split,
            ),
        )
        print(f"    dnn (200)  {scores['dnn'].rmse_w:7.3f} W  {scores['dnn'].mape_pct:6.3f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
