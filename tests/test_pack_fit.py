"""``uav-energy fit`` fits the pack: resistance and resting curve from a rest and a long
discharge, on tuning SITL pack flights (replay/sitl_packs/split.json) against SITL's curve
as the SITL vehicle file carries it; logs without a rest or a long discharge say so; hostile
battery readings do not crash the fit."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from estimator.analysis.pack_fit import PackFit, fit_pack
from estimator.cli import main
from estimator.errors import UserError
from estimator.logs import FlightSeries, load_flights
from estimator.physics.vehicle import load_vehicle, vehicle_from_toml

REPO = Path(__file__).resolve().parent.parent
PACKS = REPO / "replay" / "sitl_packs"
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
IRIS = REPO / "replay/iris/2016-08-03/002/002.log"
#: The fitted curve against SITL's over the drawn stretch (V per cell): the method's error
#: on the tuning flights is 0.5–1.6 mV RMS and under 2.6 mV at worst; a resistance left in
#: the curve (10 mΩ × 30 A / 3 cells = 0.1 V) or a charge axis off by 0.02 (≥ 10 mV on SITL's
#: slope) fails these.
RMS_BOUND_V = 0.003
MAX_BOUND_V = 0.006


def _truth(name: str) -> dict[str, float]:
    battery: dict[str, float] = json.loads((PACKS / name / "truth.json").read_text())["battery"]
    return battery


def _flight(name: str) -> FlightSeries:
    assert name in json.loads((PACKS / "split.json").read_text())["tuning"]
    return load_flights([PACKS / name / "flight.tlog"])[0]


def _curve_error_v(fit: PackFit, lo: float, hi: float) -> np.ndarray:
    """The fitted curve less SITL's (the vehicle file's, at the same 1 % points) on [lo, hi]."""
    assert fit.cell_ocv_v is not None
    sitl = np.asarray(load_vehicle(SITL_VEHICLE).battery.cell_ocv_v)
    assert len(sitl) == len(fit.cell_ocv_v)
    soc = np.linspace(0.0, 1.0, len(sitl))
    inside = (soc >= lo) & (soc <= hi)
    return np.asarray(fit.cell_ocv_v - sitl)[inside]


def test_fit_writes_the_sitl_pack_curve_and_resistance(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One charged tuning flight through the command: the vehicle file's curve within a few
    mV/cell of SITL's over the drawn stretch, the resistance within 3 %."""
    name = "pack_c65_r1"
    truth = _truth(name)
    out = tmp_path / "pack.toml"
    argv = ["fit", str(PACKS / name / "flight.tlog"), "--split", "block", "--folds", "3"]
    argv += ["--mass-kg", "3", "--capacity-ah", str(truth["capacity_ah"]), "--out", str(out)]
    assert main([*argv, "--report", str(tmp_path / "report")]) == 0
    err = capsys.readouterr().err
    assert "resting curve fitted from 11 to 100 % charge" in err, err
    battery = load_vehicle(out).battery
    assert battery.cell_ocv_v is not None and len(battery.cell_ocv_v) == 101
    assert battery.internal_resistance_ohm == pytest.approx(truth["internal_resistance_ohm"], 0.03)
    assert battery.cell_ocv_sigma_v is None  # the residual is the readings' noise
    assert "cell_ocv_v fitted by uav-energy fit from 11 to 100 % charge" in out.read_text()
    assert (tmp_path / "report" / "pack.png").stat().st_size > 10_000
    fit = replace(_fit_alone(name), cell_ocv_v=np.asarray(battery.cell_ocv_v))
    error_v = _curve_error_v(fit, 0.12, 1.0)
    assert np.sqrt(np.mean(error_v**2)) <= RMS_BOUND_V
    assert np.max(np.abs(error_v)) <= MAX_BOUND_V


def _fit_alone(name: str) -> PackFit:
    fit, reasons = fit_pack([_flight(name)], 3, _truth(name)["capacity_ah"])
    assert fit is not None and not reasons
    return fit


def test_a_part_charged_flight_is_placed_on_the_charged_flights_curve() -> None:
    """The same pack flown from 50 % after a flight from full: its start charge comes from
    the charged flight's curve (within 0.01), and the pooled curve stays within bounds over
    its stretch. Alone, its start charge is unknown: the resistance only."""
    part, full = "pack_c80_r3_soc50", "pack_c80_r3"
    truth = _truth(part)
    alone, reasons = fit_pack([_flight(part)], 3, truth["capacity_ah"])
    assert alone is not None and alone.cell_ocv_v is None
    assert alone.resistance_ohm == pytest.approx(truth["internal_resistance_ohm"], 0.03)
    assert any("no flight starts charged" in r for r in reasons)
    fit, reasons = fit_pack([_flight(full), _flight(part)], 3, truth["capacity_ah"])
    assert fit is not None and not reasons
    placed = fit.flights[1]
    assert not placed.start_full
    assert placed.start_soc == pytest.approx(truth["start_soc"], abs=0.01)
    stretch = (placed.start_soc - placed.drawn_ah / truth["capacity_ah"], placed.start_soc)
    error_v = _curve_error_v(fit, *stretch)
    assert np.sqrt(np.mean(error_v**2)) <= RMS_BOUND_V
    assert np.max(np.abs(error_v)) <= MAX_BOUND_V


def test_a_flight_without_a_rest_or_discharge_says_so() -> None:
    """The same flight from take-off on (no rest) and its first 10 % of charge (a rest, too
    little drawn): each left out with its reason, no fit."""
    name = "pack_c100_r1"
    flight, capacity_ah = _flight(name), _truth(name)["capacity_ah"]
    airborne = flight.subset(flight.current_a > 5.0)
    fit, reasons = fit_pack([airborne], 3, capacity_ah)
    assert fit is None and reasons == [
        "flight left out: no rest (the current never stays at or below 1 A for 10 s)"
    ]
    consumed = flight.extras["consumed_mah"]
    short = flight.subset(~(consumed > 0.1 * 1000 * capacity_ah))
    fit, reasons = fit_pack([short], 3, capacity_ah)
    assert fit is None and len(reasons) == 1
    assert "too little discharge (10 % of 5 Ah drawn, at least 20 % needed)" in reasons[0]


def test_the_command_says_so_in_one_line_and_fits_the_power_model(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A short real IRIS+ flight: one line on the pack, the power model fitted, exit 0; the
    JSON names the reason."""
    argv = ["fit", str(IRIS), "--split", "block", "--folds", "3", "--capacity-ah", "5.1"]
    assert main([*argv, "--json"]) == 0
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if "pack" in line]
    assert lines == [
        "uav-energy fit: pack: 002 left out: too little discharge (8 % of 5.1 Ah drawn, at "
        "least 20 % needed)",
        "uav-energy fit: pack: not fitted (the power model is)",
    ]
    summary = json.loads(captured.out)
    assert summary["pack"] is None and summary["n_points"] > 0
    assert main(argv[:-2]) == 0
    assert "pack: its charge axis needs --capacity-ah" in capsys.readouterr().err


def test_hostile_battery_readings_do_not_crash_the_fit() -> None:
    """NaN, infinite and huge voltages, currents and counters scattered through a flight: the
    readings are dropped (the counter, now jumping, gives way to the current integrated) and
    the fit stays within bounds; all-NaN readings are one reason, not a crash."""
    name = "pack_c65_r1"
    flight = _flight(name)
    rng = np.random.default_rng(7)
    n = len(flight)
    voltage, current = flight.voltage_v.copy(), flight.current_a.copy()
    consumed = flight.extras["consumed_mah"].copy()
    for column in (voltage, current, consumed):
        hit = rng.choice(n, size=n // 50, replace=False)
        column[hit] = rng.choice([np.nan, np.inf, -np.inf, 1e30, -1e30], size=len(hit))
    hostile = replace(
        flight,
        voltage_v=voltage,
        current_a=current,
        extras={**flight.extras, "consumed_mah": consumed},
    )
    fit, _ = fit_pack([hostile], 3, _truth(name)["capacity_ah"])
    assert fit is not None and fit.flights[0].charge_source == "integrated"
    assert fit.resistance_ohm == pytest.approx(_truth(name)["internal_resistance_ohm"], 0.05)
    assert np.sqrt(np.mean(_curve_error_v(fit, 0.12, 1.0) ** 2)) <= 2 * RMS_BOUND_V
    fit, reasons = fit_pack([flight], 3, 0.001)
    assert fit is None and "more than a pack of that capacity holds" in reasons[0]
    blank = replace(flight, voltage_v=np.full(n, np.nan), current_a=np.full(n, np.nan))
    fit, reasons = fit_pack([blank], 3, 3.25)
    assert fit is None and reasons == ["flight left out: no pack voltage and current readings"]


def test_the_vehicle_file_bounds_the_resistance() -> None:
    doc = load_vehicle(SITL_VEHICLE).to_toml()
    for bad in (-0.01, 0.0, 5.0, "x"):
        doc["battery"]["internal_resistance_ohm"] = bad
        with pytest.raises(UserError, match="internal_resistance_ohm"):
            vehicle_from_toml(doc, "v.toml")
    doc["battery"]["internal_resistance_ohm"] = 0.012
    vehicle = vehicle_from_toml(doc, "v.toml")
    assert vehicle.battery.internal_resistance_ohm == 0.012
    assert vehicle_from_toml(vehicle.to_toml()).battery.internal_resistance_ohm == 0.012
