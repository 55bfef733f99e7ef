"""The segments of a route: straight legs with the autopilot's speed ramps
(:class:`Kinematics`), hovers, vertical moves, landings, and their sum; each a
:class:`~estimator.physics.route_energy.RouteEnergy` from its phases, with the conventions and
the uncertainty of :mod:`estimator.physics.route_energy` (NED velocities, tracks in degrees
clockwise from north, energies at the battery in Wh)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from estimator.physics.route_energy import (
    DEFAULT_CLIMB_RATE_MPS,
    DEFAULT_DESCENT_RATE_MPS,
    DEFAULT_MAX_AIRSPEED_MPS,
    DEFAULT_MAX_GROUND_SPEED_MPS,
    J_PER_WH,
    UNCERTAINTY_SOURCES,
    Conditions,
    InfeasibleTrack,
    Phase,
    RouteEnergy,
    RouteVehicle,
    energy_with_sensitivity,
    optimal_speed,
)


def reachable_ground_speed_mps(
    conditions: Conditions, track_deg: float, max_airspeed_mps: float, along_track: bool = False
) -> float:
    """The fastest ground speed along ``track_deg`` at ``max_airspeed_mps`` in the wind (m/s;
    0 when the wind allows no headway). ``along_track``: the limit holds for the airspeed's
    component along the track only (a multicopter facing its track whose limit is forward
    drag, as ArduCopter SITL's quad), so a crosswind costs no ground speed."""
    wn, we = conditions.wind_ne_mps()
    un, ue = math.cos(math.radians(track_deg)), math.sin(math.radians(track_deg))
    along, across = wn * un + we * ue, -wn * ue + we * un
    if along_track:
        return max(along + max_airspeed_mps, 0.0)
    if abs(across) >= max_airspeed_mps:
        return 0.0
    return max(along + math.sqrt(max_airspeed_mps**2 - across**2), 0.0)


@dataclass(frozen=True)
class Kinematics:
    """How the autopilot changes speed: horizontal ``accel_mps2`` (m/s²) with ``jerk_mps3``
    (m/s³; None: no jerk limit), vertical ``vertical_accel_mps2`` (m/s²; None: at once) with
    ``vertical_jerk_mps3`` (m/s³; None: none, ArduCopter's model; PX4's MPC_JERK_AUTO limits
    every axis). A speed change of Δv takes Δv/a + a/j when Δv ≥ a²/j, else 2 sqrt(Δv/j) (a
    jerk-limited S-curve), and is flown at the mean speed with the mean acceleration (so eq.
    (2)'s kinetic term and the file's ``acceleration`` effect count the kinetic energy gained
    and lost)."""

    accel_mps2: float
    jerk_mps3: float | None = None
    vertical_accel_mps2: float | None = None
    vertical_jerk_mps3: float | None = None

    def ramp_s(self, dv_mps: float, vertical: bool = False) -> float:
        """Time (s) to change speed by ``dv_mps``."""
        dv = abs(dv_mps)
        accel, jerk = self.accel_mps2, self.jerk_mps3
        if vertical:
            accel, jerk = self.vertical_accel_mps2 or 0.0, self.vertical_jerk_mps3
            if not accel:
                return 0.0
        if jerk is None or jerk <= 0:
            return dv / accel
        if dv >= accel**2 / jerk:
            return dv / accel + accel / jerk
        return 2.0 * math.sqrt(dv / jerk)


def leg_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    *,
    distance_m: float,
    track_deg: float,
    climb_m: float = 0.0,
    ground_speed_mps: float | None = None,
    climb_rate_mps: float = DEFAULT_CLIMB_RATE_MPS,
    descent_rate_mps: float = DEFAULT_DESCENT_RATE_MPS,
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS,
    max_airspeed_mps: float = DEFAULT_MAX_AIRSPEED_MPS,
    kinematics: Kinematics | None = None,
    start_speed_mps: float = 0.0,
    end_speed_mps: float = 0.0,
    along_track: bool = False,
) -> RouteEnergy:
    """A straight leg of ``distance_m`` over ground along ``track_deg`` while changing height by
    ``climb_m`` (m, + up), at ``ground_speed_mps`` (None: :func:`optimal_speed`), never faster
    than ``max_airspeed_mps`` allows in the wind.

    Horizontal and vertical motion run together, as a multicopter's waypoint controller flies a
    sloped leg: the leg takes the longer of the horizontal and the vertical time (``climb_rate_mps``
    up, ``descent_rate_mps`` down; the horizontal speed is lowered to match). Without
    ``kinematics`` the whole leg is flown at one speed; with it the leg speeds up from
    ``start_speed_mps`` and slows to ``end_speed_mps`` (m/s: 0 to stop at its end, more to
    round a corner), the cruise speed lowered when the leg is too short to reach it.
    ``along_track``: the airspeed limit holds along the track (:func:`reachable_ground_speed_mps`).
    """
    if distance_m < 0 or not math.isfinite(distance_m):
        raise ValueError("distance must be finite and ≥ 0")
    if ground_speed_mps is None:
        ground_speed_mps = optimal_speed(
            vehicle,
            conditions,
            track_deg,
            max_ground_speed_mps=max_ground_speed_mps,
            max_airspeed_mps=max_airspeed_mps,
            along_track=along_track,
        ).ground_speed_mps
    if ground_speed_mps <= 0:
        raise ValueError("ground speed must be > 0")
    rate_mps = climb_rate_mps if climb_m >= 0 else descent_rate_mps
    if rate_mps <= 0:
        raise ValueError("vertical rates must be > 0")
    if distance_m > 0:
        reachable = reachable_ground_speed_mps(conditions, track_deg, max_airspeed_mps, along_track)
        if reachable <= 0:
            raise InfeasibleTrack(
                f"a {conditions.wind_speed_mps:g} m/s wind from {conditions.wind_from_deg:g}° "
                f"allows no headway along {track_deg:.0f}° within {max_airspeed_mps:g} m/s airspeed"
            )
        ground_speed_mps = min(ground_speed_mps, reachable)
    vertical_s = abs(climb_m) / rate_mps
    if kinematics is not None and climb_m:
        vertical_s += kinematics.ramp_s(rate_mps, vertical=True)
    ends = (min(start_speed_mps, ground_speed_mps), min(end_speed_mps, ground_speed_mps))
    cruise = ground_speed_mps
    pieces = _profile(distance_m, cruise, ends, kinematics)
    if sum(d for _, _, d in pieces) < vertical_s:  # the climb sets the pace
        cruise = _speed_for_time(distance_m, vertical_s, ends, kinematics)
        pieces = _profile(distance_m, cruise, ends, kinematics)
    time_s = max(sum(d for _, _, d in pieces), vertical_s)
    if time_s <= 0:
        return _result(vehicle, conditions, "leg", [], 0.0, 0.0, 0.0)
    rad = math.radians(track_deg)
    vd = -climb_m / time_s
    phases = [
        Phase(v * math.cos(rad), v * math.sin(rad), vd, d, a * math.cos(rad), a * math.sin(rad))
        for v, a, d in pieces
    ]
    if time_s > sum(ph.duration_s for ph in phases):  # waiting on the climb, in place
        phases.append(Phase(0.0, 0.0, vd, time_s - sum(ph.duration_s for ph in phases)))
    return _result(vehicle, conditions, "leg", phases, distance_m, climb_m, cruise, track_deg)


def _profile(
    distance_m: float,
    cruise_mps: float,
    ends: tuple[float, float],
    kinematics: Kinematics | None,
) -> list[tuple[float, float, float]]:
    """(mean speed m/s, acceleration m/s², duration s) of the speed-up, cruise and slow-down
    of a leg; the cruise speed lowered (bisection) when the leg is too short for it."""
    if distance_m <= 0 or cruise_mps <= 0:
        return []
    if kinematics is None:
        return [(cruise_mps, 0.0, distance_m / cruise_mps)]

    def ramps(v: float) -> tuple[float, float, float, float]:
        t1, t3 = kinematics.ramp_s(v - ends[0]), kinematics.ramp_s(v - ends[1])
        return t1, t3, 0.5 * (v + ends[0]) * t1, 0.5 * (v + ends[1]) * t3

    v = cruise_mps
    t1, t3, d1, d3 = ramps(v)
    if d1 + d3 > distance_m:
        v = _ramped_cruise_mps(distance_m, v, ends, kinematics)
        t1, t3, d1, d3 = ramps(v)
        scale = distance_m / (d1 + d3) if d1 + d3 > 0 else 0.0
        t1, t3, d1, d3 = t1 * scale, t3 * scale, d1 * scale, d3 * scale
    out = []
    if t1 > 0:
        out.append((d1 / t1, (v - ends[0]) / t1, t1))
    if distance_m - d1 - d3 > 0 and v > 0:
        out.append((v, 0.0, (distance_m - d1 - d3) / v))
    if t3 > 0:
        out.append((d3 / t3, (ends[1] - v) / t3, t3))
    return out


def _ramped_cruise_mps(
    distance_m: float, cruise_mps: float, ends: tuple[float, float], kin: Kinematics
) -> float:
    """The highest cruise speed (m/s) in (0, ``cruise_mps``] whose speed-up from ``ends[0]``
    and slow-down to ``ends[1]`` (m/s) fit in ``distance_m`` (m over ground): 50 bisection
    steps on [0, ``cruise_mps``], the lower end kept. The ramps' distances are those of
    :meth:`Kinematics.ramp_s` written out with its constants taken once (the same float
    operations in the same order, so the same speed to the bit: ``tests/test_route_ramps.py``
    keeps it equal to the bisection over ``ramp_s``); a leg home near home bisects at every
    estimate."""
    start, end = ends
    accel, given_jerk = kin.accel_mps2, kin.jerk_mps3
    jerked = given_jerk is not None and given_jerk > 0
    jerk = given_jerk if given_jerk is not None and jerked else 1.0  # m/s³ (unused unjerked)
    knee_mps = accel**2 / jerk if jerked else math.inf  # ramp_s's Δv ≥ a²/j
    extra_s = accel / jerk
    sqrt = math.sqrt
    lo, hi = 0.0, cruise_mps
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        dv1, dv3 = abs(mid - start), abs(mid - end)
        if not jerked:
            t1, t3 = dv1 / accel, dv3 / accel
        else:
            t1 = dv1 / accel + extra_s if dv1 >= knee_mps else 2.0 * sqrt(dv1 / jerk)
            t3 = dv3 / accel + extra_s if dv3 >= knee_mps else 2.0 * sqrt(dv3 / jerk)
        if 0.5 * (mid + start) * t1 + 0.5 * (mid + end) * t3 <= distance_m:
            lo = mid
        else:
            hi = mid
    return lo


def _profile_s(
    distance_m: float, cruise_mps: float, ends: tuple[float, float], kin: Kinematics | None
) -> float:
    return sum(d for _, _, d in _profile(distance_m, cruise_mps, ends, kin))


def _speed_for_time(
    distance_m: float, time_s: float, ends: tuple[float, float], kin: Kinematics | None
) -> float:
    """The cruise speed (m/s) that flies the leg in ``time_s`` (bisection; time falls with
    speed)."""
    lo, hi = 1e-3, distance_m / max(time_s, 1e-9) * 4.0 + 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _profile_s(distance_m, mid, ends, kin) <= time_s else (mid, hi)
    return hi


def hover_energy(vehicle: RouteVehicle, conditions: Conditions, duration_s: float) -> RouteEnergy:
    """Holding position for ``duration_s`` (s): airspeed is the wind speed."""
    if duration_s < 0:
        raise ValueError("duration must be ≥ 0")
    return _result(vehicle, conditions, "hover", [Phase(0.0, 0.0, 0.0, duration_s)], 0, 0, 0)


def vertical_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    climb_m: float,
    rate_mps: float,
    *,
    kinematics: Kinematics | None = None,
) -> RouteEnergy:
    """Climbing (``climb_m`` > 0) or descending in place at ``rate_mps`` (m/s, > 0); with
    ``kinematics``, from and to rest at its vertical acceleration."""
    if rate_mps <= 0:
        raise ValueError("vertical rate must be > 0")
    return _result(
        vehicle,
        conditions,
        "vertical",
        _vertical_phases(climb_m, rate_mps, kinematics),
        0.0,
        climb_m,
        0.0,
    )


def _vertical_phases(climb_m: float, rate_mps: float, kin: Kinematics | None) -> list[Phase]:
    """A vertical move as (speed-up, steady, slow-down) phases at their mean rates; the
    rate lowered when the move is too short to reach it."""
    if climb_m == 0:
        return []
    sign = -1.0 if climb_m > 0 else 1.0  # NED: climbing is negative down-velocity
    height = abs(climb_m)
    ramp = kin.ramp_s(rate_mps, vertical=True) if kin is not None else 0.0
    if ramp <= 0:
        return [Phase(0.0, 0.0, sign * rate_mps, height / rate_mps)]
    accel = rate_mps / ramp
    rate = min(rate_mps, math.sqrt(height * accel))  # triangular when too short
    ramp = rate / accel
    steady_m = height - rate * ramp
    phases = [Phase(0.0, 0.0, sign * rate / 2, ramp), Phase(0.0, 0.0, sign * rate / 2, ramp)]
    if steady_m > 0:
        phases.insert(1, Phase(0.0, 0.0, sign * rate, steady_m / rate))
    return phases


def landing_energy(
    vehicle: RouteVehicle,
    conditions: Conditions,
    height_m: float,
    descent_rate_mps: float,
    *,
    final_height_m: float = 0.0,
    final_rate_mps: float | None = None,
    blend_height_m: float | None = None,
    touchdown_s: float = 0.0,
    kinematics: Kinematics | None = None,
) -> RouteEnergy:
    """Landing from ``height_m`` (m above the ground): down to ``final_height_m`` at
    ``descent_rate_mps``, the rest at ``final_rate_mps`` (m/s; None: the same rate), then
    ``touchdown_s`` (s) at hover power until the motors stop (ArduCopter's LAND: WPNAV_SPEED_DN
    above LAND_ALT_LOW, then LAND_SPEED); with ``blend_height_m`` (m, above
    ``final_height_m``), the rate goes linearly with height from the first to the final
    between the two heights (PX4's MPC_LAND_ALT1 / MPC_LAND_ALT2); with ``kinematics``, the
    first descent starts from rest at its vertical acceleration."""
    if height_m < 0 or descent_rate_mps <= 0:
        raise ValueError("landing needs a height ≥ 0 and a descent rate > 0")
    slow_rate = descent_rate_mps if final_rate_mps is None else final_rate_mps
    if slow_rate <= 0:
        raise ValueError("final descent rate must be > 0")
    top_m = final_height_m if blend_height_m is None else max(blend_height_m, final_height_m)
    fast_m = max(height_m - top_m, 0.0)
    blend_m = max(min(height_m, top_m) - final_height_m, 0.0)
    ramp_s = kinematics.ramp_s(descent_rate_mps, vertical=True) if kinematics else 0.0
    ramp_s = min(ramp_s, 2.0 * fast_m / descent_rate_mps)  # starting from rest
    phases = [
        Phase(0.0, 0.0, descent_rate_mps / 2, ramp_s),
        Phase(
            0.0, 0.0, descent_rate_mps, (fast_m - descent_rate_mps * ramp_s / 2) / descent_rate_mps
        ),
        _blend_phase(blend_m, top_m - final_height_m, descent_rate_mps, slow_rate),
        Phase(0.0, 0.0, slow_rate, (height_m - fast_m - blend_m) / slow_rate),
        Phase(0.0, 0.0, 0.0, max(touchdown_s, 0.0)),
    ]
    return _result(vehicle, conditions, "landing", phases, 0.0, -height_m, 0.0)


def _blend_phase(height_m: float, span_m: float, top_rate: float, low_rate: float) -> Phase:
    """The last ``height_m`` of a ``span_m`` over which the descent rate goes linearly with
    height from ``top_rate`` (at its top) to ``low_rate`` (at its bottom), as one phase at its
    mean rate: at rate v(h) = low + k·h, the time is ln(v(height)/low)/k."""
    if height_m <= 0:
        return Phase(0.0, 0.0, 0.0, 0.0)
    slope = (top_rate - low_rate) / span_m
    if abs(slope) < 1e-9:
        return Phase(0.0, 0.0, low_rate, height_m / low_rate)
    time_s = math.log((low_rate + slope * height_m) / low_rate) / slope
    return Phase(0.0, 0.0, height_m / time_s, time_s)


def _result(
    vehicle: RouteVehicle,
    conditions: Conditions,
    kind: str,
    phases: Sequence[Phase],
    distance_m: float,
    climb_m: float,
    ground_speed_mps: float,
    track_deg: float = 0.0,
) -> RouteEnergy:
    """A segment's energy, time and sensitivities from its phases; ``ground_speed_mps`` along
    ``track_deg`` is its cruise (for the airspeed)."""
    phases = [ph for ph in phases if ph.duration_s > 0]
    time_s = sum(ph.duration_s for ph in phases)
    if phases:
        energy_wh, sens = energy_with_sensitivity(vehicle, conditions, phases)
    else:
        energy_wh, sens = 0.0, (0.0,) * len(UNCERTAINTY_SOURCES)
    rad = math.radians(track_deg)
    wn, we = conditions.wind_ne_mps()
    return RouteEnergy(
        kind=kind,
        distance_m=distance_m,
        climb_m=climb_m,
        time_s=time_s,
        ground_speed_mps=ground_speed_mps,
        airspeed_mps=math.hypot(
            ground_speed_mps * math.cos(rad) - wn, ground_speed_mps * math.sin(rad) - we
        ),
        power_w=energy_wh * J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=sens,
    )


def sum_energies(segments: Iterable[RouteEnergy]) -> RouteEnergy:
    """Several segments flown one after the other: distances, climbs, times, energies and
    sensitivities add (the sources are shared, so their σ add per source, not in quadrature)."""
    items = list(segments)
    time_s = sum(s.time_s for s in items)
    energy_wh = sum(s.energy_wh for s in items)
    # per source, in segment order (as numpy's sum over the first axis adds)
    sens = tuple(map(sum, zip(*(s.sensitivity_wh for s in items), strict=True)))
    return RouteEnergy(
        kind="sum",
        distance_m=sum(s.distance_m for s in items),
        climb_m=sum(s.climb_m for s in items),
        time_s=time_s,
        ground_speed_mps=0.0,
        airspeed_mps=0.0,
        power_w=energy_wh * J_PER_WH / time_s if time_s > 0 else 0.0,
        energy_wh=energy_wh,
        sensitivity_wh=sens if items else (0.0,) * len(UNCERTAINTY_SOURCES),
    )
