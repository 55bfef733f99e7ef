"""The resistance from steps of current between consecutive readings, and the current's own
noise (estimation/step_resistance.py): readings drawn from V = OCV − I·R with known noise."""

from __future__ import annotations

import numpy as np
import pytest

from estimator.estimation.step_resistance import STEP_MIN_A, StepResistance

R_OHM = 0.03
#: The resting voltage's change per Ah drawn (V/Ah).
DRIFT_V_PER_AH = -0.5


def _readings(
    current_noise_a: float, seed: int = 3, seconds: float = 300.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """2 Hz readings of a pack at 30 A moving smoothly by ±1 A, with a 3 A step every 20 s;
    1 mV of voltage noise, ``current_noise_a`` of white current noise (1σ); resting voltage
    falling :data:`DRIFT_V_PER_AH` (about 2 mV a reading)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.5)
    true_a = 30.0 + np.sin(t / 15.0) + 3.0 * (np.floor(t / 20.0) % 2)
    drawn_ah = np.concatenate([[0.0], np.cumsum(0.5 * (true_a[1:] + true_a[:-1]) * 0.5 / 3600)])
    ocv_v = 11.5 + DRIFT_V_PER_AH * drawn_ah
    volts = ocv_v - true_a * R_OHM + rng.normal(0.0, 0.001, len(t))
    return t, volts, true_a + rng.normal(0.0, current_noise_a, len(t))


def _run(current_noise_a: float) -> tuple[StepResistance, list, list[bool]]:
    t, volts, amps = _readings(current_noise_a)
    steps = StepResistance(0.05)
    found, flags = [], []
    for k in range(len(t)):
        step = steps.take(float(t[k]), float(volts[k]), float(amps[k]), DRIFT_V_PER_AH, R_OHM)
        if step is not None:
            found.append(step)
        flags.append(steps.within_noise)
    return steps, found, flags


def test_clean_current_steps_give_the_resistance_within_their_sigma() -> None:
    steps, found, flags = _run(0.0)
    assert len(found) >= 10
    for step in found:
        assert abs(step.resistance_ohm - R_OHM) <= 3.0 * np.sqrt(step.var_ohm2)
    # the noise of a difference (√2 mV), with what is left of the configured 50 mV prior
    assert 0.9 * np.sqrt(2) * 0.001 <= np.sqrt(steps.difference_var_v2) <= 3 * np.sqrt(2) * 0.001
    assert not any(flags)  # a clean current's small moves are the pack's own


def test_a_noisy_current_raises_the_step_needed_and_flags_its_wiggles() -> None:
    """0.3 A of white noise: the noise is learnt from consecutive differences (−ΔI_k·ΔI_(k−1)),
    only steps of 5 × its difference noise (2.1 A) count, and the moves within 3 × it are
    flagged."""
    steps, found, flags = _run(0.3)
    noise_a = np.sqrt(max(steps._current_noise_a2, 0.0))
    assert noise_a == pytest.approx(0.3, rel=0.25)
    assert found and all(
        abs(s.current_step_a) >= max(STEP_MIN_A, 5 * np.sqrt(2) * 0.2) for s in found
    )
    estimates = np.array([s.resistance_ohm for s in found])
    assert abs(np.median(estimates) / R_OHM - 1.0) <= 0.1  # no errors-in-variables bias
    assert np.mean(flags[100:]) > 0.5


def test_a_gap_between_readings_is_no_step() -> None:
    steps = StepResistance(0.05)
    assert steps.take(0.0, 11.0, 30.0, 0.0, R_OHM) is None
    assert steps.take(5.0, 10.9, 35.0, 0.0, R_OHM) is None  # 5 s apart: not a pair
    assert steps.take(5.5, 10.75, 40.0, 0.0, R_OHM) is not None
