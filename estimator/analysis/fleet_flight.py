"""One log → one fleet row (:mod:`estimator.analysis.fleet` runs this on dask workers).

Every mode replays the log through the daemon's pipeline (:func:`replay_stream`): identity
(start time, autopilot, pack), duration, airborne time, energy, the model's power error, the
pipeline's internal resistance and online mass, a usable-capacity estimate from the resting
voltage before and after the flight, the capacity the pack filter learnt (with its σ), and
the log's sanity warnings against the vehicle file (:mod:`estimator.logs.sanity`, as replay
says them: a pack of other cells makes the resistance and energy figures wrong).
``fit`` adds a per-flight fit of the theory model (:func:`fit_theory`: hover power, V_me);
``residuals`` adds the residual analysis (:func:`analyze`: effects the model lacks). Column
meanings and units: ``docs/fleet.md``.

A log that cannot be read or analysed gives a row with ``status`` "failed" and the reason in
``error``, never an exception: one bad file must not stop a fleet run.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from estimator.analysis.fit_points import preprocess
from estimator.analysis.replay import MAX_GAP_S, replay_stream, summarize, with_batteries
from estimator.analysis.residual_samples import ResidualOptions
from estimator.analysis.residuals import analyze
from estimator.analysis.theory_fit import fit_theory
from estimator.errors import UserError
from estimator.estimation.pipeline import Pipeline
from estimator.logs import battery_window_problem, iter_samples, load_flights
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import BatterySample

MODES = ("replay", "fit", "residuals")
#: Below this pack current (A) the pack counts as resting: its voltage, plus I·R, is its OCV.
REST_CURRENT_A = 2.0
#: Resting readings averaged at each end of the flight.
REST_READINGS = 5
#: A capacity estimate needs at least this drop of resting state of charge (else None).
MIN_SOC_DROP = 0.15
_HASH_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class FleetJob:
    """What to do with each log: ``mode`` (one of :data:`MODES`) against ``vehicle``."""

    mode: str
    vehicle: Vehicle
    fmt: str = "auto"


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of the file's content (the resume key)."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as handle:
        while chunk := handle.read(_HASH_CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


def flight_row(path: str, sha256: str, job: FleetJob) -> dict[str, Any]:
    """The row of one log (see the module docstring); never raises for a bad log."""
    start, start_cpu = time.perf_counter(), time.process_time()
    row: dict[str, Any] = {
        "path": path,
        "sha256": sha256,
        "mode": job.mode,
        "vehicle": job.vehicle.name,
        "status": "ok",
        "error": None,
    }
    try:
        row.update(replay_columns(Path(path), job))
        if job.mode == "fit":
            row.update(fit_columns(Path(path), job))
        elif job.mode == "residuals":
            row.update(residual_columns(Path(path), job))
    except UserError as exc:
        row.update(status="failed", error=str(exc))
    except Exception as exc:  # a bug or a log no reader expected: recorded, the run goes on
        row.update(status="failed", error=failure_reason(exc))
    row["wall_s"] = time.perf_counter() - start
    row["cpu_s"] = time.process_time() - start_cpu
    return row


#: Start of the reason of a failure no known cause explains (counted apart by the fleet run).
UNEXPECTED = "unexpected error"
#: Exceptions a damaged log can still provoke past the readers, in plain words.
_KNOWN_FAILURES: tuple[tuple[type[BaseException] | tuple[type[BaseException], ...], str], ...] = (
    (MemoryError, "the log is too large for the worker's memory"),
    (RecursionError, "the log nests too deeply to be read"),
    (np.linalg.LinAlgError, "the log's data leave the fit without a solution (too few points?)"),
    (
        (OverflowError, FloatingPointError, ZeroDivisionError, ValueError),
        "a value in the log is beyond what the analysis can compute with",
    ),
    (EOFError, "the log ends in the middle of a record"),
    (TimeoutError, "the log took too long to be read"),
    (OSError, "the log could not be read"),
)


def failure_reason(exc: BaseException) -> str:
    """One line in plain words for an exception a log provoked; one of no known cause starts
    with :data:`UNEXPECTED` and names its class and first line."""
    for kinds, reason in _KNOWN_FAILURES:
        if isinstance(exc, kinds):
            return reason
    text = str(exc).strip().splitlines()
    detail = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
    return f"{UNEXPECTED} ({detail})"


def replay_columns(path: Path, job: FleetJob) -> dict[str, Any]:
    """Identity, energy and pack figures from a replay through the daemon's pipeline."""
    vehicle = job.vehicle
    stream = iter_samples(path, job.fmt, vehicle.input_limits())
    batteries: list[BatterySample] = []
    pipeline = Pipeline(vehicle)
    flight = replay_stream(
        stream, vehicle, path.stem, samples=with_batteries(stream, batteries), pipeline=pipeline
    )
    if not flight.estimates:
        problem = battery_window_problem(stream, vehicle.battery.cells, vehicle.input_limits())
        raise UserError(problem or "no estimates: the log has no battery telemetry")
    summary = summarize([flight])
    resistance_ohm = _last_finite(e.resistance_ohm for e in flight.estimates)
    mass_delta_kg = None if pipeline.online is None else pipeline.online.mass_delta_kg
    mass_ratio = 1.0 + (mass_delta_kg or 0.0) / vehicle.mass_kg
    charge_ah = charge_used_ah(batteries)
    soc_start, soc_end = resting_soc(batteries, pipeline.pack, resistance_ohm or 0.0)
    capacity_ah = None
    if soc_start is not None and soc_end is not None and soc_start - soc_end >= MIN_SOC_DROP:
        capacity_ah = charge_ah / (soc_start - soc_end)
    learnt = learnt_capacity(pipeline)
    autopilot = stream.autopilot
    return {
        "format": flight.format,
        "start_utc": None
        if stream.start_unix_s is None
        else datetime.fromtimestamp(stream.start_unix_s, UTC),
        "autopilot_sysid": None if autopilot is None else autopilot[0],
        "pack_id": stream.pack_id,
        "samples": flight.samples,
        "skipped": flight.skipped,
        "bad_frames": flight.bad_frames,
        "truncated": flight.truncated,
        "duration_s": summary.duration_s,
        "airborne_s": summary.airborne_s,
        "energy_used_wh": summary.energy_measured_wh,
        "energy_model_wh": summary.energy_predicted_wh,
        "power_rmse_w": summary.power_rmse_w,
        "power_mape_pct": summary.power_mape_pct,
        "resistance_ohm": resistance_ohm,
        "mass_delta_kg": mass_delta_kg,
        "hover_power_tracked_w": vehicle.model.rescaled(mass_ratio=mass_ratio).hover_power_w,
        "charge_used_ah": charge_ah,
        "soc_rest_start": soc_start,
        "soc_rest_end": soc_end,
        "capacity_ah": capacity_ah,
        "pack_capacity_ah": None if learnt is None else learnt[0],
        "pack_capacity_sigma_ah": None if learnt is None else learnt[1],
        "warnings": stream.problems(vehicle.battery.cells),
    }


def learnt_capacity(pipeline: Pipeline) -> tuple[float, float] | None:
    """The pack filter's capacity and its 1σ (Ah) at the end of the flight; None when the
    filter did not run (no current) or did not learn it (σ 0: the label trusted, as against
    a chemistry's typical curve)."""
    if pipeline.pack_state is None:
        return None
    pack = pipeline.pack_state.estimate()
    if not (pack.capacity_sigma_ah > 0 and math.isfinite(pack.capacity_ah)):
        return None
    return pack.capacity_ah, pack.capacity_sigma_ah


def fit_columns(path: Path, job: FleetJob) -> dict[str, Any]:
    """The theory model fitted to this flight alone (the paper's preprocessing and priors)."""
    points = preprocess(load_flights([path], job.fmt)).kept()
    theory = fit_theory(points)
    model = theory.model
    return {
        "fit_points": theory.n_points,
        "hover_power_fit_w": model.hover_power_w,
        "hover_power_fit_stderr_w": theory.hover_stderr["hover_power_w"],
        "v_me_fit_mps": model.max_endurance_speed_mps(),
        "fit_sigma_w": theory.sigma_w,
    }


def residual_columns(path: Path, job: FleetJob) -> dict[str, Any]:
    """The residual analysis of this flight against the vehicle file."""
    result = analyze(load_flights([path], job.fmt), job.vehicle, ResidualOptions())
    mass = [e for e in result.effects if e.name == "mass"]
    return {
        "residual_rmse_before_w": result.rmse_w(False),
        "residual_rmse_after_w": result.rmse_w(True),
        "residual_noise_floor_w": result.noise_floor_w,
        "residual_effects": "; ".join(d["description"] for d in result.summary()["effects"]),
        "residual_mass_delta_kg": float(mass[0].params["delta_kg"]) if mass else None,
    }


def charge_used_ah(batteries: list[BatterySample]) -> float:
    """Charge drawn over the log (Ah): the autopilot's consumed count where it has one, else
    the current integrated over gaps up to :data:`MAX_GAP_S`."""
    consumed = [b.consumed_mah for b in batteries if b.consumed_mah is not None]
    if len(consumed) >= 2:
        return max(consumed[-1] - consumed[0], 0.0) / 1000.0
    rows = [(b.time_s, b.current_a) for b in batteries if b.current_a is not None]
    total_as = 0.0
    for (t0, i0), (t1, i1) in pairwise(rows):
        if 0.0 < t1 - t0 <= MAX_GAP_S:
            total_as += 0.5 * (i0 + i1) * (t1 - t0)
    return total_as / 3600.0


def resting_soc(
    batteries: list[BatterySample], pack: PackModel, resistance_ohm: float
) -> tuple[float | None, float | None]:
    """State of charge from the resting voltage (V + I·R → OCV → SoC) before the first and
    after the last reading at or above :data:`REST_CURRENT_A`; None where there is none."""
    rows = [(b.voltage_v, b.current_a) for b in batteries if b.current_a is not None]
    loaded = [k for k, (_, i) in enumerate(rows) if i >= REST_CURRENT_A]
    if not loaded:
        return None, None
    before = rows[: loaded[0]][-REST_READINGS:]
    after = rows[loaded[-1] + 1 :][-REST_READINGS:]

    def soc(readings: list[tuple[float, float]]) -> float | None:
        if not readings:
            return None
        ocv_v = float(np.median([v + i * resistance_ohm for v, i in readings]))
        return float(pack.soc_from_ocv(ocv_v))

    return soc(before), soc(after)


def _last_finite(values: Iterable[float]) -> float | None:
    last = None
    for value in values:
        if math.isfinite(value):
            last = value
    return last
