"""Mission files: QGroundControl ``.plan`` (JSON) and ArduPilot ``.waypoints`` (QGC WPL 110).

:func:`load_mission` reads either (by content) into a :class:`MissionFile`: home and the
mission items as the autopilot receives them (item 0 is home, as in ArduPilot's mission
protocol), and :meth:`MissionFile.legs`, the route as local legs, NED metres from home.

Supported commands: NAV_WAYPOINT, NAV_TAKEOFF, NAV_LOITER_TIME, NAV_LOITER_TURNS, NAV_LAND,
NAV_RETURN_TO_LAUNCH, DO_CHANGE_SPEED and DO_GRIPPER (release drops the payload). Other DO_ and
CONDITION_ items do not move the vehicle and are ignored (listed in ``ignored``); any other
navigation command, DO_JUMP, a QGroundControl ComplexItem (survey, corridor scan, structure
scan) and terrain-relative altitudes are refused with one sentence naming the item. Altitude frames:
MAV_FRAME_GLOBAL (above mean sea level, relative to home's) and MAV_FRAME_GLOBAL_RELATIVE_ALT
(above home), and their _INT forms. Horizontal positions are projected on the plane tangent at
home (equirectangular: within 0.1 % over 10 km). Numbers are checked against their ranges
(altitudes within ±10 km, hold times, turns, radii and speeds, :data:`ALTITUDE_RANGE_M` and
below) and a .plan's nesting before it is parsed; a FIFO or a device is refused unopened.

Following ArduCopter: a waypoint at latitude and longitude 0 stays where the vehicle is; a
loiter at altitude 0 keeps the current height; a landing flies to its position (0, 0: where it
is) at the current height and descends; take-off climbs straight up.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from estimator.errors import UserError
from estimator.file_checks import check_nesting, in_range, regular_file

#: Metres per degree of latitude (spherical Earth, radius 6378137 m).
M_PER_DEG = 111_319.5
#: Allowed ranges (inclusive): an altitude in any frame (m), a hold or loiter time (s), loiter
#: turns, a loiter radius (m), a DO_CHANGE_SPEED speed (m/s).
ALTITUDE_RANGE_M = (-10_000.0, 10_000.0)
HOLD_RANGE_S = (-1.0, 86_400.0)
TURNS_RANGE = (-1.0, 1000.0)
RADIUS_RANGE_M = (-10_000.0, 10_000.0)
SPEED_RANGE_MPS = (-1.0, 100.0)
#: A hold time (s), a number of turns or a loiter radius (m) below this is none.
MIN_PARAM = 1e-6

# MAV_CMD numbers (common.xml)
NAV_WAYPOINT = 16
NAV_LOITER_TURNS = 18
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
DO_JUMP = 177
DO_CHANGE_SPEED = 178
DO_GRIPPER = 211
#: Commands the route follows, by name (for messages).
COMMAND_NAMES = {
    NAV_WAYPOINT: "NAV_WAYPOINT",
    NAV_LOITER_TURNS: "NAV_LOITER_TURNS",
    NAV_LOITER_TIME: "NAV_LOITER_TIME",
    NAV_RETURN_TO_LAUNCH: "NAV_RETURN_TO_LAUNCH",
    NAV_LAND: "NAV_LAND",
    NAV_TAKEOFF: "NAV_TAKEOFF",
    DO_CHANGE_SPEED: "DO_CHANGE_SPEED",
    DO_GRIPPER: "DO_GRIPPER",
}
#: MAV_CMD ranges that do not move the vehicle: CONDITION_* (112–159) and DO_* (176–252).
_NON_NAV = (range(112, 160), range(176, 253))
# MAV_FRAME numbers
FRAME_GLOBAL = (0, 5)
FRAME_RELATIVE = (3, 6)
FRAME_TERRAIN = (10, 11)
FRAME_MISSION = 2

Ned = tuple[float, float, float]
#: Checked params of navigation commands: (index, name, allowed range, unit).
_PARAM_RANGES = {
    NAV_WAYPOINT: ((0, "hold time (param1)", HOLD_RANGE_S, "s"),),
    NAV_LOITER_TIME: ((0, "loiter time (param1)", HOLD_RANGE_S, "s"),),
    NAV_LOITER_TURNS: (
        (0, "turns (param1)", TURNS_RANGE, ""),
        (2, "radius (param3)", RADIUS_RANGE_M, "m"),
    ),
}


@dataclass(frozen=True)
class MissionItem:
    """One item as uploaded: ``seq`` (0 = home), MAV_CMD ``command``, MAV_FRAME ``frame``,
    param1..4, latitude/longitude (deg) and altitude (m, in ``frame``); ``where`` names it in
    the file for messages (``line 7`` or ``item 3``)."""

    seq: int
    command: int
    frame: int
    params: tuple[float, float, float, float]
    lat_deg: float
    lon_deg: float
    alt_m: float
    where: str


@dataclass(frozen=True)
class MissionLeg:
    """A piece of the route, NED metres from home (down = −height above home).

    kind: "takeoff", "waypoint", "loiter_time", "loiter_turns", "land" or "rtl".
    start_ned_m, end_ned_m: where it begins and ends (a landing ends on the ground, an RTL at
    home on the ground). hold_s: time held at the end (waypoint delay, loiter time), s.
    turns, radius_m: circles of a loiter-turns (flown round ``end_ned_m``). speed_mps:
    horizontal ground speed set by DO_CHANGE_SPEED (None: the vehicle's default).
    climb_rate_mps, descent_rate_mps: set by DO_CHANGE_SPEED types 2/3 (None: default).
    payload: False once a DO_GRIPPER release has dropped it. seq: the mission item.
    """

    kind: str
    seq: int
    start_ned_m: Ned
    end_ned_m: Ned
    hold_s: float = 0.0
    turns: float = 0.0
    radius_m: float = 0.0
    speed_mps: float | None = None
    climb_rate_mps: float | None = None
    descent_rate_mps: float | None = None
    payload: bool = True


@dataclass(frozen=True)
class MissionFile:
    """A mission read from ``path``: home (lat, lon deg, altitude m above mean sea level) and
    the items, item 0 being home; ``ignored`` lists items the route does not need."""

    path: str
    home_lat_deg: float
    home_lon_deg: float
    home_alt_amsl_m: float
    items: tuple[MissionItem, ...]
    ignored: tuple[str, ...] = field(default=())

    def ned_m(self, item: MissionItem) -> Ned:
        """The item's position, NED metres from home (lat/lon projected at home)."""
        north = (item.lat_deg - self.home_lat_deg) * M_PER_DEG
        east = (
            (item.lon_deg - self.home_lon_deg)
            * M_PER_DEG
            * math.cos(math.radians(self.home_lat_deg))
        )
        return north, east, -self.height_m(item)

    def height_m(self, item: MissionItem) -> float:
        """The item's altitude above home, m."""
        if item.frame in FRAME_GLOBAL:
            return item.alt_m - self.home_alt_amsl_m
        return item.alt_m

    def legs(self) -> list[MissionLeg]:
        """The route from home on the ground through every navigation item, in order. A
        mission that ends in the air (no LAND or RTL) ends with its last leg."""
        legs: list[MissionLeg] = []
        here: Ned = (0.0, 0.0, 0.0)
        speed: float | None = None
        climb: float | None = None
        descent: float | None = None
        payload = True
        for item in self.items[1:]:
            cmd, p = item.command, item.params
            if cmd == DO_CHANGE_SPEED:
                speed, climb, descent = _speed_change(item, speed, climb, descent)
                continue
            if cmd == DO_GRIPPER:
                payload = p[1] != 0  # param2: 0 release, 1 grab
                continue
            if cmd not in COMMAND_NAMES:
                continue
            target = self._target(item, here)
            hold, turns, radius = 0.0, 0.0, 0.0
            if cmd == NAV_TAKEOFF:
                kind, target = "takeoff", (here[0], here[1], target[2])
            elif cmd == NAV_WAYPOINT:
                kind, hold = "waypoint", _nonneg(p[0])
            elif cmd == NAV_LOITER_TIME:
                kind, hold = "loiter_time", _nonneg(p[0])
            elif cmd == NAV_LOITER_TURNS:
                kind, turns, radius = "loiter_turns", _nonneg(p[0]), _nonneg(abs(p[2]))
            elif cmd == NAV_LAND:
                if here[2] > 0:
                    raise UserError(
                        f"{item.where}: NAV_LAND starts {here[2]:.0f} m below home "
                        "(a landing below home's height is not supported)"
                    )
                kind, target = "land", (target[0], target[1], 0.0)
            else:
                kind, target = "rtl", (0.0, 0.0, 0.0)
            legs.append(
                MissionLeg(
                    kind, item.seq, here, target, hold, turns, radius, speed, climb, descent,
                    payload,
                )
            )  # fmt: skip
            here = target
            if kind in ("land", "rtl"):
                break
        if not legs:
            raise UserError(f"{self.path}: the mission has no navigation item")
        return legs

    def _target(self, item: MissionItem, here: Ned) -> Ned:
        north, east, down = self.ned_m(item)
        unset = not (math.isfinite(north) and math.isfinite(east))
        if unset or (item.lat_deg == 0 and item.lon_deg == 0):
            north, east = here[0], here[1]
        keeps_height = item.command in (NAV_LOITER_TIME, NAV_LOITER_TURNS) and item.alt_m == 0
        return north, east, here[2] if keeps_height else down


def _nonneg(value: float) -> float:
    """A duration, count or radius from a param: NaN (null in a .plan), negatives and values
    below :data:`MIN_PARAM` (no time, turn or circle to fly) are 0."""
    return value if value >= MIN_PARAM else 0.0


def _speed_change(
    item: MissionItem, speed: float | None, climb: float | None, descent: float | None
) -> tuple[float | None, float | None, float | None]:
    """DO_CHANGE_SPEED: param1 speed type (0 air, 1 ground, 2 climb, 3 descent), param2 m/s
    (−1 or 0: no change, as ArduCopter reads it)."""
    kind, value = int(item.params[0]), item.params[1]
    if math.isfinite(value):
        in_range(value, f"{item.where}: DO_CHANGE_SPEED speed (param2)", SPEED_RANGE_MPS, "m/s")
    if not value > 0:
        return speed, climb, descent
    if kind in (0, 1):
        return value, climb, descent
    if kind == 2:
        return speed, value, descent
    if kind == 3:
        return speed, climb, value
    raise UserError(f"{item.where}: DO_CHANGE_SPEED speed type {kind} is not 0–3")


# -- reading -------------------------------------------------------------------------------------


def load_mission(path: str | Path) -> MissionFile:
    """Read a ``.plan`` or ``.waypoints`` file (by content); UserError on any problem."""
    path = regular_file(path, "mission file")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read mission file {path}: {exc}") from None
    head = text.lstrip()[:20]
    if head.startswith("QGC WPL"):
        return _parse_waypoints(text, str(path))
    if head.startswith("{"):
        return _parse_plan(text, str(path))
    raise UserError(
        f"{path}: not a mission file (expected a QGroundControl .plan or 'QGC WPL 110' text)"
    )


def _parse_waypoints(text: str, path: str) -> MissionFile:
    lines = text.splitlines()
    version = lines[0].split()
    if version[:2] != ["QGC", "WPL"] or version[2:] != ["110"]:
        raise UserError(f"{path}: line 1: expected 'QGC WPL 110', got {lines[0].strip()!r}")
    items: list[MissionItem] = []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        where = f"{path}: line {number}"
        cols = line.split()
        if len(cols) != 12:
            raise UserError(f"{where}: expected 12 tab-separated columns, got {len(cols)}")
        try:
            values = [float(c) for c in cols]
        except ValueError:
            raise UserError(f"{where}: a column is not a number") from None
        if not all(math.isfinite(v) for v in values):
            raise UserError(f"{where}: a column is not a finite number")
        if any(v != int(v) for v in (*values[:4], values[11])):
            raise UserError(
                f"{where}: the index, current, frame, command and autocontinue columns "
                "must be integers"
            )
        seq = int(values[0])
        if seq != len(items):
            raise UserError(f"{where}: item number {seq}, expected {len(items)}")
        items.append(
            MissionItem(
                seq=seq,
                frame=int(values[2]),
                command=int(values[3]),
                params=(values[4], values[5], values[6], values[7]),
                lat_deg=values[8],
                lon_deg=values[9],
                alt_m=values[10],
                where=where,
            )
        )
    if not items:
        raise UserError(f"{path}: no items (the first line after the header is home)")
    home = items[0]
    return _mission(path, home.lat_deg, home.lon_deg, home.alt_m, items)


def _parse_plan(text: str, path: str) -> MissionFile:
    check_nesting(text, path)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"{path}: not valid JSON: line {exc.lineno}: {exc.msg}") from None
    except ValueError:  # an integer of thousands of digits (int()'s limit)
        raise UserError(f"{path}: holds a number too long to read") from None
    mission = doc.get("mission") if isinstance(doc, dict) else None
    if not isinstance(mission, dict):
        raise UserError(f"{path}: a .plan file needs a 'mission' object")
    home = mission.get("plannedHomePosition")
    if not (isinstance(home, list) and len(home) == 3 and all(_is_number(v) for v in home)):
        raise UserError(f"{path}: mission.plannedHomePosition must be [lat, lon, alt_amsl]")
    raw = mission.get("items")
    if not isinstance(raw, list):
        raise UserError(f"{path}: mission.items must be a list")
    lat, lon, alt = (float(v) for v in home)
    where_home = f"{path}: mission.plannedHomePosition"
    items = [MissionItem(0, NAV_WAYPOINT, FRAME_GLOBAL[0], (0, 0, 0, 0), lat, lon, alt, where_home)]
    for index, entry in enumerate(raw):
        where = f"{path}: mission item {index + 1}"
        if not isinstance(entry, dict):
            raise UserError(f"{where}: not an object")
        kind = entry.get("type")
        if kind == "ComplexItem":
            name = entry.get("complexItemType", "unknown")
            raise UserError(
                f"{where}: ComplexItem '{name}' is not supported "
                "(export the mission as plain waypoints, e.g. a .waypoints file)"
            )
        if kind != "SimpleItem":
            raise UserError(f"{where}: unknown item type {kind!r}")
        params = entry.get("params")
        command, frame = entry.get("command"), entry.get("frame")
        if not (isinstance(params, list) and len(params) == 7):
            raise UserError(f"{where}: 'params' must be a list of 7 values")
        if not (isinstance(command, int) and isinstance(frame, int)) or _bools(command, frame):
            raise UserError(f"{where}: 'command' and 'frame' must be integers")
        if not all(v is None or _is_number(v) for v in params):
            raise UserError(f"{where}: 'params' must hold numbers or null")
        p = [math.nan if v is None else float(v) for v in params]
        items.append(
            MissionItem(
                len(items), command, frame, (p[0], p[1], p[2], p[3]), p[4], p[5], p[6], where
            )
        )
    return _mission(path, lat, lon, alt, items)


def _mission(
    path: str, lat: float, lon: float, alt: float, items: Sequence[MissionItem]
) -> MissionFile:
    _check_position(items[0], "home")
    ignored: list[str] = []
    for item in items[1:]:
        if item.command in COMMAND_NAMES:
            if item.command < 100:  # navigation: a position to check
                _check_item(item)
            continue
        if item.command == DO_JUMP:
            raise UserError(f"{item.where}: DO_JUMP loops are not supported (unroll the loop)")
        if any(item.command in r for r in _NON_NAV):
            ignored.append(f"{item.where}: command {item.command}")
            continue
        raise UserError(
            f"{item.where}: command {item.command} is not supported "
            f"(supported: {', '.join(COMMAND_NAMES.values())}, and DO_/CONDITION_ items)"
        )
    return MissionFile(path, lat, lon, alt, tuple(items), tuple(ignored))


def _check_item(item: MissionItem) -> None:
    name = COMMAND_NAMES[item.command]
    if item.command == NAV_RETURN_TO_LAUNCH:  # no position: any frame
        return
    if item.frame in FRAME_TERRAIN:
        raise UserError(
            f"{item.where}: {name} has a terrain-relative altitude (frame {item.frame}); "
            "only relative or absolute altitudes are supported"
        )
    if item.frame not in FRAME_GLOBAL + FRAME_RELATIVE:
        raise UserError(f"{item.where}: {name} has an unsupported frame {item.frame}")
    if item.command == NAV_TAKEOFF:  # climbs where it is: only the altitude counts
        if not math.isfinite(item.alt_m):
            raise UserError(f"{item.where}: {name} has no altitude")
        in_range(item.alt_m, f"{item.where}: {name} altitude", ALTITUDE_RANGE_M, "m")
    else:
        _check_position(item, name)
    if item.command == NAV_LOITER_TURNS and not math.isfinite(item.params[0]):
        raise UserError(f"{item.where}: NAV_LOITER_TURNS needs a number of turns (param1)")
    for index, label, bounds, unit in _PARAM_RANGES.get(item.command, ()):
        if math.isfinite(item.params[index]):  # null in a .plan: none
            in_range(item.params[index], f"{item.where}: {name} {label}", bounds, unit)


def _check_position(item: MissionItem, name: str) -> None:
    if not (math.isfinite(item.lat_deg) and math.isfinite(item.lon_deg)):
        raise UserError(f"{item.where}: {name} has no latitude/longitude")
    if not (-90 <= item.lat_deg <= 90 and -180 <= item.lon_deg <= 180):
        raise UserError(
            f"{item.where}: {name} position {item.lat_deg}, {item.lon_deg} is not on Earth"
        )
    if not math.isfinite(item.alt_m):
        raise UserError(f"{item.where}: {name} has no altitude")
    in_range(item.alt_m, f"{item.where}: {name} altitude", ALTITUDE_RANGE_M, "m")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _bools(*values: Any) -> bool:
    return any(isinstance(v, bool) for v in values)
