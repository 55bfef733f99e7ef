"""Rotor induced velocity in axial flight (climb and descent), by momentum theory.

References
----------
- J. G. Leishman, *Principles of Helicopter Aerodynamics*, 2nd ed., Cambridge University
  Press 2006, ch. 2 (momentum theory in axial flight):

  * climb (V_c ≥ 0): v_i/v_h = −V_c/(2 v_h) + sqrt((V_c/(2 v_h))² + 1);
  * windmill brake state (V_c ≤ −2 v_h): v_i/v_h = −V_c/(2 v_h) − sqrt((V_c/(2 v_h))² − 1);
  * between them (−2 v_h < V_c < 0, the vortex ring and turbulent wake states) momentum theory
    has no valid solution; the measured induced velocity is approximated by the quartic
    v_i/v_h = κ + k1 x + k2 x² + k3 x³ + k4 x⁴, x = V_c/v_h, with κ = 1.15, k1 = −1.125,
    k2 = −1.372, k3 = −1.718, k4 = −0.655.

v_h = sqrt(T / (2 ρ A)) is the hover induced velocity; the power model holds it as
v0 = sqrt(c4 / 2) (:meth:`~estimator.physics.model.PowerModel.hover_induced_velocity_mps`).
The ideal rotor power is T (V_c + v_i).

The quartic's κ is the induced power factor of the measured rotors (1.15 in hover, where
ideal momentum theory gives 1); the power model's c3 already holds the vehicle's own hover
induced power, so the bridge here is the quartic divided by κ, plus the linear term
x (q(−2)/κ − 1)/2 that makes it meet the windmill branch at x = −2 (a change of at most
0.023 v_h). The induced ratio is then continuous from climb through the vortex ring to the
windmill state, 1 in hover.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from estimator.physics.model import FloatArray

#: Leishman's vortex-ring quartic: κ and k1..k4 of v_i/v_h = κ + k1 x + … + k4 x⁴.
VORTEX_RING_KAPPA = 1.15
VORTEX_RING_K = (-1.125, -1.372, -1.718, -0.655)
#: The windmill brake state starts at V_c / v_h = −2.
WINDMILL_CLIMB_RATIO = -2.0


def _vortex_ring_quartic(x: FloatArray) -> FloatArray:
    k1, k2, k3, k4 = VORTEX_RING_K
    return VORTEX_RING_KAPPA + x * (k1 + x * (k2 + x * (k3 + x * k4)))


_WINDMILL_EDGE_MISMATCH = (
    float(_vortex_ring_quartic(np.array(WINDMILL_CLIMB_RATIO))) / VORTEX_RING_KAPPA - 1.0
)


def induced_velocity_ratio(climb_ratio: ArrayLike) -> FloatArray:
    """v_i / v_h at the climb rate x = V_c / v_h (both m/s, V_c positive up), per sample.

    Climb branch for x ≥ 0, windmill branch for x ≤ −2, the normalised vortex-ring quartic
    between them (module docstring). 1 in hover.
    """
    x = np.asarray(climb_ratio, dtype=float)
    half = 0.5 * x
    climb = np.sqrt(half * half + 1.0) - half
    descends = x < 0.0
    if not descends.any():  # every sample climbs or hovers: the other branches are not used
        return climb
    bridge = _vortex_ring_quartic(x) / VORTEX_RING_KAPPA + half * _WINDMILL_EDGE_MISMATCH
    windmill_state = x <= WINDMILL_CLIMB_RATIO
    if not windmill_state.any():  # nothing descends into the windmill state
        return np.where(descends, bridge, climb)
    windmill = -half - np.sqrt(np.maximum(half * half - 1.0, 0.0))
    return np.where(descends, np.where(windmill_state, windmill, bridge), climb)


def axial_induced_power_ratio(climb_mps: ArrayLike, hover_induced_mps: ArrayLike) -> FloatArray:
    """Ideal rotor power in axial flight over ideal hover induced power, (V_c + v_i) / v_h
    (≥ 0), at climb rate ``climb_mps`` (m/s, up) and hover induced velocity
    ``hover_induced_mps`` (m/s, > 0).

    Where the rotors would extract power from the air (the windmill state and the fast end
    of the vortex ring, V_c + v_i < 0), the ratio is 0: the motors' controllers do not
    return it to the battery.
    """
    x = np.asarray(climb_mps, dtype=float) / hover_induced_mps
    return np.maximum(x + induced_velocity_ratio(x), 0.0)
