"""Offline, deterministic multirotor simulator: truth physics in, ArduCopter-like MAVLink out.

:func:`simulate` flies a :class:`~estimator.sim_plans.Plan` with smooth, bounded-acceleration
velocity tracking, computes the electrical power with :func:`estimator.effects.predict_power_w`
(the vehicle's model plus *hidden* effects the estimator is not told about), drains a LiPo
pack (OCV curve + internal resistance: the voltage sags and the current rises at constant
power), and emits the telemetry an ArduCopter would send, with sensor noise and MAVLink
quantisation. Everything is a pure function of :class:`SimConfig` (including ``seed``).

Clock: simulation time 0 is the autopilot's boot, so ``time_boot_ms`` / 1000, the truth's
``time_s`` and effects' ``at_s`` share one time base. Physics steps at 50 Hz.

Flight: 2 s disarmed on the ground, arm, climb to the plan's take-off altitude, fly the legs,
land, disarm, 2 s on the ground. With ``duration_s`` the legs repeat until that time (no
landing). Without it, reaching the battery reserve triggers a landing (ArduPilot's battery
failsafe). The truth's ``time_to_reserve_s`` is the time left until the reserve for the plan
flown: if the flight ends before the reserve, the plan is continued (legs repeated from the
moment the landing started) in a truth-only extension to find when the reserve would be hit.
"""

from __future__ import annotations

import bisect
import copy
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink
from scipy.signal import lfilter

from estimator.battery import CELL_OCV_POINTS_V, SOC_POINTS, PackModel
from estimator.effects import (
    Effect,
    FlightState,
    Wind,
    effects_from_tables,
    predict_context,
    predict_power_w,
)
from estimator.kinematics import tangential_accel_mps2
from estimator.model import G_MPS2, FloatArray
from estimator.sim_plans import Leg, Plan, resolve_plan
from estimator.vehicle import Vehicle, default_vehicle

DT_S = 0.02
#: Streams an ArduCopter sends by default (Hz); SR0_* style.
DEFAULT_RATES_HZ: Mapping[str, float] = {
    "HEARTBEAT": 1.0,
    "GLOBAL_POSITION_INT": 10.0,
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "SYS_STATUS": 2.0,
    "BATTERY_STATUS": 2.0,
}
#: Where in each period a stream is sent (s), so messages of one instant are not all stacked.
_STREAM_PHASE_S = {
    "HEARTBEAT": 0.0,
    "GLOBAL_POSITION_INT": 0.02,
    "LOCAL_POSITION_NED": 0.04,
    "ATTITUDE": 0.06,
    "VFR_HUD": 0.08,
    "SYS_STATUS": 0.1,
    "BATTERY_STATUS": 0.12,
}
#: ArduCopter flight modes (HEARTBEAT.custom_mode).
_MODE_STABILIZE, _MODE_AUTO, _MODE_LAND = 0, 3, 9
#: Drag seen by the attitude (horizontal drag acceleration = k V²): about 20° tilt at 14 m/s.
_DRAG_TILT_PER_MPS2 = 0.018
_EARTH_RADIUS_M = 6_378_137.0
#: Guard for the truth-only extension that finds the reserve (s of simulated flight).
_MAX_EXTENSION_S = 6 * 3600.0


@dataclass(frozen=True)
class SensorNoise:
    """Sensor errors (1σ). Velocity errors are AR(1) (EKF output) with ``velocity_tau_s``."""

    velocity_sigma_mps: float = 0.05
    velocity_tau_s: float = 1.0
    position_sigma_m: float = 0.2
    altitude_sigma_m: float = 0.1
    attitude_sigma_rad: float = 0.005
    voltage_sigma_v: float = 0.02
    current_sigma_a: float = 0.2
    #: Current-sensor gain (1 = calibrated): measured current = scale × true current + noise.
    current_scale: float = 1.0

    @classmethod
    def none(cls) -> SensorNoise:
        """Perfect sensors (only MAVLink quantisation remains)."""
        return cls(0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Dynamics:
    """Position-controller behaviour: first-order velocity tracking, bounded accel and jerk."""

    velocity_tau_s: float = 0.8
    max_accel_mps2: float = 4.0
    max_jerk_mps3: float = 8.0
    brake_accel_mps2: float = 2.0
    vertical_tau_s: float = 0.5
    max_vertical_accel_mps2: float = 2.5
    max_descent_mps: float = 2.0
    ground_s: float = 2.0


@dataclass(frozen=True)
class SimConfig:
    """Everything a simulation depends on.

    vehicle: the truth vehicle (its model and mass are the physics; its ``effects`` tables are
    hidden effects too). plan: a built-in plan name, a plan file path or a Plan. climb_legs:
    add altitude changes to a built-in plan. effects: hidden effects (the estimator is not
    told). internal_resistance_ohm: pack resistance. initial_soc: state of charge at boot.
    idle_power_w: draw on the ground, disarmed. duration_s: None = fly the plan once (or to the
    reserve); else fly (repeating the plan) until then or until the pack is empty.
    """

    vehicle: Vehicle = field(default_factory=default_vehicle)
    plan: str | Plan = "straight"
    climb_legs: bool = False
    effects: tuple[Effect, ...] = ()
    internal_resistance_ohm: float = 0.025
    initial_soc: float = 1.0
    idle_power_w: float = 5.0
    noise: SensorNoise = field(default_factory=SensorNoise)
    rates_hz: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_RATES_HZ))
    dynamics: Dynamics = field(default_factory=Dynamics)
    seed: int = 0
    duration_s: float | None = None
    home_lat_deg: float = 47.397742
    home_lon_deg: float = 8.545594
    home_msl_m: float = 488.0

    def resolved_plan(self) -> Plan:
        return (
            self.plan if isinstance(self.plan, Plan) else resolve_plan(self.plan, self.climb_legs)
        )

    def all_effects(self) -> list[Effect]:
        return effects_from_tables(self.vehicle.effects) + list(self.effects)


@dataclass(frozen=True)
class SimTruth:
    """Truth at every physics step (50 Hz); frames NED, ``time_s`` on the autopilot clock.

    power_w: electrical power at the pack terminals (V·I). power_model_w: what the vehicle's
    model alone predicts from the true state (no hidden effects). energy_remaining_wh: usable
    chemical energy above the reserve. time_to_reserve_s: time left until the reserve is hit
    (0 after). accel_centripetal_mps2 / airspeed_mps: in the air-mass frame (as the model sees).
    """

    time_s: FloatArray
    armed: np.ndarray
    flying: np.ndarray
    pn_m: FloatArray
    pe_m: FloatArray
    alt_m: FloatArray
    vn_mps: FloatArray
    ve_mps: FloatArray
    vd_mps: FloatArray
    an_mps2: FloatArray
    ae_mps2: FloatArray
    yaw_rad: FloatArray
    mode: np.ndarray
    speed_mps: FloatArray
    airspeed_mps: FloatArray
    accel_centripetal_mps2: FloatArray
    accel_tangential_mps2: FloatArray
    mass_kg: FloatArray
    power_w: FloatArray
    power_model_w: FloatArray
    voltage_v: FloatArray
    current_a: FloatArray
    soc: FloatArray
    consumed_mah: FloatArray
    energy_remaining_wh: FloatArray
    time_to_reserve_s: FloatArray

    def __len__(self) -> int:
        return len(self.time_s)

    def at(self, time_s: float | FloatArray) -> Any:
        """Index of the physics step at (or just before) ``time_s``."""
        idx = np.searchsorted(self.time_s, np.asarray(time_s) + 1e-9, side="right") - 1
        return np.clip(idx, 0, len(self.time_s) - 1)

    def flight_state(self) -> FlightState:
        return FlightState(
            self.time_s,
            self.vn_mps,
            self.ve_mps,
            self.vd_mps,
            self.an_mps2,
            self.ae_mps2,
            self.alt_m,
            self.voltage_v,
        )


@dataclass
class SimRun:
    """A simulated flight: the messages as sent (autopilot time s, message) and the truth."""

    config: SimConfig
    plan: Plan
    messages: list[tuple[float, mavlink.MAVLink_message]]
    truth: SimTruth
    #: When the reserve is (or would be) reached, autopilot time s.
    reserve_time_s: float

    @property
    def duration_s(self) -> float:
        return float(self.truth.time_s[-1])


# -- flight dynamics ----------------------------------------------------------------------------


_RECORD_NAMES = (
    *("time_s", "armed", "flying", "pn_m", "pe_m", "alt_m"),
    *("vn_mps", "ve_mps", "vd_mps", "an_mps2", "ae_mps2", "yaw_rad", "mode"),
)


class _Autopilot:
    """Steps the vehicle through ground → take-off → legs → land → ground at DT_S.

    Scalar floats throughout (north, east components): this loop runs 50 times per second of
    flight and numpy's per-call overhead would dominate.
    """

    def __init__(self, plan: Plan, dyn: Dynamics, cyclic: bool) -> None:
        self.plan, self.dyn, self.cyclic = plan, dyn, cyclic
        self.t = 0.0
        self.pn = self.pe = self.vn = self.ve = self.an = self.ae = 0.0
        self.alt = self.vz_up = self.alt_target = self.yaw = 0.0
        self.climb_mps = 2.0
        self.phase = "ground"
        self.phase_t0 = 0.0
        self.leg_i = -1
        self.leg: Leg | None = None
        self.origin = (0.0, 0.0)
        self.center = (0.0, 0.0)
        self.circle_angle = 0.0
        self.done = False

    @property
    def mode(self) -> int:
        return {"land": _MODE_LAND, "takeoff": _MODE_AUTO, "leg": _MODE_AUTO}.get(
            self.phase, _MODE_STABILIZE
        )

    def _enter(self, phase: str) -> None:
        self.phase, self.phase_t0 = phase, self.t

    def begin_land(self) -> None:
        if self.phase in ("takeoff", "leg"):
            self._enter("land")

    def resume_cyclic(self) -> None:
        """Turn a landing into endless repetition of the plan (truth-only extension)."""
        self.cyclic = True
        self._enter("leg")
        self._start_leg(0)

    def _start_leg(self, i: int) -> None:
        self.leg_i, self.leg = i, self.plan.legs[i]
        self.phase_t0 = self.t
        leg = self.leg
        self.origin = (self.pn, self.pe)
        self.circle_angle = 0.0
        if leg.kind == "circle":
            h = math.radians(leg.heading_deg)
            side = (1.0 if leg.clockwise else -1.0) * leg.radius_m
            self.center = (self.pn - side * math.sin(h), self.pe + side * math.cos(h))
        if leg.alt_m is not None:
            self.alt_target, self.climb_mps = leg.alt_m, leg.climb_mps

    def _next_leg(self) -> None:
        if self.leg_i + 1 < len(self.plan.legs):
            self._start_leg(self.leg_i + 1)
        elif self.cyclic:
            self._start_leg(0)
        else:
            self._enter("land")

    def _leg_command(self, leg: Leg) -> tuple[float, float, float, float, bool]:
        """Velocity command (n, e), feed-forward acceleration (n, e), leg finished."""
        elapsed = self.t - self.phase_t0
        timed_out = leg.duration_s is not None and elapsed >= leg.duration_s
        if leg.kind == "hover":
            return 0.0, 0.0, 0.0, 0.0, timed_out
        if leg.kind == "straight":
            h = math.radians(leg.heading_deg)
            un, ue = math.cos(h), math.sin(h)
            speed = leg.speed_mps
            finished = timed_out
            if leg.distance_m is not None:
                along = (self.pn - self.origin[0]) * un + (self.pe - self.origin[1]) * ue
                remaining = leg.distance_m - along
                speed = min(speed, math.sqrt(2.0 * self.dyn.brake_accel_mps2 * max(remaining, 0)))
                ground = math.hypot(self.vn, self.ve)
                finished = remaining <= 0.05 or (remaining < 2.0 and ground < 0.1)
            return speed * un, speed * ue, 0.0, 0.0, finished
        # circle: track the tangent, correct the radius, feed forward the centripetal accel
        rn, re = self.pn - self.center[0], self.pe - self.center[1]
        r = max(math.hypot(rn, re), 1e-6)
        rn, re = rn / r, re / r
        tn, te = (-re, rn) if leg.clockwise else (re, -rn)
        v_t = self.vn * tn + self.ve * te
        self.circle_angle += max(v_t, 0.0) * DT_S / leg.radius_m
        correction = 0.5 * (leg.radius_m - r)
        centripetal = v_t * v_t / leg.radius_m
        finished = timed_out or (
            leg.turns is not None and self.circle_angle >= 2 * math.pi * leg.turns
        )
        return (
            leg.speed_mps * tn + correction * rn,
            leg.speed_mps * te + correction * re,
            -centripetal * rn,
            -centripetal * re,
            finished,
        )

    def step(self) -> None:
        dyn = self.dyn
        cn = ce = fn = fe = vz_cmd = 0.0
        if self.phase == "ground":
            if self.t - self.phase_t0 >= dyn.ground_s and not self.done:
                self._enter("takeoff")
                self.alt_target, self.climb_mps = self.plan.takeoff_alt_m, 2.0
        elif self.phase == "landed" and self.t - self.phase_t0 >= dyn.ground_s:
            self.done = True
        if self.phase == "takeoff" and abs(self.alt - self.alt_target) < 0.3:
            self._enter("leg")
            self._start_leg(0)
        if self.phase == "leg":
            assert self.leg is not None
            cn, ce, fn, fe, finished = self._leg_command(self.leg)
            if finished:
                self._next_leg()
        if self.phase in ("takeoff", "leg"):
            down = min(self.climb_mps, dyn.max_descent_mps)
            vz_cmd = _clip(0.8 * (self.alt_target - self.alt), -down, self.climb_mps)
        elif self.phase == "land":
            vz_cmd = -max(0.5, min(1.5, 0.3 * self.alt))
        if self.phase in ("takeoff", "leg", "land"):
            self._move(cn, ce, fn, fe, vz_cmd)
        self.t = round(self.t + DT_S, 9)

    def _move(self, cn: float, ce: float, fn: float, fe: float, vz_cmd: float) -> None:
        """Velocity tracking with bounded acceleration and jerk; vertical first-order."""
        dyn = self.dyn
        dn = fn + (cn - self.vn) / dyn.velocity_tau_s
        de = fe + (ce - self.ve) / dyn.velocity_tau_s
        norm = math.hypot(dn, de)
        if norm > dyn.max_accel_mps2:
            dn, de = dn * dyn.max_accel_mps2 / norm, de * dyn.max_accel_mps2 / norm
        jerk = dyn.max_jerk_mps3 * DT_S
        self.an += _clip(dn - self.an, -jerk, jerk)
        self.ae += _clip(de - self.ae, -jerk, jerk)
        self.vn += self.an * DT_S
        self.ve += self.ae * DT_S
        self.pn += self.vn * DT_S
        self.pe += self.ve * DT_S
        limit = dyn.max_vertical_accel_mps2
        self.vz_up += _clip((vz_cmd - self.vz_up) / dyn.vertical_tau_s, -limit, limit) * DT_S
        self.alt += self.vz_up * DT_S
        if math.hypot(self.vn, self.ve) > 1.0:
            self.yaw = math.atan2(self.ve, self.vn)
        if self.phase == "land" and self.alt <= 0.0:
            self.alt = self.vz_up = self.vn = self.ve = self.an = self.ae = 0.0
            self._enter("landed")

    def run(self, steps: int) -> dict[str, np.ndarray]:
        """Record the state, then step, up to ``steps`` times; stops early at a landing start."""
        rows: list[tuple[float, ...]] = []
        for _ in range(steps):
            if self.done:
                break
            was_landing = self.phase == "land"
            flying = self.phase in ("takeoff", "leg", "land")
            rows.append(
                (
                    *(self.t, float(flying), float(flying), self.pn, self.pe, self.alt),
                    *(self.vn, self.ve, -self.vz_up, self.an, self.ae, self.yaw, self.mode),
                )
            )
            self.step()
            if self.phase == "land" and not was_landing:
                break
        cols = np.array(rows, dtype=float).reshape(-1, len(_RECORD_NAMES)).T
        return dict(zip(_RECORD_NAMES, cols, strict=True))


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


# -- battery ------------------------------------------------------------------------------------


_SOC_LIST = [float(s) for s in SOC_POINTS]
_OCV_LIST = [float(v) for v in CELL_OCV_POINTS_V]


def _cell_ocv_v(soc: float) -> float:
    """Scalar, fast version of PackModel.ocv_v per cell (same table)."""
    if soc <= 0.0:
        return _OCV_LIST[0]
    if soc >= 1.0:
        return _OCV_LIST[-1]
    i = bisect.bisect_right(_SOC_LIST, soc) - 1
    f = (soc - _SOC_LIST[i]) / (_SOC_LIST[i + 1] - _SOC_LIST[i])
    return _OCV_LIST[i] + f * (_OCV_LIST[i + 1] - _OCV_LIST[i])


def _drain(
    pack: PackModel, power_w: FloatArray, soc0: float
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """Terminal voltage, current and SoC (at the start of each step) for a power demand.

    I solves V·I = P with V = OCV − I·R. Returns how many steps the pack could deliver
    (fewer than asked when it is empty).
    """
    n = len(power_w)
    volts, amps, socs = np.empty(n), np.empty(n), np.empty(n)
    cells, r = pack.spec.cells, pack.internal_resistance_ohm
    per_step = DT_S / (3600.0 * pack.spec.capacity_ah)
    soc = soc0
    for i in range(n):
        ocv = cells * _cell_ocv_v(soc)
        p = float(power_w[i])
        if r > 0:
            disc = ocv * ocv - 4.0 * r * p
            if disc < 0 or soc <= 0.0:
                return volts[:i], amps[:i], socs[:i], i
            current = (ocv - math.sqrt(disc)) / (2.0 * r)
        else:
            if soc <= 0.0:
                return volts[:i], amps[:i], socs[:i], i
            current = p / ocv
        volts[i], amps[i], socs[i] = ocv - current * r, current, soc
        soc -= current * per_step
    return volts, amps, socs, n


# -- simulation ---------------------------------------------------------------------------------


@dataclass
class _Chunks:
    parts: list[dict[str, np.ndarray]] = field(default_factory=list)

    def cat(self) -> dict[str, np.ndarray]:
        return {k: np.concatenate([p[k] for p in self.parts]) for k in self.parts[0]}


class _Physics:
    """Power and battery for recorded trajectory chunks."""

    def __init__(self, config: SimConfig) -> None:
        v = config.vehicle
        self.model, self.mass_kg = v.model, v.mass_kg
        self.effects = config.all_effects()
        self.coupled = any(e.name == "voltage" for e in self.effects)
        self.pack = PackModel(v.battery, config.internal_resistance_ohm)
        self.idle_w = config.idle_power_w

    def power(self, rec: dict[str, np.ndarray], voltage_v: FloatArray) -> dict[str, np.ndarray]:
        state = FlightState(
            rec["time_s"],
            rec["vn_mps"],
            rec["ve_mps"],
            rec["vd_mps"],
            rec["an_mps2"],
            rec["ae_mps2"],
            rec["alt_m"],
            voltage_v,
        )
        ctx, power = predict_context(self.model, self.mass_kg, state, self.effects)
        flying = rec["flying"] > 0
        assert ctx.speed_mps is not None and ctx.accel_centripetal_mps2 is not None
        model_w = predict_power_w(self.model, self.mass_kg, state)
        return {
            "power_w": np.where(flying, power, self.idle_w),
            "power_model_w": np.where(flying, model_w, self.idle_w),
            "airspeed_mps": ctx.speed_mps,
            "accel_centripetal_mps2": ctx.accel_centripetal_mps2,
            "accel_tangential_mps2": tangential_accel_mps2(
                ctx.air_vn_mps, ctx.air_ve_mps, state.an_mps2, state.ae_mps2
            ),
            "mass_kg": ctx.mass_kg,
        }

    def advance(self, rec: dict[str, np.ndarray], soc: float, last_v: float) -> dict[str, Any]:
        """Power, voltage, current and SoC for one chunk (truncated if the pack empties)."""
        n = len(rec["time_s"])
        volts = np.full(n, last_v)
        for _ in range(2 if self.coupled else 1):
            out = self.power(rec, volts)
            volts_new, amps, socs, ok = _drain(self.pack, out["power_w"], soc)
            volts = np.concatenate([volts_new, np.full(n - ok, last_v)])
        result: dict[str, Any] = {k: v[:ok] for k, v in out.items()}
        result |= {k: v[:ok] for k, v in rec.items()}
        result |= {"voltage_v": volts[:ok], "current_a": amps, "soc": socs}
        result["end_soc"] = soc - float(np.sum(amps)) * DT_S / (3600.0 * self.pack.spec.capacity_ah)
        result["empty"] = ok < n
        return result


def simulate(config: SimConfig) -> SimRun:
    """Fly ``config``'s plan and return the messages an ArduCopter would send and the truth."""
    plan = config.resolved_plan()
    unknown = set(config.rates_hz) - set(DEFAULT_RATES_HZ)
    if unknown:
        raise ValueError(f"the simulator does not send {', '.join(sorted(unknown))}")
    if not 0.0 < config.initial_soc <= 1.0:
        raise ValueError("initial_soc must be in (0, 1]")
    physics = _Physics(config)
    pack = physics.pack
    reserve_soc = pack.spec.reserve_fraction
    ap = _Autopilot(plan, config.dynamics, cyclic=config.duration_s is not None)
    chunks, soc = _Chunks(), config.initial_soc
    last_v = float(pack.ocv_v(soc))
    reserve_time: float | None = None
    extension: tuple[_Autopilot, float, float] | None = None
    chunk_steps = round(1.0 / DT_S)
    while not ap.done:
        if config.duration_s is not None and ap.t >= config.duration_s:
            break
        steps = chunk_steps
        if config.duration_s is not None:
            steps = min(steps, max(1, math.ceil((config.duration_s - ap.t) / DT_S - 1e-9)))
        rec = ap.run(steps)
        if len(rec["time_s"]) == 0:
            continue
        out = physics.advance(rec, soc, last_v)
        soc, empty = out.pop("end_soc"), out.pop("empty")
        chunks.parts.append(out)
        if len(out["soc"]):
            last_v = float(out["voltage_v"][-1])
        if soc <= reserve_soc:
            if reserve_time is None:
                reserve_time = _crossing_time(out["time_s"], out["soc"], reserve_soc, ap.t)
            if config.duration_s is None:
                ap.begin_land()
        if ap.phase == "land" and extension is None and reserve_time is None and not ap.cyclic:
            extension = (copy.deepcopy(ap), soc, last_v)
        if empty:
            break
    data = chunks.cat()
    if reserve_time is None:
        reserve_time = _extend_to_reserve(physics, extension, ap, soc, last_v, reserve_soc)
    truth = _truth(data, pack, config, reserve_time)
    messages = _Telemetry(config, truth).messages()
    return SimRun(config, plan, messages, truth, reserve_time)


def _crossing_time(time_s: FloatArray, soc: FloatArray, level: float, t_end: float) -> float:
    below = np.nonzero(soc <= level)[0]
    return float(time_s[below[0]]) if len(below) else t_end


def _extend_to_reserve(
    physics: _Physics,
    extension: tuple[_Autopilot, float, float] | None,
    ap: _Autopilot,
    soc: float,
    last_v: float,
    reserve_soc: float,
) -> float:
    """Keep flying the plan (truth only) from the landing start, or from the end of a timed
    flight, until the reserve; return when it is reached."""
    if extension is not None:
        ext, soc, last_v = extension
        ext.resume_cyclic()
    else:
        ext = copy.deepcopy(ap)
        if ext.phase in ("ground", "landed"):
            ext.resume_cyclic()
        ext.cyclic = True
    t_limit = ext.t + _MAX_EXTENSION_S
    while ext.t < t_limit:
        rec = ext.run(round(10.0 / DT_S))
        if ext.phase == "land":
            ext.resume_cyclic()
        if len(rec["time_s"]) == 0:
            continue
        out = physics.advance(rec, soc, last_v)
        soc = out["end_soc"]
        if len(out["soc"]):
            last_v = float(out["voltage_v"][-1])
        if soc <= reserve_soc or out["empty"]:
            return _crossing_time(out["time_s"], out["soc"], reserve_soc, ext.t)
    return math.inf


def _truth(
    data: dict[str, np.ndarray], pack: PackModel, config: SimConfig, reserve_time: float
) -> SimTruth:
    t = data["time_s"]
    consumed_mah = 1000.0 * (config.initial_soc - data["soc"]) * pack.spec.capacity_ah
    values = dict(data)
    values.update(
        armed=data["armed"] > 0,
        flying=data["flying"] > 0,
        mode=data["mode"].astype(int),
        speed_mps=np.hypot(data["vn_mps"], data["ve_mps"]),
        consumed_mah=consumed_mah,
        energy_remaining_wh=pack.usable_energy_wh(data["soc"]),
        time_to_reserve_s=np.maximum(reserve_time - t, 0.0),
    )
    return SimTruth(**{f.name: values[f.name] for f in fields(SimTruth)})


# -- telemetry ----------------------------------------------------------------------------------


class _Telemetry:
    """Builds the ArduCopter-like message stream from the truth, with sensor noise.

    Each stream samples the truth at its own rate (the physics step at or before its send
    time; stamps carry 0–7 ms of scheduling jitter); noise is drawn per stream, vectorized.
    """

    def __init__(self, config: SimConfig, truth: SimTruth) -> None:
        self.config, self.truth, self.noise = config, truth, config.noise
        self.rng = np.random.default_rng(config.seed)
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        n = len(truth)
        sigma, tau = self.noise.velocity_sigma_mps, self.noise.velocity_tau_s
        self.vel_err = np.stack([_ar1(self.rng, n, sigma, tau) for _ in range(3)])
        wind = [e for e in config.all_effects() if isinstance(e, Wind)]
        wn, we = wind[0].vector_ne_mps() if wind else (0.0, 0.0)
        self.air_n, self.air_e = truth.vn_mps - wn, truth.ve_mps - we
        #: Energy drawn at the terminals before each step, J (BATTERY_STATUS hJ field).
        self.energy_j = np.cumsum(truth.power_w) * DT_S - truth.power_w * DT_S

    def messages(self) -> list[tuple[float, mavlink.MAVLink_message]]:
        t_end = float(self.truth.time_s[-1]) if len(self.truth) else 0.0
        builders = {
            "HEARTBEAT": self._heartbeat,
            "GLOBAL_POSITION_INT": self._global_position,
            "LOCAL_POSITION_NED": self._local_position,
            "ATTITUDE": self._attitude,
            "VFR_HUD": self._vfr_hud,
            "SYS_STATUS": self._sys_status,
            "BATTERY_STATUS": self._battery_status,
        }
        scheduled: list[tuple[int, int, mavlink.MAVLink_message]] = []
        for order, name in enumerate(builders):
            rate = float(self.config.rates_hz.get(name, 0.0))
            if rate <= 0:
                continue
            times = np.arange(_STREAM_PHASE_S[name], t_end + 1e-9, 1.0 / rate)
            idx = np.asarray(self.truth.at(times), dtype=int)
            ms = np.round(times * 1000).astype(int) + self.rng.integers(0, 8, len(times))
            msgs = builders[name](idx, ms)
            scheduled.extend(zip(ms.tolist(), [order] * len(msgs), msgs, strict=True))
        scheduled.sort(key=lambda item: (item[0], item[1]))
        out: list[tuple[float, mavlink.MAVLink_message]] = []
        for ms_i, _, msg in scheduled:
            msg.pack(self.mav)
            self.mav.seq = (self.mav.seq + 1) % 256
            out.append((ms_i / 1000.0, msg))
        return out

    # measured quantities (vectorized over a stream's samples)

    def _normal(self, sigma: float, n: int) -> FloatArray:
        return self.rng.normal(0.0, sigma, n) if sigma > 0 else np.zeros(n)

    def _velocity(self, idx: np.ndarray) -> tuple[FloatArray, FloatArray, FloatArray]:
        tr, e = self.truth, self.vel_err[:, idx]
        return tr.vn_mps[idx] + e[0], tr.ve_mps[idx] + e[1], tr.vd_mps[idx] + e[2]

    def _alt(self, idx: np.ndarray) -> FloatArray:
        return self.truth.alt_m[idx] + self._normal(self.noise.altitude_sigma_m, len(idx))

    def _battery(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measured voltage (mV) and current (cA), quantised as MAVLink carries them."""
        v = self.truth.voltage_v[idx] + self._normal(self.noise.voltage_sigma_v, len(idx))
        i = self.truth.current_a[idx] * self.noise.current_scale
        i = i + self._normal(self.noise.current_sigma_a, len(idx))
        return np.clip(np.round(v * 1000), 0, 65534), np.clip(np.round(i * 100), 0, 32767)

    def _remaining_pct(self, idx: np.ndarray) -> np.ndarray:
        """ArduPilot's estimate: 100 × (1 − consumed / capacity), consumed as measured."""
        capacity_mah = 1000.0 * self.config.vehicle.battery.capacity_ah
        consumed = self.truth.consumed_mah[idx] * self.noise.current_scale
        return np.clip(np.round(100.0 * (1.0 - consumed / capacity_mah)), 0, 100)

    def _attitude_angles(self, idx: np.ndarray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Roll, pitch, yaw (rad): the thrust tilts for the acceleration and the drag."""
        tr = self.truth
        air_n, air_e = self.air_n[idx], self.air_e[idx]
        air = np.hypot(air_n, air_e)
        flying = tr.flying[idx]
        fn = np.where(flying, tr.an_mps2[idx] + _DRAG_TILT_PER_MPS2 * air * air_n, 0.0)
        fe = np.where(flying, tr.ae_mps2[idx] + _DRAG_TILT_PER_MPS2 * air * air_e, 0.0)
        yaw = tr.yaw_rad[idx]
        forward = fn * np.cos(yaw) + fe * np.sin(yaw)
        right = -fn * np.sin(yaw) + fe * np.cos(yaw)
        return np.arctan2(right, G_MPS2), -np.arctan2(forward, G_MPS2), yaw

    # builders: truth indices and stamps (ms) in, messages out

    def _heartbeat(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        out = []
        for k in idx.tolist():
            armed = bool(self.truth.armed[k])
            base = (
                mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
            )
            if armed:
                base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
            status = mavlink.MAV_STATE_ACTIVE if armed else mavlink.MAV_STATE_STANDBY
            out.append(
                self.mav.heartbeat_encode(
                    mavlink.MAV_TYPE_QUADROTOR,
                    mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                    base,
                    int(self.truth.mode[k]),
                    status,
                    3,
                )
            )
        return out

    def _global_position(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        c, tr, n = self.config, self.truth, len(idx)
        pn = tr.pn_m[idx] + self._normal(self.noise.position_sigma_m, n)
        pe = tr.pe_m[idx] + self._normal(self.noise.position_sigma_m, n)
        lat = c.home_lat_deg + np.degrees(pn / _EARTH_RADIUS_M)
        lon = c.home_lon_deg + np.degrees(pe / (_EARTH_RADIUS_M * np.cos(np.radians(lat))))
        alt = self._alt(idx)
        vel = [np.clip(np.round(v * 100), -32768, 32767) for v in self._velocity(idx)]
        hdg = np.round(np.degrees(tr.yaw_rad[idx]) * 100).astype(int) % 36000
        cols = zip(
            ms.tolist(),
            np.round(lat * 1e7).astype(int).tolist(),
            np.round(lon * 1e7).astype(int).tolist(),
            np.round((c.home_msl_m + alt) * 1000).astype(int).tolist(),
            np.round(alt * 1000).astype(int).tolist(),
            *(v.astype(int).tolist() for v in vel),
            hdg.tolist(),
            strict=True,
        )
        return [self.mav.global_position_int_encode(*row) for row in cols]

    def _local_position(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        tr, n, sigma = self.truth, len(idx), self.noise.position_sigma_m
        cols = zip(
            ms.tolist(),
            (tr.pn_m[idx] + self._normal(sigma, n)).tolist(),
            (tr.pe_m[idx] + self._normal(sigma, n)).tolist(),
            (-self._alt(idx)).tolist(),
            *(v.tolist() for v in self._velocity(idx)),
            strict=True,
        )
        return [self.mav.local_position_ned_encode(*row) for row in cols]

    def _attitude(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        n, s = len(idx), self.noise.attitude_sigma_rad
        roll, pitch, yaw = self._attitude_angles(idx)
        back = np.maximum(idx - 5, 0)
        r0, p0, y0 = self._attitude_angles(back)
        span = np.maximum((idx - back) * DT_S, DT_S)
        wrap = np.remainder(yaw - y0 + np.pi, 2 * np.pi) - np.pi
        yaw_meas = np.remainder(yaw + self._normal(s, n) + np.pi, 2 * np.pi) - np.pi
        cols = zip(
            ms.tolist(),
            (roll + self._normal(s, n)).tolist(),
            (pitch + self._normal(s, n)).tolist(),
            yaw_meas.tolist(),
            ((roll - r0) / span).tolist(),
            ((pitch - p0) / span).tolist(),
            (wrap / span).tolist(),
            strict=True,
        )
        return [self.mav.attitude_encode(*row) for row in cols]

    def _vfr_hud(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        tr = self.truth
        vn, ve, vd = self._velocity(idx)
        ground = np.hypot(vn, ve)
        hover_w = self.config.vehicle.model.hover_power_w
        ratio = np.maximum(tr.power_w[idx], 0.0) / hover_w
        throttle = np.where(tr.flying[idx], np.clip(np.round(45.0 * ratio ** (2 / 3)), 0, 100), 0)
        heading = np.round(np.degrees(tr.yaw_rad[idx])).astype(int) % 360
        cols = zip(
            ground.tolist(),
            ground.tolist(),
            heading.tolist(),
            throttle.astype(int).tolist(),
            (self.config.home_msl_m + self._alt(idx)).tolist(),
            (-vd).tolist(),
            strict=True,
        )
        return [self.mav.vfr_hud_encode(*row) for row in cols]

    def _sys_status(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        mv, ca = self._battery(idx)
        sensors = (
            mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | mavlink.MAV_SYS_STATUS_SENSOR_GPS
            | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
        )
        cols = zip(
            mv.astype(int).tolist(),
            ca.astype(int).tolist(),
            self._remaining_pct(idx).astype(int).tolist(),
            strict=True,
        )
        return [
            self.mav.sys_status_encode(sensors, sensors, sensors, 250, v, i, pct, 0, 0, 0, 0, 0, 0)
            for v, i, pct in cols
        ]

    def _battery_status(self, idx: np.ndarray, ms: np.ndarray) -> list[mavlink.MAVLink_message]:
        tr, spec = self.truth, self.config.vehicle.battery
        mv, ca = self._battery(idx)
        consumed = np.round(tr.consumed_mah[idx] * self.noise.current_scale).astype(int)
        energy_hj = np.round(self.energy_j[idx] * self.noise.current_scale / 100.0).astype(int)
        state = np.where(
            tr.soc[idx] <= spec.reserve_fraction,
            mavlink.MAV_BATTERY_CHARGE_STATE_LOW,
            mavlink.MAV_BATTERY_CHARGE_STATE_OK,
        )
        cols = zip(
            mv.astype(int).tolist(),
            ca.astype(int).tolist(),
            consumed.tolist(),
            energy_hj.tolist(),
            self._remaining_pct(idx).astype(int).tolist(),
            state.tolist(),
            strict=True,
        )
        return [
            self.mav.battery_status_encode(
                0,
                mavlink.MAV_BATTERY_FUNCTION_ALL,
                mavlink.MAV_BATTERY_TYPE_LIPO,
                32767,  # temperature unknown
                [v] + [65535] * 9,  # ArduPilot without cell monitoring: total in voltages[0]
                i,
                mah,
                hj,
                pct,
                0,
                st,
                [0, 0, 0, 0],
                0,
                0,
            )
            for v, i, mah, hj, pct, st in cols
        ]


def _ar1(rng: np.random.Generator, n: int, sigma: float, tau_s: float) -> FloatArray:
    """Stationary first-order Gauss-Markov noise with std ``sigma`` and time constant tau_s."""
    if sigma <= 0 or n == 0:
        return np.zeros(n)
    phi = math.exp(-DT_S / tau_s)
    w = rng.normal(0.0, sigma * math.sqrt(1 - phi * phi), n)
    w[0] = rng.normal(0.0, sigma)
    return np.asarray(lfilter([1.0], [1.0, -phi], w), dtype=float)


# -- files --------------------------------------------------------------------------------------

#: tlog stamps are Unix µs; the simulated boot happens at this Unix time.
TLOG_EPOCH_S = 1_700_000_000.0
TRUTH_CSV_STRIDE = 5  # 50 Hz physics → 10 Hz rows
TRUTH_COLUMNS = (
    "time_s",
    "armed",
    "alt_m",
    "vn_mps",
    "ve_mps",
    "vd_mps",
    "speed_mps",
    "airspeed_mps",
    "accel_tangential_mps2",
    "accel_centripetal_mps2",
    "mass_kg",
    "power_w",
    "power_model_w",
    "voltage_v",
    "current_a",
    "soc",
    "energy_remaining_wh",
    "time_to_reserve_s",
)


def tlog_records(run: SimRun) -> list[tuple[int, bytes]]:
    """(Unix µs, frame bytes) per message: the tlog layout (8-byte big-endian µs + frame)."""
    return [(round((TLOG_EPOCH_S + t) * 1e6), bytes(m.get_msgbuf())) for t, m in run.messages]


def write_tlog(run: SimRun, path: str | Path, truth_csv: bool = True) -> Path:
    """Write the messages as a .tlog and, unless told not to, ``<stem>.truth.csv`` beside it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        for usec, frame in tlog_records(run):
            fh.write(struct.pack(">Q", usec) + frame)
    if truth_csv:
        write_truth_csv(run, path.with_name(path.stem + ".truth.csv"))
    return path


def write_truth_csv(run: SimRun, path: str | Path, stride: int = TRUTH_CSV_STRIDE) -> Path:
    """The truth at 10 Hz (every ``stride``-th physics step), columns :data:`TRUTH_COLUMNS`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tr = run.truth
    cols = np.column_stack([np.asarray(getattr(tr, c), dtype=float) for c in TRUTH_COLUMNS])
    np.savetxt(
        path,
        cols[::stride],
        delimiter=",",
        header=",".join(TRUTH_COLUMNS),
        comments="",
        fmt="%.6g",
    )
    return path


def hidden_effects_summary(effects: Sequence[Effect]) -> str:
    """One line naming the hidden effects and their parameters (open time-window ends left
    out), for logs and the CLI."""
    if not effects:
        return "none"
    return "; ".join(
        f"{e.name}(" + ", ".join(f"{k}={v}" for k, v in e.params.items() if v is not None) + ")"
        for e in effects
    )
