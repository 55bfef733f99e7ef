"""The result figures of README.md and docs/*.md, generated from the committed data.

Each ``<!-- figures:NAME -->`` … ``<!-- /figures:NAME -->`` block of those documents
(:mod:`estimator.reports.doc_blocks`) has one generator here that prints its text:

- ``iris-replay-*``: the IRIS+ flights of ``../shared/data/iris_quadcopter_logs`` replayed as
  ``uav-energy replay LOG… --vehicle F --json`` does, each period with the vehicle file fitted
  on it (in-sample), and once with the built-in vehicle; ``replay-regression-march``: the
  March flights' figures frozen in ``replay/expected.json``.
- ``plan-*``: ``uav-energy plan`` against the nine ArduCopter SITL missions of
  ``replay/sitl/missions`` (told the wind and payload SITL flew; and told still air), the
  example of docs/plan.md, a headwind leg's ground speed as flown, and the planner's climb
  term against SITL's vertical law on ``replay/sitl_axial`` (``tests/vertical_fit.py``).
- ``replay-mission``, ``replay-arducopter-bin``, ``iris-vz-sign``, ``sitl-vz-sign``:
  docs/replay.md's mission given to a replay, current ArduCopter's DataFlash log replayed,
  and the vertical-velocity check on the IRIS+ logs and on ArduCopter SITL's tlog.
- ``sim-mixed-*``: ``uav-energy sim --plan mixed [--wind 6@135] --tlog F`` and ``uav-energy
  replay F --json`` (the built-in vehicle); ``sitl-run1-builtin``: ``../shared``'s recorded
  ArduCopter SITL flight replayed with the built-in vehicle on SITL's pack
  (``sitl-run1-estimates``: how many estimates that replay gives).
- ``experiments-*``: ``uav-energy experiments`` (generated flights, seed 0).
- ``fit-*``: ``uav-energy fit`` of the real logs as ``make fit-real`` runs it, and variants
  (``--degree 6``, ``--no-priors``; ``scripts/fit_figures.py``); ``pack-fit-sitl-*``:
  ``python scripts/pack_fit_sitl.py`` (the pack fitted on SITL's pack flights).
- ``residuals-sim-*``: ``uav-energy residuals`` on simulated flights, each with an effect
  hidden from the built-in vehicle (``scripts/residual_figures.py``; ``residuals-iris-*``:
  the IRIS+ logs against the March vehicle file, and with ``residuals-cmu-*`` the real-log
  figures beyond its table, ``scripts/real_residual_figures.py``); the slower
  ``residuals-sim-changing`` (effects that change in flight; ``residuals-sim-changing-floors``:
  the largest held-out RMSE after, in noise floors) is checked by
  ``tests/test_residual_figures.py``.
- ``sitl-recordings-table``, ``sitl-effects-*``: the recordings of ``replay/sitl`` replayed,
  and the effects ``uav-energy residuals`` names on them scored against their truth
  (``scripts/sitl_figures.py``; checked by ``tests/test_sitl_recordings.py`` and
  ``tests/test_sitl_effects.py``, which compute the same results anyway, not by
  ``tests/test_figures.py``).
- ``sitl-payload-hover-current``, ``sitl-hover-power-*``: the hover current and power of
  the payload and heavier-airframe recordings of ``replay/sitl`` (``scripts/sitl_figures.py``).
- ``sitl-held-*``, ``tracker-sitl-held*``: the same analysis (and its misses' candidates), and
  the online tracker (with a flight's worst mass step and the unloaded flights' mass), on the
  held-out flights of ``replay/sitl_held`` (checked by ``tests/test_sitl_held_out.py``).
- ``residuals-sitl-*``: SITL's vertical effects fitted on ``replay/sitl_axial`` as the SITL
  vehicle file's header gives the command, and the heave gain on the clean held-out flights
  with vertical legs (``scripts/vertical_figures.py``).
- ``online-sim-*``: the online tracker on two of ``tests/test_online_effects.py``'s simulated
  flights (``scripts/online_figures.py``).
- ``state-restart-table``: ``python -m bench.trust``'s restart mid-flight (docs/daemon.md).
- ``tracker-cmu``: ``python scripts/tracker_cmu.py`` (the online tracker on the CMU M100
  flights against their payload and anemometer).
- ``tracked-wind-sitl``: ``python scripts/tracked_wind_sitl.py`` (the wind the pipeline uses
  on the ArduCopter SITL recordings of ``replay/sitl``, against their truth; checked by
  ``tests/test_sitl_recordings.py``).
- ``pack-sitl-*``: docs/pack.md's ArduCopter SITL pack flights, the tables ``python
  scripts/pack_state_sitl.py`` prints and their summary (``scripts/pack_figures.py``; the
  README's sentence too);
  ``pack-ensemble-*``: the simulator's ensemble of drawn packs; ``hover-cruise-*``: the
  hover→cruise acceptance flights (``python tests/test_endurance_acceptance.py``);
  ``pack-sitl-curve*``, ``pack-sitl-unscored``, ``pack-sitl-sigma-left``,
  ``pack-sitl-restarts-tuning``, ``hover-cruise-px4-*``, ``period-end-apart``: the prose
  figures around them, the SITL file's resting curve against SITL's table, and a reading at
  each period's end on two transports (``scripts/endurance_figures.py``).
- ``fleet-iris-*``: ``uav-energy fleet fit`` of the IRIS+ logs, ``fleet trends`` of its
  rows (docs/fleet.md; ``scripts/fleet_figures.py``) and the two periods' vehicle-file masses.
- ``tracker-sitl``: ``python scripts/tracker_sitl.py`` (the online tracker on the
  ArduCopter SITL recordings of ``replay/sitl``, against their wind and payload; checked by
  ``tests/test_tracker_sitl.py``).

Run: ``python scripts/figures.py`` rewrites the blocks (``make figures``);
``python scripts/figures.py --check`` prints the stale ones and exits 1 (``make
figures-check``; ``tests/test_figures.py`` runs the same check). Every generator is
deterministic: the check compares text exactly.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import importlib.util
import io
import json
import math
import os
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from estimator import cli
from estimator.analysis.mission_energy import FlightSettings, LegResult, MissionEnergy
from estimator.analysis.mission_validation import (
    MissionCheck,
    check_recording,
    item_ground_speeds_mps,
    leg_checks,
    predict_recording,
    truth_conditions,
)
from estimator.analysis.replay import (
    FlightReplay,
    Summary,
    replay_log,
    replay_stream,
    summarize,
)
from estimator.commands.replay import flight_names, vehicle_and_settings
from estimator.errors import UserError
from estimator.logs import iter_samples, sanity
from estimator.logs.mission_files import load_mission
from estimator.logs.sanity import SanityRecorder
from estimator.physics.lean_limit import along_track_limit_mps
from estimator.physics.route_energy import Conditions, RouteVehicle, steady_power_w
from estimator.physics.vehicle import BatterySpec, Vehicle, default_vehicle, load_vehicle
from estimator.reports.doc_blocks import Block, blocks_in, rewrite
from estimator.reports.fit_report import circles_markdown
from estimator.sim.experiments import Experiments, curve_table, reproduce
from estimator.sitl.truth_check import angle_deg

REPO = Path(__file__).resolve().parent.parent
DOCUMENTS = (REPO / "README.md", *sorted((REPO / "docs").glob("*.md")))
SHARED_DATA = REPO.parent / "shared" / "data"
IRIS = SHARED_DATA / "iris_quadcopter_logs"
SITL_RUN1 = SHARED_DATA / "ardupilot_sitl" / "run1_default_quad.tlog"
#: Current ArduCopter SITL's DataFlash log of a GUIDED flight, and its tlog (``.tlog``).
ARDUCOPTER_GUIDED = REPO / "tests" / "data" / "arducopter_guided.bin"
#: The two IRIS+ periods: their logs (as the README's ``find`` selects them) and vehicle file.
PERIODS = {
    "March 2016": ("2016-03-*", "iris_plus_2016_03.toml"),
    "June–August 2016": ("2016-0[678]-*", "iris_plus_2016_06_08.toml"),
}


def script_module(name: str, folder: Path = REPO / "scripts") -> ModuleType:
    """Another script of this folder (or of ``folder``), loaded as a module."""
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


sitl = script_module("sitl_figures")
fits = script_module("fit_figures")
residual_figures = script_module("residual_figures")
tracker_cmu = script_module("tracker_cmu")
tracker_sitl = script_module("tracker_sitl")
pack_table = script_module("pack_state_sitl")
pack_fit_table = script_module("pack_fit_sitl")
vertical_fit = script_module("vertical_fit", REPO / "tests")
vertical_figures = script_module("vertical_figures")
MISSIONS = sitl.SITL_RECORDINGS / "missions"
#: The missions the planner's flight settings were read off (docs/plan.md, "Calibration").
CALIBRATION = ("climbs_wind6", "outback_wind8", "square_wind5")
#: The planner's held-out missions, by name prefix, in the order they were flown (docs/plan.md):
#: the lean limit off the nose, then its payload scaling (rtl_payload_wind4's miss), each set
#: written and flown after its rule was frozen; the last is held out from every rule.
HELD_OUT_SETS = {"rtl_": "held out (lean limit)", "lean2_": "held out (lean limit, payload)"}
LATEST_HELD_OUT = "lean2_"

GENERATORS: dict[str, Callable[[], str]] = {}
#: The blocks whose generator reads data outside the repository, and that data.
OUTSIDE_DATA: dict[str, Path] = {}
#: The blocks whose results another test computes anyway (a minute or more of CPU), and that
#: test: it checks them, ``tests/test_figures.py`` does not.
CHECKED_BY: dict[str, str] = {}


def generator(
    name: str, reads: Path | None = None, checked_by: str | None = None
) -> Callable[[Callable[[], str]], Callable[[], str]]:
    """Register ``fn`` as the generator of the blocks called ``name``; ``reads``: the data
    outside the repository it needs; ``checked_by``: the test that checks a slow one."""

    def register(fn: Callable[[], str]) -> Callable[[], str]:
        GENERATORS[name] = fn
        if reads is not None:
            OUTSIDE_DATA[name] = reads
        if checked_by is not None:
            CHECKED_BY[name] = checked_by
        return fn

    return register


# --- IRIS+ replay ------------------------------------------------------------------------


def _iris_logs(pattern: str) -> list[Path]:
    return sorted(IRIS.glob(f"{pattern}/**/*.log"))


def _replay(logs: Sequence[Path], vehicle_file: Path | None) -> list[FlightReplay]:
    """``uav-energy replay LOG… [--vehicle F]``'s flights, with its names."""
    vehicle, settings = vehicle_and_settings(vehicle_file, None)
    flights = []
    for path, name in zip(logs, flight_names(logs), strict=True):
        stream = iter_samples(path, "auto", vehicle.input_limits())
        flights.append(replay_stream(stream, vehicle, name, settings))
    return flights


@cache
def iris_periods() -> dict[str, tuple[str, list[FlightReplay]]]:
    """Each period's vehicle file name and its flights replayed with it."""
    out = {}
    for period, (pattern, vehicle_name) in PERIODS.items():
        vehicle_file = REPO / "config" / "vehicles" / vehicle_name
        out[period] = (vehicle_name, _replay(_iris_logs(pattern), vehicle_file))
    return out


def _all_iris_flights() -> list[FlightReplay]:
    return [f for _, flights in iris_periods().values() for f in flights]


def _row(name: str, s: Summary) -> str:
    def fmt(x: float | None) -> str:
        return "–" if x is None else f"{x:.1f}"

    return (
        f"| {name} | {s.messages} | {s.airborne_s:.0f} | {s.power_points} "
        f"| {fmt(s.power_rmse_w)} | {fmt(s.power_mape_pct)} "
        f"| {s.energy_measured_wh:.2f} | {s.energy_predicted_wh:.2f} |"
    )


@generator("iris-replay-table", reads=IRIS)
def iris_replay_table() -> str:
    """Per flight, per period and over all logs: samples fed, airborne s, power points, power
    RMSE (W) and MAPE (%) against V·I, energy measured and predicted (Wh)."""
    lines = [
        "| flight | samples | airborne s | power points | RMSE W | MAPE % "
        "| E measured Wh | E model Wh |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    lines += [_row(f.name, summarize([f])) for f in _all_iris_flights()]
    for period, (vehicle_name, flights) in iris_periods().items():
        lines.append(_row(f"**{period} (`{vehicle_name}`)**", summarize(flights)))
    everything = _all_iris_flights()
    lines.append(_row(f"**all {len(everything)} logs**", summarize(everything)))
    return "\n".join(lines)


@generator("iris-replay-total", reads=IRIS)
def iris_replay_total() -> str:
    s = summarize(_all_iris_flights())
    return (
        f"{s.power_rmse_w:.1f} W RMSE, {s.power_mape_pct:.1f} % MAPE over all "
        f"{len(_all_iris_flights())}"
    )


@generator("iris-replay-errors", reads=IRIS)
def iris_replay_errors() -> str:
    """How the readers fared on every IRIS+ log: logs truncated and corrupt records skipped
    (an unreadable log stops the generator, so none is skipped)."""
    flights = _all_iris_flights()
    truncated = [f.name for f in flights if f.truncated]
    corrupt = {f.name: f.bad_frames for f in flights if f.bad_frames}
    cut = f"{len(truncated)} truncated ({', '.join(truncated)})" if truncated else "none truncated"
    records = sum(corrupt.values())
    return (
        f"all {len(flights)} logs replay without error: {cut}, {records} corrupt "
        f"record{'s' if records != 1 else ''} skipped and counted"
        + (f" (in {', '.join(corrupt)})" if corrupt else "")
    )


def vertical_pairs(path: Path) -> tuple[np.ndarray, np.ndarray, bool]:
    """(height rate, logged climb rate) in m/s of the sample pairs a log's vertical velocity
    check judges (:class:`SanityRecorder`), and whether the check warns."""
    recorder = SanityRecorder()
    for sample in iter_samples(path):
        recorder.observe(sample)
    rate, climb = recorder.judged_pairs() or (np.empty(0), np.empty(0))
    warns = any(cause == sanity.VERTICAL_VELOCITY for cause, _ in recorder.problems())
    return rate, climb, warns


def _agreement(rate: np.ndarray, climb: np.ndarray) -> tuple[int, float, float]:
    """Pairs whose signs agree, the correlation, and the median |climb| / |height rate|."""
    agree = int(np.count_nonzero(np.sign(rate) == np.sign(climb)))
    return agree, float(np.corrcoef(rate, climb)[0, 1]), float(np.median(np.abs(climb / rate)))


@generator("iris-vz-sign", reads=IRIS)
def iris_vz_sign() -> str:
    """docs/replay.md: the vertical velocity check on every IRIS+ log — the logs with enough
    judged pairs, how many warn, their signs, correlation and |vz| against the height rate."""
    logs = sorted(IRIS.glob("**/*.log"))
    judged = [p for p in map(vertical_pairs, logs) if len(p[0]) >= sanity.MIN_PAIRS]
    figures = [_agreement(rate, climb) for rate, climb, _ in judged]
    warned = sum(warns for _, _, warns in judged)
    agree, pairs = sum(f[0] for f in figures), sum(len(p[0]) for p in judged)
    opposite = "every judged pair" if agree == 0 else f"{pairs - agree} of their {pairs} pairs"
    corr = [f[1] for f in figures]
    every = "all warn" if warned == len(judged) else f"{warned} warn"
    return (
        f"of the {len(logs)} logs in `../shared/data/iris_quadcopter_logs`, the {len(judged)} "
        f"with at least {sanity.MIN_PAIRS} climbing or descending pairs {every}, with the signs "
        f"opposite on {opposite} (correlation {fits.number(min(corr), '.2f')} to "
        f"{fits.number(max(corr), '.2f')}, |vz| "
        f"≈ {fits.span([f[2] for f in figures], '.1f')} × the altitude rate)"
    )


@generator("sitl-vz-sign")
def sitl_vz_sign() -> str:
    """docs/replay.md: the same check on current ArduCopter SITL's tlog."""
    rate, climb, _ = vertical_pairs(ARDUCOPTER_GUIDED.with_suffix(".tlog"))
    agree, corr, _ = _agreement(rate, climb)
    pairs = f"all {agree}" if agree == len(rate) else f"{agree} of {len(rate)}"
    return f"agrees on {pairs} pairs (correlation {corr:+.2f})"


@generator("iris-replay-periods", reads=IRIS)
def iris_replay_periods() -> str:
    """The two periods' RMSE and MAPE ranges, and how close each one's energy comes."""
    summaries = {p: summarize(flights) for p, (_, flights) in iris_periods().items()}
    rmse = sorted(s.power_rmse_w or 0.0 for s in summaries.values())
    mape = sorted(s.power_mape_pct or 0.0 for s in summaries.values())
    energy = " and ".join(
        f"{100 * abs(s.energy_predicted_wh / s.energy_measured_wh - 1):.1f} % ({p.split()[0]})"
        for p, s in summaries.items()
    )
    return (
        f"**{rmse[0]:.1f}–{rmse[-1]:.1f} W RMSE ({mape[0]:.1f}–{mape[-1]:.1f} % MAPE)** "
        f"in-sample, and over a whole period to {energy} of the measured energy"
    )


#: The IRIS+ flights docs/replay.md reads the power module's scatter off.
QUIET_IRIS_FLIGHTS = ("2016-08-03/002/002", "2016-08-09/003/003")


def _airborne_power(flight: FlightReplay) -> tuple[np.ndarray, np.ndarray]:
    """A flight's airborne readings: measured and model power (W)."""
    _, measured, model, airborne = flight.power.arrays()
    return measured[airborne], model[airborne]


@generator("iris-replay-power-span", reads=IRIS)
def iris_replay_power_span() -> str:
    """The 5th–95th percentile of the measured power (W, to 10 W) over every IRIS+ flight's
    airborne readings."""
    measured = np.concatenate([_airborne_power(f)[0] for f in _all_iris_flights()])
    low, high = np.round(np.percentile(measured, [5, 95]), -1)
    return f"{low:.0f}–{high:.0f} W"


@generator("iris-replay-reading-noise", reads=IRIS)
def iris_replay_reading_noise() -> str:
    """On :data:`QUIET_IRIS_FLIGHTS`: the 1σ of one reading from successive differences (W)
    and the residual σ of the model (W)."""
    flights = {f.name: f for f in _all_iris_flights()}
    reading, residual = [], []
    for name in QUIET_IRIS_FLIGHTS:
        measured, model = _airborne_power(flights[name])
        reading.append(float(np.std(np.diff(measured)) / np.sqrt(2)))
        residual.append(float(np.std(model - measured)))
    return (
        f"{fits.span(reading, '.1f')} W (1σ of one reading, from their differences, on "
        f"{' and '.join(QUIET_IRIS_FLIGHTS)}, whose residual σ is {fits.span(residual, '.1f')} W)"
    )


@generator("iris-replay-march", reads=IRIS)
def iris_replay_march() -> str:
    """The power RMSE (W) of the March flights replayed with their own vehicle file."""
    _, flights = iris_periods()["March 2016"]
    return f"{summarize(flights).power_rmse_w:.0f} W"


@generator("fleet-iris-file-masses")
def fleet_iris_file_masses() -> str:
    """The masses (kg) of the two IRIS+ periods' vehicle files and their ratio."""
    march, summer = (
        load_vehicle(REPO / "config" / "vehicles" / name).mass_kg for _, name in PERIODS.values()
    )
    return f"{march:g} → {summer:g} kg (×{summer / march:.2f})"


@generator("iris-replay-builtin", reads=IRIS)
def iris_replay_builtin() -> str:
    """The same logs with the built-in vehicle (no ``--vehicle``)."""
    s = summarize(_replay(sorted(IRIS.glob("**/*.log")), None))
    return (
        f"{s.power_rmse_w:.0f} W RMSE and {s.energy_predicted_wh:.0f} Wh predicted against "
        f"{s.energy_measured_wh:.0f} Wh measured"
    )


@generator("replay-regression-march")
def replay_regression_march() -> str:
    """The span of the power RMSE frozen in ``replay/expected.json`` for the March flights
    (replayed there with the June–August vehicle file)."""
    flights = json.loads((REPO / "replay" / "expected.json").read_text())["flights"]
    rmse = [f["power_rmse_w"] for name, f in flights.items() if "/2016-03-" in name]
    return f"{min(rmse):.0f}–{max(rmse):.0f} W RMSE"


# --- mission plans against ArduCopter SITL ---------------------------------------------------


def _mission_dirs() -> list[Path]:
    """The recorded missions (a mission file without its flight is not one yet)."""
    return sorted(p for p in MISSIONS.iterdir() if (p / "truth.json").is_file())


def _truth(directory: Path) -> dict[str, Any]:
    return dict(json.loads((directory / "truth.json").read_text()))


@cache
def mission_checks(
    still_air: bool = False, settings: FlightSettings | None = None
) -> tuple[MissionCheck, ...]:
    """Every recorded mission planned with the SITL vehicle file and ``settings``, told the
    wind and payload SITL flew (or, ``still_air``, the payload only)."""
    vehicle = load_vehicle(sitl.SITL_VEHICLE)
    checks = []
    for directory in _mission_dirs():
        told = truth_conditions(_truth(directory))
        conditions = replace(told, wind_speed_mps=0.0) if still_air else told
        checks.append(check_recording(directory, vehicle, settings, conditions))
    return tuple(checks)


def _mission_inputs(directory: Path) -> str:
    """The mission file, the wind and payload SITL flew and the legs: a row's first cells."""
    told = truth_conditions(_truth(directory))
    mission_file = sorted(directory.glob("mission.*"))[0]
    legs = load_mission(mission_file).legs()
    load = "–"
    if told.payload_kg > 0:
        load = f"{told.payload_kg:g} kg" + (", released" if not legs[-1].payload else "")
    return (
        f"| {directory.name} | `{mission_file.name}` "
        f"| {told.wind_speed_mps:g} m/s from {told.wind_from_deg:03.0f}° | {load} | {len(legs)}"
    )


def _abs_errors(checks: Sequence[MissionCheck], px4: bool = False) -> np.ndarray:
    return np.abs([c.px4_error_pct if px4 else c.error_pct for c in checks])


@generator("plan-missions")
def plan_missions() -> str:
    """The per-mission rows of docs/plan.md's SITL table."""
    rows = []
    for directory, c in zip(_mission_dirs(), mission_checks(), strict=True):
        half = "calibration" if c.name in CALIBRATION else "held out"
        half = next((v for k, v in HELD_OUT_SETS.items() if c.name.startswith(k)), half)
        rows.append(
            f"{_mission_inputs(directory)} | {c.predicted_wh:.2f} ± {c.predicted_sigma_wh:.2f} "
            f"| {c.measured_wh:.2f} | {fits.number(c.error_pct, '+.1f')} % | {c.px4_wh:.2f} "
            f"| {fits.number(c.px4_error_pct, '+.1f')} % "
            f"| {c.predicted_time_s:.0f} / {c.measured_time_s:.0f} | {half} |"
        )
    header = (
        "| mission | file | wind | payload | legs | predicted Wh ± 1σ | measured Wh | error "
        "| PX4-style Wh | PX4-style error | time s plan / flown | |\n"
        "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"
    )
    return header + "\n" + "\n".join(rows)


@generator("plan-summary")
def plan_summary() -> str:
    checks = mission_checks()
    held = [c for c in checks if c.name.startswith(LATEST_HELD_OUT)]
    seen = [c for c in checks if c not in held]
    ours, px4 = _abs_errors(seen), _abs_errors(checks, px4=True)
    text = (
        f"Median |error| {np.median(ours):.1f} % (max {ours.max():.1f} %) over the "
        f"{len(seen)} missions seen when the rules were set, the planner told the wind and "
        f"payload SITL flew"
    )
    if held:
        errors = _abs_errors(held)
        text += (
            f"; {np.median(errors):.1f} % (max {errors.max():.1f} %) over the {len(held)} "
            f"flown after the last was frozen"
        )
    return (
        f"{text}; the PX4-style estimate misses by {np.median(px4):.0f} % in the median "
        f"({px4.min():.0f}–{px4.max():.0f} %)"
    )


#: docs/plan.md's example: a mission and the wind SITL flew it in.
PLAN_EXAMPLE = (MISSIONS / "climbs_wind6" / "mission.plan", "6@135")


@generator("plan-example")
def plan_example() -> str:
    """``uav-energy plan MISSION --vehicle SITL --wind W``'s output as a code block, without
    its title and the table's rules (their width follows the terminal)."""
    mission, wind = PLAN_EXAMPLE
    out = _cli("plan", str(mission), "--vehicle", str(sitl.SITL_VEHICLE), "--wind", wind)
    lines = [line.rstrip() for line in out.splitlines()[1:] if line[:1] not in "┏┡├└"]
    return "\n".join(["```", *lines, "```"])


@generator("plan-c1-c3-sigma")
def plan_c1_c3_sigma() -> str:
    """The 1σ of the hover power the planner takes from the SITL vehicle file's c1 and c3 as
    independent, % of the hover power."""
    vehicle = load_vehicle(sitl.SITL_VEHICLE)
    sigma_w = math.hypot(vehicle.model_stderr["c1"], vehicle.model_stderr["c3"])
    return f"≈ {100 * sigma_w / vehicle.model.hover_power_w:.0f} % of hover power"


@generator("plan-within-sigma")
def plan_within_sigma() -> str:
    """How many of the missions' predictions (told the wind and payload SITL flew) lie within
    their 1σ of the measured energy."""
    checks = mission_checks()
    within = sum(abs(c.predicted_wh - c.measured_wh) <= c.predicted_sigma_wh for c in checks)
    every = "every prediction is" if within == len(checks) else f"{within} predictions are"
    return f"Over the {len(checks)} SITL missions below {every} within its 1σ of the measurement"


@generator("plan-still-air")
def plan_still_air() -> str:
    errors = _abs_errors(mission_checks(still_air=True))
    return f"{np.median(errors):.1f} % / {errors.max():.1f} %"


@generator("plan-airspeed-total")
def plan_airspeed_total() -> str:
    """The airspeed limit (10.5 m/s) on the total airspeed instead of along the track."""
    settings = FlightSettings(max_airspeed_mps=10.5, airspeed_along_track=False)
    errors = _abs_errors(mission_checks(settings=settings))
    return f"{np.median(errors):.1f} % / {errors.max():.1f} %"


#: The mission whose legs docs/plan.md sets planned against flown (the RTL off the nose).
PLAN_LEGS_MISSION = MISSIONS / "tall_wind4"


@generator("plan-legs")
def plan_legs() -> str:
    """tall_wind4's legs, planned (told the wind SITL flew) against flown."""
    rows = [
        f"| {c.seq} | {c.kind} | {c.planned_time_s:.1f} / {c.flown_time_s:.1f} "
        f"| {c.planned_wh:.2f} / {c.flown_wh:.2f} | {fits.number(c.error_pct, '+.1f')} % |"
        for c in leg_checks(PLAN_LEGS_MISSION, load_vehicle(sitl.SITL_VEHICLE))
    ]
    header = "| item | leg | time s plan / flown | energy Wh plan / flown | error |\n"
    return header + "|---:|---|---:|---:|---:|\n" + "\n".join(rows)


#: The climb and descent rates (m/s) docs/plan.md gives the planner's climb term at.
CLIMB_MPS, DESCENT_MPS = 2.5, 1.5


@generator("plan-climb-power")
def plan_climb_power() -> str:
    """The planner's power beyond hover (W) at :data:`CLIMB_MPS` up and :data:`DESCENT_MPS`
    down with the SITL vehicle file, and SITL's at the same rates: its vertical law fitted on
    the climbs and descents of ``replay/sitl_axial`` (``tests/vertical_fit.py``)."""
    vehicle = load_vehicle(sitl.SITL_VEHICLE)
    climb_mps = np.array([CLIMB_MPS, -DESCENT_MPS])
    route = RouteVehicle.from_vehicle(vehicle)
    hover_w, *planned_w = steady_power_w(route, Conditions(), 0.0, 0.0, [0.0, *-climb_mps])
    axial = [vertical_fit.axial_samples(name) for name in vertical_fit.AXIAL_FLIGHTS]
    per_mps, per_mps2, _ = vertical_fit.vertical_response(axial, vehicle)
    sitl_w = per_mps * climb_mps + per_mps2 * climb_mps * np.abs(climb_mps)
    up, down = (
        f"{fits.number(plan_w - hover_w, '+.0f')} W at {abs(rate):g} m/s {way}"
        for plan_w, rate, way in zip(planned_w, climb_mps, ("up", "down"), strict=True)
    )
    measured = " and ".join(f"{fits.number(w, '+.0f')} W" for w in sitl_w)
    return (
        f"{up} and {down}, where SITL draws {measured} (its vertical law fitted on the "
        f"flights of `replay/sitl_axial`)"
    )


#: The recorded mission whose headwind leg docs/plan.md names among the remaining misses.
HEADWIND_MISSION = MISSIONS / "outback_wind8"


def upwind_leg(plan: MissionEnergy) -> LegResult:
    """The waypoint leg of ``plan`` flown most nearly into its wind."""
    legs = [r for r in plan.legs if r.leg.kind == "waypoint"]
    return min(legs, key=lambda r: angle_deg(r.track_deg, plan.conditions.wind_from_deg))


@generator("plan-headwind-leg")
def plan_headwind_leg() -> str:
    """On :data:`HEADWIND_MISSION`, the waypoint leg flown most nearly into the wind SITL
    flew: its ground speed as flown (the median) and as planned (m/s)."""
    plan = predict_recording(HEADWIND_MISSION, load_vehicle(sitl.SITL_VEHICLE))
    upwind = upwind_leg(plan)
    flown_mps = float(
        np.median(item_ground_speeds_mps(HEADWIND_MISSION / "flight.tlog", upwind.leg.seq))
    )
    return (
        f"`{HEADWIND_MISSION.name}`: the quad makes {flown_mps:.1f} m/s into "
        f"{plan.conditions.wind_speed_mps:g} m/s, planned {upwind.energy.ground_speed_mps:.1f}"
    )


@generator("plan-example-upwind")
def plan_example_upwind() -> str:
    """docs/plan.md's example (:data:`PLAN_EXAMPLE`, planned in the wind SITL flew it in): its
    leg most nearly into the wind, the speed the mission asks, the ground speed planned, and
    its share of the energy (%)."""
    plan = predict_recording(PLAN_EXAMPLE[0].parent, load_vehicle(sitl.SITL_VEHICLE))
    upwind = upwind_leg(plan)
    asked_mps = upwind.leg.speed_mps or plan.settings.cruise_mps
    share = 100 * upwind.energy.energy_wh / plan.total.energy_wh
    return (
        f"Leg {plan.legs.index(upwind) + 1} flies into the wind: the mission asks "
        f"{asked_mps:g} m/s, the SITL quad makes {upwind.energy.ground_speed_mps:.1f} m/s over "
        f"ground at its airspeed limit, and that one leg takes {share:.0f} % of the energy"
    )


#: The crosswind (m/s, across a track the nose follows) docs/plan.md gives the headway it costs.
CROSSWIND_MPS = 7.0


@generator("plan-crosswind-headway")
def plan_crosswind_headway() -> str:
    """The SITL quad's airspeed limit along its track (nose on it) in :data:`CROSSWIND_MPS`
    across, against its limit straight ahead (m/s)."""
    vehicle = load_vehicle(sitl.SITL_VEHICLE)
    assert vehicle.drag is not None and vehicle.max_airspeed_mps is not None
    straight = vehicle.max_airspeed_mps
    along = along_track_limit_mps(vehicle.drag, straight, (0.0, CROSSWIND_MPS), 0.0, 0.0)
    return f"{along:.1f} m/s along the track in {CROSSWIND_MPS:g} m/s across, against {straight:g}"


@generator("plan-headline")
def plan_headline() -> str:
    checks = mission_checks()
    told, still = _abs_errors(checks), _abs_errors(mission_checks(still_air=True))
    held = _abs_errors([c for c in checks if c.name.startswith(LATEST_HELD_OUT)])
    px4 = _abs_errors(checks, px4=True)
    return (
        f"{len(told)} AUTO missions, told the wind SITL flew: median error "
        f"{np.median(told):.1f} %, max {told.max():.1f} % ({len(held)} held out: "
        f"{np.median(held):.1f} %, max {held.max():.1f} %; 3 of the others set the flight "
        f"settings); told still air: {np.median(still):.1f} % / {still.max():.0f} %; a "
        f"PX4-style distance/set-speed estimate misses by {np.median(px4):.0f} %"
    )


# --- the simulator's flights replayed -------------------------------------------------------------


def _cli(*argv: str) -> str:
    """What ``uav-energy ARGV…`` prints on stdout (run in this process)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = cli.main(list(argv))
    if code != 0:
        raise UserError(f"uav-energy {' '.join(argv)} ended with exit code {code}")
    return out.getvalue()


@cache
def simulated_mixed(wind: str | None) -> tuple[str, dict[str, Any]]:
    """``uav-energy sim --plan mixed [--wind S@DEG] --tlog F``'s line and ``uav-energy replay
    F --json`` (the built-in vehicle, told nothing of the wind)."""
    with tempfile.TemporaryDirectory() as tmp:
        tlog = str(Path(tmp) / "mixed.tlog")
        line = _cli("sim", "--plan", "mixed", *(["--wind", wind] if wind else []), "--tlog", tlog)
        return line.strip(), json.loads(_cli("replay", tlog, "--json"))


def _replay_sentence(result: Mapping[str, Any]) -> str:
    return (
        f"power RMSE {result['power_rmse_w']:.1f} W (MAPE {result['power_mape_pct']:.1f} %), "
        f"energy {result['energy_measured_wh']:.2f} Wh measured vs "
        f"{result['energy_predicted_wh']:.2f} Wh predicted"
    )


@generator("sim-mixed-clean")
def sim_mixed_clean() -> str:
    return _replay_sentence(simulated_mixed(None)[1])


@generator("sim-mixed-wind")
def sim_mixed_wind() -> str:
    return _replay_sentence(simulated_mixed("6@135")[1])


@generator("sim-mixed-wind-line")
def sim_mixed_wind_line() -> str:
    """The summary line ``uav-energy sim`` prints, as an indented code block."""
    return "    " + simulated_mixed("6@135")[0]


@generator("sitl-run1-builtin", reads=SITL_RUN1.parent)
def sitl_run1_builtin() -> str:
    """``../shared``'s recorded SITL flight replayed with the built-in vehicle on SITL's pack
    (docs/sitl.md gives the commands)."""
    with tempfile.TemporaryDirectory() as tmp:
        vehicle_file = Path(tmp) / "sitl.toml"
        builtin_on_sitl_pack().save(vehicle_file)
        result = json.loads(
            _cli("replay", str(SITL_RUN1), "--vehicle", str(vehicle_file), "--json")
        )
    return (
        f"{result['airborne_s']:.1f} s airborne, power RMSE {result['power_rmse_w']:.1f} W "
        f"(MAPE {result['power_mape_pct']:.1f} %), {result['energy_measured_wh']:.1f} Wh "
        f"measured vs {result['energy_predicted_wh']:.1f} Wh predicted"
    )


@generator("sitl-run1-estimates", reads=SITL_RUN1.parent)
def sitl_run1_estimates() -> str:
    """How many estimates the replay of ``../shared``'s recorded SITL flight gives with
    :func:`builtin_on_sitl_pack` (``tests/test_ardupilot_sitl.py`` plays it live into the
    daemon and checks the daemon gives exactly these)."""
    return f"{len(replay_log(SITL_RUN1, builtin_on_sitl_pack()).estimates)}"


#: The SITL AUTO mission docs/replay.md replays with its mission file (``--mission``).
MISSION_REPLAYED = MISSIONS / "square_wind5"
#: How long after take-off (s) that mission's figure is read.
MISSION_READ_AFTER_S = 30.0


def estimates_csv(*argv: str) -> list[dict[str, str]]:
    """The rows of ``uav-energy replay ARGV… --out F.csv``."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "estimates.csv"
        _cli("replay", *argv, "--out", str(out))
        with out.open() as fh:
            return list(csv.DictReader(fh))


def mission_figure(flight: Path, rows: Sequence[Mapping[str, str]]) -> tuple[float, float, float]:
    """A replay's estimate rows of the SITL mission recording ``flight``: the rest of the
    mission's energy and its 1σ :data:`MISSION_READ_AFTER_S` after take-off (``MIS_WH``,
    ``MIS_SIG``, Wh), and the energy the vehicle drew from then to the disarm (Wh, ∫ V·I of
    its own readings, trapezoids)."""
    events = _truth(flight)["events"]
    time_s = [float(r["time_s"]) for r in rows]
    power_w = [float(r["power_measured_w"]) for r in rows]
    at = next(k for k, t in enumerate(time_s) if t >= events["takeoff_s"] + MISSION_READ_AFTER_S)
    end = next(k for k, t in enumerate(time_s) if t >= events["disarmed_s"])
    drawn_wh = sum(
        0.5 * (power_w[k] + power_w[k + 1]) * (time_s[k + 1] - time_s[k]) for k in range(at, end)
    )
    return (
        float(rows[at]["mission_energy_wh"]),
        float(rows[at]["mission_sigma_wh"]),
        drawn_wh / 3600,
    )


@generator("replay-mission")
def replay_mission() -> str:
    """docs/replay.md: ``uav-energy replay F.tlog --vehicle SITL --mission F.waypoints`` of
    :data:`MISSION_REPLAYED`, its mission figure against the energy drawn."""
    tlog, mission = MISSION_REPLAYED / "flight.tlog", MISSION_REPLAYED / "mission.waypoints"
    rows = estimates_csv(str(tlog), "--vehicle", str(sitl.SITL_VEHICLE), "--mission", str(mission))
    predicted_wh, sigma_wh, drawn_wh = mission_figure(MISSION_REPLAYED, rows)
    return (
        f"{predicted_wh:.2f} ± {sigma_wh:.2f} Wh against {drawn_wh:.2f} Wh drawn, "
        f"{fits.number(100 * (predicted_wh / drawn_wh - 1), '+.1f')} %"
    )


def builtin_on_sitl_pack() -> Vehicle:
    """The built-in vehicle on ArduPilot SITL's pack (3S, 3.3 Ah, 20 % reserve)."""
    return replace(default_vehicle(), name="sitl-quad", battery=BatterySpec(3.3, 3, 0.2))


@generator("replay-arducopter-bin")
def replay_arducopter_bin() -> str:
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


# --- the power model fitted on real data, and on SITL's clean flights ---------------------------


@cache
def real_fits() -> dict[str, dict[str, Any]]:
    """``uav-energy fit LOG… --mass-kg M --capacity-ah C --cells N --json`` of each dataset as
    ``make fit-real`` runs it (without writing the vehicle files)."""
    return {title: _fit(title) for title in fits.REAL_FITS}


def _fit(title: str, *extra: str) -> dict[str, Any]:
    """``uav-energy fit`` of one dataset of :data:`fits.REAL_FITS`, with ``extra`` options."""
    pattern, mass_kg, capacity_ah, cells = fits.REAL_FITS[title]
    logs = [str(p) for p in sorted(SHARED_DATA.glob(pattern))]
    options = ("--mass-kg", f"{mass_kg}", "--capacity-ah", f"{capacity_ah}", "--cells", f"{cells}")
    return dict(json.loads(_cli("fit", *logs, *options, *extra, "--json")))


@cache
def sitl_quad_fit() -> dict[str, Any]:
    """``uav-energy fit`` of the clean SITL recordings, as docs/sitl.md gives the command (the
    SITL vehicle file is this fit plus the acceleration effect found later)."""
    logs = [str(sitl.SITL_RECORDINGS / s / "flight.tlog") for s in sitl.CLEAN_RECORDINGS]
    options = ("--mass-kg", "3.0", "--capacity-ah", "2.2", "--cells", "3")
    return dict(json.loads(_cli("fit", *logs, *options, "--json")))


generator("fit-real-table", reads=SHARED_DATA)(lambda: fits.summary_table(real_fits()))
generator("fit-real-details", reads=SHARED_DATA)(lambda: fits.details_table(real_fits()))
generator("fit-real-folds", reads=SHARED_DATA)(
    lambda: ", ".join(fits.fold_difference(f, "polynomial") for f in real_fits().values())
)


@cache
def no_priors_fit() -> dict[str, Any]:
    """``uav-energy fit`` of the IRIS+ March flights with ``--no-priors`` (the data alone)."""
    return _fit("IRIS+ March 2016", "--no-priors")


def _iris_fits() -> list[dict[str, Any]]:
    """The two IRIS+ periods' fits of :func:`real_fits`."""
    return [fit for title, fit in real_fits().items() if "IRIS+" in title]


#: The speed (m/s) docs/fit.md compares the IRIS+ curves' power at with hover.
IRIS_LEG_SPEED_MPS = 5.0

generator("fit-real-inflation", reads=SHARED_DATA)(lambda: fits.inflation(real_fits().values()))
generator("fit-iris-speeds", reads=SHARED_DATA)(lambda: fits.speeds(_iris_fits()))
generator("fit-iris-flat", reads=SHARED_DATA)(lambda: fits.flat(_iris_fits(), IRIS_LEG_SPEED_MPS))
generator("fit-iris-determined", reads=SHARED_DATA)(lambda: fits.determined(_iris_fits()))
generator("fit-iris-c1-c3", reads=SHARED_DATA)(lambda: fits.profile_and_induced(_iris_fits()))
generator("fit-iris-noise", reads=SHARED_DATA)(lambda: fits.noise(_iris_fits()))
generator("fit-cmu-dip", reads=SHARED_DATA)(lambda: fits.dip(real_fits()["CMU DJI M100"]))
generator("fit-cmu-vme", reads=SHARED_DATA)(lambda: fits.v_me(real_fits()["CMU DJI M100"]))


@generator("fit-degree-6", reads=SHARED_DATA)
def fit_degree_6() -> str:
    """``uav-energy fit … --degree 6``'s held-out polynomial RMSE on IRIS+ March and CMU."""
    rmse = [
        _fit(title, "--degree", "6")["models"]["polynomial"]["rmse_w"]
        for title in ("IRIS+ March 2016", "CMU DJI M100")
    ]
    return f"{rmse[0]:.2f} W on IRIS+ March and {rmse[1]:.2f} W on CMU"


generator("fit-no-priors-cmu", reads=SHARED_DATA)(
    lambda: f"{_fit('CMU DJI M100', '--no-priors')['models']['theory']['rmse_w']:.1f} W"
)
generator("fit-sitl-run1", reads=SITL_RUN1.parent)(
    lambda: fits.theory_against_polynomial(json.loads(_cli("fit", str(SITL_RUN1), "--json")))
)
generator("fit-no-priors", reads=SHARED_DATA)(lambda: fits.no_priors(no_priors_fit()))
generator("fit-no-priors-values", reads=SHARED_DATA)(lambda: fits.no_priors_values(no_priors_fit()))
generator("fit-cmu-residual", reads=SHARED_DATA)(
    lambda: fits.residual_noise(real_fits()["CMU DJI M100"])
)
generator("sitl-quad-fit")(lambda: fits.sitl_quad_summary(sitl_quad_fit()))
generator("sitl-quad-fit-data")(lambda: fits.sitl_quad_data(sitl_quad_fit()))
generator("sitl-quad-fit-errors")(lambda: fits.sitl_quad_errors(sitl_quad_fit()))


# --- the pack fitted on SITL's pack flights ------------------------------------------------------


@cache
def pack_fits() -> dict[str, tuple[list[str], list[np.ndarray]]]:
    """``python scripts/pack_fit_sitl.py``'s fits (3 s of CPU)."""
    return dict(pack_fit_table.halves())


generator("pack-fit-sitl-table")(lambda: pack_fit_table.table(pack_fits()))
generator("pack-fit-sitl-pooled")(lambda: pack_fit_table.pooled(pack_fits()))


# --- the paper's experiments ------------------------------------------------------------------


@cache
def experiments_run() -> Experiments:
    """``uav-energy experiments`` (seed 0)."""
    with tempfile.TemporaryDirectory() as out:
        return reproduce(Path(out), seed=0)


@cache
def experiments() -> tuple[str, str]:
    """``uav-energy experiments`` (seed 0): the fit's and the circles' sentences."""
    result = experiments_run()
    truth, fitted = result.vehicle.model, result.fit.theory.model
    scores = result.fit.scores
    fit = (
        f"fitted hover power {fitted.hover_power_w:.1f} W (truth {truth.hover_power_w:.1f}), "
        f"V_me {fitted.max_endurance_speed_mps():.2f} m/s "
        f"({truth.max_endurance_speed_mps():.2f}), V_mr {fitted.max_range_speed_mps():.2f} m/s "
        f"({truth.max_range_speed_mps():.2f}); held-out RMSE theory "
        f"{scores['theory'].rmse_w:.2f} W, polynomial {scores['polynomial'].rmse_w:.2f} W, "
        f"network {scores['dnn'].rmse_w:.2f} W at a residual σ of "
        f"{result.fit.theory.sigma_w:.1f} W"
    )
    eq2 = max(abs(c.eq2_w - c.measured_w) for c in result.circles)
    miss, worst = max(
        (abs(c.eq1_w - c.measured_w), (c, r))
        for c, r in zip(result.circles, result.radii_m, strict=True)
    )
    circle, radius = worst
    circles = (
        f"eq. (2) predicts the power within {np.ceil(eq2):.0f} W; eq. (1), which ignores a⊥, "
        f"misses by up to {miss:.0f} W at {circle.speed_mps:.0f} m/s, r = {radius:.0f} m"
    )
    return fit, circles


@generator("experiments-fit")
def experiments_fit() -> str:
    return experiments()[0]


@generator("experiments-circles")
def experiments_circles() -> str:
    return experiments()[1]


generator("experiments-curve")(lambda: curve_table(experiments_run()))
generator("experiments-points")(
    lambda: (
        f"{len(experiments_run().fit.points.kept()):,} of "
        f"{len(experiments_run().fit.points):,} points kept"
    )
)
generator("experiments-circles-table")(
    lambda: circles_markdown(experiments_run().circles, experiments_run().radii_m).rstrip()
)


@generator("experiments-fit-details")
def experiments_fit_details() -> str:
    """docs/fit.md's sentence: hover power, V_me and V_mr ± 1σ against the truth, held-out
    RMSE / MAPE of each model (and the network's worst fold), the residual σ."""
    result = experiments_run()
    truth, fit = result.vehicle.model, result.fit.summary()
    return (
        f"Hover {fit['hover_power_w']:.1f} W (truth {truth.hover_power_w:.1f}), V_me "
        f"{fits.pm(fit['v_me_mps'], fit['v_me_stderr_mps'], '.2f')} m/s (truth "
        f"{truth.max_endurance_speed_mps():.2f}), V_mr "
        f"{fits.pm(fit['v_mr_mps'], fit['v_mr_stderr_mps'], '.2f')} m/s (truth "
        f"{truth.max_range_speed_mps():.2f}). Held-out by flight: theory "
        f"{fits.held_out(fit, 'theory')}, polynomial {fits.held_out(fit, 'polynomial')}, "
        f"network {fits.held_out(fit, 'dnn')} (its worst fold "
        f"{max(fit['fold_rmse_w']['dnn']):.1f} W). Residual σ {fit['noise_sigma_w']:.1f} W"
    )


# --- residual analysis of simulated flights with a hidden effect ----------------------------------


@cache
def simulated_residuals() -> tuple[dict[str, Any], dict[str, Any]]:
    return residual_figures.hidden_runs(_cli)


@cache
def changing_residuals() -> dict[str, Any]:
    return residual_figures.changing_runs(_cli)


@cache
def iris_residuals() -> dict[str, Any]:
    return residual_figures.iris_runs(_cli, IRIS)


generator("residuals-iris-table", reads=IRIS)(lambda: residual_figures.iris_table(iris_residuals()))
generator("residuals-iris-summer", reads=IRIS)(
    lambda: residual_figures.iris_summer(iris_residuals())
)
_real_blocks = script_module("real_residual_figures").generators(
    _cli, IRIS, tracker_cmu.DATA, lambda: iris_residuals()["June–August"]
)
for _name, _print in _real_blocks.items():
    generator(_name, reads=SHARED_DATA)(_print)
generator("residuals-sim-changing", checked_by="tests/test_residual_figures.py")(
    lambda: residual_figures.changing_table(changing_residuals())
)
generator("residuals-sim-changing-floors", checked_by="tests/test_residual_figures.py")(
    lambda: residual_figures.changing_floors(changing_residuals())
)
for _name, _print in vertical_figures.generators(_cli, vertical_fit).items():
    generator(_name)(_print)
for _name, _print in script_module("online_figures").generators().items():
    generator(_name)(_print)
generator("residuals-sim-table")(lambda: residual_figures.hidden_table(simulated_residuals()[0]))
generator("residuals-sim-step")(
    lambda: residual_figures.step_footnote(simulated_residuals()[0][residual_figures.STEP_ROW])
)
generator("residuals-sim-recovered")(lambda: residual_figures.recovered(simulated_residuals()[0]))
generator("residuals-sim-wind")(lambda: residual_figures.wind_rmse(simulated_residuals()[0]))
generator("residuals-sim-replay")(lambda: residual_figures.replay_table(simulated_residuals()[1]))
generator("residuals-sim-tracked")(
    lambda: residual_figures.tracked_replay(simulated_residuals()[1][residual_figures.WIND_ROW])
)


# --- the daemon ---------------------------------------------------------------------------------


@generator("state-restart-table")
def state_restart_table() -> str:
    """``python -m bench.trust``'s restart mid-flight (in process; < 1 s of CPU)."""
    trust = script_module("trust", REPO / "bench")
    return str(trust.restart_table(trust.flight()))


# --- the SITL recordings: replayed, the effects named on them, the wind in use -------------------


_SITL_RECORDINGS_TEST = "tests/test_sitl_recordings.py"
_SITL_EFFECTS_TEST = "tests/test_sitl_effects.py"


@cache
def sitl_replays() -> dict[str, FlightReplay]:
    """Every recording of ``replay/sitl`` replayed with the SITL vehicle file."""
    vehicle = load_vehicle(sitl.SITL_VEHICLE)
    logs = {s: sitl.SITL_RECORDINGS / s / "flight.tlog" for s in sitl.recordings()}
    return {s: replay_log(log, vehicle) for s, log in logs.items()}


generator("sitl-recordings-table", checked_by=_SITL_RECORDINGS_TEST)(
    lambda: sitl.recordings_table(sitl_replays())
)
generator("sitl-hexa-energy", checked_by=_SITL_RECORDINGS_TEST)(
    lambda: sitl.hexa_energy(sitl_replays())
)
generator("sitl-wind-cost", checked_by=_SITL_RECORDINGS_TEST)(
    lambda: sitl.wind_cost(sitl_replays())
)
generator("sitl-payload-hover-current")(sitl.payload_hover_current)
for _recording in (sitl.PAYLOADS[0], sitl.HEAVY_AIRFRAME):
    generator(f"sitl-hover-power-{_recording.replace('_', '-')}")(
        partial(sitl.hover_power_rise, _recording)
    )


@generator("sitl-effects-table", checked_by=_SITL_EFFECTS_TEST)
def sitl_effects_table() -> str:
    return sitl.effects_table(sitl.effect_checks())


@generator("sitl-effects-right", checked_by=_SITL_EFFECTS_TEST)
def sitl_effects_right() -> str:
    return sitl.effects_right(sitl.effect_checks())


@generator("sitl-effects-floors", checked_by=_SITL_EFFECTS_TEST)
def sitl_effects_floors() -> str:
    return sitl.effects_floors(sitl.effect_checks())


for _name, _summary in (
    ("sitl-effects-clean", sitl.effects_clean),
    ("sitl-effects-wind", sitl.effects_wind),
    ("sitl-effects-payload", sitl.effects_payload),
    ("sitl-effects-turn", sitl.effects_turn),
    ("sitl-effects-heavy", sitl.effects_heavy),
    ("sitl-effects-onset-circles", sitl.effects_onset_circles),
):
    generator(_name, checked_by=_SITL_EFFECTS_TEST)(lambda f=_summary: f(sitl.effect_checks()))


_SITL_HELD_TEST = "tests/test_sitl_held_out.py"
generator("sitl-held-table", checked_by=_SITL_HELD_TEST)(
    lambda: sitl.effects_table(sitl.held_checks(), sitl.HELD_RECORDINGS)
)
generator("sitl-held-count")(sitl.held_count)
generator("sitl-held-floors", checked_by=_SITL_HELD_TEST)(
    lambda: sitl.effects_floors(sitl.held_checks())
)
generator("sitl-held-summary", checked_by=_SITL_HELD_TEST)(
    lambda: sitl.held_summary(sitl.held_checks())
)
for _name, _figures in (
    ("sitl-held-windows", sitl.held_windows),
    ("sitl-held-autopilot-wind", sitl.held_autopilot_wind),
    ("sitl-held-short-onset", sitl.held_short_onset),
    *(
        (f"sitl-held-no-gain-{flight.replace('_', '-')}", partial(sitl.held_no_gain, name=flight))
        for flight in sitl.HELD_NO_GAIN
    ),
):
    generator(_name, checked_by=_SITL_HELD_TEST)(lambda f=_figures: f(sitl.held_checks()))


@generator("tracked-wind-sitl", checked_by=_SITL_RECORDINGS_TEST)
def tracked_wind_sitl() -> str:
    """``python scripts/tracked_wind_sitl.py``'s table (20 s of CPU; its check shares the
    replays with WIND of ``tests/test_sitl_recordings.py``)."""
    return "\n".join(script_module("tracked_wind_sitl").table_lines())


@generator("tracker-cmu", reads=tracker_cmu.DATA)
def tracker_on_cmu() -> str:
    """``python scripts/tracker_cmu.py``'s table: the online tracker on the CMU flights."""
    return tracker_cmu.report(*tracker_cmu.both())


@generator("tracker-cmu-shows", reads=tracker_cmu.DATA)
def tracker_on_cmu_shows() -> str:
    """docs/residuals.md's reading of the ``tracker-cmu`` table."""
    return str(tracker_cmu.shows(*tracker_cmu.both()))


_TRACKER_SITL_TEST = "tests/test_tracker_sitl.py"
#: The slow model error (fraction of the hover power) docs/residuals.md's counterfactual tries.
TRACKER_SITL_SLOW_ERROR = 0.02


@cache
def sitl_tracker_runs(
    recordings: Path = sitl.SITL_RECORDINGS, slow_error_fraction: float | None = None
) -> list[Any]:
    """``python scripts/tracker_sitl.py [RECORDINGS] [--slow-error-fraction F]``'s runs (10 s
    of CPU for replay/sitl; their checks share the runs of the tests that name them)."""
    return list(tracker_sitl.runs(recordings, slow_error_fraction))


generator("tracker-sitl", checked_by=_TRACKER_SITL_TEST)(
    lambda: str(tracker_sitl.report(sitl_tracker_runs()))
)
generator("tracker-sitl-shows", checked_by=_TRACKER_SITL_TEST)(
    lambda: str(tracker_sitl.shows(sitl_tracker_runs()))
)
generator("tracker-sitl-slow-2pct", checked_by=_TRACKER_SITL_TEST)(
    lambda: str(
        tracker_sitl.slow_error_share(
            sitl_tracker_runs(slow_error_fraction=TRACKER_SITL_SLOW_ERROR)
        )
    )
)
generator("tracker-sitl-held", checked_by=_SITL_HELD_TEST)(
    lambda: str(tracker_sitl.report(sitl_tracker_runs(sitl.HELD_RECORDINGS)))
)
generator("tracker-sitl-held-wind-worst", checked_by=_SITL_HELD_TEST)(
    lambda: str(tracker_sitl.worst_wind(sitl_tracker_runs(sitl.HELD_RECORDINGS)))
)
#: The held-out flight docs/residuals.md quotes a mass step of, and the set whose unloaded
#: flights it gives the mass of.
TRACKER_MASS_STEP, TRACKER_UNLOADED_SET = "held4_release_wind_legs", "held4_"
generator("tracker-sitl-held-mass-step", checked_by=_SITL_HELD_TEST)(
    lambda: str(tracker_sitl.mass_step(sitl_tracker_runs(sitl.HELD_RECORDINGS), TRACKER_MASS_STEP))
)
generator("tracker-sitl-held-unloaded", checked_by=_SITL_HELD_TEST)(
    lambda: str(
        tracker_sitl.unloaded_mass(sitl_tracker_runs(sitl.HELD_RECORDINGS), TRACKER_UNLOADED_SET)
    )
)


@generator("sitl-slow-error")
def sitl_slow_error() -> str:
    """The SITL vehicle file's slow model error, % of its hover power (measured on its fit
    flights; ``tests/test_sitl_effects.py`` checks it against them)."""
    return f"{100 * load_vehicle(sitl.SITL_VEHICLE).slow_error_fraction:.1f} %"


pack_figures = script_module("pack_figures")
for _name, _print in pack_figures.generators(pack_table).items():
    generator(_name)(_print)
_period_ends = script_module("period_ends", REPO / "tests")
for _name, _print in (
    script_module("endurance_figures").generators(pack_figures, _period_ends).items()
):
    generator(_name)(_print)


def _iris_pooled_hover_w() -> list[float]:
    """The hover power (W) of each IRIS+ period's pooled fit."""
    return [fit["hover_power_w"] for title, fit in real_fits().items() if "IRIS+" in title]


_fleet_blocks = script_module("fleet_figures").generators(
    IRIS, {title: pattern for title, (pattern, _) in PERIODS.items()}, _iris_pooled_hover_w
)
for _name, _print in _fleet_blocks.items():
    generator(_name, reads=SHARED_DATA)(_print)


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
