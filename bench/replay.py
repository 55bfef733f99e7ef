"""Replay throughput, measured against pymavlink in the same run.

1. The largest IRIS+ telemetry log in ``../shared/data/iris_quadcopter_logs`` (symlinked to a
   ``.tlog`` name, which pymavlink needs) decoded by pymavlink's
   ``mavutil.mavlink_connection(path).recv_match()`` loop — the baseline — against our reader
   alone (``estimator.logs.iter_samples``: only the message types the pipeline uses are
   parsed) and against a whole replay (reader + the daemon's pipeline, with the vehicle file
   fitted on those flights). Printed as ratios.
2. Per-format throughput in samples/s: that tlog, a 10-minute synthetic flight written as an
   ArduPilot DataFlash .bin and as a PX4 .ulg (the test fixtures' writers), and the CMU CSV
   cruise file.

Skips with a message when ``../shared`` is absent. Run: ``python -m bench.replay``.
"""

from __future__ import annotations

import gc
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from estimator.analysis.replay import replay_log
from estimator.logs import iter_samples
from estimator.physics.vehicle import Vehicle, default_vehicle, load_vehicle

REPO = Path(__file__).resolve().parent.parent
DATA = REPO.parent / "shared" / "data"
IRIS = DATA / "iris_quadcopter_logs"
CMU_CRUISE = DATA / "cmu_m100_subset" / "flights_validation_data_clean_cruise.csv"
#: The vehicle files fitted on those flights (the synthetic flights use the built-in vehicle).
IRIS_VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"
CMU_VEHICLE = REPO / "config" / "vehicles" / "dji_m100_cmu.toml"
REPEATS = 3
SYNTHETIC_REPEATS = 10  # copies of the 60 s fixture flight


def best_of(fn: Callable[[], int], repeats: int = REPEATS) -> tuple[float, int]:
    """(fastest wall time in s, the count fn returned)."""
    best, count = float("inf"), 0
    for _ in range(repeats):
        start = time.perf_counter()
        count = fn()
        best = min(best, time.perf_counter() - start)
    return best, count


def pymavlink_messages(path: Path) -> int:
    """Messages decoded by pymavlink's usual loop."""
    conn = mavutil.mavlink_connection(str(path))
    n = 0
    while conn.recv_match() is not None:
        n += 1
    conn.close()
    return n


def decoded_samples(path: Path) -> int:
    return sum(1 for _ in iter_samples(path))


def replayed_samples(path: Path, vehicle: Vehicle) -> int:
    return replay_log(path, vehicle).samples


def synthetic_logs(directory: Path) -> dict[str, Path]:
    """A long synthetic flight as .bin and .ulg, written by the test fixtures' writers."""
    sys.path.insert(0, str(REPO / "tests"))
    from fixtures.flight import Truth, make_truth, write_bin, write_ulg

    one = make_truth()
    span_s = float(one.velocity_time_s[-1] + 0.1)
    shifts = [k * span_s for k in range(SYNTHETIC_REPEATS)]
    consumed = one.consumed_mah[-1]
    long = Truth(
        velocity_time_s=np.concatenate([one.velocity_time_s + s for s in shifts]),
        v_ned_mps=np.concatenate([one.v_ned_mps] * SYNTHETIC_REPEATS),
        alt_m=np.concatenate([one.alt_m] * SYNTHETIC_REPEATS),
        battery_time_s=np.concatenate([one.battery_time_s + s for s in shifts]),
        voltage_v=np.concatenate([one.voltage_v] * SYNTHETIC_REPEATS),
        current_a=np.concatenate([one.current_a] * SYNTHETIC_REPEATS),
        consumed_mah=np.concatenate(
            [one.consumed_mah + k * consumed for k in range(SYNTHETIC_REPEATS)]
        ),
    )
    return {
        "dataflash .bin": write_bin(directory / "synthetic.bin", long),
        "ulog .ulg": write_ulg(directory / "synthetic.ulg", long),
    }


def main() -> int:
    if not IRIS.is_dir():
        print(f"bench replay: skipped: {IRIS} is absent (needs ../shared next to the repo)")
        return 0
    gc.freeze()  # what `uav-energy replay` does after its imports; the baseline gains alike
    largest = max(IRIS.rglob("*.log"), key=lambda p: p.stat().st_size)
    with tempfile.TemporaryDirectory() as tmp:
        tlog = Path(tmp) / f"{largest.stem}.tlog"
        tlog.symlink_to(largest)
        size_mb = largest.stat().st_size / 1e6
        print(f"bench replay: {largest.relative_to(IRIS)} ({size_mb:.1f} MB), best of {REPEATS}")
        t_pymavlink, n_messages = best_of(lambda: pymavlink_messages(tlog))
        t_decode, n_samples = best_of(lambda: decoded_samples(tlog))
        iris = load_vehicle(IRIS_VEHICLE)
        t_replay, _ = best_of(lambda: replayed_samples(tlog, iris))
        print(f"  pymavlink recv_match loop : {t_pymavlink:6.2f} s  ({n_messages} messages)")
        print(
            f"  uav-energy reader         : {t_decode:6.2f} s  ({n_samples} samples)"
            f"  ratio pymavlink/reader = {t_pymavlink / t_decode:.1f}"
        )
        print(
            f"  uav-energy replay (reader + pipeline): {t_replay:6.2f} s"
            f"  ratio pymavlink/replay = {t_pymavlink / t_replay:.1f}"
        )
        logs = {"tlog (IRIS+)": (tlog, iris)}
        logs |= {
            name: (path, default_vehicle()) for name, path in synthetic_logs(Path(tmp)).items()
        }
        if CMU_CRUISE.is_file():
            logs["CMU csv (cruise)"] = (CMU_CRUISE, load_vehicle(CMU_VEHICLE))
        print("  per format (samples/s, best of 3): reader alone | full replay")
        for name, (path, vehicle) in logs.items():
            t_read, n = best_of(partial(decoded_samples, path))
            t_full, _ = best_of(partial(replayed_samples, path, vehicle))
            print(
                f"    {name:18s} {n:7d} samples  {n / t_read:10.0f} | {n / t_full:8.0f}"
                f"   ({path.stat().st_size / 1e6:.1f} MB)"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
