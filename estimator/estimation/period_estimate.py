"""The estimate a period's close publishes (:class:`~estimator.estimation.estimate.Estimate`),
assembled from the pipeline's parts: the fused energy state, the endurance at the steady,
hover, V_me and V_mr powers integrated through the pack
(:meth:`~estimator.estimation.fusion.EnergyFilter.endurance_s`), the kinematic state, the
latest battery reading, the pack filter's estimate and the return figures.

Units as in the names: W, Wh, s, m/s, m; the model powers are before the bias, the
published powers and times after it.
"""

from __future__ import annotations

import math

from estimator.estimation.estimate import Estimate
from estimator.estimation.flight_power import FlightPower
from estimator.estimation.fusion import EnergyEstimate, EnergyFilter
from estimator.estimation.pack_state import PackEstimate
from estimator.estimation.return_home import ReturnFigures
from estimator.physics.kinematics import KinematicState
from estimator.telemetry.samples import BatterySample


def period_estimate(
    time_s: float,
    energy: EnergyFilter,
    est: EnergyEstimate,
    power: FlightPower,
    endurance_model_w: float,
    power_model_w: float,
    state: KinematicState | None,
    battery: BatterySample | None,
    pack: PackEstimate | None,
    back: ReturnFigures,
    stale: bool,
    endurance_valid: bool,
    steady_w: float,
) -> Estimate:
    """The estimate at ``time_s`` (s): ``est`` is ``energy``'s state now, ``power`` the model
    with the effects in use, ``endurance_model_w`` the model power (W) the endurance holds,
    ``power_model_w`` the one in force after the period's last sample (W), ``steady_w`` the
    steady power after the bias (W)."""
    bias = est.bias
    model_w = (endurance_model_w, power.p_hover_w, power.p_me_w, power.p_mr_w)
    times_s, sigmas_s = energy.endurance_s([bias * p_w for p_w in model_w], est)
    endurance_s, hover_s, vme_s, vmr_s = times_s.tolist()
    endurance_sigma_s, hover_sigma_s, vme_sigma_s, vmr_sigma_s = sigmas_s.tolist()
    # changing speed, the speed it will hold is not known: from the one before to this one
    endurance_sigma_s = math.hypot(endurance_sigma_s, power.change_spread * endurance_s)
    voltage = energy.voltage
    return Estimate(
        time_s=time_s,
        speed_mps=0.0 if state is None else state.speed_mps,
        accel_tangential_mps2=0.0 if state is None else state.accel_tangential_mps2,
        accel_centripetal_mps2=0.0 if state is None else state.accel_centripetal_mps2,
        climb_mps=0.0 if state is None else state.climb_mps,
        power_model_w=power_model_w,
        power_measured_w=None if battery is None else battery.power_w,
        energy_remaining_wh=est.energy_wh,
        energy_remaining_sigma_wh=est.energy_sigma_wh,
        endurance_s=endurance_s,
        endurance_sigma_s=endurance_sigma_s,
        hover_endurance_s=hover_s,
        vme_endurance_s=vme_s,
        v_me_mps=power.v_me_mps,
        range_vmr_m=power.v_mr_mps * vmr_s,
        bias=bias,
        bias_sigma=est.bias_sigma,
        model_only=energy.model_only,
        voltage_follows_load=energy.voltage_follows_load,
        stale=stale,
        soc=energy.soc,
        voltage_v=math.nan if battery is None else battery.voltage_v,
        resistance_ohm=math.nan if voltage is None else voltage.resistance_ohm,
        pack_soc=math.nan if pack is None else pack.soc,
        pack_soc_sigma=math.nan if pack is None else pack.soc_sigma,
        capacity_ah=math.nan if pack is None else pack.capacity_ah,
        capacity_sigma_ah=math.nan if pack is None else pack.capacity_sigma_ah,
        pack_resistance_ohm=math.nan if pack is None else pack.resistance_ohm,
        steady_power_w=steady_w,
        hover_endurance_sigma_s=hover_sigma_s,
        vme_endurance_sigma_s=vme_sigma_s,
        range_vmr_sigma_m=power.v_mr_mps * vmr_sigma_s,
        endurance_valid=endurance_valid,
        home_distance_m=back.home_distance_m,
        rth_energy_wh=back.energy_wh,
        rth_sigma_wh=back.sigma_wh,
        rth_time_s=back.time_s,
        rth_speed_mps=back.speed_mps,
        rth_wind_mps=back.wind_mps,
        rth_wind_from_deg=back.wind_from_deg,
        margin_wh=back.margin_wh,
        margin_sigma_wh=back.margin_sigma_wh,
        pnr_s=back.pnr_s,
        mission_energy_wh=back.mission_energy_wh,
        mission_sigma_wh=back.mission_sigma_wh,
        mission_feasible=back.mission_feasible,
        rth_flags=back.flags,
    )
