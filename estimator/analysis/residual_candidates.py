"""Candidate effects of a residual analysis: fitted parameters ↔ an effect of
:mod:`estimator.physics.effects`, their bounds and starting points, all flight or in a time
window.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from estimator.analysis.residual_samples import Samples
from estimator.physics.effects import (
    Acceleration,
    AirDensity,
    Avionics,
    Climb,
    Effect,
    FlightState,
    Heave,
    Mass,
    ReportedWind,
    Turn,
    Voltage,
    Wind,
    active,
    wind_from_vector,
    wind_vector_ne_mps,
)
from estimator.physics.model import SEA_LEVEL_DENSITY_KGPM3, FloatArray
from estimator.physics.vehicle import Vehicle

#: Fully charged LiPo cell under light load, V: the voltage effect's reference.
FULL_CELL_V = 4.2


@dataclass(frozen=True)
class Candidate:
    """A candidate effect: fitted parameters x ↔ :class:`Effect`.

    ``windowed``: the effect acts in a time window ``[at_s, until_s)`` searched on the training
    data (a wind that starts or stops, a payload picked up or released, a load switched on or
    off); either end may be open (the flight's start or end).
    ``switch``: x holds two parameter sets of the effect, the first acting until a switch time
    searched on the training data and the second from it (a wind that turns or changes speed:
    in hover a wind's speed shows and its direction does not, so one window spreading over
    both winds helps nowhere).
    ``source``: what the autopilot reported that the effect follows (its wind estimate, its
    gripper's actions), shown in the label; the effect's times come from it, not the search,
    unless it is also ``windowed`` (a wind estimate that holds after the wind stopped).
    """

    name: str
    x0: tuple[float, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    build: Callable[[FloatArray, float | None, float | None], Effect]
    windowed: bool = False
    starts: tuple[tuple[float, ...], ...] = ()
    switch: bool = False
    source: str = ""

    @property
    def label(self) -> str:
        if self.source:
            return (
                f"{self.name} ({self.source}, window)"
                if self.windowed
                else f"{self.name} ({self.source})"
            )
        if self.switch:
            return f"{self.name} (change)"
        return f"{self.name} (window)" if self.windowed else self.name

    def effects(
        self, x: FloatArray, at_s: float | None, until_s: float | None
    ) -> tuple[Effect, ...]:
        """The effects for parameters ``x`` in the window (for a switch: ``at_s`` is the
        switch time)."""
        if not self.switch:
            return (self.build(x, at_s, until_s),)
        half = len(x) // 2
        return self.build(x[:half], None, at_s), self.build(x[half:], at_s, None)


def _wind(x: FloatArray, at_s: float | None, until_s: float | None) -> Effect:
    """x = air-mass velocity over ground (north, east), m/s."""
    wind = wind_from_vector(float(x[0]), float(x[1]))
    return replace(wind, at_s=at_s, until_s=until_s)


def winds_within_reach(effects: Sequence[Effect], state: FlightState, reach_mps: float) -> bool:
    """Whether the vehicle could have flown its ground track through every steady wind of
    ``effects``: over the samples each blows on, the airspeed it implies (ground velocity less
    the wind's, m/s) at most ``reach_mps`` (the vehicle's fastest airspeed in any direction at
    its file's mass, :func:`~estimator.physics.lean_limit.airspeed_reach_mps`) on at least half
    of them. A multicopter at its lean limit flies through the air no faster: a stronger wind
    would have carried it off the track it flew, so a fit that needs one is absorbing
    something else (a payload draws power as a strong wind does in a hover)."""
    for effect in effects:
        if not isinstance(effect, Wind):
            continue
        wind_n, wind_e = effect.vector_ne_mps()
        airspeed_mps = np.hypot(state.vn_mps - wind_n, state.ve_mps - wind_e)
        on = np.broadcast_to(active(state.time_s, effect.at_s, effect.until_s), airspeed_mps.shape)
        blown = airspeed_mps[on > 0]
        if blown.size and float(np.median(blown)) > reach_mps:
            return False
    return True


def _reported_wind(samples: Samples) -> tuple[Candidate, ...]:
    """The autopilot's wind estimate of a single flight, scaled, if it reports any wind: all
    flight, and in a time window searched in the data (calm outside it: an estimate that
    holds its value for half a minute after the wind stopped)."""
    speed = samples.channels.get("autopilot_wind_speed_mps")
    from_deg = samples.channels.get("autopilot_wind_from_deg")
    if speed is None or from_deg is None or len(samples.flight_ids) != 1:
        return ()
    known = np.isfinite(speed) & np.isfinite(from_deg)
    if not np.any(speed[known] >= ReportedWind.CALM_MPS):
        return ()
    wind_n, wind_e = wind_vector_ne_mps(np.where(known, speed, 0.0), np.where(known, from_deg, 0.0))
    time_s = samples.state.time_s
    lower, upper = ReportedWind.bounds["scale"]
    return _constant_and_windowed(
        Candidate(
            "wind",
            (1.0,),
            (lower,),
            (upper,),
            lambda x, at, until: ReportedWind(float(x[0]), time_s, wind_n, wind_e, at, until),
            source="autopilot",
        )
    )


def _gripper_mass(samples: Samples, lower: float, upper: float) -> Candidate | None:
    """A payload held while the autopilot's gripper is grabbed, over a single flight whose
    gripper changed: a mass until the first release, or from the first grab (the first row
    after the report)."""
    state = samples.channels.get("gripper_released")
    if state is None or len(samples.flight_ids) != 1:
        return None
    changes = np.flatnonzero(np.diff(state) != 0) + 1
    if not len(changes):
        return None
    change_s = float(samples.state.time_s[changes[0]])
    released = bool(state[changes[0]] == 1.0)
    at_s, until_s = (None, change_s) if released else (change_s, None)
    return Candidate(
        "mass",
        (0.0,),
        (lower,),
        (upper,),
        lambda x, _at, _until: Mass(float(x[0]), at_s, until_s),
        source="gripper",
    )


def _constant_and_windowed(candidate: Candidate) -> tuple[Candidate, Candidate]:
    """The candidate acting all flight, and the same in a time window searched in the data."""
    return candidate, replace(candidate, windowed=True)


def _switched(candidate: Candidate) -> Candidate:
    """The candidate with one set of parameters until a switch time and another after it."""
    return replace(
        candidate,
        x0=candidate.x0 * 2,
        lower=candidate.lower * 2,
        upper=candidate.upper * 2,
        windowed=True,
        switch=True,
        starts=tuple(a + b for a in candidate.starts for b in candidate.starts),
    )


def candidates_for(vehicle: Vehicle, samples: Samples, names: Sequence[str]) -> list[Candidate]:
    """The candidates to try: ``names`` minus effects the vehicle file already has."""
    mass_lo = max(Mass.bounds["delta_kg"][0], -0.7 * vehicle.mass_kg)
    mass_hi = Mass.bounds["delta_kg"][1]
    ref_v = vehicle.battery.cells * FULL_CELL_V
    rho_lo, rho_hi = AirDensity.bounds["rho_kgpm3"]
    avi_lo, avi_hi = Avionics.bounds["power_w"]
    turn_lo, turn_hi = Turn.bounds["power_w_per_g2"]
    heave_lo, heave_hi = ((bound,) for bound in Heave.bounds["gain"])
    wind_max = Wind.bounds["speed_mps"][1]
    wind = Candidate(
        "wind",
        (0.0, 0.0),
        (-wind_max, -wind_max),
        (wind_max, wind_max),
        _wind,
        starts=tuple((4.0 * math.cos(a), 4.0 * math.sin(a)) for a in np.radians([0, 120, 240])),
    )
    all_candidates = [
        *_constant_and_windowed(wind),
        _switched(wind),
        *_constant_and_windowed(
            Candidate(
                "mass",
                (0.0,),
                (mass_lo,),
                (mass_hi,),
                lambda x, at, until: Mass(float(x[0]), at, until),
            )
        ),
        Candidate(
            "air_density",
            (SEA_LEVEL_DENSITY_KGPM3,),
            (rho_lo,),
            (rho_hi,),
            lambda x, _at, _until: AirDensity(float(x[0])),
        ),
        Candidate("climb", (0.6,), (0.2,), (1.0,), lambda x, _at, _until: Climb(float(x[0]))),
        Candidate("heave", (1.0,), heave_lo, heave_hi, lambda x, _at, _until: Heave(float(x[0]))),
        *_constant_and_windowed(
            Candidate(
                "avionics",
                (0.0,),
                (avi_lo,),
                (avi_hi,),
                lambda x, at, until: Avionics(float(x[0]), at, until),
            )
        ),
        Candidate(
            "voltage",
            (0.0,),
            (0.0,),
            (Voltage.bounds["resistance_ohm"][1],),
            lambda x, _at, _until: Voltage(float(x[0]), ref_v),
        ),
        Candidate(
            "acceleration",
            (0.95, 0.95),
            (0.2, 0.0),
            (1.0, 1.0),
            lambda x, _at, _until: Acceleration(float(x[0]), float(x[1])),
        ),
        Candidate(
            "turn",
            (0.0,),
            (turn_lo,),
            (turn_hi,),
            lambda x, _at, _until: Turn(float(x[0])),
        ),
    ]
    all_candidates.extend(_reported_wind(samples))
    if (gripper := _gripper_mass(samples, mass_lo, mass_hi)) is not None:
        all_candidates.append(gripper)
    declared = set(vehicle.effects)
    # a window is on each flight's own clock: shared by several flights it would mean "every
    # flight changed at the same time"; several flights are analysed per flight (--flight)
    one_flight = len(samples.flight_ids) == 1
    out = []
    for cand in all_candidates:
        if cand.name not in names or cand.name in declared or (cand.windowed and not one_flight):
            continue
        if cand.name == "voltage" and not samples.has_voltage:
            continue
        out.append(cand)
    return out
