"""The figures of docs/residuals.md's simulated flights, as text, from the ``--json`` objects of
``uav-energy residuals`` (``residuals-sim-*``), and those of its IRIS+ table
(``residuals-iris-table``, ``residuals-iris-summer``: the IRIS+ logs against the March vehicle
file; ``scripts/real_residual_figures.py`` has the real-log figures beyond the table). The
flights are simulated and analysed here, once each (cached); ``scripts/figures.py`` runs
``uav-energy`` in process and registers the blocks (:func:`generators`,
:func:`changing_generators`: the slower flights whose effect changes, which
``tests/test_residual_figures.py`` checks, and :func:`iris_generators`, which read the logs).

Each flight: ``uav-energy sim --plan mixed --duration 600 --seed 4 FLAGS --tlog F`` with one
effect hidden, then ``uav-energy residuals F --vehicle estimator/data/default_vehicle.toml
--json`` (the built-in vehicle: the estimator is told none of the hidden effects). Powers in W,
MAPE in %; "held out": each sample predicted by a fold that did not see it.
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Callable, Mapping
from functools import cache
from pathlib import Path
from typing import Any

from estimator.physics.effects import Avionics, Effect, Mass, Wind
from estimator.sim.files import write_tlog
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate

Residuals = Mapping[str, Any]
#: What ``uav-energy ARGV…`` prints on stdout (``scripts/figures.py`` runs it in process).
Cli = Callable[..., str]

DEFAULT_VEHICLE = str(
    Path(__file__).resolve().parent.parent / "estimator/data/default_vehicle.toml"
)

#: The flights' plan, length (s) and seed, as ``uav-energy sim`` flags.
SIM_FLAGS = ("--plan", "mixed", "--duration", "600", "--seed", "4")
#: Row label → the ``uav-energy sim`` flags that hide the effect.
HIDDEN = {
    "none": (),
    "wind 5 m/s from 60° (`--wind 5@60`)": ("--wind", "5@60"),
    "payload 0.6 kg (`--payload 0.6@0`)": ("--payload", "0.6@0"),
    "payload 0.6 kg at 250 s (`--payload 0.6@250`)": ("--payload", "0.6@250"),
    "30 W load (`--avionics 30@0`)": ("--avionics", "30@0"),
    "ρ = 1.0 (`--air-density 1.0`)": ("--air-density", "1.0"),
    "climb power (`--climb`, η = 0.6)": ("--climb",),
    "0.15 Ω losses (`--low-voltage-losses`)": ("--low-voltage-losses",),
}
#: The row whose step falls inside a held-out chunk (its footnote).
STEP_ROW = "payload 0.6 kg at 250 s (`--payload 0.6@250`)"
WIND_ROW = "wind 5 m/s from 60° (`--wind 5@60`)"
#: README.md's examples: row → what was hidden, and the parameter recovered (name, format).
RECOVERED = {
    WIND_ROW: ("wind 5 m/s from 60°", None),
    "payload 0.6 kg (`--payload 0.6@0`)": ("payload 0.6 kg", ("delta_kg", ".3f", " kg")),
    "30 W load (`--avionics 30@0`)": ("30 W load", ("power_w", ".1f", " W")),
    "ρ = 1.0 (`--air-density 1.0`)": ("ρ 1.0", ("rho_kgpm3", ".3f", "")),
}
#: The rows replayed before and after ``--write``: their label in the replay table.
REPLAYED = {WIND_ROW: "wind 5 m/s from 60°", STEP_ROW: "payload 0.6 kg at 250 s"}
#: ``replay --config``: wind and mass held at the vehicle file's values all flight.
UNTRACKED = "[vehicle]\ntrack_effects = false\n"


#: Row label → the effects hidden from the estimator that change during the flight, given to
#: the simulator as objects (``uav-energy sim --wind`` has no start time; a payload picked up
#: is :data:`STEP_ROW`).
CHANGING: dict[str, tuple[Effect, ...]] = {
    "wind 5 m/s from 60° from 250 s": (Wind(5.0, 60.0, at_s=250.0),),
    "wind 5 m/s from 60° until 300 s": (Wind(5.0, 60.0, until_s=300.0),),
    "0.8 kg from take-off, released at 300 s": (Mass(0.8, until_s=300.0),),
    "40 W load from 150 s to 400 s": (Avionics(40.0, at_s=150.0, until_s=400.0),),
    "0.6 kg released at 350 s + wind 5 m/s from 300° from 200 s": (
        Mass(0.6, until_s=350.0),
        Wind(5.0, 300.0, at_s=200.0),
    ),
    "wind 5 m/s turning from 60° to 200° at 300 s": (
        Wind(5.0, 60.0, until_s=300.0),
        Wind(5.0, 200.0, at_s=300.0),
    ),
}


def _residuals(cli: Cli, tlog: Path, *write: str) -> dict[str, Any]:
    """``uav-energy residuals TLOG --vehicle DEFAULT --json [--write F]``."""
    return dict(
        json.loads(cli("residuals", str(tlog), "--vehicle", DEFAULT_VEHICLE, "--json", *write))
    )


def _replay(cli: Cli, tlog: Path, vehicle: str | Path, *config: str) -> dict[str, Any]:
    return dict(json.loads(cli("replay", str(tlog), "--vehicle", str(vehicle), *config, "--json")))


@cache
def hidden_runs(cli: Cli) -> tuple[dict[str, Residuals], dict[str, dict[str, Residuals]]]:
    """Per row of :data:`HIDDEN`: the residuals of the flight ``uav-energy sim`` flew with the
    effect hidden (≈ 4 s of CPU a flight); per row of :data:`REPLAYED`: ``uav-energy replay
    --json`` of it with the built-in vehicle and with the file ``--write`` wrote, with wind
    and mass held (``held-*``, :data:`UNTRACKED`) and tracked online (``tracked-*``)."""
    found, replays = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "untracked.toml").write_text(UNTRACKED)
        held = ("--config", str(folder / "untracked.toml"))
        for i, (label, flags) in enumerate(HIDDEN.items()):
            tlog, written = folder / f"hidden{i}.tlog", folder / f"hidden{i}.toml"
            cli("sim", *SIM_FLAGS, *flags, "--tlog", str(tlog))
            if label not in REPLAYED:
                found[label] = _residuals(cli, tlog)
            else:
                found[label] = _residuals(cli, tlog, "--write", str(written))
                replays[label] = {
                    "held-before": _replay(cli, tlog, DEFAULT_VEHICLE, *held),
                    "held-after": _replay(cli, tlog, written, *held),
                    "tracked-before": _replay(cli, tlog, DEFAULT_VEHICLE),
                    "tracked-after": _replay(cli, tlog, written),
                }
    return found, replays


def changing_config(effects: tuple[Effect, ...]) -> SimConfig:
    """The simulated flight of a :data:`CHANGING` row (the flags of :data:`SIM_FLAGS`)."""
    return SimConfig(plan="mixed", duration_s=600.0, seed=4, effects=effects)


@cache
def changing_runs(cli: Cli) -> dict[str, Residuals]:
    """Per row of :data:`CHANGING`: the residuals of the simulated flight written as a tlog
    (≈ 7 s of CPU a flight: windows are tried on one flight)."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, (label, effects) in enumerate(CHANGING.items()):
            run = simulate(changing_config(effects))
            out[label] = _residuals(cli, write_tlog(run, Path(tmp) / f"c{i}.tlog", truth_csv=False))
    return out


#: The IRIS+ periods analysed against the March vehicle file: row label → logs (under
#: ../shared/data/iris_quadcopter_logs).
IRIS_PERIODS = {
    "March (the fit's own flights)": "2016-03-*/*/*.log",
    "June–August": "2016-0[678]-*/*/*.log",
}
IRIS_VEHICLE = Path(__file__).resolve().parent.parent / "config/vehicles/iris_plus_2016_03.toml"


@cache
def iris_runs(cli: Cli, logs_dir: Path) -> dict[str, Residuals]:
    """``uav-energy residuals LOG… --vehicle iris_plus_2016_03.toml --json`` per period (≈ 15 s
    of CPU in all)."""
    out = {}
    for label, pattern in IRIS_PERIODS.items():
        logs = [str(p) for p in sorted(logs_dir.glob(pattern))]
        out[label] = dict(
            json.loads(cli("residuals", *logs, "--vehicle", str(IRIS_VEHICLE), "--json"))
        )
    return out


def _selected(result: Residuals) -> str:
    """What was selected, each with its parameters' spread over the folds; or why nothing."""
    if not result["effects"]:
        best = max((c["r2"] for c in result["attribution"]["channels"]), default=0.0)
        return (
            f"none — {result['rmse_to_floor']:.1f}× its noise floor of "
            f"{result['noise_floor_w']:.1f} W; best channel R² {best:.2f}"
        )
    return "; then ".join(
        e["description"]
        + " (fold σ "
        + ", ".join(f"{k} {v:.2g}" for k, v in e["params_fold_sd"].items())
        + ")"
        for e in result["effects"]
    )


def iris_table(results: Mapping[str, Residuals]) -> str:
    """Per IRIS+ period: samples and flights analysed, held-out RMSE and MAPE before → after,
    and what was selected."""
    lines = [
        "| data | samples / flights | held-out RMSE before → after (W) "
        "| MAPE before → after (%) | selected |",
        "|---|---|---|---|---|",
    ]
    for label, r in results.items():
        lines.append(
            f"| {label} | {r['n_samples']:,} / {r['n_flights']} "
            f"| {r['rmse_before_w']:.1f} → {r['rmse_after_w']:.1f} "
            f"| {r['mape_before_pct']:.2f} → {r['mape_after_pct']:.2f} | {_selected(r)} |"
        )
    return "\n".join(lines)


def iris_summer(results: Mapping[str, Residuals]) -> str:
    """README.md's June–August figures: held-out RMSE and MAPE before → after."""
    r = results["June–August"]
    return (
        f"held-out RMSE {r['rmse_before_w']:.1f} → {r['rmse_after_w']:.1f} W (MAPE "
        f"{r['mape_before_pct']:.2f} → {r['mape_after_pct']:.2f} %)"
    )


def named(result: Residuals) -> str:
    """The effects selected, in order ("none" without one)."""
    return "; then ".join(e["description"] for e in result["effects"]) or "none"


def hidden_table(results: Mapping[str, Residuals]) -> str:
    """Per hidden effect: what was named, held-out RMSE and MAPE before → after, noise floor."""
    lines = [
        "| hidden (sim flag) | named | held-out RMSE before → after (W) "
        "| MAPE before → after (%) | noise floor (W) |",
        "|---|---|---|---|---|",
    ]
    for label, r in results.items():
        mark = " ¹" if label == STEP_ROW else ""
        lines.append(
            f"| {label} | {named(r)} | {r['rmse_before_w']:.1f} → {r['rmse_after_w']:.1f}{mark} "
            f"| {r['mape_before_pct']:.2f} → {r['mape_after_pct']:.2f} "
            f"| {r['noise_floor_w']:.1f} |"
        )
    return "\n".join(lines)


def step_footnote(result: Residuals) -> str:
    """The mass step's held-out RMSE in noise floors, and its in-sample fit."""
    return (
        f"{result['rmse_after_w']:.1f} W held out ({result['rmse_to_floor']:.1f} noise floors), "
        f"{result['rmse_in_sample_w']:.1f} W in-sample"
    )


def changing_table(results: Mapping[str, Residuals]) -> str:
    """Per effect that changes during the flight: what was named, held-out RMSE before →
    after (and the final effects' in-sample RMSE), MAPE before → after, noise floor."""
    lines = [
        "| hidden | named (in order) | held-out RMSE before → after (W) "
        "| MAPE before → after (%) | noise floor (W) |",
        "|---|---|---|---|---|",
    ]
    for label, r in results.items():
        lines.append(
            f"| {label} | {named(r)} | {r['rmse_before_w']:.1f} → {r['rmse_after_w']:.1f} "
            f"(in-sample {r['rmse_in_sample_w']:.1f}) "
            f"| {r['mape_before_pct']:.2f} → {r['mape_after_pct']:.2f} "
            f"| {r['noise_floor_w']:.1f} |"
        )
    return "\n".join(lines)


def changing_floors(results: Mapping[str, Residuals]) -> str:
    """The largest held-out RMSE after, in noise floors, over the flights whose effect
    changes."""
    return f"{max(r['rmse_to_floor'] for r in results.values()):.1f}"


def replay_table(replays: Mapping[str, Mapping[str, Residuals]]) -> str:
    """Replay power RMSE (W), MAPE (%) and energy (Wh) with the built-in vehicle → with the
    written file, wind and mass held at the files' values."""
    lines = [
        "| flight | replay power RMSE before → after (W) | MAPE (%) "
        "| energy measured / predicted before → after (Wh) |",
        "|---|---|---|---|",
    ]
    for label, r in replays.items():
        before, after = r["held-before"], r["held-after"]
        lines.append(
            f"| {REPLAYED[label]} | {before['power_rmse_w']:.2f} → {after['power_rmse_w']:.2f} "
            f"| {before['power_mape_pct']:.2f} → {after['power_mape_pct']:.2f} "
            f"| {before['energy_measured_wh']:.2f} / {before['energy_predicted_wh']:.2f} → "
            f"{after['energy_predicted_wh']:.2f} |"
        )
    return "\n".join(lines)


def tracked_replay(replays: Mapping[str, Residuals]) -> str:
    """The same replay with wind and mass tracked online (the default)."""
    before, after = replays["tracked-before"], replays["tracked-after"]
    return (
        f"**{before['power_rmse_w']:.2f} → {after['power_rmse_w']:.2f} W** RMSE (MAPE "
        f"{before['power_mape_pct']:.2f} → {after['power_mape_pct']:.2f} %; energy "
        f"{before['energy_predicted_wh']:.2f} → {after['energy_predicted_wh']:.2f} Wh predicted "
        f"against {after['energy_measured_wh']:.2f} Wh measured)"
    )


def recovered(results: Mapping[str, Residuals]) -> str:
    """README.md's examples: each hidden effect → the first effect named, as fitted."""
    parts = []
    for label, (hidden, spec) in RECOVERED.items():
        p = results[label]["effects"][0]["params"]
        if spec is None:  # the wind
            found = f"{p['speed_mps']:.2f} m/s from {p['from_deg']:.1f}°"
        else:
            name, fmt, unit = spec
            found = f"{p[name]:{fmt}}{unit}"
        parts.append(f"{hidden} → {found}")
    return ", ".join(parts)


def wind_rmse(results: Mapping[str, Residuals]) -> str:
    r = results[WIND_ROW]
    return f"wind {r['rmse_before_w']:.1f} → {r['rmse_after_w']:.1f} W"


def generators(cli: Cli) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the flights with an effect hidden all
    flight or stepping once (:func:`hidden_runs`)."""
    return {
        "residuals-sim-table": lambda: hidden_table(hidden_runs(cli)[0]),
        "residuals-sim-step": lambda: step_footnote(hidden_runs(cli)[0][STEP_ROW]),
        "residuals-sim-recovered": lambda: recovered(hidden_runs(cli)[0]),
        "residuals-sim-wind": lambda: wind_rmse(hidden_runs(cli)[0]),
        "residuals-sim-replay": lambda: replay_table(hidden_runs(cli)[1]),
        "residuals-sim-tracked": lambda: tracked_replay(hidden_runs(cli)[1][WIND_ROW]),
    }


def changing_generators(cli: Cli) -> dict[str, Callable[[], str]]:
    """The blocks of the flights whose effects change (:func:`changing_runs`, ≈ 50 s of
    CPU)."""
    return {
        "residuals-sim-changing": lambda: changing_table(changing_runs(cli)),
        "residuals-sim-changing-floors": lambda: changing_floors(changing_runs(cli)),
    }


def iris_generators(cli: Cli, logs_dir: Path) -> dict[str, Callable[[], str]]:
    """The blocks of the IRIS+ logs under ``logs_dir`` (:func:`iris_runs`)."""
    return {
        "residuals-iris-table": lambda: iris_table(iris_runs(cli, logs_dir)),
        "residuals-iris-summer": lambda: iris_summer(iris_runs(cli, logs_dir)),
    }
