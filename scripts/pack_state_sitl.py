"""The pack filter against the truth on the ArduCopter SITL pack flights.

Runs :func:`estimator.estimation.pack_state.track_pack` over the battery readings of each
``replay/sitl_packs/`` flight with the LABELLED capacity (5.0 Ah; vehicle
``config/vehicles/ardupilot_sitl_quad.toml``) and prints per flight, with its half of the
split (``split.json``): the charge at power-up, the capacity once half the pack's charge is
used, and the resistance at the end, each against the truth with its 1σ; beside it, the
error of the label the autopilot counts against (BATT_CAPACITY).
Run: ``python scripts/pack_state_sitl.py``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from estimator.estimation.pack_state import track_pack
from estimator.logs import iter_samples
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import load_vehicle
from estimator.telemetry.samples import BatterySample

REPO = Path(__file__).resolve().parent.parent
FLIGHTS = REPO / "replay" / "sitl_packs"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"


def main() -> None:
    vehicle = load_vehicle(VEHICLE)
    split = json.loads((FLIGHTS / "split.json").read_text())
    print(
        "| flight | half | charge at power-up (truth) | capacity at half used, Ah (truth) "
        "| error | label's error | R at the end, mΩ (truth) |"
    )
    print("|---|---|---|---|---:|---:|---|")
    for half in ("tuning", "held_out"):
        for name in split[half]:
            truth = json.loads((FLIGHTS / name / "truth.json").read_text())
            battery = truth["battery"]
            label_ah = battery["labelled_capacity_ah"]
            spec = dataclasses.replace(vehicle.battery, capacity_ah=label_ah)
            path = FLIGHTS / name / "flight.tlog"
            samples = [
                s
                for s in iter_samples(path, "auto", vehicle.input_limits())
                if isinstance(s, BatterySample)
            ]
            track = track_pack(samples, PackModel(spec))
            consumed = {s.time_s: s.consumed_mah for s in samples if s.consumed_mah is not None}
            half_mah = 500.0 * battery["start_soc"] * battery["capacity_ah"]
            at_half = next(e for t, e in track if consumed.get(t, 0.0) >= half_mah)
            first, last = track[0][1], track[-1][1]
            true_ah = battery["capacity_ah"]
            print(
                f"| {name} | {half.replace('_', '-')} "
                f"| {first.soc:.3f} ± {first.soc_sigma:.3f} ({battery['start_soc']:.3f}) "
                f"| {at_half.capacity_ah:.2f} ± {at_half.capacity_sigma_ah:.2f} ({true_ah:g}) "
                f"| {100 * (at_half.capacity_ah / true_ah - 1):+.1f} % "
                f"| {100 * (label_ah / true_ah - 1):+.0f} % "
                f"| {1000 * last.resistance_ohm:.1f} "
                f"({1000 * battery['internal_resistance_ohm']:g}) |"
            )


if __name__ == "__main__":
    main()
