"""Lithium pack model: open-circuit voltage, state of charge, usable energy.

The per-cell OCV(SoC) table is a typical resting discharge curve (room temperature) of the
pack's chemistry (:data:`CHEMISTRY_OCV_V`: LiPo, LiHV, Li-ion), used unless the vehicle file
gives its pack's own (``[battery] cell_ocv_v``); SoC is the fraction of the pack's charge left
(1 = full). Energy integrates OCV over charge, so it is the chemical energy the pack can
deliver before resistive losses (those are I²R, counted by whoever knows the current).
"""

from __future__ import annotations

import bisect
import copy
import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from estimator.physics.vehicle import BatterySpec

#: State of charge (fraction) and the matching resting cell voltage (V), ascending.
SOC_POINTS = np.linspace(0.0, 1.0, 21)
CELL_OCV_POINTS_V = np.array(
    [
        3.27,
        3.61,
        3.69,
        3.71,
        3.73,
        3.75,
        3.77,
        3.79,
        3.80,
        3.82,
        3.84,
        3.85,
        3.87,
        3.91,
        3.95,
        3.98,
        4.02,
        4.08,
        4.11,
        4.15,
        4.20,
    ]
)


#: Li-ion (NMC 18650/21700) cells: a steadier slope than LiPo's and a deeper usable range
#: (typical resting curve of NMC cells at 25 °C, e.g. Plett, *Battery Management Systems*
#: vol. 1, ch. 2, fig. 2.5; fit your pack's own with ``uav-energy fit``, docs/fit.md).
LIION_CELL_OCV_V = np.array(
    [3.00, 3.30, 3.42, 3.50, 3.55, 3.59, 3.62, 3.65, 3.68, 3.71, 3.75,
     3.79, 3.83, 3.87, 3.92, 3.96, 4.01, 4.05, 4.09, 4.14, 4.19]
)  # fmt: skip
#: LiHV cells charge to 4.35 V: the LiPo curve stretched above its knee (3.27 V at SoC 0)
#: so that full reads 4.35 V instead of 4.20 V.
LIHV_CELL_OCV_V = 3.27 + (CELL_OCV_POINTS_V - 3.27) * (4.35 - 3.27) / (4.20 - 3.27)
#: Resting cell voltage (V) at :data:`SOC_POINTS` by chemistry (``[battery] chemistry``).
CHEMISTRY_OCV_V = {"lipo": CELL_OCV_POINTS_V, "lihv": LIHV_CELL_OCV_V, "liion": LIION_CELL_OCV_V}


def interp_scalar(x: float, xp: Sequence[float], fp: Sequence[float]) -> float:
    """``np.interp(x, xp, fp)`` of one value, the same float (the same steps: ends held, a
    table point's own value, else the slope from the point below), without numpy's cost per
    call. ``xp`` ascending."""
    if math.isnan(x):
        return x
    j = bisect.bisect_right(xp, x) - 1
    if j < 0:
        return fp[0]
    if j >= len(xp) - 1:  # at or beyond the last point
        return fp[-1]
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    value = slope * (x - xp[j]) + fp[j]
    if math.isnan(value):
        value = slope * (x - xp[j + 1]) + fp[j + 1]
        if math.isnan(value) and fp[j] == fp[j + 1]:
            value = fp[j]
    return value


class PackModel:
    """A pack of ``spec.cells`` lithium cells in series with ``spec.capacity_ah`` charge."""

    def __init__(self, spec: BatterySpec, internal_resistance_ohm: float = 0.0) -> None:
        self.spec = spec
        self.internal_resistance_ohm = internal_resistance_ohm
        #: Resting cell voltage (V) at :attr:`soc_points` (evenly spaced from SoC 0 to 1:
        #: :data:`SOC_POINTS` for the built-in curves, as many as a pack's own table has).
        self.cell_ocv_v = (
            CHEMISTRY_OCV_V[spec.chemistry]
            if spec.cell_ocv_v is None
            else np.asarray(spec.cell_ocv_v, dtype=float)
        )
        # energy per cell per Ah from SoC 0 up to each table point (Wh/Ah), trapezoids
        mid_v = 0.5 * (self.cell_ocv_v[1:] + self.cell_ocv_v[:-1])
        self.soc_points = np.linspace(0.0, 1.0, len(self.cell_ocv_v))
        self._segments = len(self.cell_ocv_v) - 1
        self._cum_wh_per_ah = np.concatenate(([0.0], np.cumsum(mid_v / self._segments)))
        self._ocv_list = [float(v) for v in self.cell_ocv_v]
        self._cum_list = [float(v) for v in self._cum_wh_per_ah]
        self._soc_list = [float(v) for v in self.soc_points]

    def with_capacity(self, capacity_ah: float) -> PackModel:
        """The same pack (curve, cells, reserve, resistance) holding ``capacity_ah`` (Ah). The
        curve's tables do not depend on the capacity: the new pack shares them (the pack
        filter's capacity moves at every reading)."""
        pack = copy.copy(self)
        pack.spec = dataclasses.replace(self.spec, capacity_ah=capacity_ah)
        return pack

    def cell_ocv_slope_v(self, soc: float) -> tuple[float, float]:
        """Resting cell voltage (V) at ``soc`` and its slope dOCV/dSoC (V per unit SoC),
        the table's end segments extended in a straight line beyond SoC 0 and 1 (so that a
        filter whose state strays past an end still sees which way to go). Scalar."""
        n = self._segments
        i = min(max(int(soc * n), 0), n - 1)
        v0, v1 = self._ocv_list[i], self._ocv_list[i + 1]
        slope = (v1 - v0) * n
        return v0 + slope * (soc - i / n), slope

    def cell_energy_wh_per_ah(self, soc: float) -> float:
        """Energy per cell and Ah from SoC 0 up to ``soc`` (Wh/Ah = V·unit SoC), clipped to
        [0, 1]. Scalar."""
        s = min(max(soc, 0.0), 1.0)
        n = self._segments
        i = min(int(s * n), n - 1)
        f = s * n - i
        v0, v1 = self._ocv_list[i], self._ocv_list[i + 1]
        return self._cum_list[i] + (v0 + 0.5 * f * (v1 - v0)) * f / n

    def ocv_scalar_v(self, soc: float) -> float:
        """:meth:`ocv_v` of one state of charge (the same value, V), in scalar arithmetic."""
        s = min(max(float(soc), 0.0), 1.0)
        return self.spec.cells * interp_scalar(s, self._soc_list, self._ocv_list)

    def energy_scalar_wh(self, soc: float) -> float:
        """:meth:`energy_wh` of one state of charge (the same value, Wh), scalar."""
        s = min(max(float(soc), 0.0), 1.0)
        per_ah = interp_scalar(s, self._soc_list, self._cum_list)
        return self.spec.cells * self.spec.capacity_ah * per_ah

    def soc_from_energy_scalar(self, energy_wh: float) -> float:
        """:meth:`soc_from_energy` of one energy (the same value), scalar."""
        per_ah = float(energy_wh) / (self.spec.cells * self.spec.capacity_ah)
        return interp_scalar(per_ah, self._cum_list, self._soc_list)

    def ocv_from_energy_v(self, energy_wh: ArrayLike) -> NDArray[np.float64]:
        """Pack open-circuit voltage (V) where the pack holds ``energy_wh`` (Wh above empty):
        :meth:`ocv_v` of :meth:`soc_from_energy` in one interpolation (both are linear on the
        same table segments, so their composition is the table of OCV against energy)."""
        per_ah = np.asarray(energy_wh, dtype=float) / (self.spec.cells * self.spec.capacity_ah)
        return np.asarray(self.spec.cells * np.interp(per_ah, self._cum_wh_per_ah, self.cell_ocv_v))

    def ocv_v(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Pack open-circuit voltage (V) at state of charge ``soc`` (clipped to [0, 1])."""
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        return np.asarray(self.spec.cells * np.interp(s, self.soc_points, self.cell_ocv_v))

    def soc_from_ocv(self, pack_voltage_v: ArrayLike) -> NDArray[np.float64]:
        """State of charge of a pack resting at ``pack_voltage_v`` (V), clipped to [0, 1]."""
        cell_v = np.asarray(pack_voltage_v, dtype=float) / self.spec.cells
        return np.asarray(np.interp(cell_v, self.cell_ocv_v, self.soc_points))

    def terminal_voltage_v(self, soc: ArrayLike, current_a: ArrayLike) -> NDArray[np.float64]:
        """Voltage at the pack's terminals under load: OCV − I·R (V)."""
        return self.ocv_v(soc) - np.asarray(current_a, dtype=float) * self.internal_resistance_ohm

    def energy_wh(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Chemical energy from empty (SoC 0) up to ``soc``, Wh."""
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        per_ah = np.interp(s, self.soc_points, self._cum_wh_per_ah)
        return np.asarray(self.spec.cells * self.spec.capacity_ah * per_ah)

    def usable_energy_wh(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Energy left above the configured reserve, Wh (0 when already in the reserve)."""
        reserve_wh = self.energy_wh(self.spec.reserve_fraction)
        return np.maximum(self.energy_wh(soc) - reserve_wh, 0.0)

    def soc_from_energy(self, energy_wh: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`energy_wh`: the SoC holding ``energy_wh`` above empty."""
        per_ah = np.asarray(energy_wh, dtype=float) / (self.spec.cells * self.spec.capacity_ah)
        return np.asarray(np.interp(per_ah, self._cum_wh_per_ah, self.soc_points))
