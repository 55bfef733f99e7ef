"""A pack voltage the vehicle file's cell count cannot be (the decoder skipped it as
implausible): which cell counts it fits (:func:`pack_mismatch_text`), and, before any
estimate, the one count it is a pack above its reserve for, when there is one
(:func:`inferred_cells`; :meth:`estimator.physics.vehicle.Vehicle.flyable_cells`)."""

from __future__ import annotations

from dataclasses import replace

from estimator.physics.vehicle import Vehicle
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.plausibility import fitting_cells


def inferred_cells(decoder: TelemetryDecoder, vehicle: Vehicle) -> tuple[Vehicle, str, str] | None:
    """When the decoder's last skipped voltage is a pack above its reserve for exactly one
    cell count: ``vehicle`` with that count, the log line and a STATUSTEXT saying so; else
    None."""
    if decoder.implausible_voltage is None:
        return None
    kind, voltage_v = decoder.implausible_voltage
    counts = vehicle.flyable_cells(voltage_v)
    if len(counts) != 1:
        return None
    cells, file_cells = counts[0], vehicle.battery.cells
    line = (
        f"{kind} {voltage_v:.2f} V is a {cells}S pack above its reserve, not the vehicle "
        f"file's {file_cells}S: estimating with {cells} cells (set [battery] cells = {cells})"
    )
    text = f"pack {voltage_v:.1f}V is {cells}S, not {file_cells}S: using {cells}S"
    return replace(vehicle, battery=replace(vehicle.battery, cells=cells)), line, text


def pack_mismatch_text(decoder: TelemetryDecoder, cells: int) -> tuple[str, str] | None:
    """When the decoder skipped a pack voltage as implausible for the vehicle file's ``cells``:
    the log line saying which cell counts it fits, and a STATUSTEXT for the ground station;
    else None."""
    rejected = decoder.implausible_voltage
    if rejected is None:
        return None
    kind, voltage_v = rejected
    limits = decoder.limits
    line = (
        f"{kind} {voltage_v:.2f} V fits {fitting_cells(voltage_v)}, the vehicle file says "
        f"{cells} (believed {limits.min_voltage_v:.2f}-{limits.max_voltage_v:.2f} V): every "
        f"battery reading is skipped ({decoder.counts['voltage_implausible']} so far) and no "
        "estimate is made; is [battery] cells right?"
    )
    return line, f"pack {voltage_v:.1f}V is not {cells}S: no estimate"
