"""Trends across dates in a fleet results file (:mod:`estimator.analysis.fleet_table`).

Per vehicle (vehicle file name and autopilot system id) and per pack (where the logs name
it), over the flights with status ok and a start time: hover power (the per-flight fit's
where there is one, else the vehicle model's at the online-tracked mass), internal
resistance and usable capacity. Each series gets per-day medians and a robust slope
(Theil–Sen, with its 95 % interval) per 30 days. A hover-power change reads as a mass change
through momentum theory (P_hover ∝ m^1.5 at constant air density): m₂/m₁ = (P₂/P₁)^(2/3).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import date
from typing import Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray
from scipy.stats import theilslopes

#: (metric, unit, label) of the trended quantities.
METRICS = (
    ("hover_power_w", "W", "hover power"),
    ("resistance_ohm", "Ω", "internal resistance"),
    ("capacity_ah", "Ah", "usable capacity"),
)
_DAYS_PER_SLOPE = 30.0
#: Fewer distinct days than this: no slope.
MIN_DAYS = 2


@dataclass(frozen=True)
class Series:
    """One metric of one vehicle or pack: per-flight values and per-day medians."""

    kind: str  # "vehicle" or "pack"
    group: str
    metric: str
    unit: str
    label: str
    days: NDArray[np.float64]  # days since 1970-01-01 (UTC), per flight
    values: NDArray[np.float64]

    def per_day(self) -> list[tuple[date, float, int]]:
        """(day, median, flights) per day, in date order."""
        out = []
        for day in np.unique(np.floor(self.days)):
            on = np.floor(self.days) == day
            out.append((_date(day), float(np.median(self.values[on])), int(on.sum())))
        return out

    def slope_per_30d(self) -> tuple[float, float, float] | None:
        """Theil–Sen slope per 30 days over the per-day medians, with its 95 % interval."""
        daily = self.per_day()
        if len(daily) < MIN_DAYS:
            return None
        x = np.array([d.toordinal() for d, _, _ in daily], dtype=float)
        y = np.array([v for _, v, _ in daily])
        slope, _, low, high = theilslopes(y, x)
        return (
            float(slope * _DAYS_PER_SLOPE),
            float(low * _DAYS_PER_SLOPE),
            float(high * _DAYS_PER_SLOPE),
        )

    def as_dict(self) -> dict[str, Any]:
        slope = self.slope_per_30d()
        return {
            "kind": self.kind,
            "group": self.group,
            "metric": self.metric,
            "unit": self.unit,
            "flights": len(self.values),
            "per_day": [
                {"date": d.isoformat(), "median": v, "flights": n} for d, v, n in self.per_day()
            ],
            "slope_per_30d": None if slope is None else slope[0],
            "slope_95pct_per_30d": None if slope is None else list(slope[1:]),
        }

    def line(self) -> str:
        daily = self.per_day()
        (d0, v0, _), (d1, v1, _) = daily[0], daily[-1]
        text = (
            f"{self.kind} {self.group}: {self.label} {v0:.4g} {self.unit} ({d0}) → "
            f"{v1:.4g} {self.unit} ({d1}), {len(self.values)} flights on {len(daily)} days"
        )
        slope = self.slope_per_30d()
        if slope is not None:
            text += f"; slope {slope[0]:+.3g} {self.unit}/30 d [{slope[1]:+.3g}, {slope[2]:+.3g}]"
        if self.metric == "hover_power_w" and v0 > 0:
            text += f"; mass ×{(v1 / v0) ** (2 / 3):.3f} (momentum theory)"
        return text


@dataclass(frozen=True)
class FleetTrends:
    """Every series, and the counts of rows: all, ok, and logs with an ok row and a start
    time."""

    series: list[Series]
    rows: int
    ok: int
    dated: int

    def lines(self) -> list[str]:
        head = f"trends over {self.dated} dated ok flights ({self.ok} ok of {self.rows} rows)"
        return [head, *(s.line() for s in self.series)]

    def as_dict(self) -> dict[str, Any]:
        return {
            "rows": self.rows,
            "ok": self.ok,
            "dated": self.dated,
            "series": [s.as_dict() for s in self.series],
        }


def fleet_trends(
    table: pa.Table, since: date | None = None, until: date | None = None
) -> FleetTrends:
    """The trends of a results table (see the module docstring), over the flights started on
    or after ``since`` and on or before ``until`` (UTC dates; None: no bound)."""
    rows = table.to_pylist()
    ok = [r for r in rows if r["status"] == "ok"]
    dated = _one_per_log(
        [
            r
            for r in ok
            if r["start_utc"] is not None
            and (since is None or r["start_utc"].date() >= since)
            and (until is None or r["start_utc"].date() <= until)
        ]
    )
    series: list[Series] = []
    for kind, key in (("vehicle", _vehicle_key), ("pack", _pack_key)):
        groups: dict[str, list[dict[str, Any]]] = {}
        for row in dated:
            name = key(row)
            if name is not None:
                groups.setdefault(name, []).append(row)
        for name, members in sorted(groups.items()):
            for metric, unit, label in METRICS:
                points = [
                    (r["start_utc"].timestamp() / 86400.0, value)
                    for r in members
                    if (value := _value(r, metric)) is not None and np.isfinite(value)
                ]
                if points:
                    days, values = (np.array(c, dtype=float) for c in zip(*points, strict=True))
                    series.append(Series(kind, name, metric, unit, label, days, values))
    return FleetTrends(series, len(rows), len(ok), len(dated))


def _one_per_log(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per content hash: a ``fit`` row where there is one (it has the fitted hover
    power), else the first."""
    chosen: dict[str, dict[str, Any]] = {}
    for row in rows:
        if row["sha256"] not in chosen or row["mode"] == "fit":
            chosen[row["sha256"]] = row
    return list(chosen.values())


def _vehicle_key(row: dict[str, Any]) -> str:
    sysid = row["autopilot_sysid"]
    return row["vehicle"] if sysid is None else f"{row['vehicle']} #{sysid}"


def _pack_key(row: dict[str, Any]) -> str | None:
    pack = row["pack_id"]
    return None if pack is None else str(pack)


def _value(row: dict[str, Any], metric: str) -> float | None:
    if metric == "hover_power_w":
        fitted = row["hover_power_fit_w"]
        return row["hover_power_tracked_w"] if fitted is None else fitted
    value = row[metric]
    return None if value is None else float(value)


def _date(days: float) -> date:
    return date.fromordinal(date(1970, 1, 1).toordinal() + int(days))
