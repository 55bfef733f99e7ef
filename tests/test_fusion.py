"""Energy/bias Kalman filter and pack resistance filter on synthetic pack data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimator.estimation.fusion import EnergyFilter, FusionSettings, ResistanceFilter
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import BatterySpec
from estimator.telemetry.samples import BatterySample

SPEC = BatterySpec(capacity_ah=10.0, cells=6, reserve_fraction=0.2)


def discharge(power_w: float, seconds: float, resistance_ohm: float, dt_s: float = 0.5):
    """True pack at constant terminal power: (t, V, I, consumed mAh, usable Wh) per step."""
    pack = PackModel(SPEC, resistance_ohm)
    soc, consumed, t = 1.0, 0.0, 0.0
    while t <= seconds:
        ocv = float(pack.ocv_v(soc))
        v = 0.5 * (ocv + math.sqrt(ocv * ocv - 4 * power_w * resistance_ohm))
        i = power_w / v
        yield t, v, i, consumed, float(pack.usable_energy_wh(soc))
        soc -= i * dt_s / 3600.0 / SPEC.capacity_ah
        consumed += i * dt_s / 3.6
        t += dt_s


def run_filter(
    model_w: float, true_w: float, with_current: bool, seconds: float = 900.0
) -> tuple[EnergyFilter, float]:
    f = EnergyFilter(PackModel(SPEC), FusionSettings())
    true_wh = 0.0
    for t, v, i, consumed, usable_wh in discharge(true_w, seconds, 0.03):
        true_wh = usable_wh
        if not f.initialized:
            f.initialize(BatterySample(t, float(PackModel(SPEC).ocv_v(1.0)), 0.0, 0.0), 0.0)
            continue
        f.predict(t, model_w, f.loss_factor(f.bias * model_w))
        if with_current:
            f.update_power(v * i, model_w)
            f.update_charge(consumed)
        assert f.voltage is not None
        f.voltage.update(0.5, f.soc, v, i if with_current else f.bias * model_w / v)
    return f, true_wh


def test_measured_power_corrects_a_wrong_model_through_the_bias() -> None:
    f, true_wh = run_filter(model_w=360.0, true_w=400.0, with_current=True)
    est = f.estimate()
    assert est.bias == pytest.approx(400.0 / 360.0, rel=0.01)
    assert est.energy_wh == pytest.approx(true_wh, abs=1.0)
    assert not f.model_only


def test_without_current_sensor_the_model_runs_alone_with_a_wider_sigma() -> None:
    fused, _ = run_filter(model_w=400.0, true_w=400.0, with_current=True)
    alone, true_wh = run_filter(model_w=400.0, true_w=400.0, with_current=False)
    assert alone.model_only
    assert alone.estimate().bias == pytest.approx(1.0)
    assert alone.estimate().energy_wh == pytest.approx(true_wh, rel=0.03)
    assert alone.estimate().energy_sigma_wh > 2 * fused.estimate().energy_sigma_wh
    assert alone.estimate().bias_sigma > 5 * fused.estimate().bias_sigma


def test_model_only_sigma_covers_a_10_percent_model_error() -> None:
    alone, true_wh = run_filter(model_w=400.0, true_w=440.0, with_current=False)
    est = alone.estimate()
    assert abs(est.energy_wh - true_wh) < 2.0 * est.energy_sigma_wh


def test_resistance_is_learned_from_voltage_and_current() -> None:
    pack = PackModel(SPEC)
    r = ResistanceFilter(pack, FusionSettings())
    assert r.resistance_ohm == pytest.approx(0.024)
    soc = 0.9
    for k in range(200):
        current = 15.0 + 5.0 * math.sin(k / 5)
        r.update(0.2, soc, float(pack.ocv_v(soc)) - current * 0.035, current)
    assert r.resistance_ohm == pytest.approx(0.035, rel=0.05)


def test_endurance_integrates_voltage_sag_and_matches_the_true_discharge() -> None:
    truth = list(discharge(400.0, 4000.0, 0.03, dt_s=1.0))
    reserve_t = next(t for t, *_, usable in truth if usable <= 0)
    f = EnergyFilter(PackModel(SPEC), FusionSettings(internal_resistance_ohm=0.03))
    f.initialize(BatterySample(0.0, float(PackModel(SPEC).ocv_v(1.0)), 0.0, 0.0), 0.0)
    (time_s,), (sigma_s,) = f.endurance_s(400.0)
    assert time_s == pytest.approx(reserve_t, rel=0.005)
    assert sigma_s > 0
    naive_s = f.estimate().energy_wh / 400.0 * 3600.0  # ignores the I²R loss
    assert naive_s > time_s * 1.01


def test_endurance_of_zero_power_is_infinite_and_empty_pack_is_zero() -> None:
    f = EnergyFilter(PackModel(SPEC))
    f.initialize(BatterySample(0.0, 25.2, 0.0, 0.0), 0.0)
    times, _ = f.endurance_s(np.array([0.0, 100.0]))
    assert math.isinf(times[0]) and times[1] > 0
    g = EnergyFilter(PackModel(SPEC))
    g.initialize(BatterySample(0.0, 6 * 3.5, 0.0, 0.0), 0.0)  # below the reserve
    assert g.endurance_s(400.0)[0][0] == 0.0


def test_start_under_load_corrects_the_voltage_by_i_times_r() -> None:
    pack = PackModel(SPEC)
    rest = EnergyFilter(pack)
    rest.initialize(BatterySample(0.0, float(pack.ocv_v(0.8)), 0.0, 0.0), 0.0)
    loaded = EnergyFilter(pack)
    loaded.initialize(BatterySample(0.0, float(pack.ocv_v(0.8)) - 20.0 * 0.024, 20.0, 0.0), 0.0)
    assert loaded.soc == pytest.approx(rest.soc, abs=0.005)


def test_reboot_rebase_keeps_energy_and_restarts_the_charge_counter() -> None:
    f, _ = run_filter(model_w=400.0, true_w=400.0, with_current=True, seconds=300.0)
    before = f.estimate().energy_wh
    f.rebase(1.0)
    f.update_charge(0.0)  # the new counter starts at zero
    assert f.estimate().energy_wh == pytest.approx(before, abs=0.3)


def test_model_only_bias_uncertainty_never_exceeds_the_prior() -> None:
    f = EnergyFilter(PackModel(SPEC), FusionSettings(bias_prior_sigma=0.1))
    f.initialize(BatterySample(0.0, 25.2, None, None), 400.0)
    initial_wh = f.estimate().energy_wh
    for k in range(1, 2000):  # 30 min of manoeuvres, no current sensor
        f.predict(k * 1.0, 400.0 + 100.0 * (k % 2), 1.0)
        f.flight_state_changed(400.0 + 100.0 * (k % 2))
    est = f.estimate()
    assert est.bias_sigma == pytest.approx(0.1, rel=1e-6)
    assert np.all(np.linalg.eigvalsh(est.covariance) >= -1e-9)
    assert est.energy_sigma_wh < 0.2 * (initial_wh - est.energy_wh) + 5.0
