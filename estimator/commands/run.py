"""``uav-energy run``: the onboard daemon (see docs/daemon.md)."""

from __future__ import annotations

import argparse
import asyncio
import logging
from typing import Any

from estimator.errors import UserError
from estimator.mavlink.config import LOG_LEVELS, ServiceConfig, build_config, load_config_file
from estimator.mavlink.service import Service
from estimator.physics.vehicle import default_vehicle, load_vehicle


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "run",
        description="Listen to the autopilot's telemetry, estimate remaining energy and "
        "endurance, and republish them as MAVLink component 191 (and JSON lines).",
    )
    parser.add_argument("--config", metavar="FILE", help="TOML configuration (config/default.toml)")
    parser.add_argument("--connect", metavar="URL", help="autopilot link, e.g. tcp:127.0.0.1:5760")
    parser.add_argument(
        "--publish",
        metavar="URL",
        action="append",
        help="output link for ground stations (repeatable), e.g. udpout:127.0.0.1:14551",
    )
    parser.add_argument("--vehicle", metavar="FILE", help="vehicle TOML (default: built-in)")
    parser.add_argument(
        "--pack",
        metavar="ID",
        help="the pack flown (with [pack] dir; default: its serial from the autopilot)",
    )
    parser.add_argument("--rate", type=float, metavar="HZ", help="publish rate (0: every estimate)")
    parser.add_argument("--json", metavar="DEST", help="JSON lines: '-' (stdout) or udp:HOST:PORT")
    parser.add_argument("--target", metavar="SYS:COMP", help="autopilot ids (default: first seen)")
    parser.add_argument("--system-id", type=int, help="our MAVLink system id (default 1)")
    parser.add_argument("--battery-id", type=int, help="BATTERY_STATUS id of our estimate")
    parser.add_argument("--stale-after", type=float, metavar="S", help="silence that marks stale")
    parser.add_argument("--log-level", choices=LOG_LEVELS)
    parser.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> ServiceConfig:
    """Merge defaults, the config file and the flags into a validated ServiceConfig."""
    file_values = load_config_file(args.config) if args.config else {}
    target_system = target_component = None
    if args.target:
        sys_text, _, comp_text = args.target.partition(":")
        if not sys_text.isdigit() or (comp_text and not comp_text.isdigit()):
            raise UserError(f"--target must be SYS or SYS:COMP, got {args.target!r}")
        target_system, target_component = int(sys_text), int(comp_text or 1)
    flags = {  # ServiceConfig key → (flag, value or None when not given)
        "connect": ("--connect", args.connect),
        "publish": ("--publish", tuple(args.publish) if args.publish else None),
        "vehicle": ("--vehicle", args.vehicle),
        "pack_id": ("--pack", args.pack),
        "publish_rate_hz": ("--rate", args.rate),
        "json": ("--json", args.json),
        "target_system": ("--target", target_system),
        "target_component": ("--target", target_component),
        "system_id": ("--system-id", args.system_id),
        "battery_id": ("--battery-id", args.battery_id),
        "stale_after_s": ("--stale-after", args.stale_after),
        "log_level": ("--log-level", args.log_level),
    }
    try:
        return build_config(file_values, {key: value for key, (_, value) in flags.items()})
    except UserError as exc:
        # a value from a flag is named by the flag, not by the config key it sets
        message = str(exc)
        for key, (flag, value) in flags.items():
            if value is not None and f"config '{key}'" in message:
                raise UserError(message.replace(f"config '{key}'", flag)) from None
        raise


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    vehicle = load_vehicle(config.vehicle) if config.vehicle else default_vehicle()
    logging.basicConfig(
        level=config.log_level_number,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    from estimator.analysis.mission_energy import remaining_energy_fn

    return asyncio.run(Service(config, vehicle, mission_energy=remaining_energy_fn(vehicle)).run())
