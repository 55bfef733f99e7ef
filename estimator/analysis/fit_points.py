"""Preprocessing of flights for fitting (the seed paper's processing): 5 Hz points with speed
(m/s), tangential and centripetal acceleration (m/s²), measured power (W), take-off and landing
trimmed, |a| bounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from estimator.logs import FlightSeries
from estimator.physics.kinematics import centripetal_accel_mps2
from estimator.physics.model import FloatArray

#: Length of the time blocks over which residual correlation is measured, s.
BLOCK_S = 10.0


@dataclass(frozen=True)
class PreprocessOptions:
    """Thresholds of the paper's preprocessing (SI units)."""

    sample_rate_hz: float = 5.0
    max_accel_mps2: float = 0.5
    min_alt_m: float = 1.0
    max_vertical_speed_mps: float = 0.5
    edge_trim_s: float = 3.0
    max_gap_s: float = 2.0
    min_power_w: float = 1.0
    accel_window_s: float = 1.0


@dataclass
class Points:
    """Resampled samples, one row per 1/f_s tick; ``keep`` marks those that pass the filters."""

    flight_ids: list[str]
    flight: NDArray[np.int64]
    time_s: FloatArray
    speed_mps: FloatArray
    accel_tangential_mps2: FloatArray
    accel_perp_mps2: FloatArray
    vd_mps: FloatArray
    power_w: FloatArray
    mass_ratio: FloatArray
    keep: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.time_s)

    def select(self, mask: NDArray[np.bool_]) -> Points:
        return Points(
            flight_ids=self.flight_ids,
            flight=self.flight[mask],
            time_s=self.time_s[mask],
            speed_mps=self.speed_mps[mask],
            accel_tangential_mps2=self.accel_tangential_mps2[mask],
            accel_perp_mps2=self.accel_perp_mps2[mask],
            vd_mps=self.vd_mps[mask],
            power_w=self.power_w[mask],
            mass_ratio=self.mass_ratio[mask],
            keep=self.keep[mask],
        )

    def kept(self) -> Points:
        return self.select(self.keep)

    @property
    def n_flights(self) -> int:
        return len(np.unique(self.flight))

    @property
    def varying_mass(self) -> bool:
        return bool(np.ptp(self.mass_ratio) > 1e-9) if len(self) else False


def preprocess(
    flights: list[FlightSeries],
    options: PreprocessOptions | None = None,
    mass_kg: FloatArray | None = None,
    reference_mass_kg: float | None = None,
) -> Points:
    """All resampled points of all flights, with the paper's filters in ``keep``.

    ``mass_kg``/``reference_mass_kg``: per-flight take-off masses and the mass the fitted
    model describes; without them every mass ratio is 1.
    """
    opt = options or PreprocessOptions()
    parts = []
    for k, flight in enumerate(flights):
        ratio = 1.0
        if mass_kg is not None and reference_mass_kg is not None:
            ratio = float(mass_kg[k]) / reference_mass_kg
        parts.append(_flight_points(flight, k, ratio, opt))
    cols = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return Points(
        flight_ids=[f.flight_id for f in flights],
        flight=cols["flight"].astype(np.int64),
        time_s=cols["time_s"],
        speed_mps=cols["speed_mps"],
        accel_tangential_mps2=cols["accel_t"],
        accel_perp_mps2=cols["accel_perp"],
        vd_mps=cols["vd_mps"],
        power_w=cols["power_w"],
        mass_ratio=cols["mass_ratio"],
        keep=cols["keep"].astype(bool),
    )


def _flight_points(
    f: FlightSeries, index: int, mass_ratio: float, opt: PreprocessOptions
) -> dict[str, FloatArray]:
    dt = 1.0 / opt.sample_rate_hz
    t = f.time_s
    finite = np.isfinite(t) & np.isfinite(f.power_w) & np.isfinite(f.vn_mps) & np.isfinite(f.ve_mps)
    t = t[finite]
    empty = {k: np.empty(0) for k in _POINT_KEYS}
    if len(t) < 2:
        return empty
    # uniform grid per gap-free segment
    seg_breaks = np.flatnonzero(np.diff(t) > opt.max_gap_s) + 1
    grids, seg_id = [], []
    for s, (a, b) in enumerate(zip(np.r_[0, seg_breaks], np.r_[seg_breaks, len(t)], strict=True)):
        if b - a < 2:
            continue
        g = np.arange(t[a], t[b - 1] + 1e-9, dt)
        grids.append(g)
        seg_id.append(np.full(len(g), s))
    if not grids:
        return empty
    grid, seg = np.concatenate(grids), np.concatenate(seg_id)

    def interp(x: FloatArray) -> FloatArray:
        x = x[finite]
        ok = np.isfinite(x)
        if not ok.any():
            return np.full(len(grid), np.nan)
        return np.interp(grid, t[ok], x[ok])

    vn, ve, vd = interp(f.vn_mps), interp(f.ve_mps), interp(f.vd_mps)
    alt, power = interp(f.alt_m), interp(f.power_w)
    armed = f.extras.get("armed")
    armed_ok = np.ones(len(grid), bool)
    if armed is not None:
        armed_grid = interp(armed)
        armed_ok = ~(armed_grid < 0.5)  # unknown (NaN) counts as armed
    airborne = armed_ok & ~(alt < opt.min_alt_m) & (power >= opt.min_power_w)
    airborne &= _trim_runs(airborne, seg, round(opt.edge_trim_s * opt.sample_rate_hz))
    speed = np.hypot(vn, ve)
    # forward differences inside a segment (the paper's a ≈ (V_{i+1} − V_i) f_s)
    same_next = np.r_[seg[1:] == seg[:-1], False]
    accel_t = np.full(len(grid), np.nan)
    accel_t[:-1] = np.diff(speed) / dt
    accel_t[~same_next] = np.nan
    half = max(1, round(opt.accel_window_s * opt.sample_rate_hz / 2))
    accel_perp = centripetal_accel_mps2(
        vn, ve, _central_diff(vn, seg, half, dt), _central_diff(ve, seg, half, dt)
    )
    keep = (
        airborne
        & (np.abs(accel_t) <= opt.max_accel_mps2)
        & ~(np.abs(vd) > opt.max_vertical_speed_mps)
        & np.isfinite(accel_perp)
    )
    return {
        "flight": np.full(len(grid), float(index)),
        "time_s": grid,
        "speed_mps": speed,
        "accel_t": accel_t,
        "accel_perp": accel_perp,
        "vd_mps": vd,
        "power_w": power,
        "mass_ratio": np.full(len(grid), mass_ratio),
        "keep": keep.astype(float),
    }


_POINT_KEYS = (
    "flight",
    "time_s",
    "speed_mps",
    "accel_t",
    "accel_perp",
    "vd_mps",
    "power_w",
    "mass_ratio",
    "keep",
)


def _central_diff(x: FloatArray, seg: NDArray[np.int64], half: int, dt: float) -> FloatArray:
    """(x[i+h] − x[i−h]) / (2 h dt) inside a segment, NaN where the window leaves it."""
    out = np.full(len(x), np.nan)
    if len(x) > 2 * half:
        inside = seg[2 * half :] == seg[: -2 * half]
        diff = (x[2 * half :] - x[: -2 * half]) / (2 * half * dt)
        out[half:-half] = np.where(inside, diff, np.nan)
    return out


def _trim_runs(mask: NDArray[np.bool_], seg: NDArray[np.int64], n: int) -> NDArray[np.bool_]:
    """``mask`` with ``n`` samples removed at both ends of each true run (runs end at segments)."""
    out = mask.copy()
    if n <= 0:
        return out
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]) != 0)
    starts, ends = edges[::2], edges[1::2]
    new_seg = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
    for a, b in zip(starts, ends, strict=True):
        cuts = new_seg[(new_seg > a) & (new_seg < b)]
        for lo, hi in zip(np.r_[a, cuts], np.r_[cuts, b], strict=True):
            out[lo : min(lo + n, hi)] = False
            out[max(hi - n, lo) : hi] = False
    return out
