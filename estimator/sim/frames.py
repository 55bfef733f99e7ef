"""Telemetry of a simulated flight as an ArduCopter sends it: MAVLink 2 frames at the
stream rates, with sensor noise and MAVLink quantisation.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import common as mavlink
from scipy.signal import lfilter

from estimator.physics.effects import (
    Wind,
)
from estimator.physics.model import G_MPS2, FloatArray
from estimator.sim.run import DT_S, SimConfig, SimTruth

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


#: Drag seen by the attitude (horizontal drag acceleration = k V²): about 20° tilt at 14 m/s.
_DRAG_TILT_PER_MPS2 = 0.018


_EARTH_RADIUS_M = 6_378_137.0


class TelemetryEmitter:
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
