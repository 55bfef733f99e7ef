"""``uav-energy sitl-record SCENARIO… --out DIR``: fly scenarios in ArduCopter SITL, record them.

Each scenario (estimator/sitl/scenarios.py; ``all`` for every one of ``replay/sitl``,
``held``, ``held2`` … ``held15`` for the held-out flights of
``replay/sitl_held``, ``episodes`` for those of ``replay/sitl_episodes``, ``packs`` for every
``pack_*`` flight of ``replay/sitl_packs``) is flown in a fresh SITL
(scratch directory, free instance) and written to ``DIR/<scenario>/``: ``flight.tlog``,
``truth.json`` and, for the scenarios that log it, ``flight.BIN``. ``--mission FILE`` flies
a mission file (.plan or .waypoints) in AUTO instead, optionally in a wind (``--wind``) and
with the gripper's load (``--gripper``), into ``DIR/<name>/`` with a copy of the file (the
name is the file's directory when it is called ``mission.*``). See docs/sitl.md and
docs/plan.md.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

from estimator.errors import UserError


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "sitl-record",
        description="Fly flight scenarios (wind, payload, battery, airframes) in ArduCopter "
        "SITL and record each one's tlog, DataFlash log and truth.json.",
    )
    p.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO",
        help="scenario names (the effects of replay/sitl, pack_* packs of replay/sitl_packs), "
        "or all (every effect scenario), held / held2 / ... (the held-out effect flights, "
        "one name per set: docs/residuals.md), "
        "episodes (wind episodes to tune on), or packs / "
        "packs2 / ... / packs7 (the first to seventh set of pack_* scenarios)",
    )
    p.add_argument("--mission", metavar="FILE", help="fly this mission file in AUTO instead")
    p.add_argument(
        "--wind", metavar="SPEED@FROM_DEG", help="with --mission: wind, m/s @ degrees (from)"
    )
    p.add_argument("--gripper", action="store_true", help="with --mission: carry 1 kg")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument("--speedup", default="10", metavar="N", help="SITL speedup (default 10)")
    p.add_argument("--binary", type=Path, metavar="FILE", help="arducopter SITL binary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from estimator.commands.sim import _pair
    from estimator.logs.mission_files import load_mission
    from estimator.sitl.episode_held_scenarios import HELD_SETS
    from estimator.sitl.episode_scenarios import EPISODE_SCENARIOS
    from estimator.sitl.recorder import record
    from estimator.sitl.scenarios import (
        PACK_SETS,
        SCENARIOS,
        Scenario,
        mission_scenario,
    )

    scenarios: list[Scenario]
    if args.mission is not None:
        if args.scenarios:
            raise UserError("give scenario names or --mission, not both")
        load_mission(args.mission).legs()  # a bad file fails here, before SITL starts
        wind = None if args.wind is None else _pair(args.wind, "--wind", "SPEED@FROM_DEG")
        if wind is not None and not 0 <= wind[0] <= 30:
            raise UserError("--wind speed must be between 0 and 30 m/s")
        scenarios = [mission_scenario(args.mission, wind, args.gripper)]
    else:
        if args.wind is not None or args.gripper:
            raise UserError("--wind and --gripper go with --mission")
        if not args.scenarios:
            raise UserError("name a scenario (or all), or give --mission FILE")
        groups = {
            "all": list(SCENARIOS),
            **{name: list(held) for name, held in HELD_SETS.items()},
            "episodes": list(EPISODE_SCENARIOS),
        }
        groups |= {g: list(s) for g, s in PACK_SETS.items()}
        known = dict(SCENARIOS)
        for named in (
            *HELD_SETS.values(),
            EPISODE_SCENARIOS, *PACK_SETS.values(),
        ):  # fmt: skip
            known |= named
        names = [n for name in args.scenarios for n in groups.get(name, [name])]
        unknown = [n for n in names if n not in known]
        if unknown:
            listed = ", ".join(known)
            raise UserError(
                f"unknown scenario {unknown[0]!r}; known: {', '.join(groups)}, {listed}"
            )
        scenarios = [known[n] for n in names]
    try:
        speedup = float(args.speedup)
    except ValueError:
        raise UserError(f"--speedup needs a number, got {args.speedup!r}") from None
    if not (math.isfinite(speedup) and 0 < speedup <= 100):
        raise UserError(f"--speedup must be in (0, 100], got {args.speedup!r}")
    if args.binary is not None and not args.binary.is_file():
        raise UserError(f"--binary {args.binary} is not a file")
    for scenario in scenarios:
        name = scenario.name
        started = time.monotonic()
        truth = record(scenario, args.out / name, speedup, args.binary)
        ev = truth.events
        flown = ev.get("landed_s", math.nan) - ev.get("takeoff_s", math.nan)
        print(
            f"{name}: {flown:.0f} s airborne, {len(truth.effects)} effect(s), "
            f"{time.monotonic() - started:.0f} s wall → {args.out / name}"
        )
    return 0
