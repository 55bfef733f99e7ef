"""Online wind and mass tracking on simulated flights replayed the daemon's way (tlog →
samples → causal kinematics → tracker): hidden wind and mass are recovered during flight, a
payload step is followed, clean flights stay at zero, and the vehicle file's values are the
start."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from estimator.errors import UserError
from estimator.estimation.airborne import TAKEOFF_SETTLE_S
from estimator.estimation.autopilot_wind import AutopilotWind
from estimator.estimation.hypotheses import Hypothesis
from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.online_settings import OnlineSettings
from estimator.estimation.track_runner import TrackPoint, track_samples
from estimator.logs import iter_samples
from estimator.physics.effect_tables import effects_to_tables
from estimator.physics.effects import (
    Climb,
    Effect,
    FlightState,
    Mass,
    PowerContext,
    Wind,
    predict_power_w,
    wind_from_vector,
)
from estimator.physics.vehicle import Vehicle, default_vehicle, load_vehicle
from estimator.sim.files import write_tlog
from estimator.sim.plans import Leg, Plan
from estimator.sim.run import SimConfig, SimRun
from estimator.sim.simulator import simulate
from estimator.telemetry.samples import Sample, VelocitySample, WindSample

VEHICLE = default_vehicle()
#: A wind known to 0.2 m/s from the start: in a hover, the wind held there leaves the mass
#: next to nothing unknown (:mod:`estimator.estimation.reported_sigma`), so a test of what
#: the power alone pins is not one of the wind.
KNOWN_WIND = OnlineSettings(initial_wind_sigma_mps=0.2)


def track(tmp_path: Path, plan: str, seed: int, effects: tuple[Effect, ...]) -> list[TrackPoint]:
    duration = 600.0 if plan == "mixed" else None
    run = simulate(SimConfig(plan=plan, duration_s=duration, seed=seed, effects=effects))
    path = write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)
    return track_samples(iter_samples(path), OnlineEffects.from_vehicle(VEHICLE))


def at(points: list[TrackPoint], time_s: float) -> TrackPoint:
    times = np.array([p.time_s for p in points])
    return points[min(int(np.searchsorted(times, time_s)), len(points) - 1)]


def angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize(
    ("plan", "seed", "wind"), [("mixed", 41, Wind(5.0, 60.0)), ("circles", 42, Wind(4.0, 250.0))]
)
def test_wind_is_tracked_online(tmp_path: Path, plan: str, seed: int, wind: Wind) -> None:
    points = track(tmp_path, plan, seed, (wind,))
    for p in (at(points, 200.0), points[-1]):
        assert abs(p.wind_speed_mps - wind.speed_mps) < 1.0
        assert angle_diff_deg(p.wind_from_deg, wind.from_deg) < 20.0
        assert abs(p.mass_delta_kg) < 0.1


def test_mass_and_wind_together_are_tracked(tmp_path: Path) -> None:
    points = track(tmp_path, "mixed", 43, (Wind(6.0, 300.0), Mass(-0.4)))
    final = points[-1]
    assert abs(final.mass_delta_kg + 0.4) < 0.1
    assert final.mass_sigma_kg < 0.1
    assert abs(final.wind_speed_mps - 6.0) < 1.0
    assert angle_diff_deg(final.wind_from_deg, 300.0) < 20.0


def test_payload_picked_up_in_flight_is_followed(tmp_path: Path) -> None:
    points = track(tmp_path, "mixed", 44, (Mass(0.6, at_s=250.0),))
    assert abs(at(points, 240.0).mass_delta_kg) < 0.1
    assert abs(at(points, 330.0).mass_delta_kg - 0.6) < 0.1
    assert abs(points[-1].mass_delta_kg - 0.6) < 0.1


def test_clean_flight_stays_at_no_wind_and_file_mass(tmp_path: Path) -> None:
    # the wind is held in hover (module docstring), so the first legs settle it: after 150 s
    points = track(tmp_path, "mixed", 45, ())
    late = [p for p in points if p.time_s > 150.0]
    assert max(p.wind_speed_mps for p in late) < 1.0
    assert max(abs(p.mass_delta_kg) for p in late) < 0.05


def test_starts_from_the_vehicle_file_and_keeps_other_effects() -> None:
    tables = effects_to_tables([Wind(4.0, 90.0), Mass(0.3), Climb(0.5)])
    vehicle = Vehicle(VEHICLE.name, VEHICLE.mass_kg, VEHICLE.model, VEHICLE.battery, {}, tables)
    tracker = OnlineEffects.from_vehicle(vehicle)
    assert tracker.wind.speed_mps == pytest.approx(4.0)
    assert tracker.wind.from_deg == pytest.approx(90.0)
    assert tracker.mass_delta_kg == pytest.approx(0.3)
    assert tracker.mass_ratio == pytest.approx(3.3 / 3.0)
    names = [e.name for e in tracker.effects]
    assert names == ["wind", "mass", "climb"]


def test_bad_samples_leave_the_estimate_alone() -> None:
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    before = tracker.effects
    assert tracker.update(1.0, math.nan, 0.0, 0.0, 0.0, 0.0, 400.0) == before
    tracker.update(2.0, 5.0, 0.0, 0.0, 0.0, 0.0, 400.0)
    after_good = tracker.effects
    assert tracker.update(1.5, 5.0, 0.0, 0.0, 0.0, 0.0, 400.0) == after_good  # time backwards
    assert tracker.rejected == 2


def test_wind_vector_round_trip() -> None:
    for wind in (Wind(5.0, 60.0), Wind(3.0, 250.0), Wind(0.0, 0.0)):
        wn, we = wind.vector_ne_mps()
        back = wind_from_vector(wn, we)
        assert back.speed_mps == pytest.approx(wind.speed_mps)
        if wind.speed_mps:
            assert angle_diff_deg(back.from_deg, wind.from_deg) < 1e-9


def test_a_covariance_that_lost_positive_definiteness_is_restarted_not_raised() -> None:
    """Damaged logs can drive the UKF covariance indefinite; the tracker restarts it and
    carries on (the daemon never dies on bad input)."""
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    tracker.update(0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 380.0)
    tracker._p = np.diag([1.0, -1.0, 1.0])  # what a run of garbage readings can leave
    tracker.update(0.5, 5.0, 0.0, 0.0, 0.0, 0.0, 380.0)
    assert tracker.resets == 1
    assert math.isfinite(tracker.wind.speed_mps) and math.isfinite(tracker.mass_delta_kg)
    assert np.all(np.linalg.eigvalsh(tracker._p) > 0)


@dataclass(frozen=True)
class WindFrom(Wind):
    """A hidden wind that sets in at ``at_s`` (s on the flight's clock): for the simulator."""

    at_s: float = 0.0

    def adjust(self, ctx: PowerContext) -> None:
        wn, we = self.vector_ne_mps()
        on = (ctx.state.time_s >= self.at_s).astype(float)
        ctx.air_vn_mps = ctx.air_vn_mps - wn * on
        ctx.air_ve_mps = ctx.air_ve_mps - we * on


HOVER_FIRST = Plan(
    "hover-then-legs",
    (
        Leg("hover", duration_s=60.0),
        *(Leg("straight", 10.0, heading_deg=h, duration_s=40.0) for h in (30.0, 120.0, 210.0)),
        *(Leg("straight", 10.0, heading_deg=h, duration_s=40.0) for h in (300.0, 30.0, 120.0)),
        Leg("hover", duration_s=60.0),
    ),
)


def track_plan(
    tmp_path: Path, plan: Plan, effects: tuple[Effect, ...]
) -> tuple[SimRun, list[TrackPoint], OnlineEffects]:
    run = simulate(SimConfig(plan=plan, seed=7, effects=effects))
    path = write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    return run, track_samples(iter_samples(path), tracker), tracker


def hover_reached_s(run: SimRun) -> float:
    return float(run.truth.time_s[np.nonzero(run.truth.alt_m > 19.5)[0][0]])


def test_nothing_is_learnt_on_the_ground_nor_in_the_take_off_climb(tmp_path: Path) -> None:
    run, points, _ = track_plan(tmp_path, HOVER_FIRST, (Mass(1.0),))
    airborne_s = float(run.truth.time_s[np.nonzero(run.truth.alt_m > 1.0)[0][0]])
    assert points[0].time_s >= airborne_s + TAKEOFF_SETTLE_S
    climbing = run.truth.vd_mps[run.truth.at(points[0].time_s)] < -1.0
    assert not climbing


def test_a_payload_carried_from_take_off_is_learnt_within_20_s_of_hover(tmp_path: Path) -> None:
    run, points, _ = track_plan(tmp_path, HOVER_FIRST, (Mass(1.0),))
    hover_s = hover_reached_s(run)
    for p in (at(points, hover_s + 20.0), at(points, hover_s + 45.0)):
        assert abs(p.mass_delta_kg - 1.0) < 0.15
        assert abs(p.wind_speed_mps) < 0.5  # a hover step is mass: the wind is held


def test_a_payload_released_in_hover_is_learnt_within_5_s(tmp_path: Path) -> None:
    release_s = 340.0  # in the last hover
    run, points, tracker = track_plan(
        tmp_path, HOVER_FIRST, (Mass(1.0), Mass(-1.0, at_s=release_s))
    )
    assert run.truth.speed_mps[run.truth.at(release_s)] < 0.5
    assert abs(at(points, release_s - 5.0).mass_delta_kg - 1.0) < 0.15
    assert abs(at(points, release_s + 5.0).mass_delta_kg) < 0.15
    assert tracker.changes >= 1


def test_a_payload_picked_up_in_forward_flight_wins_over_a_wind_change(tmp_path: Path) -> None:
    pickup_s = 150.0  # on the third leg
    _, points, _ = track_plan(tmp_path, HOVER_FIRST, (Mass(0.6, at_s=pickup_s),))
    after = at(points, pickup_s + 30.0)
    assert abs(after.mass_delta_kg - 0.6) < 0.15
    assert after.wind_speed_mps < 1.0


def test_a_wind_setting_in_during_forward_flight_is_detected(tmp_path: Path) -> None:
    onset_s = 150.0
    wind = WindFrom(6.0, 60.0, at_s=onset_s)
    _, points, tracker = track_plan(tmp_path, HOVER_FIRST, (wind,))
    before = at(points, onset_s - 5.0)
    assert before.wind_speed_mps < 1.0
    after = at(points, onset_s + 40.0)
    assert abs(after.wind_speed_mps - 6.0) < 1.5
    assert angle_diff_deg(after.wind_from_deg, 60.0) < 25.0
    assert abs(after.mass_delta_kg) < 0.15
    assert tracker.changes >= 1


def test_the_wind_along_the_track_is_applied_before_the_wind_across_it(tmp_path: Path) -> None:
    """One straight leg into a headwind: the along-track component is identified, the cross
    one is not; the effects to apply carry the former and the vehicle file's value of the
    latter. Flying across afterwards keeps them; only a wind in use that the estimate refutes
    is replaced by the estimate."""
    plan = Plan("one-leg", (Leg("straight", 10.0, heading_deg=90.0, duration_s=120.0),))
    _, _, tracker = track_plan(tmp_path, plan, (Wind(5.0, 90.0),))
    along, across = math.radians(90.0), math.radians(0.0)
    sigma = tracker.sigma
    assert sigma["wind_n_mps"] > 1.0  # across the track: not identified
    effects = tracker.identified_effects(along, 1.0, 0.15)
    assert effects is not None
    applied = next(e for e in effects if isinstance(e, Wind))
    wn, we = applied.vector_ne_mps()
    assert we == pytest.approx(-5.0, abs=1.0)  # the headwind, along the track (east)
    assert wn == pytest.approx(0.0, abs=1e-9)  # across: the vehicle file's (none)
    # flying across it next, the head wind in use stands and the cross component stays unknown
    assert tracker.identified_effects(across, 1.0, 0.0, effects) is None
    # but a wind in use that the estimate refutes (the file's calm) gives way to the estimate
    refuting = tracker.identified_effects(across, 1.0, 0.0)
    assert refuting is not None
    assert next(e for e in refuting if isinstance(e, Wind)).vector_ne_mps()[1] == pytest.approx(
        -5.0, abs=1.0
    )


def with_autopilot_wind(
    samples: list[Sample], wind_ne_mps: tuple[float, float], period_s: float = 1.0
) -> list[Sample]:
    """``samples`` with the autopilot's wind report (air-mass velocity NED, m/s) after the
    first velocity sample of every ``period_s`` of the log's clock (ArduPilot's WIND)."""
    out: list[Sample] = []
    next_s = -math.inf
    for sample in samples:
        out.append(sample)
        if isinstance(sample, VelocitySample) and sample.time_s >= next_s:
            out.append(WindSample(sample.time_s, *wind_ne_mps))
            next_s = sample.time_s + period_s
    return out


ONE_LEG = Plan("one-leg", (Leg("straight", 10.0, heading_deg=90.0, duration_s=120.0),))


def test_the_autopilot_wind_report_identifies_the_wind_across_a_single_leg(
    tmp_path: Path,
) -> None:
    """Power on one straight leg shows only the wind along it; the autopilot's own estimate
    (1 m/s, weighed as one measurement a minute) also settles the one across it."""
    wind = Wind(5.0, 45.0)  # from the north-east: head wind and cross wind on an eastward leg
    run = simulate(SimConfig(plan=ONE_LEG, seed=7, effects=(wind,)))
    samples = list(iter_samples(write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)))
    alone = OnlineEffects.from_vehicle(VEHICLE)
    track_samples(samples, alone)
    aided = OnlineEffects.from_vehicle(VEHICLE)
    track_samples(with_autopilot_wind(samples, wind.vector_ne_mps()), aided)
    assert alone.sigma["wind_n_mps"] > 1.0  # across the track, power alone cannot tell
    assert aided.sigma["wind_n_mps"] < 1.0 and aided.autopilot_wind_steps > 20
    assert abs(aided.wind.speed_mps - 5.0) < 1.0
    assert angle_diff_deg(aided.wind.from_deg, 45.0) < 15.0
    assert abs(aided.mass_delta_kg) < 0.1


def test_an_autopilot_reporting_no_wind_or_stale_or_bad_reports_changes_nothing(
    tmp_path: Path,
) -> None:
    """An autopilot that does not estimate the wind reports exactly zero; a report older than
    ``autopilot_wind_max_age_s`` or not finite is not taken either: the estimate is the one
    from power alone."""
    run = simulate(SimConfig(plan=ONE_LEG, seed=7, effects=(Wind(5.0, 90.0),)))
    samples = list(iter_samples(write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)))
    alone = OnlineEffects.from_vehicle(VEHICLE)
    track_samples(samples, alone)
    stale = [WindSample(-100.0, -5.0, 0.0), *samples]  # reported once, long before the flight
    for variant in (
        with_autopilot_wind(samples, (0.0, 0.0)),
        stale,
        with_autopilot_wind(samples, (math.nan, 1.0)),
    ):
        tracker = OnlineEffects.from_vehicle(VEHICLE)
        track_samples(variant, tracker)
        assert tracker.autopilot_wind_steps == 0
        np.testing.assert_array_equal(tracker._x, alone._x)


def test_a_wind_change_the_autopilot_reports_is_followed_where_power_cannot_show_it(
    tmp_path: Path,
) -> None:
    """In hover the power hardly shows the wind (and the tracker holds it); a wind that the
    autopilot reports setting in there reopens the wind's variance after three steps apart
    and is followed: most of the way in 25 s, within 1 m/s in a minute."""
    onset_s, wind = 120.0, WindFrom(6.0, 60.0, at_s=120.0)
    plan = Plan("hover", (Leg("hover", duration_s=200.0),))
    run = simulate(SimConfig(plan=plan, seed=7, effects=(wind,)))
    samples = list(iter_samples(write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)))
    reports: list[Sample] = []
    for sample in samples:
        reports.append(sample)
        if isinstance(sample, VelocitySample):
            blowing = sample.time_s >= onset_s + 5.0  # the autopilot's estimate lags
            reports.append(
                WindSample(sample.time_s, *(wind.vector_ne_mps() if blowing else (0.2, 0.0)))
            )
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    points = track_samples(reports, tracker)
    assert at(points, onset_s - 5.0).wind_speed_mps < 1.0
    soon, later = at(points, onset_s + 25.0), at(points, onset_s + 60.0)
    assert soon.wind_speed_mps > 4.0  # most of the way: a minute of reports weighs as one
    assert abs(later.wind_speed_mps - 6.0) < 1.0
    for p in (soon, later):
        assert angle_diff_deg(p.wind_from_deg, 60.0) < 15.0
    assert tracker.changes >= 1


def _disagreement(distance2: float) -> float:
    """The probability that the report and the estimate disagree at a squared Mahalanobis
    distance ``distance2``, as the tracker weighs their gap: even odds at χ²₂'s 5 % point."""
    return 1.0 / (1.0 + math.exp(-0.5 * (distance2 - OnlineSettings().autopilot_wind_gap_chi2)))


def test_a_moving_report_widens_the_wind_sigma_by_its_lag_and_a_held_one_by_its_gap() -> None:
    """The autopilot's report lags the wind (a first-order lag: w − r = τ r'): while it moves at
    0.5 m/s² the reported 1σ takes τ × 0.5 m/s more (either way: one magnitude for both
    components); while it holds a wind the estimate does not share (ArduCopter's EKF in a
    hover), its gap, weighed by how likely the two disagree: a quarter of the squared gap
    2 m/s apart, within both their 1σ, seven tenths at 2 m/s each way; neither once the
    report is stale; the estimate itself is unchanged."""
    settings = OnlineSettings()
    reports = AutopilotWind(settings)
    x, p = np.array([1.0, 0.0, 0.0]), np.diag([0.04, 0.04, 0.001])
    var = 0.04 + settings.autopilot_wind_sigma_mps**2  # the innovation's, per component
    for k in range(5):  # still: 1 m/s from the north, reported at 2 Hz
        reports.take(WindSample(0.5 * k, -1.0, 0.0))
    assert reports.lag_mps(2.0) == 0.0
    gap_n, gap_e = reports.gap_ne_mps(x, p, 2.0)  # 2 m/s apart: d² 3.85
    share = _disagreement(4.0 / var)
    assert share == pytest.approx(0.26, abs=0.01)
    assert (gap_n, gap_e) == pytest.approx((-2.0 * math.sqrt(share), 0.0))
    for k in range(1, 9):  # the report's east component grows at 0.5 m/s²
        reports.take(WindSample(2.0 + 0.5 * k, -1.0, 0.25 * k))
    assert reports.lag_mps(6.0) == pytest.approx(settings.autopilot_wind_lag_s * 0.5)
    gap_n, gap_e = reports.gap_ne_mps(x, p, 6.0)  # 2 m/s each way: d² 7.7, beyond χ²₂ at 5 %
    share = _disagreement(8.0 / var)
    assert share == pytest.approx(0.70, abs=0.01)
    assert (gap_n, gap_e) == pytest.approx((-2.0 * math.sqrt(share), 2.0 * math.sqrt(share)))
    assert reports.lag_mps(6.0 + settings.autopilot_wind_max_age_s + 1.0) == 0.0
    assert reports.gap_ne_mps(x, p, 6.0 + settings.autopilot_wind_max_age_s + 1.0) == (0, 0)
    reports.restart()
    assert reports.lag_mps(6.0) == 0.0


def _rising_reports() -> tuple[AutopilotWind, float]:
    """Reports of still air for 2 s, then of an east wind rising at 0.5 m/s² until 6 s (2 Hz);
    and the EKF's time constant τ (s) of the default settings."""
    settings = OnlineSettings()
    reports = AutopilotWind(settings)
    for k in range(5):
        reports.take(WindSample(0.5 * k, 0.0, 0.0))
    for k in range(1, 9):
        reports.take(WindSample(2.0 + 0.5 * k, 0.0, 0.25 * k))
    return reports, settings.autopilot_wind_lag_s


def test_a_report_that_stalls_while_it_follows_a_change_keeps_its_lag_decaying() -> None:
    """The gap a first-order lag leaves closes as e^(−t/τ): a report that rises at 0.5 m/s²
    and then holds still for 3 s (the EKF stalling as it follows a gust) keeps a lag term that
    decays from τ × 0.5 m/s at that pace, not one that drops to zero with its rate."""
    reports, tau_s = _rising_reports()
    assert reports.lag_mps(6.0) == pytest.approx(tau_s * 0.5)
    for k in range(1, 7):  # then still until 9 s: its rate over 2 s falls to zero by 8 s
        reports.take(WindSample(6.0 + 0.5 * k, 0.0, 2.0))
    # decaying from 6 s, the last report the rate over the last 2 s stood at 0.5 m/s²
    assert reports.lag_mps(9.0) == pytest.approx(tau_s * 0.5 * math.exp(-3.0 / tau_s))
    assert reports.lag_mps(9.5) == pytest.approx(tau_s * 0.5 * math.exp(-3.5 / tau_s))


def test_the_reports_first_wind_after_its_zeros_is_no_lag() -> None:
    """An autopilot that does not estimate the wind reports exactly zero; ArduCopter SITL's
    first report at take-off in a 9 m/s wind was 8.5 m/s, a step from those zeros it did not
    follow from any wind: no lag (it was read as 24 m/s, held through the take-off hover). Its
    rising after that is the EKF following, and counts."""
    reports = AutopilotWind(OnlineSettings())
    for k in range(6):
        reports.take(WindSample(0.5 * k, 0.0, 0.0))
    for k in range(6, 10):
        reports.take(WindSample(0.5 * k, 8.5, 0.0))
    assert reports.lag_mps(4.5) == 0.0
    for k in range(10, 14):
        reports.take(WindSample(0.5 * k, 8.5 + 0.25 * (k - 9), 0.0))
    assert reports.lag_mps(6.5) == pytest.approx(OnlineSettings().autopilot_wind_lag_s * 0.5)


def test_the_reports_rate_is_its_last_spans_at_every_report() -> None:
    """The rate is measured over the last ``autopilot_wind_rate_span_s`` at each report, not
    once a span: a report still for 5-6.5 s that then moves 1 m/s in half a second has a lag term
    at once (τ × 1 m/s over 2 s), however many still reports came before it."""
    settings = OnlineSettings()
    for still in (10, 11, 12, 13):
        reports = AutopilotWind(settings)
        times = [0.5 * k for k in range(still)]
        for t in times:
            reports.take(WindSample(t, 3.0, 0.0))
        reports.take(WindSample(times[-1] + 0.5, 4.0, 0.0))
        lag_mps = reports.lag_mps(times[-1] + 0.5)
        assert lag_mps == pytest.approx(settings.autopilot_wind_lag_s * 1.0 / 2.0)


def test_a_report_held_in_a_hover_keeps_its_lag_until_the_vehicle_moves() -> None:
    """ArduCopter's EKF holds its wind in a hover: a report that rose at 0.5 m/s² as a hover
    began, then held still, keeps its lag term of τ × 0.5 m/s for as long as the vehicle
    hovers, and it decays at the lag's pace once the vehicle moves again."""
    reports, tau_s = _rising_reports()
    reports.hovering = True
    for k in range(1, 41):  # held still through a 20 s hover
        reports.take(WindSample(6.0 + 0.5 * k, 0.0, 2.0))
    assert reports.lag_mps(26.0) == pytest.approx(tau_s * 0.5)
    reports.hovering = False
    for k in range(1, 5):
        reports.take(WindSample(26.0 + 0.5 * k, 0.0, 2.0))
    assert reports.lag_mps(28.0) == pytest.approx(tau_s * 0.5 * math.exp(-2.0 / tau_s))


def test_the_trackers_reported_wind_sigma_takes_in_the_reports_lag(tmp_path: Path) -> None:
    """Through the tracker: the same flight with a report that is still and with one that moves
    at the end has the same estimate, and a wider wind 1σ with the moving one: both
    components by the report's lag (τ × 0.5 m/s, whichever way the wind went; the north 1σ
    exactly so, within 0.1 %), the east, the way it moves, by its gap to the estimate too
    (weighed by how likely they disagree; all but east)."""
    run = simulate(SimConfig(plan=ONE_LEG, seed=7, effects=(Wind(5.0, 90.0),)))
    samples = list(iter_samples(write_tlog(run, tmp_path / "flight.tlog", truth_csv=False)))
    still = OnlineEffects.from_vehicle(VEHICLE)
    track_samples(with_autopilot_wind(samples, (0.0, -5.0)), still)
    moving = OnlineEffects.from_vehicle(VEHICLE)
    track_samples(with_autopilot_wind(samples, (0.0, -5.0)), moving)
    end_s = moving._time_s or 0.0
    moving.take_autopilot_wind(WindSample(end_s - 2.0, 0.0, -5.0))
    moving.take_autopilot_wind(WindSample(end_s, 0.0, -6.0))
    np.testing.assert_array_equal(moving._x, still._x)
    lag_mps = OnlineSettings().autopilot_wind_lag_s * 0.5
    assert moving.sigma["wind_n_mps"] == pytest.approx(
        math.hypot(still.sigma["wind_n_mps"], lag_mps), rel=1e-3
    )
    gap_e_var = moving.sigma["wind_e_mps"] ** 2 - still.sigma["wind_e_mps"] ** 2 - lag_mps**2
    assert gap_e_var > 0.2**2  # the moved report is further from the estimate


def test_a_vehicle_file_states_its_slow_model_error_within_bounds(tmp_path: Path) -> None:
    """``[model] slow_error_fraction`` is read, written back, and bounded (hostile input)."""
    doc = (Path(__file__).resolve().parent.parent / "config/vehicles/dji_m100_cmu.toml").read_text()
    path = tmp_path / "v.toml"
    path.write_text(doc)
    vehicle = load_vehicle(path)
    assert vehicle.slow_error_fraction == 0.05
    assert vehicle.to_toml()["model"]["slow_error_fraction"] == 0.05
    for bad in ("0.9", "-0.01", '"5 %"', "nan"):
        path.write_text(doc.replace("slow_error_fraction = 0.05", f"slow_error_fraction = {bad}"))
        with pytest.raises(UserError, match="slow_error_fraction"):
            load_vehicle(path)


def test_the_slow_model_error_keeps_a_biased_hover_from_pinning_the_mass() -> None:
    """A model 30 W short in hover for a minute, the wind known (so the wind held there
    leaves the mass next to nothing unknown): taken as white noise the mass is pinned to
    the bias within a few hundredths of a kilogram; with a slow error of 5 % of the hover
    power the mass σ stays wide enough to cover the truth (no payload)."""
    hover_w = VEHICLE.model.hover_power_w
    settings = KNOWN_WIND
    ends = {}
    for fraction in (0.0, 0.05):
        tracker = OnlineEffects(
            VEHICLE.model, VEHICLE.mass_kg, settings=settings, slow_error_fraction=fraction
        )
        for k in range(60):
            tracker.update(2.0 * k, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w + 30.0)
        ends[fraction] = abs(tracker.mass_delta_kg) / tracker.sigma["mass_kg"]
    assert ends[0.0] > 5.0
    assert ends[0.05] < 3.0


def test_an_undecided_duel_is_reported_as_the_mixture_of_its_two_hypotheses() -> None:
    """After a change in forward flight the mass-step and wind-change hypotheses run side by
    side; until one is clearly likelier, what the tracker reports and applies spans both."""
    tracker = OnlineEffects.from_vehicle(VEHICLE)
    tracker.update(0.0, 5.0, 0.0, 0.0, 0.0, 0.0, 380.0)
    own_x, own_p = tracker._x.copy(), tracker._p.copy()
    alone = tracker.sigma["mass_kg"]
    rival_x = own_x + np.array([2.0, 0.0, -0.4])
    tracker._rival = Hypothesis(rival_x, own_p, tracker._form, tracker._loglik)
    assert tracker.mass_delta_kg == pytest.approx(own_x[2] - 0.2)
    assert tracker.wind.vector_ne_mps()[0] == pytest.approx(own_x[0] + 1.0)
    assert tracker.sigma["mass_kg"] == pytest.approx(math.hypot(alone, 0.2), rel=0.05)
    undecided = tracker.identified_effects(0.0, 10.0, 0.1)
    assert undecided is not None and undecided[1] == Mass(0.0)  # the file's mass stays
    tracker._loglik += 20.0  # the estimate's hypothesis far likelier: it alone is reported
    assert tracker.mass_delta_kg == pytest.approx(own_x[2])
    assert tracker.sigma["mass_kg"] == pytest.approx(alone)


def test_a_report_that_stays_apart_at_chi2_1_percent_for_three_steps_is_a_change() -> None:
    """A wind that stopped: the report at 0 for three steps, the estimate still at 3.5 m/s
    with a 1σ of 0.5 m/s (squared distance 9.8 with the report's 1 m/s, between χ²₂ at 1 %
    and at 0.1 %): the third step is a change the autopilot saw; a report 2 m/s apart is
    not (3.2)."""
    watcher = AutopilotWind(OnlineSettings())
    watcher.take(WindSample(10.0, 0.0, 0.0))
    p = np.diag([0.25, 0.25, 0.01])
    near = np.array([0.0, 2.0, 0.0])
    assert not any(watcher.saw_a_change(near, p) for _ in range(5))
    stale = np.array([0.0, 3.5, 0.0])
    assert [watcher.saw_a_change(stale, p) for _ in range(3)] == [False, False, True]


def test_the_step_after_an_alarm_whose_readings_straddled_the_change_completes_it() -> None:
    """A 2 kg payload picked up in hover in the middle of a step: that step's power is half
    way, the alarm's redo leaves the mass half way with the 1σ of a settled one, and the next
    step, beyond the gate of that estimate, is the rest of the change, not an outlier."""
    tracker = OnlineEffects.from_vehicle(VEHICLE)

    def hover_w(mass_kg: float) -> float:
        state = FlightState(*(np.zeros(1) for _ in range(7)), voltage_v=np.full(1, np.nan))
        return float(predict_power_w(VEHICLE.model, VEHICLE.mass_kg, state, [Mass(mass_kg)])[0])

    before_w, after_w = hover_w(0.0), hover_w(2.0)
    for k in range(20):
        tracker.update(2.0 * k, 0.0, 0.0, 0.0, 0.0, 0.0, before_w)
    tracker.update(40.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5 * (before_w + after_w))
    assert tracker.changes == 1 and 0.5 < tracker.mass_delta_kg < 1.5
    tracker.update(42.0, 0.0, 0.0, 0.0, 0.0, 0.0, after_w)
    assert abs(tracker.mass_delta_kg - 2.0) < 0.15
    assert tracker.changes == 1  # the same change


def test_a_step_that_did_not_settle_the_estimate_is_reported_with_a_changed_states_sigma() -> None:
    """A settled hover, then one step 60 W short: beyond the gate (not taken) and below the
    change alarm. An outlier or the start of a change (a payload released): the estimate stays,
    but its reported 1σ is a changed state's until the next step tells which. Held at the
    settled 1σ, a release read the carried payload at 18σ for that step (ArduCopter SITL,
    release_wind2). The next step back at the hover power: an outlier, the settled 1σ again.
    Still short: the alarm, the mass follows the drop from that step's readings alone (which
    may straddle the change) and its 1σ stays a changed state's for that step and the next
    (which reads the power still settling: held at the settled 1σ, a release in a hover read
    0.16 kg heavy at 3.6σ there, ArduCopter SITL held13_stop_then_release); a fourth step
    settles it."""
    hover_w = VEHICLE.model.hover_power_w
    initial_kg = OnlineSettings().initial_mass_sigma_fraction * VEHICLE.mass_kg
    for after_w, outlier in ((hover_w, True), (hover_w - 60.0, False)):
        tracker = OnlineEffects.from_vehicle(VEHICLE, settings=KNOWN_WIND)
        for k in range(20):
            tracker.update(2.0 * k, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w)
        settled, mass_kg = tracker.sigma, tracker.mass_delta_kg
        tracker.update(40.0, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w - 60.0)
        assert (tracker.rejected, tracker.changes) == (1, 0)
        assert tracker.mass_delta_kg == mass_kg
        assert tracker.sigma["mass_kg"] >= initial_kg > 10 * settled["mass_kg"]
        assert tracker.sigma["wind_n_mps"] >= KNOWN_WIND.initial_wind_sigma_mps
        tracker.update(42.0, 0.0, 0.0, 0.0, 0.0, 0.0, after_w)
        if outlier:
            assert tracker.changes == 0
            assert tracker.sigma["mass_kg"] == pytest.approx(settled["mass_kg"], rel=0.1)
            continue
        assert tracker.changes == 1
        assert tracker.mass_delta_kg < mass_kg - 0.2
        assert tracker.sigma["mass_kg"] >= initial_kg
        tracker.update(44.0, 0.0, 0.0, 0.0, 0.0, 0.0, after_w)
        assert tracker.sigma["mass_kg"] >= initial_kg
        tracker.update(46.0, 0.0, 0.0, 0.0, 0.0, 0.0, after_w)
        assert tracker.sigma["mass_kg"] < 0.5 * initial_kg


def test_innovations_leaning_towards_a_change_are_reported_with_a_changed_states_sigma() -> None:
    """A settled hover, then a step 50 W short: inside the gate (taken) and below the change
    alarm, but the CUSUM's sum grows past half its threshold: a change may be under way, and
    the filter follows one only at its random walk's pace, so the step reports a changed
    state's 1σ (held at the settled one, a release read half way was 9.2σ off for a step:
    ArduCopter SITL, held10_release_after_stop). Back at the hover power the sum falls: the
    settled 1σ again. A step 25 W short then grows it past half way again."""
    hover_w = VEHICLE.model.hover_power_w
    initial_kg = OnlineSettings().initial_mass_sigma_fraction * VEHICLE.mass_kg
    tracker = OnlineEffects.from_vehicle(VEHICLE, settings=KNOWN_WIND)
    for k in range(20):
        tracker.update(2.0 * k, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w)
    settled_kg, mass_kg = tracker.sigma["mass_kg"], tracker.mass_delta_kg
    tracker.update(40.0, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w - 50.0)
    assert (tracker.rejected, tracker.changes) == (0, 0)
    assert tracker.mass_delta_kg < mass_kg  # taken
    assert tracker.sigma["mass_kg"] >= initial_kg > 10 * settled_kg
    tracker.update(42.0, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w)
    assert tracker.sigma["mass_kg"] == pytest.approx(settled_kg, rel=0.1)
    tracker.update(44.0, 0.0, 0.0, 0.0, 0.0, 0.0, hover_w - 25.0)
    assert (tracker.rejected, tracker.changes) == (0, 0)
    assert tracker.sigma["mass_kg"] >= initial_kg
