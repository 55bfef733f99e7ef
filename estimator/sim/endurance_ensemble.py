"""Simulated flights to the pack's reserve, each replayed through the daemon's pipeline as
its MAVLink stream decodes, with a PX4-style endurance beside (charge left over the 50 s mean
current): the hover→cruise acceptance flights and the ensemble of drawn packs that calibrates
the endurance's σ (``tests/test_endurance_acceptance.py``; figures in docs/pack.md,
docs/daemon.md and README.md). Times in s, errors relative to the true time left.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from estimator.estimation.estimate import Estimate
from estimator.estimation.pack_state import OWN_CURVE_SIGMA_V, PackSettings
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.physics.battery import CHEMISTRY_OCV_V, SOC_POINTS
from estimator.physics.effects import Avionics, Wind
from estimator.physics.vehicle import default_vehicle
from estimator.sim.plans import builtin_plan
from estimator.sim.run import SensorNoise, SimConfig, SimRun
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.samples import BatterySample

#: Drawn flights of the calibration ensemble.
ENSEMBLE_FLIGHTS = 12
#: What the acceptance flights hide from the estimator: a wind and an avionics load.
HIDDEN = (Wind(speed_mps=3.0, from_deg=200.0), Avionics(power_w=15.0))
#: When after the hover→cruise change the acceptance tests judge the endurance (s), and the
#: later times docs/daemon.md's tables add.
CHECK_AFTER_CHANGE_S = (10.0, 30.0, 120.0)
TABLE_AFTER_CHANGE_S = (*CHECK_AFTER_CHANGE_S, 300.0, 600.0, 1200.0)
#: The PX4-style estimate's current average, s.
PX4_AVERAGE_S = 50.0


@dataclass
class Flown:
    """A simulated flight: the run (with its truth), the pipeline's estimates, the PX4-style
    endurance ((time s, endurance s) per battery reading) and when the cruise began (s)."""

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
    """Simulate ``config`` and replay its MAVLink stream through the pipeline."""
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
    """Each flight of ``configs`` flown (:func:`fly`) and scored every 20 s of its cruise."""
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


def hover_cruise_config(cruise_speed_mps: float) -> SimConfig:
    """The built-in hover-cruise plan (60 s hover, then cruise to the reserve) with
    :data:`HIDDEN` effects, cruising at ``cruise_speed_mps`` (seed 0)."""
    plan = builtin_plan("hover-cruise", cruise_speed_mps=cruise_speed_mps)
    return SimConfig(plan=plan, effects=HIDDEN, seed=0)


def hover_cruise(cruise_speed_mps: float) -> Flown:
    """:func:`hover_cruise_config` flown."""
    return fly(hover_cruise_config(cruise_speed_mps))


def signed_pct(fraction: float) -> str:
    """``fraction`` as a signed percentage with a typographic minus (``−0.47 %``)."""
    return f"{100 * fraction:+.2f} %".replace("-", "−")


def _after_label(after_s: float) -> str:
    return f"{after_s:.0f} s" if after_s < 120 else f"{after_s / 60:.0f} min"


def figures_after_change(flown: Flown, after_s: float) -> tuple[Estimate, float, float]:
    """The estimate ``after_s`` after the change, the true time left then (s) and the
    PX4-style endurance (s)."""
    t = flown.change_s + after_s
    estimate = flown.estimate_at(t)
    return estimate, flown.truth_left_s(estimate.time_s), flown.px4_at(t)


def table_rows(flown: Flown) -> list[str]:
    """docs/daemon.md's table of ``flown``: truth, ours ± 1σ and PX4-style after the change
    (markdown rows)."""
    rows = []
    for after_s in TABLE_AFTER_CHANGE_S:
        e, truth_s, px4_s = figures_after_change(flown, after_s)
        rows.append(
            f"| {_after_label(after_s)} | {truth_s:.0f} | {e.endurance_s:.0f} ± "
            f"{e.endurance_sigma_s:.0f} | {signed_pct((e.endurance_s - truth_s) / truth_s)} "
            f"| {px4_s:.0f} | {signed_pct((px4_s - truth_s) / truth_s)} |"
        )
    return rows
