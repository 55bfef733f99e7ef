"""The model's slow error (:mod:`estimator.analysis.slow_error`): window means of a residual
carry a slow offset and average white noise away."""

from __future__ import annotations

import numpy as np
import pytest

from estimator.analysis.slow_error import slow_error_fraction, window_means_w


def test_white_noise_averages_out_and_a_slow_error_stays() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 600.0, 0.5)  # 2 Hz, 60 windows of 10 s
    white = rng.normal(0.0, 10.0, len(t))
    # 10 W white noise: a 20-sample mean scatters by 10/sqrt(20) = 2.2 W
    assert slow_error_fraction([(t, white)], 400.0) == pytest.approx(2.24 / 400, rel=0.25)
    slow = 8.0 * np.sin(2 * np.pi * t / 120.0)  # 8 W over two minutes: sd 5.7 W
    assert slow_error_fraction([(t, white + slow)], 400.0) == pytest.approx(6.1 / 400, rel=0.2)


def test_sparse_windows_are_left_out_and_too_little_data_is_an_error() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 15.0, 25.0, 26.0, 27.0, 28.0, 29.0])
    r = np.array([1.0] * 5 + [100.0] + [3.0] * 5)
    assert window_means_w(t, r).tolist() == [1.0, 3.0]  # the window of one sample is out
    with pytest.raises(ValueError, match="two windows"):
        slow_error_fraction([(t[:5], r[:5])], 400.0)
