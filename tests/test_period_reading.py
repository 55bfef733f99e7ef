"""The reading a period ends with: the readings held over its last STAMP_WINDOW_S."""

from __future__ import annotations

import pytest

from estimator.estimation.period_reading import STAMP_WINDOW_S, period_end_reading
from estimator.telemetry.samples import BatterySample

BEFORE = BatterySample(9.75, 15.80, 6.0, 100.0)
END_S = 10.0


def test_a_latest_reading_before_the_window_is_taken_whole() -> None:
    latest = BatterySample(END_S - 2 * STAMP_WINDOW_S, 15.70, 8.0, 101.0, 80.0)
    assert period_end_reading(BEFORE, [latest], END_S) is latest


def test_the_reading_taken_moves_continuously_as_a_stamp_crosses_the_end() -> None:
    """A reading just before the end counts for the time it held; the same reading just past
    the end (the next period's) leaves this one with the reading before it, whole."""
    step = BatterySample(0.0, 15.40, 12.0, 102.0)
    taken = [
        period_end_reading(BEFORE, [BatterySample(END_S - lead_s, 15.40, 12.0, 102.0)], END_S)
        for lead_s in (0.001, STAMP_WINDOW_S / 2, STAMP_WINDOW_S - 1e-9)
    ]
    share = 0.001 / STAMP_WINDOW_S  # 1 ms of the window: almost the reading before, whole
    assert taken[0].voltage_v == pytest.approx(15.80 + share * (15.40 - 15.80))
    assert taken[0].current_a == pytest.approx(6.0 + share * (12.0 - 6.0))
    half = taken[1]
    assert half.voltage_v == pytest.approx((BEFORE.voltage_v + step.voltage_v) / 2)
    assert half.current_a == pytest.approx((BEFORE.current_a + step.current_a) / 2)
    assert half.consumed_mah == pytest.approx(101.0)
    assert taken[2].voltage_v == pytest.approx(step.voltage_v, abs=1e-6)
    # past the end it is not this period's: the period ends with the reading before it
    assert period_end_reading(None, [BEFORE], END_S) is BEFORE


def test_every_reading_in_the_window_counts_for_the_time_it_held() -> None:
    w = STAMP_WINDOW_S
    readings = [
        BatterySample(END_S - 0.75 * w, 15.0, 10.0, 1.0),
        BatterySample(END_S - 0.25 * w, 14.0, 20.0, 2.0),
    ]
    taken = period_end_reading(BEFORE, readings, END_S)
    # held: BEFORE 0.25 w, the first 0.5 w, the second 0.25 w
    assert taken.voltage_v == pytest.approx(0.25 * 15.80 + 0.5 * 15.0 + 0.25 * 14.0)
    assert taken.current_a == pytest.approx(0.25 * 6.0 + 0.5 * 10.0 + 0.25 * 20.0)


def test_without_a_current_or_a_reading_before_the_latest_is_taken() -> None:
    latest = BatterySample(END_S - 0.01, 15.70, 8.0, 101.0)
    assert period_end_reading(None, [latest], END_S) is latest
    no_current = BatterySample(9.5, 15.80)
    assert period_end_reading(no_current, [latest], END_S) is latest
    taken = period_end_reading(BEFORE, [BatterySample(END_S - 0.01, 15.70, 8.0)], END_S)
    assert taken.consumed_mah is None  # the latest's, not a mean with a missing value
