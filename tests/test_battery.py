"""The pack curve: a vehicle file may give its pack's resting cell voltage per state of charge."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from estimator.errors import UserError
from estimator.physics.battery import CELL_OCV_POINTS_V, PackModel
from estimator.physics.vehicle import BatterySpec, default_vehicle, load_vehicle
from estimator.sim.pack_drain import drain_pack
from estimator.sitl.pack import SOC_TABLE, resting_cell_voltage_v

REPO = Path(__file__).resolve().parent.parent
#: ArduPilot SITL's pack curve as the SITL vehicle file carries it.
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"


def sitl_curve() -> tuple[float, ...]:
    curve = load_vehicle(SITL_VEHICLE).battery.cell_ocv_v
    assert curve is not None
    return curve


def test_a_pack_curve_round_trips_through_the_vehicle_file(tmp_path: Path) -> None:
    vehicle = default_vehicle()
    battery = replace(vehicle.battery, cell_ocv_v=sitl_curve())
    path = tmp_path / "v.toml"
    replace(vehicle, battery=battery).save(path)
    assert load_vehicle(path).battery == battery
    # without one, the file says nothing and the built-in curve is used
    vehicle.save(path)
    assert "cell_ocv_v" not in path.read_text()
    assert np.array_equal(PackModel(load_vehicle(path).battery).cell_ocv_v, CELL_OCV_POINTS_V)


def test_the_pack_model_follows_the_configured_curve() -> None:
    curve = sitl_curve()
    pack = PackModel(BatterySpec(capacity_ah=2.2, cells=3, cell_ocv_v=curve))
    half = (len(curve) - 1) // 2  # the table is evenly spaced from SoC 0 to 1
    assert pack.ocv_v(0.5) == pytest.approx(3 * curve[half])
    assert pack.soc_from_ocv(3 * curve[4]) == pytest.approx(pack.soc_points[4])
    # energy from empty to full is the charge times the mean voltage over the table
    mean_v = float(np.mean(0.5 * (np.asarray(curve[1:]) + np.asarray(curve[:-1]))))
    assert pack.energy_wh(1.0) == pytest.approx(3 * 2.2 * mean_v)
    assert pack.soc_from_energy(pack.energy_wh(0.37)) == pytest.approx(0.37)


def test_a_curve_that_sags_more_holds_less_energy_above_the_reserve() -> None:
    # SITL's curve sits up to 0.3 V/cell below the built-in LiPo curve at low charge: taking
    # one for the other overstates the energy left, hence the endurance, by a few percent
    builtin = PackModel(BatterySpec(capacity_ah=2.2, cells=3))
    sitl = PackModel(BatterySpec(capacity_ah=2.2, cells=3, cell_ocv_v=sitl_curve()))
    ratio = builtin.usable_energy_wh(1.0) / sitl.usable_energy_wh(1.0)
    assert 1.02 < ratio < 1.06


@pytest.mark.parametrize(
    ("value", "says"),
    [
        ([3.7] * 10, "list of 11 to 201 cell voltages"),
        ("3.7", "list of 11 to 201 cell voltages"),
        ([3.0 + 0.05 * i for i in range(20)] + [True], "list of 11 to 201 cell voltages"),
        ([3.0 + 0.001 * i for i in range(202)], "list of 11 to 201 cell voltages"),
        ([3.0 + 0.05 * i for i in range(21)][::-1], "must rise"),
        ([1.0 + 0.05 * i for i in range(21)], "between 2 and 4.5 V"),
    ],
)
def test_a_bad_pack_curve_is_one_clear_error(tmp_path: Path, value: object, says: str) -> None:
    path = tmp_path / "v.toml"
    default_vehicle().save(path)
    text = path.read_text().replace("[battery]\n", f"[battery]\ncell_ocv_v = {value!r}\n")
    path.write_text(text.replace("'", '"').replace("True", "true"))
    with pytest.raises(UserError, match=says) as err:
        load_vehicle(path)
    assert "\n" not in str(err.value)


def test_the_simulator_drains_a_pack_along_its_curve() -> None:
    curve = sitl_curve()
    pack = PackModel(BatterySpec(capacity_ah=2.2, cells=3, cell_ocv_v=curve))
    volts, _amps, socs, n = drain_pack(pack, np.full(5, 300.0), soc0=0.5)
    assert n == 5
    assert volts[0] == pytest.approx(3 * curve[(len(curve) - 1) // 2])
    assert np.all(np.diff(socs) < 0)


def test_the_sitl_curve_is_as_good_as_its_file_says() -> None:
    """``cell_ocv_sigma_v`` of the SITL vehicle file against SITL's own table (scaled to
    4.2 V per cell as SITL does): RMS within the σ and no point beyond 2σ, from 5 % charge
    (below, SITL's curve falls towards 0 V and is never flown)."""
    battery = load_vehicle(SITL_VEHICLE).battery
    assert battery.cell_ocv_sigma_v is not None and battery.cell_ocv_v is not None
    soc = np.linspace(0.05, 1.0, 20001)
    table_v = 4.2 / SOC_TABLE[0][0] * np.array([resting_cell_voltage_v(s) for s in soc])
    file_v = np.interp(soc, np.linspace(0.0, 1.0, len(battery.cell_ocv_v)), battery.cell_ocv_v)
    error_v = file_v - table_v
    assert np.sqrt(np.mean(error_v**2)) <= battery.cell_ocv_sigma_v
    assert np.abs(error_v).max() <= 2.0 * battery.cell_ocv_sigma_v


def test_a_curve_sigma_comes_with_its_curve(tmp_path: Path) -> None:
    doc = SITL_VEHICLE.read_text()
    path = tmp_path / "v.toml"
    path.write_text(doc.replace("cell_ocv_sigma_v = 0.001", "cell_ocv_sigma_v = -1"))
    with pytest.raises(UserError, match="cell_ocv_sigma_v' must be between"):
        load_vehicle(path)
    path.write_text("\n".join(ln for ln in doc.splitlines() if not ln.startswith("cell_ocv_v")))
    with pytest.raises(UserError, match="give both"):
        load_vehicle(path)


def test_the_scalar_curve_lookups_give_numpy_s_values_to_the_bit() -> None:
    """The pipeline's per-period lookups (OCV, energy, charge from energy) skip numpy for one
    value: every figure must stay the float numpy gives, on table points, between them,
    beyond the ends and for NaN, on the built-in and a pack's own curve."""
    rng = np.random.default_rng(11)
    for battery in (default_vehicle().battery, load_vehicle(SITL_VEHICLE).battery):
        pack = PackModel(battery)
        full_wh = float(pack.energy_wh(1.0))
        socs = [*rng.uniform(-0.2, 1.2, 3000), *pack.soc_points, 0.0, -0.0, 1.0, math.nan]
        energies = [*rng.uniform(-1.0, 1.2 * full_wh, 3000), *(pack.soc_points * full_wh)]
        for soc in socs:
            for numpy_v, scalar_v in (
                (float(pack.ocv_v(soc)), pack.ocv_scalar_v(soc)),
                (float(pack.energy_wh(soc)), pack.energy_scalar_wh(soc)),
            ):
                assert numpy_v == scalar_v or (math.isnan(numpy_v) and math.isnan(scalar_v))
        for energy_wh in energies:
            assert float(pack.soc_from_energy(energy_wh)) == pack.soc_from_energy_scalar(energy_wh)


def test_the_ocv_at_an_energy_is_the_ocv_at_its_charge() -> None:
    """The endurance integral's one lookup of the OCV at each energy level equals the OCV at
    the charge holding that energy (both tables are linear on the same segments), on and
    between the table's points and beyond its ends, for the label and a learned capacity."""
    rng = np.random.default_rng(5)
    for battery in (default_vehicle().battery, load_vehicle(SITL_VEHICLE).battery):
        for capacity_ah in (battery.capacity_ah, 0.8 * battery.capacity_ah):
            pack = PackModel(replace(battery, capacity_ah=capacity_ah))
            full_wh = float(pack.energy_wh(1.0))
            energies = np.concatenate(
                (rng.uniform(-1.0, 1.2 * full_wh, 3000), pack.energy_wh(pack.soc_points))
            )
            composed_v = pack.ocv_v(pack.soc_from_energy(energies))
            np.testing.assert_allclose(pack.ocv_from_energy_v(energies), composed_v, rtol=1e-12)
