"""Acceptance: a simulated flight that hovers, then cruises until the reserve.

The simulator (``estimator.sim.simulator``) flies with effects the estimator is not told about
(wind,
an avionics load), a LiPo pack with internal resistance (the voltage sags, the current rises
at constant power) and sensor noise. The pipeline sees only the MAVLink stream. Endurance
10 s, 30 s and 2 min after the hover→cruise change must be within 3 % of the true time left;
the PX4-style estimate (remaining charge / 50 s average current) is computed on the same
stream for comparison (figures in docs/daemon.md).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from estimator.estimation.estimate import Estimate
from estimator.estimation.pack_state import OWN_CURVE_SIGMA_V, PackSettings
from estimator.estimation.pipeline import Pipeline, PipelineSettings
from estimator.physics.battery import CHEMISTRY_OCV_V, SOC_POINTS
from estimator.physics.effects import Avionics, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.plans import builtin_plan
from estimator.sim.run import SensorNoise, SimConfig, SimRun
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import BatterySample

ROOT = Path(__file__).resolve().parent.parent
CHECK_AFTER_CHANGE_S = (10.0, 30.0, 120.0)
#: Drawn flights of the calibration ensemble.
ENSEMBLE_FLIGHTS = 12
PX4_AVERAGE_S = 50.0


@dataclass
class Flown:
    run: SimRun
    estimates: list[Estimate]
    px4: list[tuple[float, float]]  # (time_s, PX4-style endurance s)
    change_s: float

    def estimate_at(self, time_s: float) -> Estimate:
        times = [e.time_s for e in self.estimates]
        return self.estimates[int(np.searchsorted(times, time_s))]

    def px4_at(self, time_s: float) -> float:
        times = [t for t, _ in self.px4]
        return self.px4[int(np.searchsorted(times, time_s))][1]

    def truth_left_s(self, time_s: float) -> float:
        return float(self.run.truth.time_to_reserve_s[self.run.truth.at(time_s)])


def px4_style_endurance_s(
    samples: list[BatterySample], capacity_ah: float, reserve_fraction: float, initial_soc: float
) -> list[tuple[float, float]]:
    """Remaining charge above the reserve (from the consumed-charge counter and a known
    initial SoC) divided by the current averaged over the last 50 s."""
    out = []
    window: list[tuple[float, float]] = []
    for s in samples:
        if s.current_a is None or s.consumed_mah is None:
            continue
        window.append((s.time_s, s.current_a))
        window = [(t, i) for t, i in window if t > s.time_s - PX4_AVERAGE_S]
        mean_a = float(np.mean([i for _, i in window]))
        soc = initial_soc - s.consumed_mah / 1000.0 / capacity_ah
        remaining_ah = max(soc - reserve_fraction, 0.0) * capacity_ah
        out.append((s.time_s, 3600.0 * remaining_ah / mean_a if mean_a > 0.5 else np.inf))
    return out


def fly(config: SimConfig, settings: PipelineSettings | None = None) -> Flown:
    run = simulate(config)
    decoder = TelemetryDecoder()
    pipeline = Pipeline(config.vehicle, settings)
    estimates, battery = [], []
    for _, msg in run.messages:
        for sample in decoder.decode(msg):
            if isinstance(sample, BatterySample):
                battery.append(sample)
            estimate = pipeline.process(sample)
            if estimate is not None:
                estimates.append(estimate)
    truth = run.truth
    moving = np.nonzero((truth.speed_mps > 0.5) & truth.flying & (truth.alt_m > 15.0))[0]
    spec = config.vehicle.battery
    px4 = px4_style_endurance_s(
        battery, spec.capacity_ah, spec.reserve_fraction, config.initial_soc
    )
    return Flown(run, estimates, px4, float(truth.time_s[moving[0]]))


HIDDEN = (Wind(speed_mps=3.0, from_deg=200.0), Avionics(power_w=15.0))


@pytest.fixture(scope="module", params=[10.0, 14.0], ids=["cruise10", "cruise14"])
def hover_cruise(request: pytest.FixtureRequest) -> Flown:
    """The built-in hover-cruise plan (60 s hover, then cruise to the reserve) with hidden
    wind and avionics load, cruising at 10 m/s (below hover power) or 14 m/s (above)."""
    plan = builtin_plan("hover-cruise", cruise_speed_mps=request.param)
    return fly(SimConfig(plan=plan, effects=HIDDEN, seed=0))


@pytest.mark.slow
@pytest.mark.parametrize("after_s", CHECK_AFTER_CHANGE_S)
def test_endurance_after_hover_to_cruise_is_within_3_percent(
    hover_cruise: Flown, after_s: float
) -> None:
    t = hover_cruise.change_s + after_s
    estimate = hover_cruise.estimate_at(t)
    truth_s = hover_cruise.truth_left_s(estimate.time_s)
    assert not estimate.model_only and not estimate.stale
    assert abs(estimate.endurance_s - truth_s) <= 0.03 * truth_s


@pytest.mark.slow
@pytest.mark.parametrize("after_s", (10.0, 30.0))
def test_state_aware_estimate_beats_px4_style_average_right_after_the_change(
    hover_cruise: Flown, after_s: float
) -> None:
    t = hover_cruise.change_s + after_s
    estimate = hover_cruise.estimate_at(t)
    truth_s = hover_cruise.truth_left_s(estimate.time_s)
    px4_error = abs(hover_cruise.px4_at(t) - truth_s)
    assert abs(estimate.endurance_s - truth_s) < px4_error


@pytest.mark.slow
def test_energy_estimate_tracks_the_truth_within_its_sigma(hover_cruise: Flown) -> None:
    truth = hover_cruise.run.truth
    for estimate in hover_cruise.estimates[:: len(hover_cruise.estimates) // 40]:
        true_wh = float(truth.energy_remaining_wh[truth.at(estimate.time_s)])
        assert abs(estimate.energy_remaining_wh - true_wh) <= 2 * estimate.energy_remaining_sigma_wh


def coverage(flown: Flown) -> np.ndarray:
    """|error| / σ of the endurance every 20 s of the cruise."""
    run = flown.run
    z = []
    for t in np.arange(flown.change_s + 10.0, run.reserve_time_s - 60.0, 20.0):
        e = flown.estimate_at(float(t))
        z.append(abs(e.endurance_s - flown.truth_left_s(e.time_s)) / e.endurance_sigma_s)
    return np.array(z)


def report() -> None:
    """Print the tables of docs/daemon.md: ``python tests/test_endurance_acceptance.py``."""
    flown = fly(SimConfig(plan="hover-cruise", effects=HIDDEN, seed=0))
    table(flown, "built-in hover-cruise (10 m/s), wind 3 m/s, avionics 15 W")
    z = coverage(flown)
    print(
        f"default settings: {np.mean(z <= 1):.0%} within 1σ, {np.mean(z <= 3):.0%} within 3σ "
        f"(n = {len(z)}), mean |error|/σ {np.mean(z):.2f}"
    )
    fast = builtin_plan("hover-cruise", cruise_speed_mps=14.0)
    table(fly(SimConfig(plan=fast, effects=HIDDEN, seed=0)), "hover-cruise at 14 m/s, same")
    ensemble()


def curve_error_v(
    rng: np.random.Generator, sigma_v: float = OWN_CURVE_SIGMA_V
) -> tuple[float, ...]:
    """A pack's resting curve minus the one its vehicle file gives (V per cell at each table
    point): a Gauss–Markov walk over the state of charge, 1σ ``sigma_v``, decorrelating over
    0.1 of charge — the error the estimator's default settings assume of a pack's own curve."""
    phi = float(np.exp(-np.diff(SOC_POINTS)[0] / PackSettings().ocv_curve_correlation_soc))
    error = [float(rng.normal(0.0, sigma_v))]
    for _ in SOC_POINTS[1:]:
        error.append(phi * error[-1] + float(rng.normal(0.0, sigma_v * np.sqrt(1 - phi * phi))))
    return tuple(error)


#: The built-in vehicle with its pack's curve given as its own (the simulator's): the capacity
#: is learnt in flight against it (against a chemistry's typical curve the label is trusted).
OWN_CURVE_VEHICLE = replace(
    default_vehicle(),
    battery=replace(
        default_vehicle().battery, cell_ocv_v=tuple(float(v) for v in CHEMISTRY_OCV_V["lipo"])
    ),
)


def ensemble_configs(flights: int) -> list[SimConfig]:
    """Hover→cruise flights to the reserve with drawn packs and conditions (seeded: always
    the same flights): real capacity U(60, 105) % of the label, start SoC U(0.5, 1), resting
    curve off the vehicle file's (:func:`curve_error_v`), current-sensor gain N(1, 1 %),
    pack resistance U(15, 40) mΩ, wind U(0, 6) m/s from any direction, avionics U(0, 30) W,
    cruise U(6, 14) m/s."""
    rng = np.random.default_rng(2026)
    configs = []
    for k in range(flights):
        plan = builtin_plan("hover-cruise", cruise_speed_mps=float(rng.uniform(6.0, 14.0)))
        configs.append(
            SimConfig(
                vehicle=OWN_CURVE_VEHICLE,
                plan=plan,
                effects=(
                    Wind(speed_mps=float(rng.uniform(0, 6)), from_deg=float(rng.uniform(0, 360))),
                    Avionics(power_w=float(rng.uniform(0, 30))),
                ),
                internal_resistance_ohm=float(rng.uniform(0.015, 0.04)),
                initial_soc=float(rng.uniform(0.5, 1.0)),
                capacity_fraction=float(rng.uniform(0.6, 1.05)),
                ocv_error_v_per_cell=curve_error_v(rng),
                noise=SensorNoise(current_scale=float(rng.normal(1.0, 0.01))),
                seed=k,
            )
        )
    return configs


@dataclass
class EnsembleErrors:
    """Endurance every 20 s of each cruise until 60 s before the reserve: |error|/σ (z),
    and the relative errors of ours and of the PX4-style estimate, per flight."""

    z: np.ndarray
    ours: list[np.ndarray]
    px4: list[np.ndarray]


def ensemble_errors(configs: list[SimConfig]) -> EnsembleErrors:
    z: list[float] = []
    ours, px4 = [], []
    for config in configs:
        flown = fly(config)
        errors, px4_errors = [], []
        end_s = flown.run.reserve_time_s - 60.0
        for t in np.arange(flown.change_s + 10.0, end_s, 20.0):
            e = flown.estimate_at(float(t))
            truth_s = flown.truth_left_s(e.time_s)
            sigma_s = e.endurance_sigma_s
            z.append(abs(e.endurance_s - truth_s) / sigma_s if sigma_s > 0 else np.inf)
            errors.append((e.endurance_s - truth_s) / truth_s)
            px4_errors.append((flown.px4_at(float(t)) - truth_s) / truth_s)
        ours.append(np.array(errors))
        px4.append(np.array(px4_errors))
    return EnsembleErrors(np.array(z), ours, px4)


@pytest.fixture(scope="module")
def drawn() -> EnsembleErrors:
    """The drawn flights' errors (module-scoped: one ensemble for both coverage tests)."""
    return ensemble_errors(ensemble_configs(ENSEMBLE_FLIGHTS))


@pytest.mark.slow
def test_one_sigma_holds_55_to_80_percent_on_drawn_packs(drawn: EnsembleErrors) -> None:
    """Pooled over drawn packs (aged, mislabelled, part-charged, their curve a little off) on
    the default settings, the true endurance is inside ±1σ for 55–80 % of the estimates (57.6 %
    measured): σ neither too narrow nor too wide."""
    assert len(drawn.z) > 100
    assert 0.55 <= np.mean(drawn.z <= 1.0) <= 0.80


@pytest.mark.slow
def test_three_sigma_holds_97_percent_on_drawn_packs(drawn: EnsembleErrors) -> None:
    assert np.mean(drawn.z <= 3.0) >= 0.97


@pytest.mark.slow
def test_the_docs_give_the_ensemble_as_measured(drawn: EnsembleErrors) -> None:
    """The ensemble's coverage and median error in README.md, docs/pack.md and
    docs/daemon.md are what this ensemble measures: a figure that drifts fails here."""
    one, three = np.mean(drawn.z <= 1.0), np.mean(drawn.z <= 3.0)
    median = np.median(100 * np.abs(np.concatenate(drawn.ours)))
    docs = {name: (ROOT / name).read_text() for name in ("README.md", "docs/pack.md")}
    docs["docs/daemon.md"] = (ROOT / "docs" / "daemon.md").read_text()
    for name, text in docs.items():
        flat = " ".join(text.split())
        assert f"{100 * one:.1f} %" in flat and f"{100 * three:.1f} %" in flat, name
        assert f"{median:.2f} %" in flat, name


def ensemble(flights: int = ENSEMBLE_FLIGHTS) -> None:
    """Print coverage and error figures over ``flights`` drawn flights (docs/daemon.md)."""
    result = ensemble_errors(ensemble_configs(flights))
    for name, per_flight in (("uav-energy", result.ours), ("PX4-style", result.px4)):
        arr = 100 * np.abs(np.concatenate(per_flight))
        print(
            f"  {name:10s}: |error| median {np.median(arr):.2f} %, max {arr.max():.2f} %, "
            f"within 3 %: {np.mean(arr <= 3):.0%} (n = {len(arr)})"
        )
    z = result.z
    print(
        f"ensemble of {flights} drawn packs, default settings: {np.mean(z <= 1):.1%} within "
        f"1σ, {np.mean(z <= 3):.1%} within 3σ (n = {len(z)}), mean |error|/σ {np.mean(z):.2f}"
    )


def _signed_pct(fraction: float) -> str:
    return f"{100 * fraction:+.2f} %".replace("-", "−")


def _after_label(after_s: float) -> str:
    return f"{after_s:.0f} s" if after_s < 120 else f"{after_s / 60:.0f} min"


def table_rows(flown: Flown) -> list[str]:
    """The rows of a docs/daemon.md table: truth, ours ± 1σ and PX4-style after the change."""
    rows = []
    for after_s in (*CHECK_AFTER_CHANGE_S, 300.0, 600.0, 1200.0):
        t = flown.change_s + after_s
        e = flown.estimate_at(t)
        truth_s = flown.truth_left_s(e.time_s)
        px4_s = flown.px4_at(t)
        rows.append(
            f"| {_after_label(after_s)} | {truth_s:.0f} | {e.endurance_s:.0f} ± "
            f"{e.endurance_sigma_s:.0f} | {_signed_pct((e.endurance_s - truth_s) / truth_s)} "
            f"| {px4_s:.0f} | {_signed_pct((px4_s - truth_s) / truth_s)} |"
        )
    return rows


def table(flown: Flown, title: str) -> None:
    print(title)
    print(
        f"hover→cruise at {flown.change_s:.1f} s, "
        f"reserve reached at {flown.run.reserve_time_s:.1f} s"
    )
    print("| after change | truth s | estimate ± 1σ s | error | PX4-style s | error |")
    print("|---:|---:|---:|---:|---:|---:|")
    print("\n".join(table_rows(flown)))


@pytest.mark.slow
def test_the_docs_give_the_hover_cruise_tables_as_measured(hover_cruise: Flown) -> None:
    """docs/daemon.md's tables and the README's summary come from this flight: a figure
    that drifts fails here."""
    doc = (ROOT / "docs" / "daemon.md").read_text()
    rows = table_rows(hover_cruise)
    for row in rows:
        assert row in doc, row
    cells = [row.strip("| ").split(" | ") for row in rows[:3]]
    ours = " / ".join(c[3].removesuffix(" %") for c in cells)
    px4 = " / ".join(c[5].removesuffix(" %") for c in cells)
    assert f"| +10 s / +30 s / +2 min | {ours} % | {px4} % |" in (ROOT / "README.md").read_text()


if __name__ == "__main__":
    report()
