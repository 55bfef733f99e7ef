"""The fleet results file: one Parquet row per (log, mode), its schema, atomic writes, and the
keys a resumed run skips.

Columns a mode does not produce are null (``fit_*`` outside ``fleet fit``, ``residual_*``
outside ``fleet residuals``), so rows of every mode share one file and one schema. The
meaning of each column is in :data:`COLUMNS` and ``docs/fleet.md``. A file written before a
column was added reads with that column null (:data:`KEY_COLUMNS` must be there).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from estimator.errors import UserError

#: (name, type, meaning) of every column, in file order.
COLUMNS: tuple[tuple[str, pa.DataType, str], ...] = (
    ("path", pa.string(), "absolute path of the log"),
    ("sha256", pa.string(), "SHA-256 of the log's content (the resume key)"),
    ("mode", pa.string(), "replay, fit or residuals"),
    ("vehicle", pa.string(), "name in the vehicle file used"),
    ("status", pa.string(), "ok or failed"),
    ("error", pa.string(), "why the log failed (one line); null when ok"),
    ("format", pa.string(), "tlog, dataflash, ulog or cmu-csv"),
    ("start_utc", pa.timestamp("us", tz="UTC"), "first record's receive time (tlogs)"),
    ("autopilot_sysid", pa.int32(), "MAVLink system id of the autopilot decoded (tlogs)"),
    ("pack_id", pa.string(), "pack serial number (else name) from SMART_BATTERY_INFO"),
    ("samples", pa.int64(), "telemetry samples fed to the pipeline"),
    ("skipped", pa.int64(), "records skipped on purpose (unused types, implausible values)"),
    ("bad_frames", pa.int64(), "corrupt records"),
    ("truncated", pa.bool_(), "the file ends inside a record"),
    ("duration_s", pa.float64(), "log time spanned by the estimates, s"),
    ("airborne_s", pa.float64(), "airborne time (armed, above 1 m, above idle power), s"),
    ("energy_used_wh", pa.float64(), "measured V·I energy over the airborne time, Wh"),
    ("energy_model_wh", pa.float64(), "model power over the same intervals, Wh"),
    ("power_rmse_w", pa.float64(), "pipeline model power vs measured, airborne RMSE, W"),
    ("power_mape_pct", pa.float64(), "same, mean absolute percentage error, %"),
    ("resistance_ohm", pa.float64(), "pack internal resistance, pipeline's final estimate, Ω"),
    ("mass_delta_kg", pa.float64(), "online-tracked mass minus the vehicle file's, kg"),
    ("hover_power_tracked_w", pa.float64(), "vehicle model's hover power at the tracked mass, W"),
    ("charge_used_ah", pa.float64(), "charge drawn over the whole log, Ah"),
    ("soc_rest_start", pa.float64(), "state of charge from the resting voltage before flight"),
    ("soc_rest_end", pa.float64(), "state of charge from the resting voltage after landing"),
    ("capacity_ah", pa.float64(), "charge used ÷ resting-SoC drop (drop ≥ 0.15), Ah"),
    ("pack_capacity_ah", pa.float64(), "pack filter's learnt capacity at the end, Ah"),
    ("pack_capacity_sigma_ah", pa.float64(), "its 1σ, Ah"),
    (
        "warnings",
        pa.map_(pa.string(), pa.string()),
        "sanity checks against the vehicle file: cause → sentence (logs/sanity.py)",
    ),
    ("fit_points", pa.int64(), "fit: points kept by the paper's preprocessing"),
    ("hover_power_fit_w", pa.float64(), "fit: hover power of this flight's fit, W"),
    ("hover_power_fit_stderr_w", pa.float64(), "fit: its 1σ, W"),
    ("v_me_fit_mps", pa.float64(), "fit: maximum-endurance speed, m/s"),
    ("fit_sigma_w", pa.float64(), "fit: residual σ of the fit, W"),
    ("residual_rmse_before_w", pa.float64(), "residuals: held-out RMSE, vehicle file, W"),
    ("residual_rmse_after_w", pa.float64(), "residuals: with the effects found, W"),
    ("residual_noise_floor_w", pa.float64(), "residuals: noise floor, W"),
    ("residual_effects", pa.string(), "residuals: effects found, '; '-separated"),
    ("residual_mass_delta_kg", pa.float64(), "residuals: mass effect found, kg"),
    ("wall_s", pa.float64(), "worker wall-clock time for this log, s"),
    ("cpu_s", pa.float64(), "worker CPU time for this log (less than wall_s: waiting), s"),
)
SCHEMA = pa.schema([(name, kind) for name, kind, _ in COLUMNS])
#: Columns every results file has had: without them a file is not one.
KEY_COLUMNS = ("path", "sha256", "mode", "status")


def to_table(rows: Iterable[Mapping[str, Any]]) -> pa.Table:
    """Rows (dicts; missing columns are null) as a table of :data:`SCHEMA`."""
    rows = list(rows)
    return pa.Table.from_pylist([{k: row.get(k) for k in SCHEMA.names} for row in rows], SCHEMA)


def read_table(path: Path) -> pa.Table | None:
    """The results file, None if it does not exist; a user error if it is not one of ours."""
    if not path.exists():
        return None
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise UserError(f"{path} is not a readable Parquet file ({exc})") from None
    missing = [name for name in KEY_COLUMNS if name not in table.column_names]
    if missing:
        raise UserError(f"{path} is not a fleet results file (no column {missing[0]!r})")
    for field in SCHEMA:
        if field.name not in table.column_names:  # added since the file was written
            table = table.append_column(field, pa.nulls(table.num_rows, field.type))
    try:
        return table.select(SCHEMA.names).cast(SCHEMA)
    except (pa.ArrowException, ValueError) as exc:
        raise UserError(f"{path} is not a fleet results file ({exc})") from None


def write_table(path: Path, table: pa.Table) -> None:
    """Write atomically (a temporary file beside it, then a rename): a reader or a crash never
    sees half a file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table.sort_by([("path", "ascending"), ("mode", "ascending")]), tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None


def done_keys(table: pa.Table | None, mode: str, retry_failed: bool = False) -> set[str]:
    """Content hashes already in ``table`` for ``mode`` (failed ones too, unless
    ``retry_failed``)."""
    if table is None:
        return set()
    keys = set()
    for row in table.select(["sha256", "mode", "status"]).to_pylist():
        if row["mode"] == mode and row["sha256"] and not (retry_failed and row["status"] != "ok"):
            keys.add(row["sha256"])
    return keys


def without(table: pa.Table, mode: str, hashes: set[str]) -> pa.Table:
    """``table`` without the rows of ``mode`` whose hash is in ``hashes`` (to be redone)."""
    keep = [
        not (row["mode"] == mode and row["sha256"] in hashes)
        for row in table.select(["sha256", "mode"]).to_pylist()
    ]
    return table.filter(pa.array(keep, pa.bool_()))
