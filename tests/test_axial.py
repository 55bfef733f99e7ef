"""Induced velocity in axial flight against momentum theory (Leishman, ch. 2)."""

from __future__ import annotations

import numpy as np
import pytest

from estimator.physics.axial import (
    VORTEX_RING_KAPPA,
    axial_induced_power_ratio,
    induced_velocity_ratio,
)


def test_hover_is_one() -> None:
    assert float(induced_velocity_ratio(0.0)) == pytest.approx(1.0)
    assert float(axial_induced_power_ratio(0.0, 4.0)) == pytest.approx(1.0)


def test_climb_branch_is_exact() -> None:
    # v_i/v_h = −x/2 + sqrt(x²/4 + 1): x = 1.5 gives 0.5 (3-4-5), x = 3.75 gives 0.25
    got = induced_velocity_ratio([1.5, 3.75])
    assert got == pytest.approx([0.5, 0.25])
    # the momentum balance it solves: v_i (V_c + v_i) = v_h²
    x = np.linspace(0.0, 10.0, 51)
    r = induced_velocity_ratio(x)
    assert r * (x + r) == pytest.approx(np.ones_like(x))


def test_windmill_branch_is_exact() -> None:
    # v_i/v_h = −x/2 − sqrt(x²/4 − 1): x = −2.5 gives 0.5, x = −2 gives 1
    assert induced_velocity_ratio([-2.5, -2.0]) == pytest.approx([0.5, 1.0])
    # the momentum balance of the windmill state: v_i (V_c + v_i) = −v_h²
    x = np.linspace(-12.0, -2.0, 51)
    r = induced_velocity_ratio(x)
    assert r * (x + r) == pytest.approx(-np.ones_like(x))


def test_vortex_ring_bridge_follows_the_quartic_and_is_continuous() -> None:
    # inside the bridge: the quartic over κ, within the 0.023 end correction
    x = -1.0
    quartic = 1.15 + 1.125 - 1.372 + 1.718 - 0.655
    assert float(induced_velocity_ratio(x)) == pytest.approx(quartic / VORTEX_RING_KAPPA, abs=0.023)
    # continuous at both ends of the bridge (the windmill branch meets it with a square-root
    # slope, hence the small step)
    for edge in (0.0, -2.0):
        both = induced_velocity_ratio([edge - 1e-12, edge + 1e-12])
        assert both[0] == pytest.approx(both[1], abs=1e-5)
    # the vortex ring raises the induced velocity above hover's
    assert np.all(induced_velocity_ratio(np.linspace(-1.9, -0.1, 19)) > 1.0)


def test_power_ratio_rises_with_climb_rate_and_returns_nothing_in_descent() -> None:
    climb = np.linspace(-30.0, 20.0, 1001)
    ratio = axial_induced_power_ratio(climb, 5.0)
    assert np.all(np.diff(ratio) >= -1e-12)
    assert np.all(ratio >= 0.0)
    assert np.all(ratio[climb < 0] < 1.0)
    assert np.all(ratio[climb <= -10.0] == 0.0)  # windmill: the rotors would give power back
