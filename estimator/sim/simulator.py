"""Offline, deterministic multirotor simulator: truth physics in, ArduCopter-like MAVLink out.

:func:`simulate` flies a :class:`~estimator.sim.plans.Plan` with smooth, bounded-acceleration
velocity tracking, computes the electrical power with
:func:`estimator.physics.effects.predict_power_w`
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

import copy
import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from estimator.physics.battery import PackModel
from estimator.physics.effects import (
    FlightState,
    predict_context,
    predict_power_w,
)
from estimator.physics.kinematics import tangential_accel_mps2
from estimator.physics.model import FloatArray
from estimator.sim.autopilot import Autopilot
from estimator.sim.frames import TelemetryEmitter
from estimator.sim.pack_drain import drain_pack
from estimator.sim.run import DEFAULT_RATES_HZ, DT_S, SimConfig, SimRun, SimTruth

#: Guard for the truth-only extension that finds the reserve (s of simulated flight).
_MAX_EXTENSION_S = 6 * 3600.0


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
        self.pack = PackModel(config.real_battery(), config.internal_resistance_ohm)
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
            "mass_kg": np.broadcast_to(ctx.mass_kg, power.shape),
        }

    def advance(self, rec: dict[str, np.ndarray], soc: float, last_v: float) -> dict[str, Any]:
        """Power, voltage, current and SoC for one chunk (truncated if the pack empties)."""
        n = len(rec["time_s"])
        volts = np.full(n, last_v)
        for _ in range(2 if self.coupled else 1):
            out = self.power(rec, volts)
            volts_new, amps, socs, ok = drain_pack(self.pack, out["power_w"], soc)
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
    ap = Autopilot(plan, config.dynamics, cyclic=config.duration_s is not None)
    chunks, soc = _Chunks(), config.initial_soc
    last_v = float(pack.ocv_v(soc))
    reserve_time: float | None = None
    extension: tuple[Autopilot, float, float] | None = None
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
    messages = TelemetryEmitter(config, truth).messages()
    return SimRun(config, plan, messages, truth, reserve_time)


def _crossing_time(time_s: FloatArray, soc: FloatArray, level: float, t_end: float) -> float:
    below = np.nonzero(soc <= level)[0]
    return float(time_s[below[0]]) if len(below) else t_end


def _extend_to_reserve(
    physics: _Physics,
    extension: tuple[Autopilot, float, float] | None,
    ap: Autopilot,
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
