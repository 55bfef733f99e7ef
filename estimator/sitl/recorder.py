"""Fly one scenario in ArduCopter SITL; record ``flight.tlog``, ``flight.BIN``, ``truth.json``.

The tlog holds every message the recording ground station received (pymavlink's format: an
8-byte big-endian µs receive stamp, then the frame). ``truth.json`` holds the scenario, the
model and pack, every effect switched with its start and end in the autopilot's clock
(``time_boot_ms`` in s; wind speed m/s and the direction it blows from in degrees, payload
kg), and the take-off, landing and (when flown to it) reserve times. Times of the autopilot's
clock are those of the messages around the event (streams at 2–4 Hz: ±0.5 s).
"""

from __future__ import annotations

import bisect
import itertools
import json
import math
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from estimator.errors import UserError
from estimator.logs.mission_files import M_PER_DEG, load_mission
from estimator.sitl.launch import (
    HOME,
    SitlOptions,
    free_instance,
    running_sitl,
    serial_port,
    sitl_binary,
)
from estimator.sitl.pack import (
    CELLS,
    MAX_VOLTAGE_V,
    SITL_BATT_VOLTAGE_V,
    cell_voltage_v,
    soc_at_cell_voltage,
)
from estimator.sitl.pilot import Pilot
from estimator.sitl.scenarios import (
    GRIPPER_LOAD_KG,
    GRIPPER_STRING_M,
    AutoMission,
    Circle,
    Goto,
    Grip,
    Hover,
    Leg,
    LegsToReserve,
    Mission,
    Scenario,
    SetWind,
    Step,
    Takeoff,
)
from estimator.telemetry.decode import gripper_released

#: Above this height (m) the vehicle counts as airborne for take-off and landing times.
AIRBORNE_M = 1.0
#: Longest flight to the reserve (s of the autopilot's clock).
MAX_FLIGHT_S = 3600.0


@dataclass
class Truth:
    """What was switched on and when (s of the autopilot's clock)."""

    scenario: str
    description: str
    frame: str
    model_json: dict[str, Any] | None
    params: dict[str, float]
    speedup: float
    #: SITL's multicopter frame model mass without payload (SIM_Frame.h default 3.0 unless
    #: the model JSON says "mass"), kg.
    mass_kg: float = 3.0
    home: tuple[float, float, float, float] = HOME
    effects: list[dict[str, Any]] = field(default_factory=list)
    events: dict[str, float] = field(default_factory=dict)
    battery: dict[str, Any] = field(default_factory=dict)

    def open_effect(self, kind: str, at_s: float, **values: float) -> None:
        self.effects.append({"effect": kind, **values, "start_s": round(at_s, 3), "end_s": None})

    def close_effect(self, kind: str, at_s: float) -> None:
        for e in self.effects:
            if e["effect"] == kind and e["end_s"] is None:
                e["end_s"] = round(at_s, 3)

    def event(self, name: str, at_s: float) -> None:
        self.events.setdefault(name, round(at_s, 3))

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


class Flight:
    """Flies a scenario's steps with a :class:`Pilot` and keeps the :class:`Truth`."""

    def __init__(self, pilot: Pilot, scenario: Scenario, truth: Truth) -> None:
        self.pilot, self.scenario, self.truth = pilot, scenario, truth
        self.gripped = False
        self.payload_on = False
        self.landing = False
        pilot.listeners.append(self._watch)

    @property
    def now_s(self) -> float:
        return self.pilot.state.boot_s

    def _watch(self, msg: Any) -> None:
        """Take-off, landing and the gripper load's weight follow the height; the gripper is
        open or closed as the autopilot says it finished (a mission's own DO_GRIPPER too)."""
        s, t = self.pilot.state, self.pilot.state.boot_s
        if msg.get_type() == "HEARTBEAT" and s.armed:
            self.truth.event("armed_s", t)
        if msg.get_type() == "STATUSTEXT" and (released := gripper_released(msg.text)) is not None:
            self.gripped = not released
        if msg.get_type() != "GLOBAL_POSITION_INT":
            return
        if s.armed and s.alt_m > AIRBORNE_M:
            self.truth.event("takeoff_s", t)
        if self.landing and s.alt_m < AIRBORNE_M:
            self.truth.event("landed_s", t)
        weighs = self.gripped and s.alt_m >= GRIPPER_STRING_M
        if weighs and not self.payload_on:
            self.truth.open_effect("payload", t, mass_kg=GRIPPER_LOAD_KG)
        elif self.payload_on and not weighs:
            self.truth.close_effect("payload", t)
        self.payload_on = weighs

    def fly(self) -> None:
        p = self.pilot
        p.connect()
        for step in self.scenario.steps:
            self.step(step)
        self.landing = True
        if p.state.armed:
            p.land()
        self.truth.event("disarmed_s", self.now_s)
        p.hold(2.0)
        for kind in ("wind", "payload"):
            self.truth.close_effect(kind, self.now_s)

    def step(self, step: Step) -> None:
        p = self.pilot
        if isinstance(step, Takeoff):
            p.arm_guided()
            p.takeoff(step.alt_m)
        elif isinstance(step, Hover):
            here = (p.state.north_m, p.state.east_m, -p.state.alt_m)
            p.hold(step.duration_s, p.every(1.0, lambda: p.send_target(here)))
        elif isinstance(step, Leg):
            velocity = (step.vn_mps, step.ve_mps, step.vd_mps)
            p.hold(step.duration_s, p.every(0.5, lambda: p.send_velocity(*velocity)))
        elif isinstance(step, Goto):
            self._goto(step)
        elif isinstance(step, Circle):
            self._circle(step)
        elif isinstance(step, Mission):
            self._mission(step)
        elif isinstance(step, SetWind):
            self._wind(step)
        elif isinstance(step, Grip):
            action = mavlink.GRIPPER_ACTION_GRAB if step.grab else mavlink.GRIPPER_ACTION_RELEASE
            p.command(mavlink.MAV_CMD_DO_GRIPPER, 1, action)
            self.gripped = step.grab
        elif isinstance(step, LegsToReserve):
            self._to_reserve(step)
        elif isinstance(step, AutoMission):
            self._auto_mission(step)

    def _goto(self, step: Goto) -> None:
        p = self.pilot
        p.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, 1, step.speed_mps, -1)
        target = (step.north_m, step.east_m, -p.state.alt_m)
        tick = p.every(1.0, lambda: p.send_target(target))
        tick()

        def dist() -> float:
            return math.hypot(p.state.north_m - target[0], p.state.east_m - target[1])

        def arrived() -> bool:
            return dist() < 1.5 and math.hypot(p.state.vn_mps, p.state.ve_mps) < 0.5

        timeout = dist() / step.speed_mps + 40.0
        p.wait_for(arrived, timeout, f"goto {step.north_m:.0f},{step.east_m:.0f}", tick)

    def _circle(self, step: Circle) -> None:
        """Position, velocity and centripetal acceleration of a point moving round the
        circle, sent at 10 Hz of the autopilot's clock."""
        p = self.pilot
        omega = step.speed_mps / step.radius_m  # rad/s, signed: + counter-clockwise
        start_n, start_e, down = p.state.north_m, p.state.east_m, -p.state.alt_m
        # the centre is east of the start
        cn, ce, t0 = start_n, start_e + step.radius_m, p.state.boot_s

        def send() -> None:
            # θ from north towards east; counter-clockwise seen from above is θ decreasing;
            # the start (west of the centre) is θ = 3π/2
            theta = 1.5 * math.pi - omega * (p.state.boot_s - t0)
            r, w = step.radius_m, omega
            north = cn + r * math.cos(theta)
            east = ce + r * math.sin(theta)
            vel = (r * w * math.sin(theta), -r * w * math.cos(theta), 0.0)
            acc = (-r * w * w * math.cos(theta), -r * w * w * math.sin(theta), 0.0)
            p.send_target((north, east, down), vel, acc)

        duration = abs(step.turns * 2 * math.pi / omega)
        p.hold(duration, p.every(0.1, send))

    def _mission(self, step: Mission) -> None:
        p = self.pilot
        lat0, lon0, _, _ = HOME
        alt = p.state.alt_m
        frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        items = [(mavlink.MAV_CMD_NAV_WAYPOINT, frame, 0.0, 0.0, lat0, lon0, 0.0)]
        # DO_CHANGE_SPEED: speed type 1 (ground speed), m/s
        items.append((mavlink.MAV_CMD_DO_CHANGE_SPEED, frame, 1.0, step.speed_mps, 0, 0, 0))
        for north, east in step.waypoints:
            lat = lat0 + north / M_PER_DEG
            lon = lon0 + east / (M_PER_DEG * math.cos(math.radians(lat0)))
            items.append((mavlink.MAV_CMD_NAV_WAYPOINT, frame, 0.0, 0.0, lat, lon, alt))
        p.upload_mission(items)
        p.state.mission_reached = -1
        p.set_mode("AUTO")
        last = len(items) - 1
        length = sum(
            math.dist(a, b) for a, b in zip(step.waypoints, step.waypoints[1:], strict=False)
        )
        p.wait_for(
            lambda: p.state.mission_reached >= last,
            length / step.speed_mps + 60.0,
            "mission",
        )
        p.set_mode("GUIDED")

    def _auto_mission(self, step: AutoMission) -> None:
        """Upload the file's items, arm in GUIDED, MISSION_START (AUTO from the ground) and
        wait until the mission has landed the vehicle and it disarmed."""
        p = self.pilot
        mission = load_mission(step.path)
        legs = mission.legs()
        if legs[-1].kind not in ("land", "rtl"):
            raise UserError(f"{step.path}: an AUTO flight's mission must end with LAND or RTL")
        p.upload_items(mission.items)
        p.arm_guided()
        p.command(mavlink.MAV_CMD_MISSION_START, 0, 0)
        self.truth.event("mission_start_s", self.now_s)
        p.wait_for(lambda: p.state.alt_m > AIRBORNE_M, 60.0, "mission take-off")
        self.landing = True

        def landed() -> bool:
            return not p.state.armed or p.state.alt_m < 0.3

        p.wait_for(landed, MAX_FLIGHT_S, "mission to its landing")
        if p.state.armed:
            p.wait_disarmed()

    def _wind(self, step: SetWind) -> None:
        p, t = self.pilot, self.truth
        p.set_param("SIM_WIND_DIR", step.from_deg)
        p.set_param("SIM_WIND_SPD", step.speed_mps)
        t.close_effect("wind", self.now_s)
        if step.speed_mps > 0:
            t.open_effect("wind", self.now_s, speed_mps=step.speed_mps, from_deg=step.from_deg)

    def _to_reserve(self, step: LegsToReserve) -> None:
        """Loop over the step's legs until the consumed charge reaches the true reserve; the
        reserve's time, charge, voltage and current go to the truth."""
        p, pack = self.pilot, _battery_truth(self.scenario)
        if not pack["drains"]:
            raise UserError(f"{self.scenario.name}: LegsToReserve needs a draining pack")
        reserve_mah = 1000 * (pack["start_soc"] - step.reserve_fraction) * pack["capacity_ah"]
        ends_s = list(itertools.accumulate(leg.duration_s for leg in step.legs))
        start = p.state.boot_s

        def fly() -> None:
            into_s = (p.state.boot_s - start) % ends_s[-1]
            leg = step.legs[min(bisect.bisect_right(ends_s, into_s), len(ends_s) - 1)]
            p.send_velocity(leg.vn_mps, leg.ve_mps)

        def reached() -> bool:
            return p.state.consumed_mah >= reserve_mah

        p.wait_for(reached, MAX_FLIGHT_S, "flight to the reserve", p.every(0.5, fly))
        self.truth.event("reserve_s", self.now_s)
        self.truth.battery.update(
            reserve_consumed_mah=round(p.state.consumed_mah, 1),
            reserve_voltage_v=round(p.state.voltage_v, 3),
            reserve_current_a=round(p.state.current_a, 2),
        )


def record(
    scenario: Scenario,
    out_dir: Path,
    speedup: float = 10.0,
    binary: Path | None = None,
    on_step: Callable[[str], None] | None = None,
) -> Truth:
    """Fly ``scenario`` in a fresh SITL (scratch directory, free instance) and write
    ``flight.tlog``, ``truth.json`` and, when the scenario logs DataFlash, ``flight.BIN``
    into ``out_dir``."""
    binary = binary or sitl_binary()
    if binary is None:
        raise UserError(
            "no ArduCopter SITL binary: give --binary FILE, set ARDUPILOT_SITL_BINARY "
            "or provide ../shared/tools/ardupilot-sitl/arducopter"
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    params = scenario.all_params()
    truth = Truth(
        scenario=scenario.name,
        description=scenario.description,
        frame=scenario.frame,
        model_json=scenario.model_json,
        params=params,
        speedup=speedup,
        mass_kg=float((scenario.model_json or {}).get("mass", 3.0)),
        battery=_battery_truth(scenario),
    )
    with tempfile.TemporaryDirectory(prefix=f"sitl-{scenario.name}-") as scratch:
        work = Path(scratch)
        opts = SitlOptions(
            binary=binary,
            workdir=work,
            instance=free_instance(),
            model=scenario.frame,
            model_json=scenario.model_json,
            params=params,
            speedup=speedup,
        )
        with running_sitl(opts):
            pilot = Pilot(f"tcp:127.0.0.1:{serial_port(opts.instance)}", out_dir / "flight.tlog")
            try:
                Flight(pilot, scenario, truth).fly()
            finally:
                pilot.close()
        logs = sorted((work / "logs").glob("*.BIN"), key=lambda f: f.stat().st_mtime)
        for step in scenario.steps:
            if isinstance(step, AutoMission):
                _copy_mission(Path(step.path), out_dir)
        if scenario.dataflash and logs:
            shutil.copyfile(logs[-1], out_dir / "flight.BIN")
    (out_dir / "truth.json").write_text(json.dumps(truth.as_dict(), indent=1) + "\n")
    return truth


def _copy_mission(path: Path, out_dir: Path) -> None:
    """The flown mission file beside the recording, as ``mission.<suffix>``."""
    target = out_dir / f"mission{path.suffix}"
    if not target.exists() or not target.samefile(path):
        shutil.copyfile(path, target)


def _battery_truth(scenario: Scenario) -> dict[str, Any]:
    """The simulated pack (capacity Ah, resistance Ω, full voltage V), what the autopilot is
    told it holds (BATT_CAPACITY, Ah), and its voltage (V) and true state of charge (0–1) at
    power-up: SIM_BATT_VOLTAGE read in SITL's table."""
    pack = scenario.model_json or {}
    if "battCapacityAh" not in pack:
        return {
            "cells": CELLS,
            "capacity_ah": None,
            "max_voltage_v": MAX_VOLTAGE_V,
            "drains": False,
        }
    params = scenario.all_params()
    max_voltage_v = float(pack.get("maxVoltage", MAX_VOLTAGE_V))
    set_v = float(params.get("SIM_BATT_VOLTAGE", SITL_BATT_VOLTAGE_V))
    start_voltage_v = min(set_v, max_voltage_v)  # Battery::init_voltage
    return {
        "cells": CELLS,
        "capacity_ah": pack["battCapacityAh"],
        "labelled_capacity_ah": params["BATT_CAPACITY"] / 1000,
        "max_voltage_v": max_voltage_v,
        "internal_resistance_ohm": pack.get("refBatRes"),
        "drains": True,
        "start_voltage_v": start_voltage_v,
        "start_soc": round(soc_at_cell_voltage(cell_voltage_v(start_voltage_v, max_voltage_v)), 4),
    }
