"""Closed-form Kalman steps for the daemon's small filters (scalar measurements): the linear
one in scalar arithmetic, the unscented one in numpy.

The steps are filterpy's (``KalmanFilter.predict``/``update`` with the Joseph-form
covariance; ``UnscentedKalmanFilter`` with ``MerweScaledSigmaPoints``), written out for the
shapes used here: two states (linear), three or four (unscented), and one measurement.
Importing filterpy runs its package ``__init__``, which loads every submodule and with them
``scipy.stats``, ``scipy.linalg`` and ``scipy.ndimage``: about 60 MB of the daemon's resident
memory and 0.7 s of its start-up for a few 3 × 3 products. tests/test_kalman.py checks every step
here against filterpy's on random inputs (equal to 1e-12).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np


class LinearKalman:
    """A linear Kalman filter of two states: state ``x`` (2 floats) and covariance ``P``
    (2 × 2, nested lists), both replaced by :meth:`predict` and :meth:`update` (the caller
    may also edit them). Written out in scalar arithmetic: once per period, numpy's calls on
    2 × 2 arrays cost more than the products they save."""

    def __init__(self, x: Sequence[float], p: Sequence[Sequence[float]]) -> None:
        self.x = [float(v) for v in x]
        self.P = [[float(v) for v in row] for row in p]

    def predict(self, f: Sequence[Sequence[float]], q: Sequence[Sequence[float]]) -> None:
        """x ← F x, P ← F P Fᵀ + Q."""
        (f00, f01), (f10, f11) = f
        (p00, p01), (p10, p11) = self.P
        x0, x1 = self.x
        self.x = [f00 * x0 + f01 * x1, f10 * x0 + f11 * x1]
        a00, a01 = f00 * p00 + f01 * p10, f00 * p01 + f01 * p11  # F P
        a10, a11 = f10 * p00 + f11 * p10, f10 * p01 + f11 * p11
        (q00, q01), (q10, q11) = q
        self.P = [
            [a00 * f00 + a01 * f01 + q00, a00 * f10 + a01 * f11 + q01],
            [a10 * f00 + a11 * f01 + q10, a10 * f10 + a11 * f11 + q11],
        ]

    def update(self, z: float, h: Sequence[float], r_var: float) -> None:
        """Fold in one measurement ``z = h · x + noise`` of variance ``r_var``; the Joseph
        form P ← (I − K h) P (I − K h)ᵀ + K r Kᵀ keeps P symmetric and positive."""
        h0, h1 = h
        (p00, p01), (p10, p11) = self.P
        x0, x1 = self.x
        pht0, pht1 = p00 * h0 + p01 * h1, p10 * h0 + p11 * h1
        s_var = h0 * pht0 + h1 * pht1 + r_var
        g0, g1 = pht0 / s_var, pht1 / s_var
        innovation = z - (h0 * x0 + h1 * x1)
        self.x = [x0 + g0 * innovation, x1 + g1 * innovation]
        a00, a01, a10, a11 = 1.0 - g0 * h0, -g0 * h1, -g1 * h0, 1.0 - g1 * h1  # I − K h
        b00, b01 = a00 * p00 + a01 * p10, a00 * p01 + a01 * p11  # (I − K h) P
        b10, b11 = a10 * p00 + a11 * p10, a10 * p01 + a11 * p11
        self.P = [
            [b00 * a00 + b01 * a01 + r_var * (g0 * g0), b00 * a10 + b01 * a11 + r_var * (g0 * g1)],
            [b10 * a00 + b11 * a01 + r_var * (g1 * g0), b10 * a10 + b11 * a11 + r_var * (g1 * g1)],
        ]


class UnscentedUpdate(NamedTuple):
    """An unscented update's posterior state and covariance, its innovation y (measurement
    minus predicted mean), the innovation variance S and the gain K (per unit of the
    measurement)."""

    x: np.ndarray
    p: np.ndarray
    y: float
    s_var: float
    gain: np.ndarray


class MerweSigmaPoints:
    """Van der Merwe's scaled sigma points for an ``n``-state (2n + 1 points) and their mean
    and covariance weights (``alpha``, ``beta``, ``kappa`` as in filterpy)."""

    def __init__(self, n: int, alpha: float = 1.0, beta: float = 2.0, kappa: float = 0.0) -> None:
        self.n = n
        lam = alpha**2 * (n + kappa) - n
        self._scale = lam + n
        self.wm = np.full(2 * n + 1, 0.5 / (n + lam))
        self.wc = self.wm.copy()
        self.wm[0] = lam / (n + lam)
        self.wc[0] = lam / (n + lam) + (1.0 - alpha**2 + beta)

    def points(self, x: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The (2n + 1) × n sigma points of mean ``x`` and covariance ``p``: x, x + U_k,
        x − U_k with U the upper Cholesky factor of (λ + n) P; raises
        ``np.linalg.LinAlgError`` when ``p`` is not positive definite."""
        u = np.linalg.cholesky(self._scale * np.asarray(p, dtype=float).T).T
        return np.vstack([x, x + u, x - u])

    def variance(self, z_sigmas: np.ndarray) -> float:
        """The variance of a scalar predicted at each sigma point (``z_sigmas``, 2n + 1)."""
        dz = z_sigmas - float(self.wm @ z_sigmas)
        return float(self.wc @ (dz * dz))

    def update(
        self,
        x: np.ndarray,
        p: np.ndarray,
        sigmas: np.ndarray,
        z_sigmas: np.ndarray,
        z: float,
        r_var: float,
    ) -> UnscentedUpdate:
        """The unscented update of mean ``x`` and covariance ``p`` from their sigma points
        ``sigmas`` and the measurement predicted at each (``z_sigmas``, 2n + 1), for a
        measurement ``z`` of noise variance ``r_var``; raises ``np.linalg.LinAlgError`` for
        an innovation variance that is not positive."""
        z_mean = float(self.wm @ z_sigmas)
        dz = z_sigmas - z_mean
        s_var = float(self.wc @ (dz * dz)) + r_var
        if not s_var > 0.0:
            raise np.linalg.LinAlgError("innovation variance is not positive")
        gain = ((sigmas - x).T @ (self.wc * dz)) / s_var
        y = z - z_mean
        return UnscentedUpdate(x + gain * y, p - s_var * np.outer(gain, gain), y, s_var, gain)


def state_from_json(x_doc: Any, p_doc: Any, n: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A filter's state (n,) and covariance (n × n) from their JSON lists; ValueError (or
    TypeError) when they are not finite arrays of those shapes, or the covariance is not
    symmetric positive semi-definite (to rounding)."""
    x = np.array([float(v) for v in x_doc])
    p = np.array([[float(v) for v in row] for row in p_doc])
    if x.shape != (n,) or p.shape != (n, n) or not (np.isfinite(x).all() and np.isfinite(p).all()):
        raise ValueError(f"{what} is not a finite state of {n} with its {n}×{n} covariance")
    scale = max(float(np.abs(p).max()), 1e-300)
    if not np.allclose(p, p.T, rtol=1e-9, atol=1e-12 * scale):
        raise ValueError(f"{what}: the covariance is not symmetric")
    if np.linalg.eigvalsh(0.5 * (p + p.T)).min() < -1e-9 * scale:
        raise ValueError(f"{what}: the covariance is not positive semi-definite")
    return x, p
