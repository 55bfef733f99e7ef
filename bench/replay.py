"""Replay throughput against the usual Python way of reading the same log, in one run.

Every bench log is read three ways, each timed as the best of a few runs:

- **baseline**: the library a user would reach for, asked for the same messages our reader
  uses — pymavlink's ``mavutil.mavlink_connection(path).recv_match(type=[…])`` loop for
  MAVLink tlogs and DataFlash .bin, pyulog's ``ULog(path, message_name_filter_list=[…])`` for
  PX4 .ulg (pymavlink does not read ULog). The CMU CSV has no such library: throughput only.
- **reader**: ``estimator.logs.iter_samples`` — the same messages decoded into samples, with
  the plausibility and time checks;
- **replay**: the reader plus the daemon's whole pipeline (``replay_log``): estimates, the
  power trace, the online wind/mass tracker. The pipeline's own cost is printed beside it in
  µs per sample: (replay − reader) / samples.

Both "reader only" (in this process) and "whole process" (``uav-energy replay LOG --vehicle F
--json`` against ``python -c <baseline loop>``, interpreter start and imports included) are
printed as ratios baseline / ours: above 1 we are faster.

Logs: the largest IRIS+ tlog (real, 8 % of its frames used), the ArduCopter SITL tlog in
``../shared``, a 10-minute flight of our simulator as a tlog (dense: every other frame used),
a 10-minute synthetic flight as DataFlash .bin and as PX4 .ulg (the test fixtures' writers), and
the CMU CSV cruise file. Skips with a message when ``../shared`` is absent.
Run: ``python -m bench.replay`` (``make bench`` runs every bench).
"""

from __future__ import annotations

import contextlib
import gc
import io
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from estimator.analysis.replay import replay_log
from estimator.logs import iter_samples
from estimator.logs.ulog import TOPICS
from estimator.physics.vehicle import Vehicle, default_vehicle, load_vehicle
from estimator.telemetry.decode import USED_MESSAGE_IDS

REPO = Path(__file__).resolve().parent.parent
DATA = REPO.parent / "shared" / "data"
IRIS = DATA / "iris_quadcopter_logs"
SITL_TLOG = DATA / "ardupilot_sitl" / "run1_default_quad.tlog"
CMU_CRUISE = DATA / "cmu_m100_subset" / "flights_validation_data_clean_cruise.csv"
#: The vehicle files fitted on those flights (the simulated flights use the built-in vehicle).
IRIS_VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"
CMU_VEHICLE = REPO / "config" / "vehicles" / "dji_m100_cmu.toml"
UAV_ENERGY = Path(sys.executable).parent / "uav-energy"
REPEATS = 3
SYNTHETIC_REPEATS = 10  # copies of the 60 s fixture flight
SIMULATED_S = 600.0
#: The messages our readers use (estimator.telemetry.decode.USED_MESSAGE_IDS by name;
#: estimator.logs.dataflash), asked of pymavlink by type.
TLOG_TYPES = sorted(
    mavlink.mavlink_map[i].msgname if i in mavlink.mavlink_map else "WIND"  # ardupilotmega
    for i in USED_MESSAGE_IDS
)
DATAFLASH_TYPES = ["XKF1", "NKF1", "GPS", "BAT", "CURR", "ARM", "EV", "MSG"]

#: The baselines as scripts (argv[1] = the log), so the whole-process run times them too.
PYMAVLINK_LOOP = """
import sys
from pymavlink import mavutil
conn = mavutil.mavlink_connection(sys.argv[1])
n = 0
while conn.recv_match(type={types!r}) is not None:
    n += 1
print(n)
"""
PYULOG_READ = """
import sys
from pyulog import ULog
ulog = ULog(sys.argv[1], message_name_filter_list={topics!r})
print(sum(len(d.data["timestamp"]) for d in ulog.data_list))
"""


@dataclass
class BenchLog:
    name: str
    path: Path
    vehicle: Vehicle
    vehicle_file: Path | None
    baseline: str | None  # a script of the baselines above, None: no baseline library


def best_of(fn: Callable[[], int], repeats: int = REPEATS) -> tuple[float, int]:
    """(fastest wall time in s, the count fn returned)."""
    best, count = float("inf"), 0
    for _ in range(repeats):
        start = time.perf_counter()
        count = fn()
        best = min(best, time.perf_counter() - start)
    return best, count


def run_script(script: str, path: Path) -> int:
    """Run a baseline script in this process; its count is the last line it prints."""
    out = io.StringIO()
    argv, sys.argv = sys.argv, ["baseline", str(path)]
    try:
        with contextlib.redirect_stdout(out):
            exec(script, {"__name__": "__baseline__"})
    finally:
        sys.argv = argv
    return int(out.getvalue().split()[-1])


def process_seconds(argv: list[str], repeats: int = REPEATS) -> float:
    """Fastest wall time (s) of a whole process."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - start)
    return best


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
        "synthetic .bin": write_bin(directory / "synthetic.bin", long),
        "synthetic .ulg": write_ulg(directory / "synthetic.ulg", long),
    }


def simulated_tlog(directory: Path) -> Path:
    """A 10-minute mixed flight of our simulator, as the tlog it streams."""
    from estimator.sim.files import write_tlog
    from estimator.sim.run import SimConfig
    from estimator.sim.simulator import simulate

    run = simulate(SimConfig(plan="mixed", duration_s=SIMULATED_S, seed=7))
    return write_tlog(run, directory / "simulated.tlog", truth_csv=False)


def bench_logs(directory: Path) -> list[BenchLog]:
    largest = max(IRIS.rglob("*.log"), key=lambda p: p.stat().st_size)
    iris_tlog = directory / f"iris_{largest.stem}.tlog"  # pymavlink knows a tlog by its name
    iris_tlog.symlink_to(largest)
    tlog_loop = PYMAVLINK_LOOP.format(types=TLOG_TYPES)
    builtin = default_vehicle()
    logs = [
        BenchLog(
            f"IRIS+ {largest.relative_to(IRIS)}",
            iris_tlog,
            load_vehicle(IRIS_VEHICLE),
            IRIS_VEHICLE,
            tlog_loop,
        )
    ]
    if SITL_TLOG.is_file():
        logs.append(BenchLog("ArduCopter SITL tlog", SITL_TLOG, builtin, None, tlog_loop))
    logs.append(BenchLog("simulated tlog", simulated_tlog(directory), builtin, None, tlog_loop))
    synthetic = synthetic_logs(directory)
    logs.append(
        BenchLog(
            "synthetic .bin",
            synthetic["synthetic .bin"],
            builtin,
            None,
            PYMAVLINK_LOOP.format(types=DATAFLASH_TYPES),
        )
    )
    logs.append(
        BenchLog(
            "synthetic .ulg",
            synthetic["synthetic .ulg"],
            builtin,
            None,
            PYULOG_READ.format(topics=list(TOPICS)),
        )
    )
    if CMU_CRUISE.is_file():
        logs.append(
            BenchLog("CMU csv (cruise)", CMU_CRUISE, load_vehicle(CMU_VEHICLE), CMU_VEHICLE, None)
        )
    return logs


def ratio(baseline_s: float | None, ours_s: float) -> str:
    return "—" if baseline_s is None else f"{baseline_s / ours_s:6.1f}×"


def bench_one(log: BenchLog) -> None:
    size_mb = log.path.stat().st_size / 1e6
    t_base = n_base = None
    if log.baseline is not None:
        script = log.baseline
        t_base, n_base = best_of(lambda: run_script(script, log.path))
    t_read, n_samples = best_of(lambda: sum(1 for _ in iter_samples(log.path)))
    t_replay, _ = best_of(lambda: replay_log(log.path, log.vehicle).samples)
    vehicle_args = [] if log.vehicle_file is None else ["--vehicle", str(log.vehicle_file)]
    p_ours = process_seconds([str(UAV_ENERGY), "replay", str(log.path), *vehicle_args, "--json"])
    p_base = None
    if log.baseline is not None:
        p_base = process_seconds([sys.executable, "-c", log.baseline, str(log.path)])
    base = "" if t_base is None else f", baseline {n_base} messages {t_base:.2f} s"
    print(f"  {log.name} ({size_mb:.1f} MB, {n_samples} samples{base})")
    print(
        f"    reader  {t_read:6.3f} s  {n_samples / t_read:8.0f} samples/s   "
        f"baseline/reader {ratio(t_base, t_read)}"
    )
    pipeline_us = (t_replay - t_read) / n_samples * 1e6
    print(
        f"    replay  {t_replay:6.3f} s  {n_samples / t_replay:8.0f} samples/s   "
        f"baseline/replay {ratio(t_base, t_replay)}   pipeline {pipeline_us:5.1f} µs/sample"
    )
    shown = "—" if p_base is None else f"{p_base:.2f} s"
    print(
        f"    whole process: uav-energy replay {p_ours:.2f} s, baseline {shown}   "
        f"ratio {ratio(p_base, p_ours)}",
        flush=True,
    )


def main() -> int:
    if not IRIS.is_dir():
        print(f"bench replay: skipped: {IRIS} is absent (needs ../shared next to the repo)")
        return 0
    gc.freeze()  # what `uav-energy replay` does after its imports; the baseline gains alike
    print(f"bench replay: best of {REPEATS}; ratios are baseline time / ours (> 1: faster)")
    with tempfile.TemporaryDirectory() as tmp:
        for log in bench_logs(Path(tmp)):
            bench_one(log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
