"""ArduCopter DataFlash logs of 2014–2016 (Copter 3.2–3.4 layouts), read and replayed.

The layouts are those of real logs of the time (see :data:`fixtures.dataflash_writer.
COPTER_32_FORMATS`): ``TimeMS`` clocks, ``EKF1`` velocity, ``CURR`` battery, no ``BAT``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fixtures.dataflash_writer import COPTER_32_FORMATS, DataFlashWriter
from fixtures.flight import ARM_S, DISARM_S, Truth, make_truth, write_copter32_bin

from estimator.cli import main
from estimator.errors import UserError
from estimator.logs import iter_samples, load_flights
from estimator.telemetry.samples import ArmedSample, BatterySample, Sample, VelocitySample


@pytest.fixture(scope="module")
def truth() -> Truth:
    return make_truth()


def _read(path: Path) -> list[Sample]:
    return list(iter_samples(path))


def test_copter32_log_gives_boot_time_ekf1_velocity_curr_battery_and_arming(
    tmp_path: Path, truth: Truth
) -> None:
    stream = iter_samples(write_copter32_bin(tmp_path / "old.bin", truth))
    samples = list(stream)
    v = [s for s in samples if isinstance(s, VelocitySample)]
    assert len(v) == len(truth.velocity_time_s)
    np.testing.assert_allclose([s.time_s for s in v], truth.velocity_time_s + 0.002, atol=1e-9)
    got = np.array([(s.vn_mps, s.ve_mps, s.vd_mps, s.alt_m) for s in v])
    np.testing.assert_allclose(got[:, :3], truth.v_ned_mps, atol=1e-5)
    np.testing.assert_allclose(got[:, 3], truth.alt_m, atol=1e-4)
    bat = [s for s in samples if isinstance(s, BatterySample)]
    assert len(bat) == len(truth.battery_time_s)
    np.testing.assert_allclose([b.voltage_v for b in bat], truth.voltage_v, atol=0.005)
    np.testing.assert_allclose([b.current_a for b in bat], truth.current_a, atol=0.005)
    np.testing.assert_allclose([b.consumed_mah for b in bat], truth.consumed_mah, rtol=1e-5)
    armed = [(round(a.time_s), a.armed) for a in samples if isinstance(a, ArmedSample)]
    assert armed == [(ARM_S, True), (DISARM_S, False)]
    assert stream.velocity_source == "EKF1.VD"
    assert (stream.skipped, stream.bad_frames, stream.missing) == (0, 0, None)


def test_copter32_gps_is_timed_by_its_boot_clock_not_the_gps_week(tmp_path: Path) -> None:
    log = DataFlashWriter()
    log.define("GPS", layouts=COPTER_32_FORMATS)
    for i in range(3):
        boot_ms = 1000 * (i + 1)
        log.write("GPS", Status=3, TimeMS=400_000_000 + boot_ms, T=boot_ms, Spd=4.0, GCrs=90.0)
    v = [s for s in _read(log.save(tmp_path / "gps.bin")) if isinstance(s, VelocitySample)]
    assert [s.time_s for s in v] == [1.0, 2.0, 3.0]
    assert v[0].ve_mps == pytest.approx(4.0)


def test_copter34_curr_in_float_volts_and_amps(tmp_path: Path) -> None:
    log = DataFlashWriter()
    log.define("CURR", "Qfff", "TimeUS,Volt,Curr,CurrTot")  # Copter 3.4
    log.write("CURR", TimeUS=2_000_000, Volt=11.87, Curr=12.5, CurrTot=150.5)
    (sample,) = _read(log.save(tmp_path / "curr34.bin"))
    assert sample == BatterySample(2.0, pytest.approx(11.87), 12.5, 150.5, None)


def test_replay_of_a_copter32_log_estimates_its_airborne_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_copter32_bin(tmp_path / "old.bin")
    assert main(["replay", str(path), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    (flight,) = result["flights"]
    assert flight["messages"] > 0
    assert flight["airborne_s"] > 0.5 * (DISARM_S - ARM_S)


def _no_battery_log(path: Path) -> Path:
    log = DataFlashWriter()
    for name in ("EKF1", "GPS", "EV"):
        log.define(name, layouts=COPTER_32_FORMATS)
    for i in range(20):
        log.write("EKF1", TimeMS=100 * i, VN=1.0)
        log.write("GPS", Status=3, T=100 * i, Spd=1.0)
    return log.save(path)


def test_replay_of_a_log_without_battery_names_what_it_has(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _no_battery_log(tmp_path / "nobat.bin")
    assert main(["replay", str(path)]) == 0  # reported, not fatal (the others may replay)
    err = capsys.readouterr().err
    assert f"{path} gave no estimates: no battery record (BAT or CURR); it has EKF1, GPS" in err
    with pytest.raises(UserError, match="no battery record"):
        load_flights([path])


def test_curr_without_a_current_column_says_so(tmp_path: Path) -> None:
    log = DataFlashWriter()
    log.define("EKF1", layouts=COPTER_32_FORMATS)
    log.define("CURR", "IhH", "TimeMS,Volt,Vcc")
    for i in range(20):
        log.write("EKF1", TimeMS=100 * i)
        log.write("CURR", TimeMS=100 * i + 5, Volt=1200, Vcc=5000)
    with pytest.raises(UserError, match="CURR present but no current column; it has EKF1, CURR"):
        load_flights([log.save(tmp_path / "nocurr.bin")])
