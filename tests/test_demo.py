"""The live demo (:mod:`estimator.sim.demo`) at maximum speed on a short mission: its summary
figures come from the flight it flew, and they are sane."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from estimator.analysis.replay import replay_log
from estimator.errors import UserError
from estimator.physics.vehicle import default_vehicle
from estimator.sim.demo import (
    DEFAULT_WIND,
    DemoSummary,
    LiveTable,
    cruise_start_s,
    demo_plan,
    run_demo,
    summary_table,
)
from estimator.sim.plans import Leg, Plan
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

#: Take-off, hover, a 150 m leg, a turn; then the demo's cruise: ~130 s of it in 200 s.
SHORT = Plan(
    "short",
    (
        Leg("hover", duration_s=10.0),
        Leg("straight", 8.0, heading_deg=90.0, distance_m=150.0),
        Leg("circle", 6.0, radius_m=20.0, turns=1.0),
    ),
)
DURATION_S = 200.0
MAX_SPEEDUP = 1000.0  # the simulator and the daemon pace each other: as fast as they go


def _demo(tmp_path: Path, wind: object) -> tuple[DemoSummary, str]:
    out = io.StringIO()
    summary = run_demo(
        base_plan=SHORT,
        duration_s=DURATION_S,
        wind=wind,  # type: ignore[arg-type]
        speedup=MAX_SPEEDUP,
        out_dir=tmp_path,
        console=Console(file=out, width=100),
    )
    return summary, out.getvalue()


@pytest.fixture(scope="module")
def windy(tmp_path_factory: pytest.TempPathFactory) -> tuple[DemoSummary, str, Path]:
    out_dir = tmp_path_factory.mktemp("windy")
    summary, table = _demo(out_dir, DEFAULT_WIND)
    return summary, table, out_dir


def test_summary_figures_are_those_of_the_flight_flown(
    windy: tuple[DemoSummary, str, Path],
) -> None:
    """The final remaining-energy error equals a replay of the demo's tlog against the truth
    it wrote beside it; the estimate count is that replay's."""
    summary, _, out_dir = windy
    replayed = replay_log(out_dir / "demo.tlog", default_vehicle()).estimates
    truth = np.genfromtxt(out_dir / "demo.truth.csv", delimiter=",", names=True)
    assert summary.estimates == len(replayed)
    assert summary.flight_s == pytest.approx(DURATION_S, abs=0.1)
    last = replayed[-1]
    true_end_wh = np.interp(last.time_s, truth["time_s"], truth["energy_remaining_wh"])
    assert summary.energy_error_end_wh == pytest.approx(
        last.energy_remaining_wh - true_end_wh, abs=0.05
    )
    assert summary.final_bias == pytest.approx(last.bias)
    written = json.loads((out_dir / "summary.json").read_text())
    assert written["estimates"] == summary.estimates
    assert written["wind_cost_wh"] == pytest.approx(summary.wind_cost_wh)
    assert [c["after_s"] for c in written["endurance"]] == [10.0, 30.0, 60.0, 120.0]


def test_remaining_energy_and_cruise_endurance_match_the_truth(
    windy: tuple[DemoSummary, str, Path],
) -> None:
    summary, _, _ = windy
    assert abs(summary.energy_error_end_wh) < 2.0
    assert summary.energy_error_rms_wh < 2.0
    assert summary.energy_within_1sigma_pct >= 90.0
    checks = {c.after_s: c for c in summary.endurance}
    assert set(checks) == {10.0, 30.0, 60.0, 120.0}
    for after in (60.0, 120.0):  # once the fused bias has learned the head wind
        assert abs(checks[after].error_pct) < 5.0
        assert 0 < checks[after].sigma_s < 0.1 * checks[after].estimate_s


def test_the_hidden_wind_costs_energy_and_endurance(
    windy: tuple[DemoSummary, str, Path],
) -> None:
    summary, _, _ = windy
    assert summary.power_rmse_w is not None and summary.power_mape_pct is not None
    assert summary.power_rmse_w > 20.0  # the model misses the wind until it is learnt online
    assert summary.wind_cost_wh > 1.0
    assert summary.final_bias == pytest.approx(1.0, abs=0.05)  # the wind is in the model now
    speed, direction = summary.wind_learnt.split(" m/s from ")
    assert float(speed) == pytest.approx(6.0, abs=1.0)  # hidden: 6 m/s from 30°
    assert abs(float(direction.rstrip("°")) - 30.0) < 20.0
    assert summary.wind_cost_reserve_s > 60.0
    assert summary.reserve_s < summary.reserve_without_wind_s


def test_without_wind_the_model_is_right_and_costs_nothing(tmp_path: Path) -> None:
    summary, _ = _demo(tmp_path, None)
    assert summary.wind == "none"
    assert summary.power_rmse_w is not None and summary.power_rmse_w < 20.0
    assert abs(summary.wind_cost_wh) < 0.05 * summary.energy_measured_wh
    assert summary.wind_cost_reserve_s == 0.0
    assert summary.final_bias == pytest.approx(1.0, abs=0.03)


def test_live_table_and_summary_show_predicted_measured_and_truth(
    windy: tuple[DemoSummary, str, Path],
) -> None:
    summary, table, _ = windy
    for header in ("P mod", "P meas", "E Wh ±σ", "E true", "end min", "mission min"):
        assert header in table
    # the two endurance columns measure different things: the table says which
    assert " ".join(LiveTable.CAPTION.split()[:8]) in " ".join(table.split())
    # the simulator holds no MAVLink mission: the daemon does not ask it for one
    assert not any(key.startswith("mission_") for key in summary.counters)
    assert "hidden wind 6 m/s from 30°" in table
    out = io.StringIO()
    Console(file=out, width=120).print(summary_table(summary))
    text = out.getvalue()
    assert "endurance 120 s into the cruise" in text
    assert f"{summary.power_rmse_w:.1f} W" in text


def test_cruise_start_is_found_in_the_truth_and_endless_plans_are_refused(
    windy: tuple[DemoSummary, str, Path],
) -> None:
    _, _, out_dir = windy
    truth = np.genfromtxt(out_dir / "demo.truth.csv", delimiter=",", names=True)
    moving_fast = truth["time_s"][np.abs(truth["speed_mps"] - 10.0) < 0.3]
    assert moving_fast.size and moving_fast[-1] == pytest.approx(DURATION_S, abs=0.2)
    with pytest.raises(UserError, match="never ends"):
        demo_plan("hover-cruise")
    assert demo_plan(SHORT).legs[-1].endless
    landed = simulate(SimConfig(plan=Plan("hover", (Leg("hover", duration_s=5.0),)))).truth
    assert math.isnan(cruise_start_s(landed))


@pytest.mark.parametrize("kwargs", [{"speedup": 0.0}, {"duration_s": -5.0}])
def test_bad_speedup_or_duration_is_a_user_error(kwargs: dict[str, float]) -> None:
    with pytest.raises(UserError):
        run_demo(**kwargs)  # type: ignore[arg-type]
