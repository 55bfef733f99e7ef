"""Return home and the rest of the mission, live: energy, margin, point of no return.

The pipeline hands every position, home, mission and mission-item sample to
:class:`ReturnHome` and asks it for :class:`ReturnFigures` with each estimate, so the daemon
and a replay give the same figures.

Return (ArduPilot's RTL by default; PX4's with the settings of
:func:`estimator.estimation.rtl_profiles.px4_rtl`): climb to ``return_alt_m`` over home when
lower (a vehicle higher returns at its height), fly the great-circle bearing to home, loiter
(PX4: after a descent to ``descend_alt_m``), land. The horizontal leg flies at the airspeed
of least energy per metre over ground in the wind in use (or at ``return_speed_mps`` over
ground when the autopilot's return speed is set), the climb and the landing at the vertical
speeds of :mod:`estimator.physics.route_segments` (the leg physics is there, not here).
Energies are electrical (terminal) energy scaled by the fused bias; the margin compares them,
times the pack's loss factor OCV/V, with the usable energy left above the reserve.

σ of the return energy: the bias's (model error), and the change of the energy when the wind
moves by its 1σ along and across the bearing and the mass by its 1σ (the online tracker's, or
the ``untracked_*`` figures when tracking is off), in quadrature.

Point of no return: the margin falls at the chemical drain of the current steady power plus
the rate at which the return energy grows (smoothed over ``rate_time_constant_s`` of sample
clock), both taken as constant: PNR = margin / (drain + growth), ∞ when that sum is not
positive (flying home), 0 once the margin is gone.

Flags (:data:`FLAG_NAMES`): a missing input makes the figures NaN with its bit set, never an
exception.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from estimator.errors import UserError
from estimator.logs.mission_files import MissionFile, MissionItem, MissionLeg
from estimator.physics.effects import Effect, Mass, Wind, wind_from_vector
from estimator.physics.route_energy import (
    DEFAULT_ACCEL_MPS2,
    DEFAULT_CLIMB_RATE_MPS,
    DEFAULT_DESCENT_RATE_MPS,
    DEFAULT_JERK_MPS3,
    DEFAULT_LAND_ALT_LOW_M,
    DEFAULT_LAND_SPEED_MPS,
    DEFAULT_MAX_AIRSPEED_MPS,
    DEFAULT_MAX_GROUND_SPEED_MPS,
    DEFAULT_RTL_ALT_M,
    DEFAULT_RTL_LOITER_S,
    DEFAULT_RTL_PAUSE_S,
    DEFAULT_VERTICAL_ACCEL_MPS2,
    MIN_GROUND_SPEED_MPS,
    UNCERTAINTY_SOURCES,
    Conditions,
    InfeasibleTrack,
    RouteEnergy,
    RouteVehicle,
    optimal_ground_speed_mps,
)
from estimator.physics.route_segments import (
    Kinematics,
    hover_energy,
    landing_energy,
    leg_energy,
    sum_energies,
    vertical_energy,
)
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import (
    HomeSample,
    MissionCurrentSample,
    PositionSample,
    WindSample,
)

FLAG_NO_HOME, FLAG_NO_POSITION, FLAG_NO_MISSION, FLAG_NOT_FLYING = 1, 2, 4, 8
FLAG_MISSION_UNUSABLE = 16
FLAG_NAMES = {
    FLAG_NO_HOME: "no home",
    FLAG_NO_POSITION: "no position",
    FLAG_NO_MISSION: "no mission",
    FLAG_NOT_FLYING: "not flying",
    FLAG_MISSION_UNUSABLE: "mission energy not computable",
}
#: The model energy of mission legs flown in conditions, the return added when they end in the
#: air (the daemon passes :func:`estimator.analysis.mission_energy.mission_energy`'s total).
MissionEnergyFn = Callable[[Sequence[MissionLeg], Conditions], RouteEnergy]
_EARTH_RADIUS_M = 6_371_008.8


@dataclass(frozen=True, slots=True)
class MissionSample:
    """A whole mission read from the autopilot (the daemon's download), in sequence order,
    item 0 being home (as ArduPilot numbers them), on the autopilot's clock ``time_s``."""

    time_s: float
    items: tuple[MissionItem, ...]


#: Wind-optimal speeds kept (the cache starts over when full).
_SPEED_CACHE_SIZE = 4096
#: Hover, vertical and landing segments of the return kept for one set of conditions and
#: settings (the memo starts over when full, or when either changes).
_SEGMENTS_KEPT = 256
ReturnSample = PositionSample | HomeSample | MissionSample | MissionCurrentSample | WindSample
WIND_SOURCES = ("tracked", "autopilot")


@dataclass(frozen=True, slots=True)
class ReturnSettings:
    """return_alt_m: height over home (m) the return flies at least (ArduPilot RTL_ALT).
    return_speed_mps: 0 = the wind-optimal airspeed; else the ground speed the autopilot
    returns at (ArduPilot RTL_SPEED / WPNAV_SPEED, PX4 MPC_XY_CRUISE), m/s.
    max_airspeed_mps: the fastest the vehicle flies through the air (its lean-angle limit; the
    wind-optimal search stays below it), m/s; None: the vehicle file's ``max_airspeed_mps``,
    else :data:`~estimator.physics.route_energy.DEFAULT_MAX_AIRSPEED_MPS`.
    airspeed_along_track: that limit holds for the airspeed along the track (a multicopter
    facing its track; :func:`~estimator.physics.route_segments.reachable_ground_speed_mps`).
    max_ground_speed_mps: the fastest return ground speed the autopilot accepts (ArduCopter
    RTL_SPEED ≤ 20 m/s), m/s.
    accel_mps2, jerk_mps3, vertical_accel_mps2: how the autopilot changes speed (ArduCopter
    WPNAV_ACCEL, WPNAV_JERK, WPNAV_ACCEL_Z): the stop from the current velocity and the speed
    ramps (:class:`~estimator.physics.route_segments.Kinematics`); vertical_jerk_mps3: the
    vertical ramps' jerk limit (None: none; PX4's MPC_JERK_AUTO). pause_s: RTL's pause in
    place before it turns home (2 s, measured in SITL by the mission-energy work).
    climb_rate_mps / descent_rate_mps: vertical speeds of the climb and of the landing above
    land_alt_low_m (ArduCopter WPNAV_SPEED_UP / _DN, m/s); land_speed_mps below it (LAND_SPEED);
    loiter_s: hover over home before the descent (RTL_LOIT_TIME); touchdown_s: hover power
    until the motors stop.
    descend_alt_m: PX4's RTL_DESCEND_ALT: with a loiter (``loiter_s`` > 0) the vehicle descends
    to this height over home first and loiters there (m); None: it loiters at its return height
    (ArduCopter). blend_alt_m: PX4's MPC_LAND_ALT1: from this height the landing rate goes
    linearly down to land_speed_mps at land_alt_low_m (m; None: a step at land_alt_low_m).
    crawl_alt_m / crawl_speed_mps: PX4's MPC_LAND_ALT3 / MPC_LAND_CRWL, the last metres over a
    distance sensor (0: no crawl).
    rate_time_constant_s: smoothing of the return energy's rate of change (s).
    mission_period_s: the mission's remaining energy is recomputed this often (s).
    wind_source: "tracked" (the wind in use: the online tracker's once identified, else the
    vehicle file's) or "autopilot" (the autopilot's own estimate, WIND / WIND_COV, with 1σ
    ``autopilot_wind_sigma_mps`` per component, while one is at most
    ``autopilot_wind_max_age_s`` old; else the tracked one): a vehicle whose power hardly
    shows the wind (ArduCopter SITL's quad) but whose autopilot estimates it from drag.
    untracked_wind_sigma_mps / untracked_mass_sigma_fraction: wind (m/s) and mass (share of
    the vehicle's) 1σ when the online tracker is off."""

    return_alt_m: float = DEFAULT_RTL_ALT_M
    return_speed_mps: float = 0.0
    max_airspeed_mps: float | None = None
    airspeed_along_track: bool = True
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS
    accel_mps2: float = DEFAULT_ACCEL_MPS2
    jerk_mps3: float = DEFAULT_JERK_MPS3
    vertical_accel_mps2: float = DEFAULT_VERTICAL_ACCEL_MPS2
    vertical_jerk_mps3: float | None = None
    pause_s: float = DEFAULT_RTL_PAUSE_S
    climb_rate_mps: float = DEFAULT_CLIMB_RATE_MPS
    descent_rate_mps: float = DEFAULT_DESCENT_RATE_MPS
    loiter_s: float = DEFAULT_RTL_LOITER_S
    land_alt_low_m: float = DEFAULT_LAND_ALT_LOW_M
    land_speed_mps: float = DEFAULT_LAND_SPEED_MPS
    touchdown_s: float = 0.0
    descend_alt_m: float | None = None
    blend_alt_m: float | None = None
    crawl_alt_m: float = 0.0
    crawl_speed_mps: float = 0.0
    rate_time_constant_s: float = 10.0
    mission_period_s: float = 5.0
    wind_source: str = "tracked"
    autopilot_wind_sigma_mps: float = 1.0
    autopilot_wind_max_age_s: float = 10.0
    untracked_wind_sigma_mps: float = 1.0
    untracked_mass_sigma_fraction: float = 0.05

    @property
    def kinematics(self) -> Kinematics:
        """How the autopilot changes speed, from the four settings above."""
        return Kinematics(
            self.accel_mps2, self.jerk_mps3, self.vertical_accel_mps2, self.vertical_jerk_mps3
        )


@dataclass(frozen=True, slots=True)
class ReturnInputs:
    """The estimator's state at one estimate (sample clock ``time_s``, ground velocity
    ``velocity_ne_mps`` north/east m/s).

    effects: those in use (wind, mass, …); wind_sigma_ne_mps: 1σ of the wind's north and east
    components (m/s); mass_sigma_kg; bias and its 1σ (measured / model power); energy_wh and
    its 1σ: usable energy above the reserve; loss_factor: chemical over terminal energy
    (OCV/V); steady_power_w: terminal power of the current steady flight (W, bias applied);
    flying: the estimate rests on flight (endurance valid)."""

    time_s: float
    velocity_ne_mps: tuple[float, float]
    effects: tuple[Effect, ...]
    wind_sigma_ne_mps: tuple[float, float]
    mass_sigma_kg: float
    bias: float
    bias_sigma: float
    energy_wh: float
    energy_sigma_wh: float
    loss_factor: float
    steady_power_w: float
    flying: bool


@dataclass(frozen=True, slots=True)
class ReturnFigures:
    """Distance to home (m), return energy (Wh, electrical) with 1σ, time (s) and the ground
    speed of its leg home (m/s: the wind-optimal one, or the configured) and the wind it
    assumes (m/s, from ° clockwise from north), margin above
    the reserve after the return (Wh) with 1σ, point of no return (s), rest of the mission +
    return (Wh) with 1σ and its feasibility (None unknown), flags (bits of FLAG_NAMES)."""

    home_distance_m: float = math.nan
    energy_wh: float = math.nan
    sigma_wh: float = math.nan
    time_s: float = math.nan
    speed_mps: float = math.nan
    wind_mps: float = math.nan
    wind_from_deg: float = math.nan
    margin_wh: float = math.nan
    margin_sigma_wh: float = math.nan
    pnr_s: float = math.nan
    mission_energy_wh: float = math.nan
    mission_sigma_wh: float = math.nan
    mission_feasible: bool | None = None
    flags: int = 0


def distance_bearing(
    lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float
) -> tuple[float, float]:
    """Great-circle distance (m) and initial bearing (rad from north towards east) from point 1
    to point 2 (WGS84 degrees, spherical Earth)."""
    p1, p2 = math.radians(lat1_deg), math.radians(lat2_deg)
    dl = math.radians(lon2_deg - lon1_deg)
    a = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    distance = 2 * _EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(a)))
    bearing = math.atan2(
        math.sin(dl) * math.cos(p2),
        math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dl),
    )
    return distance, bearing


class ReturnHome:
    """What the return needs that the estimator does not already hold: position, home,
    mission and the item flown; and the return energy's recent rate of change."""

    def __init__(
        self,
        vehicle: Vehicle,
        settings: ReturnSettings | None = None,
        mission_energy: MissionEnergyFn | None = None,
    ) -> None:
        # no sensitivities to the model's coefficients: live, the fused bias calibrates them
        # (and each would cost a prediction per piece)
        self._vehicle = replace(RouteVehicle.from_vehicle(vehicle), model_stderr=(0.0,) * 5)
        self._mission_energy = mission_energy
        self._speeds: dict[tuple[float, ...], float] = {}  # _best_speed_mps's cache
        # _segments' memo: the segments by (kind, metres or seconds, m/s), for these
        # conditions and settings
        self._segments: dict[tuple[str, float, float], tuple[RouteEnergy, ...]] = {}
        self._segments_for: tuple[Conditions, ReturnSettings] | None = None
        self._mission_time_s = -math.inf  # sample clock of the last mission figure
        self._mission_figures: tuple[float, float, bool | None, int] = (math.nan, math.nan, None, 0)
        self.settings = settings or ReturnSettings()
        self._max_airspeed_mps = float(
            self.settings.max_airspeed_mps or vehicle.max_airspeed_mps or DEFAULT_MAX_AIRSPEED_MPS
        )
        self.position: PositionSample | None = None
        self.home: HomeSample | None = None
        self.mission: tuple[MissionItem, ...] | None = None
        self.current_seq: int | None = None
        self.autopilot_wind: WindSample | None = None
        self._last: tuple[float, float] | None = None  # (time s, return energy Wh)
        self._rate_wh_per_s = 0.0

    def take(self, sample: ReturnSample) -> None:
        if isinstance(sample, PositionSample):
            self.position = sample
        elif isinstance(sample, HomeSample):
            self.home = sample
        elif isinstance(sample, MissionSample):
            self.mission = sample.items
            self._mission_time_s = -math.inf
        elif isinstance(sample, WindSample):
            self.autopilot_wind = sample
        else:
            self.current_seq = sample.seq

    def restart(self) -> None:
        """The autopilot rebooted: its position and home are gone (the mission stays)."""
        self.position, self.home, self._last, self._rate_wh_per_s = None, None, None, 0.0

    @property
    def located(self) -> bool:
        """The vehicle's position and home are both known: :meth:`figures` can be made."""
        return self.position is not None and self.home is not None

    def unlocated(self, flying: bool) -> ReturnFigures:
        """The figures while not :attr:`located`: NaN, with the flags saying why (and
        ``flying`` whether the estimate rests on flight)."""
        flags = 0 if flying else FLAG_NOT_FLYING
        if self.home is None:
            flags |= FLAG_NO_HOME
        if self.position is None:
            flags |= FLAG_NO_POSITION
        if self.mission is None:
            flags |= FLAG_NO_MISSION
        self._last = None
        return ReturnFigures(flags=flags)

    def figures(self, time_s: float, inputs: ReturnInputs) -> ReturnFigures:
        position, home = self.position, self.home
        if position is None or home is None:
            return self.unlocated(inputs.flying)
        flags = 0 if inputs.flying else FLAG_NOT_FLYING
        if self.mission is None:
            flags |= FLAG_NO_MISSION
        distance_m, bearing_rad = distance_bearing(
            position.lat_deg, position.lon_deg, home.lat_deg, home.lon_deg
        )
        alt_m = 0.0 if position.alt_m is None else position.alt_m
        conditions = self.conditions(inputs)
        energy_wh, time_leg_s, sigma_wh, speed_mps = self._return_energy(
            distance_m, bearing_rad, alt_m, conditions, inputs
        )
        margin_wh = inputs.energy_wh - energy_wh * inputs.loss_factor
        margin_sigma_wh = math.hypot(inputs.energy_sigma_wh, sigma_wh * inputs.loss_factor)
        pnr_s = self._point_of_no_return(time_s, energy_wh, margin_wh, inputs)
        mission_wh, mission_sigma_wh, feasible, mission_flags = self._mission_figures_now(
            time_s, position, conditions, inputs
        )
        return ReturnFigures(
            home_distance_m=distance_m,
            energy_wh=energy_wh,
            sigma_wh=sigma_wh,
            time_s=time_leg_s,
            speed_mps=speed_mps,
            wind_mps=conditions.wind_speed_mps,
            wind_from_deg=conditions.wind_from_deg,
            margin_wh=margin_wh,
            margin_sigma_wh=margin_sigma_wh,
            pnr_s=pnr_s,
            mission_energy_wh=mission_wh,
            mission_sigma_wh=mission_sigma_wh,
            mission_feasible=feasible,
            flags=flags | mission_flags,
        )

    def _mission_figures_now(
        self,
        time_s: float,
        position: PositionSample,
        conditions: Conditions,
        inputs: ReturnInputs,
    ) -> tuple[float, float, bool | None, int]:
        """Energy (Wh, bias applied) and 1σ of the rest of the mission from here and the return
        after it, whether it leaves the reserve, and a flag; recomputed once per
        ``mission_period_s`` of sample clock (a whole mission's legs cost more than a return)."""
        if self.mission is None or self._mission_energy is None:
            return math.nan, math.nan, None, 0
        if time_s - self._mission_time_s < self.settings.mission_period_s:
            return self._mission_figures
        self._mission_time_s = time_s
        try:
            legs = self._remaining_legs(position)
            route = self._mission_energy(legs, conditions)
        except (UserError, ValueError):  # no navigation item, a leg with no headway
            self._mission_figures = (math.nan, math.nan, None, FLAG_MISSION_UNUSABLE)
            return self._mission_figures
        energy_wh, sigma_wh = self._scaled(route, inputs)
        feasible = inputs.energy_wh - energy_wh * inputs.loss_factor >= 0
        self._mission_figures = (energy_wh, sigma_wh, feasible, 0)
        return self._mission_figures

    def _remaining_legs(self, position: PositionSample) -> list[MissionLeg]:
        """The mission's legs from the item flown (MISSION_CURRENT) on, the first starting
        here; none left: a return from here."""
        assert self.mission is not None and self.home is not None
        home = self.home
        mission = MissionFile(
            "the autopilot's mission", home.lat_deg, home.lon_deg, home.alt_amsl_m, self.mission
        )
        here = mission.ned_m(
            MissionItem(
                -1, 16, 3, (0.0, 0.0, 0.0, 0.0), position.lat_deg, position.lon_deg,
                position.alt_m or 0.0, "the vehicle's position",
            )
        )  # fmt: skip
        seq = self.current_seq or 0
        rest = [leg for leg in mission.legs() if leg.seq >= seq]
        if not rest:
            return [MissionLeg("rtl", seq, here, (0.0, 0.0, 0.0))]
        return [replace(rest[0], start_ned_m=here), *rest[1:]]

    def _point_of_no_return(
        self, time_s: float, energy_wh: float, margin_wh: float, inputs: ReturnInputs
    ) -> float:
        """Seconds until the margin is 0 at the current drain and return-energy growth."""
        if self._last is not None and time_s > self._last[0]:
            dt = time_s - self._last[0]
            rate = (energy_wh - self._last[1]) / dt
            gain = min(1.0, dt / self.settings.rate_time_constant_s)
            self._rate_wh_per_s += gain * (rate - self._rate_wh_per_s)
        self._last = (time_s, energy_wh)
        if not inputs.flying:
            return math.nan
        if margin_wh <= 0:
            return 0.0
        drain = (inputs.steady_power_w / 3600.0 + self._rate_wh_per_s) * inputs.loss_factor
        return margin_wh / drain if drain > 0 else math.inf

    def _return_energy(
        self,
        distance_m: float,
        bearing_rad: float,
        alt_m: float,
        conditions: Conditions,
        inputs: ReturnInputs,
    ) -> tuple[float, float, float, float]:
        """Electrical energy (Wh, bias applied), time (s), 1σ (Wh) and leg ground speed (m/s)
        of the return."""
        return_energy, speed_mps = self.route(
            distance_m, math.degrees(bearing_rad), alt_m, conditions, inputs.velocity_ne_mps
        )
        energy_wh, sigma_wh = self._scaled(return_energy, inputs)
        return energy_wh, return_energy.time_s, sigma_wh, speed_mps

    @staticmethod
    def _scaled(route: RouteEnergy, inputs: ReturnInputs) -> tuple[float, float]:
        """A route's model energy with the fused bias (Wh) and its 1σ (Wh): the bias's, the
        wind's and the payload's (the model coefficients' σ is what the bias calibrates)."""
        model_wh = route.energy_wh
        sens = dict(zip(UNCERTAINTY_SOURCES, route.sensitivity_wh, strict=True))
        spread = (model_wh * inputs.bias_sigma, sens["wind_n"], sens["wind_e"], sens["payload"])
        return inputs.bias * model_wh, inputs.bias * math.sqrt(sum(x * x for x in spread))

    def _best_speed_mps(self, conditions: Conditions, track_deg: float) -> float:
        """The wind-optimal ground speed (m/s) at the track, wind and payload rounded to 1°,
        0.1 m/s and 0.01 kg, cached: the search costs more than the rest of the return, and
        in flight those inputs change slowly."""
        key = (
            round(track_deg) % 360,
            round(conditions.wind_speed_mps, 1),
            round(conditions.wind_from_deg) % 360,
            round(conditions.payload_kg, 2),
        )
        speed = self._speeds.get(key)
        if speed is None:
            if len(self._speeds) >= _SPEED_CACHE_SIZE:
                self._speeds.clear()
            rounded = replace(
                conditions, wind_speed_mps=key[1], wind_from_deg=key[2], payload_kg=key[3]
            )
            try:
                speed = optimal_ground_speed_mps(
                    self._vehicle,
                    rounded,
                    key[0],
                    max_airspeed_mps=self._max_airspeed_mps,
                    max_ground_speed_mps=self.settings.max_ground_speed_mps,
                    along_track=self.settings.airspeed_along_track,
                )
            except InfeasibleTrack:
                speed = MIN_GROUND_SPEED_MPS
            self._speeds[key] = speed
        return speed

    def conditions(self, inputs: ReturnInputs) -> Conditions:
        """Wind and payload of the return with their 1σ: the effects in use (the tracker's
        σ, the larger component's), or the autopilot's wind (``wind_source``)."""
        wind = next((e for e in inputs.effects if isinstance(e, Wind)), Wind())
        mass = next((e for e in inputs.effects if isinstance(e, Mass)), Mass())
        speed, from_deg, sigma = wind.speed_mps, wind.from_deg, max(inputs.wind_sigma_ne_mps)
        reported = self.autopilot_wind
        s = self.settings
        if (
            s.wind_source == "autopilot"
            and reported is not None
            and inputs.time_s - reported.time_s <= s.autopilot_wind_max_age_s
        ):
            theirs = wind_from_vector(reported.wind_n_mps, reported.wind_e_mps)
            speed, from_deg = theirs.speed_mps, theirs.from_deg
            sigma = s.autopilot_wind_sigma_mps
        return Conditions(
            wind_speed_mps=speed,
            wind_from_deg=from_deg,
            payload_kg=mass.delta_kg,
            wind_sigma_mps=sigma,
            payload_sigma_kg=inputs.mass_sigma_kg,
        )

    def route(
        self,
        distance_m: float,
        track_deg: float,
        alt_m: float,
        conditions: Conditions,
        velocity_ne_mps: tuple[float, float] = (0.0, 0.0),
    ) -> tuple[RouteEnergy, float]:
        """The return (:mod:`estimator.physics.route_segments`, model energy before the bias) from
        a ground velocity ``velocity_ne_mps`` (m/s): stop and pause in place (at hover power;
        the distance flown away while stopping is added to the leg), climb in place to the
        return height, the leg home with the autopilot's speed ramps, the descent to the
        loiter height (PX4), the loiter over home, the landing; and the leg's cruise ground
        speed (m/s)."""
        s = self.settings
        k = s.kinematics
        rv = self._vehicle
        height_m = max(alt_m, s.return_alt_m)
        vn, ve = velocity_ne_mps
        rad = math.radians(track_deg)
        stop_s = k.ramp_s(math.hypot(vn, ve))
        away_mps = max(-(vn * math.cos(rad) + ve * math.sin(rad)), 0.0)
        distance_m += away_mps * stop_s / 2.0
        limits = {
            "max_airspeed_mps": self._max_airspeed_mps,
            "max_ground_speed_mps": s.max_ground_speed_mps,
            "along_track": s.airspeed_along_track,
        }
        speed = s.return_speed_mps or self._best_speed_mps(conditions, track_deg)
        try:
            leg = leg_energy(
                rv, conditions, distance_m=distance_m, track_deg=track_deg,
                ground_speed_mps=speed, kinematics=k, **limits,  # type: ignore[arg-type]
            )  # fmt: skip
        except InfeasibleTrack:  # no headway within the airspeed limit: crawl (a lower bound)
            leg = leg_energy(
                rv, conditions, distance_m=distance_m, track_deg=track_deg,
                ground_speed_mps=MIN_GROUND_SPEED_MPS,
            )  # fmt: skip
        loiter_m = height_m
        if s.descend_alt_m is not None and s.loiter_s > 0:
            loiter_m = min(height_m, s.descend_alt_m)
        total = sum_energies(
            [
                *self._segments_of(conditions, "hover", stop_s + s.pause_s),
                *self._segments_of(conditions, "vertical", height_m - alt_m, s.climb_rate_mps),
                leg,
                *self._segments_of(conditions, "vertical", loiter_m - height_m, s.descent_rate_mps),
                *self._segments_of(conditions, "hover", s.loiter_s),
                *self._segments_of(conditions, "landing", loiter_m),
            ]
        )
        return total, leg.ground_speed_mps

    def _segments_of(
        self, conditions: Conditions, kind: str, amount: float, rate_mps: float = 0.0
    ) -> tuple[RouteEnergy, ...]:
        """The return's segments that do not depend on where home is: a hover of ``amount``
        s, a vertical move of ``amount`` m (+ up) at ``rate_mps`` m/s, or the landing from
        ``amount`` m over home. Each is a function of exactly the conditions, the settings and
        these arguments, so it is kept (memo) and computed again only when one of them moves:
        in flight the wind, payload and their σ move at the tracker's steps, the height with
        the position, the loiter and landing not at all below the return height."""
        held = self._segments_for
        if held is None or held[1] is not self.settings or held[0] != conditions:
            self._segments.clear()
            self._segments_for = (conditions, self.settings)
        key = (kind, amount, rate_mps)
        segments = self._segments.get(key)
        if segments is None:
            if len(self._segments) >= _SEGMENTS_KEPT:
                self._segments.clear()
            rv, k = self._vehicle, self.settings.kinematics
            if kind == "hover":
                segments = (hover_energy(rv, conditions, amount),)
            elif kind == "vertical":
                segments = (vertical_energy(rv, conditions, amount, rate_mps, kinematics=k),)
            else:
                segments = tuple(self.landing(conditions, amount))
            self._segments[key] = segments
        return segments

    def landing(self, conditions: Conditions, height_m: float) -> list[RouteEnergy]:
        """The landing from ``height_m`` (m over home): fast, (PX4) blended, slow, and the
        crawl over a distance sensor when set, then the touchdown."""
        s, rv = self.settings, self._vehicle
        crawl_m = min(s.crawl_alt_m, height_m) if s.crawl_speed_mps > 0 else 0.0
        above = landing_energy(
            rv, conditions, height_m - crawl_m, s.descent_rate_mps,
            final_height_m=s.land_alt_low_m - crawl_m, final_rate_mps=s.land_speed_mps,
            blend_height_m=None if s.blend_alt_m is None else s.blend_alt_m - crawl_m,
            touchdown_s=0.0 if crawl_m else s.touchdown_s, kinematics=s.kinematics,
        )  # fmt: skip
        if not crawl_m:
            return [above]
        crawl = landing_energy(
            rv, conditions, crawl_m, s.crawl_speed_mps, touchdown_s=s.touchdown_s
        )
        return [above, crawl]
