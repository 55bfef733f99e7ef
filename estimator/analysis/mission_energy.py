"""Energy of a mission before flight: per leg, in total with its 1σ, and whether it is feasible.

A mission's legs (:meth:`~estimator.logs.mission_files.MissionFile.legs`) are flown the way
ArduCopter's AUTO mode flies them (:class:`FlightSettings`, its parameters' defaults): take-off
straight up at WPNAV_SPEED_UP; waypoint legs straight at the mission's ground speed
(DO_CHANGE_SPEED, else WPNAV_SPEED), climbing or descending on the way; holds and loiters in
place (air speed = wind speed); loiter turns at CIRCLE_RATE on their radius; LAND flies to its
position and descends at WPNAV_SPEED_DN, the last LAND_ALT_LOW at LAND_SPEED; RTL climbs to
RTL_ALT when lower, flies home, waits RTL_LOIT_TIME and lands. A mission that ends in the air
gets that return added. Each piece's energy is :mod:`estimator.physics.route_segments`'s; the
total's σ keeps the shared sources (model, wind, payload) correlated along the route.

Feasibility: the pack's usable energy above its reserve (vehicle file ``[battery]``, at the
start's state of charge) against mission + return; margin = usable − needed, with the needed
energy's σ. The recommended speed of each horizontal leg is the wind-optimal ground speed
(least energy per metre over ground).

Alongside, a *PX4-style* estimate for comparison: time = the route's length at the set speeds
(horizontal distance / cruise speed, vertical / climb or descent rate, plus holds), energy =
time × one average power (the model's still-air, no-payload power at the cruise speed): what a
distance-and-set-speed estimate knows, blind to wind and payload.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from estimator.errors import UserError
from estimator.estimation.return_home import MissionEnergyFn
from estimator.logs.mission_files import MissionLeg
from estimator.physics.battery import PackModel
from estimator.physics.lean_limit import along_track_limit_mps
from estimator.physics.route_energy import (
    DEFAULT_ACCEL_MPS2,
    DEFAULT_CLIMB_RATE_MPS,
    DEFAULT_DESCENT_RATE_MPS,
    DEFAULT_JERK_MPS3,
    DEFAULT_LAND_ALT_LOW_M,
    DEFAULT_LAND_SPEED_MPS,
    DEFAULT_MAX_AIRSPEED_MPS,
    DEFAULT_RTL_ALT_M,
    DEFAULT_RTL_LOITER_S,
    DEFAULT_RTL_PAUSE_S,
    DEFAULT_VERTICAL_ACCEL_MPS2,
    Conditions,
    InfeasibleTrack,
    RouteEnergy,
    RouteVehicle,
    SpeedChoice,
    optimal_speed,
    steady_power_w,
)
from estimator.physics.route_segments import (
    Kinematics,
    hover_energy,
    landing_energy,
    leg_energy,
    reachable_ground_speed_mps,
    sum_energies,
    vertical_energy,
)
from estimator.physics.vehicle import Vehicle

#: Headings a loiter circle is split into (the wind's effect varies round it).
CIRCLE_PIECES = 36


@dataclass(frozen=True)
class FlightSettings:
    """How the autopilot flies a mission (ArduCopter parameter defaults), m/s, m, s, °/s.

    cruise_mps: WPNAV_SPEED (horizontal ground speed without DO_CHANGE_SPEED).
    climb_mps / descent_mps: WPNAV_SPEED_UP / WPNAV_SPEED_DN. land_mps: LAND_SPEED, below
    land_slow_m (LAND_ALT_LOW). rtl_alt_m: RTL_ALT. rtl_loiter_s: RTL_LOIT_TIME.
    circle_rate_dps: CIRCLE_RATE. rtl_pause_s: RTL's start in place before it turns home
    (measured in SITL). touchdown_s: time on the ground, motors running, before they stop.
    max_speed_mps: the highest ground speed recommended (WPNAV_SPEED's maximum).
    accel_mps2, jerk_mps3, vertical_accel_mps2: WPNAV_ACCEL, WPNAV_JERK, WPNAV_ACCEL_Z.
    corner_speed_mps: the speed a waypoint turn of 90° is rounded at (measured in SITL; other
    angles θ scale it by sqrt(cot(θ/2)), 0 for a reversal). spool_s: motors spinning up at
    take-off before the climb. max_airspeed_mps: the vehicle's (None: its file's, else 20).
    airspeed_along_track: the limit holds for the airspeed along the track (the vehicle
    faces its track; :func:`~estimator.physics.route_segments.reachable_ground_speed_mps`).
    """

    cruise_mps: float = 10.0
    climb_mps: float = DEFAULT_CLIMB_RATE_MPS
    descent_mps: float = DEFAULT_DESCENT_RATE_MPS
    land_mps: float = DEFAULT_LAND_SPEED_MPS
    land_slow_m: float = DEFAULT_LAND_ALT_LOW_M
    rtl_alt_m: float = DEFAULT_RTL_ALT_M
    rtl_loiter_s: float = DEFAULT_RTL_LOITER_S
    rtl_pause_s: float = DEFAULT_RTL_PAUSE_S
    circle_rate_dps: float = 20.0
    touchdown_s: float = 0.0
    max_speed_mps: float = 20.0
    accel_mps2: float = DEFAULT_ACCEL_MPS2
    jerk_mps3: float = DEFAULT_JERK_MPS3
    vertical_accel_mps2: float = DEFAULT_VERTICAL_ACCEL_MPS2
    corner_speed_mps: float = 3.0
    spool_s: float = 2.0
    max_airspeed_mps: float | None = None
    airspeed_along_track: bool = True

    @property
    def airspeed_limit_mps(self) -> float:
        """The airspeed limit in force, m/s."""
        return self.max_airspeed_mps or DEFAULT_MAX_AIRSPEED_MPS

    @property
    def kinematics(self) -> Kinematics:
        return Kinematics(self.accel_mps2, self.jerk_mps3, self.vertical_accel_mps2)

    def corner_mps(self, turn_deg: float) -> float:
        """Speed (m/s) a turn of ``turn_deg`` (0 straight on, 180 back) is flown at."""
        half = math.radians(min(abs(turn_deg), 180.0)) / 2
        if half < 1e-6:
            return math.inf
        return self.corner_speed_mps * math.sqrt(max(math.cos(half), 0.0) / math.sin(half))


@dataclass(frozen=True)
class LegResult:
    """One mission leg: its ``leg`` (positions NED m from home), ``track_deg`` (horizontal
    direction, ° from north; NaN when vertical only), the energy flown at the mission's speeds
    (``energy``) and, for horizontal legs, the wind-optimal ground speed (``recommended``) with
    the leg's energy at it (``recommended_energy_wh``, Wh); ``added``: a return not in the
    file."""

    leg: MissionLeg
    track_deg: float
    energy: RouteEnergy
    recommended: SpeedChoice | None
    recommended_energy_wh: float | None
    added: bool = False

    @property
    def name(self) -> str:
        return f"{self.leg.kind} (added)" if self.added else self.leg.kind


@dataclass(frozen=True)
class Px4Style:
    """The distance/set-speed estimate: time_s, energy_wh at average_power_w (W)."""

    time_s: float
    average_power_w: float
    energy_wh: float


@dataclass(frozen=True)
class MissionEnergy:
    """A mission's legs, totals and feasibility. usable_wh: the pack's energy above its reserve
    at the start (Wh); reserve_wh: the reserve's energy (Wh); margin_wh = usable − total (Wh;
    its σ is the total's)."""

    legs: tuple[LegResult, ...]
    total: RouteEnergy
    usable_wh: float
    reserve_wh: float
    px4: Px4Style
    conditions: Conditions
    settings: FlightSettings

    @property
    def margin_wh(self) -> float:
        return self.usable_wh - self.total.energy_wh

    @property
    def feasible(self) -> bool:
        """Mission and return fit in the usable energy above the reserve."""
        return self.margin_wh >= 0.0

    def profile(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cumulative distance over ground (m), energy remaining above the reserve (Wh) and
        its 1σ (Wh) at the start and after each leg."""
        distance = np.cumsum([0.0, *(r.energy.distance_m for r in self.legs)])
        sens = np.cumsum(
            [np.zeros(len(self.total.sensitivity_wh))]
            + [np.asarray(r.energy.sensitivity_wh) for r in self.legs],
            axis=0,
        )
        used = np.cumsum([0.0, *(r.energy.energy_wh for r in self.legs)])
        return distance, self.usable_wh - used, np.sqrt(np.sum(sens * sens, axis=1))


def remaining_energy_fn(vehicle: Vehicle) -> MissionEnergyFn:
    """The rest of a mission's model energy as :func:`mission_energy` computes it, for the
    pipeline's MIS_* figures (the daemon's and a replay's)."""
    return lambda legs, conditions: mission_energy(legs, vehicle, conditions).total


def mission_energy(
    legs: Sequence[MissionLeg],
    vehicle: Vehicle,
    conditions: Conditions,
    settings: FlightSettings = FlightSettings(),
    start_soc: float = 1.0,
) -> MissionEnergy:
    """Per-leg and total energy of ``legs`` in ``conditions``; a return home is added when the
    mission ends in the air. UserError when the wind allows no headway on a leg."""
    rv = RouteVehicle.from_vehicle(vehicle)
    if settings.max_airspeed_mps is None:
        settings = replace(settings, max_airspeed_mps=vehicle.max_airspeed_mps)
    flown = list(legs)
    added = flown[-1].kind not in ("land", "rtl")
    if added:
        last = flown[-1]
        flown.append(
            MissionLeg(
                "rtl", last.seq, last.end_ned_m, (0.0, 0.0, 0.0), speed_mps=last.speed_mps,
                climb_rate_mps=last.climb_rate_mps, descent_rate_mps=last.descent_rate_mps,
                payload=last.payload,
            )
        )  # fmt: skip
    corners = _corner_speeds(flown, settings)
    results = []
    for i, (leg, heading) in enumerate(zip(flown, _headings(flown), strict=True)):
        cond = conditions if leg.payload else replace(conditions, payload_kg=0, payload_sigma_kg=0)
        ends = (corners[i], corners[i + 1])
        leg_settings = _off_nose(settings, vehicle, cond, leg, heading)
        try:
            results.append(_leg(rv, cond, leg, leg_settings, ends, added and i == len(flown) - 1))
        except InfeasibleTrack as exc:
            raise UserError(f"leg {i + 1} ({leg.kind}, item {leg.seq}): {exc}") from None
    total = sum_energies(r.energy for r in results)
    pack = PackModel(vehicle.battery)
    return MissionEnergy(
        legs=tuple(results),
        total=total,
        usable_wh=float(pack.usable_energy_wh(start_soc)),
        reserve_wh=float(pack.energy_wh(vehicle.battery.reserve_fraction)),
        px4=_px4_style(rv, flown, settings),
        conditions=conditions,
        settings=settings,
    )


def _track(leg: MissionLeg) -> tuple[float, float]:
    """Horizontal direction (° from north) and length (m) of a leg."""
    (n0, e0, _), (n1, e1, _) = leg.start_ned_m, leg.end_ned_m
    return math.degrees(math.atan2(e1 - e0, n1 - n0)) % 360.0, math.hypot(n1 - n0, e1 - e0)


def _headings(legs: Sequence[MissionLeg]) -> list[float]:
    """Where the nose points on each leg (° from north): along its track (ArduCopter's
    WP_YAW_BEHAVIOR default faces the next waypoint), except on RTL, which keeps the heading
    of the last leg that moved over the ground (that default's RTL exception); NaN before any."""
    headings, last = [], math.nan
    for leg in legs:
        track, distance = _track(leg)
        if leg.kind != "rtl" and distance > 0:
            last = track
        headings.append(last if leg.kind == "rtl" else track)
    return headings


def _off_nose(
    settings: FlightSettings,
    vehicle: Vehicle,
    conditions: Conditions,
    leg: MissionLeg,
    heading_deg: float,
) -> FlightSettings:
    """``settings`` with the airspeed limit along ``leg``'s track for a nose at
    ``heading_deg`` and the payload carried, when the vehicle file states its drag per body axis
    (:func:`~estimator.physics.lean_limit.along_track_limit_mps`); loiter circles, legs
    without a heading and vehicles without the drag law keep the limit straight ahead."""
    track, distance = _track(leg)
    if (
        vehicle.drag is None
        or not settings.airspeed_along_track
        or leg.kind == "loiter_turns"
        or distance <= 0
        or not math.isfinite(heading_deg)
    ):
        return settings
    mass_ratio = 1.0 + conditions.payload_kg / vehicle.mass_kg
    limit_mps = along_track_limit_mps(
        vehicle.drag,
        settings.airspeed_limit_mps,
        conditions.wind_ne_mps(),
        track,
        heading_deg,
        mass_ratio,
    )
    return replace(settings, max_airspeed_mps=limit_mps)


def _corner_speeds(legs: Sequence[MissionLeg], s: FlightSettings) -> list[float]:
    """Ground speed (m/s) at the start of each leg and at the end of the last: 0 (at rest)
    except between two waypoint legs without a hold, where the turn is rounded
    (:meth:`FlightSettings.corner_mps`)."""
    speeds = [0.0] * (len(legs) + 1)
    for i in range(1, len(legs)):
        before, after = legs[i - 1], legs[i]
        (track0, dist0), (track1, dist1) = _track(before), _track(after)
        through = before.kind == after.kind == "waypoint" and before.hold_s == 0
        if through and dist0 > 0 and dist1 > 0:
            turn = abs((track1 - track0 + 180.0) % 360.0 - 180.0)
            speeds[i] = s.corner_mps(turn)
    return speeds


def _leg(
    rv: RouteVehicle,
    c: Conditions,
    leg: MissionLeg,
    s: FlightSettings,
    ends: tuple[float, float],
    added: bool,
) -> LegResult:
    track, distance = _track(leg)
    speed = leg.speed_mps or s.cruise_mps
    energy = replace(sum_energies(_pieces(rv, c, leg, s, track, speed, ends)), kind=leg.kind)
    recommended, recommended_wh = None, None
    if distance > 0:
        flown = reachable_ground_speed_mps(c, track, s.airspeed_limit_mps, s.airspeed_along_track)
        energy = replace(energy, ground_speed_mps=min(speed, flown))
        recommended = optimal_speed(
            rv, c, track, max_ground_speed_mps=s.max_speed_mps,
            max_airspeed_mps=s.airspeed_limit_mps, along_track=s.airspeed_along_track,
        )  # fmt: skip
        best = _pieces(rv, c, leg, s, track, recommended.ground_speed_mps, ends)
        recommended_wh = sum_energies(best).energy_wh
    return LegResult(
        leg, track if distance > 0 else math.nan, energy, recommended, recommended_wh, added
    )


def _pieces(
    rv: RouteVehicle,
    c: Conditions,
    leg: MissionLeg,
    s: FlightSettings,
    track_deg: float,
    speed_mps: float,
    ends: tuple[float, float],
) -> list[RouteEnergy]:
    """The pieces of one leg flown at ground speed ``speed_mps`` (module docstring), entered
    and left at the ``ends`` speeds (m/s)."""
    climb_mps = leg.climb_rate_mps or s.climb_mps
    descent_mps = leg.descent_rate_mps or s.descent_mps
    (n0, e0, d0), (n1, e1, d1) = leg.start_ned_m, leg.end_ned_m
    distance = math.hypot(n1 - n0, e1 - e0)

    kin = s.kinematics

    def horizontal(dist_m: float, climb_m: float = 0.0) -> RouteEnergy:
        return leg_energy(
            rv, c, distance_m=dist_m, track_deg=track_deg, climb_m=climb_m,
            ground_speed_mps=speed_mps, climb_rate_mps=climb_mps, descent_rate_mps=descent_mps,
            max_airspeed_mps=s.airspeed_limit_mps, kinematics=kin,
            along_track=s.airspeed_along_track,
            start_speed_mps=ends[0], end_speed_mps=ends[1],
        )  # fmt: skip

    def vertical(climb_m: float, rate_mps: float) -> RouteEnergy:
        return vertical_energy(rv, c, climb_m, rate_mps, kinematics=kin)

    def land(height_m: float) -> RouteEnergy:
        return landing_energy(
            rv, c, height_m, descent_mps, final_height_m=s.land_slow_m,
            final_rate_mps=s.land_mps, touchdown_s=s.touchdown_s, kinematics=kin,
        )  # fmt: skip

    if leg.kind == "takeoff":
        return [hover_energy(rv, c, s.spool_s), vertical(d0 - d1, climb_mps)]
    if leg.kind in ("waypoint", "loiter_time"):
        return [horizontal(distance, d0 - d1), hover_energy(rv, c, leg.hold_s)]
    if leg.kind == "loiter_turns":
        return [horizontal(max(distance - leg.radius_m, 0.0), d0 - d1), *_circle(rv, c, leg, s)]
    if leg.kind == "land":
        return [horizontal(distance), land(-d0)]
    height, pieces = -d0, [hover_energy(rv, c, s.rtl_pause_s)]  # rtl
    if height < s.rtl_alt_m:
        pieces.append(vertical(s.rtl_alt_m - height, climb_mps))
        height = s.rtl_alt_m
    return [*pieces, horizontal(distance), hover_energy(rv, c, s.rtl_loiter_s), land(height)]


def _circle(
    rv: RouteVehicle, c: Conditions, leg: MissionLeg, s: FlightSettings
) -> list[RouteEnergy]:
    """Loiter turns: ``leg.turns`` circles of ``leg.radius_m`` split into
    :data:`CIRCLE_PIECES` headings, at the least of the mission's speed, radius × CIRCLE_RATE
    and sqrt(½ a r) (ArduCopter keeps half its acceleration for the turn), speeding up in the
    first piece and stopping in the last."""
    if leg.turns <= 0:
        return []
    if leg.radius_m <= 0:  # turning in place
        return [hover_energy(rv, c, leg.turns * 360.0 / s.circle_rate_dps)]
    speed = min(
        leg.speed_mps or s.cruise_mps,
        leg.radius_m * math.radians(s.circle_rate_dps),
        math.sqrt(0.5 * s.accel_mps2 * leg.radius_m),
    )
    piece_m = 2 * math.pi * leg.radius_m * leg.turns / CIRCLE_PIECES
    last = CIRCLE_PIECES - 1
    return [
        leg_energy(
            rv, c, distance_m=piece_m, track_deg=360.0 * k / CIRCLE_PIECES, ground_speed_mps=speed,
            max_airspeed_mps=s.airspeed_limit_mps, along_track=s.airspeed_along_track,
            kinematics=s.kinematics, start_speed_mps=0.0 if k == 0 else speed,
            end_speed_mps=0.0 if k == last else speed,
        )
        for k in range(CIRCLE_PIECES)
    ]  # fmt: skip


def _px4_style(rv: RouteVehicle, legs: Sequence[MissionLeg], s: FlightSettings) -> Px4Style:
    """Time from distances at the set speeds, energy at one average power (module docs)."""
    time_s = 0.0
    for leg in legs:
        (n0, e0, d0), (n1, e1, d1) = leg.start_ned_m, leg.end_ned_m
        speed = leg.speed_mps or s.cruise_mps
        time_s += math.hypot(n1 - n0, e1 - e0) / speed + leg.hold_s
        time_s += max(d0 - d1, 0.0) / (leg.climb_rate_mps or s.climb_mps)
        time_s += max(d1 - d0, 0.0) / (leg.descent_rate_mps or s.descent_mps)
        if leg.turns > 0 and leg.radius_m > 0:
            time_s += 2 * math.pi * leg.radius_m * leg.turns / speed
    power_w = float(steady_power_w(rv, Conditions(), s.cruise_mps, 0.0)[0])
    return Px4Style(time_s, power_w, power_w * time_s / 3600.0)
