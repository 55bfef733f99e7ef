"""What the ground station sees before the endurance is valid (start-up) and after."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest

from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.link import MavlinkLink, parse_url
from estimator.mavlink.publish import ENDURANCE_FIELDS, battery_status, json_line, named_values
from estimator.physics.vehicle import default_vehicle
from estimator.telemetry.samples import BatterySample


@pytest.fixture(scope="module")
def estimate() -> Estimate:
    pipeline = Pipeline(default_vehicle())
    pipeline.process(BatterySample(0.0, 16.8, 20.0, 0.0))
    flushed = pipeline.process(BatterySample(1.0, 16.7, 20.0, 5.0))
    assert flushed is not None
    return replace(flushed, endurance_s=1500.0, endurance_valid=True)


def link() -> MavlinkLink:
    return MavlinkLink(parse_url("udpout:127.0.0.1:14550"), 1, 191, 10)


def test_a_valid_endurance_is_published_everywhere(estimate: Estimate) -> None:
    status = battery_status(link(), estimate, 9, 50.0)
    assert status.time_remaining == 1500
    values = {m.name: m.value for m in named_values(link(), estimate)}
    assert values["ENDUR_S"] == 1500.0
    assert int(values["FLAGS"]) & 4 == 0
    assert json.loads(json_line(estimate))["endurance_s"] == 1500.0


def test_an_endurance_not_yet_valid_is_unknown_everywhere(estimate: Estimate) -> None:
    early = replace(estimate, endurance_valid=False)
    status = battery_status(link(), early, 9, 50.0)
    assert status.time_remaining == 0  # MAVLink: 0 = not provided
    assert status.battery_remaining >= 0  # the energy left is still given
    values = {m.name: m.value for m in named_values(link(), early)}
    assert math.isnan(values["ENDUR_S"]) and math.isnan(values["RANGE_VMR"])
    assert values["ENERGY_WH"] == pytest.approx(early.energy_remaining_wh)
    assert int(values["FLAGS"]) & 4 == 4
    doc = json.loads(json_line(early))
    assert doc["endurance_valid"] is False
    assert all(doc[name] is None for name in ENDURANCE_FIELDS)
    assert doc["energy_remaining_wh"] == pytest.approx(early.energy_remaining_wh)


def test_an_absurd_endurance_never_reaches_time_remaining(estimate: Estimate) -> None:
    for endurance_s in (math.inf, -5.0, math.nan):
        status = battery_status(link(), replace(estimate, endurance_s=endurance_s), 9, 50.0)
        assert status.time_remaining == 0


def test_battery_remaining_is_the_packs_learnt_charge(estimate: Estimate) -> None:
    """BATTERY_STATUS.battery_remaining: the charge of the real pack as learnt in flight
    (a pack holding less than its label shows its own charge, not the label's count)."""
    learnt = replace(estimate, pack_soc=0.42, capacity_ah=3.1)
    assert battery_status(link(), learnt, 9, 50.0).battery_remaining == 42
    values = {m.name: m.value for m in named_values(link(), learnt)}
    assert values["PACK_SOC"] == pytest.approx(42.0) and values["PACK_AH"] == pytest.approx(3.1)
    unknown = replace(estimate, pack_soc=math.nan)
    assert battery_status(link(), unknown, 9, 50.0).battery_remaining >= 0
