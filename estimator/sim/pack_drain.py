"""The simulated LiPo pack: open-circuit voltage by state of charge and the drain at a
given electrical power through the internal resistance (V, A, W, s).
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from estimator.physics.battery import SOC_POINTS, PackModel
from estimator.physics.model import FloatArray
from estimator.sim.run import DT_S

_SOC_LIST = [float(s) for s in SOC_POINTS]


def _cell_ocv_v(ocv_list: list[float], soc: float) -> float:
    """Scalar, fast version of PackModel.ocv_v per cell (``ocv_list``: the pack's table)."""
    if soc <= 0.0:
        return ocv_list[0]
    if soc >= 1.0:
        return ocv_list[-1]
    i = bisect.bisect_right(_SOC_LIST, soc) - 1
    f = (soc - _SOC_LIST[i]) / (_SOC_LIST[i + 1] - _SOC_LIST[i])
    return ocv_list[i] + f * (ocv_list[i + 1] - ocv_list[i])


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
    ocv_list = [float(v) for v in pack.cell_ocv_v]
    soc = soc0
    for i in range(n):
        ocv = cells * _cell_ocv_v(ocv_list, soc)
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
