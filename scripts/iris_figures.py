"""The IRIS+ replay figures of README.md and docs/replay.md, and the two periods' vehicle-file
masses of docs/fleet.md.

- ``iris-replay-*``: the flights of ``../shared/data/iris_quadcopter_logs`` replayed as
  ``uav-energy replay LOG… --vehicle F --json`` does, each period with the vehicle file fitted
  on it (in-sample), and once with the built-in vehicle (no ``--vehicle``);
- ``replay-regression-march``: the March flights' figures frozen in ``replay/expected.json``;
- ``fleet-iris-file-masses``: the masses of the two periods' vehicle files.

``scripts/figures.py`` registers the blocks (:func:`iris_generators`, which read the logs,
and :func:`generators`); ``tests/test_figures.py`` checks them.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from functools import cache, partial
from pathlib import Path
from types import ModuleType

import numpy as np

from estimator.analysis.replay import FlightReplay, Summary, replay_stream, summarize
from estimator.commands.replay import flight_names, vehicle_and_settings
from estimator.logs import iter_samples
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
VEHICLES = REPO / "config" / "vehicles"
#: The two IRIS+ periods: their logs (as the README's ``find`` selects them) and vehicle file.
PERIODS = {
    "March 2016": ("2016-03-*", "iris_plus_2016_03.toml"),
    "June–August 2016": ("2016-0[678]-*", "iris_plus_2016_06_08.toml"),
}
#: The IRIS+ flights docs/replay.md reads the power module's scatter off.
QUIET_IRIS_FLIGHTS = ("2016-08-03/002/002", "2016-08-09/003/003")


def replay(logs: Sequence[Path], vehicle_file: Path | None) -> list[FlightReplay]:
    """``uav-energy replay LOG… [--vehicle F]``'s flights, with its names."""
    vehicle, settings = vehicle_and_settings(vehicle_file, None)
    flights = []
    for path, name in zip(logs, flight_names(logs), strict=True):
        stream = iter_samples(path, "auto", vehicle.input_limits())
        flights.append(replay_stream(stream, vehicle, name, settings))
    return flights


@cache
def iris_periods(iris: Path) -> dict[str, tuple[str, list[FlightReplay]]]:
    """Each period's vehicle file name and its flights (under ``iris``) replayed with it."""
    out = {}
    for period, (pattern, vehicle_name) in PERIODS.items():
        logs = sorted(iris.glob(f"{pattern}/**/*.log"))
        out[period] = (vehicle_name, replay(logs, VEHICLES / vehicle_name))
    return out


def all_flights(iris: Path) -> list[FlightReplay]:
    return [f for _, flights in iris_periods(iris).values() for f in flights]


def _row(name: str, s: Summary) -> str:
    def fmt(x: float | None) -> str:
        return "–" if x is None else f"{x:.1f}"

    return (
        f"| {name} | {s.messages} | {s.airborne_s:.0f} | {s.power_points} "
        f"| {fmt(s.power_rmse_w)} | {fmt(s.power_mape_pct)} "
        f"| {s.energy_measured_wh:.2f} | {s.energy_predicted_wh:.2f} |"
    )


def replay_table(iris: Path) -> str:
    """Per flight, per period and over all logs: samples fed, airborne s, power points, power
    RMSE (W) and MAPE (%) against V·I, energy measured and predicted (Wh)."""
    lines = [
        "| flight | samples | airborne s | power points | RMSE W | MAPE % "
        "| E measured Wh | E model Wh |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    lines += [_row(f.name, summarize([f])) for f in all_flights(iris)]
    for period, (vehicle_name, flights) in iris_periods(iris).items():
        lines.append(_row(f"**{period} (`{vehicle_name}`)**", summarize(flights)))
    everything = all_flights(iris)
    lines.append(_row(f"**all {len(everything)} logs**", summarize(everything)))
    return "\n".join(lines)


def replay_total(iris: Path) -> str:
    s = summarize(all_flights(iris))
    return (
        f"{s.power_rmse_w:.1f} W RMSE, {s.power_mape_pct:.1f} % MAPE over all "
        f"{len(all_flights(iris))}"
    )


def replay_errors(iris: Path) -> str:
    """How the readers fared on every IRIS+ log: logs truncated and corrupt records skipped
    (an unreadable log stops the generator, so none is skipped)."""
    flights = all_flights(iris)
    truncated = [f.name for f in flights if f.truncated]
    corrupt = {f.name: f.bad_frames for f in flights if f.bad_frames}
    cut = f"{len(truncated)} truncated ({', '.join(truncated)})" if truncated else "none truncated"
    records = sum(corrupt.values())
    return (
        f"all {len(flights)} logs replay without error: {cut}, {records} corrupt "
        f"record{'s' if records != 1 else ''} skipped and counted"
        + (f" (in {', '.join(corrupt)})" if corrupt else "")
    )


def replay_periods(iris: Path) -> str:
    """The two periods' RMSE and MAPE ranges, and how close each one's energy comes."""
    summaries = {p: summarize(flights) for p, (_, flights) in iris_periods(iris).items()}
    rmse = sorted(s.power_rmse_w or 0.0 for s in summaries.values())
    mape = sorted(s.power_mape_pct or 0.0 for s in summaries.values())
    energy = " and ".join(
        f"{100 * abs(s.energy_predicted_wh / s.energy_measured_wh - 1):.1f} % ({p.split()[0]})"
        for p, s in summaries.items()
    )
    return (
        f"**{rmse[0]:.1f}–{rmse[-1]:.1f} W RMSE ({mape[0]:.1f}–{mape[-1]:.1f} % MAPE)** "
        f"in-sample, and over a whole period to {energy} of the measured energy"
    )


def _airborne_power(flight: FlightReplay) -> tuple[np.ndarray, np.ndarray]:
    """A flight's airborne readings: measured and model power (W)."""
    _, measured, model, airborne = flight.power.arrays()
    return measured[airborne], model[airborne]


def power_span(iris: Path) -> str:
    """The 5th–95th percentile of the measured power (W, to 10 W) over every IRIS+ flight's
    airborne readings."""
    measured = np.concatenate([_airborne_power(f)[0] for f in all_flights(iris)])
    low, high = np.round(np.percentile(measured, [5, 95]), -1)
    return f"{low:.0f}–{high:.0f} W"


def reading_noise(iris: Path, fits: ModuleType) -> str:
    """On :data:`QUIET_IRIS_FLIGHTS`: the 1σ of one reading from successive differences (W)
    and the residual σ of the model (W); ``fits``: ``scripts/fit_figures.py`` (its
    :func:`span`)."""
    flights = {f.name: f for f in all_flights(iris)}
    reading, residual = [], []
    for name in QUIET_IRIS_FLIGHTS:
        measured, model = _airborne_power(flights[name])
        reading.append(float(np.std(np.diff(measured)) / np.sqrt(2)))
        residual.append(float(np.std(model - measured)))
    return (
        f"{fits.span(reading, '.1f')} W (1σ of one reading, from their differences, on "
        f"{' and '.join(QUIET_IRIS_FLIGHTS)}, whose residual σ is {fits.span(residual, '.1f')} W)"
    )


def replay_march(iris: Path) -> str:
    """The power RMSE (W) of the March flights replayed with their own vehicle file."""
    _, flights = iris_periods(iris)["March 2016"]
    return f"{summarize(flights).power_rmse_w:.0f} W"


def replay_builtin(iris: Path) -> str:
    """The same logs with the built-in vehicle (no ``--vehicle``)."""
    s = summarize(replay(sorted(iris.glob("**/*.log")), None))
    return (
        f"{s.power_rmse_w:.0f} W RMSE and {s.energy_predicted_wh:.0f} Wh predicted against "
        f"{s.energy_measured_wh:.0f} Wh measured"
    )


def regression_march() -> str:
    """The span of the power RMSE frozen in ``replay/expected.json`` for the March flights
    (replayed there with the June–August vehicle file)."""
    flights = json.loads((REPO / "replay" / "expected.json").read_text())["flights"]
    rmse = [f["power_rmse_w"] for name, f in flights.items() if "/2016-03-" in name]
    return f"{min(rmse):.0f}–{max(rmse):.0f} W RMSE"


def file_masses() -> str:
    """The masses (kg) of the two IRIS+ periods' vehicle files and their ratio."""
    march, summer = (load_vehicle(VEHICLES / name).mass_kg for _, name in PERIODS.values())
    return f"{march:g} → {summer:g} kg (×{summer / march:.2f})"


def iris_generators(iris: Path, fits: ModuleType) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the blocks that read the IRIS+ logs
    (``iris``); ``fits``: ``scripts/fit_figures.py``."""
    return {
        "iris-replay-table": partial(replay_table, iris),
        "iris-replay-total": partial(replay_total, iris),
        "iris-replay-errors": partial(replay_errors, iris),
        "iris-replay-periods": partial(replay_periods, iris),
        "iris-replay-power-span": partial(power_span, iris),
        "iris-replay-reading-noise": partial(reading_noise, iris, fits),
        "iris-replay-march": partial(replay_march, iris),
        "iris-replay-builtin": partial(replay_builtin, iris),
    }


def generators() -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the blocks that read the repository only."""
    return {"replay-regression-march": regression_march, "fleet-iris-file-masses": file_masses}
