"""A pack voltage that does not follow the load (estimation/load_response.py): synthetic readings
of a real pack (V = OCV − I·R, noisy) and of a simulator's battery (V falling with time, or
fixed, whatever the current), what the fusion then learns from them, and recorded flights."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from estimator.analysis.replay import replay_stream
from estimator.estimation.fusion import EnergyFilter, FusionSettings
from estimator.estimation.load_response import FLOOR_OHM_PER_CELL, LoadResponse
from estimator.logs import iter_samples
from estimator.physics.battery import PackModel
from estimator.physics.vehicle import BatterySpec, load_vehicle
from estimator.telemetry.samples import BatterySample

CELLS = 4


def _current_a(seconds: float = 120.0) -> np.ndarray:
    """1 Hz current of a flight: 5 A at hover, a 10 m/s leg at 12 A from 40 to 70 s (3 s
    ramps), back to 5 A; 0.1 A of white noise."""
    rng = np.random.default_rng(7)
    t = np.arange(seconds)
    leg = np.clip((t - 40) / 3.0, 0.0, 1.0) - np.clip((t - 70) / 3.0, 0.0, 1.0)
    return 5.0 + 7.0 * leg + rng.normal(0.0, 0.1, len(t))


def _verdict(volts: np.ndarray, amps: np.ndarray) -> tuple[LoadResponse, int | None]:
    """The detector over 1 Hz readings, and the index of the reading that flagged them."""
    load = LoadResponse(CELLS)
    fired = [k for k in range(len(volts)) if load.take(1.0, float(volts[k]), float(amps[k]))]
    assert len(fired) <= 1  # said once
    return load, fired[0] if fired else None


@pytest.mark.parametrize("resistance_ohm_per_cell", [0.0015, 0.005, 0.0125])
def test_a_real_pack_is_never_flagged(resistance_ohm_per_cell: float) -> None:
    """Down to 1.5 mΩ a cell (a new high-rate cell), 4 mV readings, a resting voltage falling
    with the charge drawn: the voltage follows the load, R̂ within 3σ of the truth."""
    rng = np.random.default_rng(11)
    amps = _current_a()
    drawn_ah = np.cumsum(amps) / 3600.0
    ocv_v = 16.4 - 1.2 * drawn_ah
    true_ohm = resistance_ohm_per_cell * CELLS
    volts = np.round((ocv_v - true_ohm * amps + rng.normal(0.0, 0.002, len(amps))) / 0.004) * 0.004
    load, fired = _verdict(volts, amps)
    assert fired is None and not load.unresponsive
    assert abs(load.resistance_ohm - true_ohm) <= 3.0 * load.sigma_ohm


@pytest.mark.parametrize("fall_v_per_s", [0.0, 0.03])
def test_a_voltage_that_ignores_the_load_is_flagged_once_the_load_stepped(
    fall_v_per_s: float,
) -> None:
    """A voltage falling with time only (PX4 SIH: 30 mV/s of armed time) or fixed (a
    simulator's constant pack), in mV: flagged after the leg's steps of load, not before."""
    amps = _current_a()
    volts = np.round((16.2 - fall_v_per_s * np.arange(len(amps))) * 1000.0) / 1000.0
    load, fired = _verdict(volts, amps)
    assert fired is not None and 40 <= fired <= 80
    assert load.resistance_ohm + 3.0 * load.sigma_ohm < FLOOR_OHM_PER_CELL * CELLS
    assert "does not follow the load" in load.describe()


def test_arming_and_disarming_are_no_steps() -> None:
    """A simulator's battery that starts falling at arming and resets at disarming: the
    readings at rest (below 1 A) break the pairs, so neither jump counts as a step."""
    load = LoadResponse(CELLS)
    for volts, amps in [(16.2, 0.0), (16.2, 0.0), (16.17, 5.0), (16.14, 5.0), (16.2, 0.0)]:
        load.take(1.0, volts, amps)
    assert load.steps == 0 and not load.unresponsive


def test_the_fusion_learns_no_resistance_from_a_voltage_that_ignores_the_load() -> None:
    """Model-only fusion (no current sensor: the modelled current) on a voltage that falls with
    time: before the verdict the resistance filter reads the fall as a resistance; at the
    verdict R is its prior again, stays there, and the energy state says so."""
    spec = BatterySpec(capacity_ah=1.5, cells=CELLS)
    settings = FusionSettings()
    energy = EnergyFilter(PackModel(spec), settings)
    energy.initialize(BatterySample(0.0, 16.2, None, None, None), 80.0)
    assert energy.voltage is not None and energy.voltage_follows_load
    prior_ohm = settings.resistance_prior_ohm_per_cell * CELLS
    amps = _current_a()
    learnt = []
    for k, current_a in enumerate(amps):
        energy.voltage.update(1.0, 0.9, 16.2 - 0.01 * k, float(current_a))
        learnt.append(energy.voltage.resistance_ohm)
    assert max(learnt[:40]) > 2.0 * prior_ohm  # the fall read as a resistance, until...
    assert not energy.voltage_follows_load
    assert learnt[-1] == pytest.approx(prior_ohm)
    assert energy.voltage.snapshot()["var_ohm2"] == pytest.approx(prior_ohm**2)


REPLAY = Path(__file__).resolve().parent.parent / "replay"
SITL_QUAD = REPLAY.parent / "config/vehicles/ardupilot_sitl_quad.toml"


@pytest.mark.parametrize(
    ("log", "vehicle", "withhold_current", "flagged"),
    [
        ("sitl_packs/pack_c100_r1/flight.tlog", SITL_QUAD, False, False),  # 2.5 mΩ a cell
        ("sitl_packs/pack_c65_r1_payload/flight.tlog", SITL_QUAD, True, False),
        ("iris/2016-03-21/010/010.log", REPLAY / "vehicle.toml", False, False),
        ("iris/2016-08-09/003/003.log", REPLAY / "vehicle.toml", True, False),
        ("sitl/clean_legs/flight.tlog", SITL_QUAD, False, True),  # SITL's fixed 12.6 V
    ],
)
def test_recorded_packs(log: str, vehicle: Path, withhold_current: bool, flagged: bool) -> None:
    """Replayed recordings: real packs (ArduCopter SITL's pack model, the IRIS+ flights; also on
    the modelled current, their own withheld) are never flagged; SITL's fixed voltage is."""
    stream = iter_samples(REPLAY / log)
    samples = (
        replace(s, current_a=None, consumed_mah=None)
        if withhold_current and isinstance(s, BatterySample)
        else s
        for s in stream
    )
    estimates = replay_stream(stream, load_vehicle(vehicle), log, samples=samples).estimates
    assert estimates
    assert any(not e.voltage_follows_load for e in estimates) is flagged
