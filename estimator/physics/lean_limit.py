"""How fast a multicopter can fly through the air where its nose does not point along the
track: its lean limit against a drag that acts per body axis.

ArduPilot describes a multicopter's horizontal drag per body axis (EKF3's parameters
EK3_DRAG_BCOEF_X / EK3_DRAG_BCOEF_Y, ballistic coefficients in kg/m², and EK3_DRAG_MCOEF, the
rotors' momentum drag in 1/s): the deceleration along body x is ½ ρ vx |vx| / BCOEF_X +
MCOEF vx, and likewise along y (ArduPilot's EKF3 parameter documentation; its SITL multicopter
flies this law, libraries/SITL/SIM_Frame.cpp). At its lean limit the vehicle balances a fixed
horizontal force, so the fastest airspeed depends on where the nose points: airspeed 45° off
the nose meets only 1/√2 of the quadratic drag of the same airspeed straight ahead.

The vehicle file's ``max_airspeed_mps`` is the fastest airspeed straight ahead; it fixes the
deceleration the lean limit balances (g tan of the lean, whatever the mass), and
:func:`along_track_limit_mps` gives the airspeed along a track flown with the nose at
``heading_deg`` that meets the same deceleration. The coefficients hold at the vehicle file's
mass: a payload scales them (:meth:`DragLaw.at_mass_ratio`), so a heavier vehicle flies
faster at the same lean.
Velocities in m/s (north, east: airspeed is ground velocity less the wind's), angles in degrees
clockwise from north.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

#: Sea-level air density (kg/m³), as EKF3 scales its drag coefficients.
SEA_LEVEL_AIR_DENSITY_KGPM3 = 1.225
#: Bisection steps for the ground speed at the limit (m/s resolution ≈ span / 2⁶⁰).
_BISECTION_STEPS = 60


@dataclass(frozen=True)
class DragLaw:
    """A multicopter's horizontal drag per body axis: ballistic coefficients along x (nose)
    and y (right), kg/m², and momentum drag, 1/s (the EKF3 parameters' meanings)."""

    bcoef_x_kgpm2: float
    bcoef_y_kgpm2: float
    mcoef_per_s: float

    def at_mass_ratio(self, mass_ratio: float) -> DragLaw:
        """The law of the same airframe at ``mass_ratio`` times the mass it was stated at:
        a ballistic coefficient is mass over drag area (× ratio), and the rotors' momentum drag
        grows with the square root of their thrust, the weight (÷ √ratio of deceleration)."""
        return DragLaw(
            self.bcoef_x_kgpm2 * mass_ratio,
            self.bcoef_y_kgpm2 * mass_ratio,
            self.mcoef_per_s / math.sqrt(mass_ratio),
        )

    def deceleration_mps2(self, x_mps: float, y_mps: float) -> float:
        """The drag's deceleration (m/s²) at airspeed ``x_mps`` along the nose and ``y_mps``
        to its right (body frame, level)."""
        half_rho = 0.5 * SEA_LEVEL_AIR_DENSITY_KGPM3
        ax = half_rho * x_mps * abs(x_mps) / self.bcoef_x_kgpm2 + self.mcoef_per_s * x_mps
        ay = half_rho * y_mps * abs(y_mps) / self.bcoef_y_kgpm2 + self.mcoef_per_s * y_mps
        return math.hypot(ax, ay)


def along_track_limit_mps(
    law: DragLaw,
    straight_limit_mps: float,
    wind_ne_mps: tuple[float, float],
    track_deg: float,
    heading_deg: float,
    mass_ratio: float = 1.0,
) -> float:
    """The airspeed along ``track_deg`` (m/s) at which a vehicle flying with its nose at
    ``heading_deg`` and ``mass_ratio`` times the mass ``law`` was stated at (a payload) meets
    the deceleration of ``straight_limit_mps`` straight ahead at that mass, in the
    wind ``wind_ne_mps`` (the air's velocity over the ground, north and east); −inf when no
    airspeed along the track is left (the wind across it alone needs the limit). Equals
    ``straight_limit_mps`` in still air with the nose along the track."""
    limit_mps2 = law.deceleration_mps2(straight_limit_mps, 0.0)
    law = law.at_mass_ratio(mass_ratio)
    un, ue = math.cos(math.radians(track_deg)), math.sin(math.radians(track_deg))
    hn, he = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
    wind_along = wind_ne_mps[0] * un + wind_ne_mps[1] * ue

    def deceleration(ground_mps: float) -> float:
        an, ae = ground_mps * un - wind_ne_mps[0], ground_mps * ue - wind_ne_mps[1]
        return law.deceleration_mps2(an * hn + ae * he, -an * he + ae * hn)

    low = max(wind_along, 0.0)  # the least airspeed along the track (none, or a tailwind's)
    if deceleration(low) >= limit_mps2:
        return -math.inf
    high = low + 2.0 * straight_limit_mps + 2.0 * math.hypot(*wind_ne_mps)
    low = _fastest_mps(deceleration, limit_mps2, low, high)
    return low - wind_along if low > wind_along else -math.inf


def _fastest_mps(
    deceleration: Callable[[float], float], limit_mps2: float, low: float, high: float
) -> float:
    """The speed (m/s) between ``low`` (below the limit) and ``high`` (above it) at which
    ``deceleration`` (m/s², growing with the speed) meets ``limit_mps2``, by bisection."""
    for _ in range(_BISECTION_STEPS):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if deceleration(middle) < limit_mps2 else (low, middle)
    return low


def airspeed_reach_mps(law: DragLaw | None, straight_limit_mps: float) -> float:
    """The fastest airspeed (m/s) at the lean limit in any direction off the nose: the
    deceleration of ``straight_limit_mps`` straight ahead met by an airspeed at 0–90° off the
    nose (1° steps; with equal quadratic coefficients the most is 2^¼ times the straight limit,
    at 45°). Without a drag law, ``straight_limit_mps``."""
    if law is None:
        return straight_limit_mps
    limit_mps2 = law.deceleration_mps2(straight_limit_mps, 0.0)
    drag = law

    def off_the_nose(off_deg: int) -> Callable[[float], float]:
        cos_off, sin_off = math.cos(math.radians(off_deg)), math.sin(math.radians(off_deg))
        return lambda air_mps: drag.deceleration_mps2(air_mps * cos_off, air_mps * sin_off)

    high_mps = 4.0 * straight_limit_mps
    return max(
        straight_limit_mps,
        *(_fastest_mps(off_the_nose(d), limit_mps2, 0.0, high_mps) for d in range(91)),
    )
