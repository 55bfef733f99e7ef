"""Offline fitting of the power model, the paper's two baselines, and held-out validation.

Pipeline (all steps follow the seed paper unless noted):

1. :func:`preprocess`: resample each flight onto a uniform ``sample_rate_hz`` grid (5 Hz, linear
   interpolation, never across gaps longer than ``max_gap_s``); tangential acceleration
   a ≈ (V_{i+1} − V_i)·f_s (the paper's forward difference) and the centripetal a⊥ from the
   velocity vector's central difference over ``accel_window_s`` (a noisy a⊥ would bias the
   fit: the load factor is quadratic in it) via
   :func:`estimator.kinematics.centripetal_accel_mps2`; keep |a| ≤ 0.5 m/s²; drop
   ground, take-off and landing: not armed, below ``min_alt_m``, climbing or descending faster
   than ``max_vertical_speed_mps`` (the model is for level flight), and ``edge_trim_s`` at both
   ends of each airborne stretch.
2. :func:`fit_theory`: least squares of eq. (2) over the points. Parameters are fitted in the
   well-conditioned hover parametrization (:class:`estimator.model.HoverParameters`):
   θ = [P_hover, logit(profile fraction), ln U_tip, ln v0, ln c5]. The raw c1..c5 correlate at
   about −1 because P(V) data barely separate blade-profile from induced power; weak physical
   priors (Gaussian penalty residuals on the last four θ, :class:`Priors`) keep refits stable.
   ``priors=None`` fits the data alone. Standard errors come from the Jacobian at the optimum
   (Laplace approximation, priors included) with the noise level taken from the residuals and
   inflated by their long-run variance over 10 s blocks, so that correlated telemetry noise is
   not counted as independent evidence; c1..c5 errors and correlations follow by the delta
   method.
3. The checks: a polynomial in V (:class:`PolynomialModel`) and the paper's model-free network
   (:class:`NetworkModel`: 3 × 10 tanh, Adam, learning rate 0.01, scaled inputs/outputs).
4. :func:`cross_validate`: every model's RMSE and MAPE on data it was not fitted on, folds by
   flight (or by contiguous time block when there are too few flights), never random samples.

When the points carry a mass ratio (payload flights, e.g. CMU), the theory model is rescaled per
point with :meth:`PowerModel.rescaled` (c3 ∝ m^1.5, c4 ∝ m) and the baselines get the mass ratio
as an extra input.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from sklearn.compose import TransformedTargetRegressor
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from estimator.errors import UserError
from estimator.kinematics import centripetal_accel_mps2
from estimator.logs import FlightSeries
from estimator.model import COEFFICIENT_NAMES, HoverParameters, PowerModel

FloatArray = NDArray[np.float64]
#: Length of the time blocks over which residual correlation is measured, s.
BLOCK_S = 10.0
THETA_NAMES = (
    "hover_power_w",
    "logit_profile_fraction",
    "ln_tip_speed",
    "ln_induced_velocity",
    "ln_c5",
)


# -- preprocessing ----------------------------------------------------------------------------


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


# -- the theory model ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Priors:
    """Gaussian priors (mean, sd) on θ[1:]: logit profile fraction, ln U_tip, ln v0, ln c5.

    Defaults are generic multirotor values, deliberately wide: profile share of hover power
    0.3 (×/÷ e^0.8 on the odds), tip speed 100 m/s (×/÷ 1.5), hover induced velocity 5.5 m/s
    (×/÷ 1.65; 5.3 m/s for a 1.3 kg IRIS+, 6.5 m/s for a 3.6 kg M100 by momentum theory),
    parasite coefficient 0.05 W s³/m³ (×/÷ 4.5).
    """

    logit_profile_fraction: tuple[float, float] = (math.log(0.3 / 0.7), 0.8)
    ln_tip_speed: tuple[float, float] = (math.log(100.0), 0.4)
    ln_induced_velocity: tuple[float, float] = (math.log(5.5), 0.5)
    ln_c5: tuple[float, float] = (math.log(0.05), 1.5)

    def arrays(self) -> tuple[FloatArray, FloatArray]:
        pairs = [
            self.logit_profile_fraction,
            self.ln_tip_speed,
            self.ln_induced_velocity,
            self.ln_c5,
        ]
        return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])


def theta_to_model(theta: FloatArray) -> PowerModel:
    """θ (see :data:`THETA_NAMES`) → :class:`PowerModel`."""
    return HoverParameters(
        hover_power_w=float(theta[0]),
        profile_fraction=float(1.0 / (1.0 + math.exp(-theta[1]))),
        tip_speed_mps=float(math.exp(theta[2])),
        induced_velocity_mps=float(math.exp(theta[3])),
        parasite_coeff=float(math.exp(theta[4])),
    ).to_model()


def model_to_theta(model: PowerModel) -> FloatArray:
    h = model.hover_parameters()
    f = min(max(h.profile_fraction, 1e-6), 1 - 1e-6)
    return np.array(
        [
            h.hover_power_w,
            math.log(f / (1 - f)),
            math.log(h.tip_speed_mps),
            math.log(h.induced_velocity_mps),
            math.log(max(h.parasite_coeff, 1e-9)),
        ]
    )


def theory_power_w(
    model: PowerModel, speed_mps: FloatArray, accel_perp_mps2: FloatArray, mass_ratio: FloatArray
) -> FloatArray:
    """Eq. (2) without the kinetic term, rescaled per point to its mass ratio, W."""
    out = np.empty(len(speed_mps))
    for r in np.unique(mass_ratio):
        rows = mass_ratio == r
        m = model if r == 1.0 else model.rescaled(mass_ratio=float(r))
        out[rows] = m.power_w(speed_mps[rows], accel_perp_mps2[rows])
    return out


@dataclass
class TheoryFit:
    """Result of :func:`fit_theory`. Standard errors are 1σ; ``correlation`` is of c1..c5."""

    model: PowerModel
    theta: FloatArray
    theta_cov: FloatArray
    coeff_stderr: dict[str, float]
    correlation: FloatArray
    hover_stderr: dict[str, float]
    sigma_w: float
    noise_inflation: float
    n_points: int
    priors: Priors | None
    prior_dominated: list[str] = field(default_factory=list)

    def predict(self, points: Points) -> FloatArray:
        return theory_power_w(
            self.model, points.speed_mps, points.accel_perp_mps2, points.mass_ratio
        )

    def curve_stderr_w(self, speed_mps: FloatArray, accel_perp_mps2: float = 0.0) -> FloatArray:
        """1σ of the fitted P(V) at each speed (delta method over θ), W."""
        v = np.asarray(speed_mps, dtype=float)
        a = np.full(len(v), accel_perp_mps2)
        jac = _numeric_jacobian(lambda th: theta_to_model(th).power_w(v, a), self.theta)
        return np.sqrt(np.einsum("ij,jk,ik->i", jac, self.theta_cov, jac))

    def speed_stderr_mps(self) -> dict[str, float]:
        """1σ of V_me and V_mr (delta method), m/s."""

        def speeds(th: FloatArray) -> FloatArray:
            m = theta_to_model(th)
            return np.array([m.max_endurance_speed_mps(), m.max_range_speed_mps()])

        jac = _numeric_jacobian(speeds, self.theta, rel_step=1e-3)
        var = np.einsum("ij,jk,ik->i", jac, self.theta_cov, jac)
        return {"v_me_mps": float(np.sqrt(var[0])), "v_mr_mps": float(np.sqrt(var[1]))}


def fit_theory(points: Points, priors: Priors | None = Priors()) -> TheoryFit:
    """Least-squares fit of eq. (2) to kept points (see the module docstring)."""
    pts = points
    n = len(pts)
    if n < 10:
        raise UserError(f"only {n} usable points after preprocessing; need at least 10 to fit")
    theta0 = _initial_theta(pts)
    prior_mean, prior_sd = priors.arrays() if priors is not None else (None, None)

    def data_resid(th: FloatArray) -> FloatArray:
        return theory_power_w(
            theta_to_model(th), pts.speed_mps, pts.accel_perp_mps2, pts.mass_ratio
        ) - np.asarray(pts.power_w)

    def solve(scale_w: float, start: FloatArray) -> FloatArray:
        def resid(th: FloatArray) -> FloatArray:
            r = data_resid(th) / scale_w
            if prior_mean is None or prior_sd is None:
                return r
            return np.concatenate([r, (th[1:] - prior_mean) / prior_sd])

        lower = np.array([1e-3, -12.0, math.log(10.0), math.log(0.3), math.log(1e-6)])
        upper = np.array([np.inf, 12.0, math.log(1000.0), math.log(50.0), math.log(10.0)])
        sol = least_squares(
            resid, np.clip(start, lower + 1e-9, upper - 1e-9), bounds=(lower, upper), x_scale="jac"
        )
        return np.asarray(sol.x, dtype=float)

    # noise level first from a provisional fit, then the final fit weighted by it
    scale = float(np.std(pts.power_w)) or 1.0
    theta = theta0
    for _ in range(2):
        theta = solve(scale, theta)
        resid = data_resid(theta)
        sigma = float(np.sqrt(np.sum(resid**2) / max(n - 5, 1)))
        inflation = _noise_inflation(resid, pts.flight, pts.time_s, sigma)
        scale = sigma * inflation
    jac = _numeric_jacobian(data_resid, theta) / scale
    info = jac.T @ jac
    if prior_sd is not None:
        info[1:, 1:] += np.diag(1.0 / prior_sd**2)
    theta_cov = np.asarray(np.linalg.pinv(info), dtype=float)
    model = theta_to_model(theta)
    c_jac = _numeric_jacobian(lambda th: theta_to_model(th).as_array(), theta)
    c_cov = c_jac @ theta_cov @ c_jac.T
    c_sd = np.sqrt(np.clip(np.diag(c_cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.clip(c_cov / np.outer(c_sd, c_sd), -1.0, 1.0)
    hover_sd = _hover_stderr(theta, theta_cov)
    dominated = []
    if prior_sd is not None:
        post_sd = np.sqrt(np.diag(theta_cov))[1:]
        dominated = [THETA_NAMES[k + 1] for k in range(4) if post_sd[k] > 0.7 * prior_sd[k]]
    return TheoryFit(
        model=model,
        theta=theta,
        theta_cov=theta_cov,
        coeff_stderr={name: float(c_sd[k]) for k, name in enumerate(COEFFICIENT_NAMES)},
        correlation=corr,
        hover_stderr=hover_sd,
        sigma_w=sigma,
        noise_inflation=inflation,
        n_points=n,
        priors=priors,
        prior_dominated=dominated,
    )


def _initial_theta(pts: Points) -> FloatArray:
    slow = pts.speed_mps < 1.5
    hover = float(np.median(pts.power_w[slow])) if slow.sum() >= 5 else float(np.min(pts.power_w))
    return np.array(
        [max(hover, 1.0), math.log(0.3 / 0.7), math.log(100.0), math.log(5.5), math.log(0.05)]
    )


def _hover_stderr(theta: FloatArray, cov: FloatArray) -> dict[str, float]:
    def hp(th: FloatArray) -> FloatArray:
        h = theta_to_model(th).hover_parameters()
        return np.array(
            [
                h.hover_power_w,
                h.profile_fraction,
                h.tip_speed_mps,
                h.induced_velocity_mps,
                h.parasite_coeff,
            ]
        )

    jac = _numeric_jacobian(hp, theta)
    sd = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", jac, cov, jac), 0, None))
    names = (
        "hover_power_w",
        "profile_fraction",
        "tip_speed_mps",
        "induced_velocity_mps",
        "parasite_coeff",
    )
    return {name: float(sd[k]) for k, name in enumerate(names)}


def _numeric_jacobian(
    fn: Callable[[FloatArray], FloatArray], x: FloatArray, rel_step: float = 1e-6
) -> FloatArray:
    """Central-difference Jacobian of a vector function."""
    f0 = np.atleast_1d(fn(x))
    jac = np.empty((len(f0), len(x)))
    for k in range(len(x)):
        h = rel_step * max(abs(x[k]), 1.0)
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        jac[:, k] = (np.atleast_1d(fn(xp)) - np.atleast_1d(fn(xm))) / (2 * h)
    return jac


def _noise_inflation(
    resid: FloatArray,
    flight: NDArray[np.int64],
    time_s: FloatArray,
    sigma: float,
    block_s: float = BLOCK_S,
) -> float:
    """sqrt(long-run variance)/σ of the residuals, ≥ 1 (batch means over time blocks).

    Telemetry noise is correlated in time (gusts, sensor drift, interpolation), so n samples
    carry less information than n independent ones. Residuals are averaged over blocks of
    ``block_s`` seconds within each flight; n_block·var(block mean) estimates the long-run
    variance, whose ratio to σ² is the factor by which independent-noise errors are too small.
    """
    if sigma <= 0 or len(resid) < 20:
        return 1.0
    key = flight.astype(np.int64) * 10_000_000 + np.floor((time_s - time_s.min()) / block_s).astype(
        np.int64
    )
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    if len(counts) < 5:
        return 1.0
    sums = np.bincount(inverse, weights=resid - resid.mean())
    long_run_var = float(np.sum(sums**2) / len(resid))
    return max(1.0, math.sqrt(long_run_var) / sigma)


# -- the paper's checks ----------------------------------------------------------------------


class Regressor(Protocol):
    def fit(self, points: Points) -> Regressor: ...
    def predict(self, points: Points) -> FloatArray: ...


def _features(points: Points, with_mass: bool) -> FloatArray:
    cols = [points.speed_mps]
    if with_mass:
        cols.append(points.mass_ratio)
    return np.column_stack(cols)


@dataclass
class PolynomialModel:
    """P = Σ_k b_k (V/V_s)^k (+ b_m (mass ratio − 1) when masses differ), least squares."""

    degree: int = 3
    with_mass: bool = False
    speed_scale_mps: float = 1.0
    coef: FloatArray = field(default_factory=lambda: np.zeros(0))

    def _design(self, points: Points) -> FloatArray:
        v = points.speed_mps / self.speed_scale_mps
        cols = [v**k for k in range(self.degree + 1)]
        if self.with_mass:
            cols.append(points.mass_ratio - 1.0)
        return np.column_stack(cols)

    def fit(self, points: Points) -> PolynomialModel:
        self.speed_scale_mps = max(float(np.max(points.speed_mps)), 1.0)
        solution = np.linalg.lstsq(self._design(points), points.power_w, rcond=None)[0]
        self.coef = np.asarray(solution, dtype=float)
        return self

    def predict(self, points: Points) -> FloatArray:
        return np.asarray(self._design(points) @ self.coef, dtype=float)


@dataclass
class NetworkModel:
    """The paper's model-free check: MLP 3 × 10 tanh, Adam, learning rate 0.01.

    Inputs and output are standardised; training stops when the loss stalls.
    """

    with_mass: bool = False
    seed: int = 0
    max_iter: int = 300
    _net: TransformedTargetRegressor | None = None

    def fit(self, points: Points) -> NetworkModel:
        mlp = MLPRegressor(
            hidden_layer_sizes=(10, 10, 10),
            activation="tanh",
            solver="adam",
            learning_rate_init=0.01,
            max_iter=self.max_iter,
            n_iter_no_change=15,
            tol=1e-5,
            random_state=self.seed,
        )
        self._net = TransformedTargetRegressor(
            regressor=make_pipeline(StandardScaler(), mlp), transformer=StandardScaler()
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            self._net.fit(_features(points, self.with_mass), points.power_w)
        return self

    def predict(self, points: Points) -> FloatArray:
        if self._net is None:
            raise RuntimeError("network not fitted")
        return np.asarray(self._net.predict(_features(points, self.with_mass)), dtype=float)


@dataclass
class TheoryRegressor:
    """:func:`fit_theory` behind the :class:`Regressor` interface (for cross-validation)."""

    priors: Priors | None = field(default_factory=Priors)
    result: TheoryFit | None = None

    def fit(self, points: Points) -> TheoryRegressor:
        self.result = fit_theory(points, self.priors)
        return self

    def predict(self, points: Points) -> FloatArray:
        if self.result is None:
            raise RuntimeError("theory model not fitted")
        return self.result.predict(points)


# -- held-out validation ------------------------------------------------------------------------


@dataclass(frozen=True)
class Score:
    """Held-out error: pooled RMSE (W), MAPE (%), and the RMSE of each fold (W)."""

    rmse_w: float
    mape_pct: float
    fold_rmse_w: tuple[float, ...]

    def as_dict(self) -> dict[str, float]:
        return {"rmse_w": round(self.rmse_w, 3), "mape_pct": round(self.mape_pct, 3)}


def fold_labels(
    points: Points, folds: int = 5, split: str = "auto"
) -> tuple[NDArray[np.int64], str]:
    """Fold index per point and the split used: whole flights, or contiguous time blocks.

    ``auto`` splits by flight when there are at least 3 flights, otherwise into ``folds``
    consecutive time blocks of every flight.
    """
    flights = np.unique(points.flight)
    if split == "auto":
        split = "flight" if len(flights) >= 3 else "block"
    if split == "flight":
        if len(flights) < 2:
            raise UserError("cannot hold out whole flights with only one flight; use --split block")
        k = min(folds, len(flights))
        # greedy balance of point counts over folds, largest flights first (deterministic)
        sizes = {f: int(np.sum(points.flight == f)) for f in flights}
        load = np.zeros(k)
        label_of: dict[int, int] = {}
        for f in sorted(flights, key=lambda f: (-sizes[f], f)):
            j = int(np.argmin(load))
            label_of[int(f)] = j
            load[j] += sizes[f]
        return np.array([label_of[int(f)] for f in points.flight], dtype=np.int64), "flight"
    if split == "block":
        labels = np.empty(len(points), dtype=np.int64)
        for f in flights:
            rows = np.flatnonzero(points.flight == f)
            labels[rows] = np.minimum(np.arange(len(rows)) * folds // len(rows), folds - 1)
        return labels, "block"
    raise UserError(f"unknown split {split!r} (choose auto, flight or block)")


def score(predicted: FloatArray, measured: FloatArray, labels: NDArray[np.int64]) -> Score:
    err = predicted - measured
    fold_rmse = tuple(float(np.sqrt(np.mean(err[labels == j] ** 2))) for j in np.unique(labels))
    mape = float(np.mean(np.abs(err) / np.abs(measured)) * 100.0)
    return Score(float(np.sqrt(np.mean(err**2))), mape, fold_rmse)


def cross_validate(
    points: Points,
    factories: dict[str, Callable[[], Regressor]],
    folds: int = 5,
    split: str = "auto",
    progress: Callable[[str], None] | None = None,
) -> tuple[dict[str, Score], str]:
    """Held-out score of each model: fit on all folds but one, predict that one, pool."""
    labels, used = fold_labels(points, folds, split)
    scores = {}
    for name, make in factories.items():
        predicted = np.empty(len(points))
        for j in np.unique(labels):
            if progress is not None:
                progress(f"{name}: fold {j + 1}/{len(np.unique(labels))}")
            train, test = labels != j, labels == j
            predicted[test] = make().fit(points.select(train)).predict(points.select(test))
        scores[name] = score(predicted, points.power_w, labels)
    return scores, used


# -- everything together ------------------------------------------------------------------------


@dataclass(frozen=True)
class FitOptions:
    preprocess: PreprocessOptions = field(default_factory=PreprocessOptions)
    priors: Priors | None = field(default_factory=Priors)
    polynomial_degree: int = 3
    folds: int = 5
    split: str = "auto"
    seed: int = 0


@dataclass
class FitReport:
    """Everything ``uav-energy fit`` prints and plots."""

    points: Points
    theory: TheoryFit
    polynomial: PolynomialModel
    network: NetworkModel
    scores: dict[str, Score]
    split: str
    options: FitOptions

    def summary(self) -> dict[str, object]:
        """The JSON object of ``uav-energy fit --json``."""
        model = self.theory.model
        speeds_sd = self.theory.speed_stderr_mps()
        kept = self.points.kept()
        return {
            "n_points": len(kept),
            "n_flights": kept.n_flights,
            "params": {k: float(v) for k, v in model.as_dict().items()},
            "stderr": self.theory.coeff_stderr,
            "correlation": np.round(np.nan_to_num(self.theory.correlation), 4).tolist(),
            "hover_parameters": {k: float(v) for k, v in model.hover_parameters().__dict__.items()},
            "hover_parameters_stderr": self.theory.hover_stderr,
            "prior_dominated": self.theory.prior_dominated,
            "hover_power_w": model.hover_power_w,
            "hover_power_stderr_w": self.theory.hover_stderr["hover_power_w"],
            "v_me_mps": model.max_endurance_speed_mps(),
            "v_me_stderr_mps": speeds_sd["v_me_mps"],
            "v_mr_mps": model.max_range_speed_mps(),
            "v_mr_stderr_mps": speeds_sd["v_mr_mps"],
            "noise_sigma_w": self.theory.sigma_w,
            "noise_inflation": self.theory.noise_inflation,
            "speed_range_mps": [float(np.min(kept.speed_mps)), float(np.max(kept.speed_mps))],
            "split": self.split,
            "models": {name: s.as_dict() for name, s in self.scores.items()},
            "fold_rmse_w": {
                name: [round(x, 3) for x in s.fold_rmse_w] for name, s in self.scores.items()
            },
        }


def fit_all(
    points: Points,
    options: FitOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> FitReport:
    """Fit theory, polynomial and network on all kept points and score each held-out."""
    opt = options or FitOptions()
    kept = points.kept()
    if len(kept) < 10:
        raise UserError(
            f"only {len(kept)} of {len(points)} samples pass the preprocessing (level, "
            f"|a| ≤ {opt.preprocess.max_accel_mps2} m/s², airborne); nothing to fit"
        )
    with_mass = kept.varying_mass
    factories: dict[str, Callable[[], Regressor]] = {
        "theory": lambda: TheoryRegressor(opt.priors),
        "polynomial": lambda: PolynomialModel(opt.polynomial_degree, with_mass),
        "dnn": lambda: NetworkModel(with_mass, opt.seed),
    }
    scores, used = cross_validate(kept, factories, opt.folds, opt.split, progress)
    if progress is not None:
        progress("final fits on all points")
    theory = fit_theory(kept, opt.priors)
    poly = PolynomialModel(opt.polynomial_degree, with_mass).fit(kept)
    net = NetworkModel(with_mass, opt.seed).fit(kept)
    return FitReport(points, theory, poly, net, scores, used, opt)


# -- per-flight validation (experiment 2) ------------------------------------------------------


@dataclass(frozen=True)
class FlightCheck:
    """Mean measured and predicted power over one flight's kept points (W, m/s, m/s²)."""

    flight_id: str
    n_points: int
    speed_mps: float
    accel_perp_mps2: float
    measured_w: float
    eq2_w: float
    eq1_w: float
    eq2_rmse_w: float
    eq2_mape_pct: float


def check_flights(
    theory: TheoryFit, points: Points, min_speed_mps: float = 0.0
) -> list[FlightCheck]:
    """Per flight: how eq. (2) (with the measured a⊥) and eq. (1) (a⊥ ignored) predict it.

    Only kept points at ``min_speed_mps`` or faster count (e.g. to leave out hovers).
    """
    kept = points.select(points.keep & (points.speed_mps >= min_speed_mps))
    eq2 = theory.predict(kept)
    eq1 = theory_power_w(theory.model, kept.speed_mps, np.zeros(len(kept)), kept.mass_ratio)
    out = []
    for k in np.unique(kept.flight):
        rows = kept.flight == k
        err = eq2[rows] - kept.power_w[rows]
        out.append(
            FlightCheck(
                flight_id=kept.flight_ids[int(k)],
                n_points=int(rows.sum()),
                speed_mps=float(np.mean(kept.speed_mps[rows])),
                accel_perp_mps2=float(np.mean(kept.accel_perp_mps2[rows])),
                measured_w=float(np.mean(kept.power_w[rows])),
                eq2_w=float(np.mean(eq2[rows])),
                eq1_w=float(np.mean(eq1[rows])),
                eq2_rmse_w=float(np.sqrt(np.mean(err**2))),
                eq2_mape_pct=float(np.mean(np.abs(err) / np.abs(kept.power_w[rows])) * 100),
            )
        )
    return out
