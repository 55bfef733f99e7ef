"""``uav-energy plan MISSION --vehicle F``: the energy of a mission before flight.

Reads a QGroundControl ``.plan`` or ArduPilot ``.waypoints`` file, flies it on paper the way
ArduCopter's AUTO mode does (:mod:`estimator.analysis.mission_energy`) in the given wind and
payload, and prints a table per leg (energy ± 1σ, time, recommended ground speed), the totals,
whether mission and return fit in the pack's usable energy above its reserve, and a
PX4-style distance/set-speed estimate for comparison. ``--json`` prints one object instead,
``--report DIR`` writes the plots. See docs/plan.md.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from estimator.analysis.mission_energy import FlightSettings, MissionEnergy, mission_energy
from estimator.commands.sim import _number, _pair
from estimator.errors import UserError
from estimator.estimation.pack_memory import check_pack_id, load_record
from estimator.logs import detect_format
from estimator.logs.mission_files import MissionFile, load_mission
from estimator.physics.route_energy import UNCERTAINTY_SOURCES, Conditions
from estimator.physics.vehicle import Vehicle, load_vehicle

#: Characters the leg table needs (wider than a default 80-column pipe).
TABLE_WIDTH = 132
#: Heaviest take-off mass a multirotor lifts, as a multiple of the vehicle file's mass: the
#: usual design thrust-to-weight of 2 (hover near half throttle) spent on hover alone, with no
#: margin left to climb or steer. The vehicle file records no thrust, so this is the rule of
#: thumb, not the airframe's own figure.
MAX_LIFT_PER_MASS = 2.0


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    d = FlightSettings()
    p = subparsers.add_parser(
        "plan",
        description="Energy of a mission file (.plan or .waypoints) per leg, in total with its "
        "1σ, and whether mission and return fit above the reserve, in a given wind and payload.",
    )
    p.add_argument("mission", type=Path, metavar="MISSION", help=".plan or .waypoints file")
    p.add_argument("--vehicle", required=True, type=Path, metavar="FILE.toml")
    p.add_argument(
        "--wind", metavar="SPEED@FROM_DEG", help="wind, m/s @ the direction it blows from (°)"
    )
    p.add_argument("--wind-sigma", default="1.0", metavar="MPS", help="1σ per wind component")
    p.add_argument("--payload", default="0", metavar="KG", help="payload beyond the file's mass")
    p.add_argument("--payload-sigma", default="0.05", metavar="KG", help="1σ of the payload")
    p.add_argument(
        "--speed", default=str(d.cruise_mps), metavar="MPS", help="default waypoint ground speed"
    )
    p.add_argument("--start-soc", default="1.0", metavar="SOC", help="state of charge at start")
    p.add_argument(
        "--pack",
        metavar="ID",
        help="plan on this pack's learnt capacity (with --pack-dir; docs/pack.md)",
    )
    p.add_argument("--pack-dir", type=Path, metavar="DIR", help="the packs' memory")
    p.add_argument("--report", type=Path, metavar="DIR", help="write PNG plots and summary.md")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    vehicle = _with_pack(load_vehicle(args.vehicle), args.pack, args.pack_dir)
    mission = _load_mission(args.mission)
    conditions = _conditions(args, vehicle)
    speed = _number(args.speed, "--speed", positive=True)
    soc = _number(args.start_soc, "--start-soc")
    if not 0 <= soc <= 1:
        raise UserError(f"--start-soc must be in [0, 1], got {args.start_soc!r}")
    settings = replace(FlightSettings(), cruise_mps=speed)
    result = mission_energy(mission.legs(), vehicle, conditions, settings, start_soc=soc)
    if args.report is not None:
        from estimator.reports.plan_report import write_report

        write_report(result, args.report, f"{args.mission.name} · {vehicle.name}")
    if args.json:
        print(json.dumps(summary(result, str(args.mission), vehicle.name), indent=2), flush=True)
    else:
        _print(result, str(args.mission), vehicle.name, mission.ignored)
    if args.report is not None:
        Console(stderr=True).print(f"wrote {args.report}/summary.md and plots")
    return 0


def _with_pack(vehicle: Vehicle, pack_id: str | None, pack_dir: Path | None) -> Vehicle:
    """The vehicle with the pack's learnt capacity (``--pack``, ``--pack-dir``)."""
    if (pack_id is None) != (pack_dir is None):
        raise UserError("--pack ID and --pack-dir DIR go together")
    if pack_id is None or pack_dir is None:
        return vehicle
    record = load_record(pack_dir, check_pack_id(pack_id))
    if record is None:
        raise UserError(f"pack {pack_id!r} has no memory in {pack_dir} yet (fly or replay it)")
    return replace(vehicle, battery=replace(vehicle.battery, capacity_ah=record.capacity_ah))


def _load_mission(path: Path) -> MissionFile:
    """The mission file; a flight log given in its place is named for what it is."""
    try:
        fmt = detect_format(path)
    except UserError:  # not a log (or not readable): the mission reader says what is wrong
        return load_mission(path)
    raise UserError(
        f"{path} is a flight log ({fmt}), not a mission: plan takes a .plan or .waypoints "
        "file (uav-energy replay takes logs)"
    )


def _conditions(args: argparse.Namespace, vehicle: Vehicle) -> Conditions:
    speed, from_deg = 0.0, 0.0
    if args.wind is not None:
        speed, from_deg = _pair(args.wind, "--wind", "SPEED@FROM_DEG")
        if not 0 <= speed <= 30:
            raise UserError("--wind speed must be between 0 and 30 m/s")
    payload = _number(args.payload, "--payload")
    _check_lift(vehicle, payload)
    wind_sigma = _number(args.wind_sigma, "--wind-sigma")
    payload_sigma = _number(args.payload_sigma, "--payload-sigma")
    if wind_sigma < 0 or payload_sigma < 0:
        raise UserError("--wind-sigma and --payload-sigma must be ≥ 0")
    return Conditions(speed, from_deg % 360.0, payload, wind_sigma, payload_sigma)


def _check_lift(vehicle: Vehicle, payload_kg: float) -> None:
    """A payload that leaves no positive mass, or more than the rotors lift (a take-off mass
    beyond :data:`MAX_LIFT_PER_MASS` × the vehicle file's), is a UserError."""
    mass_kg = vehicle.mass_kg + payload_kg
    if mass_kg <= 0:
        raise UserError("--payload must leave a positive mass")
    ratio = mass_kg / vehicle.mass_kg
    if ratio > MAX_LIFT_PER_MASS:
        hover_w = vehicle.model.rescaled(mass_ratio=ratio).hover_power_w
        raise UserError(
            f"--payload {payload_kg:g} kg: the vehicle cannot lift it ({mass_kg:g} kg is "
            f"{ratio:.1f}× the vehicle file's {vehicle.mass_kg:g} kg, a multirotor lifts at most "
            f"about {MAX_LIFT_PER_MASS:g}×; hover would need {hover_w:.0f} W against "
            f"{vehicle.model.hover_power_w:.0f} W empty)"
        )


def summary(result: MissionEnergy, mission: str, vehicle: str) -> dict[str, Any]:
    """The JSON object of ``--json`` (documented in docs/plan.md)."""
    c, total = result.conditions, result.total

    def num(x: float | None, digits: int = 3) -> float | None:
        return None if x is None or not math.isfinite(x) else round(x, digits)

    return {
        "mission": mission,
        "vehicle": vehicle,
        "conditions": {
            "wind_speed_mps": c.wind_speed_mps,
            "wind_from_deg": c.wind_from_deg,
            "wind_sigma_mps": c.wind_sigma_mps,
            "payload_kg": c.payload_kg,
            "payload_sigma_kg": c.payload_sigma_kg,
        },
        "legs": [
            {
                "leg": i + 1,
                "kind": r.name,
                "item": r.leg.seq,
                "distance_m": num(r.energy.distance_m, 1),
                "climb_m": num(r.energy.climb_m, 1),
                "track_deg": num(r.track_deg, 1),
                "ground_speed_mps": num(r.energy.ground_speed_mps, 2),
                "time_s": num(r.energy.time_s, 1),
                "power_w": num(r.energy.power_w, 1),
                "energy_wh": num(r.energy.energy_wh),
                "energy_sigma_wh": num(r.energy.energy_sigma_wh),
                "payload": r.leg.payload,
                "recommended_ground_speed_mps": num(
                    r.recommended.ground_speed_mps if r.recommended else None, 2
                ),
                "recommended_airspeed_mps": num(
                    r.recommended.airspeed_mps if r.recommended else None, 2
                ),
                "recommended_energy_wh": num(r.recommended_energy_wh),
            }
            for i, r in enumerate(result.legs)
        ],
        "total": {
            "distance_m": num(total.distance_m, 1),
            "time_s": num(total.time_s, 1),
            "energy_wh": num(total.energy_wh),
            "energy_sigma_wh": num(total.energy_sigma_wh),
            "sigma_by_source_wh": {
                name: num(abs(s))
                for name, s in zip(UNCERTAINTY_SOURCES, total.sensitivity_wh, strict=True)
            },
        },
        "usable_wh": num(result.usable_wh),
        "margin_wh": num(result.margin_wh),
        "feasible": result.feasible,
        "px4_style": {
            "time_s": num(result.px4.time_s, 1),
            "average_power_w": num(result.px4.average_power_w, 1),
            "energy_wh": num(result.px4.energy_wh),
        },
    }


def _print(result: MissionEnergy, mission: str, vehicle: str, ignored: tuple[str, ...]) -> None:
    console = Console(width=max(Console().width, TABLE_WIDTH))
    c = result.conditions
    table = Table(
        title=f"{mission} · {vehicle} · wind {c.wind_speed_mps:g} m/s from "
        f"{c.wind_from_deg:03.0f}° · payload {c.payload_kg:g} kg"
    )
    for name in ("leg", "kind", "item", "dist m", "climb m", "track °", "speed m/s", "time s",
                 "power W", "energy Wh", "best m/s", "at best Wh"):  # fmt: skip
        table.add_column(name, justify="left" if name == "kind" else "right")
    for i, r in enumerate(result.legs):
        e = r.energy
        table.add_row(
            str(i + 1),
            r.name,
            str(r.leg.seq),
            f"{e.distance_m:.0f}",
            f"{e.climb_m:+.0f}",
            "–" if math.isnan(r.track_deg) else f"{r.track_deg:.0f}",
            f"{e.ground_speed_mps:.1f}" if e.distance_m > 0 else "–",
            f"{e.time_s:.0f}",
            f"{e.power_w:.0f}",
            f"{e.energy_wh:.2f} ± {e.energy_sigma_wh:.2f}",
            f"{r.recommended.ground_speed_mps:.1f}" if r.recommended else "–",
            f"{r.recommended_energy_wh:.2f}" if r.recommended_energy_wh is not None else "–",
        )
    t = result.total
    table.add_section()
    table.add_row(
        "", "total", "", f"{t.distance_m:.0f}", "", "", "", f"{t.time_s:.0f}",
        f"{t.power_w:.0f}", f"{t.energy_wh:.2f} ± {t.energy_sigma_wh:.2f}", "",
        f"{sum(r.recommended_energy_wh or r.energy.energy_wh for r in result.legs):.2f}",
    )  # fmt: skip
    console.print(table)
    verdict = "[green]feasible[/]" if result.feasible else "[red]NOT feasible[/]"
    sigmas = result.margin_wh / t.energy_sigma_wh if t.energy_sigma_wh > 0 else math.inf
    console.print(
        f"mission + return {t.energy_wh:.2f} ± {t.energy_sigma_wh:.2f} Wh in {t.time_s / 60:.1f} "
        f"min; usable above the reserve {result.usable_wh:.2f} Wh; margin "
        f"{result.margin_wh:+.2f} Wh ({sigmas:+.1f}σ): {verdict}"
    )
    px4 = result.px4
    console.print(
        f"PX4-style (distance / set speed, {px4.average_power_w:.0f} W average, blind to wind "
        f"and payload): {px4.energy_wh:.2f} Wh in {px4.time_s / 60:.1f} min",
        highlight=False,
    )
    for note in ignored:
        console.print(f"ignored (does not move the vehicle): {note}", highlight=False)
