"""The closed-form Kalman steps equal filterpy's on random inputs (to 1e-12)."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import (
    KalmanFilter,
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
)

from estimator.estimation.kalman import LinearKalman, MerweSigmaPoints

TOL = {"rtol": 1e-12, "atol": 1e-12}


def random_covariance(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.normal(size=(n, n)) * rng.uniform(0.01, 10.0, size=n)
    return a @ a.T + 1e-3 * np.eye(n)


def test_linear_predict_and_update_equal_filterpy() -> None:
    n = 2
    rng = np.random.default_rng(n)
    for _ in range(200):
        x, p = rng.normal(size=n) * 50, random_covariance(rng, n)
        f, q = np.eye(n) + rng.normal(size=(n, n)) * 0.1, random_covariance(rng, n) * 0.01
        h, z, r_var = rng.normal(size=n), float(rng.normal() * 100), float(rng.uniform(0.1, 50))
        ref = KalmanFilter(dim_x=n, dim_z=1)
        ref.x, ref.P = x.copy(), p.copy()
        ref.predict(F=f, Q=q)
        ref.update(np.array([z]), R=np.array([[r_var]]), H=h[None, :])
        ours = LinearKalman(x.tolist(), p.tolist())
        ours.predict(f.tolist(), q.tolist())
        ours.update(z, h.tolist(), r_var)
        np.testing.assert_allclose(ours.x, ref.x, **TOL)
        np.testing.assert_allclose(ours.P, ref.P, **TOL)


def test_sigma_points_and_unscented_update_equal_filterpy() -> None:
    """OnlineEffects' step: sigma points drawn from (x, P) (filterpy: ``predict(dt=0)`` with
    the identity process and Q = 0), a nonlinear scalar measurement, the update."""
    rng = np.random.default_rng(7)
    ref_points = MerweScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
    ours = MerweSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
    np.testing.assert_allclose(ours.wm, ref_points.Wm, **TOL)
    np.testing.assert_allclose(ours.wc, ref_points.Wc, **TOL)

    def measure(point: np.ndarray) -> float:  # a power-like nonlinear function of the state
        return float(400 + 3 * point[0] ** 2 - 2 * point[1] * point[0] + 90 * np.tanh(point[2]))

    for _ in range(200):
        x, p = rng.normal(size=3) * 3, random_covariance(rng, 3)
        z, r_var = float(measure(x) + rng.normal() * 20), float(rng.uniform(1.0, 400.0))
        ukf = UnscentedKalmanFilter(
            3, 1, 1.0, hx=lambda s: np.array([measure(s)]), fx=lambda s, dt: s, points=ref_points
        )
        ukf.x, ukf.P, ukf.Q = x.copy(), p.copy(), np.zeros((3, 3))
        ukf.predict(dt=0.0)
        ukf.update(np.array([z]), R=np.array([[r_var]]))
        sigmas = ours.points(x, p)
        np.testing.assert_allclose(sigmas, ukf.sigmas_f, **TOL)
        post = ours.update(x, p, sigmas, np.array([measure(s) for s in sigmas]), z, r_var)
        np.testing.assert_allclose(post.x, ukf.x, **TOL)
        np.testing.assert_allclose(post.p, ukf.P, **TOL)
        assert post.y == pytest.approx(float(ukf.y[0]), rel=1e-12, abs=1e-12)
        assert post.s_var == pytest.approx(float(ukf.S[0, 0]), rel=1e-12)


def test_sigma_points_of_an_indefinite_covariance_raise_like_filterpy() -> None:
    p = np.diag([1.0, -1.0, 1.0])
    with pytest.raises(np.linalg.LinAlgError):
        MerweScaledSigmaPoints(3, 1.0, 2.0, 0.0).sigma_points(np.zeros(3), p)
    with pytest.raises(np.linalg.LinAlgError):
        MerweSigmaPoints(3).points(np.zeros(3), p)
