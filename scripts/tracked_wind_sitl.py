"""The wind the daemon's pipeline uses against the truth on the ArduCopter SITL recordings.

Replays each quad recording of ``replay/sitl/`` (vehicle
``config/vehicles/ardupilot_sitl_quad.toml``) through the pipeline twice, with and without the
autopilot's WIND reports, and prints per flight the median and 90th percentile of
|wind in use − truth| (vector difference, m/s) over the estimates from 30 s after take-off to
the landing. Run: ``python scripts/tracked_wind_sitl.py``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from estimator.analysis.replay import replay_stream
from estimator.analysis.sitl_truth import RecordingTruth, air_velocity_ne, load_truth
from estimator.estimation.estimate import Estimate
from estimator.logs import iter_samples
from estimator.physics.vehicle import Vehicle, load_vehicle
from estimator.telemetry.samples import Sample, WindSample

REPO = Path(__file__).resolve().parent.parent
RECORDINGS = REPO / "replay" / "sitl"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: Estimates this long after take-off (s) are scored: the first legs have settled the wind.
SETTLE_S = 30.0


def wind_errors_mps(estimates: Iterable[Estimate], truth: RecordingTruth) -> np.ndarray:
    errors = []
    for e in estimates:
        if not truth.takeoff_s + SETTLE_S < e.time_s < truth.landed_s or e.rth_wind_mps is None:
            continue
        used = air_velocity_ne(e.rth_wind_mps, e.rth_wind_from_deg or 0.0)
        errors.append(float(np.hypot(*(used - truth.wind_ne_mps(e.time_s)))))
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
        truth = load_truth(truth_path, vehicle.mass_kg)
        if not truth.stock_quad:
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
        lines.append(f"| {truth.scenario} | {cells[0]} | {cells[1]} |")
    return lines


def main() -> None:
    print("\n".join(table_lines()))


if __name__ == "__main__":
    main()
