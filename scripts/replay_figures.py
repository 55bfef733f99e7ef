"""The figures of single flights replayed with the built-in vehicle, and of the logs' vertical
velocity check (docs/sim.md, docs/sitl.md, docs/replay.md):

- ``sim-mixed-*``: ``uav-energy sim --plan mixed [--wind 6@135] --tlog F`` and ``uav-energy
  replay F --json`` (the built-in vehicle, told nothing of the wind);
- ``sitl-run1-builtin``: ``../shared``'s recorded ArduCopter SITL flight replayed with the
  built-in vehicle on SITL's pack (``sitl-run1-estimates``: how many estimates that replay
  gives);
- ``replay-arducopter-bin``: current ArduCopter SITL's DataFlash log replayed, against the
  tlog of the same flight;
- ``iris-vz-sign``, ``sitl-vz-sign``: the vertical velocity check on the IRIS+ logs and on
  ArduCopter SITL's tlog.

``scripts/figures.py`` registers the blocks (:func:`generators`, and those that read
``../shared``: :func:`iris_generators`, :func:`run1_generators`); ``tests/test_figures.py``
checks them.
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import replace
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from pymavlink import mavutil

from estimator.analysis.replay import replay_log, summarize
from estimator.logs import iter_samples, sanity
from estimator.physics.vehicle import BatterySpec, Vehicle, default_vehicle
from estimator.telemetry.firmware import copter_vz_up
from estimator.telemetry.vz_sense import DECIDING_PAIRS

#: What ``uav-energy ARGV…`` prints on stdout (``scripts/figures.py`` runs it in process).
Cli = Callable[..., str]

REPO = Path(__file__).resolve().parent.parent
#: Current ArduCopter SITL's DataFlash log of a GUIDED flight, and its tlog (``.tlog``).
ARDUCOPTER_GUIDED = REPO / "tests" / "data" / "arducopter_guided.bin"
#: The wind docs/sim.md's windy flight is simulated in.
SIM_WIND = "6@135"


def vertical_pairs(path: Path) -> tuple[np.ndarray, np.ndarray, bool]:
    """(height rate, logged climb rate) in m/s of the sample pairs a log's vertical velocity
    check judges (its stream's :class:`~estimator.logs.sanity.SanityRecorder`), and whether
    the log warns about its vertical velocity."""
    stream = iter_samples(path)
    list(stream)
    rate, climb = stream.sanity.judged_pairs() or (np.empty(0), np.empty(0))
    warns = any(cause == sanity.VERTICAL_VELOCITY for cause, _ in stream.problems())
    return rate, climb, warns


def sent_pairs(path: Path) -> tuple[bool, np.ndarray, np.ndarray]:
    """Whether the tlog ``path`` has a firmware STATUSTEXT of a Copter that sends
    GLOBAL_POSITION_INT.vz positive up (:func:`copter_vz_up`: the reader then reads it so),
    and the (height rate, climb rate) in m/s of its successive GLOBAL_POSITION_INT as sent,
    vz taken positive down as MAVLink defines it (the pairs
    :func:`~estimator.logs.sanity.rate_pairs` judges); one pass over the log."""
    log = mavutil.mavmmaplog(str(path))
    named, rows = False, []
    while (msg := log.recv_match(type=["STATUSTEXT", "GLOBAL_POSITION_INT"])) is not None:
        if msg.get_type() == "STATUSTEXT":
            named = named or bool(copter_vz_up(msg.text))
        else:
            rows.append((msg.time_boot_ms / 1000.0, msg.vz / 100.0, msg.relative_alt / 1000.0))
    return named, *sanity.rate_pairs(*np.array(rows, dtype=float).reshape(-1, 3).T)


def _agreement(rate: np.ndarray, climb: np.ndarray) -> tuple[int, float, float]:
    """Pairs whose signs agree, the correlation, and the median |climb| / |height rate|."""
    agree = int(np.count_nonzero(np.sign(rate) == np.sign(climb)))
    return agree, float(np.corrcoef(rate, climb)[0, 1]), float(np.median(np.abs(climb / rate)))


def iris_vz_sign(iris: Path, fits: ModuleType) -> str:
    """docs/replay.md: the vertical velocity check on every IRIS+ log (under ``iris``): how
    many name an old Copter; the logs with enough judged pairs, their vz as sent (MAVLink's
    positive down: the firmware text's flip undone) and as read, how many warn, their signs,
    correlation and |vz| against the height rate; ``fits``: ``scripts/fit_figures.py`` (its
    number formats)."""
    logs = sorted(iris.glob("**/*.log"))
    every = [(*sent_pairs(p), *vertical_pairs(p)) for p in logs]
    judged = [j for j in every if len(j[1]) >= sanity.MIN_PAIRS]
    sent = [_agreement(rate, climb) for _, rate, climb, *_ in judged]
    read = [_agreement(rate, climb) for *_, rate, climb, _ in judged]
    pairs = sum(len(j[1]) for j in judged)
    read_pairs = sum(len(j[3]) for j in judged)
    corr = [f[1] for f in sent]
    warned = sum(j[5] for j in judged)
    unnamed = sum(not j[0] for j in judged)
    return (
        f"of the {len(logs)} logs in `../shared/data/iris_quadcopter_logs`, "
        f"{sum(j[0] for j in every)} name their firmware as a Copter before 3.6; the "
        f"{len(judged)} with at least {sanity.MIN_PAIRS} climbing or descending pairs of "
        f"GLOBAL_POSITION_INT, their vz as sent taken as MAVLink defines it, have the signs "
        f"opposite on {pairs - sum(f[0] for f in sent)} of their {pairs} pairs (correlation "
        f"{fits.number(min(corr), '.2f')} to {fits.number(max(corr), '.2f')}, |vz| "
        f"≈ {fits.span([f[2] for f in sent], '.1f')} × the altitude rate); read as the "
        f"firmware text says or, in the {unnamed} naming no firmware, as their height says "
        f"after {DECIDING_PAIRS} judged pairs, the signs agree on {sum(f[0] for f in read)} of "
        f"their {read_pairs} pairs as read, and {warned} log(s) say how they read their vz"
    )


def sitl_vz_sign() -> str:
    """docs/replay.md: the same check on current ArduCopter SITL's tlog."""
    rate, climb, _ = vertical_pairs(ARDUCOPTER_GUIDED.with_suffix(".tlog"))
    agree, corr, _ = _agreement(rate, climb)
    pairs = f"all {agree}" if agree == len(rate) else f"{agree} of {len(rate)}"
    return f"agrees on {pairs} pairs (correlation {corr:+.2f})"


@cache
def simulated_mixed(cli: Cli, wind: str | None) -> tuple[str, dict[str, Any]]:
    """``uav-energy sim --plan mixed [--wind S@DEG] --tlog F``'s line and ``uav-energy replay
    F --json`` (the built-in vehicle, told nothing of the wind)."""
    with tempfile.TemporaryDirectory() as tmp:
        tlog = str(Path(tmp) / "mixed.tlog")
        line = cli("sim", "--plan", "mixed", *(["--wind", wind] if wind else []), "--tlog", tlog)
        return line.strip(), json.loads(cli("replay", tlog, "--json"))


def sim_mixed(cli: Cli, wind: str | None) -> str:
    """The replay of :func:`simulated_mixed`: power RMSE and MAPE, energy measured and
    predicted."""
    result: Mapping[str, Any] = simulated_mixed(cli, wind)[1]
    return (
        f"power RMSE {result['power_rmse_w']:.1f} W (MAPE {result['power_mape_pct']:.1f} %), "
        f"energy {result['energy_measured_wh']:.2f} Wh measured vs "
        f"{result['energy_predicted_wh']:.2f} Wh predicted"
    )


def sim_mixed_wind_line(cli: Cli) -> str:
    """The summary line ``uav-energy sim`` prints, as an indented code block."""
    return "    " + simulated_mixed(cli, SIM_WIND)[0]


def builtin_on_sitl_pack() -> Vehicle:
    """The built-in vehicle on ArduPilot SITL's pack (3S, 3.3 Ah, 20 % reserve)."""
    return replace(default_vehicle(), name="sitl-quad", battery=BatterySpec(3.3, 3, 0.2))


def run1_builtin(cli: Cli, run1: Path) -> str:
    """``../shared``'s recorded SITL flight (``run1``) replayed with the built-in vehicle on
    SITL's pack (docs/sitl.md gives the commands)."""
    with tempfile.TemporaryDirectory() as tmp:
        vehicle_file = Path(tmp) / "sitl.toml"
        builtin_on_sitl_pack().save(vehicle_file)
        result = json.loads(cli("replay", str(run1), "--vehicle", str(vehicle_file), "--json"))
    return (
        f"{result['airborne_s']:.1f} s airborne, power RMSE {result['power_rmse_w']:.1f} W "
        f"(MAPE {result['power_mape_pct']:.1f} %), {result['energy_measured_wh']:.1f} Wh "
        f"measured vs {result['energy_predicted_wh']:.1f} Wh predicted"
    )


def run1_estimates(run1: Path) -> str:
    """How many estimates the replay of ``../shared``'s recorded SITL flight gives with
    :func:`builtin_on_sitl_pack` (``tests/test_ardupilot_sitl.py`` plays it live into the
    daemon and checks the daemon gives exactly these)."""
    return f"{len(replay_log(run1, builtin_on_sitl_pack()).estimates)}"


def arducopter_bin() -> str:
    """docs/replay.md: ``tests/data/arducopter_guided.bin`` (current ArduCopter SITL's
    DataFlash log) and the tlog of the same flight replayed with :func:`builtin_on_sitl_pack`:
    airborne s, power RMSE (W) and MAPE (%)."""
    figures = []
    for suffix in (".bin", ".tlog"):
        s = summarize([replay_log(ARDUCOPTER_GUIDED.with_suffix(suffix), builtin_on_sitl_pack())])
        figures.append((s.airborne_s, s.power_rmse_w or math.nan, s.power_mape_pct or math.nan))
    (bin_s, bin_w, bin_pct), (tlog_s, tlog_w, tlog_pct) = figures
    return (
        f"{bin_s:.0f} s airborne, RMSE {bin_w:.1f} W, MAPE {bin_pct:.1f} %, as the tlog of the "
        f"same flight ({tlog_s:.0f} s, {tlog_w:.1f} W, {tlog_pct:.1f} %"
    )


def generators(cli: Cli) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the blocks that read the repository
    only."""
    return {
        "sim-mixed-clean": partial(sim_mixed, cli, None),
        "sim-mixed-wind": partial(sim_mixed, cli, SIM_WIND),
        "sim-mixed-wind-line": partial(sim_mixed_wind_line, cli),
        "replay-arducopter-bin": arducopter_bin,
        "sitl-vz-sign": sitl_vz_sign,
    }


def iris_generators(iris: Path, fits: ModuleType) -> dict[str, Callable[[], str]]:
    """The block that reads the IRIS+ logs (``iris``); ``fits``: ``scripts/fit_figures.py``."""
    return {"iris-vz-sign": partial(iris_vz_sign, iris, fits)}


def run1_generators(cli: Cli, run1: Path) -> dict[str, Callable[[], str]]:
    """The blocks that read ``../shared``'s recorded SITL flight (``run1``)."""
    return {
        "sitl-run1-builtin": partial(run1_builtin, cli, run1),
        "sitl-run1-estimates": partial(run1_estimates, run1),
    }
