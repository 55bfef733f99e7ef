"""Samples of a residual analysis: the level-flight rows of every flight (NED frame, SI units),
smoothed velocity and its derivative, held-out chunk, fold and block of each row, and the
telemetry channels the attribution looks at.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimator.errors import UserError
from estimator.logs import FlightSeries
from estimator.physics.effects import (
    EFFECT_TYPES,
    FlightState,
)
from estimator.physics.kinematics import centripetal_accel_mps2, tangential_accel_mps2
from estimator.physics.model import FloatArray

IntArray = NDArray[np.int64]


#: Extras of a log that are not physical channels.
_NOT_CHANNELS = ("armed", "consumed_mah")


@dataclass(frozen=True)
class ResidualOptions:
    """Settings of the analysis (SI units); see the module docstring."""

    folds: int = 5
    #: Length of the held-out chunks (s), assigned to the folds in turn.
    chunk_s: float = 20.0
    #: Length of the evaluation blocks of the rank test (s): see the module docstring of
    #: :mod:`estimator.analysis.residuals`.
    block_s: float = 2.5
    guard_s: float = 5.0
    z_threshold: float = 3.0
    min_gain_fraction: float = 0.10
    smooth_s: float = 0.5
    min_alt_m: float = 1.0
    min_power_w: float = 1.0
    #: Rows below this fraction of the flight's median power are not airborne (touch-down).
    min_power_fraction: float = 0.25
    max_gap_s: float = 2.0
    #: Take-off transient: at least this long (s) after the first airborne row, and until the
    #: vertical speed first falls to ``level_mps`` (m/s).
    settle_s: float = 5.0
    level_mps: float = 0.3
    #: The final descent, dropped, starts after the last stretch of level rows at least this
    #: long (s): a touch-down slows below ``level_mps`` for a moment.
    level_stretch_s: float = 1.0
    min_flight_s: float = 30.0
    candidates: tuple[str, ...] = tuple(EFFECT_TYPES)
    #: Channels with a held-out R² below this do not count as predicting the residual.
    min_r2: float = 0.05
    #: A residual whose held-out RMSE exceeds this many noise floors is not noise.
    noise_ratio: float = 2.0
    #: At most this many effects are selected.
    max_effects: int = 6
    #: A load (W) above this that is as good held out as a mass is named as the mass.
    max_load_w: float = 50.0


@dataclass
class Samples:
    """Airborne rows of all flights, concatenated (NED frame, flight clock per flight).

    ``chunk``: held-out chunk of each row (unique over flights, one unused id between
    flights); ``fold``: the fold that holds it out; ``block``: evaluation block id (unique over
    flights);
    ``channels``: per-row telemetry for structure plots and attribution (``*_deg`` circular).
    """

    flight_ids: list[str]
    flight: IntArray
    state: FlightState
    power_w: FloatArray
    fold: IntArray
    chunk: IntArray
    block: IntArray
    channels: dict[str, FloatArray]
    skipped_flights: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.power_w)

    def state_at(self, rows: NDArray[np.bool_]) -> FlightState:
        s = self.state
        return FlightState(
            s.time_s[rows],
            s.vn_mps[rows],
            s.ve_mps[rows],
            s.vd_mps[rows],
            s.an_mps2[rows],
            s.ae_mps2[rows],
            s.alt_m[rows],
            s.voltage_v[rows],
            None if s.ad_mps2 is None else s.ad_mps2[rows],
        )

    def train_rows(self, fold: int, guard_s: float) -> NDArray[np.bool_]:
        """Rows outside the chunks of ``fold`` and further than ``guard_s`` from them (chunks
        are longer than two guards, so only the neighbouring chunks matter)."""
        t = self.state.time_s
        n_chunks = int(self.chunk.max()) + 1
        start, end = np.full(n_chunks, np.inf), np.full(n_chunks, -np.inf)
        np.minimum.at(start, self.chunk, t)
        np.maximum.at(end, self.chunk, t)
        held = np.zeros(n_chunks + 1, dtype=bool)  # the extra one: "no neighbour"
        held[self.chunk[self.fold == fold]] = True
        prev = np.where(self.chunk > 0, self.chunk - 1, n_chunks)
        nxt = np.minimum(self.chunk + 1, n_chunks)
        near_prev = held[prev] & (t - end[np.minimum(prev, n_chunks - 1)] <= guard_s)
        near_next = held[nxt] & (start[np.minimum(nxt, n_chunks - 1)] - t <= guard_s)
        return ~held[self.chunk] & ~near_prev & ~near_next

    @property
    def has_voltage(self) -> bool:
        return bool(np.mean(np.isfinite(self.state.voltage_v)) > 0.5)


def prepare(flights: Sequence[FlightSeries], options: ResidualOptions | None = None) -> Samples:
    """Airborne samples of ``flights`` with smoothed kinematics, folds, blocks and channels."""
    opt = options or ResidualOptions()
    parts: list[dict[str, FloatArray]] = []
    ids: list[str] = []
    skipped: list[str] = []
    block_base = 0
    chunk_base = 0
    for flight in flights:
        part = _flight_rows(flight, opt)
        if part is None:
            skipped.append(flight.flight_id)
            continue
        part["flight"] = np.full(len(part["time_s"]), float(len(ids)))
        part["block"] = part["block"] + block_base
        block_base = int(part["block"].max()) + 1
        part["chunk"] = part["chunk"] + chunk_base
        chunk_base = int(part["chunk"].max()) + 2
        ids.append(flight.flight_id)
        parts.append(part)
    if not parts:
        raise UserError(
            f"no flight has {opt.min_flight_s:.0f} s of airborne samples with power and velocity"
        )
    common = set.intersection(*(set(p) for p in parts))
    cols = {k: np.concatenate([p[k] for p in parts]) for k in common}
    state = FlightState(
        cols["time_s"],
        cols["vn_mps"],
        cols["ve_mps"],
        cols["vd_mps"],
        cols["an_mps2"],
        cols["ae_mps2"],
        cols["alt_m"],
        cols["voltage_v"],
        cols["ad_mps2"],
    )
    channels = {
        "time_s": cols["time_s"],
        "speed_mps": np.hypot(cols["vn_mps"], cols["ve_mps"]),
        "heading_deg": np.degrees(np.arctan2(cols["ve_mps"], cols["vn_mps"])) % 360.0,
        "accel_centripetal_mps2": centripetal_accel_mps2(
            cols["vn_mps"], cols["ve_mps"], cols["an_mps2"], cols["ae_mps2"]
        ),
        "accel_tangential_mps2": tangential_accel_mps2(
            cols["vn_mps"], cols["ve_mps"], cols["an_mps2"], cols["ae_mps2"]
        ),
        "climb_mps": -cols["vd_mps"],
        "alt_m": cols["alt_m"],
        "voltage_v": cols["voltage_v"],
        "energy_used_wh": cols["energy_used_wh"],
    }
    for key in sorted(common - set(_PART_KEYS)):
        channels[key] = cols[key]
    channels = {k: v for k, v in channels.items() if _informative(v)}
    samples = Samples(
        flight_ids=ids,
        flight=cols["flight"].astype(np.int64),
        state=state,
        power_w=cols["power_w"],
        fold=cols["fold"].astype(np.int64),
        chunk=cols["chunk"].astype(np.int64),
        block=cols["block"].astype(np.int64),
        channels=channels,
        skipped_flights=skipped,
    )
    n_blocks = len(np.unique(samples.block))
    if n_blocks < 2 * opt.folds:
        raise UserError(
            f"only {n_blocks} blocks of {opt.block_s:g} s of airborne data; need at least "
            f"{2 * opt.folds} (a few minutes of flight) for a held-out test"
        )
    return samples


_PART_KEYS = (
    *("time_s", "vn_mps", "ve_mps", "vd_mps", "an_mps2", "ae_mps2", "ad_mps2", "alt_m"),
    "voltage_v",
    *("power_w", "energy_used_wh", "fold", "chunk", "block", "flight"),
)


def _informative(x: FloatArray) -> bool:
    finite = x[np.isfinite(x)]
    return len(finite) > 0.5 * len(x) and float(np.ptp(finite)) > 0


def _level_between(
    t: FloatArray, vd_mps: FloatArray, rows: IntArray, opt: ResidualOptions
) -> IntArray:
    """``rows`` from the first level flight after take-off to the last before landing: the
    take-off transient (spool-up, ground effect, the climb away; at least ``settle_s``) and
    the final descent are not the level flight the model and its effects describe. Climbs
    in between stay. Rows without a vertical speed count as level."""
    if len(rows) == 0:
        return rows
    level = ~(np.abs(vd_mps[rows]) > opt.level_mps)
    settled = level & (t[rows] >= t[rows[0]] + opt.settle_s)
    if not settled.any():
        return rows[:0]
    first = int(np.argmax(settled))
    # stretches of consecutive level rows: their first and last index
    edges = np.diff(np.r_[0, level.astype(np.int8), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    steady = ends[t[rows[ends]] - t[rows[starts]] >= opt.level_stretch_s]
    last = int(steady[-1]) if len(steady) else len(rows) - 1 - int(np.argmax(level[::-1]))
    return rows[first : last + 1]


def _flight_rows(f: FlightSeries, opt: ResidualOptions) -> dict[str, FloatArray] | None:
    t = f.time_s
    ok = np.isfinite(t) & np.isfinite(f.power_w) & np.isfinite(f.vn_mps) & np.isfinite(f.ve_mps)
    ok &= np.r_[True, np.diff(t) > 0]
    armed = f.extras.get("armed")
    if armed is not None:
        ok &= ~(armed == 0.0)
    ok &= ~(f.alt_m < opt.min_alt_m)
    ok &= f.power_w >= opt.min_power_w
    if ok.any():
        ok &= f.power_w >= opt.min_power_fraction * float(np.median(f.power_w[ok]))
    rows = _level_between(t, f.vd_mps, np.flatnonzero(ok), opt)
    if len(rows) < 10 or t[rows[-1]] - t[rows[0]] < opt.min_flight_s:
        return None
    t = t[rows]
    seg = np.r_[0, np.cumsum(np.diff(t) > opt.max_gap_s)]
    vn = _smooth(t, f.vn_mps[rows], seg, opt.smooth_s)
    ve = _smooth(t, f.ve_mps[rows], seg, opt.smooth_s)
    vd = np.nan_to_num(f.vd_mps[rows])
    an, ae = _gradient(vn, t, seg), _gradient(ve, t, seg)
    ad = _gradient(_smooth(t, vd, seg, opt.smooth_s), t, seg)
    power = f.power_w[rows]
    dt = np.diff(t, prepend=t[0])
    dt[np.r_[True, seg[1:] != seg[:-1]]] = 0.0
    chunk = np.floor((t - t[0]) / opt.chunk_s)
    part: dict[str, FloatArray] = {
        "time_s": t,
        "vn_mps": vn,
        "ve_mps": ve,
        "vd_mps": vd,
        "an_mps2": an,
        "ae_mps2": ae,
        "ad_mps2": ad,
        "alt_m": f.alt_m[rows],
        "voltage_v": f.voltage_v[rows],
        "power_w": power,
        "energy_used_wh": np.cumsum(power * dt) / 3600.0,
        "fold": chunk % opt.folds,
        "chunk": chunk,
        "block": np.floor((t - t[0]) / opt.block_s),
    }
    for key, values in f.extras.items():
        if key not in _NOT_CHANNELS and len(values) == len(f.time_s):
            part[key] = np.asarray(values, dtype=float)[rows]
    return part


def _smooth(t: FloatArray, x: FloatArray, seg: IntArray, sigma_s: float) -> FloatArray:
    """Gaussian kernel smoothing (1σ ``sigma_s``) on irregular times, within segments."""
    x = np.nan_to_num(x)
    if sigma_s <= 0:
        return x
    num, den = np.zeros(len(x)), np.zeros(len(x))
    reach = max(1, int(np.ceil(3 * sigma_s / max(float(np.median(np.diff(t))), 1e-3))))
    for k in range(-reach, reach + 1):
        j = np.clip(np.arange(len(x)) + k, 0, len(x) - 1)
        w = np.exp(-0.5 * ((t[j] - t) / sigma_s) ** 2) * (seg[j] == seg)
        w[(np.arange(len(x)) + k < 0) | (np.arange(len(x)) + k >= len(x))] = 0.0
        num += w * x[j]
        den += w
    return num / den


def through_accel_filter(samples: Samples, values: FloatArray, opt: ResidualOptions) -> FloatArray:
    """``values`` (one per row of ``samples``; e.g. power, W) through the filter the rows'
    accelerations went through, within gap-free stretches: the central difference that
    differentiates the velocities (on even steps a mean over the two intervals around a row,
    trapezoid weights) and their Gaussian smoothing (1σ ``opt.smooth_s``).

    An acceleration is a smoothed derivative of sampled velocities: a transient shorter than
    the filter reads lower and longer than it was. A power compared with it unfiltered fits
    a gain that grows with the transients' sharpness; through the same filter the two are
    compared like with like (a term linear in the acceleration then fits a gain that does not
    depend on the filter). The vertical figures of docs/residuals.md fit the heave gain so."""
    t = samples.state.time_s
    x = np.nan_to_num(np.asarray(values, dtype=float))
    dt = np.diff(t)
    joined = (np.diff(samples.flight) == 0) & (dt > 0) & (dt <= opt.max_gap_s)
    seg = np.r_[0, np.cumsum(~joined)]
    span = np.where(joined, dt, 0.0)
    left, right = np.r_[0.0, span], np.r_[span, 0.0]
    total = left + right
    mean = x.copy()
    both = total > 0
    prev, nxt = np.r_[x[:1], x[:-1]], np.r_[x[1:], x[-1:]]
    mean[both] = (left * (prev + x) + right * (x + nxt))[both] / (2.0 * total[both])
    return _smooth(t, mean, seg, opt.smooth_s)


def _gradient(x: FloatArray, t: FloatArray, seg: IntArray) -> FloatArray:
    out = np.zeros(len(x))
    for s in np.unique(seg):
        rows = seg == s
        if rows.sum() >= 2:
            out[rows] = np.gradient(x[rows], t[rows])
    return out
