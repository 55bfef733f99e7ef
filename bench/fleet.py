"""``uav-energy fleet`` throughput on a LocalCluster with 1 and 2 worker processes.

Two sets, each with ``fleet replay`` (the built-in vehicle for the generated set, the
June–August IRIS+ vehicle file for the IRIS+ logs):

1. 1,000 generated logs: 50 simulated 30 s flights of the built-in vehicle (hover, then
   cruise; seeds 0–49), each written as a tlog on 20 different days (the stamps differ, so
   do the content hashes; the replay work is the same as for 1,000 flights), generated once
   on two dask workers and cached in ``$XDG_CACHE_HOME/uav-energy/fleet-logs-v2`` (about
   50 kB each);
2. the 73 IRIS+ logs in ``../shared/data/iris_quadcopter_logs`` (skipped when absent).

Per set and worker count: wall time of the run (the cluster already started; its start-up
printed apart), logs per second, the per-log worker time summed, wall-clock and CPU (wall
grows over CPU when the workers wait for a CPU: the machine's load average before each run is
printed), and the speed-up 1 → 2 workers as a ratio. Every run writes a fresh results file
(no resume).
Run: ``python -m bench fleet`` (or ``make bench``, which runs every bench).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import pyarrow.compute as pc
import pyarrow.parquet as pq

from estimator.analysis.fleet import connect, run_fleet
from estimator.analysis.fleet_flight import FleetJob
from estimator.physics.vehicle import Vehicle, default_vehicle, load_vehicle
from estimator.sim.files import TLOG_EPOCH_S, write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

REPO = Path(__file__).resolve().parent.parent
IRIS = REPO.parent / "shared" / "data" / "iris_quadcopter_logs"
IRIS_VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"
FLIGHTS = 50
DAYS_PER_FLIGHT = 20
FLIGHT_S = 30.0
WORKERS = (1, 2)


def cache_dir() -> Path:
    base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    return base / "uav-energy" / "fleet-logs-v2"


def log_path(directory: Path, index: int) -> Path:
    return directory / f"gen-{index:04d}.tlog"


def generate_flight(seed: int, directory: Path) -> int:
    """Simulate flight ``seed`` and write its :data:`DAYS_PER_FLIGHT` logs (atomically)."""
    run = simulate(SimConfig(plan="hover-cruise", duration_s=FLIGHT_S, seed=seed))
    for day in range(DAYS_PER_FLIGHT):
        index = seed * DAYS_PER_FLIGHT + day
        tmp = write_tlog(
            run, directory / f".gen-{index:04d}.tmp", False, TLOG_EPOCH_S + 86400.0 * day
        )
        tmp.replace(log_path(directory, index))
    return seed


def generated_logs() -> list[Path]:
    directory = cache_dir()
    directory.mkdir(parents=True, exist_ok=True)
    paths = [log_path(directory, k) for k in range(FLIGHTS * DAYS_PER_FLIGHT)]
    missing = sorted({k // DAYS_PER_FLIGHT for k, p in enumerate(paths) if not p.exists()})
    if missing:
        start = time.perf_counter()
        with connect(None, 2) as client:
            client.gather(client.map(generate_flight, missing, directory=directory))
        print(f"  simulated {len(missing)} flights in {time.perf_counter() - start:.0f} s")
    return paths


def measure(name: str, logs: list[Path], vehicle: Vehicle) -> None:
    size_mb = sum(p.stat().st_size for p in logs) / 1e6
    print(f"  {name}: {len(logs)} logs, {size_mb:.0f} MB, fleet replay")
    wall: dict[int, float] = {}
    for workers in WORKERS:
        load = os.getloadavg()[0]
        start = time.perf_counter()
        with connect(None, workers) as client, tempfile.TemporaryDirectory() as tmp:
            startup_s = time.perf_counter() - start
            out = Path(tmp) / "r.parquet"
            counts = run_fleet(client, logs, FleetJob("replay", vehicle), out)
            rows = pq.read_table(out, columns=["wall_s", "cpu_s"])
            task_s, cpu_s = (pc.sum(rows[c]).as_py() for c in ("wall_s", "cpu_s"))
        wall[workers] = counts.wall_s
        print(
            f"    {workers} worker(s): {counts.wall_s:6.1f} s  "
            f"({len(logs) / counts.wall_s:6.1f} logs/s, {counts.ok} ok, {counts.failed} failed; "
            f"cluster start {startup_s:.1f} s)\n"
            f"      per-log work summed {task_s:.1f} s (CPU {cpu_s:.1f} s), workers busy "
            f"{100 * task_s / (counts.wall_s * workers):.0f} %, load average before {load:.1f}"
        )
    print(f"    speed-up 1 → 2 workers: {wall[1] / wall[2]:.2f}×")


def main() -> int:
    print(f"bench fleet: LocalCluster, processes with one thread, {os.cpu_count()} CPUs")
    measure("generated", generated_logs(), default_vehicle())
    if IRIS.is_dir():
        measure("IRIS+", sorted(IRIS.rglob("*.log")), load_vehicle(IRIS_VEHICLE))
    else:
        print(f"  IRIS+: skipped: {IRIS} is absent (needs ../shared next to the repo)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
