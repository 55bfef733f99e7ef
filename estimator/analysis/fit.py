"""Offline fitting of the power model, the paper's two baselines, and held-out validation.

Pipeline (all steps follow the seed paper unless noted):

1. :func:`preprocess`: resample each flight onto a uniform ``sample_rate_hz`` grid (5 Hz, linear
   interpolation, never across gaps longer than ``max_gap_s``); tangential acceleration
   a ≈ (V_{i+1} − V_i)·f_s (the paper's forward difference) and the centripetal a⊥ from the
   velocity vector's central difference over ``accel_window_s`` (a noisy a⊥ would bias the
   fit: the load factor is quadratic in it) via
   :func:`estimator.physics.kinematics.centripetal_accel_mps2`; keep |a| ≤ 0.5 m/s²; drop
   ground, take-off and landing: not armed, below ``min_alt_m``, climbing or descending faster
   than ``max_vertical_speed_mps`` (the model is for level flight), and ``edge_trim_s`` at both
   ends of each airborne stretch.
2. :func:`fit_theory`: least squares of eq. (2) over the points. Parameters are fitted in the
   well-conditioned hover parametrization (:class:`estimator.physics.model.HoverParameters`):
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

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from estimator.analysis.baselines import NetworkModel, PolynomialModel, Regressor, TheoryRegressor
from estimator.analysis.fit_points import Points, PreprocessOptions
from estimator.analysis.theory_fit import Priors, TheoryFit, fit_theory, theory_power_w
from estimator.errors import UserError
from estimator.physics.model import FloatArray


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
