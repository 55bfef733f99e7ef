"""The pack from flight logs: internal resistance and resting cell curve OCV(state of charge).

A flight is used when its log has a **rest** (the current at most ``rest_current_a`` for
``rest_min_s``, e.g. powered up before take-off) and a **long discharge** (at least
``min_drawn_fraction`` of ``capacity_ah`` drawn). Per flight, with ``c`` the charge drawn
since the log's first reading (the autopilot's consumed-charge counter, else the current
integrated, Ah), one bounded linear least-squares fit of

    V = OCV_pack(c) − I·R

gives ``R`` (Ω) and the resting pack voltage on knots every ``knot_step`` of capacity in
``c``, falling with ``c`` (steps ≥ 0), with a light penalty on its curvature. The curve
changes slowly with the charge drawn, the current in steps (take-off, hover, cruise, landing):
the steps at the same charge give ``R``, a rest gives the curve without it.

The charge axis needs the pack's capacity ``Q`` (``capacity_ah``, the real one: a pack that
holds less than stated stretches the curve) and the charge at the start ``s0``:
state of charge = ``s0 − c/Q``. Neither follows from the voltage without a curve to read it
against, so: ``s0`` is 1 for a flight whose curve at ``c = 0`` is within ``full_tolerance_v``
of the chemistry's full cell voltage (a charged pack). The charged flights' resting points
``(V + I·R)/cells`` are fitted together on the evenly spaced state-of-charge grid of
``points`` (rising); a flight that started part-charged is then placed where its own curve
best matches theirs (overlapping by at least :data:`MIN_OVERLAP` of charge) and joins the
pooled fit. Without a charged flight the start charge is unknown and only ``R`` is fitted.
The RMS of the pooled residual is the curve's σ (V per cell) over the fitted stretch.
Outside it the curve is the chemistry's typical one shifted to join the fitted part at its
ends: a discharge from full to the reserve gives the curve from the reserve up, not below.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import lsq_linear
from scipy.sparse import csr_matrix, diags, hstack, vstack

from estimator.logs import FlightSeries
from estimator.physics.battery import CHEMISTRY_OCV_V, SOC_POINTS
from estimator.physics.vehicle import CELL_SAG_ALLOWANCE_V, OCV_RANGE_V, OCV_SIGMA_RANGE_V

FloatArray = NDArray[np.float64]

#: Largest current magnitude believed (A): beyond, a reading is a glitch or forged.
MAX_CURRENT_A = 1000.0
#: A flight that did not start charged is placed on the charged flights' curve only where
#: its discharge overlaps it by at least this much charge (fraction).
MIN_OVERLAP = 0.05
#: The autopilot's consumed-charge counter is used when its total is within this fraction
#: of the current integrated (a counter that jumps or restarts is not).
COUNTER_AGREEMENT = 0.25
#: ... and when it comes with at least this fraction of the readings.
COUNTER_COVERAGE = 0.9
#: A flight that drew more than this many times the stated capacity contradicts it.
MAX_DRAWN_FRACTION = 1.5


@dataclass(frozen=True)
class PackFitOptions:
    """Settings of the pack fit (SI units, charge as a fraction of the capacity)."""

    rest_current_a: float = 1.0
    rest_min_s: float = 10.0
    min_drawn_fraction: float = 0.2
    #: Knot spacing of the per-flight fit in charge drawn (fraction of the capacity).
    knot_step: float = 0.01
    #: Curvature penalty (V per knot step², against the readings' V): small, it only keeps
    #: sparse stretches of the curve smooth.
    smoothing: float = 0.3
    full_tolerance_v: float = 0.03
    #: Points of the written curve (state of charge 0, 1/(points−1), …, 1).
    points: int = 101


@dataclass(frozen=True)
class FlightPack:
    """One flight's discharge: its pack resistance (Ω), state of charge at the log's start
    (NaN: not known), whether it started charged (else placed on the charged flights' curve),
    the charge drawn (Ah) and
    where the readings came from (``consumed`` counter or ``integrated`` current)."""

    flight_id: str
    resistance_ohm: float
    start_soc: float
    start_full: bool
    drawn_ah: float
    charge_source: str


@dataclass(frozen=True)
class PackFit:
    """The fitted pack: resting cell voltage (V) at ``points`` evenly spaced states of charge
    from 0 to 1, the fitted stretch of charge (the rest is the chemistry's curve joined on),
    the curve's σ (V per cell, RMS residual) — all three None without a charged flight —,
    the pack's resistance (Ω, median over flights), the flights used and the resting points
    (state of charge, V per cell) for plots."""

    cell_ocv_v: FloatArray | None
    fitted_soc: tuple[float, float] | None
    sigma_v: float | None
    resistance_ohm: float
    flights: tuple[FlightPack, ...]
    points_soc: FloatArray
    points_cell_v: FloatArray

    def summary(self) -> dict[str, object]:
        """The ``pack`` object of ``uav-energy fit --json``."""
        curve = self.cell_ocv_v
        return {
            "resistance_ohm": round(self.resistance_ohm, 5),
            "cell_ocv_sigma_v": None if self.sigma_v is None else round(self.sigma_v, 5),
            "fitted_soc": None
            if self.fitted_soc is None
            else [round(s, 4) for s in self.fitted_soc],
            "cell_ocv_v": None if curve is None else [round(float(v), 5) for v in curve],
            "flights": [
                {
                    "flight": f.flight_id,
                    "resistance_ohm": round(f.resistance_ohm, 5),
                    "start_soc": None if np.isnan(f.start_soc) else round(f.start_soc, 4),
                    "start_full": f.start_full,
                    "drawn_ah": round(f.drawn_ah, 4),
                    "charge_source": f.charge_source,
                }
                for f in self.flights
            ],
        }


@dataclass(frozen=True)
class _Discharge:
    """A usable flight's readings: charge drawn (Ah), pack voltage (V), current (A)."""

    flight_id: str
    drawn_ah: FloatArray
    voltage_v: FloatArray
    current_a: FloatArray
    charge_source: str


def fit_pack(
    flights: list[FlightSeries],
    cells: int,
    capacity_ah: float,
    chemistry: str = "lipo",
    options: PackFitOptions | None = None,
) -> tuple[PackFit | None, list[str]]:
    """Fit the pack to the flights that have a rest and a long discharge. Returns the fit
    (None when no flight qualifies) and one sentence per flight left out, saying why."""
    opt = options or PackFitOptions()
    reasons: list[str] = []
    discharges: list[_Discharge] = []
    for flight in flights:
        found = _discharge(flight, cells, capacity_ah, opt)
        if isinstance(found, str):
            reasons.append(f"{flight.flight_id} left out: {found}")
        else:
            discharges.append(found)
    if not discharges:
        return None, reasons
    typical_v = CHEMISTRY_OCV_V[chemistry]
    curves = []
    for d in discharges:
        knots_ah = _knots(float(d.drawn_ah[-1]), opt.knot_step * capacity_ah)
        pack_v, resistance_ohm = _monotone_fit(
            d.drawn_ah, d.voltage_v, knots_ah, opt.smoothing, d.current_a
        )
        full = bool(pack_v[0] / cells >= float(typical_v[-1]) - opt.full_tolerance_v)
        curves.append((d, knots_ah / capacity_ah, pack_v / cells, resistance_ohm, full))
    resistance = float(np.median([c[3] for c in curves]))
    if not any(c[4] for c in curves):
        reasons.append(
            "no flight starts charged (the curve at power-up more than "
            f"{1000 * opt.full_tolerance_v:g} mV/cell below full): the charge at its start is "
            "not known, so the resting curve is not fitted (the resistance is)"
        )
        flights_used = tuple(
            FlightPack(d.flight_id, r, float("nan"), False, float(d.drawn_ah[-1]), d.charge_source)
            for d, _, _, r, _ in curves
        )
        empty = np.zeros(0)
        return PackFit(None, None, None, resistance, flights_used, empty, empty), reasons
    # charged flights first: their pooled curve places the others (by their drawn stretch)
    anchored: tuple[FloatArray, FloatArray] | None = None
    used: list[FlightPack] = []
    soc_parts: list[FloatArray] = []
    cell_parts: list[FloatArray] = []
    for d, drawn_fraction, cell_v, resistance_ohm, full in sorted(curves, key=lambda c: not c[4]):
        if not full and anchored is None:
            anchored = _pooled(np.concatenate(soc_parts), np.concatenate(cell_parts), opt)
        start_soc = 1.0 if full else _placed(drawn_fraction, cell_v, anchored, opt)
        if start_soc is None:
            reasons.append(
                f"{d.flight_id} left out of the curve: its discharge does not overlap the "
                f"charged flights' curve by {100 * MIN_OVERLAP:g} % of charge"
            )
            continue
        used.append(
            FlightPack(
                d.flight_id, resistance_ohm, start_soc, full, float(d.drawn_ah[-1]), d.charge_source
            )
        )
        soc_parts.append(start_soc - d.drawn_ah / capacity_ah)
        cell_parts.append((d.voltage_v + d.current_a * resistance_ohm) / cells)
    soc = np.concatenate(soc_parts)
    cell_v = np.concatenate(cell_parts)
    grid, fitted = _pooled(soc, cell_v, opt)
    residual_v = cell_v - np.interp(soc, grid, fitted)
    sigma_v = float(np.clip(np.sqrt(np.mean(residual_v**2)), *OCV_SIGMA_RANGE_V))
    fit = PackFit(
        _joined(grid, fitted, typical_v, opt.points),
        (float(np.min(soc)), float(np.max(soc))),
        sigma_v,
        resistance,
        tuple(used),
        soc,
        cell_v,
    )
    return fit, reasons


def _pooled(
    soc: FloatArray, cell_v: FloatArray, opt: PackFitOptions
) -> tuple[FloatArray, FloatArray]:
    """The rising curve (V per cell) through resting points on the written curve's grid
    points that cover them: (grid, voltages)."""
    step = 1.0 / (opt.points - 1)
    lo_k = max(int(np.floor(float(np.min(soc)) / step + 1e-9)), 0)
    hi_k = min(int(np.ceil(float(np.max(soc)) / step - 1e-9)), opt.points - 1)
    grid = np.arange(lo_k, hi_k + 1, dtype=float) * step
    # rising in charge = falling in (1 − charge): the same fit on the mirrored axis
    fitted_rev, _ = _monotone_fit(1.0 - soc, cell_v, (1.0 - grid)[::-1], opt.smoothing, None)
    return grid, fitted_rev[::-1]


def _placed(
    drawn_fraction: FloatArray,
    cell_v: FloatArray,
    anchored: tuple[FloatArray, FloatArray] | None,
    opt: PackFitOptions,
) -> float | None:
    """State of charge at the start of a flight that did not start charged: where its curve
    (``cell_v`` at ``drawn_fraction`` of capacity, V per cell) best matches the charged
    flights' (``anchored``: grid, V per cell) over at least :data:`MIN_OVERLAP` of charge;
    None when it cannot overlap that much."""
    if anchored is None:
        return None
    grid, fitted = anchored
    low = max(float(drawn_fraction[-1]), float(grid[0]))
    candidates = np.arange(low + MIN_OVERLAP, 1.0 + 1e-9, 0.001)
    best: tuple[float, float] | None = None
    for s in candidates:
        soc = s - drawn_fraction
        inside = (soc >= grid[0]) & (soc <= grid[-1])
        if not inside.any():
            continue
        cost = float(np.mean((cell_v[inside] - np.interp(soc[inside], grid, fitted)) ** 2))
        if best is None or cost < best[0]:
            best = (cost, float(s))
    return None if best is None else best[1]


def _discharge(
    flight: FlightSeries, cells: int, capacity_ah: float, opt: PackFitOptions
) -> _Discharge | str:
    """The flight's readings if it has a rest and a long discharge, else why not. Readings
    with a non-finite value, a cell voltage outside the believable range or a current beyond
    :data:`MAX_CURRENT_A` are dropped."""
    v, i, t = flight.voltage_v, flight.current_a, flight.time_s
    cell_lo = OCV_RANGE_V[0] - CELL_SAG_ALLOWANCE_V
    ok = (
        np.isfinite(v)
        & np.isfinite(i)
        & np.isfinite(t)
        & (v > cells * cell_lo)
        & (v < cells * OCV_RANGE_V[1])
        & (np.abs(i) <= MAX_CURRENT_A)
    )
    if np.count_nonzero(ok) < 10:
        return "no pack voltage and current readings"
    t, v, i = t[ok], v[ok], i[ok]
    integrated_ah = np.concatenate(([0.0], np.cumsum(0.5 * (i[1:] + i[:-1]) * np.diff(t)) / 3600))
    drawn_ah, source = integrated_ah, "integrated"
    consumed = flight.extras.get("consumed_mah")
    known = np.zeros(len(t), dtype=bool) if consumed is None else np.isfinite(consumed[ok])
    if consumed is not None and known.mean() >= COUNTER_COVERAGE:
        # the counter between its readings (some messages carry none), if it never runs back
        # and agrees with the current it counts
        counter_mah = np.interp(t, t[known], consumed[ok][known])
        counted_ah = (counter_mah - counter_mah[0]) / 1000.0
        total_ah = max(float(integrated_ah[-1]), 1e-9)
        agrees = abs(float(counted_ah[-1]) - total_ah) <= COUNTER_AGREEMENT * total_ah
        if agrees and np.all(np.diff(counted_ah) >= -0.001):
            drawn_ah, source = counted_ah, "consumed"
    drawn_ah = np.maximum.accumulate(drawn_ah)
    if _longest_rest_s(t, i, opt.rest_current_a) < opt.rest_min_s:
        return (
            f"no rest (the current never stays at or below {opt.rest_current_a:g} A for "
            f"{opt.rest_min_s:g} s)"
        )
    drawn_fraction = float(drawn_ah[-1]) / capacity_ah
    if drawn_fraction < opt.min_drawn_fraction:
        return (
            f"too little discharge ({100 * drawn_fraction:.0f} % of {capacity_ah:g} Ah drawn, "
            f"at least {100 * opt.min_drawn_fraction:.0f} % needed)"
        )
    if drawn_fraction > MAX_DRAWN_FRACTION:
        return (
            f"{drawn_fraction:.1f} times its {capacity_ah:g} Ah drawn: more than a pack of that "
            "capacity holds"
        )
    return _Discharge(flight.flight_id, drawn_ah, v, i, source)


def _longest_rest_s(time_s: FloatArray, current_a: FloatArray, rest_current_a: float) -> float:
    """The longest stretch (s) of consecutive readings at or below ``rest_current_a``."""
    resting = np.abs(current_a) <= rest_current_a
    edges = np.diff(np.concatenate(([0], resting.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return float(np.max(time_s[ends] - time_s[starts], initial=0.0))


def _knots(span: float, step: float) -> FloatArray:
    """Evenly spaced knots from 0 covering ``span`` (at least two)."""
    if span <= 0:
        return np.zeros(2)
    return np.arange(int(np.ceil(span / step - 1e-9)) + 1, dtype=float) * step


def _monotone_fit(
    x: FloatArray,
    y: FloatArray,
    knots: FloatArray,
    smoothing: float,
    current_a: FloatArray | None,
) -> tuple[FloatArray, float]:
    """Least squares of ``y ≈ f(x) − current·R`` with ``f`` piecewise linear on ``knots``
    (ascending), falling (each step ≥ 0) and its second differences penalised by
    ``smoothing``; ``R`` ≥ 0 (0 without ``current_a``). Returns ``f`` at the knots and R."""
    n = len(knots)
    if n < 2 or knots[-1] <= knots[0]:
        knots = np.array([0.0, max(float(np.max(x)), 1e-6)])
        n = 2
    # linear interpolation weights of each reading on its two knots
    j = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, n - 2)
    w = np.clip((x - knots[j]) / (knots[j + 1] - knots[j]), 0.0, 1.0)
    rows = np.arange(len(x))
    interp = csr_matrix(
        (np.concatenate((1 - w, w)), (np.concatenate((rows, rows)), np.concatenate((j, j + 1)))),
        shape=(len(x), n),
    )
    # f = f0 − cumsum(steps): columns [f0, step_1..step_{n−1}]
    falling = csr_matrix(np.hstack((np.ones((n, 1)), -np.tril(np.ones((n, n - 1)), -1))))
    design = interp @ falling
    bounds_lo = [-np.inf] + [0.0] * (n - 1)
    bounds_hi = [np.inf] * n
    blocks = [design]
    if current_a is not None:
        blocks = [hstack([design, csr_matrix(-current_a.reshape(-1, 1))])]
        bounds_lo.append(0.0)
        bounds_hi.append(np.inf)
    columns = blocks[0].shape[1]
    target = [y]
    if n > 2 and smoothing > 0:
        # second difference of f = −(step_{k+1} − step_k)
        curvature = diags([-1.0, 1.0], [0, 1], shape=(n - 2, n - 1)) * (
            smoothing * np.sqrt(len(x) / n)
        )
        pad_right = columns - n
        penalty = hstack(
            [csr_matrix((n - 2, 1)), curvature]
            + ([csr_matrix((n - 2, pad_right))] if pad_right else [])
        )
        blocks.append(penalty)
        target.append(np.zeros(n - 2))
    solved = lsq_linear(
        vstack(blocks).tocsr(),
        np.concatenate(target),
        bounds=(np.array(bounds_lo), np.array(bounds_hi)),
        lsmr_tol="auto",
    )
    params = solved.x
    f = params[0] - np.concatenate(([0.0], np.cumsum(params[1:n])))
    return f, float(params[n]) if current_a is not None else 0.0


def _joined(grid: FloatArray, fitted: FloatArray, typical_v: FloatArray, points: int) -> FloatArray:
    """The curve at ``points`` evenly spaced states of charge: ``fitted`` on ``grid``, the
    typical curve shifted to meet it beyond; strictly rising and within the cell range."""
    soc = np.linspace(0.0, 1.0, points)
    typical = np.interp(soc, SOC_POINTS, typical_v)
    below = typical + fitted[0] - np.interp(grid[0], SOC_POINTS, typical_v)
    above = typical + fitted[-1] - np.interp(grid[-1], SOC_POINTS, typical_v)
    curve = np.where(soc < grid[0], below, np.where(soc > grid[-1], above, 0.0))
    inside = (soc >= grid[0]) & (soc <= grid[-1])
    curve[inside] = np.interp(soc[inside], grid, fitted)
    # strictly rising at 0.1 mV a point (a flat stretch of the fit, rounded for the file)
    lo, hi = OCV_RANGE_V
    curve = np.clip(curve, lo, hi - 1e-4 * points)
    for k in range(1, points):
        curve[k] = max(curve[k], curve[k - 1] + 1e-4)
    return np.asarray(np.round(curve, 5), dtype=float)
