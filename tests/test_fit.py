"""Fitting on generated flights: accuracy, honest standard errors, preprocessing, validation."""

from __future__ import annotations

import numpy as np
import pytest

from estimator.analysis.baselines import PolynomialModel
from estimator.analysis.fit import FitOptions, check_flights, fit_all, fold_labels
from estimator.analysis.fit_points import PreprocessOptions, preprocess
from estimator.analysis.theory_fit import Priors, fit_theory
from estimator.errors import UserError
from estimator.logs import FlightSeries
from estimator.physics.vehicle import default_vehicle
from estimator.sim.flightgen import NoiseSpec, experiment1, experiment2

VEHICLE = default_vehicle()
TRUTH = VEHICLE.model
SPEEDS = np.array([0.0, 3.0, 6.0, 9.0, 12.0, 14.0])


def _exp1(seed: int, noise: NoiseSpec | None = None) -> list[FlightSeries]:
    return experiment1(TRUTH, VEHICLE.mass_kg, legs=2, noise=noise, seed=seed)


def test_fitted_curve_matches_the_generating_curve_within_the_noise() -> None:
    flights = experiment1(TRUTH, VEHICLE.mass_kg, seed=3)
    fit = fit_theory(preprocess(flights).kept())
    v = np.linspace(0, 14, 29)
    error = fit.model.power_w(v) - TRUTH.power_w(v)
    # per-sample noise is ~9 W; the fitted curve is within a small fraction of it everywhere
    assert np.max(np.abs(error)) < 0.3 * fit.sigma_w
    assert np.max(np.abs(error) / fit.curve_stderr_w(v)) < 4.0
    assert fit.model.hover_power_w == pytest.approx(TRUTH.hover_power_w, abs=2.0)
    assert fit.model.max_endurance_speed_mps() == pytest.approx(
        TRUTH.max_endurance_speed_mps(), abs=0.3
    )


@pytest.mark.parametrize("noise", [NoiseSpec.white(), NoiseSpec()], ids=["white", "realistic"])
def test_reported_standard_errors_are_honest_over_seeds(noise: NoiseSpec) -> None:
    z_curve, z_hover = [], []
    for seed in range(12):
        fit = fit_theory(preprocess(_exp1(seed, noise)).kept())
        error = fit.model.power_w(SPEEDS) - TRUTH.power_w(SPEEDS)
        z_curve.append(error / fit.curve_stderr_w(SPEEDS))
        z_hover.append(
            (fit.model.hover_power_w - TRUTH.hover_power_w) / fit.hover_stderr["hover_power_w"]
        )
    z = np.abs(np.concatenate(z_curve))
    # nominal 95 % within 2σ; allow sampling slack, and catch over-wide errors too
    assert np.mean(z < 2.0) >= 0.8
    assert np.mean(np.abs(z_hover) < 2.0) >= 0.75
    assert 0.4 < np.sqrt(np.mean(z**2)) < 1.6


def test_raw_coefficients_are_degenerate_and_priors_stabilise_them() -> None:
    spread = {"priors": [], "none": []}
    for seed in range(4):
        points = preprocess(_exp1(seed)).kept()
        free = fit_theory(points, priors=None)
        assert free.correlation[0, 2] < -0.95  # c1 and c3 trade off against each other
        spread["none"].append(free.model.c1)
        spread["priors"].append(fit_theory(points, Priors()).model.c1)
        # the curve is determined either way
        np.testing.assert_allclose(free.model.power_w(SPEEDS), TRUTH.power_w(SPEEDS), atol=3.0)
    assert np.std(spread["priors"]) < np.std(spread["none"])


def test_preprocessing_drops_ground_climbs_and_accelerations() -> None:
    flights = _exp1(0)
    points = preprocess(flights)
    kept = points.kept()
    assert 0.2 * len(points) < len(kept) < 0.9 * len(points)
    assert np.all(np.abs(kept.accel_tangential_mps2) <= 0.5)
    assert np.all(np.abs(kept.vd_mps) <= 0.5)
    assert np.all(kept.power_w > 50.0)  # ground idle (8 W) is gone
    assert np.allclose(np.diff(points.time_s)[np.diff(points.flight) == 0], 0.2)


def test_thresholds_are_options() -> None:
    flights = _exp1(0)
    strict = preprocess(flights, PreprocessOptions(max_accel_mps2=0.1))
    loose = preprocess(flights, PreprocessOptions(max_accel_mps2=2.0))
    assert strict.keep.sum() < loose.keep.sum()


def test_slow_logs_are_resampled_to_five_hertz() -> None:
    t = np.arange(0.0, 60.0, 0.5)  # 2 Hz like the IRIS+ SYS_STATUS
    n = len(t)
    flight = FlightSeries(
        "slow",
        t,
        np.full(n, 4.0),
        np.zeros(n),
        np.zeros(n),
        np.full(n, 10.0),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full(n, 300.0),
    )
    points = preprocess([flight])
    assert np.allclose(np.diff(points.time_s), 0.2)
    assert len(points) == pytest.approx(5 * 59.5 + 1, abs=1)


def test_held_out_folds_are_whole_flights_or_contiguous_blocks() -> None:
    points = preprocess(_exp1(0)).kept()
    labels, split = fold_labels(points, 5, "flight")
    assert split == "flight"
    for f in np.unique(points.flight):
        assert len(np.unique(labels[points.flight == f])) == 1
    labels, split = fold_labels(points, 4, "block")
    for f in np.unique(points.flight):
        rows = labels[points.flight == f]
        assert np.all(np.diff(rows) >= 0)  # blocks follow time, never shuffled
    one = points.select(points.flight == points.flight[0])
    with pytest.raises(UserError):
        fold_labels(one, 5, "flight")


def test_all_three_models_score_near_the_noise_on_held_out_data() -> None:
    points = preprocess(_exp1(1))
    report = fit_all(points, FitOptions(split="block", folds=3))
    noise = report.theory.sigma_w
    for name in ("theory", "polynomial", "dnn"):
        assert report.scores[name].rmse_w < 1.5 * noise, name
    assert report.scores["theory"].rmse_w <= report.scores["polynomial"].rmse_w * 1.05
    summary = report.summary()
    assert set(summary["models"]) == {"theory", "polynomial", "dnn"}


def test_too_few_points_is_a_user_error() -> None:
    points = preprocess(_exp1(0))
    with pytest.raises(UserError, match="usable points"):
        fit_theory(points.select(np.arange(len(points)) < 5))


def test_polynomial_baseline_recovers_a_cubic() -> None:
    points = preprocess(_exp1(0)).kept()
    points.power_w = 100 + 2 * points.speed_mps**3
    poly = PolynomialModel(3).fit(points)
    np.testing.assert_allclose(poly.predict(points), points.power_w, atol=1e-6)


def test_experiment2_eq2_predicts_circles_better_than_eq1() -> None:
    fit = fit_theory(preprocess(experiment1(TRUTH, VEHICLE.mass_kg, seed=5)).kept())
    circles = experiment2(TRUTH, VEHICLE.mass_kg, speeds_mps=[5.0, 6.0], radii_m=[10.0], seed=6)
    for check in check_flights(fit, preprocess(circles), min_speed_mps=0.5):
        assert abs(check.eq2_w - check.measured_w) < 5.0
        assert abs(check.eq2_w - check.measured_w) < abs(check.eq1_w - check.measured_w)


def test_paper_experiments_reproduction_writes_its_report(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from estimator.sim.experiments import reproduce

    result = reproduce(tmp_path, seed=2)
    lines = (tmp_path / "summary.md").read_text().splitlines()
    assert sum(line.startswith("| 10 | ") for line in lines) == 6  # six r = 10 m circles
    assert (tmp_path / "experiment2.png").stat().st_size > 1000
    assert (tmp_path / "experiment1" / "curves.png").stat().st_size > 1000
    assert abs(result.fit.theory.model.hover_power_w - VEHICLE.model.hover_power_w) < 2.0
