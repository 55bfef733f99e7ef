"""SITL flight scenarios as data: a model, parameters, and steps flown in order.

Steps (positions local NED m from the take-off point, speeds m/s, durations s of the
autopilot's clock): :class:`Takeoff`, :class:`Hover`, :class:`Leg` (GUIDED velocity),
:class:`Goto` (GUIDED position), :class:`Circle` (GUIDED position + velocity + acceleration
along a circle), :class:`Mission` (AUTO), :class:`SetWind` (SIM_WIND_SPD/SIM_WIND_DIR),
:class:`Grip` (the simulated servo gripper), :class:`LegsToReserve` (legs and hovers in a
loop until the pack reaches its true reserve), :class:`AutoMission` (a mission file in AUTO).
Every flight ends with LAND (an AUTO mission that lands by itself ends there).

Packs (:func:`pack_scenario`; six sets, :data:`PACK_SETS`): a 3S pack labelled 5.0 Ah that
really holds less, with a higher resistance or partly charged at power-up
(:class:`estimator.sitl.pack.Pack`), flown to its true reserve.

Payload: ArduPilot's SITL servo gripper (SIM_GRPS_*) holds a 1.0 kg load once it closes on
the ground; the load's mass is added to the multicopter's (``MultiCopter::gross_mass``) from
2 m above ground (its string length) until the jaw opens (SIM_Gripper_Servo.cpp).
Wind: SIM_WIND_T = 1 (the same wind at every height; the default fades it below 60 m),
SIM_WIND_DIR is the direction it blows from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from estimator.sitl.pack import Pack

#: The servo gripper on output 9, as SITL's gripper model expects it.
GRIPPER_PARAMS = {
    "GRIP_ENABLE": 1, "GRIP_TYPE": 1, "GRIP_GRAB": 2000, "GRIP_RELEASE": 1000,
    "SERVO9_FUNCTION": 28,
    "SIM_GRPS_ENABLE": 1, "SIM_GRPS_PIN": 9, "SIM_GRPS_GRAB": 2000, "SIM_GRPS_RELEASE": 1000,
}  # fmt: skip
#: Load the SITL gripper carries (kg; fixed in SIM_Gripper_Servo.cpp).
GRIPPER_LOAD_KG = 1.0
#: Height above ground from which the gripper's load weighs on the vehicle (m).
GRIPPER_STRING_M = 2.0
#: DataFlash: only what a power analysis needs (ATTITUDE_MED, GPS, PM, CTUN, NTUN, CMD,
#: CURRENT, MOTBATT), written only while armed, streamed messages at most 4 Hz.
DATAFLASH_PARAMS = {
    "LOG_BACKEND_TYPE": 1, "LOG_BITMASK": 131902, "LOG_DISARMED": 0, "LOG_FILE_RATEMAX": 4,
}  # fmt: skip
NO_DATAFLASH = {"LOG_BACKEND_TYPE": 0}
#: Every flight: uniform wind, no turbulence; no failsafe on the short SITL pack; missions
#: start at their first item; the EKF estimates the wind from drag (the coefficients SITL
#: suggests for its quad at start-up), so the autopilot's WIND message carries it.
BASE_PARAMS = {
    "SIM_WIND_T": 1, "SIM_WIND_TURB": 0, "BATT_FS_LOW_ACT": 0, "BATT_FS_CRT_ACT": 0,
    "MIS_RESTART": 1, "EK3_DRAG_BCOEF_X": 17.209, "EK3_DRAG_BCOEF_Y": 17.209,
    "EK3_DRAG_MCOEF": 0.209, "SIM_ESC_TELEM": 0,
}  # fmt: skip
#: The draining 3S pack of ../shared/tools/ardupilot-sitl/quad_batt.json (model JSON keys).
DRAINING_PACK = {"maxVoltage": 12.6, "battCapacityAh": 2.2, "refBatRes": 0.01}
#: SITL sets every frame's hover power to refCurrent × refVoltage (29.3 A × 12.09 V) whatever
#: its mass or motor count (SIM_Frame.cpp); a heavier quad with the same rotors needs
#: (4/3)^1.5 of it: 45.1 A for 4 kg.
HEAVY_QUAD = {"mass": 4.0, "refCurrent": 45.1}


@dataclass(frozen=True)
class Takeoff:
    alt_m: float = 20.0


@dataclass(frozen=True)
class Hover:
    duration_s: float


@dataclass(frozen=True)
class Leg:
    """GUIDED velocity over ground for ``duration_s``: north, east and down (NED, m/s; a
    negative ``vd_mps`` climbs)."""

    vn_mps: float
    ve_mps: float
    duration_s: float
    vd_mps: float = 0.0


@dataclass(frozen=True)
class Goto:
    north_m: float
    east_m: float
    speed_mps: float


@dataclass(frozen=True)
class Circle:
    """``turns`` circles of ``radius_m`` at ``speed_mps`` (counter-clockwise seen from above
    when positive), starting where the vehicle is."""

    radius_m: float
    speed_mps: float
    turns: float


@dataclass(frozen=True)
class Mission:
    """AUTO through ``waypoints`` (north, east m from home, at the current height) at
    ``speed_mps``; back to GUIDED at the last one."""

    waypoints: tuple[tuple[float, float], ...]
    speed_mps: float


@dataclass(frozen=True)
class SetWind:
    speed_mps: float
    from_deg: float = 0.0


@dataclass(frozen=True)
class Grip:
    grab: bool


@dataclass(frozen=True)
class LegsToReserve:
    """``legs`` (velocity legs; a hover is a leg at 0 m/s) flown again and again until the
    pack's true state of charge is down to ``reserve_fraction``: the consumed charge reaches
    (state of charge at power-up − ``reserve_fraction``) × the capacity of the simulated
    pack."""

    legs: tuple[Leg, ...]
    reserve_fraction: float = 0.2


@dataclass(frozen=True)
class AutoMission:
    """The mission file ``path`` (QGroundControl .plan or ArduPilot .waypoints) uploaded with
    MISSION_ITEM_INT and flown in AUTO from the ground (armed in GUIDED, then
    MAV_CMD_MISSION_START) until the autopilot has landed and disarmed."""

    path: str


Step = (
    Takeoff | Hover | Leg | Goto | Circle | Mission | SetWind | Grip | LegsToReserve | AutoMission
)


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    steps: tuple[Step, ...]
    #: SITL ``--model`` frame (``quad``, ``hexa``); ``model_json`` overrides its parameters.
    frame: str = "quad"
    model_json: dict[str, Any] | None = None
    params: dict[str, float] = field(default_factory=dict)
    dataflash: bool = False

    def all_params(self) -> dict[str, float]:
        out: dict[str, float] = dict(BASE_PARAMS)
        out.update(DATAFLASH_PARAMS if self.dataflash else NO_DATAFLASH)
        if any(isinstance(s, Grip) for s in self.steps):
            out.update(GRIPPER_PARAMS)
        if self.model_json and "battCapacityAh" in self.model_json:
            out["BATT_CAPACITY"] = round(1000 * self.model_json["battCapacityAh"])
        out.update(self.params)
        return out


def out_and_back(speed_mps: float, leg_s: float) -> tuple[Leg, Leg]:
    """A north leg and a south leg of ``leg_s`` s at ``speed_mps`` m/s."""
    return Leg(speed_mps, 0, leg_s), Leg(-speed_mps, 0, leg_s)


#: Routes at 20 m: velocity legs across 2–12 m/s, circles, a mission.
LEGS = (
    Hover(30), Leg(4, 0, 25), Leg(-8, 0, 12.5), Hover(10), Leg(0, 6, 20), Leg(0, -12, 10),
    Leg(2, 0, 30), Leg(-10, 0, 6), Leg(0, 3, 30), Leg(0, -9, 10), Hover(20),
)  # fmt: skip
CIRCLES = (
    Hover(20), Circle(20, 4, 1), Circle(30, 8, 1.5), Goto(0, 0, 5), Circle(15, -6, 2),
    Goto(40, 40, 10), Goto(0, 0, 3), Hover(20),
)  # fmt: skip
SQUARE = ((0, 0), (80, 0), (80, 80), (0, 80), (0, 0))
MISSION = (Hover(20), Mission(SQUARE, 5), Mission(SQUARE, 10), Hover(20))


def by_name(*scenarios: Scenario) -> dict[str, Scenario]:
    """``scenarios`` keyed by their names."""
    return {s.name: s for s in scenarios}


SCENARIOS: dict[str, Scenario] = by_name(
    Scenario("clean_legs", "no effect; velocity legs 2–12 m/s", (Takeoff(), *LEGS)),
    Scenario("clean_circles", "no effect; circles r 15–30 m at 4–8 m/s", (Takeoff(), *CIRCLES)),
    Scenario("clean_mission", "no effect; AUTO square at 5 then 10 m/s", (Takeoff(), *MISSION)),
    Scenario(
        "wind_onset",
        "wind 6 m/s from 060° switched on mid-flight",
        (Takeoff(), *LEGS[:6], SetWind(6, 60), Hover(30), *LEGS[6:], *LEGS[1:4]),
        dataflash=True,
    ),
    Scenario(
        "wind_constant",
        "wind 5 m/s from 300° throughout",
        (SetWind(5, 300), Takeoff(), *LEGS),
    ),
    Scenario(
        "wind_stop",
        "wind 7 m/s from 200° that stops mid-flight",
        (SetWind(7, 200), Takeoff(), *LEGS[:6], SetWind(0), Hover(30), *LEGS[6:]),
    ),
    Scenario(
        "wind_turn",
        "wind 6 m/s turning from 090° to 180° mid-flight",
        (SetWind(6, 90), Takeoff(), *CIRCLES[:3], SetWind(6, 180), Hover(30), *CIRCLES[3:]),
    ),
    Scenario(
        "payload_takeoff",
        "1 kg gripper payload carried from take-off to landing",
        (Grip(True), Hover(3), Takeoff(), Hover(40), *LEGS[1:]),
    ),
    Scenario(
        "payload_release",
        "1 kg gripper payload released in a hover mid-flight",
        (
            Grip(True),
            Hover(3),
            Takeoff(),
            Hover(40),
            *LEGS[1:6],
            Hover(30),
            Grip(False),
            Hover(40),
            *LEGS[6:],
        ),
        dataflash=True,
    ),
    Scenario(
        "payload_wind",
        "1 kg payload from take-off and wind 5 m/s from 120° switched on mid-flight",
        (
            Grip(True),
            Hover(3),
            Takeoff(),
            Hover(40),
            *LEGS[1:6],
            SetWind(5, 120),
            Hover(30),
            *LEGS[6:],
        ),
    ),
    Scenario(
        "hexa_clean",
        "another airframe: SITL's built-in hexa (FRAME_CLASS 2), no effect",
        (Takeoff(), *LEGS[:6], Circle(20, 5, 1), Hover(20)),
        frame="hexa",
        params={"FRAME_CLASS": 2},
    ),
    Scenario(
        "heavy_quad",
        "another airframe: a 4 kg quad drawing the hover power of its weight (P ∝ m^1.5)",
        (Takeoff(), *LEGS),
        model_json=HEAVY_QUAD,
    ),
    Scenario(
        "battery_reserve",
        "draining 3S 2.2 Ah pack flown on 6 m/s legs to its 20 % reserve",
        (Takeoff(), Hover(30), LegsToReserve(out_and_back(6, 15))),
        model_json=DRAINING_PACK,
    ),
    Scenario(
        "wind_onset_circles",
        "wind 5 m/s from 330° switched on during circles",
        (Takeoff(), *CIRCLES[:2], SetWind(5, 330), *CIRCLES[2:]),
    ),
)


def mission_scenario(
    path: str, wind: tuple[float, float] | None = None, gripper: bool = False
) -> Scenario:
    """A flight of the mission file ``path`` in AUTO, named after the file's directory (or
    its stem for a file at the top), in a wind (m/s, from °) set before take-off, carrying the
    gripper's load from take-off when ``gripper``."""
    file = Path(path)
    name = file.parent.name if file.stem == "mission" else file.stem
    steps: list[Step] = []
    parts = []
    if wind is not None:
        steps.append(SetWind(*wind))
        parts.append(f"wind {wind[0]:g} m/s from {wind[1]:03.0f}°")
    if gripper:
        steps += [Grip(True), Hover(3)]
        parts.append(f"{GRIPPER_LOAD_KG:g} kg gripper payload")
    steps.append(AutoMission(str(file)))
    description = f"AUTO mission {file.name}" + (f", {', '.join(parts)}" if parts else "")
    return Scenario(name, description, tuple(steps))


#: A 90 m box at 6 m/s (sides of 15 s), and a 20 s hover (zero velocity).
BOX = (Leg(6, 0, 15), Leg(0, 6, 15), Leg(-6, 0, 15), Leg(0, -6, 15))
STOP = Leg(0, 0, 20)
#: Flown to a pack's reserve: the box, a hover, the box, a hover, out and back at 10 m/s, a
#: hover (198 s a loop): current steps for the pack's resistance.
PACK_LEGS = (*BOX, STOP, *BOX, STOP, *out_and_back(10, 9), STOP)


def pack_scenario(
    pack: Pack,
    wind: SetWind | None = None,
    wind_mid_flight: bool = False,
    payload: bool = False,
    airframe: dict[str, float] | None = None,
) -> Scenario:
    """A flight of ``pack`` on :data:`PACK_LEGS` to its true reserve, named
    ``pack_c<true capacity, % of the label>_r<resistance, 10 mΩ>[_soc<charge at power-up,
    %>][_wind][_payload]``; in ``wind`` from before take-off, or from after a first box when
    ``wind_mid_flight``; with the gripper's load from take-off when ``payload``; ``airframe``:
    model JSON keys of the quad itself."""
    name = (
        f"pack_c{100 * pack.true_capacity_ah / pack.labelled_capacity_ah:.0f}"
        f"_r{100 * pack.resistance_ohm:.0f}"
    )
    if pack.start_soc < 1:
        name += f"_soc{100 * pack.start_soc:.0f}"
    parts = [
        f"3S pack labelled {pack.labelled_capacity_ah:g} Ah holding {pack.true_capacity_ah:g} Ah, "
        f"{pack.resistance_ohm:g} Ω, {100 * pack.start_soc:.0f} % charged at power-up, "
        "flown to its true 20 % reserve"
    ]
    before: list[Step] = []
    airborne: list[Step] = [Takeoff(), Hover(20)]
    if wind is not None:
        name += "_wind"
        when = "switched on mid-flight" if wind_mid_flight else "from before take-off"
        parts.append(f"wind {wind.speed_mps:g} m/s from {wind.from_deg:03.0f}° {when}")
        if wind_mid_flight:
            airborne += [*BOX, wind]
        else:
            before.append(wind)
    if payload:
        name += "_payload"
        before += [Grip(True), Hover(3)]
        parts.append(f"{GRIPPER_LOAD_KG:g} kg gripper payload from take-off")
    if airframe:
        parts.append(", ".join(f"{key} {value:g}" for key, value in airframe.items()))
    steps = (*before, *airborne, LegsToReserve(PACK_LEGS))
    model_json = pack.model_json() | (airframe or {})
    return Scenario(name, "; ".join(parts), steps, model_json=model_json, params=pack.params())


#: Motors with more thrust for the quad with the 1 kg load on a 0.03 Ω pack: SITL's motor
#: thrust falls with the square of the voltage, and with SITL's hoverThrOut 0.39 the 4 kg quad
#: runs out of it at ~9.0 V under load (measured: 100 % throttle, sinking from 20 m, 25 % true
#: charge left), before the true reserve's 8.75 V. The current per thrust (refCurrent ×
#: refVoltage / hover thrust) is unchanged.
STRONG_MOTORS = {"hoverThrOut": 0.25}
#: Packs labelled 5.0 Ah: true capacity 100/80/65 %, 0.01 or 0.03 Ω, full or partly charged.
PACK_SCENARIOS: dict[str, Scenario] = by_name(
    pack_scenario(Pack(5.0, 0.01)),
    pack_scenario(Pack(4.0, 0.01)),
    pack_scenario(Pack(3.25, 0.01)),
    pack_scenario(Pack(5.0, 0.03)),
    pack_scenario(Pack(4.0, 0.03)),
    pack_scenario(Pack(3.25, 0.03)),
    pack_scenario(Pack(5.0, 0.01, 0.75)),
    pack_scenario(Pack(3.25, 0.03, 0.75)),
    pack_scenario(Pack(5.0, 0.01, 0.5)),
    pack_scenario(Pack(4.0, 0.03, 0.5)),
    pack_scenario(Pack(4.0, 0.01), SetWind(5, 300)),
    pack_scenario(Pack(3.25, 0.01), payload=True),
    pack_scenario(
        Pack(4.0, 0.03, 0.75),
        SetWind(5, 120),
        wind_mid_flight=True,
        payload=True,
        airframe=STRONG_MOTORS,
    ),
)
#: The second held-out set (recorded 2026-11-26 after the rules of commit 2190ac9 were frozen;
#: none of it tuned on): capacities, resistances, charges and winds the first 13 flights do
#: not have.
PACK_SCENARIOS_2: dict[str, Scenario] = by_name(
    pack_scenario(Pack(4.5, 0.02)),
    pack_scenario(Pack(3.5, 0.01, 0.85)),
    pack_scenario(Pack(4.5, 0.03), SetWind(3, 45)),
    pack_scenario(Pack(3.5, 0.02, 0.6)),
    pack_scenario(Pack(5.0, 0.02), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(4.0, 0.02, 0.85), SetWind(7, 200)),
    pack_scenario(Pack(3.5, 0.03, 0.7)),
)
#: The third held-out set (recorded 2026-11-26 after the rules of commit a8aa701 were frozen;
#: none of it tuned on): 60, 75, 85 and 95 % of the label, 40 mΩ (an old pack, on the
#: stronger motors so the quad keeps its thrust to the reserve), 90, 80, 65 and 55 % charged at
#: power-up, wind 4 m/s from 120° and 6 m/s from 330°.
PACK_SCENARIOS_3: dict[str, Scenario] = by_name(
    pack_scenario(Pack(3.75, 0.04), airframe=STRONG_MOTORS),
    pack_scenario(Pack(4.25, 0.01, 0.9)),
    pack_scenario(Pack(4.75, 0.02, 0.65), SetWind(4, 120)),
    pack_scenario(Pack(3.75, 0.02), SetWind(6, 330)),
    pack_scenario(Pack(4.25, 0.03, 0.8), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(5.0, 0.04, 0.55), airframe=STRONG_MOTORS),
    pack_scenario(Pack(3.0, 0.01)),
)
#: The fourth held-out set (recorded 2026-11-26 after the endurance's course averaging,
#: commit "endurance over the courses flown", was frozen; none of it tuned on): mostly wind,
#: the effect that rule is about — 3, 5, 6 and 8 m/s from four directions —, 65–95 % of the
#: label, 10–30 mΩ, 60–90 % charged at power-up, one with the payload.
PACK_SCENARIOS_4: dict[str, Scenario] = by_name(
    pack_scenario(Pack(4.5, 0.01), SetWind(6, 250)),
    pack_scenario(Pack(3.5, 0.02), SetWind(8, 30)),
    pack_scenario(Pack(5.0, 0.03, 0.8), SetWind(5, 170)),
    pack_scenario(Pack(4.0, 0.02, 0.7), SetWind(5, 90), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(3.25, 0.02)),
    pack_scenario(Pack(4.75, 0.01, 0.6)),
    pack_scenario(Pack(3.75, 0.03, 0.9), SetWind(3, 300)),
)
#: The fifth held-out set (recorded 2026-11-26 after the endurance's pattern rule, commit
#: "endurance over one period of a repeated pattern", was frozen; none of it tuned on):
#: strong wind that the quad cannot hold the box's speed into (8 and 9 m/s), a wind that
#: starts after the first box, 60–100 % of the label, 10–30 mΩ, 65–85 % charged at power-up,
#: the payload in wind.
PACK_SCENARIOS_5: dict[str, Scenario] = by_name(
    pack_scenario(Pack(3.25, 0.03), SetWind(9, 200)),
    pack_scenario(Pack(4.25, 0.02), SetWind(7, 60), wind_mid_flight=True),
    pack_scenario(Pack(4.5, 0.01, 0.75), SetWind(8, 300)),
    pack_scenario(Pack(3.75, 0.02, 0.85)),
    pack_scenario(Pack(5.0, 0.01), SetWind(4, 10), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(3.0, 0.02)),
    pack_scenario(Pack(4.0, 0.03, 0.65), SetWind(6, 140)),
)
#: The sixth held-out set (recorded 2026-11-26 after the endurance's pattern found by
#: matching the flight against itself, commit d8c59ea, was frozen; none of it tuned on): winds
#: of 3-9 m/s from six directions (one from after the first box), one flight without wind,
#: the payload on the stronger motors, 65-100 % of the label, 10-30 mΩ, 70-100 % charged.
PACK_SCENARIOS_6: dict[str, Scenario] = by_name(
    pack_scenario(Pack(3.5, 0.01), SetWind(8, 100)),
    pack_scenario(Pack(4.75, 0.03), SetWind(6, 240), wind_mid_flight=True),
    pack_scenario(Pack(4.0, 0.01, 0.8)),
    pack_scenario(Pack(3.25, 0.02, 0.9), SetWind(5, 330)),
    pack_scenario(Pack(4.5, 0.02), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(5.0, 0.02, 0.7), SetWind(9, 20)),
    pack_scenario(Pack(3.75, 0.01), SetWind(3, 180)),
)
#: The seventh held-out set (recorded 2026-11-26 after the bank's tempered weights, commit
#: 19b3e8c, were frozen; none of it tuned on), fourteen flights as the issue asks for:
#: 65-100 % of the label, 10-30 mΩ, 50-100 % charged, winds of 3-7 m/s from nine directions
#: (from before take-off), the payload on the stronger motors.
PACK_SCENARIOS_7: dict[str, Scenario] = by_name(
    pack_scenario(Pack(5.0, 0.03, 0.5)),
    pack_scenario(Pack(4.0, 0.01, 0.75), SetWind(5, 250)),
    pack_scenario(Pack(3.25, 0.03), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(4.0, 0.03), SetWind(7, 100)),
    pack_scenario(Pack(3.25, 0.01, 0.75), SetWind(4, 30)),
    pack_scenario(Pack(4.75, 0.01), SetWind(6, 160), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(4.25, 0.02, 0.9)),
    pack_scenario(Pack(5.0, 0.01, 0.75), SetWind(5, 300)),
    pack_scenario(Pack(4.5, 0.03, 0.6)),
    pack_scenario(Pack(3.25, 0.02), SetWind(6, 200)),
    pack_scenario(Pack(4.0, 0.02), SetWind(3, 80), payload=True, airframe=STRONG_MOTORS),
    pack_scenario(Pack(5.0, 0.03, 0.75), SetWind(4, 130)),
    pack_scenario(Pack(3.5, 0.01, 0.9)),
    pack_scenario(Pack(3.75, 0.03), SetWind(5, 350)),
)
#: Every set of pack scenarios by its ``sitl-record`` group name: the first (tuning and
#: held out), then the held-out sets recorded after each freeze.
PACK_SETS: dict[str, dict[str, Scenario]] = {
    "packs": PACK_SCENARIOS,
    "packs2": PACK_SCENARIOS_2,
    "packs3": PACK_SCENARIOS_3,
    "packs4": PACK_SCENARIOS_4,
    "packs5": PACK_SCENARIOS_5,
    "packs6": PACK_SCENARIOS_6,
    "packs7": PACK_SCENARIOS_7,
}
