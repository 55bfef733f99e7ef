"""Rotary-wing propulsion power models: pure numpy, vectorized, no I/O.

References
----------
- Y. Zeng, J. Xu, R. Zhang, "Energy minimization for wireless communication with rotary-wing
  UAV", IEEE TWC 2019: eq. (12) power model and the physical meaning of its parameters.
- The seed paper (``shared/seed/energy-model-uav-communications.tex``): eq. (1), the same model
  with five fitted coefficients c1..c5, and eq. (2), its heuristic generalization to 2-D level
  flight with centripetal acceleration a⊥ and the kinetic-energy change.

All inputs are SI: speeds are horizontal *airspeed* magnitudes (m/s), accelerations m/s²,
power W. When the coefficients are fitted to battery data they are electrical power at the
battery (propulsion efficiency folded in).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

G_MPS2 = 9.80665
SEA_LEVEL_DENSITY_KGPM3 = 1.225
COEFFICIENT_NAMES = ("c1", "c2", "c3", "c4", "c5")

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PowerModel:
    """Eq. (1)/(2) of the seed paper.

    c1: blade-profile power in hover, W.          c2: 3/U_tip², s²/m².
    c3: induced power in hover, W.                c4: 2·v0² (v0 hover induced velocity), m²/s².
    c5: parasite (fuselage drag) coefficient, W·s³/m³.
    """

    c1: float
    c2: float
    c3: float
    c4: float
    c5: float

    def __post_init__(self) -> None:
        for name in COEFFICIENT_NAMES:
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f"coefficient {name} must be finite and ≥ 0, got {value}")
        if self.c4 <= 0.0:
            raise ValueError("power model coefficient c4 must be > 0")

    # -- evaluation ----------------------------------------------------------------------------

    def power_w(
        self,
        speed_mps: ArrayLike,
        accel_centripetal_mps2: ArrayLike = 0.0,
        mass_ratio: ArrayLike = 1.0,
        density_ratio: float = 1.0,
    ) -> FloatArray:
        """Power in level flight at airspeed V with centripetal acceleration a⊥, W.

        With a⊥ = 0 this is eq. (1); otherwise the integrand of eq. (2) without the
        kinetic-energy term (add :func:`kinetic_power_w` for an instantaneous prediction).
        Blade profile c1 (1 + c2 V²) + induced c3 n (sqrt(n² + V⁴/c4²) − V²/c4)^½ + parasite
        c5 V³, with the load factor n² = 1 + a⊥²/g². ``mass_ratio`` (per sample) and
        ``density_ratio`` evaluate :meth:`rescaled` models without building them.
        """
        return level_power_w(
            self.scaled(mass_ratio, density_ratio), speed_mps, accel_centripetal_mps2
        )

    def induced_w(
        self,
        speed_mps: ArrayLike,
        load_factor2: ArrayLike,
        mass_ratio: ArrayLike = 1.0,
        density_ratio: float = 1.0,
    ) -> FloatArray:
        """Eq. (2)'s induced term at airspeed V (m/s) and squared load factor n² (thrust over
        weight, squared): c3 n (sqrt(n² + V⁴/c4²) − V²/c4)^½, W (rescaled like
        :meth:`power_w`)."""
        return induced_power_w(self.scaled(mass_ratio, density_ratio), speed_mps, load_factor2)

    def hover_induced_velocity_mps(
        self, mass_ratio: ArrayLike = 1.0, density_ratio: float = 1.0
    ) -> FloatArray:
        """Mean rotor induced velocity in hover v0 = sqrt(c4 / 2), m/s (rescaled like
        :meth:`power_w`)."""
        return hover_induced_velocity_mps(self.scaled(mass_ratio, density_ratio))

    @property
    def hover_power_w(self) -> float:
        """P(0) = c1 + c3, W."""
        return self.c1 + self.c3

    # -- characteristic speeds -------------------------------------------------------------------

    def max_endurance_speed_mps(self, max_speed_mps: float = 30.0) -> float:
        """V_me = argmin P(V) on [0, max_speed_mps], m/s."""
        return _argmin_on_grid(lambda v: self.power_w(v), 0.0, max_speed_mps)

    def max_range_speed_mps(self, max_speed_mps: float = 30.0) -> float:
        """V_mr = argmin P(V)/V on (0, max_speed_mps], m/s (energy per metre is lowest)."""
        return _argmin_on_grid(lambda v: self.power_w(v) / v, 0.05, max_speed_mps)

    # -- parametrizations --------------------------------------------------------------------------

    def as_array(self) -> FloatArray:
        """[c1, c2, c3, c4, c5]."""
        return np.array([self.c1, self.c2, self.c3, self.c4, self.c5])

    @classmethod
    def from_array(cls, values: ArrayLike) -> PowerModel:
        c = np.asarray(values, dtype=float)
        return cls(*(float(x) for x in c))

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def hover_parameters(self) -> HoverParameters:
        """The same model in the well-conditioned hover parametrization."""
        return HoverParameters(
            hover_power_w=self.hover_power_w,
            profile_fraction=self.c1 / self.hover_power_w,
            tip_speed_mps=math.sqrt(3.0 / self.c2) if self.c2 > 0 else math.inf,
            induced_velocity_mps=math.sqrt(self.c4 / 2.0),
            parasite_coeff=self.c5,
        )

    def rescaled(self, mass_ratio: float = 1.0, density_ratio: float = 1.0) -> PowerModel:
        """The model for mass m·mass_ratio and air density ρ·density_ratio (:meth:`scaled`)."""
        if mass_ratio <= 0 or density_ratio <= 0:
            raise ValueError("mass and density ratios must be > 0")
        return PowerModel(*(float(c) for c in self.scaled(mass_ratio, density_ratio)))

    def scaled(self, mass_ratio: ArrayLike = 1.0, density_ratio: float = 1.0) -> Coefficients:
        """c1..c5 for mass m·mass_ratio (one float, or one per sample) and air density
        ρ·density_ratio, from Zeng et al.'s parameters: c1 ∝ ρ, c2 fixed (tip speed),
        c3 ∝ W^{3/2} ρ^{-1/2}, c4 ∝ W/ρ, c5 ∝ ρ."""
        ratio = mass_ratio if isinstance(mass_ratio, float) else np.asarray(mass_ratio, dtype=float)
        return (
            self.c1 * density_ratio,
            self.c2,
            self.c3 * ratio**1.5 / math.sqrt(density_ratio),
            self.c4 * ratio / density_ratio,
            self.c5 * density_ratio,
        )


#: A model's c1..c5 as :meth:`PowerModel.scaled` gives them (floats, or arrays per sample).
Coefficients = tuple[float | FloatArray, ...]


def level_power_w(
    coefficients: Coefficients, speed_mps: ArrayLike, accel_centripetal_mps2: ArrayLike = 0.0
) -> FloatArray:
    """:meth:`PowerModel.power_w` with the (rescaled) ``coefficients``, W."""
    c1, c2, c3, c4, c5 = coefficients
    v = np.asarray(speed_mps, dtype=float)
    v2 = v * v
    load2 = 1.0 + np.square(np.asarray(accel_centripetal_mps2, dtype=float) / G_MPS2)
    induced = _induced_w(c3, c4, v2, load2)
    return np.asarray(c1 * (1.0 + c2 * v2) + induced + c5 * v2 * v, dtype=float)


def induced_power_w(
    coefficients: Coefficients, speed_mps: ArrayLike, load_factor2: ArrayLike
) -> FloatArray:
    """:meth:`PowerModel.induced_w` with the (rescaled) ``coefficients``, W."""
    v = np.asarray(speed_mps, dtype=float)
    return _induced_w(
        coefficients[2], coefficients[3], v * v, np.asarray(load_factor2, dtype=float)
    )


def hover_induced_velocity_mps(coefficients: Coefficients) -> FloatArray:
    """:meth:`PowerModel.hover_induced_velocity_mps` with the (rescaled) ``coefficients``, m/s."""
    return np.asarray(np.sqrt(0.5 * coefficients[3]), dtype=float)


def _induced_w(
    c3: float | FloatArray, c4: float | FloatArray, v2: FloatArray, load2: FloatArray
) -> FloatArray:
    """Eq. (2)'s induced term, W, from the (rescaled) c3 and c4, V² (m²/s²) and n²."""
    v2_c4 = v2 / c4
    return np.asarray(c3 * np.sqrt(load2 * (np.sqrt(load2 + v2_c4 * v2_c4) - v2_c4)))


@dataclass(frozen=True)
class HoverParameters:
    """Well-conditioned parametrization of :class:`PowerModel`.

    hover_power_w: P(0) = c1 + c3, W — the best-determined quantity in any flight.
    profile_fraction: c1 / (c1 + c3), the share of hover power that is blade profile (0..1).
    tip_speed_mps: rotor blade tip speed U_tip, m/s (c2 = 3 / U_tip²).
    induced_velocity_mps: mean rotor induced velocity in hover v0, m/s (c4 = 2 v0²).
    parasite_coeff: c5 = ½ d0 ρ s A, W·s³/m³.
    """

    hover_power_w: float
    profile_fraction: float
    tip_speed_mps: float
    induced_velocity_mps: float
    parasite_coeff: float

    def to_model(self) -> PowerModel:
        c1 = self.profile_fraction * self.hover_power_w
        return PowerModel(
            c1=c1,
            c2=3.0 / self.tip_speed_mps**2,
            c3=self.hover_power_w - c1,
            c4=2.0 * self.induced_velocity_mps**2,
            c5=self.parasite_coeff,
        )


@dataclass(frozen=True)
class RotorcraftPhysics:
    """Physical airframe parameters in Zeng et al.'s notation; all rotors lumped together.

    mass_kg: take-off mass. air_density_kgpm3: ρ. rotor_radius_m: R of one rotor.
    rotor_count: number of rotors (disc area A = n π R²). tip_speed_mps: U_tip = Ω R.
    solidity: s, blade area over disc area. profile_drag_coeff: δ. induced_correction: k.
    fuselage_drag_ratio: d0.
    """

    mass_kg: float
    rotor_radius_m: float
    rotor_count: int = 4
    tip_speed_mps: float = 120.0
    solidity: float = 0.05
    profile_drag_coeff: float = 0.012
    induced_correction: float = 0.1
    fuselage_drag_ratio: float = 0.6
    air_density_kgpm3: float = SEA_LEVEL_DENSITY_KGPM3

    @property
    def disc_area_m2(self) -> float:
        return self.rotor_count * math.pi * self.rotor_radius_m**2

    def to_model(self) -> PowerModel:
        """Mechanical rotor power model (no electrical losses)."""
        rho, area, u_tip = self.air_density_kgpm3, self.disc_area_m2, self.tip_speed_mps
        weight_n = self.mass_kg * G_MPS2
        return PowerModel(
            c1=self.profile_drag_coeff / 8.0 * rho * self.solidity * area * u_tip**3,
            c2=3.0 / u_tip**2,
            c3=(1.0 + self.induced_correction) * weight_n**1.5 / math.sqrt(2.0 * rho * area),
            c4=weight_n / (rho * area),
            c5=0.5 * self.fuselage_drag_ratio * rho * self.solidity * area,
        )


def kinetic_power_w(mass_kg: float, velocity_mps: ArrayLike, accel_mps2: ArrayLike) -> FloatArray:
    """Rate of change of kinetic energy m vᵀa, W (eq. (2)'s ΔK, differentiated).

    ``velocity_mps`` and ``accel_mps2`` are vectors along the last axis (any frame, same one).
    """
    v = np.asarray(velocity_mps, dtype=float)
    a = np.asarray(accel_mps2, dtype=float)
    return np.asarray(mass_kg * np.sum(v * a, axis=-1), dtype=float)


def _argmin_on_grid(
    fn: Callable[[FloatArray], FloatArray], lo: float, hi: float, points: int = 601, rounds: int = 3
) -> float:
    """Global minimum of a 1-D function on [lo, hi]: a grid of ``points``, then ``rounds`` - 1
    grids as fine between the best point's neighbours (each shrinks the bracket 300×: on a
    30 m/s range the last spacing is ~1e-6 m/s). Vectorized calls of ``fn`` only, no scipy:
    the daemon's return figures use it."""
    a, b = lo, hi
    best_x, best_value = lo, math.inf
    for _ in range(rounds):
        grid = np.linspace(a, b, points)
        values = fn(grid)
        i = int(np.argmin(values))
        if values[i] < best_value:
            best_x, best_value = float(grid[i]), float(values[i])
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, points - 1)]
        if b <= a:
            break
    return best_x
