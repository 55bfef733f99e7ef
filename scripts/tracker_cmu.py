"""The daemon's online tracker on the CMU M100 flights, against their payload and anemometer:
the running mass and wind over each whole airborne flight, with the vehicle file's slow model
error (``[model] slow_error_fraction``) and without it (the model's errors taken as white).

Prints the block ``tracker-cmu`` of docs/residuals.md ("The running value, step by step"),
which ``make figures`` writes and ``tests/test_figures.py`` checks (and ``tracker-cmu-shows``,
the sentence that reads it).

Run: ``python scripts/tracker_cmu.py [DATA_DIR]`` (default ../shared/data/cmu_m100_subset).
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from estimator.analysis.tracker_truth import TrackerRun, cmu_truth, track_flight
from estimator.logs import cmu
from estimator.physics.vehicle import Vehicle, load_vehicle

ROOT = Path(__file__).resolve().parent.parent
VEHICLE = ROOT / "config" / "vehicles" / "dji_m100_cmu.toml"
DATA = ROOT.parent / "shared" / "data" / "cmu_m100_subset"


def runs(vehicle: Vehicle, data: Path = DATA) -> list[TrackerRun]:
    """Every CMU flight of ``data`` through the pipeline with ``vehicle``."""
    flights = cmu.load_flights(sorted(data.glob("*.csv")))
    return [track_flight(f, vehicle, cmu_truth(f)) for f in flights]


def both(data: Path = DATA) -> tuple[list[TrackerRun], list[TrackerRun]]:
    """The runs with the vehicle file as committed, and with its slow error set to 0."""
    vehicle = load_vehicle(VEHICLE)
    return runs(vehicle, data), runs(replace(vehicle, slow_error_fraction=0.0), data)


def table_lines(with_error: list[TrackerRun], white: list[TrackerRun]) -> list[str]:
    """One row per flight: the truth, the end value, then within 2σ / 3σ and the most
    |error|/σ of mass and wind, with the slow error and without it."""
    lines = [
        "| flight | payload kg | wind m/s | end mass kg | mass within 2σ / 3σ | most \\|z\\| "
        "| wind within 2σ / 3σ | most \\|z\\| | without the slow error: mass | most \\|z\\| "
        "| wind | most \\|z\\| |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for run, before in zip(with_error, white, strict=True):
        wind_n, wind_e, payload_kg = run.truth[0]
        end = f"{run.estimate[-1, 2]:+.2f} ± {run.sigma[-1, 2]:.2f}"
        lines.append(
            f"| {run.name} | {payload_kg:.2f} | {np.hypot(wind_n, wind_e):.1f} "
            f"| {end} | {run.coverage_cells()} | {before.coverage_cells()} |"
        )
    return lines


def pooled(runs_: list[TrackerRun], sigmas: float) -> tuple[float, float]:
    """Share of all steps within ``sigmas`` σ: mass, wind."""
    z = np.vstack([r.z() for r in runs_])
    return float(np.mean(z[:, 2] <= sigmas)), float(np.mean(z[:, :2].max(axis=1) <= sigmas))


def summary_lines(with_error: list[TrackerRun], white: list[TrackerRun]) -> list[str]:
    """Pooled over the flights' steps, with and without the slow error."""
    out = []
    for label, group in (("with the slow error", with_error), ("without", white)):
        m2, w2 = pooled(group, 2.0)
        m3, w3 = pooled(group, 3.0)
        out.append(
            f"{label}: mass {100 * m2:.0f} % within 2σ, {100 * m3:.0f} % within 3σ; "
            f"wind {100 * w2:.0f} %, {100 * w3:.0f} % ({sum(len(r.time_s) for r in group)} steps)"
        )
    return out


#: The aim for the live tracker: at least this share of a flight's steps within 2σ (and none
#: beyond 3σ), for the mass and for the wind.
AIM_WITHIN_2_SIGMA = 0.90


def _flight(run: TrackerRun) -> str:
    return run.name.removeprefix("cmu-")


def _flights_short(short: list[TrackerRun]) -> str:
    """``short``'s flights and their mass within 2σ, as a parenthesis (empty: none)."""
    if not short:
        return ""
    named = [f"{_flight(r)}: {100 * r.within(2.0)[0]:.0f} %" for r in short]
    return f" (flight{'s' * (len(named) > 1)} {', '.join(named)} within 2σ, or a step beyond 3σ)"


def shows(with_error: list[TrackerRun], white: list[TrackerRun]) -> str:
    """docs/residuals.md's reading of the table: the end masses, the pooled shares and the
    largest |error|/σ with and without the slow error, and which flights miss the aim."""
    outside = [r for r in with_error if r.z()[-1, 2] > 2.0]
    ends = "no flight's mass ends" if not outside else f"{len(outside)} flights' masses end"
    (m2, _), (m3, _) = pooled(with_error, 2.0), pooled(with_error, 3.0)
    (w2, _), (w3, _) = pooled(white, 2.0), pooled(white, 3.0)
    worst, worst_white = (max(float(r.z().max()) for r in group) for group in (with_error, white))
    mass_short = [
        r for r in with_error if r.within(2.0)[0] < AIM_WITHIN_2_SIGMA or r.z()[:, 2].max() > 3.0
    ]
    mass_holds = len(with_error) - len(mass_short)
    wind_holds = [r for r in with_error if r.within(2.0)[1] >= AIM_WITHIN_2_SIGMA]
    lowest = min(with_error, key=lambda r: r.within(2.0)[1])
    return (
        f"with the slow error, {ends} outside 2σ, and pooled over the flights {100 * m2:.0f} % "
        f"of the steps hold the mass within 2σ and {100 * m3:.0f} % within 3σ (without it: "
        f"{100 * w2:.0f} % and {100 * w3:.0f} %; the largest |error|/σ {worst:.1f} against "
        f"{worst_white:.1f}). The aim for the live tracker is ≥ {100 * AIM_WITHIN_2_SIGMA:.0f} % "
        f"within 2σ and 3σ always on every flight: the mass holds it on {mass_holds} of "
        f"{len(with_error)}{_flights_short(mass_short)}, and the wind within 2σ on "
        f"{len(wind_holds)} of {len(with_error)} (flight {_flight(lowest)}: "
        f"{100 * lowest.within(2.0)[1]:.0f} %"
    )


def report(with_error: list[TrackerRun], white: list[TrackerRun]) -> str:
    """The table and the pooled lines, as docs/residuals.md gives them."""
    return "\n".join([*table_lines(with_error, white), "", *summary_lines(with_error, white)])


def main(argv: list[str]) -> int:
    print(report(*both(Path(argv[0]) if argv else DATA)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
