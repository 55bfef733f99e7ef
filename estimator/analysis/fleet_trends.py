"""Trends across dates in a fleet results file (:mod:`estimator.analysis.fleet_table`).

Per vehicle (vehicle file name and autopilot system id) and per pack (where the logs name
it), over the flights with status ok and a start time: hover power (the per-flight fit's
where there is one, else the vehicle model's at the online-tracked mass), internal
resistance, usable capacity from the resting voltage and the capacity the pack filter
learnt (capacity fade). Each series gets per-day medians and a robust slope (Theil–Sen, with
its 95 % interval) per 30 days; a series whose flights carry a 1σ (the learnt capacity) gets
per-day inverse-variance weighted means and a weighted least-squares slope instead, its
interval widened by the scatter beyond the σ (√(χ²/dof) when above 1). A hover-power change
reads as a mass change through momentum theory (P_hover ∝ m^1.5 at constant air density):
m₂/m₁ = (P₂/P₁)^(2/3).
"""

from __future__ import annotations

import math
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
    ("pack_capacity_ah", "Ah", "learnt capacity"),
)
#: The column of each metric's per-flight 1σ, where it has one.
SIGMA_COLUMNS = {"pack_capacity_ah": "pack_capacity_sigma_ah"}
#: Two-sided 95 % quantile of the normal distribution.
_Z95 = 1.959964
_DAYS_PER_SLOPE = 30.0
#: Fewer distinct days than this: no slope.
MIN_DAYS = 2


@dataclass(frozen=True)
class Series:
    """One metric of one vehicle or pack: per-flight values (with their 1σ where the metric
    has one) and per-day figures."""

    kind: str  # "vehicle" or "pack"
    group: str
    metric: str
    unit: str
    label: str
    days: NDArray[np.float64]  # days since 1970-01-01 (UTC), per flight
    values: NDArray[np.float64]
    sigmas: NDArray[np.float64] | None = None

    def per_day(self) -> list[tuple[date, float, int]]:
        """(day, value, flights) per day, in date order: the median, or with σ the
        inverse-variance weighted mean."""
        out = []
        for day in np.unique(np.floor(self.days)):
            on = np.floor(self.days) == day
            if self.sigmas is None:
                value = float(np.median(self.values[on]))
            else:
                weights = self.sigmas[on] ** -2.0
                value = float(np.sum(weights * self.values[on]) / np.sum(weights))
            out.append((_date(day), value, int(on.sum())))
        return out

    def slope_per_30d(self) -> tuple[float, float, float] | None:
        """Slope per 30 days with its 95 % interval: Theil–Sen over the per-day medians, or
        with σ weighted least squares over the flights."""
        daily = self.per_day()
        if len(daily) < MIN_DAYS:
            return None
        if self.sigmas is not None:
            return self._weighted_slope_per_30d(self.sigmas)
        x = np.array([d.toordinal() for d, _, _ in daily], dtype=float)
        y = np.array([v for _, v, _ in daily])
        slope, _, low, high = theilslopes(y, x)
        return (
            float(slope * _DAYS_PER_SLOPE),
            float(low * _DAYS_PER_SLOPE),
            float(high * _DAYS_PER_SLOPE),
        )

    def _weighted_slope_per_30d(self, sigmas: NDArray[np.float64]) -> tuple[float, float, float]:
        x = self.days - float(np.mean(self.days))
        (slope, intercept), cov = np.polyfit(x, self.values, 1, w=1.0 / sigmas, cov="unscaled")
        dof = len(x) - 2
        chi2 = float(np.sum(((self.values - slope * x - intercept) / sigmas) ** 2))
        scale = max(chi2 / dof, 1.0) if dof > 0 else 1.0
        half = _Z95 * float(np.sqrt(cov[0, 0] * scale))
        return (
            float(slope * _DAYS_PER_SLOPE),
            float((slope - half) * _DAYS_PER_SLOPE),
            float((slope + half) * _DAYS_PER_SLOPE),
        )

    def as_dict(self) -> dict[str, Any]:
        slope = self.slope_per_30d()
        per_day = "median" if self.sigmas is None else "weighted_mean"
        return {
            "kind": self.kind,
            "group": self.group,
            "metric": self.metric,
            "unit": self.unit,
            "flights": len(self.values),
            "per_day": [
                {"date": d.isoformat(), per_day: v, "flights": n} for d, v, n in self.per_day()
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
        if self.sigmas is not None:
            text += " (σ-weighted)"
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
                sigma_column = SIGMA_COLUMNS.get(metric)
                points = [
                    (r["start_utc"].timestamp() / 86400.0, value, sigma)
                    for r in members
                    if (value := _value(r, metric)) is not None
                    and np.isfinite(value)
                    and (sigma := _sigma(r, sigma_column)) is not None
                ]
                if points:
                    days, values, sigmas = (
                        np.array(c, dtype=float) for c in zip(*points, strict=True)
                    )
                    series.append(
                        Series(
                            kind,
                            name,
                            metric,
                            unit,
                            label,
                            days,
                            values,
                            None if sigma_column is None else sigmas,
                        )
                    )
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


def _sigma(row: dict[str, Any], column: str | None) -> float | None:
    """The row's 1σ in ``column`` (finite and > 0, else None); NaN for metrics without one."""
    if column is None:
        return math.nan
    sigma = row[column]
    return float(sigma) if sigma is not None and math.isfinite(sigma) and sigma > 0 else None


def _date(days: float) -> date:
    return date.fromordinal(date(1970, 1, 1).toordinal() + int(days))
