"""Residual analysis: what the power model lacks, found on data it was not fitted on.

The residual is r = measured electrical power − model power (the vehicle file's model and
effects through :func:`estimator.physics.effects.predict_power_w`) at every airborne sample of every
flight, all phases included (take-off, climbs, turns, accelerations, landing).

Method
------
1. **Samples** (:func:`prepare`): each flight's rows (one per power sample) while airborne
   (armed or unknown, above ``min_alt_m`` when the altitude is known, measured power above
   ``min_power_w`` and above ``min_power_fraction`` of the flight's median: motors at idle on
   touch-down are not flight). Ground velocity is smoothed with a Gaussian kernel of
   ``smooth_s`` (s, 1σ) inside gap-free stretches and differentiated for the horizontal
   acceleration (NED). Channels for the structure and the attribution: flight time, ground
   speed, heading, a⊥, tangential acceleration, climb rate, altitude, battery voltage, energy
   drawn so far (a state-of-charge proxy from the measured power), and the log's own numeric
   extras (CMU: payload, airflow).
2. **Held-out split**: each flight is cut into contiguous time chunks of ``chunk_s`` seconds,
   assigned to the ``folds`` in turn; fold j holds out its chunks and trains on the rest minus
   a guard of ``guard_s`` seconds on both sides of each held-out chunk (correlated noise must
   not leak). Never random samples. Short chunks keep the training data close to every
   held-out time: an effect that changes in flight is located within a chunk.
3. **Candidates**: one :class:`Candidate` per effect of :mod:`estimator.physics.effects` not
already in
   the vehicle file, each with one or two parameters fitted by ``scipy.optimize.least_squares``
   (soft-L1 loss, bounds from the effect's ``bounds``). ``mass`` and ``avionics`` come twice:
   constant (``at_s`` null) and stepped, the step time searched on the training data by a
   linearised scan over the sample times, then all parameters refitted together.
4. **Greedy forward selection**: at each step every remaining candidate is added to the
   selected set and scored by its held-out predictions. The held-out squared errors of the
   current and the extended model are summed per evaluation block of ``block_s`` seconds and
   compared pairwise over the blocks (a Wilcoxon signed-rank test on the block gains, as a z:
   a rank test because block gains are heavy-tailed, a few manoeuvre blocks dominating their
   spread, which would hide an effect that helps nearly every block; 5 s blocks are several
   times the 1–2 s correlation time of telemetry noise, so block gains are nearly independent,
   and short enough that an effect seen only in turns or in accelerations still spans many
   blocks). A candidate qualifies when z > ``z_threshold`` (3: one-sided p ≈ 0.001, ≈ 1 %
   family-wise over the candidates) *and*
   it cuts the held-out RMSE by at least ``min_gain_fraction``; the best qualifying one is
   added; selection stops when none qualifies. On clean data nothing qualifies.
5. **Attribution**: the held-out residual left after selection is regressed on each channel
   alone with a k-nearest-neighbour regressor (sklearn, same folds; the mean per value for
   channels with at most 16 distinct values, like a payload column); the channel with the
   highest held-out R² is where the remaining structure lives. When nothing was selected and a
   channel still predicts the residual, no candidate explains it and that channel is where to
   look.

Final parameters are refitted on all samples; their spread over the folds is reported too.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.stats import rankdata
from sklearn.neighbors import KNeighborsRegressor

from estimator.errors import UserError
from estimator.estimation.online_effects import wind_from_vector
from estimator.logs import FlightSeries
from estimator.physics.effects import (
    EFFECT_TYPES,
    Acceleration,
    AirDensity,
    Avionics,
    Climb,
    Effect,
    FlightState,
    Mass,
    Turn,
    Voltage,
    Wind,
    effects_from_tables,
    predict_power_w,
)
from estimator.physics.kinematics import centripetal_accel_mps2, tangential_accel_mps2
from estimator.physics.model import SEA_LEVEL_DENSITY_KGPM3
from estimator.physics.vehicle import Vehicle

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
#: Fully charged LiPo cell under light load, V: the voltage effect's reference.
FULL_CELL_V = 4.2
#: Extras of a log that are not physical channels.
_NOT_CHANNELS = ("armed",)


@dataclass(frozen=True)
class ResidualOptions:
    """Settings of the analysis (SI units); see the module docstring."""

    folds: int = 5
    #: Length of the held-out chunks (s), assigned to the folds in turn.
    chunk_s: float = 20.0
    block_s: float = 5.0
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
    #: vertical speed first falls to ``level_mps`` (m/s); the final descent from the last row
    #: at or below it is dropped too.
    settle_s: float = 5.0
    level_mps: float = 0.3
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


# -- samples ----------------------------------------------------------------------------------


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
            f"only {n_blocks} blocks of {opt.block_s:.0f} s of airborne data; need at least "
            f"{2 * opt.folds} (a few minutes of flight) for a held-out test"
        )
    return samples


_PART_KEYS = (
    *("time_s", "vn_mps", "ve_mps", "vd_mps", "an_mps2", "ae_mps2", "alt_m", "voltage_v"),
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
    last = len(rows) - 1 - int(np.argmax(level[::-1]))
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


def _gradient(x: FloatArray, t: FloatArray, seg: IntArray) -> FloatArray:
    out = np.zeros(len(x))
    for s in np.unique(seg):
        rows = seg == s
        if rows.sum() >= 2:
            out[rows] = np.gradient(x[rows], t[rows])
    return out


# -- candidates -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Candidate:
    """A candidate effect: fitted parameters x ↔ :class:`Effect`.

    ``windowed``: the effect acts in a time window ``[at_s, until_s)`` searched on the training
    data (a wind that starts or stops, a payload picked up or released, a load switched on or
    off); either end may be open (the flight's start or end).
    ``null``: x at which the effect does nothing (None when it always acts, like ``climb``).
    """

    name: str
    x0: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    build: Callable[[FloatArray, float | None, float | None], Effect]
    null: tuple[float, ...] | None = None
    windowed: bool = False
    starts: tuple[tuple[float, ...], ...] = ()

    @property
    def label(self) -> str:
        return f"{self.name} (window)" if self.windowed else self.name


def _wind(x: FloatArray, at_s: float | None, until_s: float | None) -> Effect:
    """x = air-mass velocity over ground (north, east), m/s."""
    wind = wind_from_vector(float(x[0]), float(x[1]))
    return replace(wind, at_s=at_s, until_s=until_s)


def _constant_and_windowed(candidate: Candidate) -> tuple[Candidate, Candidate]:
    """The candidate acting all flight, and the same in a time window searched in the data."""
    return candidate, replace(candidate, windowed=True)


def candidates_for(vehicle: Vehicle, samples: Samples, names: Sequence[str]) -> list[Candidate]:
    """The candidates to try: ``names`` minus effects the vehicle file already has."""
    mass_lo = max(Mass.bounds["delta_kg"][0], -0.7 * vehicle.mass_kg)
    mass_hi = Mass.bounds["delta_kg"][1]
    ref_v = vehicle.battery.cells * FULL_CELL_V
    rho_lo, rho_hi = AirDensity.bounds["rho_kgpm3"]
    avi_lo, avi_hi = Avionics.bounds["power_w"]
    turn_lo, turn_hi = Turn.bounds["power_w_per_g2"]
    wind_max = Wind.bounds["speed_mps"][1]
    all_candidates = [
        *_constant_and_windowed(
            Candidate(
                "wind",
                (0.0, 0.0),
                (-wind_max, -wind_max),
                (wind_max, wind_max),
                _wind,
                null=(0.0, 0.0),
                starts=tuple(
                    (4.0 * math.cos(a), 4.0 * math.sin(a)) for a in np.radians([0, 120, 240])
                ),
            )
        ),
        *_constant_and_windowed(
            Candidate(
                "mass",
                (0.0,),
                (mass_lo,),
                (mass_hi,),
                lambda x, at, until: Mass(float(x[0]), at, until),
                (0.0,),
            )
        ),
        Candidate(
            "air_density",
            (SEA_LEVEL_DENSITY_KGPM3,),
            (rho_lo,),
            (rho_hi,),
            lambda x, _at, _until: AirDensity(float(x[0])),
            (SEA_LEVEL_DENSITY_KGPM3,),
        ),
        Candidate("climb", (0.6,), (0.2,), (1.0,), lambda x, _at, _until: Climb(float(x[0]))),
        *_constant_and_windowed(
            Candidate(
                "avionics",
                (0.0,),
                (avi_lo,),
                (avi_hi,),
                lambda x, at, until: Avionics(float(x[0]), at, until),
                (0.0,),
            )
        ),
        Candidate(
            "voltage",
            (0.0,),
            (0.0,),
            (Voltage.bounds["resistance_ohm"][1],),
            lambda x, _at, _until: Voltage(float(x[0]), ref_v),
            (0.0,),
        ),
        Candidate(
            "acceleration",
            (0.95, 0.95),
            (0.2, 0.0),
            (1.0, 1.0),
            lambda x, _at, _until: Acceleration(float(x[0]), float(x[1])),
            (1.0, 1.0),
        ),
        Candidate(
            "turn",
            (0.0,),
            (turn_lo,),
            (turn_hi,),
            lambda x, _at, _until: Turn(float(x[0])),
            (0.0,),
        ),
    ]
    declared = set(vehicle.effects)
    # a window is on each flight's own clock: shared by several flights it would mean "every
    # flight changed at the same time"; several flights are analysed per flight (--flight)
    one_flight = len(samples.flight_ids) == 1
    out = []
    for cand in all_candidates:
        if cand.name not in names or cand.name in declared or (cand.windowed and not one_flight):
            continue
        if cand.name == "voltage" and not samples.has_voltage:
            continue
        out.append(cand)
    return out


# -- fitting ----------------------------------------------------------------------------------


@dataclass
class Term:
    """A candidate with fitted parameters (and, when windowed, its time window, s)."""

    candidate: Candidate
    x: FloatArray
    at_s: float | None = None
    until_s: float | None = None

    def effect(self) -> Effect:
        return self.candidate.build(self.x, self.at_s, self.until_s)


class _Problem:
    """Predictions for a set of rows with the vehicle's model and base effects.

    ``first_s``/``last_s``: the flight clock's first and last airborne time over all samples
    (a window reaching them is open on that side).
    """

    def __init__(self, vehicle: Vehicle, samples: Samples, rows: NDArray[np.bool_]) -> None:
        self.vehicle = vehicle
        self.state = samples.state_at(rows)
        self.power_w = samples.power_w[rows]
        self.base = effects_from_tables(vehicle.effects)
        self.first_s = float(samples.state.time_s.min())
        self.last_s = float(samples.state.time_s.max())

    def predict(self, effects: Sequence[Effect]) -> FloatArray:
        return predict_power_w(
            self.vehicle.model, self.vehicle.mass_kg, self.state, [*self.base, *effects]
        )


def _fit_terms(
    problem: _Problem,
    terms: list[Term],
    f_scale_w: float,
    warm: frozenset[int] = frozenset(),
    fixed: Sequence[Effect] = (),
) -> list[Term]:
    """Joint least squares of all terms' x (windows held) on top of the ``fixed`` effects;
    multi-start where given, except for terms whose index is in ``warm`` (their x is already
    a good start)."""
    if not terms:
        return terms
    sizes = [len(t.x) for t in terms]
    lower = np.concatenate([t.candidate.lower for t in terms])
    upper = np.concatenate([t.candidate.upper for t in terms])

    def unpack(x: FloatArray) -> list[Term]:
        out, k = [], 0
        for term, n in zip(terms, sizes, strict=True):
            out.append(Term(term.candidate, x[k : k + n].copy(), term.at_s, term.until_s))
            k += n
        return out

    def resid(x: FloatArray) -> FloatArray:
        return problem.predict([*fixed, *(t.effect() for t in unpack(x))]) - problem.power_w

    starts = [np.concatenate([t.x for t in terms])]
    for i, term in enumerate(terms):
        if i in warm:
            continue
        for s in term.candidate.starts:
            x = starts[0].copy()
            k = sum(sizes[:i])
            x[k : k + sizes[i]] = s
            starts.append(x)
    best = None
    for x0 in starts:
        # strictly inside the bounds: least_squares stalls when started on one
        x0 = np.clip(x0, lower + 1e-3 * (upper - lower), upper - 1e-3 * (upper - lower))
        sol = least_squares(
            resid, x0, bounds=(lower, upper), loss="soft_l1", f_scale=f_scale_w, x_scale="jac"
        )
        if best is None or sol.cost < best.cost:
            best = sol
    assert best is not None
    return unpack(best.x)


def best_window(time_s: FloatArray, gain: FloatArray) -> tuple[int, int, float]:
    """The time window where an effect helps most: first and last index (into the rows sorted
    by time) and the summed ``gain`` (per-row loss without the effect minus with it) of the
    contiguous run with the largest sum. Prefix sums: O(n log n) for the sort, O(n) after."""
    order = np.argsort(time_s, kind="stable")
    prefix = np.concatenate([[0.0], np.cumsum(gain[order])])
    low = np.minimum.accumulate(prefix[:-1])
    sums = prefix[1:] - low
    last = int(np.argmax(sums))
    first = int(np.argmin(prefix[: last + 1]))
    return first, last, float(sums[last])


#: Window ends this close (s) to the flight's first/last airborne sample are open.
_OPEN_END_S = 10.0


def _search_window(
    problem: _Problem, others: list[Term], term: Term, f_scale_w: float, warm: bool
) -> Term:
    """Fit ``term``'s parameters and time window on top of ``others``.

    Starts: the parameters fitted over the whole flight, and over its first and second half
    (an effect present in one half only, or a different one in each, as a wind that turns).
    From each, alternately the window with the largest robust gain for these parameters
    (:func:`best_window`, linear in the samples) and the parameters for that window; the
    start with the lowest robust loss wins.
    """
    fixed = [t.effect() for t in others]
    loss_cap = (3.0 * f_scale_w) ** 2
    loss_without = np.minimum((problem.power_w - problem.predict(fixed)) ** 2, loss_cap)
    t = problem.state.time_s
    ts = np.sort(t)
    middle = float(np.median(ts))
    first_fit = frozenset({0} if warm else ())
    best: tuple[float, Term] | None = None
    starts: list[tuple[float | None, float | None]] = [(None, None), (None, middle), (middle, None)]
    for window in starts:
        start = Term(term.candidate, term.x, *window)
        current = _fit_terms(problem, [start], f_scale_w, first_fit, fixed)[0]
        found: tuple[float | None, float | None] | None = None
        for _ in range(4):
            always = Term(current.candidate, current.x)
            loss_with = np.minimum(
                (problem.power_w - problem.predict([*fixed, always.effect()])) ** 2, loss_cap
            )
            lo, hi, _gain = best_window(t, loss_without - loss_with)
            window = (
                None
                if lo == 0 or ts[lo] - problem.first_s < _OPEN_END_S
                # any time between two training rows splits them alike (a held-out gap)
                else 0.5 * float(ts[lo - 1] + ts[lo]),
                None
                if hi == len(ts) - 1 or problem.last_s - ts[hi] < _OPEN_END_S
                else 0.5 * float(ts[hi] + ts[hi + 1]),
            )
            if window == found:
                break
            found = window
            current = Term(current.candidate, current.x, *window)
            current = _fit_terms(problem, [current], f_scale_w, frozenset({0}), fixed)[0]
        loss = float(
            np.sum(
                np.minimum(
                    (problem.power_w - problem.predict([*fixed, current.effect()])) ** 2,
                    loss_cap,
                )
            )
        )
        if best is None or loss < best[0]:
            best = (loss, current)
    assert best is not None
    return best[1]


def fit_design(
    problem: _Problem,
    candidates: Sequence[Candidate],
    f_scale_w: float,
    warm: Sequence[FloatArray | None] = (),
) -> list[Term]:
    """Fit ``candidates`` together: constant ones first, then each window, then all.

    ``warm``: starting x per candidate position (e.g. from the previous selection step).
    """
    warm = [*warm, *([None] * (len(candidates) - len(warm)))]
    terms = [
        Term(c, np.asarray(c.x0 if w is None else w, dtype=float))
        for c, w in zip(candidates, warm, strict=True)
    ]
    known = frozenset(i for i, w in enumerate(warm) if w is not None)
    steady = [i for i, t in enumerate(terms) if not t.candidate.windowed]
    fitted = _fit_terms(
        problem,
        [terms[i] for i in steady],
        f_scale_w,
        frozenset(k for k, i in enumerate(steady) if i in known),
    )
    for i, term in zip(steady, fitted, strict=True):
        terms[i] = term
    resolved = list(steady)
    for i, term in enumerate(terms):
        if term.candidate.windowed:
            others = [terms[k] for k in resolved]
            terms[i] = _search_window(problem, others, term, f_scale_w, i in known)
            resolved.append(i)
    return _fit_terms(problem, terms, f_scale_w, frozenset(range(len(terms))))


# -- selection --------------------------------------------------------------------------------


@dataclass
class CandidateScore:
    """One candidate tried at one selection step (held-out figures)."""

    step: int
    label: str
    rmse_w: float
    gain_fraction: float
    z: float
    qualifies: bool
    params: dict[str, Any]


@dataclass
class Selected:
    """An effect chosen by the selection: final parameters (all data) and held-out RMSE after."""

    name: str
    effect: Effect
    rmse_after_w: float
    z: float
    params_fold_sd: dict[str, float]
    #: Qualifying candidates as good on held-out data (label, RMSE W, z of chosen vs it).
    ties: list[tuple[str, float, float]] = field(default_factory=list)
    #: The best other candidate of that step (label, RMSE W, z of chosen vs it), if any.
    runner_up: tuple[str, float, float] | None = None
    #: The candidate's label ("mass (window)" for one in a time window).
    label: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "label": self.label or self.name,
            "description": describe(self.effect),
            "params": _round_params(self.effect.params),
            "rmse_after_w": round(self.rmse_after_w, 3),
            "z": round(self.z, 2),
            "params_fold_sd": {k: round(v, 4) for k, v in self.params_fold_sd.items()},
            "indistinguishable_from": [
                {"candidate": label, "rmse_w": round(r, 3), "z": round(z, 2)}
                for label, r, z in self.ties
            ],
            "runner_up": None
            if self.runner_up is None
            else {
                "candidate": self.runner_up[0],
                "rmse_w": round(self.runner_up[1], 3),
                "z": round(self.runner_up[2], 2),
            },
        }


@dataclass
class ChannelScore:
    channel: str
    r2: float


@dataclass
class ResidualResult:
    """Everything the command prints, writes and plots."""

    samples: Samples
    options: ResidualOptions
    predicted_before_w: FloatArray
    predicted_after_w: FloatArray
    selected: list[Selected]
    table: list[CandidateScore]
    attribution: list[ChannelScore]
    attribution_before: list[ChannelScore]
    noise_floor_w: float
    #: The final effects (fitted on all samples) at every sample: the in-sample fit, W.
    predicted_final_w: FloatArray | None = None

    @property
    def effects(self) -> list[Effect]:
        return [s.effect for s in self.selected]

    def residual_before_w(self) -> FloatArray:
        return self.samples.power_w - self.predicted_before_w

    def residual_after_w(self) -> FloatArray:
        return self.samples.power_w - self.predicted_after_w

    def rmse_w(self, after: bool) -> float:
        r = self.residual_after_w() if after else self.residual_before_w()
        return float(np.sqrt(np.mean(r**2)))

    def mape_pct(self, after: bool) -> float:
        r = self.residual_after_w() if after else self.residual_before_w()
        return float(np.mean(np.abs(r) / np.abs(self.samples.power_w)) * 100.0)

    def rmse_in_sample_w(self) -> float:
        """RMSE of the final effects (fitted on all samples, change times included), W: what
        the held-out RMSE cannot reach when a change falls inside a held-out chunk."""
        final = self.predicted_after_w if self.predicted_final_w is None else self.predicted_final_w
        return float(np.sqrt(np.mean((self.samples.power_w - final) ** 2)))

    def rmse_to_floor(self) -> float:
        """Held-out RMSE after selection over the noise floor (1 = white noise only)."""
        floor = self.noise_floor_w
        return self.rmse_w(True) / floor if floor > 0 else math.inf

    def unexplained_share(self) -> float:
        """Share of the remaining residual's variance above the white noise floor (0..1):
        structure the selected effects do not explain."""
        rmse = self.rmse_w(True)
        return max(0.0, 1.0 - (self.noise_floor_w / rmse) ** 2) if rmse > 0 else 0.0

    def verdict(self) -> str:
        """One sentence: what was added and what is left. Never "noise" when the residual's
        RMSE is more than ``noise_ratio`` noise floors."""
        best = self.attribution[0] if self.attribution else None
        channel = None if best is None else f"{best.channel} (held-out R² {best.r2:.2f})"
        predictive = best is not None and best.r2 >= self.options.min_r2
        ratio = self.rmse_to_floor()
        level = (
            f"held-out RMSE {self.rmse_w(True):.1f} W is {ratio:.1f}× the noise floor "
            f"{self.noise_floor_w:.1f} W"
        )
        added = "; ".join(
            describe(s.effect)
            + (f" (as good held out: {', '.join(t[0] for t in s.ties)})" if s.ties else "")
            for s in self.selected
        )
        head = (
            f"added {added}" if self.selected else "no candidate effect improves the held-out error"
        )
        if ratio > self.options.noise_ratio:
            where = (
                f"the channel that best predicts it is {channel}"
                if predictive
                else f"no channel predicts it well (best: {channel or 'none'})"
            )
            return (
                f"{head}; the remaining residual is not noise: {level}, "
                f"{100 * self.unexplained_share():.0f} % of its variance is unexplained "
                f"structure; {where}"
            )
        if predictive:
            return f"{head}; {level}; the remaining residual is best predicted by {channel}"
        if not self.selected:
            return f"{head} and no channel predicts the residual ({level}): it looks like noise"
        return f"{head}; {level}: the remaining residual is at the noise level"

    def summary(self) -> dict[str, Any]:
        """The JSON object of ``uav-energy residuals --json``."""
        return {
            "rmse_before_w": round(self.rmse_w(False), 3),
            "rmse_after_w": round(self.rmse_w(True), 3),
            "mape_before_pct": round(self.mape_pct(False), 3),
            "mape_after_pct": round(self.mape_pct(True), 3),
            "effects": [s.as_dict() for s in self.selected],
            "attribution": {
                "verdict": self.verdict(),
                "best_channel": self.attribution[0].channel if self.attribution else None,
                "channels": [
                    {"channel": c.channel, "r2": round(c.r2, 4)} for c in self.attribution
                ],
                "channels_before": [
                    {"channel": c.channel, "r2": round(c.r2, 4)} for c in self.attribution_before
                ],
            },
            "selection": [
                {
                    "step": c.step,
                    "candidate": c.label,
                    "rmse_w": round(c.rmse_w, 3),
                    "gain_pct": round(100.0 * c.gain_fraction, 2),
                    "z": round(c.z, 2),
                    "qualifies": c.qualifies,
                    "params": _round_params(c.params),
                }
                for c in self.table
            ],
            "n_samples": len(self.samples),
            "n_flights": len(self.samples.flight_ids),
            "flights": self.samples.flight_ids,
            "skipped_flights": self.samples.skipped_flights,
            "split": f"chunks of {self.options.chunk_s:g} s assigned to {self.options.folds} "
            f"folds in turn, guard {self.options.guard_s:g} s",
            "test": f"Wilcoxon signed-rank over {len(np.unique(self.samples.block))} blocks of "
            f"{self.options.block_s:g} s, z > {self.options.z_threshold:g} and RMSE gain ≥ "
            f"{100 * self.options.min_gain_fraction:g} %",
            "noise_floor_w": round(self.noise_floor_w, 3),
            "rmse_to_floor": round(self.rmse_to_floor(), 2),
            "rmse_in_sample_w": round(self.rmse_in_sample_w(), 3),
            "unexplained_share": round(self.unexplained_share(), 3),
        }


def _when(at_s: float | None, until_s: float | None) -> str:
    if at_s is None and until_s is None:
        return "all flight"
    if at_s is None:
        return f"from the start until {until_s:.0f} s"
    if until_s is None:
        return f"from {at_s:.0f} s on"
    return f"from {at_s:.0f} s until {until_s:.0f} s"


def describe(effect: Effect) -> str:
    """The effect in words with units, e.g. "wind 6.0 m/s from 61°, from 150 s on"."""
    p = effect.params
    if isinstance(effect, Wind):
        what = f"wind {effect.speed_mps:.1f} m/s from {effect.from_deg:.0f}°"
    elif isinstance(effect, Mass):
        what = f"mass {effect.delta_kg:+.2f} kg"
    elif isinstance(effect, Avionics):
        what = f"load {effect.power_w:+.1f} W"
    else:
        what = effect.name + " " + ", ".join(f"{k} {v:.4g}" for k, v in p.items())
    if "at_s" in p:
        return f"{what}, {_when(p['at_s'], p.get('until_s'))}"
    return what


def _round_params(params: dict[str, Any]) -> dict[str, Any]:
    return {k: (None if v is None else round(float(v), 4)) for k, v in params.items()}


def _robust_scale_w(r: FloatArray) -> float:
    """Soft-L1 scale: 3 robust σ (MAD) of the residual, at least 1 W."""
    mad = float(np.median(np.abs(r - np.median(r))))
    return max(3.0 * 1.4826 * mad, 1.0)


def _held_out(
    vehicle: Vehicle,
    samples: Samples,
    candidates: Sequence[Candidate],
    opt: ResidualOptions,
    f_scale_w: float,
    warm: Sequence[FloatArray | None],
) -> tuple[FloatArray, list[list[Term]]]:
    """Held-out predictions of the design ``candidates`` and the terms fitted in each fold."""
    predicted = np.empty(len(samples))
    per_fold = []
    for j in range(opt.folds):
        test = samples.fold == j
        if not test.any():
            continue
        train = samples.train_rows(j, opt.guard_s)
        terms = fit_design(_Problem(vehicle, samples, train), candidates, f_scale_w, warm)
        predicted[test] = _Problem(vehicle, samples, test).predict([t.effect() for t in terms])
        per_fold.append(terms)
    return predicted, per_fold


def _block_gain_z(samples: Samples, err_old: FloatArray, err_new: FloatArray) -> float:
    """Wilcoxon signed-rank statistic (normal approximation, as a z) of the per-block gains
    in held-out squared error: positive when the new errors are smaller. A rank test, not the
    mean over its standard error: block gains are heavy-tailed (a few manoeuvre blocks
    dominate the spread), which would hide an effect that helps nearly every block."""
    gain = np.bincount(samples.block, weights=err_old**2 - err_new**2)
    counts = np.bincount(samples.block)
    gain = gain[(counts > 0) & (gain != 0.0)]
    n = len(gain)
    if n < 2:
        return 0.0
    ranks = rankdata(np.abs(gain))
    w_plus = float(ranks[gain > 0].sum())
    mean = n * (n + 1) / 4.0
    _, tie_counts = np.unique(ranks, return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24.0 - float(np.sum(tie_counts**3 - tie_counts)) / 48.0
    return (w_plus - mean) / math.sqrt(var) if var > 0 else 0.0


def analyze(
    flights: Sequence[FlightSeries],
    vehicle: Vehicle,
    options: ResidualOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> ResidualResult:
    """Residual analysis of ``flights`` against ``vehicle`` (see the module docstring)."""
    opt = options or ResidualOptions()
    if opt.folds < 2:
        raise UserError("need at least 2 folds for held-out scoring")
    if not opt.chunk_s > 2 * opt.guard_s:
        raise UserError(
            "held-out chunks must be longer than two guards (--chunk-s > 2 × --guard-s)"
        )
    samples = prepare(flights, opt)
    everything = np.ones(len(samples), dtype=bool)
    before = _Problem(vehicle, samples, everything).predict([])
    f_scale_w = _robust_scale_w(samples.power_w - before)
    remaining = candidates_for(vehicle, samples, opt.candidates)
    chosen: list[Candidate] = []
    warm: list[FloatArray | None] = []
    current = before
    selected: list[Selected] = []
    table: list[CandidateScore] = []
    step = 0
    while remaining:
        step += 1
        rmse_now = float(np.sqrt(np.mean((samples.power_w - current) ** 2)))
        trials = []
        for k, cand in enumerate(remaining):
            if progress is not None:
                progress(f"step {step}: {cand.label} ({k + 1}/{len(remaining)})")
            predicted, folds = _held_out(vehicle, samples, [*chosen, cand], opt, f_scale_w, warm)
            rmse = float(np.sqrt(np.mean((samples.power_w - predicted) ** 2)))
            gain = 1.0 - rmse / rmse_now if rmse_now > 0 else 0.0
            z = _block_gain_z(samples, samples.power_w - current, samples.power_w - predicted)
            ok = z > opt.z_threshold and gain >= opt.min_gain_fraction
            median_params = folds[len(folds) // 2][-1].effect().params
            table.append(CandidateScore(step, cand.label, rmse, gain, z, ok, median_params))
            trials.append((rmse, z, ok, cand, predicted, folds))
        good = [t for t in trials if t[2]]
        if not good:
            break
        rmse, z, _, cand, predicted, folds = _pick(samples, good, opt)
        # the other candidates of this step, best first (z: chosen vs it); qualifying ones
        # the held-out data cannot tell from the chosen one are ties
        others = [t for t in sorted(trials, key=lambda t: t[0]) if t[3] is not cand]
        rivals = [
            (
                t[3].label,
                t[0],
                _block_gain_z(samples, samples.power_w - t[4], samples.power_w - predicted),
            )
            for t in others
        ]
        ties = [
            rival
            for rival, t in zip(rivals, others, strict=True)
            if t[2] and rival[2] < opt.z_threshold
        ]
        chosen.append(cand)
        current = predicted
        final = fit_design(_Problem(vehicle, samples, everything), chosen, f_scale_w, warm)
        warm = [t.x for t in final]
        fold_effects = [terms[-1].effect() for terms in folds]
        selected.append(
            Selected(
                cand.name,
                final[-1].effect(),
                rmse,
                z,
                _fold_sd(fold_effects, final[-1]),
                ties,
                rivals[0] if rivals else None,
                cand.label,
            )
        )
        # earlier effects are refitted jointly with the new one
        for i, term in enumerate(final[:-1]):
            selected[i].effect = term.effect()
        # a windowed effect may come again (a wind that turns, a second payload): only its
        # all-flight form leaves; an all-flight effect is final
        remaining = [
            c
            for c in remaining
            if c.name != cand.name
            or (cand.windowed and c.windowed and len(chosen) < opt.max_effects)
        ]
    if progress is not None:
        progress("attribution")
    after_resid = samples.power_w - current
    attribution = attribute(samples, after_resid, opt)
    attribution_before = attribute(samples, samples.power_w - before, opt)
    return ResidualResult(
        samples=samples,
        options=opt,
        predicted_before_w=before,
        predicted_after_w=current,
        selected=selected,
        table=table,
        attribution=attribution,
        attribution_before=attribution_before,
        noise_floor_w=_noise_floor_w(samples, after_resid),
        predicted_final_w=_Problem(vehicle, samples, everything).predict(
            [s.effect for s in selected]
        ),
    )


def _pick(samples: Samples, good: list[Any], opt: ResidualOptions) -> Any:
    """The qualifying trial (rmse, z, ok, candidate, predicted, folds) with the lowest held-out
    RMSE; but a constant load above ``max_load_w`` that held-out data cannot tell from a mass
    (a payload draws power in every flight state alike when current is linear in thrust) is
    named as that mass: loads that large are payloads, not electronics."""
    best = min(good, key=lambda t: t[0])
    cand, folds = best[3], best[5]
    if cand.name != "avionics":
        return best
    load_w = float(np.median([terms[-1].x[0] for terms in folds]))
    if abs(load_w) <= opt.max_load_w:
        return best
    for trial in good:
        same_kind = trial[3].name == "mass" and trial[3].windowed == cand.windowed
        if same_kind:
            z = _block_gain_z(samples, samples.power_w - trial[4], samples.power_w - best[4])
            if z < opt.z_threshold:
                return trial
    return best


def _fold_sd(fold_effects: list[Effect], final: Term) -> dict[str, float]:
    """Spread (1σ) of each numeric parameter over the folds (angles wrapped to the final)."""
    out: dict[str, float] = {}
    ref = final.effect().params
    for key, value in ref.items():
        values = [e.params[key] for e in fold_effects]
        if value is None or any(v is None for v in values):
            continue
        diffs = np.asarray(values, dtype=float) - float(value)
        if key.endswith("_deg"):
            diffs = (diffs + 180.0) % 360.0 - 180.0
        out[key] = float(np.sqrt(np.mean(diffs**2)))
    return out


def _noise_floor_w(samples: Samples, resid: FloatArray) -> float:
    """Sample-to-sample noise of the residual, W: RMS of successive differences / √2.

    What no smooth effect can explain (white measurement noise); slow structure cancels.
    """
    same = samples.flight[1:] == samples.flight[:-1]
    d = np.diff(resid)[same]
    return float(np.sqrt(np.mean(d**2) / 2.0)) if len(d) else math.nan


# -- attribution ------------------------------------------------------------------------------


def _features(values: FloatArray, circular: bool) -> FloatArray:
    if circular:
        rad = np.radians(values)
        return np.column_stack([np.cos(rad), np.sin(rad)])
    sd = float(np.nanstd(values)) or 1.0
    return (values / sd).reshape(-1, 1)


_MAX_DISCRETE_VALUES = 16


def _group_means(x_train: FloatArray, y_train: FloatArray, x_test: FloatArray) -> FloatArray:
    """Mean of ``y_train`` per distinct ``x_train`` value, at ``x_test`` (NaN if unseen)."""
    keys, inverse = np.unique(x_train, return_inverse=True)
    means = np.bincount(inverse, weights=y_train) / np.bincount(inverse)
    idx = np.clip(np.searchsorted(keys, x_test), 0, len(keys) - 1)
    return np.where(keys[idx] == x_test, means[idx], np.nan)


def attribute(samples: Samples, resid: FloatArray, opt: ResidualOptions) -> list[ChannelScore]:
    """Held-out R² of ``resid`` predicted from each channel alone, best first: k-NN
    regression (sklearn), or the mean per value for channels with few distinct values."""
    scores = []
    for name, values in samples.channels.items():
        finite = np.isfinite(values)
        x = _features(np.where(finite, values, 0.0), name.endswith("_deg"))
        # a few distinct values (payload, flight regime): k-NN would break the many exact
        # ties by sample order; the mean residual per value is the nonparametric answer
        discrete = len(np.unique(values[finite])) <= _MAX_DISCRETE_VALUES
        predicted = np.full(len(resid), np.nan)
        baseline = np.full(len(resid), np.nan)
        for j in range(opt.folds):
            test = (samples.fold == j) & finite
            train = samples.train_rows(j, opt.guard_s) & finite
            if test.sum() == 0 or train.sum() < 20:
                continue
            baseline[test] = float(np.mean(resid[train]))
            if discrete:
                predicted[test] = _group_means(values[train], resid[train], values[test])
                predicted[test] = np.where(
                    np.isnan(predicted[test]), baseline[test], predicted[test]
                )
                continue
            k = int(np.clip(round(math.sqrt(train.sum())), 10, 200))
            k = min(k, int(train.sum()))
            knn = KNeighborsRegressor(n_neighbors=k).fit(x[train], resid[train])
            predicted[test] = knn.predict(x[test])
        ok = np.isfinite(predicted)
        if ok.sum() < 20:
            continue
        sse = float(np.sum((resid[ok] - predicted[ok]) ** 2))
        sst = float(np.sum((resid[ok] - baseline[ok]) ** 2))
        scores.append(ChannelScore(name, 1.0 - sse / sst if sst > 0 else 0.0))
    return sorted(scores, key=lambda c: -c.r2)
