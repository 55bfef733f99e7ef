"""``uav-energy demo``: a simulated mission with a hidden wind, flown live into the daemon."""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from estimator.sim.demo import run_demo, summary_table


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "demo",
        description="The simulator flies a mission with a wind the estimator is not told "
        "about, over loopback MAVLink into the daemon; a live table shows predicted vs "
        "measured power and endurance, then an accuracy summary.",
    )
    p.add_argument("--speedup", type=float, default=20.0, help="× real time (default 20)")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="tlog and truth directory")
    p.add_argument("--seed", type=int, default=0, help="simulator noise seed")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    summary = run_demo(speedup=args.speedup, out_dir=args.out, seed=args.seed)
    Console().print(summary_table(summary))
    return 0
