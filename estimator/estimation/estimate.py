"""What the pipeline gives: one published estimate (:class:`Estimate`) and the power
readings it scored (:class:`PowerReading`), as plain frozen records (units in the names)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


@dataclass(frozen=True, slots=True)
class Estimate:
    """One published estimate. Powers in W, energy in Wh, times in s, speeds m/s, range m.

    power_model_w: the model's power for the current flight state (before the bias).
    power_measured_w: latest V·I, None without a current sensor.
    endurance_s: time to the reserve if the current steady power continues (1σ alongside).
    hover_endurance_s / vme_endurance_s: the same when hovering / flying at V_me.
    range_vmr_m: distance over ground (no wind) at V_mr until the reserve.
    bias: measured over modelled power (1 = the model is right).
    model_only: no measured current fused (uncertainty is wider).
    voltage_follows_load: False once the pack voltage is found not to move with the load
    (:mod:`estimator.estimation.load_response`): nothing is learnt from it.
    pack_soc, capacity_ah, pack_resistance_ohm: the pack as learned in flight from its voltage,
    current and charge (:mod:`estimator.estimation.pack_state`; NaN without a current):
    state of charge (fraction of the real pack), real capacity (Ah), resistance (Ω).
    *_sigma_*: 1σ of the quantity named before it (first-order propagation).
    stale: battery telemetry older than the configured limit (or, in the daemon, a silent
    link).
    endurance_valid: the endurance figures rest on flight: False from start-up until the
    first reading after take-off (:mod:`estimator.estimation.airborne`) has been fused, since the
    model's
    scale is learnt only in flight. Publishers do not give the endurance figures before
    (:mod:`estimator.mavlink.publish`).
    home_distance_m, rth_*, margin_*, pnr_s, mission_*, rth_flags: the return home and the
    mission (:mod:`estimator.estimation.return_home`): distance to home over ground (m), the
    electrical energy (Wh) and time (s) of the return, the ground speed home (m/s) and the
    wind assumed (m/s, from °), the margin (usable energy above the
    reserve left after it, Wh), the point of no return (s until the margin is 0 at the current
    power), the energy of the rest of the mission and the return after it (Wh), and whether it
    leaves the reserve (None: unknown); NaN with a bit of ``rth_flags`` set when an input is
    missing (:data:`~estimator.estimation.return_home.FLAG_NAMES`).
    """

    time_s: float
    speed_mps: float
    accel_tangential_mps2: float
    accel_centripetal_mps2: float
    climb_mps: float
    power_model_w: float
    power_measured_w: float | None
    energy_remaining_wh: float
    energy_remaining_sigma_wh: float
    endurance_s: float
    endurance_sigma_s: float
    hover_endurance_s: float
    vme_endurance_s: float
    v_me_mps: float
    range_vmr_m: float
    bias: float
    bias_sigma: float
    model_only: bool
    stale: bool
    soc: float = math.nan
    voltage_v: float = math.nan
    resistance_ohm: float = math.nan
    pack_soc: float = math.nan
    pack_soc_sigma: float = math.nan
    capacity_ah: float = math.nan
    capacity_sigma_ah: float = math.nan
    pack_resistance_ohm: float = math.nan
    steady_power_w: float = math.nan
    hover_endurance_sigma_s: float = math.nan
    vme_endurance_sigma_s: float = math.nan
    range_vmr_sigma_m: float = math.nan
    endurance_valid: bool = True
    home_distance_m: float = math.nan
    rth_energy_wh: float = math.nan
    rth_sigma_wh: float = math.nan
    rth_time_s: float = math.nan
    rth_speed_mps: float = math.nan
    rth_wind_mps: float = math.nan
    rth_wind_from_deg: float = math.nan
    margin_wh: float = math.nan
    margin_sigma_wh: float = math.nan
    pnr_s: float = math.nan
    mission_energy_wh: float = math.nan
    mission_sigma_wh: float = math.nan
    mission_feasible: bool | None = None
    rth_flags: int = 0
    voltage_follows_load: bool = True

    def as_dict(self) -> dict[str, float | bool | None]:
        return {name: getattr(self, name) for name in _ESTIMATE_FIELDS}


_ESTIMATE_FIELDS = tuple(f.name for f in fields(Estimate))


@dataclass(frozen=True, slots=True)
class PowerReading:
    """A battery reading with a current, against the model power in force when it arrived
    (a prediction: the reading was not yet fused). Powers W, time s; armed None = unknown;
    alt_m: height over home of the latest velocity sample (None = unknown)."""

    time_s: float
    measured_w: float
    model_w: float
    armed: bool | None
    alt_m: float | None
