"""The figures of docs/plan.md and docs/replay.md on the ArduCopter SITL missions of
``replay/sitl/missions``:

- ``plan-*``: ``uav-energy plan`` against the recorded missions (told the wind and payload
  SITL flew; and told still air), the example of docs/plan.md, a headwind leg's ground speed
  as flown, and the planner's climb term against SITL's vertical law on
  ``replay/sitl_axial`` (``tests/vertical_fit.py``);
- ``replay-mission``: docs/replay.md's mission given to a replay (``uav-energy replay F.tlog
  --vehicle SITL --mission F.waypoints``), its mission figure against the energy drawn.

``scripts/figures.py`` registers the blocks (:func:`generators`); ``tests/test_figures.py``
checks them (``tests/test_replay.py`` reads a replay's mission figure with
:func:`mission_figure`).
"""

from __future__ import annotations

import csv
import json
import math
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from estimator.analysis.mission_energy import FlightSettings, LegResult, MissionEnergy
from estimator.analysis.mission_validation import (
    MissionCheck,
    check_recording,
    item_ground_speeds_mps,
    leg_checks,
    predict_recording,
    truth_conditions,
)
from estimator.logs.mission_files import load_mission
from estimator.physics.lean_limit import along_track_limit_mps
from estimator.physics.route_energy import Conditions, RouteVehicle, steady_power_w
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.truth_check import angle_deg

#: What ``uav-energy ARGV…`` prints on stdout (``scripts/figures.py`` runs it in process).
Cli = Callable[..., str]

REPO = Path(__file__).resolve().parent.parent
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
MISSIONS = REPO / "replay" / "sitl" / "missions"
#: The missions the planner's flight settings were read off (docs/plan.md, "Calibration").
CALIBRATION = ("climbs_wind6", "outback_wind8", "square_wind5")
#: The planner's held-out missions, by name prefix, in the order they were flown (docs/plan.md):
#: the lean limit off the nose, then its payload scaling (rtl_payload_wind4's miss), each set
#: written and flown after its rule was frozen; the last is held out from every rule.
HELD_OUT_SETS = {"rtl_": "held out (lean limit)", "lean2_": "held out (lean limit, payload)"}
LATEST_HELD_OUT = "lean2_"


def _mission_dirs() -> list[Path]:
    """The recorded missions (a mission file without its flight is not one yet)."""
    return sorted(p for p in MISSIONS.iterdir() if (p / "truth.json").is_file())


def _truth(directory: Path) -> dict[str, Any]:
    return dict(json.loads((directory / "truth.json").read_text()))


@cache
def mission_checks(
    still_air: bool = False, settings: FlightSettings | None = None
) -> tuple[MissionCheck, ...]:
    """Every recorded mission planned with the SITL vehicle file and ``settings``, told the
    wind and payload SITL flew (or, ``still_air``, the payload only)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    checks = []
    for directory in _mission_dirs():
        told = truth_conditions(_truth(directory))
        conditions = replace(told, wind_speed_mps=0.0) if still_air else told
        checks.append(check_recording(directory, vehicle, settings, conditions))
    return tuple(checks)


def _mission_inputs(directory: Path) -> str:
    """The mission file, the wind and payload SITL flew and the legs: a row's first cells."""
    told = truth_conditions(_truth(directory))
    mission_file = sorted(directory.glob("mission.*"))[0]
    legs = load_mission(mission_file).legs()
    load = "–"
    if told.payload_kg > 0:
        load = f"{told.payload_kg:g} kg" + (", released" if not legs[-1].payload else "")
    return (
        f"| {directory.name} | `{mission_file.name}` "
        f"| {told.wind_speed_mps:g} m/s from {told.wind_from_deg:03.0f}° | {load} | {len(legs)}"
    )


def _abs_errors(checks: Sequence[MissionCheck], px4: bool = False) -> np.ndarray:
    return np.abs([c.px4_error_pct if px4 else c.error_pct for c in checks])


def missions_table(fits: ModuleType) -> str:
    """The per-mission rows of docs/plan.md's SITL table; ``fits``:
    ``scripts/fit_figures.py`` (its number format)."""
    rows = []
    for directory, c in zip(_mission_dirs(), mission_checks(), strict=True):
        half = "calibration" if c.name in CALIBRATION else "held out"
        half = next((v for k, v in HELD_OUT_SETS.items() if c.name.startswith(k)), half)
        rows.append(
            f"{_mission_inputs(directory)} | {c.predicted_wh:.2f} ± {c.predicted_sigma_wh:.2f} "
            f"| {c.measured_wh:.2f} | {fits.number(c.error_pct, '+.1f')} % | {c.px4_wh:.2f} "
            f"| {fits.number(c.px4_error_pct, '+.1f')} % "
            f"| {c.predicted_time_s:.0f} / {c.measured_time_s:.0f} | {half} |"
        )
    header = (
        "| mission | file | wind | payload | legs | predicted Wh ± 1σ | measured Wh | error "
        "| PX4-style Wh | PX4-style error | time s plan / flown | |\n"
        "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"
    )
    return header + "\n" + "\n".join(rows)


def summary() -> str:
    checks = mission_checks()
    held = [c for c in checks if c.name.startswith(LATEST_HELD_OUT)]
    seen = [c for c in checks if c not in held]
    ours, px4 = _abs_errors(seen), _abs_errors(checks, px4=True)
    text = (
        f"Median |error| {np.median(ours):.1f} % (max {ours.max():.1f} %) over the "
        f"{len(seen)} missions seen when the rules were set, the planner told the wind and "
        f"payload SITL flew"
    )
    if held:
        errors = _abs_errors(held)
        text += (
            f"; {np.median(errors):.1f} % (max {errors.max():.1f} %) over the {len(held)} "
            f"flown after the last was frozen"
        )
    return (
        f"{text}; the PX4-style estimate misses by {np.median(px4):.0f} % in the median "
        f"({px4.min():.0f}–{px4.max():.0f} %)"
    )


#: docs/plan.md's example: a mission and the wind SITL flew it in.
PLAN_EXAMPLE = (MISSIONS / "climbs_wind6" / "mission.plan", "6@135")


def example(cli: Cli) -> str:
    """``uav-energy plan MISSION --vehicle SITL --wind W``'s output as a code block, from the
    table on: without its title (it holds the mission's absolute path, so how it wraps follows
    where the repository is checked out) and the table's rules (their width follows the
    terminal)."""
    mission, wind = PLAN_EXAMPLE
    out = cli("plan", str(mission), "--vehicle", str(SITL_VEHICLE), "--wind", wind).splitlines()
    table = next(i for i, line in enumerate(out) if line.startswith("┏"))
    lines = [line.rstrip() for line in out[table:] if line[:1] not in "┏┡├└"]
    return "\n".join(["```", *lines, "```"])


def c1_c3_sigma() -> str:
    """The 1σ of the hover power the planner takes from the SITL vehicle file's c1 and c3 as
    independent, % of the hover power."""
    vehicle = load_vehicle(SITL_VEHICLE)
    sigma_w = math.hypot(vehicle.model_stderr["c1"], vehicle.model_stderr["c3"])
    return f"≈ {100 * sigma_w / vehicle.model.hover_power_w:.0f} % of hover power"


def within_sigma() -> str:
    """How many of the missions' predictions (told the wind and payload SITL flew) lie within
    their 1σ of the measured energy."""
    checks = mission_checks()
    within = sum(abs(c.predicted_wh - c.measured_wh) <= c.predicted_sigma_wh for c in checks)
    every = "every prediction is" if within == len(checks) else f"{within} predictions are"
    return f"Over the {len(checks)} SITL missions below {every} within its 1σ of the measurement"


def still_air_errors() -> str:
    errors = _abs_errors(mission_checks(still_air=True))
    return f"{np.median(errors):.1f} % / {errors.max():.1f} %"


def airspeed_total() -> str:
    """The airspeed limit (10.5 m/s) on the total airspeed instead of along the track."""
    settings = FlightSettings(max_airspeed_mps=10.5, airspeed_along_track=False)
    errors = _abs_errors(mission_checks(settings=settings))
    return f"{np.median(errors):.1f} % / {errors.max():.1f} %"


#: The mission whose legs docs/plan.md sets planned against flown (the RTL off the nose).
PLAN_LEGS_MISSION = MISSIONS / "tall_wind4"


def legs_table(fits: ModuleType) -> str:
    """tall_wind4's legs, planned (told the wind SITL flew) against flown."""
    rows = [
        f"| {c.seq} | {c.kind} | {c.planned_time_s:.1f} / {c.flown_time_s:.1f} "
        f"| {c.planned_wh:.2f} / {c.flown_wh:.2f} | {fits.number(c.error_pct, '+.1f')} % |"
        for c in leg_checks(PLAN_LEGS_MISSION, load_vehicle(SITL_VEHICLE))
    ]
    header = "| item | leg | time s plan / flown | energy Wh plan / flown | error |\n"
    return header + "|---:|---|---:|---:|---:|\n" + "\n".join(rows)


#: The climb and descent rates (m/s) docs/plan.md gives the planner's climb term at.
CLIMB_MPS, DESCENT_MPS = 2.5, 1.5


def climb_power(fits: ModuleType, vertical_fit: ModuleType) -> str:
    """The planner's power beyond hover (W) at :data:`CLIMB_MPS` up and :data:`DESCENT_MPS`
    down with the SITL vehicle file, and SITL's at the same rates: its vertical law fitted on
    the climbs and descents of ``replay/sitl_axial`` (``vertical_fit``:
    ``tests/vertical_fit.py``)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    climb_mps = np.array([CLIMB_MPS, -DESCENT_MPS])
    route = RouteVehicle.from_vehicle(vehicle)
    hover_w, *planned_w = steady_power_w(route, Conditions(), 0.0, 0.0, [0.0, *-climb_mps])
    axial = [vertical_fit.axial_samples(name) for name in vertical_fit.AXIAL_FLIGHTS]
    per_mps, per_mps2, _ = vertical_fit.vertical_response(axial, vehicle)
    sitl_w = per_mps * climb_mps + per_mps2 * climb_mps * np.abs(climb_mps)
    up, down = (
        f"{fits.number(plan_w - hover_w, '+.0f')} W at {abs(rate):g} m/s {way}"
        for plan_w, rate, way in zip(planned_w, climb_mps, ("up", "down"), strict=True)
    )
    measured = " and ".join(f"{fits.number(w, '+.0f')} W" for w in sitl_w)
    return (
        f"{up} and {down}, where SITL draws {measured} (its vertical law fitted on the "
        f"flights of `replay/sitl_axial`)"
    )


#: The recorded mission whose headwind leg docs/plan.md names among the remaining misses.
HEADWIND_MISSION = MISSIONS / "outback_wind8"


def upwind_leg(plan: MissionEnergy) -> LegResult:
    """The waypoint leg of ``plan`` flown most nearly into its wind."""
    legs = [r for r in plan.legs if r.leg.kind == "waypoint"]
    return min(legs, key=lambda r: angle_deg(r.track_deg, plan.conditions.wind_from_deg))


def headwind_leg() -> str:
    """On :data:`HEADWIND_MISSION`, the waypoint leg flown most nearly into the wind SITL
    flew: its ground speed as flown (the median) and as planned (m/s)."""
    plan = predict_recording(HEADWIND_MISSION, load_vehicle(SITL_VEHICLE))
    upwind = upwind_leg(plan)
    flown_mps = float(
        np.median(item_ground_speeds_mps(HEADWIND_MISSION / "flight.tlog", upwind.leg.seq))
    )
    return (
        f"`{HEADWIND_MISSION.name}`: the quad makes {flown_mps:.1f} m/s into "
        f"{plan.conditions.wind_speed_mps:g} m/s, planned {upwind.energy.ground_speed_mps:.1f}"
    )


def example_upwind() -> str:
    """docs/plan.md's example (:data:`PLAN_EXAMPLE`, planned in the wind SITL flew it in): its
    leg most nearly into the wind, the speed the mission asks, the ground speed planned, and
    its share of the energy (%)."""
    plan = predict_recording(PLAN_EXAMPLE[0].parent, load_vehicle(SITL_VEHICLE))
    upwind = upwind_leg(plan)
    asked_mps = upwind.leg.speed_mps or plan.settings.cruise_mps
    share = 100 * upwind.energy.energy_wh / plan.total.energy_wh
    return (
        f"Leg {plan.legs.index(upwind) + 1} flies into the wind: the mission asks "
        f"{asked_mps:g} m/s, the SITL quad makes {upwind.energy.ground_speed_mps:.1f} m/s over "
        f"ground at its airspeed limit, and that one leg takes {share:.0f} % of the energy"
    )


#: The crosswind (m/s, across a track the nose follows) docs/plan.md gives the headway it costs.
CROSSWIND_MPS = 7.0


def crosswind_headway() -> str:
    """The SITL quad's airspeed limit along its track (nose on it) in :data:`CROSSWIND_MPS`
    across, against its limit straight ahead (m/s)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    assert vehicle.drag is not None and vehicle.max_airspeed_mps is not None
    straight = vehicle.max_airspeed_mps
    along = along_track_limit_mps(vehicle.drag, straight, (0.0, CROSSWIND_MPS), 0.0, 0.0)
    return f"{along:.1f} m/s along the track in {CROSSWIND_MPS:g} m/s across, against {straight:g}"


def headline() -> str:
    checks = mission_checks()
    told, still = _abs_errors(checks), _abs_errors(mission_checks(still_air=True))
    held = _abs_errors([c for c in checks if c.name.startswith(LATEST_HELD_OUT)])
    px4 = _abs_errors(checks, px4=True)
    return (
        f"{len(told)} AUTO missions, told the wind SITL flew: median error "
        f"{np.median(told):.1f} %, max {told.max():.1f} % ({len(held)} held out: "
        f"{np.median(held):.1f} %, max {held.max():.1f} %; 3 of the others set the flight "
        f"settings); told still air: {np.median(still):.1f} % / {still.max():.0f} %; a "
        f"PX4-style distance/set-speed estimate misses by {np.median(px4):.0f} %"
    )


#: The SITL AUTO mission docs/replay.md replays with its mission file (``--mission``).
MISSION_REPLAYED = MISSIONS / "square_wind5"
#: How long after take-off (s) that mission's figure is read.
MISSION_READ_AFTER_S = 30.0


def estimates_csv(cli: Cli, *argv: str) -> list[dict[str, str]]:
    """The rows of ``uav-energy replay ARGV… --out F.csv``."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "estimates.csv"
        cli("replay", *argv, "--out", str(out))
        with out.open() as fh:
            return list(csv.DictReader(fh))


def mission_figure(flight: Path, rows: Sequence[Mapping[str, str]]) -> tuple[float, float, float]:
    """A replay's estimate rows of the SITL mission recording ``flight``: the rest of the
    mission's energy and its 1σ :data:`MISSION_READ_AFTER_S` after take-off (``MIS_WH``,
    ``MIS_SIG``, Wh), and the energy the vehicle drew from then to the disarm (Wh, ∫ V·I of
    its own readings, trapezoids)."""
    events = _truth(flight)["events"]
    time_s = [float(r["time_s"]) for r in rows]
    power_w = [float(r["power_measured_w"]) for r in rows]
    at = next(k for k, t in enumerate(time_s) if t >= events["takeoff_s"] + MISSION_READ_AFTER_S)
    end = next(k for k, t in enumerate(time_s) if t >= events["disarmed_s"])
    drawn_wh = sum(
        0.5 * (power_w[k] + power_w[k + 1]) * (time_s[k + 1] - time_s[k]) for k in range(at, end)
    )
    return (
        float(rows[at]["mission_energy_wh"]),
        float(rows[at]["mission_sigma_wh"]),
        drawn_wh / 3600,
    )


def replay_mission(cli: Cli, fits: ModuleType) -> str:
    """docs/replay.md: ``uav-energy replay F.tlog --vehicle SITL --mission F.waypoints`` of
    :data:`MISSION_REPLAYED`, its mission figure against the energy drawn."""
    tlog, mission = MISSION_REPLAYED / "flight.tlog", MISSION_REPLAYED / "mission.waypoints"
    rows = estimates_csv(cli, str(tlog), "--vehicle", str(SITL_VEHICLE), "--mission", str(mission))
    predicted_wh, sigma_wh, drawn_wh = mission_figure(MISSION_REPLAYED, rows)
    return (
        f"{predicted_wh:.2f} ± {sigma_wh:.2f} Wh against {drawn_wh:.2f} Wh drawn, "
        f"{fits.number(100 * (predicted_wh / drawn_wh - 1), '+.1f')} %"
    )


def generators(
    cli: Cli, fits: ModuleType, vertical_fit: ModuleType
) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it; ``fits``: ``scripts/fit_figures.py`` (its
    number format); ``vertical_fit``: ``tests/vertical_fit.py``."""
    return {
        "plan-missions": partial(missions_table, fits),
        "plan-summary": summary,
        "plan-example": partial(example, cli),
        "plan-c1-c3-sigma": c1_c3_sigma,
        "plan-within-sigma": within_sigma,
        "plan-still-air": still_air_errors,
        "plan-airspeed-total": airspeed_total,
        "plan-legs": partial(legs_table, fits),
        "plan-climb-power": partial(climb_power, fits, vertical_fit),
        "plan-headwind-leg": headwind_leg,
        "plan-example-upwind": example_upwind,
        "plan-crosswind-headway": crosswind_headway,
        "plan-headline": headline,
        "replay-mission": partial(replay_mission, cli, fits),
    }
