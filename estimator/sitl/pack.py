"""SITL's simulated pack: its resting voltage by state of charge, and a pack to fly.

ArduPilot's SITL battery (libraries/SITL/SIM_Battery.cpp) keeps the charge left in Ah and
gives the resting voltage of one cell by state of charge from a table (4.173 V at 100 %),
scaled by the pack's ``maxVoltage`` / 4.173; under load it subtracts current × resistance and
low-pass filters the result. The multicopter frame takes ``battCapacityAh``, ``refBatRes`` and
``maxVoltage`` from the model JSON, and the charge at power-up from SIM_BATT_VOLTAGE: the
table read backwards at that voltage (``Battery::set_initial_SoC``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: SITL's resting cell voltage (V) by state of charge (%) (SIM_Battery.cpp ``soc_table``).
SOC_TABLE = (
    (4.173, 100.0), (4.112, 96.15), (4.085, 92.31), (4.071, 88.46), (4.039, 84.62),
    (3.987, 80.77), (3.943, 76.92), (3.908, 73.08), (3.887, 69.23), (3.854, 65.38),
    (3.833, 61.54), (3.801, 57.69), (3.783, 53.85), (3.742, 50.0), (3.715, 46.15),
    (3.679, 42.31), (3.636, 38.46), (3.588, 34.62), (3.543, 30.77), (3.503, 26.92),
    (3.462, 23.08), (3.379, 19.23), (3.296, 15.38), (3.218, 11.54), (3.165, 7.69),
    (3.091, 3.85), (2.977, 2.0), (2.8, 1.5), (2.7, 1.3), (2.5, 1.2), (2.3, 1.1), (2.1, 1.0),
    (1.9, 0.9), (1.6, 0.8), (1.3, 0.7), (1.0, 0.6), (0.6, 0.4), (0.3, 0.2), (0.01, 0.01),
    (0.001, 0.001),
)  # fmt: skip
_CELL_V = np.array([v for v, _ in reversed(SOC_TABLE)])
_SOC_PCT = np.array([s for _, s in reversed(SOC_TABLE)])
#: Cells of the SITL packs flown here, and their full pack voltage (V).
CELLS = 3
MAX_VOLTAGE_V = 12.6
#: SIM_BATT_VOLTAGE's default (V): a pack at ``maxVoltage`` 12.6 V or less starts full.
SITL_BATT_VOLTAGE_V = 12.6


def resting_cell_voltage_v(soc: float) -> float:
    """SITL's resting voltage of one cell (V, before the ``maxVoltage`` scaling) at the state
    of charge ``soc`` (0–1)."""
    return float(np.interp(100.0 * soc, _SOC_PCT, _CELL_V))


def soc_at_cell_voltage(cell_v: float) -> float:
    """The state of charge (0–1) SITL starts at for a resting cell voltage ``cell_v`` (V,
    before the ``maxVoltage`` scaling; above 4.173 V: full)."""
    return float(np.interp(cell_v, _CELL_V, _SOC_PCT)) / 100.0


def cell_voltage_v(pack_v: float, max_voltage_v: float = MAX_VOLTAGE_V) -> float:
    """A pack voltage (V) as SITL's table cell voltage (V): scaled by 4.173 / ``maxVoltage``."""
    return pack_v / max_voltage_v * SOC_TABLE[0][0]


def pack_voltage_v(cell_v: float, max_voltage_v: float = MAX_VOLTAGE_V) -> float:
    """SITL's table cell voltage ``cell_v`` (V) as the pack's (V): scaled by ``maxVoltage`` /
    4.173."""
    return cell_v / SOC_TABLE[0][0] * max_voltage_v


@dataclass(frozen=True)
class Pack:
    """A 3S SITL pack that holds ``true_capacity_ah`` (Ah) while the autopilot is told
    ``labelled_capacity_ah`` (Ah, BATT_CAPACITY), with internal resistance ``resistance_ohm``
    (Ω), powered up at the true state of charge ``start_soc`` (0–1)."""

    true_capacity_ah: float
    resistance_ohm: float
    start_soc: float = 1.0
    labelled_capacity_ah: float = 5.0

    @property
    def start_voltage_v(self) -> float:
        """Resting pack voltage (V, mV-rounded) at ``start_soc``: SIM_BATT_VOLTAGE."""
        return round(pack_voltage_v(resting_cell_voltage_v(self.start_soc)), 3)

    def model_json(self) -> dict[str, float]:
        """SITL's multicopter model JSON keys of the true pack."""
        return {
            "maxVoltage": MAX_VOLTAGE_V,
            "battCapacityAh": self.true_capacity_ah,
            "refBatRes": self.resistance_ohm,
        }

    def params(self) -> dict[str, float]:
        """The label (BATT_CAPACITY, mAh) and the power-up voltage (SIM_BATT_VOLTAGE, V)."""
        return {
            "BATT_CAPACITY": round(1000 * self.labelled_capacity_ah),
            "SIM_BATT_VOLTAGE": self.start_voltage_v,
        }
