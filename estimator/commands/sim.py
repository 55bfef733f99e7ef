"""``uav-energy sim``: fly the simulated multirotor, live over MAVLink and/or into files.

``--connect URL`` plays the flight in (sped-up) real time as an ArduCopter (system 1,
component 1) and answers stream-rate requests; ``--tlog FILE`` writes the sent messages
(and the truth beside them as ``<stem>.truth.csv``); ``--truth FILE.csv`` writes the truth
where asked. Without ``--connect`` the flight is simulated and written at once. Hidden
effects (``--wind``, ``--payload``, ...) change the truth power without telling anyone.
See docs/sim.md.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import sys
from pathlib import Path
from typing import BinaryIO

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from estimator.errors import UserError
from estimator.mavlink.link import open_link
from estimator.physics.effects import AirDensity, Avionics, Climb, Effect, Mass, Voltage, Wind
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.sim.files import hidden_effects_summary, write_tlog, write_truth_csv
from estimator.sim.link import SimPlayer
from estimator.sim.plans import BUILTIN_PLANS
from estimator.sim.run import SimConfig, SimRun
from estimator.sim.simulator import simulate

#: What ``--low-voltage-losses`` hides: 0.15 Ω between sensor and motors, model exact when full.
LOW_VOLTAGE_RESISTANCE_OHM = 0.15
#: What ``--climb`` hides: electrical-to-climb-work efficiency.
CLIMB_EFFICIENCY = 0.6


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "sim",
        description="Simulate an ArduCopter-like multirotor: play it over MAVLink in real time "
        "and/or write a tlog and the truth.",
    )
    p.add_argument("--connect", metavar="URL", help="e.g. udpout:127.0.0.1:14550, tcpin:...")
    p.add_argument("--tlog", type=Path, metavar="FILE", help="write the messages (and truth)")
    p.add_argument("--truth", type=Path, metavar="FILE.csv", help="write the truth at 10 Hz")
    p.add_argument(
        "--plan",
        default="straight",
        metavar="PLAN",
        help=f"{'|'.join(BUILTIN_PLANS)} or a plan file (default: straight)",
    )
    p.add_argument("--vehicle", type=Path, metavar="FILE.toml", help="truth vehicle")
    p.add_argument("--speedup", default="1", metavar="N", help="playback speed (default 1)")
    p.add_argument("--duration", metavar="S", help="fly this long, repeating the plan")
    p.add_argument("--wind", metavar="SPEED@FROM_DEG", help="hidden wind, m/s @ degrees")
    p.add_argument("--payload", metavar="KG@T_S", help="hidden mass step (kg) at time T_S")
    p.add_argument("--air-density", metavar="RHO", help="hidden air density, kg/m³")
    p.add_argument("--climb", action="store_true", help="climb legs, with climb power")
    p.add_argument("--avionics", metavar="W@T_S", help="hidden electrical load step")
    p.add_argument(
        "--low-voltage-losses", action="store_true", help="hidden losses growing as V sags"
    )
    p.add_argument("--seed", default="0", metavar="N", help="sensor-noise seed (default 0)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    if args.connect is None and args.tlog is None and args.truth is None:
        raise UserError("nothing to do: give --connect URL, --tlog FILE or --truth FILE.csv")
    speedup = _number(args.speedup, "--speedup", positive=True)
    err = Console(stderr=True)
    with err.status("simulating…"):
        sim_run = simulate(config)
    if args.connect is not None:
        asyncio.run(_play(sim_run, args.connect, speedup, args.tlog, err))
    elif args.tlog is not None:
        write_tlog(sim_run, args.tlog)
    if args.tlog is not None and args.connect is not None:
        write_truth_csv(sim_run, args.tlog.with_name(args.tlog.stem + ".truth.csv"))
    if args.truth is not None:
        write_truth_csv(sim_run, args.truth)
    tr = sim_run.truth
    print(
        f"simulated {sim_run.duration_s:.1f} s of '{sim_run.plan.name}': "
        f"{len(sim_run.messages)} messages, mean flying power "
        f"{float(tr.power_w[tr.flying].mean()) if tr.flying.any() else 0.0:.1f} W, "
        f"reserve at {sim_run.reserve_time_s:.1f} s; hidden effects: "
        f"{hidden_effects_summary(config.all_effects())}"
    )
    return 0


async def _play(run: SimRun, url: str, speedup: float, tlog: Path | None, err: Console) -> None:
    link = await open_link(url, source_system=1, source_component=1)
    fh: BinaryIO | None = None
    try:
        if tlog is not None:
            tlog.parent.mkdir(parents=True, exist_ok=True)
            fh = tlog.open("wb")
        with Progress(
            TextColumn("sim"),
            BarColumn(),
            TextColumn("{task.completed:.0f}/{task.total:.0f} s"),
            TimeElapsedColumn(),
            console=err,
            disable=not sys.stderr.isatty(),
        ) as progress:
            task = progress.add_task("sim", total=run.duration_s)
            player = SimPlayer(run, link, speedup, fh, lambda t: progress.update(task, completed=t))
            await player.play()
    finally:
        if fh is not None:
            fh.close()
        await link.close()


def config_from_args(args: argparse.Namespace) -> SimConfig:
    """SimConfig from the command line; a malformed flag is one UserError sentence."""
    vehicle = default_vehicle() if args.vehicle is None else load_vehicle(args.vehicle)
    effects: list[Effect] = []
    if args.wind is not None:
        speed, from_deg = _pair(args.wind, "--wind", "SPEED@FROM_DEG")
        if speed < 0 or speed > 30:
            raise UserError("--wind speed must be between 0 and 30 m/s")
        effects.append(Wind(speed_mps=speed, from_deg=from_deg % 360.0))
    if args.payload is not None:
        kg, at_s = _pair(args.payload, "--payload", "KG@T_S")
        if vehicle.mass_kg + kg <= 0 or at_s < 0:
            raise UserError("--payload must leave a positive mass and start at T_S ≥ 0")
        effects.append(Mass(delta_kg=kg, at_s=at_s))
    if args.air_density is not None:
        rho = _number(args.air_density, "--air-density", positive=True)
        if not 0.3 <= rho <= 1.6:
            raise UserError("--air-density must be between 0.3 and 1.6 kg/m³")
        effects.append(AirDensity(rho_kgpm3=rho))
    if args.climb:
        effects.append(Climb(efficiency=CLIMB_EFFICIENCY))
    if args.avionics is not None:
        watts, at_s = _pair(args.avionics, "--avionics", "W@T_S")
        if at_s < 0:
            raise UserError("--avionics must start at T_S ≥ 0")
        effects.append(Avionics(power_w=watts, at_s=at_s))
    if args.low_voltage_losses:
        full_v = 4.2 * vehicle.battery.cells
        effects.append(Voltage(resistance_ohm=LOW_VOLTAGE_RESISTANCE_OHM, reference_v=full_v))
    duration = None if args.duration is None else _number(args.duration, "--duration", True)
    seed = _number(args.seed, "--seed")
    if seed != int(seed) or seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {args.seed!r}")
    return SimConfig(
        vehicle=vehicle,
        plan=args.plan,
        climb_legs=bool(args.climb) and args.plan in BUILTIN_PLANS,
        effects=tuple(effects),
        seed=int(seed),
        duration_s=duration,
    )


def _number(text: str, flag: str, positive: bool = False) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"{flag} needs a number, got {text!r}") from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise UserError(f"{flag} must be a {'positive ' if positive else ''}number, got {text!r}")
    return value


def _pair(text: str, flag: str, form: str) -> tuple[float, float]:
    left, sep, right = text.partition("@")
    if not sep:
        raise UserError(f"{flag} needs the form {form}, got {text!r}")
    return _number(left, flag), _number(right, flag)
