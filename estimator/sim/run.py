"""What a simulation takes and gives: :class:`SimConfig` in, :class:`SimRun` (truth and the
autopilot's frames) out; the physics step ``DT_S``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from estimator.physics.battery import PackModel
from estimator.physics.effect_tables import effects_from_tables
from estimator.physics.effects import Effect, FlightState
from estimator.physics.model import FloatArray
from estimator.physics.vehicle import BatterySpec, Vehicle, default_vehicle
from estimator.sim.plans import Plan, resolve_plan

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
    capacity_fraction: the real pack's capacity over the vehicle file's (label) one (an aged
    pack below 1; the autopilot still counts against the label). ocv_error_v_per_cell: the
    real pack's resting curve minus the vehicle file's, V per cell at each of its table's
    points (None: the same curve).
    idle_power_w: draw on the ground, disarmed. duration_s: None = fly the plan once (or to the
    reserve); else fly (repeating the plan) until then or until the pack is empty.
    """

    vehicle: Vehicle = field(default_factory=default_vehicle)
    plan: str | Plan = "straight"
    climb_legs: bool = False
    effects: tuple[Effect, ...] = ()
    internal_resistance_ohm: float = 0.025
    initial_soc: float = 1.0
    capacity_fraction: float = 1.0
    ocv_error_v_per_cell: tuple[float, ...] | None = None
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

    def real_battery(self) -> BatterySpec:
        """The pack that flies: the vehicle file's with the real capacity and curve."""
        spec = self.vehicle.battery
        curve = spec.cell_ocv_v
        if self.ocv_error_v_per_cell is not None:
            drawn = PackModel(spec).cell_ocv_v + np.asarray(self.ocv_error_v_per_cell)
            # a resting curve rises with the charge, whatever the error drawn
            rising = np.maximum.accumulate(drawn + 1e-4 * np.arange(len(drawn)))
            curve = tuple(float(v) for v in rising)
        return dataclasses.replace(
            spec, capacity_ah=spec.capacity_ah * self.capacity_fraction, cell_ocv_v=curve
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
