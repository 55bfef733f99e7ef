"""Least-squares fit of the theory model (eq. 1/2) in its hover parametrization, with
physical priors, standard errors and correlations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from estimator.analysis.fit_points import BLOCK_S, Points
from estimator.errors import UserError
from estimator.physics.model import COEFFICIENT_NAMES, FloatArray, HoverParameters, PowerModel

THETA_NAMES = (
    "hover_power_w",
    "logit_profile_fraction",
    "ln_tip_speed",
    "ln_induced_velocity",
    "ln_c5",
)


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
