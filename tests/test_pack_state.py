"""The pack filter (estimator.estimation.pack_state): charge, real capacity and resistance
from voltage, current and the charge counted; on synthetic packs and on the ArduCopter SITL
pack flights of replay/sitl_packs (a 5.0 Ah label, the real pack 65–100 % of it, 10 or 30 mΩ,
powered up at 50–100 % charge; see their SOURCE.md and the held-out split in split.json)."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fixtures.held_voltage import held_voltage_flight, own_curve_vehicle

from estimator.analysis.pack_flights import half_used_s, replay_pack_flight
from estimator.estimation.estimate import Estimate
from estimator.estimation.pack_bank import PackBank, track_pack
from estimator.estimation.pack_state import PackEstimate, PackFilter, PackPrior, PackSettings
from estimator.estimation.pipeline import Pipeline
from estimator.logs import iter_samples
from estimator.mavlink.pack_alerts import PackLabelAlert
from estimator.physics.battery import CHEMISTRY_OCV_V, SOC_POINTS, PackModel
from estimator.physics.vehicle import BatterySpec, default_vehicle, load_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import BatterySample

ROOT = Path(__file__).resolve().parent.parent
PACK_FLIGHTS = ROOT / "replay" / "sitl_packs"
SPLIT = json.loads((PACK_FLIGHTS / "split.json").read_text())
#: A 6S 10 Ah LiPo whose resting curve is its own (measured on the pack).
OWN = BatterySpec(10.0, 6, cell_ocv_v=tuple(float(v) for v in CHEMISTRY_OCV_V["lipo"]))


def discharge(
    spec: BatterySpec, fraction: float, soc0: float, amps: float, until_soc: float
) -> list[BatterySample]:
    """Readings (1 s) of a pack holding ``fraction`` of ``spec``'s label at a current that
    alternates ``amps`` and 1.5 × ``amps`` each minute, from ``soc0`` to ``until_soc``."""
    real = PackModel(dataclasses.replace(spec, capacity_ah=spec.capacity_ah * fraction))
    soc, consumed_mah, out = soc0, 0.0, [BatterySample(0.0, float(real.ocv_v(soc0)), 0.0, 0.0)]
    t = 0
    while soc > until_soc:
        t += 1
        current = amps * (1.5 if (t // 60) % 2 else 1.0)
        soc -= current / 3600.0 / real.spec.capacity_ah
        consumed_mah += current / 3.6
        volts = float(real.ocv_v(soc)) - 0.025 * current
        out.append(BatterySample(float(t), volts, current, consumed_mah))
    return out


@pytest.mark.parametrize("fraction", [1.0, 0.8, 0.65])
@pytest.mark.parametrize("soc0", [1.0, 0.6])
def test_capacity_and_charge_are_learned_against_the_label(fraction: float, soc0: float) -> None:
    samples = discharge(OWN, fraction, soc0, 30.0, soc0 - 0.35)
    track = track_pack(samples, PackModel(OWN))
    first, last = track[0][1], track[-1][1]
    assert first.soc == pytest.approx(soc0, abs=0.02)
    assert last.capacity_ah == pytest.approx(10.0 * fraction, rel=0.05)
    assert abs(last.capacity_ah - 10.0 * fraction) < 3 * last.capacity_sigma_ah
    assert last.resistance_ohm == pytest.approx(0.025, rel=0.05)


def test_a_prior_from_an_earlier_flight_is_where_the_capacity_starts() -> None:
    f = PackFilter(PackModel(OWN), PackSettings(), PackPrior(7.0, 0.2, 0.03, 0.003))
    f.start(float(PackModel(OWN).ocv_v(1.0)), 0.0)
    est = f.estimate()
    assert est.capacity_ah == pytest.approx(7.0, rel=0.01)
    assert est.capacity_sigma_ah == pytest.approx(0.2, rel=0.05)
    assert est.resistance_ohm == pytest.approx(0.03, rel=0.05)


def test_a_label_trusted_exactly_stays_the_capacity() -> None:
    samples = discharge(OWN, 0.8, 1.0, 30.0, 0.6)
    track = track_pack(samples, PackModel(OWN), PackSettings(capacity_sigma_fraction=0.0))
    assert track[-1][1].capacity_ah == pytest.approx(10.0)


def test_a_reading_far_off_the_prediction_is_not_used() -> None:
    pack = PackModel(OWN)
    f = PackFilter(pack, PackSettings())
    f.start(float(pack.ocv_v(0.9)), 0.0)
    for _ in range(50):
        f.update(1.0, float(pack.ocv_v(0.9)), 0.0)
    before = f.x.copy()
    f.update(1.0, 0.001, 0.0)  # a forged or glitched 1 mV
    assert f.rejected == 1
    assert np.array_equal(f.x, before)


def test_a_snapshot_round_trips_and_a_forged_one_is_refused() -> None:
    pack = PackModel(OWN)
    f = PackFilter(pack, PackSettings())
    f.start(float(pack.ocv_v(0.9)), 0.0)
    f.count(500.0)
    f.update(1.0, float(pack.ocv_v(0.85)) - 0.5, 20.0)
    g = PackFilter(pack, PackSettings())
    g.restore(json.loads(json.dumps(f.snapshot())))
    assert g.estimate() == f.estimate()
    for forged in ({"x": [1.0, 100.0, 0.0, 0.0]}, {"P": [[-1.0] * 4] * 4}, {"charge_ah": 1e300}):
        with pytest.raises(ValueError):
            PackFilter(pack, PackSettings()).restore({**f.snapshot(), **forged})


@pytest.mark.parametrize("chemistry", sorted(CHEMISTRY_OCV_V))
def test_each_chemistry_has_a_rising_curve_and_a_full_voltage(chemistry: str) -> None:
    curve = CHEMISTRY_OCV_V[chemistry]
    assert len(curve) == len(SOC_POINTS) and np.all(np.diff(curve) > 0)
    assert curve[-1] == pytest.approx({"lipo": 4.20, "lihv": 4.35, "liion": 4.19}[chemistry])
    pack = PackModel(BatterySpec(5.0, 4, chemistry=chemistry))
    v, slope = pack.cell_ocv_slope_v(0.5)
    assert v == pytest.approx(float(pack.ocv_v(0.5)) / 4) and slope > 0
    assert pack.cell_energy_wh_per_ah(1.0) == pytest.approx(float(pack.energy_wh(1.0)) / 20.0)


# -- the SITL pack flights ----------------------------------------------------------------------


def _flight(
    name: str,
) -> tuple[dict[str, Any], list[tuple[float, PackEstimate]], list[BatterySample]]:
    truth = json.loads((PACK_FLIGHTS / name / "truth.json").read_text())
    vehicle = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
    label = dataclasses.replace(
        vehicle.battery, capacity_ah=truth["battery"]["labelled_capacity_ah"]
    )
    samples = [
        s
        for s in iter_samples(PACK_FLIGHTS / name / "flight.tlog", "auto", vehicle.input_limits())
        if isinstance(s, BatterySample)
    ]
    return truth, track_pack(samples, PackModel(label)), samples


def _flights(misses: Mapping[str, str]) -> list[Any]:
    """Every SITL pack flight as a test parameter (with its set in the id), each of
    ``misses`` a strict xfail whose reason is the miss's cause."""
    return [
        pytest.param(
            n,
            id=f"{n}-{half.replace('_', '-')}",
            marks=[pytest.mark.xfail(strict=True, reason=misses[n])] if n in misses else [],
        )
        for half, names in SPLIT.items()
        for n in names
    ]


@pytest.mark.parametrize("name", _flights({}))
def test_sitl_pack_charge_at_power_up_and_capacity_before_half_is_used(name: str) -> None:
    """Replayed with the LABELLED 5.0 Ah: the charge at power-up within 5 % of the truth
    (and 3σ), and the real capacity within 5 % (and 3σ) once half the pack's charge is used;
    the resistance within 10 % at the end."""
    truth, track, samples = _flight(name)
    battery = truth["battery"]
    first = track[0][1]
    assert abs(first.soc - battery["start_soc"]) <= min(0.05, 3 * first.soc_sigma)
    half_s = half_used_s(samples, battery)
    at_half = next(est for t, est in track if t >= half_s)
    error_ah = at_half.capacity_ah - battery["capacity_ah"]
    assert abs(error_ah) <= 0.05 * battery["capacity_ah"]
    assert abs(error_ah) <= 3 * at_half.capacity_sigma_ah
    last = track[-1][1]
    resistance = battery["internal_resistance_ohm"]
    assert math.isclose(last.resistance_ohm, resistance, rel_tol=0.1)


# -- the pipeline and the ground station's warning -----------------------------------------------


def _alert_estimate(capacity_ah: float, sigma_ah: float, stale: bool = False) -> Estimate:
    return replace(BASE_ESTIMATE, capacity_ah=capacity_ah, capacity_sigma_ah=sigma_ah, stale=stale)


def test_the_label_warning_goes_out_once_beyond_3_sigma_and_rearms_within_2() -> None:
    alert = PackLabelAlert(label_ah=4.0)
    assert alert.update(_alert_estimate(3.5, 0.3)) is None  # 1.7σ: could be the label
    assert alert.update(_alert_estimate(3.0, 0.3, stale=True)) is None
    sent = alert.update(_alert_estimate(3.0, 0.3))
    assert sent is not None and sent.text == "pack holds ~3.0Ah, configured 4.0Ah"
    assert alert.update(_alert_estimate(2.9, 0.1)) is None  # already said
    assert alert.update(_alert_estimate(3.5, 0.3)) is None  # 1.7σ: re-armed
    assert alert.update(_alert_estimate(3.0, 0.2)) is not None
    assert alert.sent == 2
    assert PackLabelAlert(4.0).update(_alert_estimate(math.nan, math.nan)) is None


#: Mislabelled packs announced later than 90 s after take-off, and why.
LATE_WARNINGS = {
    "pack_c95_r2_soc65_wind": "held-out 3, as first scored: a pack 5 % short of its label, "
    "powered up at 65 %, is announced 100 s after take-off (3σ of the capacity is 5 % only "
    "once enough charge has been drawn)",
    "pack_c95_r1_soc60": "held-out 4, as first scored: the same, 5 % short and powered up at "
    "60 %, announced 91 s after take-off",
    "pack_c95_r3_wind": "held-out 6, as first scored: a pack 5 % short, fully charged, "
    "announced 90.3 s after take-off",
}


@pytest.mark.parametrize("name", _flights(LATE_WARNINGS))
def test_the_pipeline_learns_the_pack_and_warns_of_a_wrong_label(name: str) -> None:
    """The daemon's pipeline replaying a SITL pack flight with the LABELLED 5.0 Ah: a pack
    holding 60–95 % of its label is announced within 90 s of take-off, one that holds its
    label never; the published capacity is within 5 % (and 3σ) before half of the charge is
    used."""
    vehicle = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
    flight = replay_pack_flight(PACK_FLIGHTS / name, vehicle)  # under the pack's label
    truth = flight.truth
    battery = truth["battery"]
    alert = PackLabelAlert(battery["labelled_capacity_ah"])
    warned_s = [e.time_s for e in flight.estimates if alert.update(e) is not None]
    takeoff_s = truth["events"]["takeoff_s"]
    if battery["capacity_ah"] < battery["labelled_capacity_ah"]:
        assert warned_s and warned_s[0] - takeoff_s <= 90.0, warned_s
    else:
        assert not warned_s
    half_s = half_used_s(flight.readings, battery)
    before_half = [e for e in flight.estimates if takeoff_s <= e.time_s <= half_s]
    last = before_half[-1]
    assert abs(last.capacity_ah - battery["capacity_ah"]) <= 0.05 * battery["capacity_ah"]
    assert abs(last.capacity_ah - battery["capacity_ah"]) <= 3 * last.capacity_sigma_ah


#: An estimate to vary in the warning's tests.
BASE_ESTIMATE = Estimate(
    time_s=100.0, speed_mps=0.0, accel_tangential_mps2=0.0, accel_centripetal_mps2=0.0,
    climb_mps=0.0, power_model_w=300.0, power_measured_w=300.0, energy_remaining_wh=30.0,
    energy_remaining_sigma_wh=1.0, endurance_s=300.0, endurance_sigma_s=10.0,
    hover_endurance_s=300.0, vme_endurance_s=320.0, v_me_mps=5.0, range_vmr_m=3000.0,
    bias=1.0, bias_sigma=0.01, model_only=False, stale=False,
)  # fmt: skip


@pytest.mark.parametrize("soc0", [0.5, 0.75, 1.0])
def test_the_charge_before_take_off_is_read_within_5_percent_on_the_simulator(
    soc0: float,
) -> None:
    """The built-in simulator powered up at ``soc0`` (its vehicle trusting a typical LiPo
    curve): the charge before take-off within 5 % of the truth, and within 2σ."""
    run = simulate(SimConfig(plan="hover-cruise", duration_s=30.0, initial_soc=soc0, seed=3))
    decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle())
    first = None
    for _, msg in run.messages:
        for sample in decoder.decode(msg):
            estimate = pipeline.process(sample)
            if first is None and estimate is not None and math.isfinite(estimate.pack_soc):
                first = estimate
    assert first is not None and not run.truth.flying[run.truth.at(first.time_s)]
    assert abs(first.pack_soc - soc0) <= 0.05
    assert abs(first.pack_soc - soc0) <= 2 * first.pack_soc_sigma


def test_a_resistance_measured_on_the_pack_is_the_prior() -> None:
    """``[battery] internal_resistance_ohm`` (written by ``uav-energy fit``) starts the filter,
    ± 30 %; the pack's memory, where there is one, wins."""
    spec = replace(OWN, internal_resistance_ohm=0.021)
    assert PackFilter(PackModel(spec), PackSettings()).resistance_prior() == pytest.approx(
        (0.021, 0.0063)
    )
    memory = PackPrior(capacity_ah=4.0, capacity_sigma_ah=0.1, resistance_ohm=0.03,
                       resistance_sigma_ohm=0.002)  # fmt: skip
    assert PackFilter(PackModel(spec), PackSettings(), memory).resistance_prior() == (0.03, 0.002)


def test_a_voltage_that_holds_as_charge_is_drawn_refutes_the_pack() -> None:
    """A source whose voltage sags with the current but not with the charge drawn (a
    simulator's battery of constant voltage) drives q to its bound: the filter is refuted
    within 10 readings there, and a bank drops it; packs of 65-100 % of their label are not."""
    pack, rest_v = PackModel(OWN), float(PackModel(OWN).ocv_v(0.95))
    held = [
        replace(s, voltage_v=rest_v - 0.025 * s.current_a)
        for s in discharge(OWN, 1.0, 0.95, 30.0, 0.55)
    ]
    bank = PackBank(pack, PackSettings())
    pinned_at = None
    for s in held:
        assert s.current_a is not None
        bank.take(s.time_s, s.voltage_v, s.current_a, s.consumed_mah)
        if pinned_at is None and bank.best.x[1] <= 0.4:
            pinned_at = s.time_s
        if bank.refuted:
            break
    assert pinned_at is not None and bank.refuted
    assert s.time_s - pinned_at <= 10.0
    for fraction in (1.0, 0.65):
        bank = PackBank(pack, PackSettings())
        for s in discharge(OWN, fraction, 1.0, 30.0, 0.3):
            assert s.current_a is not None
            bank.take(s.time_s, s.voltage_v, s.current_a, s.consumed_mah)
        assert not bank.refuted


def test_a_refuted_pack_leaves_the_energy_counted_against_the_label() -> None:
    """The pipeline on the built-in simulator, its vehicle with the pack's own curve, the
    voltage the pack reports held at its resting value less I·R (the charge drawn never
    shows): the pack filter is refuted, the capacity no longer published, and the energy left
    is the label's count, within 3σ of the truth at every estimate after; before, the
    capacity sat at 2.5 × the label and the energy left ended 4.8σ off."""
    run = simulate(
        SimConfig(vehicle=own_curve_vehicle(), plan="hover-cruise", duration_s=300.0, seed=3)
    )
    decoder, pipeline = TelemetryDecoder(), Pipeline(own_curve_vehicle())
    after = []
    for _, msg in held_voltage_flight(300.0):
        for sample in decoder.decode(msg):
            estimate = pipeline.process(sample)
            if estimate is not None and pipeline.packs.refuted:
                after.append(estimate)
    assert after and all(math.isnan(e.capacity_ah) for e in after)
    truth = run.truth.energy_remaining_wh[run.truth.at(np.array([e.time_s for e in after]))]
    z = (np.array([e.energy_remaining_wh for e in after]) - truth) / np.array(
        [e.energy_remaining_sigma_wh for e in after]
    )
    assert np.abs(z).max() <= 3.0, np.abs(z).max()


def test_a_refuted_pack_stays_refuted_in_a_daemon_restarted_from_its_state() -> None:
    """The state file keeps the refutation: a pipeline resumed from a snapshot taken 20 s
    after it learns no pack again and counts the energy against the label as the pipeline
    that ran on does; before, it started a new pack filter, which anchored the energy again
    until that one too was refuted. A forged flag is refused."""
    messages = [m for _, m in held_voltage_flight(300.0)]
    decoder, first = TelemetryDecoder(), Pipeline(own_curve_vehicle())
    snapshot, restart_at, ends, learning = None, 0, [], None
    for k, msg in enumerate(messages):
        for sample in decoder.decode(msg):
            estimate = first.process(sample)
            if learning is None and estimate is not None and first.pack_state is not None:
                learning = first.snapshot()  # a snapshot with a pack filter, for the forgery
            if estimate is None or not first.packs.refuted:
                continue
            ends.append(estimate)
            if snapshot is None and estimate.time_s - ends[0].time_s >= 20.0:
                snapshot, restart_at = json.loads(json.dumps(first.snapshot())), k + 1
    assert snapshot is not None and snapshot["pack_refuted"] is True
    decoder, restarted = TelemetryDecoder(), Pipeline(own_curve_vehicle())
    restarted.resume(snapshot)
    after = [
        e
        for msg in messages[restart_at:]
        for sample in decoder.decode(msg)
        if (e := restarted.process(sample)) is not None
    ]
    assert after and restarted.packs.refuted and restarted.pack_state is None
    assert all(math.isnan(e.capacity_ah) for e in after)
    end, ran_on = after[-1], ends[-1]
    assert end.time_s == ran_on.time_s
    assert abs(end.energy_remaining_wh - ran_on.energy_remaining_wh) < 0.1 * (
        ran_on.energy_remaining_sigma_wh
    )
    assert learning is not None  # forged: a refutation that is not a flag, or with a pack filter
    for forged in ({**snapshot, "pack_refuted": "yes"}, {**learning, "pack_refuted": True}):
        with pytest.raises(ValueError, match="pack"):
            restarted.check_snapshot(forged)
