"""Which readings a step of the online tracker takes (:mod:`estimator.estimation.tracker_readings`):
the gates by cause, and a step the vertical gates mostly left out skipped whole."""

from __future__ import annotations

import math

from estimator.estimation.online_settings import OnlineSettings
from estimator.estimation.tracker_readings import TrackerReading, select_readings
from estimator.physics.kinematics import KinematicState

SETTINGS = OnlineSettings()
HOVER_W = 300.0
MAX_AD_MPS2 = SETTINGS.max_vertical_accel_mps2


def reading(
    time_s: float, vd_mps: float = 0.0, ad_mps2: float = 0.0, power_w: float = 310.0
) -> TrackerReading:
    """A level reading at 5 m/s north (vertical speed and acceleration down positive)."""
    state = KinematicState(
        time_s, 5.0, 0.0, vd_mps, 0.0, 0.0, 5.0, 0.0, 0.0, -vd_mps, 20.0, 0.1, ad_mps2
    )
    return TrackerReading(state, power_w, 16.0)


def test_each_gate_counts_its_readings_and_keeps_the_rest_in_order() -> None:
    readings = [
        reading(10.0),
        reading(10.5, power_w=math.nan),  # not finite
        reading(9.0),  # before the last step
        reading(11.0, vd_mps=1.5),  # fast vertical motion
        reading(11.5, power_w=50.0),  # idle
        reading(12.0),
        reading(12.5),
    ]
    selection = select_readings(readings, SETTINGS, 9.5, MAX_AD_MPS2, HOVER_W)
    assert [r.state.time_s for r, _ in selection.kept] == [10.0, 12.0, 12.5]
    assert (selection.rejected, selection.vertical, selection.idle) == (2, 1, 1)
    assert selection.kept[0][1] == (10.0, 5.0, 0.0, 0.0, 0.0, 0.0)


def test_a_step_the_vertical_gates_mostly_left_out_is_a_transition_and_skipped_whole() -> None:
    """A descent starting: the power falls first (the readings the gates keep read light),
    then the filtered state leaves the gates. Half the step gated keeps the rest; more than
    half leaves them all out."""
    start = [reading(20.0, power_w=240.0), reading(20.5, power_w=230.0)]
    half = [*start, reading(21.0, vd_mps=1.2), reading(21.5, ad_mps2=1.0)]
    assert len(select_readings(half, SETTINGS, None, MAX_AD_MPS2, HOVER_W).kept) == 2
    most = [start[0], reading(20.5, vd_mps=1.1), reading(21.0, vd_mps=1.2), reading(21.5, 1.4)]
    selection = select_readings(most, SETTINGS, None, MAX_AD_MPS2, HOVER_W)
    assert selection.kept == [] and selection.vertical == 4
