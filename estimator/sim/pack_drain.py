"""The simulated LiPo pack: open-circuit voltage by state of charge and the drain at a
given electrical power through the internal resistance (V, A, W, s).
"""

from __future__ import annotations

import math

import numpy as np

from estimator.physics.battery import PackModel
from estimator.physics.model import FloatArray
from estimator.sim.run import DT_S


def _cell_ocv_v(pack: PackModel, soc: float) -> float:
    """Scalar, fast version of PackModel.ocv_v per cell (clipped to the table's ends)."""
    return pack.cell_ocv_slope_v(min(max(soc, 0.0), 1.0))[0]


def drain_pack(
    pack: PackModel, power_w: FloatArray, soc0: float
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """Terminal voltage, current and SoC (at the start of each step) for a power demand.

    I solves V·I = P with V = OCV − I·R. Returns how many steps the pack could deliver
    (fewer than asked when it is empty).
    """
    n = len(power_w)
    volts, amps, socs = np.empty(n), np.empty(n), np.empty(n)
    cells, r = pack.spec.cells, pack.internal_resistance_ohm
    per_step = DT_S / (3600.0 * pack.spec.capacity_ah)
    soc = soc0
    for i in range(n):
        ocv = cells * _cell_ocv_v(pack, soc)
        p = float(power_w[i])
        if r > 0:
            disc = ocv * ocv - 4.0 * r * p
            if disc < 0 or soc <= 0.0:
                return volts[:i], amps[:i], socs[:i], i
            current = (ocv - math.sqrt(disc)) / (2.0 * r)
        else:
            if soc <= 0.0:
                return volts[:i], amps[:i], socs[:i], i
            current = p / ocv
        volts[i], amps[i], socs[i] = ocv - current * r, current, soc
        soc -= current * per_step
    return volts, amps, socs, n
