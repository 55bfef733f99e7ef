"""Flight-state kinematics: speed, tangential and centripetal acceleration (horizontal plane).

Frames: velocity and acceleration are horizontal NED components (north, east), m/s and m/s².
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Below about this speed the direction of flight is noise; a⊥ is faded out smoothly.
DEFAULT_SPEED_FLOOR_MPS = 0.5


def centripetal_accel_mps2(
    vn_mps: ArrayLike,
    ve_mps: ArrayLike,
    an_mps2: ArrayLike,
    ae_mps2: ArrayLike,
    speed_floor_mps: float = DEFAULT_SPEED_FLOOR_MPS,
) -> NDArray[np.float64]:
    """a⊥ = |v × a| / |v| with a continuous low-speed treatment.

    The exact a⊥ is undefined at V = 0. We use |v × a| / sqrt(V² + V_f²): equal to a⊥ within
    1 − V_f²/(2V²) above the floor (3 % at 2 m/s for V_f = 0.5 m/s), tending to 0 in hover,
    continuous everywhere. A fixed-radius turn has a⊥ = V²/r → 0 as V → 0 anyway.
    """
    vn, ve = np.asarray(vn_mps, dtype=float), np.asarray(ve_mps, dtype=float)
    an, ae = np.asarray(an_mps2, dtype=float), np.asarray(ae_mps2, dtype=float)
    cross = np.abs(vn * ae - ve * an)
    return np.asarray(cross / np.sqrt(vn * vn + ve * ve + speed_floor_mps**2), dtype=float)


def tangential_accel_mps2(
    vn_mps: ArrayLike,
    ve_mps: ArrayLike,
    an_mps2: ArrayLike,
    ae_mps2: ArrayLike,
    speed_floor_mps: float = DEFAULT_SPEED_FLOOR_MPS,
) -> NDArray[np.float64]:
    """Signed acceleration along the velocity, vᵀa / sqrt(V² + V_f²) (same treatment as a⊥)."""
    vn, ve = np.asarray(vn_mps, dtype=float), np.asarray(ve_mps, dtype=float)
    an, ae = np.asarray(an_mps2, dtype=float), np.asarray(ae_mps2, dtype=float)
    dot = vn * an + ve * ae
    return np.asarray(dot / np.sqrt(vn * vn + ve * ve + speed_floor_mps**2), dtype=float)
