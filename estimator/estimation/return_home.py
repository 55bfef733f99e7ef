"""Return home and the rest of the mission, live: energy, margin, point of no return.

The pipeline hands every position, home, mission and mission-item sample to
:class:`ReturnHome` and asks it for :class:`ReturnFigures` with each estimate, so the daemon
and a replay give the same figures.

Return (ArduPilot's RTL, which PX4's resembles): climb to ``return_alt_m`` over home when
lower (a vehicle higher returns at its height), fly the great-circle bearing to home, descend
and land. The horizontal leg flies at the airspeed of least energy per metre over ground in
the wind in use (or at ``return_speed_mps`` over ground when the autopilot's return speed is
set), the climb and the landing at the vertical speeds of :mod:`estimator.physics.route_energy`
(the leg physics is there, not here). Energies are electrical (terminal) energy scaled by the
fused bias; the margin compares them, times the pack's loss factor OCV/V, with the usable
energy left above the reserve.

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
from collections.abc import Sequence
from dataclasses import dataclass, replace

from estimator.physics.effects import Effect, Mass, Wind
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import (
    HomeSample,
    MissionCurrentSample,
    MissionItem,
    MissionSample,
    PositionSample,
)

FLAG_NO_HOME, FLAG_NO_POSITION, FLAG_NO_MISSION, FLAG_NOT_FLYING = 1, 2, 4, 8
FLAG_NAMES = {
    FLAG_NO_HOME: "no home",
    FLAG_NO_POSITION: "no position",
    FLAG_NO_MISSION: "no mission",
    FLAG_NOT_FLYING: "not flying",
}
_EARTH_RADIUS_M = 6_371_008.8
ReturnSample = PositionSample | HomeSample | MissionSample | MissionCurrentSample


@dataclass(frozen=True, slots=True)
class ReturnSettings:
    """return_alt_m: height over home (m) the return flies at least (ArduPilot RTL_ALT).
    return_speed_mps: 0 = the wind-optimal airspeed; else the ground speed the autopilot
    returns at (ArduPilot RTL_SPEED / WPNAV_SPEED, PX4 MPC_XY_CRUISE), m/s.
    rate_time_constant_s: smoothing of the return energy's rate of change (s).
    untracked_wind_sigma_mps / untracked_mass_sigma_fraction: wind (m/s) and mass (share of
    the vehicle's) 1σ when the online tracker is off."""

    return_alt_m: float = 15.0
    return_speed_mps: float = 0.0
    rate_time_constant_s: float = 10.0
    untracked_wind_sigma_mps: float = 1.0
    untracked_mass_sigma_fraction: float = 0.05


@dataclass(frozen=True, slots=True)
class ReturnInputs:
    """The estimator's state at one estimate. effects: those in use (wind, mass, …);
    wind_sigma_ne_mps: 1σ of the wind's north and east components (m/s); mass_sigma_kg;
    bias and its 1σ (measured / model power); energy_wh and its 1σ: usable energy above the
    reserve; loss_factor: chemical over terminal energy (OCV/V); steady_power_w: terminal
    power of the current steady flight (W, bias applied); flying: the estimate rests on flight
    (endurance valid)."""

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
    """Distance to home (m), return energy (Wh, electrical) with 1σ and time (s), margin above
    the reserve after the return (Wh) with 1σ, point of no return (s), rest of the mission +
    return (Wh) with 1σ and its feasibility (None unknown), flags (bits of FLAG_NAMES)."""

    home_distance_m: float = math.nan
    energy_wh: float = math.nan
    sigma_wh: float = math.nan
    time_s: float = math.nan
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

    def __init__(self, vehicle: Vehicle, settings: ReturnSettings | None = None) -> None:
        self.vehicle = vehicle
        self.settings = settings or ReturnSettings()
        self.position: PositionSample | None = None
        self.home: HomeSample | None = None
        self.mission: tuple[MissionItem, ...] | None = None
        self.current_seq: int | None = None
        self._last: tuple[float, float] | None = None  # (time s, return energy Wh)
        self._rate_wh_per_s = 0.0

    def take(self, sample: ReturnSample) -> None:
        if isinstance(sample, PositionSample):
            self.position = sample
        elif isinstance(sample, HomeSample):
            self.home = sample
        elif isinstance(sample, MissionSample):
            self.mission = sample.items
        else:
            self.current_seq = sample.seq

    def restart(self) -> None:
        """The autopilot rebooted: its position and home are gone (the mission stays)."""
        self.position, self.home, self._last, self._rate_wh_per_s = None, None, None, 0.0

    def figures(self, time_s: float, inputs: ReturnInputs) -> ReturnFigures:
        flags = 0 if inputs.flying else FLAG_NOT_FLYING
        if self.home is None:
            flags |= FLAG_NO_HOME
        if self.position is None:
            flags |= FLAG_NO_POSITION
        if self.mission is None:
            flags |= FLAG_NO_MISSION
        position, home = self.position, self.home
        if position is None or home is None:
            self._last = None
            return ReturnFigures(flags=flags)
        distance_m, bearing_rad = distance_bearing(
            position.lat_deg, position.lon_deg, home.lat_deg, home.lon_deg
        )
        alt_m = 0.0 if position.alt_m is None else position.alt_m
        energy_wh, time_leg_s, sigma_wh = self._return_energy(
            distance_m, bearing_rad, alt_m, inputs
        )
        margin_wh = inputs.energy_wh - energy_wh * inputs.loss_factor
        margin_sigma_wh = math.hypot(inputs.energy_sigma_wh, sigma_wh * inputs.loss_factor)
        pnr_s = self._point_of_no_return(time_s, energy_wh, margin_wh, inputs)
        return ReturnFigures(
            home_distance_m=distance_m,
            energy_wh=energy_wh,
            sigma_wh=sigma_wh,
            time_s=time_leg_s,
            margin_wh=margin_wh,
            margin_sigma_wh=margin_sigma_wh,
            pnr_s=pnr_s,
            flags=flags,
        )

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
        self, distance_m: float, bearing_rad: float, alt_m: float, inputs: ReturnInputs
    ) -> tuple[float, float, float]:
        """Electrical energy (Wh, bias applied), time (s) and 1σ (Wh) of the return."""
        energy, time_s = self._leg(distance_m, bearing_rad, alt_m, inputs.effects)
        wind = next((e for e in inputs.effects if isinstance(e, Wind)), Wind())
        along = (math.cos(bearing_rad), math.sin(bearing_rad))
        across = (-along[1], along[0])
        sn, se = inputs.wind_sigma_ne_mps
        spread = [energy * inputs.bias_sigma]
        for u in (along, across):
            sigma = math.hypot(u[0] * sn, u[1] * se)
            moved = _moved_wind(wind, u[0] * sigma, u[1] * sigma)
            spread.append(
                self._leg(distance_m, bearing_rad, alt_m, _with(inputs.effects, moved))[0] - energy
            )
        mass = next((e for e in inputs.effects if isinstance(e, Mass)), Mass())
        heavier = replace(mass, delta_kg=mass.delta_kg + inputs.mass_sigma_kg)
        spread.append(
            self._leg(distance_m, bearing_rad, alt_m, _with(inputs.effects, heavier))[0] - energy
        )
        return inputs.bias * energy, time_s, inputs.bias * math.sqrt(sum(x * x for x in spread))

    def _leg(
        self, distance_m: float, bearing_rad: float, alt_m: float, effects: Sequence[Effect]
    ) -> tuple[float, float]:
        """Model energy (Wh) and time (s) of the return with these effects."""
        raise NotImplementedError  # route_energy (branch plan)


def _moved_wind(wind: Wind, dn_mps: float, de_mps: float) -> Wind:
    from estimator.estimation.online_effects import wind_from_vector

    wn, we = wind.vector_ne_mps()
    return wind_from_vector(wn + dn_mps, we + de_mps)


def _with(effects: Sequence[Effect], effect: Effect) -> tuple[Effect, ...]:
    """``effects`` with ``effect`` in place of the one of its type (or added)."""
    kept = [e for e in effects if type(e) is not type(effect)]
    return (effect, *kept)
