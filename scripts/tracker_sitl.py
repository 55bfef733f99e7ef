"""The daemon's online tracker on the ArduCopter SITL recordings, against their truth: the
running wind and mass and their 1σ after each tracker step, from take-off to landing.

Each recording of SITL's stock quad in ``replay/sitl/`` (the scenarios and the AUTO missions
of ``replay/sitl/missions/``; vehicle ``config/vehicles/ardupilot_sitl_quad.toml``) goes
through the pipeline as the daemon runs it (:func:`track_samples`); each step is compared with
the truth at its time (``truth.json``, :mod:`estimator.analysis.sitl_truth`): SITL's wind as
the air mass's velocity over ground, the gripper payload while held. Wind as in
``scripts/tracker_cmu.py``: both components within kσ of their own 1σ.

Prints the block ``tracker-sitl`` of docs/residuals.md, which ``make figures`` writes and
``tests/test_tracker_sitl.py`` checks (with ``tracker-sitl-shows``, the sentence that reads
it, and ``tracker-sitl-slow-2pct``). ``--slow-error-fraction F``: the same with the vehicle
file's ``[model] slow_error_fraction`` (none stated: the model's errors taken as white) set to
F, what the tracker would do told that the model's error stays correlated.

Run: ``python scripts/tracker_sitl.py [RECORDINGS] [--slow-error-fraction F]`` (default
replay/sitl).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from estimator.analysis.sitl_truth import RecordingTruth, load_truth
from estimator.analysis.tracker_truth import TrackerRun, track_samples
from estimator.errors import UserError
from estimator.logs import iter_samples
from estimator.physics.vehicle import SLOW_ERROR_RANGE, Vehicle, load_vehicle
from estimator.telemetry.samples import GripperSample

ROOT = Path(__file__).resolve().parent.parent
VEHICLE = ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
RECORDINGS = ROOT / "replay" / "sitl"
#: Evidence (nats) for the truth over the estimate below which the readings did not tell
#: them apart (e² ≈ 7 times likelier), and the autopilot's wind report's distance (m/s) from
#: the true wind beyond which it did not either: :func:`blind_steps`.
BLIND_NATS = 2.0
REPORT_OFF_MPS = 2.0
#: The recordings ``config/vehicles/ardupilot_sitl_quad.toml`` was fitted on (its header).
FITTED_ON = ("clean_circles", "clean_legs", "clean_mission")


def folders(recordings: Path = RECORDINGS) -> list[Path]:
    """The recordings' folders: the scenarios, then the missions."""
    return sorted(p.parent for p in recordings.glob("*/truth.json")) + sorted(
        p.parent for p in recordings.glob("missions/*/truth.json")
    )


def track_recording(
    folder: Path, vehicle: Vehicle, truth: RecordingTruth
) -> tuple[RecordingTruth, TrackerRun]:
    """``folder/flight.tlog`` through the pipeline, its steps from take-off to landing, against
    ``truth`` with the gripper releases the autopilot reported in the log (that truth, and the
    steps)."""
    samples = list(iter_samples(folder / "flight.tlog", "auto", vehicle.input_limits()))
    releases = [s.time_s for s in samples if isinstance(s, GripperSample) and s.released]
    truth = truth.released_at(releases)

    def truth_at(time_s: float) -> tuple[float, float, float]:
        wind_n, wind_e = truth.wind_ne_mps(time_s)
        return float(wind_n), float(wind_e), truth.mass_delta_kg(time_s)

    span_s = (truth.takeoff_s, truth.landed_s)
    return truth, track_samples(truth.scenario, samples, vehicle, truth_at, span_s)


def runs(
    recordings: Path = RECORDINGS, slow_error_fraction: float | None = None
) -> list[tuple[RecordingTruth, TrackerRun]]:
    """Every stock-quad recording of ``recordings`` with its tracker steps (with the vehicle
    file's slow model error, or ``slow_error_fraction`` when given)."""
    vehicle = load_vehicle(VEHICLE)
    if slow_error_fraction is not None:
        low, high = SLOW_ERROR_RANGE
        if not low <= slow_error_fraction <= high:
            raise UserError(f"--slow-error-fraction must be between {low:g} and {high:g}")
        vehicle = replace(vehicle, slow_error_fraction=slow_error_fraction)
    out = []
    for folder in folders(recordings):
        truth = load_truth(folder / "truth.json", vehicle.mass_kg)
        if truth.stock_quad:
            out.append(track_recording(folder, vehicle, truth))
    if not out:
        raise UserError(f"no recording of SITL's stock quad under {recordings}")
    return out


def _truth_cell(truth: RecordingTruth) -> str:
    """The wind spells (speed from direction) and payloads (kg from–to s), or "still air"."""
    parts = [f"{w.speed_mps:g} m/s from {w.from_deg:03.0f}°" for w in truth.winds]
    parts += [
        f"{p.mass_kg:g} kg {p.start_s - truth.takeoff_s:.0f}–{p.end_s - truth.takeoff_s:.0f} s"
        for p in truth.payloads
    ]
    return "; ".join(parts) or "still air"


def table_lines(flights: list[tuple[RecordingTruth, TrackerRun]]) -> list[str]:
    """One row per flight: the set it belongs to, its truth (times from take-off), the
    steps, then within 2σ / 3σ and the most |error|/σ of mass and wind, and the share of steps
    with the vehicle file's effects in use."""
    lines = [
        "| flight | set | truth | steps | mass within 2σ / 3σ | most \\|z\\| "
        "| wind within 2σ / 3σ | most \\|z\\| | not applied |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for truth, run in flights:
        steps = f"{len(run.time_s)}" + (f" (+{run.across_changes})" if run.across_changes else "")
        lines.append(
            f"| {run.name} | {flight_set(truth)} | {_truth_cell(truth)} | {steps} "
            f"| {run.coverage_cells()} | {100 * run.not_applied():.0f} % |"
        )
    return lines


def flight_set(truth: RecordingTruth) -> str:
    """ "fit" for a recording the vehicle file was fitted on, else "held out"."""
    return "fit" if truth.scenario in FITTED_ON else "held out"


def pooled(runs_: list[TrackerRun], sigmas: float) -> tuple[float, float]:
    """Share of all steps within ``sigmas`` σ: mass, wind."""
    z = np.vstack([r.z() for r in runs_])
    return float(np.mean(z[:, 2] <= sigmas)), float(np.mean(z[:, :2].max(axis=1) <= sigmas))


def meets_aim(runs_: list[TrackerRun]) -> bool:
    """The issue's aim over the steps of ``runs_``: mass and wind within 2σ on at least 90 %
    of them, within 3σ on all."""
    z = np.vstack([r.z() for r in runs_])
    return min(pooled(runs_, 2.0)) >= 0.90 and float(z.max()) <= 3.0


def summary_lines(flights: list[tuple[RecordingTruth, TrackerRun]]) -> list[str]:
    """Pooled over the steps of all flights, of the held-out ones, of those fitted on, and of
    each held-out set of ``replay/sitl_held`` (``held_*``, ``held2_*``, …, by the flights'
    name before the first "_"): the shares within 1σ, 2σ and 3σ (a 1σ that is right holds
    the mass within 1σ on 68 % of the steps, both wind components on 47 %: a σ too wide
    shows there); with how many flights meet the aim alone (a group without flights has no
    line)."""
    out = []
    sets = sorted(
        {r.name.split("_")[0] for _, r in flights if r.name.startswith("held")},
        key=lambda label: (len(label), label),
    )
    groups = (
        ("all", [r for _, r in flights]),
        ("held out", [r for t, r in flights if flight_set(t) == "held out"]),
        ("fit", [r for t, r in flights if flight_set(t) == "fit"]),
        *(
            (f"{label}_*", [r for _, r in flights if r.name.split("_")[0] == label])
            for label in sets
        ),
    )
    for label, group in groups:
        if not group:
            continue
        (m1, w1), (m2, w2), (m3, w3) = (pooled(group, k) for k in (1.0, 2.0, 3.0))
        steps = sum(len(r.time_s) for r in group)
        unapplied = sum(int(np.sum(~r.applied)) for r in group) / steps
        out.append(
            f"{label} ({len(group)} flights, {steps} steps): mass {100 * m2:.0f} % within 2σ, "
            f"{100 * m3:.0f} % within 3σ ({100 * m1:.0f} % within 1σ); wind {100 * w2:.0f} %, "
            f"{100 * w3:.0f} % ({100 * w1:.0f} %); not applied {100 * unapplied:.0f} %; the aim "
            f"met on {sum(meets_aim([r]) for r in group)} of {len(group)}"
        )
    return out


def shows(flights: list[tuple[RecordingTruth, TrackerRun]]) -> str:
    """docs/residuals.md's reading of the table: the flights that meet the aim alone, whether
    the pooled steps do (their shares within 1σ, 2σ and 3σ), and the flights with a step
    beyond 3σ, with the largest |error|/σ of the mass and of the wind there."""
    runs_ = [r for _, r in flights]
    meeting = [r.name for r in runs_ if meets_aim([r])]
    (m1, _), (m2, w2), (m3, w3) = (pooled(runs_, k) for k in (1.0, 2.0, 3.0))
    beyond = []
    for run in runs_:
        z = run.z()
        worst = (("mass", float(z[:, 2].max())), ("wind", float(z[:, :2].max())))
        parts = [f"{label} {value:.1f}σ" for label, value in worst if value > 3.0]
        if parts:
            beyond.append(f"{run.name} ({', '.join(parts)})")
    return (
        f"{len(meeting)} of the {len(runs_)} flights meet the aim alone "
        f"({', '.join(meeting) or 'none'}); the pooled steps "
        f"{'do' if meets_aim(runs_) else 'do not'} (mass {100 * m2:.0f} % within 2σ, "
        f"{100 * m3:.0f} % within 3σ and {100 * m1:.0f} % within 1σ; wind {100 * w2:.0f} %, "
        f"{100 * w3:.0f} %). A step beyond 3σ: {'; '.join(beyond) or 'none'}"
    )


def blind_steps(run: TrackerRun) -> np.ndarray:
    """Which of ``run``'s steps beyond 3σ nothing the tracker read could have told from the
    truth: since the truth last changed (or the take-off), the readings' evidence for the
    truth over the estimate, ½ Σ (ΔP/σ)² over the steps (ΔP the model's mean power over a
    step's readings at the truth less at the estimate after it, σ the step's noise: the log
    of how much likelier the readings are at the truth), is below :data:`BLIND_NATS`; and, for
    the wind, the autopilot's report was :data:`REPORT_OFF_MPS` or more off the true wind, or
    there was none. (A diagnosis of where the misses sit, not a rule the tracker uses.)"""
    assert run.told is not None
    power_sigmas = np.nan_to_num(run.told[:, 0])
    changed = np.ones(len(run.time_s), dtype=bool)
    changed[1:] = np.any(run.truth[1:] != run.truth[:-1], axis=1)
    spell = np.cumsum(changed)  # steps of one truth share a number
    evidence = np.zeros(len(power_sigmas))
    for number in np.unique(spell):
        steps = spell == number
        evidence[steps] = 0.5 * np.cumsum(power_sigmas[steps] ** 2)
    z = run.z()
    report_blind = ~(run.told[:, 1] < REPORT_OFF_MPS)  # NaN: no report
    wind_ok = (z[:, :2].max(axis=1) <= 3.0) | report_blind
    return (z.max(axis=1) > 3.0) & (evidence < BLIND_NATS) & wind_ok


def blind(flights: list[tuple[RecordingTruth, TrackerRun]]) -> str:
    """How many of the steps beyond 3σ were blind (:func:`blind_steps`), and the flights that
    miss the aim only at blind steps."""
    runs_ = [r for _, r in flights]
    beyond = {r.name: int(np.sum(r.z().max(axis=1) > 3.0)) for r in runs_}
    if not any(beyond.values()):
        return f"no step is beyond 3σ, on any of the {len(runs_)} flights"
    blind_counts = {r.name: int(np.sum(blind_steps(r))) for r in runs_}
    missing = [r for r in runs_ if not meets_aim([r])]
    only_blind = [
        r.name
        for r in missing
        if min(r.within(2.0)) >= 0.90 and blind_counts[r.name] == beyond[r.name]
    ]
    return (
        f"of the {sum(beyond.values())} steps beyond 3σ, on "
        f"{sum(n > 0 for n in beyond.values())} of the {len(runs_)} flights, "
        f"{sum(blind_counts.values())} were blind: since the truth last changed the readings "
        f"held less than {BLIND_NATS:g} nats of evidence for it over the estimate, and for "
        f"the wind the autopilot's report was {REPORT_OFF_MPS:g} m/s or more off it. Of the "
        f"{len(missing)} flights that miss the aim, {len(only_blind)} miss it only at blind "
        f"steps{(' (' + ', '.join(only_blind) + ')') if only_blind else ''}"
    )


def worst_wind(flights: list[tuple[RecordingTruth, TrackerRun]]) -> str:
    """The largest |error|/σ of the wind (its larger component) over ``flights``, and where."""
    worst = max((float(r.z()[:, :2].max()), r.name) for _, r in flights)
    return f"up to {worst[0]:.1f}σ, on {worst[1]}"


def mass_step(flights: list[tuple[RecordingTruth, TrackerRun]], name: str) -> str:
    """The flight ``name``'s worst step of the mass: its error (kg) and |error|/σ."""
    [run] = [r for _, r in flights if r.name == name]
    z = run.z()[:, 2]
    worst = int(np.argmax(z))
    error_kg = float(run.estimate[worst, 2] - run.truth[worst, 2])
    return f"{error_kg:+.2f} kg, {z[worst]:.1f}σ".replace("-", "−")


def unloaded_mass(flights: list[tuple[RecordingTruth, TrackerRun]], prefix: str) -> str:
    """Over the steps of the flights named ``prefix``… that carry no payload: the median
    error of the mass (kg, light or heavy) and its median 1σ."""
    runs_ = [r for t, r in flights if r.name.startswith(prefix) and not t.payloads]
    error_kg = float(np.median(np.concatenate([r.estimate[:, 2] - r.truth[:, 2] for r in runs_])))
    sigma_kg = float(np.median(np.concatenate([r.sigma[:, 2] for r in runs_])))
    side = "light" if error_kg < 0 else "heavy"
    return f"{abs(error_kg):.2f} kg {side} at a 1σ of {sigma_kg:.2f} kg"


def slow_error_share(flights: list[tuple[RecordingTruth, TrackerRun]]) -> str:
    """The mass's and the wind's share of the steps within 2σ pooled over ``flights`` (run with
    another slow model error: ``--slow-error-fraction``)."""
    mass_2, wind_2 = pooled([r for _, r in flights], 2.0)
    return (
        f"{100 * mass_2:.0f} % of the steps within 2σ for the mass, {100 * wind_2:.0f} % "
        "for the wind"
    )


def report(flights: list[tuple[RecordingTruth, TrackerRun]]) -> str:
    """The table and the pooled lines, as docs/residuals.md gives them."""
    return "\n".join([*table_lines(flights), "", *summary_lines(flights)])


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recordings", nargs="?", type=Path, default=RECORDINGS)
    parser.add_argument("--slow-error-fraction", type=float, help="of the hover power")
    args = parser.parse_args(argv)
    try:
        flights = runs(args.recordings, args.slow_error_fraction)
        print(report(flights))
        print(f"\n{blind(flights)}")
    except UserError as exc:
        print(f"tracker_sitl: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
