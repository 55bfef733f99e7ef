"""The pack learned in flight against the truth on the ArduCopter SITL pack flights.

Replays each ``replay/sitl_packs/`` flight through the daemon's pipeline with the LABELLED
capacity (5.0 Ah; vehicle ``config/vehicles/ardupilot_sitl_quad.toml``) and prints per
flight, with its set in ``split.json`` (tuning, then the held-out sets): the charge at
power-up and the capacity once half the pack's charge is used (each with its 1σ, the truth
in brackets), and the endurance's median and worst |error| from 60 s after take-off until 60
s before the true reserve — ours, a PX4-style estimate and ArduPilot's own
``battery_remaining`` over the same readings (:mod:`estimator.analysis.peer_endurance`) —
with our 1σ coverage; then the pooled figures of each set. Run: ``python
scripts/pack_state_sitl.py``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from estimator.analysis.pack_flights import (
    PackFlight,
    Restart,
    half_used_s,
    replay_pack_flight,
    replay_restarted,
)
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
FLIGHTS = REPO / "replay" / "sitl_packs"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"


#: The header of the per-flight table (docs/pack.md).
TABLE_HEADER = (
    "| flight | half | charge at power-up | capacity at half used, Ah "
    "| endurance median / worst |error| % | within 1σ | PX4-style % | ArduPilot % |\n"
    "|---|---|---|---|---|---:|---|---|"
)
#: The header of the restart table (docs/pack.md).
RESTART_HEADER = (
    "| restarted flight | half | endurance error 60 s after | most \\|z\\| after |\n"
    "|---|---|---:|---:|"
)


def _pct(errors: np.ndarray) -> str:
    a = 100 * np.abs(errors[np.isfinite(errors)])
    return f"{np.median(a):.1f} / {a.max():.1f}" if len(a) else "–"


def table_row(flight: PackFlight, half: str) -> str:
    """One flight's row of the table (docs/pack.md)."""
    battery = flight.truth["battery"]
    first = next(e for e in flight.estimates if np.isfinite(e.pack_soc))
    half_s = half_used_s(flight.readings, battery)
    at_half = [e for e in flight.estimates if e.time_s <= half_s][-1]
    inside = f"{np.mean(np.abs(flight.z) <= 1):.0%}" if len(flight.z) else "–"
    return (
        f"| {flight.name} | {half} "
        f"| {first.pack_soc:.3f} ± {first.pack_soc_sigma:.3f} ({battery['start_soc']:.3f}) "
        f"| {at_half.capacity_ah:.2f} ± {at_half.capacity_sigma_ah:.2f} "
        f"({battery['capacity_ah']:g}) "
        f"| {_pct(flight.errors)} | {inside} | {_pct(flight.px4_errors)} "
        f"| {_pct(flight.ardupilot_errors)} |"
    )


def pooled_line(half: str, flights: Sequence[PackFlight]) -> str:
    """The pooled figures of one set of ``split.json`` (docs/pack.md, under the table)."""
    z = np.concatenate([f.z for f in flights])
    z = z[np.isfinite(z)]
    worst_above = float(np.max(z)) if len(z) else float("nan")
    return (
        f"{half}: {len(z)} estimates, {np.mean(np.abs(z) <= 1):.0%} within 1σ, "
        f"{np.mean(np.abs(z) <= 3):.0%} within 3σ, highest above the truth "
        f"{worst_above:+.2f}σ; |error| ours {_pct(np.concatenate([f.errors for f in flights]))}"
        f" %, PX4-style {_pct(np.concatenate([f.px4_errors for f in flights]))} %, "
        f"ArduPilot {_pct(np.concatenate([f.ardupilot_errors for f in flights]))} %"
    )


def restart_row(restart: Restart, half: str) -> str:
    """One flight's row of the restart table (docs/pack.md)."""
    return (
        f"| {restart.name} | {half} | {100 * restart.error_at:+.1f} % ({restart.z_at:+.1f}σ) "
        f"| {restart.worst_abs_z:.1f}σ |"
    )


def main() -> None:
    vehicle = load_vehicle(VEHICLE)
    split = json.loads((FLIGHTS / "split.json").read_text())
    print(TABLE_HEADER)
    pooled: dict[str, list[PackFlight]] = {}
    for half in split:
        for name in split[half]:
            flight = replay_pack_flight(FLIGHTS / name, vehicle)
            pooled.setdefault(half, []).append(flight)
            print(table_row(flight, half.replace("_", "-")))
    for half, flights in pooled.items():
        print(f"\n{pooled_line(half, flights)}")
    print(f"\n{RESTART_HEADER}")
    for half in split:
        for name in split[half]:
            restart = replay_restarted(FLIGHTS / name, vehicle)
            if restart is not None:
                print(restart_row(restart, half.replace("_", "-")))


if __name__ == "__main__":
    main()
