"""The CMU DJI Matrice 100 package-delivery CSV layout (Rodrigues et al., doi:10.1184/R1/12683453).

Columns used (see ``shared/data/cmu_m100_subset/SOURCE.md``): ``time`` (s), ``twist_linear_*``
(body-frame velocity, m/s), ``orientation_*`` (quaternion, body → ENU world), ``position_z``
(m above take-off), ``y`` (battery power V·I, W), ``payload`` (g), ``flight`` (id),
``wind_speed``/``wind_angle`` (airflow at the airframe's anemometer, m/s and deg from north).

Velocity: the body twist rotated by the quaternion is ENU (x east, y north, z up); it is
returned as NED. The dataset has power only (no separate voltage and current), so flights carry
``voltage_v = current_a = NaN``; :func:`iter_samples` must emit :class:`BatterySample` and uses
the pack's nominal voltage with ``current = P / V_nominal`` (power exact, V and I nominal).

The take-off / cruise / landing files of the same flights join into whole flights: read them
together and rows are grouped by ``flight`` and sorted by ``time``.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from estimator.errors import UserError
from estimator.logs import FlightSeries, FloatArray, SampleStream
from estimator.logs.series_samples import series_samples
from estimator.telemetry.samples import RebootSample, Sample

#: DJI TB47D pack of the M100: 6S LiPo, 22.2 V nominal, 4.5 Ah (README.txt of the dataset).
NOMINAL_VOLTAGE_V = 22.2
REQUIRED_COLUMNS = (
    "time",
    "orientation_x",
    "orientation_y",
    "orientation_z",
    "orientation_w",
    "twist_linear_x",
    "twist_linear_y",
    "twist_linear_z",
    "position_z",
    "y",
    "flight",
)
OPTIONAL_COLUMNS = ("payload", "wind_speed", "wind_angle")
#: Largest magnitude believed in any used column (s, m/s, m, W, g, deg, flight id): beyond it a
#: cell is damage, and products of such cells overflow.
MAX_ABS_VALUE = 1e9
#: Regime files of the dataset, recognised from the file name only to label rows.
REGIMES = {"takeoff": 0.0, "cruise": 1.0, "landing": 2.0}


def looks_like_cmu_header(line: str) -> bool:
    """True if a CSV header line has the CMU columns (content-based format detection)."""
    names = {c.strip().strip('"') for c in line.split(",")}
    return {"twist_linear_x", "orientation_w", "y", "flight"} <= names


def load_flights(paths: Sequence[Path]) -> list[FlightSeries]:
    """All flights in the given CSV files, one :class:`FlightSeries` per ``flight`` id."""
    columns = _concat([_read_csv(p) for p in paths])
    order = np.lexsort((columns["time"], columns["flight"]))
    columns = {k: v[order] for k, v in columns.items()}
    flights = []
    for flight in np.unique(columns["flight"]):
        rows = columns["flight"] == flight
        t = columns["time"][rows]
        keep = np.concatenate(([True], np.diff(t) > 0))  # duplicate stamps across files
        flights.append(
            _series(f"cmu-{int(flight)}", {k: v[rows][keep] for k, v in columns.items()})
        )
    return flights


def iter_samples(path: Path) -> SampleStream:
    """Velocity and battery samples of every flight in one CSV, flight after flight.

    A :class:`RebootSample` separates flights (each flight's clock starts again).
    """
    flights = load_flights([path])
    stream = SampleStream(path, "cmu-csv", iter(()))
    stream._it = flight_samples(flights)
    return stream


def flight_samples(flights: list[FlightSeries]) -> Iterator[Sample]:
    """The samples of ``flights`` as the daemon would receive them: velocity, then power at
    the nominal voltage, row by row (:func:`~estimator.logs.series_samples.series_samples`);
    a :class:`RebootSample` between flights (each flight's clock starts again)."""
    for i, f in enumerate(flights):
        if i > 0:
            yield RebootSample(float(f.time_s[0]))
        yield from series_samples(f, NOMINAL_VOLTAGE_V)


def rotate(quat_xyzw: FloatArray, vectors: FloatArray) -> FloatArray:
    """Each row of ``vectors`` (n × 3) rotated by the unit quaternion in the same row of
    ``quat_xyzw`` (n × 4, scalar last, normalised here): body frame → ENU for the CMU
    orientation. numpy only (scipy's Rotation costs a second of import at start-up)."""
    q = quat_xyzw / np.linalg.norm(quat_xyzw, axis=1, keepdims=True)
    axis, w = q[:, :3], q[:, 3:]
    twice = 2.0 * np.cross(axis, vectors)
    return np.asarray(vectors + w * twice + np.cross(axis, twice), dtype=float)


def _series(flight_id: str, c: dict[str, FloatArray]) -> FlightSeries:
    quat = np.column_stack(
        [c["orientation_x"], c["orientation_y"], c["orientation_z"], c["orientation_w"]]
    )
    body = np.column_stack([c["twist_linear_x"], c["twist_linear_y"], c["twist_linear_z"]])
    enu = rotate(quat, body)
    nan = np.full(len(c["time"]), np.nan)
    extras = {"regime": c["regime"]}
    if "payload" in c:
        extras["payload_kg"] = c["payload"] / 1000.0
    if "wind_speed" in c:
        extras["airflow_speed_mps"] = c["wind_speed"]
    if "wind_angle" in c:
        extras["airflow_from_deg"] = c["wind_angle"]
    return FlightSeries(
        flight_id=flight_id,
        time_s=c["time"],
        vn_mps=enu[:, 1],
        ve_mps=enu[:, 0],
        vd_mps=-enu[:, 2],
        alt_m=c["position_z"],
        voltage_v=nan,
        current_a=nan.copy(),
        power_w=c["y"],
        extras=extras,
    )


def _read_csv(path: Path) -> dict[str, FloatArray]:
    try:
        with path.open(newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise UserError(f"{path} is empty")
            missing = [c for c in REQUIRED_COLUMNS if c not in header]
            if missing:
                raise UserError(f"{path} lacks the CMU column(s) {', '.join(missing)}")
            wanted = [c for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c in header]
            index = [header.index(c) for c in wanted]
            rows = []
            for line_no, row in enumerate(reader, start=2):
                if not row:
                    continue
                try:
                    rows.append([float(row[i]) for i in index])
                except (ValueError, IndexError):
                    raise UserError(f"{path} line {line_no} is not a row of numbers") from None
                if any(abs(v) > MAX_ABS_VALUE for v in rows[-1]):
                    raise UserError(f"{path} line {line_no} has a value beyond ±{MAX_ABS_VALUE:g}")
    except csv.Error as exc:
        raise UserError(f"{path} is not a readable CSV file ({exc})") from None
    except UnicodeDecodeError:
        raise UserError(f"{path} is not a text CSV file") from None
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    if not rows:
        raise UserError(f"{path} has a header but no data rows")
    data = np.array(rows, dtype=float)
    if not np.all(np.isfinite(data[:, : len(REQUIRED_COLUMNS)])):
        raise UserError(f"{path} has empty or non-finite values in required columns")
    columns = {name: data[:, k] for k, name in enumerate(wanted)}
    regime = next((v for k, v in REGIMES.items() if k in path.name.lower()), np.nan)
    columns["regime"] = np.full(len(data), regime)
    return columns


def _concat(parts: list[dict[str, FloatArray]]) -> dict[str, FloatArray]:
    keys = set.intersection(*(set(p) for p in parts))
    return {k: np.concatenate([p[k] for p in parts]) for k in keys}
