"""The wind the daemon's pipeline uses against the truth on the ArduCopter SITL recordings.

Replays each quad recording of ``replay/sitl/`` (vehicle
``config/vehicles/ardupilot_sitl_quad.toml``) through the pipeline twice, with and without the
autopilot's WIND reports, and prints per flight the median and 90th percentile of
|wind in use − truth| (vector difference, m/s) over the estimates from 30 s after take-off to
the landing. Run: ``python scripts/tracked_wind_sitl.py``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from estimator.analysis.replay import replay_stream
from estimator.estimation.estimate import Estimate
from estimator.logs import iter_samples
from estimator.physics.effects import Wind
from estimator.physics.vehicle import Vehicle, load_vehicle
from estimator.telemetry.samples import Sample, WindSample

REPO = Path(__file__).resolve().parent.parent
RECORDINGS = REPO / "replay" / "sitl"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: Estimates this long after take-off (s) are scored: the first legs have settled the wind.
SETTLE_S = 30.0


def air_velocity_ne(speed_mps: float, from_deg: float) -> np.ndarray:
    """The air mass's velocity over ground (north, east), m/s, of a wind from ``from_deg``."""
    return np.array(Wind(speed_mps, from_deg).vector_ne_mps())


def truth_wind_ne(winds: list[dict], time_s: float) -> np.ndarray:
    for w in winds:
        if w["start_s"] <= time_s < w["end_s"]:
            return air_velocity_ne(w["speed_mps"], w["from_deg"])
    return np.zeros(2)


def wind_errors_mps(estimates: Iterable[Estimate], truth: dict) -> np.ndarray:
    winds = [e for e in truth["effects"] if e["effect"] == "wind"]
    ev = truth["events"]
    errors = []
    for e in estimates:
        if not ev["takeoff_s"] + SETTLE_S < e.time_s < ev["landed_s"] or e.rth_wind_mps is None:
            continue
        used = air_velocity_ne(e.rth_wind_mps, e.rth_wind_from_deg or 0.0)
        errors.append(float(np.hypot(*(used - truth_wind_ne(winds, e.time_s)))))
    return np.array(errors)


def replayed(path: Path, vehicle: Vehicle, with_wind_reports: bool) -> list[Estimate]:
    stream = iter_samples(path, "auto", vehicle.input_limits())
    samples: Iterable[Sample] = (
        stream if with_wind_reports else (s for s in stream if not isinstance(s, WindSample))
    )
    return replay_stream(stream, vehicle, path.parent.name, samples=samples).estimates


def table_lines(with_wind: Mapping[str, list[Estimate]] | None = None) -> list[str]:
    """The table of docs/residuals.md, one line a row (header first). ``with_wind``: the
    estimates of recordings already replayed with their WIND reports, by scenario (the others
    are replayed here)."""
    vehicle = load_vehicle(VEHICLE)
    lines = [
        "| flight | without WIND: median / p90 m/s | with WIND: median / p90 m/s |",
        "|---|---:|---:|",
    ]
    for truth_path in sorted(RECORDINGS.glob("*/truth.json")):
        truth = json.loads(truth_path.read_text())
        if truth["frame"] != "quad" or truth.get("model_json"):
            continue  # another airframe than the vehicle file's
        tlog = truth_path.with_name("flight.tlog")
        given = (with_wind or {}).get(truth_path.parent.name)
        cells = []
        for estimates in (
            replayed(tlog, vehicle, False),
            given if given is not None else replayed(tlog, vehicle, True),
        ):
            errors = wind_errors_mps(estimates, truth)
            cells.append(f"{np.median(errors):.2f} / {np.percentile(errors, 90):.2f}")
        lines.append(f"| {truth['scenario']} | {cells[0]} | {cells[1]} |")
    return lines


def main() -> None:
    print("\n".join(table_lines()))


if __name__ == "__main__":
    main()
