"""Lithium-polymer pack model: open-circuit voltage, state of charge, usable energy.

The per-cell OCV(SoC) table is a typical LiPo discharge curve at rest (room temperature),
used unless the vehicle file gives its pack's own (``[battery] cell_ocv_v``); SoC is the
fraction of rated charge left (1 = full). Energy integrates OCV over charge, so it
is the chemical energy the pack can deliver before resistive losses (those are I²R, counted
by whoever knows the current).
"""

from __future__ import annotations

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


class PackModel:
    """A pack of ``spec.cells`` LiPo cells in series with ``spec.capacity_ah`` rated charge."""

    def __init__(self, spec: BatterySpec, internal_resistance_ohm: float = 0.0) -> None:
        self.spec = spec
        self.internal_resistance_ohm = internal_resistance_ohm
        #: Resting cell voltage (V) at each of :data:`SOC_POINTS`.
        self.cell_ocv_v = (
            CELL_OCV_POINTS_V if spec.cell_ocv_v is None else np.asarray(spec.cell_ocv_v)
        )
        # energy per cell per Ah from SoC 0 up to each table point (Wh/Ah), trapezoids
        mid_v = 0.5 * (self.cell_ocv_v[1:] + self.cell_ocv_v[:-1])
        self._cum_wh_per_ah = np.concatenate(([0.0], np.cumsum(np.diff(SOC_POINTS) * mid_v)))

    def ocv_v(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Pack open-circuit voltage (V) at state of charge ``soc`` (clipped to [0, 1])."""
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        return np.asarray(self.spec.cells * np.interp(s, SOC_POINTS, self.cell_ocv_v))

    def soc_from_ocv(self, pack_voltage_v: ArrayLike) -> NDArray[np.float64]:
        """State of charge of a pack resting at ``pack_voltage_v`` (V), clipped to [0, 1]."""
        cell_v = np.asarray(pack_voltage_v, dtype=float) / self.spec.cells
        return np.asarray(np.interp(cell_v, self.cell_ocv_v, SOC_POINTS))

    def terminal_voltage_v(self, soc: ArrayLike, current_a: ArrayLike) -> NDArray[np.float64]:
        """Voltage at the pack's terminals under load: OCV − I·R (V)."""
        return self.ocv_v(soc) - np.asarray(current_a, dtype=float) * self.internal_resistance_ohm

    def energy_wh(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Chemical energy from empty (SoC 0) up to ``soc``, Wh."""
        s = np.clip(np.asarray(soc, dtype=float), 0.0, 1.0)
        per_ah = np.interp(s, SOC_POINTS, self._cum_wh_per_ah)
        return np.asarray(self.spec.cells * self.spec.capacity_ah * per_ah)

    def usable_energy_wh(self, soc: ArrayLike) -> NDArray[np.float64]:
        """Energy left above the configured reserve, Wh (0 when already in the reserve)."""
        reserve_wh = self.energy_wh(self.spec.reserve_fraction)
        return np.maximum(self.energy_wh(soc) - reserve_wh, 0.0)

    def soc_from_energy(self, energy_wh: ArrayLike) -> NDArray[np.float64]:
        """Inverse of :meth:`energy_wh`: the SoC holding ``energy_wh`` above empty."""
        per_ah = np.asarray(energy_wh, dtype=float) / (self.spec.cells * self.spec.capacity_ah)
        return np.asarray(np.interp(per_ah, self._cum_wh_per_ah, SOC_POINTS))
