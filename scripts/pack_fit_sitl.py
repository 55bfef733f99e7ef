"""The pack fitted by ``uav-energy fit`` against the truth on the ArduCopter SITL pack flights.

Fits each ``replay/sitl_packs/`` flight's pack (:func:`estimator.analysis.pack_fit.fit_pack`,
3 cells, the pack's true capacity as ``--capacity-ah``): a flight powered up charged alone, a
part-charged one with a charged flight of the same capacity from the same half of the split
(``split.json``), as the same pack flown twice. Prints per flight: the resistance and the
charge at power-up (truth in brackets), the stretch of charge its discharge covers, and the
fitted curve's error against SITL's own table (scaled to 4.2 V/cell as SITL does) at the
curve's 1 % points over that stretch, RMS and worst (mV/cell), with the fit's σ; then each
half's pooled RMS and worst. Run: ``python scripts/pack_fit_sitl.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from estimator.analysis.pack_fit import fit_pack
from estimator.logs import load_flights
from estimator.sitl.pack import CELLS, pack_voltage_v, resting_cell_voltage_v

REPO = Path(__file__).resolve().parent.parent
FLIGHTS = REPO / "replay" / "sitl_packs"
#: Part-charged flights and the charged flight of the same capacity they are fitted with.
CHARGED_PARTNER = {
    "pack_c100_r1_soc75": "pack_c100_r1",
    "pack_c80_r3_soc50": "pack_c80_r3",
    "pack_c65_r3_soc75": "pack_c65_r3",
    "pack_c100_r1_soc50": "pack_c100_r3",
    "pack_c80_r3_soc75_wind_payload": "pack_c80_r1",
}


#: The table's header (docs/fit.md).
TABLE_HEADER = (
    "| flight | fitted | R mΩ (true) | charge at power-up (true) | stretch "
    "| RMS / worst mV/cell | σ mV/cell |\n"
    "|---|---|---|---|---|---|---|"
)
#: The halves of ``split.json`` the table has, in its order.
HALVES = ("tuning", "held_out")


def curve_errors_v(name: str) -> tuple[str, np.ndarray]:
    """One flight's table row (docs/fit.md) and its curve errors (V per cell)."""
    truth = json.loads((FLIGHTS / name / "truth.json").read_text())["battery"]
    names = [CHARGED_PARTNER[name], name] if name in CHARGED_PARTNER else [name]
    flights = load_flights([FLIGHTS / n / "flight.tlog" for n in names])
    fit, _ = fit_pack(flights, CELLS, truth["capacity_ah"])
    assert fit is not None and fit.cell_ocv_v is not None and fit.sigma_v is not None
    own = fit.flights[-1]
    lo, hi = own.start_soc - own.drawn_ah / truth["capacity_ah"], own.start_soc
    soc = np.linspace(0.0, 1.0, len(fit.cell_ocv_v))
    inside = (soc >= lo) & (soc <= hi)
    sitl = np.array([pack_voltage_v(resting_cell_voltage_v(s)) / CELLS for s in soc[inside]])
    errors = fit.cell_ocv_v[inside] - sitl
    row = (
        f"| {name} | {'with ' + names[0] if len(names) > 1 else 'alone'} "
        f"| {1000 * own.resistance_ohm:.2f} ({1000 * truth['internal_resistance_ohm']:g}) "
        f"| {own.start_soc:.3f} ({truth['start_soc']:.3f}) | {lo:.2f}–{hi:.2f} "
        f"| {1000 * np.sqrt(np.mean(errors**2)):.2f} / {1000 * np.max(np.abs(errors)):.2f} "
        f"| {1000 * fit.sigma_v:.2f} |"
    )
    return row, errors


def pooled_row(half: str, errors: list[np.ndarray]) -> str:
    """A half's pooled RMS and worst error (mV/cell)."""
    e = np.concatenate(errors)
    return (
        f"{half}: {len(errors)} flights, RMS {1000 * np.sqrt(np.mean(e**2)):.2f} mV/cell, "
        f"worst {1000 * np.max(np.abs(e)):.2f} mV/cell"
    )


def halves() -> dict[str, tuple[list[str], list[np.ndarray]]]:
    """Per half of :data:`HALVES`: its flights' table rows and curve errors (V per cell)."""
    split = json.loads((FLIGHTS / "split.json").read_text())
    out = {}
    for half in HALVES:
        rows, errors = zip(*(curve_errors_v(name) for name in split[half]), strict=True)
        out[half] = (list(rows), list(errors))
    return out


def table(fitted: dict[str, tuple[list[str], list[np.ndarray]]]) -> str:
    """docs/fit.md's table: every flight of :func:`halves`, tuning first."""
    return "\n".join([TABLE_HEADER, *(row for rows, _ in fitted.values() for row in rows)])


def pooled(fitted: dict[str, tuple[list[str], list[np.ndarray]]]) -> str:
    """docs/fit.md's sentence under the table: each half's :func:`pooled_row`."""
    return "; ".join(
        pooled_row(half.replace("_", "-"), errors) for half, (_, errors) in fitted.items()
    )


def main() -> None:
    fitted = halves()
    print(table(fitted))
    print()
    print(pooled(fitted))


if __name__ == "__main__":
    main()
