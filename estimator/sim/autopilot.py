"""The simulated autopilot: velocity tracking of a plan's legs with bounded acceleration,
arming, take-off, landing and ArduCopter's flight modes (NED frame, 50 Hz steps).
"""

from __future__ import annotations

import math

import numpy as np

from estimator.sim.plans import Leg, Plan
from estimator.sim.run import DT_S, Dynamics

#: ArduCopter flight modes (HEARTBEAT.custom_mode).
_MODE_STABILIZE, _MODE_AUTO, _MODE_LAND = 0, 3, 9


_RECORD_NAMES = (
    *("time_s", "armed", "flying", "pn_m", "pe_m", "alt_m"),
    *("vn_mps", "ve_mps", "vd_mps", "an_mps2", "ae_mps2", "yaw_rad", "mode"),
)


class Autopilot:
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
