"""Figures of docs/pack.md and docs/daemon.md beyond the tables of ``scripts/pack_figures.py``
(which computes the results most of these read):

- the SITL vehicle file's resting curve against SITL's own table (as
  ``tests/test_battery.py`` checks it against the file's σ);
- the SITL pack flights that reach their reserve too soon to be scored, and what is left of
  the σ on the sets within 1σ most often (the remaining energy's, against the errors);
- the hover→cruise acceptance flights' PX4-style figure just after the change and in
  mid-flight (``python tests/test_endurance_acceptance.py``);
- how far apart two transports' energies end when a reading sits at each period's end
  (``tests/period_ends.py``, the stream of ``tests/test_pipeline.py``);
- docs/daemon.md's table of a restart mid-flight (``state-restart-table``), as ``python -m
  bench.trust`` prints it (in process; < 1 s of CPU).

``scripts/figures.py`` registers the blocks (:func:`generators`); ``tests/test_figures.py``
checks them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from estimator.physics.vehicle import load_vehicle
from estimator.sim.endurance_ensemble import figures_after_change
from estimator.sitl.pack import SOC_TABLE, resting_cell_voltage_v

REPO = Path(__file__).resolve().parent.parent
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: The charge (fraction) from which the curve is compared with SITL's table: below it SITL's
#: curve falls towards 0 V and is never flown (``tests/test_battery.py``).
CURVE_FROM_SOC = 0.05
#: The sets docs/pack.md reads the σ left on (within 1σ at or above 80 %).
SIGMA_SETS = ("tuning", "held_out_2")
#: The cruise speed (m/s) and time after the change (s) of the PX4-style figure's lag, and the
#: times after the change (s) that docs/daemon.md calls mid-flight.
LAG_AT = (14.0, 10.0)
MID_FLIGHT_S = (120.0, 300.0, 600.0)


def curve_errors_v() -> np.ndarray:
    """The SITL vehicle file's resting cell voltage minus SITL's table (scaled to 4.2 V per
    cell as SITL does; V), from :data:`CURVE_FROM_SOC` to full."""
    curve = load_vehicle(SITL_VEHICLE).battery.cell_ocv_v
    assert curve is not None
    soc = np.linspace(CURVE_FROM_SOC, 1.0, 20001)
    table_v = 4.2 / SOC_TABLE[0][0] * np.array([resting_cell_voltage_v(s) for s in soc])
    return np.interp(soc, np.linspace(0.0, 1.0, len(curve)), curve) - table_v


def curve() -> str:
    errors_mv = 1000 * curve_errors_v()
    return (
        f"{np.sqrt(np.mean(errors_mv**2)):.1f} mV RMS and at most "
        f"{np.abs(errors_mv).max():.1f} mV off"
    )


def curve_worst() -> str:
    return f"{1000 * np.abs(curve_errors_v()).max():.1f} mV"


def unscored(packs: ModuleType) -> str:
    """The pack flights with no scored estimate, and when after take-off they reach the
    reserve (s)."""
    flights = [f for f in packs._all() if not len(f.errors)]
    parts = [
        f"{f.name} reaches its reserve "
        f"{f.truth['events']['reserve_s'] - f.truth['events']['takeoff_s']:.0f} s after take-off"
        for f in flights
    ]
    return " and ".join(parts) + (
        " and is not scored" if len(parts) == 1 else " and are not scored"
    )


def _energy_sigma_share(flights: Sequence[Any]) -> float:
    """Median over the scored span (60 s after take-off to 60 s before the reserve) of the
    remaining energy's 1σ over the remaining energy (%)."""
    shares = []
    for f in flights:
        events = f.truth["events"]
        shares += [
            e.energy_remaining_sigma_wh / e.energy_remaining_wh
            for e in f.estimates
            if events["takeoff_s"] + 60 <= e.time_s <= events["reserve_s"] - 60
            and e.energy_remaining_wh > 0
        ]
    return 100 * float(np.median(shares))


def sigma_left(packs: ModuleType) -> str:
    """On :data:`SIGMA_SETS`: the curve's 1σ per cell (mV, the vehicle file's), the median
    remaining energy's 1σ (% of it) per set, and the sets' median |error| of the endurance."""
    sigma_v = load_vehicle(SITL_VEHICLE).battery.cell_ocv_sigma_v
    assert sigma_v is not None
    sets = [packs._scored(packs.flights()[half]) for half in SIGMA_SETS]
    shares = [_energy_sigma_share(pooled) for pooled in sets]
    errors = [float(np.median(packs._abs_pct(pooled))) for pooled in sets]
    return (
        f"±{1000 * sigma_v:.0f} mV/cell and the capacity: {min(shares):.1f}–{max(shares):.1f} % "
        f"of the energy left), where SITL's curve and current are exact and the errors left are "
        f"{min(errors):.1f}–{max(errors):.1f} %"
    )


def restart_misses(packs: ModuleType, half: str = "tuning") -> str:
    """The flights of the set ``half`` that, restarted 90 s after take-off, miss the test's
    bound 60 s after the restart: their error and z then."""
    bound = 100 * packs.RESTART_BOUND
    missed = [r for r in packs.restarts()[half] if abs(r.error_at) > packs.RESTART_BOUND]
    if not missed:
        return f"every flight of the set is within {bound:.0f} % at 60 s"
    parts = [
        f"{r.name} ({packs._signed(r.error_at)} %, {packs._signed(r.z_at / 100, 1)}σ)"
        for r in missed
    ]
    inside = all(abs(r.z_at) <= 1 for r in missed)
    verb = "misses" if len(missed) == 1 else "miss"
    where = "inside" if inside else "not all inside"
    whose = "its" if len(missed) == 1 else "their"
    return f"{' and '.join(parts)} {verb} {bound:.0f} % at 60 s, {where} {whose} σ"


def _px4_pct(ensemble: ModuleType, speed_mps: float, after_s: float) -> float:
    """The PX4-style figure's error (%) ``after_s`` after the change to ``speed_mps``."""
    _, truth_s, px4_s = figures_after_change(ensemble._hover_cruise(speed_mps), after_s)
    return 100 * (px4_s / truth_s - 1)


def px4_lag(ensemble: ModuleType) -> str:
    speed_mps, after_s = LAG_AT
    return f"{_px4_pct(ensemble, speed_mps, after_s):+.0f} % at {speed_mps:.0f} m/s"


def px4_mid_flight(ensemble: ModuleType) -> str:
    errors = [_px4_pct(ensemble, v, t) for v in (10.0, 14.0) for t in MID_FLIGHT_S]
    return f"{min(errors):.1f}–{max(errors):.1f} %"


def generators(
    packs: ModuleType, ensemble: ModuleType, period_ends: ModuleType, trust: ModuleType
) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it; ``packs`` and ``ensemble``:
    ``scripts/pack_figures.py`` and ``scripts/ensemble_figures.py`` as ``scripts/figures.py``
    loaded them (their results are cached there); ``period_ends``: ``tests/period_ends.py``;
    ``trust``: ``bench/trust.py``."""
    return {
        "pack-sitl-curve": curve,
        "pack-sitl-curve-worst": curve_worst,
        "pack-sitl-unscored": lambda: unscored(packs),
        "pack-sitl-sigma-left": lambda: sigma_left(packs),
        "pack-sitl-restarts-tuning": lambda: restart_misses(packs),
        "hover-cruise-px4-lag": lambda: px4_lag(ensemble),
        "hover-cruise-px4-mid": lambda: px4_mid_flight(ensemble),
        "period-end-apart": lambda: f"{period_ends.apart_pct():.2f} %",
        "state-restart-table": lambda: str(trust.restart_table(trust.flight())),
    }
