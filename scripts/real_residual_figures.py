"""The real-log figures of docs/residuals.md and README.md beyond the IRIS+ residuals table
(``uav-energy residuals`` against a vehicle file, and the file it writes replayed with wind
and mass held at the files' values):

- IRIS+ June–August against the March vehicle file: the runner-up and the second step of the
  analysis, the online tracker's settled mass per flight, the file written from June
  replayed on July–August, and the one written from all of June–August replayed on them
  (in-sample);
- CMU M100: all flights together (and the file written, replayed), and each flight (every
  candidate with the online tracker; wind and mass only) against its payload and anemometer
  (:func:`estimator.analysis.tracker_truth.cmu_truth`).

Commands (``I`` = ../shared/data/iris_quadcopter_logs, ``M`` = its March file
config/vehicles/iris_plus_2016_03.toml, ``C`` = ../shared/data/cmu_m100_subset, ``V`` =
config/vehicles/dji_m100_cmu.toml, ``held.toml`` = ``[vehicle] track_effects = false``)::

    uav-energy residuals $I/2016-06-*/*/*.log --vehicle $M --write june.toml --json
    uav-energy replay $I/2016-0[78]-*/*/*.log --vehicle $M --config held.toml --json
    uav-energy replay $I/2016-0[78]-*/*/*.log --vehicle june.toml --config held.toml --json
    uav-energy residuals $C/*.csv --vehicle $V --flight cmu-NNN --online --json
    uav-energy residuals $C/*.csv --vehicle $V --flight cmu-NNN --candidates wind,mass --json

``scripts/figures.py`` registers the blocks (:func:`generators`); ≈ 3 min of CPU in all.
Powers in W, energies in Wh, masses in kg, winds in m/s from degrees.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable, Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from estimator.analysis.tracker_truth import Truth, cmu_truth, track_samples
from estimator.logs import cmu, iter_samples
from estimator.physics.effects import wind_from_deg
from estimator.physics.vehicle import load_vehicle

#: What ``uav-energy ARGV…`` prints on stdout (``scripts/figures.py`` runs it in process).
Cli = Callable[..., str]
Json = Mapping[str, Any]

VEHICLES = Path(__file__).resolve().parent.parent / "config/vehicles"
MARCH_VEHICLE = VEHICLES / "iris_plus_2016_03.toml"
CMU_VEHICLE = VEHICLES / "dji_m100_cmu.toml"
JUNE, LATER, SUMMER = "2016-06-*/*/*.log", "2016-0[78]-*/*/*.log", "2016-0[678]-*/*/*.log"
#: ``replay --config``: wind and mass held at the vehicle file's values all flight.
UNTRACKED = "[vehicle]\ntrack_effects = false\n"
#: A flight's tracker steps from this share of them on are its settled value.
SETTLED_FROM = 0.5
#: The online wind "agrees" with the anemometer's when their speeds differ by at most this.
WIND_AGREES_MPS = 1.0
#: The online tracker's late mass is "on the payload" within this (kg).
MASS_AGREES_KG = 0.10
#: An online wind this far (m/s) from the anemometer's is named apart from the others.
WIND_APART_MPS = 3.0


class WrittenReplay(NamedTuple):
    """``residuals --write`` of some logs (its JSON), and ``replay --json`` of others with
    the vehicle file and with the written one (wind and mass held)."""

    fitted: Json
    before: Json
    after: Json


def written_replay(
    cli: Cli, vehicle: Path, fitted: Sequence[str], replayed: Sequence[str]
) -> WrittenReplay:
    """The analysis of the ``fitted`` logs against ``vehicle`` with ``--write``, then the
    ``replayed`` logs with ``vehicle`` and with the written file."""
    with tempfile.TemporaryDirectory() as tmp:
        written, held = Path(tmp) / "written.toml", Path(tmp) / "held.toml"
        held.write_text(UNTRACKED)
        given = ("--vehicle", str(vehicle))
        fit = cli("residuals", *fitted, *given, "--write", str(written), "--json")
        config = ("--config", str(held))
        before = cli("replay", *replayed, *given, *config, "--json")
        after = cli("replay", *replayed, "--vehicle", str(written), *config, "--json")
    return WrittenReplay(json.loads(fit), json.loads(before), json.loads(after))


def replay_change(run: WrittenReplay) -> str:
    """The replay's power error and energy, with the given file → with the written one."""
    before, after = run.before, run.after
    return (
        f"power RMSE {before['power_rmse_w']:.1f} → {after['power_rmse_w']:.1f} W, MAPE "
        f"{before['power_mape_pct']:.1f} → {after['power_mape_pct']:.1f} %, energy predicted "
        f"{before['energy_predicted_wh']:.1f} → {after['energy_predicted_wh']:.1f} Wh against "
        f"{before['energy_measured_wh']:.1f} Wh measured"
    )


# --- IRIS+ June–August against the March file ------------------------------------------------


def _iris_logs(data: Path, pattern: str) -> list[str]:
    return [str(p) for p in sorted(data.glob(pattern))]


def settled_masses_kg(data: Path) -> list[float]:
    """Per June–August flight with at least 4 tracker steps: the median of its online
    tracker's mass difference over the second half of them (started from the March file)."""
    vehicle = load_vehicle(MARCH_VEHICLE)
    masses = []
    for log in sorted(data.glob(SUMMER)):
        run = track_samples(log.stem, iter_samples(log), vehicle)
        steps = len(run.time_s)
        if steps >= 4:
            masses.append(float(np.median(run.estimate[int(steps * SETTLED_FROM) :, 2])))
    return masses


def _step(summer: Json, step: int, candidate: str) -> Json:
    """One candidate's row of a step of the analysis's selection."""
    return next(
        row for row in summer["selection"] if row["step"] == step and row["candidate"] == candidate
    )


def _runner_up(summer: Json) -> tuple[Json, Json]:
    """The first selected effect, and its runner-up's row of step 1."""
    chosen = summer["effects"][0]
    return chosen, _step(summer, 1, chosen["runner_up"]["candidate"])


def offset(summer: Json, masses_kg: list[float]) -> str:
    """README.md: the effect chosen, its runner-up, the tracker's settled mass."""
    chosen, runner = _runner_up(summer)
    return (
        f"a flat {chosen['params']['power_w']:+.0f} W offset (runner-up: "
        f"{runner['params']['delta_kg']:+.2f} kg of {runner['candidate']}; the online tracker "
        f"settles at {np.median(masses_kg):+.2f} kg per flight)"
    )


def offset_share(summer: Json) -> str:
    """docs/residuals.md: the load chosen (W) and its share of the March file's hover power."""
    power_w = summer["effects"][0]["params"]["power_w"]
    hover_w = load_vehicle(MARCH_VEHICLE).model.hover_power_w
    return f"**{power_w:+.0f} W** ({100 * power_w / hover_w:+.0f} % of the March hover power)"


def runner_up(summer: Json) -> str:
    """docs/residuals.md: the runner-up of step 1, its held-out RMSE against the chosen one's
    and the z of the block test between them."""
    chosen, runner = _runner_up(summer)
    return (
        f"`{runner['candidate']}` **{runner['params']['delta_kg']:+.3f} kg** (held-out RMSE "
        f"{runner['rmse_w']:.1f} W vs {chosen['rmse_after_w']:.1f} W); the block test prefers "
        f"the constant load (z = {chosen['runner_up']['z']:.1f} against {runner['candidate']})"
    )


def tracker(summer: Json, masses_kg: list[float]) -> str:
    """docs/residuals.md: the tracker's settled mass over the flights, against the runner-up."""
    _, runner = _runner_up(summer)
    low, high = np.percentile(masses_kg, [25, 75])
    return (
        f"**{np.median(masses_kg):+.3f} kg** (median of the {len(masses_kg)} flights' "
        f"second-half medians, IQR {low:.2f}–{high:.2f} kg), consistent with the offline "
        f"`{runner['candidate']}` candidate ({runner['params']['delta_kg']:+.3f} kg)"
    )


def second_step(summer: Json) -> str:
    """docs/residuals.md: the best candidate of step 2, not selected, and the channel that
    best predicts what is left."""
    rows = [row for row in summer["selection"] if row["step"] == 2]
    best = max(rows, key=lambda row: row["gain_pct"])
    channel = max(summer["attribution"]["channels"], key=lambda c: c["r2"])
    return (
        f"`{best['candidate']}` would lower the held-out RMSE by a further "
        f"{best['gain_pct']:.1f} % (z = {best['z']:.1f}), below the 10 % minimum gain: not "
        f"selected. After the load, no channel predicts the residual well (best R² "
        f"{channel['r2']:.2f}, `{channel['channel']}`)"
    )


def june_replay(run: WrittenReplay) -> str:
    """docs/residuals.md: fitted on June, replayed on July–August."""
    return (
        f"fitted on June ({run.fitted['effects'][0]['description']}), replayed on July–August "
        f"({run.before['logs']} logs, not seen by the fit): {replay_change(run)}"
    )


# --- CMU M100 -----------------------------------------------------------------------------


class Flight(NamedTuple):
    """One flight: its truth, the analysis with every candidate (and ``--online``), and with
    wind and mass only."""

    name: str
    truth: Truth
    every: Json
    wind_mass: Json


def _csvs(data: Path) -> list[str]:
    return [str(p) for p in sorted(data.glob("*.csv"))]


def flights(cli: Cli, data: Path) -> list[Flight]:
    """Each flight's two analyses, with its truth."""
    csvs, out = _csvs(data), []
    for flight in cmu.load_flights(sorted(data.glob("*.csv"))):
        args = (*csvs, "--vehicle", str(CMU_VEHICLE), "--flight", flight.flight_id, "--json")
        every = json.loads(cli("residuals", *args, "--online"))
        wind_mass = json.loads(cli("residuals", *args, "--candidates", "wind,mass"))
        out.append(Flight(flight.flight_id, cmu_truth(flight), every, wind_mass))
    return out


def _mass_kg(result: Json) -> float | None:
    """The mass difference selected, if any."""
    return next((e["params"]["delta_kg"] for e in result["effects"] if e["name"] == "mass"), None)


def _wind(speed_mps: float, from_deg: float) -> str:
    return f"{speed_mps:.1f} m/s from {from_deg:.0f}°"


def _truth_wind(truth: Truth) -> tuple[float, float]:
    """The anemometer's ambient wind: speed (m/s), where it blows from (°)."""
    north, east = truth.wind_ne_mps
    return float(np.hypot(north, east)), float(wind_from_deg(north, east))


def _late(flight: Flight) -> Json:
    """The online tracker's medians over the second half of the flight."""
    return flight.every["online"][0]["late_median"]


def _short(run: Flight) -> str:
    return run.name.removeprefix("cmu-")


def table(runs: list[Flight]) -> str:
    """One row per flight: payload, held-out RMSE, what was selected, the wind+mass mass,
    the online tracker's late mass and wind, the anemometer's wind."""
    lines = [
        "| flight | payload (kg) | held-out RMSE before → after (W) | selected (all candidates) "
        "| wind+mass only: mass Δ (kg) | online mass Δ (kg) ² | online wind ² "
        "| anemometer wind |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for run in runs:
        every, late = run.every, _late(run)
        effects = [e["description"].removesuffix(", all flight") for e in every["effects"]]
        selected = "; then ".join(effects) or "none"
        mass = _mass_kg(run.wind_mass)
        lines.append(
            f"| {_short(run)} | {run.truth.mass_delta_kg:.2f} "
            f"| {every['rmse_before_w']:.1f} → {every['rmse_after_w']:.1f} | {selected} "
            f"| {'—' if mass is None else f'{mass:+.2f}'} | {late['mass_delta_kg']:+.2f} "
            f"| {_wind(late['wind_speed_mps'], late['wind_from_deg'])} "
            f"| {_wind(*_truth_wind(run.truth))} |"
        )
    return "\n".join(lines)


def _wind_agrees(runs: list[Flight]) -> int:
    return sum(
        abs(_late(r)["wind_speed_mps"] - _truth_wind(r.truth)[0]) <= WIND_AGREES_MPS for r in runs
    )


def offline_mass(runs: list[Flight]) -> str:
    """The mass ``residuals`` finds per flight where selected, against the payload, and the
    flights without payload that select nothing."""
    found = [(m, r.truth.mass_delta_kg) for r in runs if (m := _mass_kg(r.every)) is not None]
    empty = [r for r in runs if r.truth.mass_delta_kg == 0.0]
    quiet = sum(not r.every["effects"] for r in empty)
    return (
        f"the per-flight mass found equals the payload within "
        f"{max(abs(m - p) for m, p in found):.2f} kg wherever it is selected ({len(found)} of "
        f"{len(runs)} flights), and {quiet} of the {len(empty)} no-payload flights select "
        f"nothing"
    )


def offline_wind(runs: list[Flight]) -> str:
    """How many flights ``residuals`` names a wind on (every candidate, and wind and mass
    only), the anemometer's winds and the flights' noise floors (W)."""
    named = sum(
        any(e["name"] == "wind" for e in r.every["effects"] + r.wind_mass["effects"]) for r in runs
    )
    on = "on no flight" if not named else f"on {named} of {len(runs)} flights"
    speeds = [_truth_wind(r.truth)[0] for r in runs]
    floors = [r.every["noise_floor_w"] for r in runs]
    return (
        f"The offline tool selects a wind {on}: {min(speeds):.0f}–{max(speeds):.0f} m/s winds "
        f"change the M100's power by less than its {min(floors):.0f}–{max(floors):.0f} W "
        f"sample noise"
    )


def readme(runs: list[Flight]) -> str:
    """README.md's bullet: :func:`offline_mass`, and the online wind against the anemometer."""
    return (
        f"{offline_mass(runs)}. The online wind's speed agrees with the anemometer's within "
        f"{WIND_AGREES_MPS:.1f} m/s on {_wind_agrees(runs)} of {len(runs)} flights"
    )


def online_mass(runs: list[Flight]) -> str:
    """docs/residuals.md: the online tracker's late mass against the payload."""
    errors = {_short(r): _late(r)["mass_delta_kg"] - r.truth.mass_delta_kg for r in runs}
    off = [
        f"on {_short(r)} it reads {_late(r)['mass_delta_kg']:+.2f} kg for "
        f"{r.truth.mass_delta_kg:.2f} kg"
        for r in runs
        if abs(errors[_short(r)]) > MASS_AGREES_KG
    ]
    near = len(runs) - len(off)
    mean_kg = float(np.mean(np.abs(list(errors.values()))))
    return (
        f"within {MASS_AGREES_KG:.2f} kg of the payload on {near} of {len(runs)} flights; "
        + ", ".join(off)
        + f"; mean absolute error {mean_kg:.2f} kg"
    )


def online_wind(runs: list[Flight]) -> str:
    """docs/residuals.md: the online tracker's late wind speed against the anemometer's, the
    flights far from it named apart."""
    pairs = {_short(r): (_late(r)["wind_speed_mps"], _truth_wind(r.truth)[0]) for r in runs}
    apart = {k: v for k, v in pairs.items() if abs(v[0] - v[1]) > WIND_APART_MPS}
    close = [v for k, v in pairs.items() if k not in apart]
    tracked, measured = ([v[i] for v in close] for i in (0, 1))
    text = (
        f"{min(tracked):.1f}–{max(tracked):.1f} m/s on {len(close)} flights against "
        f"{min(measured):.1f}–{max(measured):.1f} m/s measured"
    )
    for name, (online_mps, anemometer_mps) in apart.items():
        text += f", and {online_mps:.1f} m/s on {name} ({anemometer_mps:.1f} measured)"
    return text


def unselected(runs: list[Flight]) -> str:
    """docs/residuals.md: each payload flight that selects nothing, with its best candidate
    of step 1 (its gain and z, short of the rule)."""
    parts = []
    for run in runs:
        if run.every["effects"] or run.truth.mass_delta_kg == 0.0:
            continue
        rows = [row for row in run.every["selection"] if row["step"] == 1]
        best = max(rows, key=lambda row: row["gain_pct"])
        value = ", ".join(f"{k} {v:+.2f}" for k, v in best["params"].items() if v is not None)
        parts.append(
            f"{_short(run)}'s best candidate, `{best['candidate']}` ({value}), cuts the "
            f"held-out error by {best['gain_pct']:.0f} % at z {best['z']:.1f} only"
        )
    return "; ".join(parts) or "every payload flight selects an effect"


def _channels(analysis: Json) -> tuple[Json, float]:
    """The channel that best predicts the residual left, and the next best R²."""
    ranked = sorted(analysis["attribution"]["channels"], key=lambda c: -c["r2"])
    return ranked[0], ranked[1]["r2"]


def pooled_result(run: WrittenReplay) -> str:
    """docs/residuals.md: all flights together, the effect selected and the ones it cannot
    be told from, and the channel left."""
    analysis = run.fitted
    chosen = analysis["effects"][0]
    ties = ", ".join(
        f"`{t['candidate']}` (z = {t['z']:+.2f} between them)"
        for t in chosen["indistinguishable_from"]
    )
    best, next_r2 = _channels(analysis)
    return (
        f"Held-out RMSE **{analysis['rmse_before_w']:.1f} → {analysis['rmse_after_w']:.1f} W**, "
        f"MAPE {analysis['mape_before_pct']:.1f} → {analysis['mape_after_pct']:.1f} % "
        f"({analysis['n_samples']:,} samples). Selected: {chosen['description']}"
        + (f" — *as good held out as* {ties}" if ties else "")
        + f". The residual left is best predicted by **`{best['channel']}`** (held-out R² "
        f"{best['r2']:.2f}; every other channel ≤ {next_r2:.2f})"
    )


def generators(
    cli: Cli, iris: Path, cmu_data: Path, summer: Callable[[], Json]
) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it; ``iris``, ``cmu_data``: the logs' folders;
    ``summer``: the IRIS+ June–August ``residuals --json`` against the March file
    (``scripts/residual_figures.py`` computes it for its table)."""
    masses = cache(lambda: settled_masses_kg(iris))
    june = cache(
        lambda: written_replay(cli, MARCH_VEHICLE, _iris_logs(iris, JUNE), _iris_logs(iris, LATER))
    )
    in_sample = cache(lambda: written_replay(cli, MARCH_VEHICLE, *[_iris_logs(iris, SUMMER)] * 2))
    together = cache(lambda: written_replay(cli, CMU_VEHICLE, *[_csvs(cmu_data)] * 2))
    each = cache(lambda: flights(cli, cmu_data))
    return {
        "residuals-iris-offset": lambda: offset(summer(), masses()),
        "residuals-iris-runner-up": lambda: runner_up(summer()),
        "residuals-iris-offset-share": lambda: offset_share(summer()),
        "residuals-iris-tracker": lambda: tracker(summer(), masses()),
        "residuals-iris-second-step": lambda: second_step(summer()),
        "residuals-iris-june-replay": lambda: june_replay(june()),
        "residuals-iris-june-replay-change": lambda: replay_change(june()),
        "residuals-iris-in-sample-replay": lambda: replay_change(in_sample()),
        "residuals-cmu-pooled": lambda: pooled_result(together()),
        "residuals-cmu-noise-floor": lambda: f"{together().fitted['noise_floor_w']:.0f} W",
        "residuals-cmu-pooled-replay": lambda: replay_change(together()),
        "residuals-cmu-table": lambda: table(each()),
        "residuals-cmu-readme": lambda: readme(each()),
        "residuals-cmu-offline-mass": lambda: offline_mass(each()),
        "residuals-cmu-offline-wind": lambda: offline_wind(each()),
        "residuals-cmu-online-mass": lambda: online_mass(each()),
        "residuals-cmu-online-wind": lambda: online_wind(each()),
        "residuals-cmu-unselected": lambda: unselected(each()),
    }
