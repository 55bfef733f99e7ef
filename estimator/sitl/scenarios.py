"""SITL flight scenarios as data: a model, parameters, and steps flown in order.

Steps (positions local NED m from the take-off point, speeds m/s, durations s of the
autopilot's clock): :class:`Takeoff`, :class:`Hover`, :class:`Leg` (GUIDED velocity),
:class:`Goto` (GUIDED position), :class:`Circle` (GUIDED position + velocity + acceleration
along a circle), :class:`Mission` (AUTO), :class:`SetWind` (SIM_WIND_SPD/SIM_WIND_DIR),
:class:`Grip` (the simulated servo gripper), :class:`LegsToReserve` (out-and-back legs until
the pack reaches its reserve), :class:`AutoMission` (a mission file in AUTO). Every flight
ends with LAND (an AUTO mission that lands by itself ends there).

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
    vn_mps: float
    ve_mps: float
    duration_s: float


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
    """North/south legs of ``leg_s`` at ``speed_mps`` until the consumed charge reaches
    (1 − ``reserve_fraction``) of the pack's capacity."""

    speed_mps: float
    leg_s: float
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

SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
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
            (Takeoff(), Hover(30), LegsToReserve(6, 15)),
            model_json=DRAINING_PACK,
        ),
        Scenario(
            "wind_onset_circles",
            "wind 5 m/s from 330° switched on during circles",
            (Takeoff(), *CIRCLES[:2], SetWind(5, 330), *CIRCLES[2:]),
        ),
    )
}


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
