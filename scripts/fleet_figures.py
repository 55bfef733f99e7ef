"""The figures of docs/fleet.md's IRIS+ section: ``uav-energy fleet fit "$I/**/*.log"
--vehicle config/vehicles/iris_plus_2016_06_08.toml`` (``I=../shared/data/iris_quadcopter_logs``)
and ``uav-energy fleet trends`` of its rows, over all its dates and ``--since 2016-05-01``.

The rows are what the fleet's workers compute (:func:`estimator.analysis.fleet_flight.flight_row`,
17 s of CPU for the 73 logs), here in one process: a fleet run adds only their scheduling.
``scripts/figures.py`` registers the blocks; ``tests/test_figures.py`` checks them where
``../shared`` holds the logs.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Callable, Mapping, Sequence
from datetime import date
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from estimator.analysis.fleet import expand_inputs
from estimator.analysis.fleet_flight import FleetJob, file_sha256, flight_row
from estimator.analysis.fleet_table import to_table
from estimator.analysis.fleet_trends import Series, fleet_trends
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
VEHICLE = REPO / "config" / "vehicles" / "iris_plus_2016_06_08.toml"
#: ``fleet trends --since``: the summer's flights.
SUMMER_SINCE = date(2016, 5, 1)
#: Flights that drew less charge than this (Ah) are the short ones of the capacity bullet.
SHORT_FLIGHT_AH = 0.8
#: Row label of the quartile table → (column, unit, scale from the column's unit, format).
QUARTILES = {
    "hover power, per-flight fit": ("hover_power_fit_w", "W", 1.0, ".1f"),
    "internal resistance": ("resistance_ohm", "mΩ", 1e3, ".1f"),
    "usable capacity (flights with a drop ≥ 0.15)": ("capacity_ah", "Ah", 1.0, ".2f"),
}
Row = dict[str, Any]


@cache
def rows(iris: Path) -> tuple[Row, ...]:
    """``uav-energy fleet fit`` of every IRIS+ log under ``iris``: one row per log."""
    job = FleetJob("fit", load_vehicle(VEHICLE))
    logs = expand_inputs([f"{iris}/**/*.log"])
    return tuple(flight_row(str(log), file_sha256(log), job) for log in logs)


def _ok(iris: Path) -> list[Row]:
    return [r for r in rows(iris) if r["status"] == "ok"]


def _period(iris: Path, pattern: str) -> list[Row]:
    """The ok rows of the logs whose folder under ``iris`` matches ``pattern``."""
    return [
        r for r in _ok(iris) if fnmatch.fnmatch(Path(r["path"]).relative_to(iris).parts[0], pattern)
    ]


def _column(pooled: Sequence[Row], column: str) -> np.ndarray:
    return np.array([r[column] for r in pooled if r[column] is not None], dtype=float)


def _hover_series(iris: Path, metric: str, since: date | None = None) -> Series:
    """The one vehicle's trend of ``metric`` (``fleet trends``)."""
    trends = fleet_trends(to_table(rows(iris)), since=since)
    [series] = [s for s in trends.series if s.kind == "vehicle" and s.metric == metric]
    return series


def counts(iris: Path) -> str:
    """How many logs are ok, how many failed, and why, with their dates."""
    failed: dict[str, list[str]] = {}
    for row in rows(iris):
        if row["status"] != "ok":
            failed.setdefault(row["error"], []).append(Path(row["path"]).relative_to(iris).parts[0])
    reasons = "; ".join(
        f'{len(days)} logs of {", ".join(sorted(set(days)))}: "{error}"'
        for error, days in sorted(failed.items())
    )
    return (
        f"{len(_ok(iris))} logs ok, {sum(map(len, failed.values()))} failed with their reason"
        + (f" ({reasons})" if reasons else "")
    )


def quartiles(iris: Path, periods: Mapping[str, str]) -> str:
    """Per period: the quartiles of hover power, resistance and usable capacity."""
    pooled = {title: _period(iris, pattern) for title, pattern in periods.items()}
    lines = [
        "| | " + " | ".join(f"{t} ({len(p)} flights)" for t, p in pooled.items()) + " |",
        "|---|" + "---|" * len(pooled),
    ]
    for label, (column, unit, scale, fmt) in QUARTILES.items():
        cells = []
        for flights in pooled.values():
            values = scale * _column(flights, column)
            q = " / ".join(f"{v:{fmt}}" for v in np.percentile(values, [25, 50, 75]))
            count = f" ({len(values)})" if len(values) < len(flights) else ""
            cells.append(f"{q} {unit}{count}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _medians(iris: Path, periods: Mapping[str, str], column: str) -> list[float]:
    return [float(np.median(_column(_period(iris, p), column))) for p in periods.values()]


def _slope(series: Series, unit: str, scale: float) -> str:
    """The Theil–Sen slope per 30 days and its 95 % interval, and whether that holds zero."""
    slope = series.slope_per_30d()
    assert slope is not None
    low, high = (f"{scale * v:+.1f}".replace("-", "−") for v in slope[1:])
    holds = "includes" if slope[1] <= 0 <= slope[2] else "excludes"
    return (
        f"{scale * slope[0]:+.1f} {unit} per 30 days with a 95 % interval [{low}, {high}] "
        f"that {holds} zero"
    )


def mass(iris: Path, periods: Mapping[str, str]) -> str:
    """Hover power from period to period and through the summer, and the mass ratio
    momentum theory gives (P_hover ∝ m^1.5)."""
    first, last = _medians(iris, periods, "hover_power_fit_w")
    summer = _hover_series(iris, "hover_power_w", SUMMER_SINCE)
    daily = [v for _, v, _ in summer.per_day()]
    whole = _hover_series(iris, "hover_power_w").per_day()
    return (
        f"hover power steps from {first:.0f} W to {last:.0f} W between March and June "
        f"(per-day medians {min(daily):.0f}–{max(daily):.0f} W from June to August, slope "
        f"{_slope(summer, 'W', 1.0)}): ×{(last / first) ** (2 / 3):.2f} in mass by momentum "
        f"theory from the period medians (×{(whole[-1][1] / whole[0][1]) ** (2 / 3):.2f} from "
        f"the first and last days' medians, as `summary.md` prints it)"
    )


def pooled_fits(iris: Path, periods: Mapping[str, str], pooled_w: Sequence[float]) -> str:
    """The periods' median per-flight hover power against ``pooled_w``, the hover power of
    each period's pooled fit (docs/fit.md)."""
    medians = _medians(iris, periods, "hover_power_fit_w")
    worst = max(abs(m - p) for m, p in zip(medians, pooled_w, strict=True))
    pooled = " and ".join(f"{p:.1f}" for p in pooled_w)
    return (
        f"The per-flight medians agree with the pooled fits of [fit.md](fit.md) ({pooled} W) "
        f"within {math.ceil(10 * worst) / 10:.1f} W"
    )


def resistance(iris: Path, periods: Mapping[str, str]) -> str:
    """The resistance from period to period and through the summer."""
    first, last = (1e3 * r for r in _medians(iris, periods, "resistance_ohm"))
    summer = _hover_series(iris, "resistance_ohm", SUMMER_SINCE)
    (d0, v0, _), (d1, v1, _) = summer.per_day()[0], summer.per_day()[-1]
    change = "lower" if last < first else "higher"
    return (
        f"**Resistance** is {abs(first - last):.0f} mΩ ({100 * abs(1 - last / first):.0f} %) "
        f"{change} in summer than in March; the logs do not say whether that is the air "
        f"temperature (LiPo resistance falls as the pack warms) or another pack. Within "
        f"June–August: per-day medians {1e3 * v0:.1f} mΩ ({d0.day} {d0:%B}) → "
        f"{1e3 * v1:.1f} mΩ ({d1.day} {d1:%B}), Theil–Sen slope {_slope(summer, 'mΩ', 1e3)}"
    )


def capacity(iris: Path) -> str:
    """The spread of the per-flight usable capacity, on short flights and the deepest two."""
    flights = sorted(
        (r["charge_used_ah"], r["capacity_ah"]) for r in _ok(iris) if r["capacity_ah"] is not None
    )
    read = [c for _, c in flights]
    short = [c for drawn, c in flights if drawn < SHORT_FLIGHT_AH]
    deepest = flights[-2:]
    return (
        f"The per-flight figures scatter from {min(read):.1f} to {max(read):.1f} Ah around the "
        f"nominal {load_vehicle(VEHICLE).battery.capacity_ah:.1f} Ah; flights that drew less "
        f"than {SHORT_FLIGHT_AH} Ah read {np.median(short):.1f} Ah at the median "
        f"({min(short):.1f}–{max(short):.1f} Ah), the deepest read "
        f"{' and '.join(f'{c:.2f}' for _, c in deepest)} Ah for "
        f"{' and '.join(f'{d:.1f}' for d, _ in deepest)} Ah drawn"
    )


def generators(
    iris: Path, periods: Mapping[str, str], pooled_w: Callable[[], Sequence[float]]
) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it (``scripts/figures.py`` registers them);
    ``periods``: title → the glob of its folders under ``iris``; ``pooled_w``: the hover
    power of each period's pooled fit."""
    iris = iris.resolve()  # the rows name each log by its real path
    return {
        "fleet-iris-counts": lambda: counts(iris),
        "fleet-iris-quartiles": lambda: quartiles(iris, periods),
        "fleet-iris-mass": lambda: mass(iris, periods),
        "fleet-iris-pooled-fits": lambda: pooled_fits(iris, periods, pooled_w()),
        "fleet-iris-resistance": lambda: resistance(iris, periods),
        "fleet-iris-capacity": lambda: capacity(iris),
    }
