"""The one pipeline: samples in, estimates out (deterministic, sample-clocked)."""

from __future__ import annotations

import math
from dataclasses import replace

import period_ends
import pytest

from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.physics.battery import PackModel
from estimator.physics.effects import Effect, Mass, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.plans import Leg, Plan
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
)

VEHICLE = default_vehicle()
PACK = PackModel(VEHICLE.battery)
FULL_V = float(PACK.ocv_v(1.0))
#: The flights' pack resistance (Ω): the filters' prior, 4 mΩ per cell.
RESISTANCE_OHM = 0.004 * VEHICLE.battery.cells


def flight(seconds: float, speed_mps: float = 8.0, current: bool = True, t0: float = 0.0):
    """Rest on a full pack, arm, then level flight at ``speed_mps``: 10 Hz velocity, 2 Hz
    battery, the voltage the pack's resting curve less I·R at the charge drawn so far."""
    samples: list[Sample] = [BatterySample(t0, FULL_V, 0.0, 0.0), ArmedSample(t0, True)]
    power_w = float(VEHICLE.model.power_w(speed_mps))
    consumed = 0.0
    for k in range(1, int(seconds * 10)):
        t = t0 + k * 0.1
        samples.append(VelocitySample(t, speed_mps, 0.0, 0.0, 20.0))
        if k % 5 == 0:
            ocv_v = float(PACK.ocv_v(1.0 - consumed / 1000.0 / VEHICLE.battery.capacity_ah))
            v = ocv_v - power_w / ocv_v * RESISTANCE_OHM
            consumed += power_w / v * 0.5 / 3.6
            samples.append(
                BatterySample(t, v, power_w / v if current else None, consumed if current else None)
            )
    return samples


def run(pipeline: Pipeline, samples: list[Sample]) -> list[Estimate]:
    return [e for s in samples if (e := pipeline.process(s)) is not None]


def test_no_estimate_before_the_first_battery_sample_then_one_per_period() -> None:
    p = Pipeline(VEHICLE)  # periods of 1 s of sample clock
    assert p.process(VelocitySample(0.0, 1.0, 0.0, 0.0)) is None
    assert p.process(BatterySample(0.1, FULL_V, 0.0, 0.0)) is None
    assert p.counts["energy_initialized"] == 1
    assert p.process(VelocitySample(0.2, 1.0, 0.0, 0.0)) is None  # the period runs to 1.0
    assert p.process(BatterySample(0.6, FULL_V, 1.0, 1.0)) is None
    estimate = p.process(VelocitySample(1.05, 1.0, 0.0, 0.0))
    assert isinstance(estimate, Estimate) and estimate.time_s == 1.05
    assert [r.time_s for r in p.readings] == [0.6]  # the reading that period fused
    assert p.process(VelocitySample(1.5, 1.0, 0.0, 0.0)) is None
    assert p.process(VelocitySample(2.0, 1.0, 0.0, 0.0)) is not None
    assert p.counts["estimates"] == 2


def test_a_reading_is_fused_in_the_period_its_time_falls_in() -> None:
    """A link stamps BATTERY_STATUS with the newest autopilot time it has seen, so a reading
    can be the first sample past a period's end; a log with denser positions has one of
    those first. Either way the reading belongs to the next period: the periods fuse the
    same readings, and the pack filter learns the same pack."""

    def stream(dense: bool) -> list[Sample]:
        samples: list[Sample] = [BatterySample(0.0, FULL_V, 0.3, 0.0), ArmedSample(0.0, True)]
        consumed_mah = 0.0
        for k in range(1, 600):
            t = k * 0.1 + 0.08  # positions stamped 80 ms past each tenth
            if dense and k % 10 == 0:
                samples.append(VelocitySample(t - 0.08, 8.0, 0.0, 0.0, 20.0))
            if k % 5 == 0:
                current_a = 20.0 + 3.0 * ((k // 5) % 3)
                consumed_mah += current_a * 0.5 / 3.6
                voltage_v = FULL_V - 0.02 * current_a - 0.0005 * k
                samples.append(BatterySample(t, voltage_v, current_a, consumed_mah))
            samples.append(VelocitySample(t, 8.0, 0.0, 0.0, 20.0))
        return samples

    fused = []
    for dense in (False, True):
        p = Pipeline(VEHICLE)
        periods = [
            (e.time_s, [r.time_s for r in p.readings])
            for s in stream(dense)
            if (e := p.process(s)) is not None
        ]
        for end_s, readings in periods:  # periods of 1 s of the sample clock
            assert all(t < math.floor(end_s) for t in readings), (end_s, readings)
        assert p.pack_state is not None
        fused.append(([r for _, r in periods], p.pack_state.estimate()))
    assert fused[0] == fused[1]


def test_a_reading_at_a_period_end_teaches_the_same_pack_on_either_side() -> None:
    """A pack that reports on a cadence locked to the autopilot clock, a reading at each
    second: one transport stamps it 3 ms early, the other 3 ms late (a link stamps
    BATTERY_STATUS, which has no time, with the newest autopilot time). A period ends with
    the readings held over its last few ms (estimator.estimation.period_reading), so the two
    end close in energy (docs/daemon.md gives how close: ``period-end-apart``); with "the
    period's latest reading" they were 0.24 % apart (before a0b61fa)."""
    early_wh, late_wh = (period_ends.energy_left_wh(s) for s in period_ends.SHIFTS_S)
    assert late_wh == pytest.approx(early_wh, rel=1e-3)


def test_flush_closes_the_open_period() -> None:
    p = Pipeline(VEHICLE)
    p.process(BatterySample(0.0, FULL_V, 0.0, 0.0))
    p.process(VelocitySample(0.3, 1.0, 0.0, 0.0))
    flushed = p.flush()
    assert flushed is not None and flushed.time_s == 0.3
    assert p.flush() is None  # nothing left to close


def test_the_energy_drawn_does_not_depend_on_the_estimate_period() -> None:
    """Each sample's model power is integrated whatever the period: short and long periods
    draw the same energy from the same flight (model only, so no fusion step differs)."""
    samples = flight(60.0, current=False)
    drawn_wh = []
    for period_s in (0.1, 1.0, 5.0):
        p = Pipeline(VEHICLE, PipelineSettings(estimate_period_s=period_s))
        estimates = run(p, samples)
        assert len(estimates) == pytest.approx(60.0 / period_s, abs=2)
        end = p.flush() or estimates[-1]
        start_wh = float(p.pack.usable_energy_wh(p.pack.soc_from_ocv(FULL_V)))
        drawn_wh.append(start_wh - end.energy_remaining_wh)
    assert drawn_wh[0] > 4.0  # a minute at about 300 W
    assert drawn_wh[1] == pytest.approx(drawn_wh[0], rel=0.005)
    assert drawn_wh[2] == pytest.approx(drawn_wh[0], rel=0.005)


def test_same_samples_give_identical_estimates() -> None:
    samples = flight(60.0)
    assert run(Pipeline(VEHICLE), samples) == run(Pipeline(VEHICLE), samples)


def test_level_flight_estimate_is_consistent() -> None:
    estimates = run(Pipeline(VEHICLE), flight(120.0))
    last = estimates[-1]
    assert last.speed_mps == pytest.approx(8.0, abs=0.01)
    assert last.power_model_w == pytest.approx(float(VEHICLE.model.power_w(8.0)), rel=0.01)
    assert last.bias == pytest.approx(1.0, abs=0.02)
    assert not last.model_only and not last.stale
    assert last.hover_endurance_s < last.endurance_s  # hover costs more than 8 m/s
    assert last.vme_endurance_s >= last.endurance_s * 0.999  # V_me is the best endurance
    assert 5.0 < last.v_me_mps < 10.0
    assert last.range_vmr_m > 0
    assert all(e.energy_remaining_sigma_wh > 0 and e.endurance_sigma_s > 0 for e in estimates)
    assert last.hover_endurance_sigma_s > 0 and last.vme_endurance_sigma_s > 0
    assert last.range_vmr_sigma_m == pytest.approx(
        last.range_vmr_m * last.vme_endurance_sigma_s / last.vme_endurance_s, rel=0.2
    )


def test_no_current_sensor_runs_on_the_model_with_a_wider_sigma() -> None:
    fused = run(Pipeline(VEHICLE), flight(120.0))[-1]
    alone = run(Pipeline(VEHICLE), flight(120.0, current=False))[-1]
    assert alone.model_only and not fused.model_only
    assert alone.power_measured_w is None
    # both carry the start's charge from a typical curve; the model alone adds its scale
    assert alone.endurance_sigma_s > 1.1 * fused.endurance_sigma_s
    assert alone.endurance_s == pytest.approx(fused.endurance_s, rel=0.05)


def test_no_current_sensor_on_the_simulator_stream() -> None:
    run_ = simulate(SimConfig(plan="hover-cruise", duration_s=90.0, seed=5))
    decoder, p = TelemetryDecoder(), Pipeline(VEHICLE)
    estimates = []
    for _, msg in run_.messages:
        if msg.get_type() in ("SYS_STATUS", "BATTERY_STATUS"):
            msg.current_battery = -1  # the autopilot has no current sensor
            if msg.get_type() == "BATTERY_STATUS":
                msg.current_consumed = -1
        for sample in decoder.decode(msg):
            if (e := p.process(sample)) is not None:
                estimates.append(e)
    last = estimates[-1]
    truth_wh = float(run_.truth.energy_remaining_wh[run_.truth.at(last.time_s)])
    assert last.model_only
    assert abs(last.energy_remaining_wh - truth_wh) < 2 * last.energy_remaining_sigma_wh


def test_reboot_resets_kinematics_keeps_energy_and_follows_the_new_clock() -> None:
    p = Pipeline(VEHICLE)
    run(p, flight(100.0))
    before = p.process(RebootSample(0.5))  # closes the old clock's open period
    assert before is not None and before.time_s == pytest.approx(99.9)
    after = run(p, flight(30.0, t0=0.5)[2:])  # same vehicle, new clock, counter restarts at 0
    assert p.counts["reboot"] == 1
    assert after[0].time_s <= 1.0  # the first period on the new clock
    assert after[-1].energy_remaining_wh < before.energy_remaining_wh
    assert after[-1].energy_remaining_wh > before.energy_remaining_wh - 5.0
    assert math.isfinite(after[-1].endurance_s)


def test_disarmed_vehicle_draws_no_model_power() -> None:
    p = Pipeline(VEHICLE)
    run(p, flight(10.0))
    p.process(ArmedSample(10.0, False))
    estimate = p.process(VelocitySample(10.1, 0.0, 0.0, 0.0))
    assert estimate is not None and estimate.power_model_w == 0.0
    assert math.isinf(estimate.endurance_s)


def test_old_battery_data_marks_the_estimate_stale() -> None:
    p = Pipeline(VEHICLE, PipelineSettings(battery_stale_s=2.0))
    run(p, flight(10.0))
    estimate = p.process(VelocitySample(15.0, 8.0, 0.0, 0.0))
    assert estimate is not None and estimate.stale


def test_vehicle_effects_go_through_the_one_power_prediction() -> None:
    with_load = replace(VEHICLE, effects={"avionics": {"power_w": 50.0}})
    base = run(Pipeline(VEHICLE), flight(20.0))[-1]
    loaded = run(Pipeline(with_load), flight(20.0))[-1]
    assert loaded.power_model_w == pytest.approx(base.power_model_w + 50.0, abs=0.5)


def test_out_of_order_samples_are_counted_and_skipped() -> None:
    p = Pipeline(VEHICLE)
    run(p, flight(5.0))
    assert p.process(VelocitySample(1.0, 1.0, 0.0, 0.0)) is None
    assert p.process(BatterySample(1.0, FULL_V, 1.0, 1.0)) is None
    assert p.counts["velocity_out_of_order"] == 1 and p.counts["battery_out_of_order"] == 1


def _model_power_error_w(
    settings: PipelineSettings, hidden: tuple[Effect, ...]
) -> tuple[float, Pipeline]:
    """RMS of model − measured power over the last half of a simulated mixed flight."""
    sim = simulate(SimConfig(plan="mixed", effects=hidden, duration_s=400.0, seed=3))
    decoder, pipeline = TelemetryDecoder(), Pipeline(VEHICLE, settings)
    errors = []
    for _, msg in sim.messages:
        for sample in decoder.decode(msg):
            est = pipeline.process(sample)
            if est is not None and est.time_s > 200.0 and est.power_measured_w is not None:
                errors.append(est.power_model_w - est.power_measured_w)
    return math.sqrt(sum(e * e for e in errors) / len(errors)), pipeline


def test_a_hidden_wind_is_tracked_online_and_the_model_follows_it() -> None:
    hidden = (Wind(speed_mps=5.0, from_deg=60.0),)
    frozen_w, _ = _model_power_error_w(PipelineSettings(track_effects=False), hidden)
    tracked_w, pipeline = _model_power_error_w(PipelineSettings(), hidden)
    assert pipeline.online is not None
    wind = pipeline.online.wind
    assert wind.speed_mps == pytest.approx(5.0, abs=1.0)
    assert abs((wind.from_deg - 60.0 + 180.0) % 360.0 - 180.0) < 20.0
    assert any(isinstance(e, Wind) and e.speed_mps > 3.0 for e in pipeline.effects)
    assert tracked_w < 0.5 * frozen_w


def test_an_unidentified_wind_leaves_the_model_alone() -> None:
    """Straight one-direction flight: wind and mass trade off, so nothing is applied."""
    pipeline = Pipeline(VEHICLE)
    run(pipeline, flight(120.0))
    assert pipeline.online is not None and pipeline.online.updates > 0
    assert pipeline.effects == Pipeline(VEHICLE).effects


def test_arming_at_idle_on_the_ground_teaches_the_bias_nothing() -> None:
    """Armed on the ground at 0 A (the model says hover power): the bias keeps its prior and
    the endurance is not valid, so no absurd time reaches the ground station."""
    p = Pipeline(VEHICLE)
    samples: list[Sample] = [BatterySample(0.0, FULL_V, 0.0, 0.0), ArmedSample(0.0, True)]
    for k in range(1, 300):
        t = k * 0.1
        samples.append(VelocitySample(t, 0.0, 0.0, 0.0, 0.05))
        if k % 5 == 0:
            samples.append(BatterySample(t, FULL_V, 0.3, 0.0))
    estimates = run(p, samples)
    assert estimates and all(not e.endurance_valid for e in estimates)
    assert estimates[-1].bias == pytest.approx(1.0, abs=0.01)
    assert p.counts["readings_ground"] > 50
    assert p.online is not None and p.online.steps == 0


def _first_valid(effects: tuple[Effect, ...]) -> tuple[Estimate, float, list[Estimate]]:
    """Hover at 20 m until the reserve: the first estimate with a valid endurance, the true
    time to the reserve then, and the estimates before it."""
    plan = Plan("hover", (Leg("hover", duration_s=400.0),))
    sim = simulate(SimConfig(plan=plan, effects=effects, seed=5))
    decoder, pipeline = TelemetryDecoder(), Pipeline(VEHICLE)
    estimates = []
    for _, msg in sim.messages:
        for sample in decoder.decode(msg):
            est = pipeline.process(sample)
            if est is not None:
                estimates.append(est)
                if est.endurance_valid:
                    truth_s = float(sim.truth.time_to_reserve_s[sim.truth.at(est.time_s)])
                    return est, truth_s, estimates[:-1]
    raise AssertionError("no valid endurance")


@pytest.mark.parametrize("payload_kg", [0.0, 1.0])
def test_the_first_endurance_published_after_take_off_is_within_10_percent(
    payload_kg: float,
) -> None:
    first, truth_s, before = _first_valid((Mass(payload_kg),) if payload_kg else ())
    assert first.endurance_s == pytest.approx(truth_s, rel=0.10)
    assert first.time_s < 20.0  # take-off at 2 s, 20 m reached at about 13 s
    assert before and all(not e.endurance_valid for e in before)


def test_the_autopilot_wind_reaches_the_tracker_and_the_return() -> None:
    """A WIND report is a sample like the others: counted, kept by the online tracker and by
    the return figures (``[return] wind = "autopilot"`` uses it)."""
    pipeline = Pipeline(default_vehicle())
    report = WindSample(3.0, -4.0, 1.0)
    run(pipeline, [*flight(2.0), report])
    assert pipeline.counts["autopilot_wind"] == 1
    assert pipeline.returning.autopilot_wind == report
    assert pipeline.online is not None and pipeline.online.autopilot.report == report


def test_a_current_sensor_that_falls_silent_leaves_the_energy_falling() -> None:
    """The pack filter learns while there is a current; once the readings come without one
    the energy is the model's, still falling, not pinned to the pack's last estimate."""
    samples = flight(120.0)
    silent = [
        replace(s, current_a=None, consumed_mah=None)
        if isinstance(s, BatterySample) and s.time_s > 60.0
        else s
        for s in samples
    ]
    estimates = run(Pipeline(VEHICLE), silent)
    at_60, last = (next(e for e in estimates if e.time_s >= 60.0), estimates[-1])
    drawn_wh = at_60.energy_remaining_wh - last.energy_remaining_wh
    expected_wh = float(VEHICLE.model.power_w(8.0)) * (last.time_s - at_60.time_s) / 3600.0
    assert drawn_wh == pytest.approx(expected_wh, rel=0.1)


def test_the_first_estimate_rests_on_the_pack_even_from_one_reading() -> None:
    """A first period that closes with no reading but the one that started the fusion (PX4
    at 0.5 Hz before the daemon's rate is in) gives an estimate on the pack filter, with
    the σ the next one has, not the fusion's own start (which takes the label as exact)."""
    p = Pipeline(VEHICLE)
    assert p.process(BatterySample(0.1, FULL_V, 0.5, 0.0)) is None
    first = p.process(VelocitySample(1.05, 0.0, 0.0, 0.0))
    assert p.process(BatterySample(1.5, FULL_V, 0.5, 0.1)) is None
    second = p.process(VelocitySample(2.05, 0.0, 0.0, 0.0))
    assert first is not None and second is not None
    assert math.isfinite(first.pack_soc) and math.isfinite(first.capacity_sigma_ah)
    assert first.energy_remaining_sigma_wh == pytest.approx(
        second.energy_remaining_sigma_wh, rel=0.1
    )
