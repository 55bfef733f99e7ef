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
2. **Held-out split**: each flight is cut into ``folds`` contiguous time chunks; fold j holds
   out chunk j of every flight and trains on the rest minus a guard of ``guard_s`` seconds on
   both sides of the held-out chunk (correlated noise must not leak). Never random samples.
3. **Candidates**: one :class:`Candidate` per effect of :mod:`estimator.physics.effects` not
already in
   the vehicle file, each with one or two parameters fitted by ``scipy.optimize.least_squares``
   (soft-L1 loss, bounds from the effect's ``bounds``). ``mass`` and ``avionics`` come twice:
   constant (``at_s`` null) and stepped, the step time searched on the training data by a
   linearised scan over the sample times, then all parameters refitted together.
4. **Greedy forward selection**: at each step every remaining candidate is added to the
   selected set and scored by its held-out predictions. The held-out squared errors of the
   current and the extended model are summed per evaluation block of ``block_s`` seconds and
   compared pairwise over the blocks (a Diebold–Mariano test: mean block gain over its standard
   error; 5 s blocks are several times the 1–2 s correlation time of telemetry noise, so block
   gains are nearly independent, and short enough that an effect seen only in turns or in
   accelerations still spans many blocks). A candidate qualifies when
   z > ``z_threshold`` (3: one-sided p ≈ 0.001, ≈ 1 % family-wise over the candidates) *and*
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
    block_s: float = 5.0
    guard_s: float = 5.0
    z_threshold: float = 3.0
    min_gain_fraction: float = 0.01
    smooth_s: float = 0.5
    min_alt_m: float = 1.0
    min_power_w: float = 1.0
    #: Rows below this fraction of the flight's median power are not airborne (touch-down).
    min_power_fraction: float = 0.25
    max_gap_s: float = 2.0
    min_flight_s: float = 30.0
    candidates: tuple[str, ...] = tuple(EFFECT_TYPES)
    #: Channels with a held-out R² below this do not count as predicting the residual.
    min_r2: float = 0.05


# -- samples ----------------------------------------------------------------------------------


@dataclass
class Samples:
    """Airborne rows of all flights, concatenated (NED frame, flight clock per flight).

    ``fold``: held-out chunk of each row; ``block``: evaluation block id (unique over flights);
    ``channels``: per-row telemetry for structure plots and attribution (``*_deg`` circular).
    """

    flight_ids: list[str]
    flight: IntArray
    state: FlightState
    power_w: FloatArray
    fold: IntArray
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
        """Rows outside held-out chunk ``fold`` and further than ``guard_s`` from it."""
        t = self.state.time_s
        train = self.fold != fold
        for f in np.unique(self.flight):
            held = (self.flight == f) & (self.fold == fold)
            if not held.any():
                continue
            lo, hi = t[held].min() - guard_s, t[held].max() + guard_s
            train &= ~((self.flight == f) & (t >= lo) & (t <= hi))
        return train

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
    for flight in flights:
        part = _flight_rows(flight, opt)
        if part is None:
            skipped.append(flight.flight_id)
            continue
        part["flight"] = np.full(len(part["time_s"]), float(len(ids)))
        part["block"] = part["block"] + block_base
        block_base = int(part["block"].max()) + 1
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
    *("power_w", "energy_used_wh", "fold", "block", "flight"),
)


def _informative(x: FloatArray) -> bool:
    finite = x[np.isfinite(x)]
    return len(finite) > 0.5 * len(x) and float(np.ptp(finite)) > 0


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
    rows = np.flatnonzero(ok)
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
    span = t[-1] - t[0]
    fold = np.minimum(((t - t[0]) / span * opt.folds).astype(int), opt.folds - 1)
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
        "fold": fold.astype(float),
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

    ``stepped``: the effect applies from a step time ``at_s`` searched on the training data.
    ``null``: x at which the effect does nothing (None when it always acts, like ``climb``).
    """

    name: str
    x0: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    build: Callable[[FloatArray, float | None], Effect]
    null: tuple[float, ...] | None = None
    stepped: bool = False
    starts: tuple[tuple[float, ...], ...] = ()

    @property
    def label(self) -> str:
        return f"{self.name} (step)" if self.stepped else self.name


def _wind(x: FloatArray, _at: float | None) -> Effect:
    """x = air-mass velocity over ground (north, east), m/s."""
    return wind_from_vector(float(x[0]), float(x[1]))


def _constant_and_stepped(candidate: Candidate) -> tuple[Candidate, Candidate]:
    """The candidate acting all flight, and the same from a step time searched in the data."""
    return candidate, replace(candidate, stepped=True)


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
        Candidate(
            "wind",
            (0.0, 0.0),
            (-wind_max, -wind_max),
            (wind_max, wind_max),
            _wind,
            null=(0.0, 0.0),
            starts=tuple((4.0 * math.cos(a), 4.0 * math.sin(a)) for a in np.radians([0, 120, 240])),
        ),
        *_constant_and_stepped(
            Candidate(
                "mass", (0.0,), (mass_lo,), (mass_hi,), lambda x, at: Mass(float(x[0]), at), (0.0,)
            )
        ),
        Candidate(
            "air_density",
            (SEA_LEVEL_DENSITY_KGPM3,),
            (rho_lo,),
            (rho_hi,),
            lambda x, _at: AirDensity(float(x[0])),
            (SEA_LEVEL_DENSITY_KGPM3,),
        ),
        Candidate("climb", (0.6,), (0.2,), (1.0,), lambda x, _at: Climb(float(x[0]))),
        *_constant_and_stepped(
            Candidate(
                "avionics",
                (0.0,),
                (avi_lo,),
                (avi_hi,),
                lambda x, at: Avionics(float(x[0]), at),
                (0.0,),
            )
        ),
        Candidate(
            "voltage",
            (0.0,),
            (0.0,),
            (Voltage.bounds["resistance_ohm"][1],),
            lambda x, _at: Voltage(float(x[0]), ref_v),
            (0.0,),
        ),
        Candidate(
            "acceleration",
            (0.95, 0.95),
            (0.2, 0.0),
            (1.0, 1.0),
            lambda x, _at: Acceleration(float(x[0]), float(x[1])),
            (1.0, 1.0),
        ),
        Candidate("turn", (0.0,), (turn_lo,), (turn_hi,), lambda x, _at: Turn(float(x[0])), (0.0,)),
    ]
    declared = set(vehicle.effects)
    out = []
    for cand in all_candidates:
        if cand.name not in names or cand.name in declared:
            continue
        if cand.name == "voltage" and not samples.has_voltage:
            continue
        out.append(cand)
    return out


# -- fitting ----------------------------------------------------------------------------------


@dataclass
class Term:
    """A candidate with fitted parameters (and step time)."""

    candidate: Candidate
    x: FloatArray
    at_s: float | None = None

    def effect(self) -> Effect:
        return self.candidate.build(self.x, self.at_s)


class _Problem:
    """Predictions for a set of rows with the vehicle's model and base effects."""

    def __init__(self, vehicle: Vehicle, samples: Samples, rows: NDArray[np.bool_]) -> None:
        self.vehicle = vehicle
        self.state = samples.state_at(rows)
        self.power_w = samples.power_w[rows]
        self.base = effects_from_tables(vehicle.effects)

    def predict(self, effects: Sequence[Effect]) -> FloatArray:
        return predict_power_w(
            self.vehicle.model, self.vehicle.mass_kg, self.state, [*self.base, *effects]
        )


def _fit_terms(
    problem: _Problem, terms: list[Term], f_scale_w: float, warm: frozenset[str] = frozenset()
) -> list[Term]:
    """Joint least squares of all terms' x (step times held); multi-start where given,
    except for terms whose label is in ``warm`` (their x is already a good start)."""
    if not terms:
        return terms
    sizes = [len(t.x) for t in terms]
    lower = np.concatenate([t.candidate.lower for t in terms])
    upper = np.concatenate([t.candidate.upper for t in terms])

    def unpack(x: FloatArray) -> list[Term]:
        out, k = [], 0
        for term, n in zip(terms, sizes, strict=True):
            out.append(Term(term.candidate, x[k : k + n].copy(), term.at_s))
            k += n
        return out

    def resid(x: FloatArray) -> FloatArray:
        return problem.predict([t.effect() for t in unpack(x)]) - problem.power_w

    starts = [np.concatenate([t.x for t in terms])]
    for i, term in enumerate(terms):
        if term.candidate.label in warm:
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


def _search_step(
    problem: _Problem, others: list[Term], term: Term, f_scale_w: float
) -> float | None:
    """Step time minimising the linearised squared error of ``term`` on top of ``others``."""
    cand = term.candidate
    assert cand.null is not None
    effects = [t.effect() for t in others]
    base = problem.predict(effects)
    r = problem.power_w - base
    null = np.asarray(cand.null, dtype=float)
    span = np.asarray(cand.upper) - np.asarray(cand.lower)
    jac = []
    for k in range(len(null)):
        h = np.zeros(len(null))
        h[k] = 0.05 * span[k]
        jac.append((problem.predict([*effects, cand.build(null + h, None)]) - base) / h[k])
    j = np.column_stack(jac)
    # robust: do not let outliers pick the step
    clip = 3.0 * f_scale_w
    r = np.clip(r, -clip, clip)
    t = problem.state.time_s
    order = np.argsort(t, kind="stable")
    ts = t[order]
    n = len(ts)
    if n < 20:
        return None
    lo, hi = int(0.05 * n), int(0.95 * n)

    def gain(at: float) -> float:
        after = t >= at
        ja, ra = j[after], r[after]
        gram = ja.T @ ja
        if np.linalg.det(gram) <= 1e-12:
            return -np.inf
        delta = np.linalg.solve(gram, ja.T @ ra)
        return float(ra @ ja @ delta)

    coarse = np.unique(ts[np.linspace(lo, hi, 60).astype(int)])
    gains = np.array([gain(a) for a in coarse])
    i = int(np.argmax(gains))
    a_lo = coarse[max(i - 1, 0)]
    a_hi = coarse[min(i + 1, len(coarse) - 1)]
    fine = np.unique(ts[(ts >= a_lo) & (ts <= a_hi)])
    k = int(np.argmax([gain(a) for a in fine]))
    # any time between the previous sample and the chosen one splits the data alike (a
    # held-out gap, for one): take the middle
    before = ts[ts < fine[k]]
    return float(fine[k] if len(before) == 0 else 0.5 * (before[-1] + fine[k]))


def fit_design(
    problem: _Problem,
    candidates: Sequence[Candidate],
    f_scale_w: float,
    warm: dict[str, FloatArray] | None = None,
) -> list[Term]:
    """Fit ``candidates`` together: continuous ones first, then each step time, then all.

    ``warm``: starting x by candidate label (e.g. from the previous selection step).
    """
    warm = warm or {}
    terms = [Term(c, np.asarray(warm.get(c.label, c.x0), dtype=float)) for c in candidates]
    known = frozenset(warm)
    steady = [i for i, t in enumerate(terms) if not t.candidate.stepped]
    fitted = _fit_terms(problem, [terms[i] for i in steady], f_scale_w, known)
    for i, term in zip(steady, fitted, strict=True):
        terms[i] = term
    resolved = list(steady)
    for i, term in enumerate(terms):
        if term.candidate.stepped:
            others = [terms[k] for k in resolved]
            term.at_s = _search_step(problem, others, term, f_scale_w)
            resolved.append(i)
    return _fit_terms(problem, terms, f_scale_w, known)


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

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
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

    def verdict(self) -> str:
        best = self.attribution[0] if self.attribution else None
        where = (
            f"{best.channel} (held-out R² {best.r2:.2f})"
            if best is not None and best.r2 >= self.options.min_r2
            else None
        )
        if not self.selected:
            if where is None:
                return (
                    "no candidate effect improves the held-out error and no channel predicts "
                    "the residual: it looks like noise"
                )
            return (
                "no candidate effect explains the residual; the telemetry channel that best "
                f"predicts it is {where}"
            )
        names = ", ".join(
            s.name + (f" (as good held out: {', '.join(t[0] for t in s.ties)})" if s.ties else "")
            for s in self.selected
        )
        if where is None:
            return f"added {names}; the remaining residual is not predicted by any channel"
        return f"added {names}; the remaining residual is best predicted by {where}"

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
            "split": f"{self.options.folds} contiguous time chunks per flight, "
            f"guard {self.options.guard_s:g} s",
            "test": f"Diebold-Mariano over {len(np.unique(self.samples.block))} blocks of "
            f"{self.options.block_s:g} s, z > {self.options.z_threshold:g} and RMSE gain ≥ "
            f"{100 * self.options.min_gain_fraction:g} %",
            "noise_floor_w": round(self.noise_floor_w, 3),
        }


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
    warm: dict[str, FloatArray],
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
    """Diebold–Mariano statistic over evaluation blocks: mean block gain / its standard error."""
    gain = np.bincount(samples.block, weights=err_old**2 - err_new**2)
    counts = np.bincount(samples.block)
    gain = gain[counts > 0]
    if len(gain) < 2:
        return 0.0
    sd = float(np.std(gain, ddof=1))
    if sd == 0.0:
        return 0.0 if gain.mean() == 0 else math.copysign(math.inf, float(gain.mean()))
    return float(gain.mean() / (sd / math.sqrt(len(gain))))


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
    samples = prepare(flights, opt)
    everything = np.ones(len(samples), dtype=bool)
    before = _Problem(vehicle, samples, everything).predict([])
    f_scale_w = _robust_scale_w(samples.power_w - before)
    remaining = candidates_for(vehicle, samples, opt.candidates)
    chosen: list[Candidate] = []
    warm: dict[str, FloatArray] = {}
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
        rmse, z, _, cand, predicted, folds = min(good, key=lambda t: t[0])
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
        warm = {t.candidate.label: t.x for t in final}
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
            )
        )
        # earlier effects are refitted jointly with the new one
        for i, term in enumerate(final[:-1]):
            selected[i].effect = term.effect()
        remaining = [c for c in remaining if c.name != cand.name]
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
    )


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
