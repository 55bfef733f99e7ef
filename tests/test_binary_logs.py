"""ArduPilot DataFlash (.bin) and PX4 ULog (.ulg) readers, on spec-faithful fixtures."""

from __future__ import annotations

import itertools
import math
import random
from pathlib import Path

import numpy as np
import pytest
from fixtures.dataflash_writer import DataFlashWriter
from fixtures.flight import ARM_S, DISARM_S, Truth, make_truth, write_bin, write_ulg
from fixtures.ulog_writer import ULogWriter
from pymavlink.DFReader import DFReader_binary
from pyulog import ULog

from estimator.errors import UserError
from estimator.logs import SampleStream, detect_format, iter_samples, ulog
from estimator.telemetry.samples import ArmedSample, BatterySample, Sample, VelocitySample


@pytest.fixture(scope="module")
def truth() -> Truth:
    return make_truth()


def _read(path: Path) -> tuple[list[Sample], SampleStream]:
    stream = iter_samples(path)
    return list(stream), stream


def _of(samples: list[Sample], kind: type) -> list:
    return [s for s in samples if isinstance(s, kind)]


def _in_time_order(samples: list[Sample]) -> bool:
    times = [s.time_s for s in samples]
    return all(a <= b for a, b in itertools.pairwise(times))


# -- the fixtures are the real formats ---------------------------------------------------------


def test_dataflash_fixture_is_read_by_pymavlink_with_the_written_values(
    tmp_path: Path, truth: Truth
) -> None:
    path = write_bin(tmp_path / "f.bin", truth)
    log = DFReader_binary(str(path))
    xkf1 = []
    while (msg := log.recv_match(type=["XKF1"])) is not None:
        if msg.C == 0:
            xkf1.append((msg.VN, msg.VE, msg.VD, msg.PD))
    assert len(xkf1) == len(truth.velocity_time_s)
    got = np.array(xkf1)
    np.testing.assert_allclose(got[:, :3], truth.v_ned_mps, atol=1e-5)
    np.testing.assert_allclose(-got[:, 3], truth.alt_m, atol=1e-4)


def test_ulog_fixture_is_read_by_pyulog_without_corruption(tmp_path: Path, truth: Truth) -> None:
    path = write_ulg(tmp_path / "f.ulg", truth)
    ulog = ULog(str(path))
    assert not ulog.file_corruption
    position = ulog.get_dataset("vehicle_local_position").data
    np.testing.assert_allclose(position["vx"], truth.v_ned_mps[:, 0], atol=1e-5)
    battery = ulog.get_dataset("battery_status", 0).data
    np.testing.assert_allclose(battery["voltage_v"], truth.voltage_v, rtol=1e-6)


def test_formats_are_recognised_by_content_not_name(tmp_path: Path) -> None:
    assert detect_format(write_bin(tmp_path / "a.log")) == "dataflash"
    assert detect_format(write_ulg(tmp_path / "b.bin")) == "ulog"


# -- DataFlash ---------------------------------------------------------------------------------


@pytest.mark.parametrize("velocity", ["XKF1", "NKF1", "GPS"])
def test_dataflash_velocity_source_gives_the_flown_velocity(
    tmp_path: Path, truth: Truth, velocity: str
) -> None:
    samples, stream = _read(write_bin(tmp_path / "f.bin", truth, velocity=velocity))
    v = _of(samples, VelocitySample)
    assert len(v) == len(truth.velocity_time_s)
    got = np.array([(s.vn_mps, s.ve_mps, s.vd_mps, s.alt_m) for s in v])
    # XKF1's second core logs VN + 3 m/s: only the first core may come through
    np.testing.assert_allclose(got[:, :3], truth.v_ned_mps, atol=2e-3)
    np.testing.assert_allclose(got[:, 3], truth.alt_m, atol=0.02)
    assert _in_time_order(samples)
    assert (stream.skipped, stream.bad_frames, stream.truncated) == (0, 0, False)


def test_dataflash_battery_and_arming(tmp_path: Path, truth: Truth) -> None:
    samples, _ = _read(write_bin(tmp_path / "f.bin", truth))
    bat = _of(samples, BatterySample)
    assert len(bat) == len(truth.battery_time_s)
    np.testing.assert_allclose([b.voltage_v for b in bat], truth.voltage_v, rtol=1e-6)
    np.testing.assert_allclose([b.current_a for b in bat], truth.current_a, rtol=1e-6)
    np.testing.assert_allclose([b.consumed_mah for b in bat], truth.consumed_mah, rtol=1e-5)
    armed = _of(samples, ArmedSample)
    assert [(round(a.time_s), a.armed) for a in armed] == [(ARM_S, True), (DISARM_S, False)]


def test_dataflash_unknown_values_become_none_and_other_batteries_are_ignored(
    tmp_path: Path,
) -> None:
    log = DataFlashWriter()
    log.define("BAT")
    log.define("EV")
    log.write("EV", TimeUS=500_000, Id=10)
    log.write("BAT", TimeUS=1_000_000, Inst=0, Volt=12.1, Curr=math.nan, CurrTot=math.nan)
    log.write("BAT", TimeUS=1_000_100, Inst=1, Volt=3.3, Curr=1.0, CurrTot=5.0)
    log.write("BAT", TimeUS=2_000_000, Inst=0, Volt=math.nan, Curr=10.0, CurrTot=5.0)
    log.write("BAT", TimeUS=3_000_000, Inst=0, Volt=12.0, Curr=10.0, CurrTot=5.0, RemPct=255)
    log.write("EV", TimeUS=4_000_000, Id=11)
    samples, stream = _read(log.save(tmp_path / "bat.bin"))
    bat = _of(samples, BatterySample)
    assert [(b.time_s, b.current_a, b.consumed_mah) for b in bat] == [
        (1.0, None, None),
        (3.0, pytest.approx(10.0), pytest.approx(5.0)),
    ]
    assert bat[1].remaining_pct is None  # 255: not a percentage
    assert stream.skipped == 1  # the NaN voltage
    assert [(a.time_s, a.armed) for a in _of(samples, ArmedSample)] == [(0.5, True), (4.0, False)]


def test_dataflash_old_curr_message_gives_volts_and_amps(tmp_path: Path) -> None:
    log = DataFlashWriter()
    log.define("CURR")  # Copter 3.3: Volt and Curr as integer centivolts / centiamps
    log.write("CURR", TimeUS=1_000_000, Volt=1187, Curr=1234, Vcc=5000, CurrTot=150.5)
    samples, _ = _read(log.save(tmp_path / "curr.bin"))
    assert samples == [BatterySample(1.0, 11.87, 12.34, 150.5, None)]


def test_dataflash_truncated_file_reads_up_to_the_damage(tmp_path: Path, truth: Truth) -> None:
    data = write_bin(tmp_path / "f.bin", truth).read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(data[: len(data) // 2 + 7])
    samples, stream = _read(cut)
    assert stream.truncated
    assert 300 < len(samples) < 600 and _in_time_order(samples)
    assert max(s.time_s for s in samples) > 25.0


def test_dataflash_corrupt_region_is_counted_and_skipped(tmp_path: Path, truth: Truth) -> None:
    data = write_bin(tmp_path / "f.bin", truth).read_bytes()
    bad = tmp_path / "bad.bin"
    bad.write_bytes(data[:40_000] + b"\x00garbage" * 10 + data[40_000:])
    samples, stream = _read(bad)
    assert stream.bad_frames == 1 and not stream.truncated
    assert len(_of(samples, VelocitySample)) >= len(truth.velocity_time_s) - 2


@pytest.mark.parametrize("seed", range(20))
def test_dataflash_magic_followed_by_noise_is_a_user_error(tmp_path: Path, seed: int) -> None:
    """Seeded noise (it was os.urandom: the reader's words depend on the bytes, and one draw in
    a few dozen met a FMT it could not parse, which the test took for a failure): whatever the
    bytes, one sentence naming the file as no DataFlash log it can read."""
    noise = tmp_path / "noise.bin"
    noise.write_bytes(b"\xa3\x95" + random.Random(seed).randbytes(4000))
    with pytest.raises(UserError, match=r"(not a DataFlash log|cannot read DataFlash log)") as err:
        iter_samples(noise)
    assert "\n" not in str(err.value)


# -- ULog --------------------------------------------------------------------------------------


def test_ulog_gives_the_flown_velocity_battery_and_arming(tmp_path: Path, truth: Truth) -> None:
    samples, stream = _read(write_ulg(tmp_path / "f.ulg", truth))
    v = _of(samples, VelocitySample)
    np.testing.assert_allclose(
        [(s.vn_mps, s.ve_mps, s.vd_mps) for s in v], truth.v_ned_mps, atol=1e-5
    )
    bat = _of(samples, BatterySample)  # instance 1 (3.0 V) must not appear
    np.testing.assert_allclose([b.voltage_v for b in bat], truth.voltage_v, rtol=1e-6)
    assert bat[0].remaining_pct == pytest.approx(100.0, abs=0.01)
    armed = [(round(a.time_s), a.armed) for a in _of(samples, ArmedSample)]
    assert armed == [(0, False), (ARM_S, True), (DISARM_S, False)]
    assert _in_time_order(samples)
    assert (stream.skipped, stream.bad_frames, stream.truncated) == (0, 0, False)


def test_ulog_unknown_current_and_invalid_velocity(tmp_path: Path) -> None:
    log = ULogWriter()
    log.add_format("battery_status")
    log.add_format("vehicle_local_position")
    log.subscribe("battery_status")
    log.subscribe("vehicle_local_position")
    log.write("battery_status", timestamp=1_000_000, voltage_v=16.0, current_a=-1.0,
              discharged_mah=-1.0, remaining=-1.0, connected=True)  # fmt: skip
    log.write("battery_status", timestamp=2_000_000, voltage_v=16.0, current_a=5.0,
              connected=False)  # fmt: skip
    log.write("vehicle_local_position", timestamp=1_500_000, vx=1.0, v_xy_valid=False,
              v_z_valid=True)  # fmt: skip
    log.write("vehicle_local_position", timestamp=2_500_000, vx=2.0, z=-3.0, v_xy_valid=True,
              v_z_valid=True)  # fmt: skip
    samples, stream = _read(log.save(tmp_path / "u.ulg"))
    assert samples == [
        BatterySample(1.0, 16.0, None, None, None),
        VelocitySample(2.5, 2.0, 0.0, 0.0, 3.0),
    ]
    assert stream.skipped == 2


#: The GPS fields the reader uses, as PX4 ≤ 1.14 (``alt``, mm) and ≥ 1.15 (``altitude_msl_m``)
#: log them.
_GPS_FIELDS = [("uint8_t", "fix_type"), ("bool", "vel_ned_valid"), ("float", "vel_n_m_s"),
               ("float", "vel_e_m_s"), ("float", "vel_d_m_s")]  # fmt: skip
_GPS_ALTITUDES = {"vehicle_gps_position": ("int32_t", "alt"),
                  "sensor_gps": ("double", "altitude_msl_m")}  # fmt: skip


@pytest.mark.parametrize("topic", ["vehicle_gps_position", "sensor_gps"])
def test_ulog_without_a_valid_local_velocity_takes_the_gps_with_a_3d_fix(
    tmp_path: Path, topic: str
) -> None:
    alt_type, alt_name = _GPS_ALTITUDES[topic]
    log = ULogWriter()
    log.add_format("vehicle_local_position")
    log.add_format(topic, [("uint64_t", "timestamp"), (alt_type, alt_name), *_GPS_FIELDS])
    log.subscribe("vehicle_local_position")
    log.subscribe(topic)
    log.write("vehicle_local_position", timestamp=1_000_000, vx=1.0, v_xy_valid=False)
    for t_us, fix, alt_m, vn in ((1_100_000, 2, 100.0, 9.0), (1_200_000, 3, 101.0, 2.0),
                                 (1_300_000, 3, 104.0, 3.0)):  # fmt: skip
        alt = round(alt_m * 1000) if alt_name == "alt" else alt_m  # mm in PX4 ≤ 1.14
        log.write(topic, timestamp=t_us, fix_type=fix, vel_ned_valid=True, vel_n_m_s=vn,
                  vel_d_m_s=-1.0, **{alt_name: alt})  # fmt: skip
    samples, stream = _read(log.save(tmp_path / "gps.ulg"))
    assert samples == [VelocitySample(1.2, 2.0, 0.0, -1.0, 0.0),
                       VelocitySample(1.3, 3.0, 0.0, -1.0, 3.0)]  # fmt: skip
    assert stream.velocity_source == f"{topic}.vel_d_m_s"
    assert stream.skipped == 2  # the invalid local velocity, the 2-D fix


def test_ulog_takes_the_battery_instance_with_a_connected_pack(tmp_path: Path) -> None:
    log = ULogWriter()
    log.add_format("battery_status")
    log.subscribe("battery_status", multi_id=0)  # logged, but no pack connected
    log.subscribe("battery_status", multi_id=1)
    for k in range(3):
        t = 1_000_000 * (k + 1)
        log.write("battery_status", 0, timestamp=t, voltage_v=0.0, connected=False)
        log.write("battery_status", 1, timestamp=t + 10, voltage_v=15.5, current_a=9.0,
                  connected=True)  # fmt: skip
    samples, _ = _read(log.save(tmp_path / "two.ulg"))
    assert [(b.voltage_v, b.current_a) for b in _of(samples, BatterySample)] == [(15.5, 9.0)] * 3


def test_ulog_truncated_file_reads_up_to_the_damage(tmp_path: Path, truth: Truth) -> None:
    data = write_ulg(tmp_path / "f.ulg", truth).read_bytes()
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(data[: len(data) // 2 + 7])  # inside a data message
    samples, stream = _read(cut)
    assert stream.truncated
    assert 300 < len(samples) < 700 and _in_time_order(samples)


def _long_ulog() -> bytes:
    """A ULog of 4000 local positions and batteries (about 250 kB: longer than the tail
    whose reads are watched), its last record a battery reading."""
    log = ULogWriter(start_timestamp_us=1000)
    for topic in ("vehicle_local_position", "battery_status"):
        log.add_format(topic)
        log.subscribe(topic)
    for k in range(4000):
        t = 1_000_000 + 100_000 * k
        log.write("vehicle_local_position", timestamp=t, vx=1.0, v_xy_valid=True, v_z_valid=True)
        log.write("battery_status", timestamp=t, voltage_v=16.0, current_a=10.0, connected=True)
    return log.raw()


#: Bytes cut off the end of :func:`_long_ulog` (its messages: 40 bytes a battery reading, 49 a
#: position): inside the last one's body, its header left whole, 1 or 2 bytes of its header
#: left, at its start, inside the one before, at that one's start, far before; or a message
#: appended that declares the largest body (65535 bytes), cut by 1 byte and whole.
_ULOG_ENDS = [1, 7, 37, 38, 39, 40, 41, 89, 1000]
_HUGE_MESSAGE = b"\xff\xffD" + bytes(0xFFFF)


@pytest.mark.parametrize("end", [*_ULOG_ENDS, "huge-1", "huge"])
def test_ulog_truncation_is_told_as_when_every_read_is_watched(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, end: int | str
) -> None:
    data = _long_ulog()
    if isinstance(end, int):
        data = data[:-end]
    else:
        data += _HUGE_MESSAGE[: len(_HUGE_MESSAGE) - (end == "huge-1")]
    path = tmp_path / "end.ulg"
    path.write_bytes(data)
    tail_only = iter_samples(path)
    monkeypatch.setattr(ulog, "MAX_READ_BYTES", len(data) + 1)  # the whole file is the tail
    every_read = iter_samples(path)
    assert tail_only.truncated == every_read.truncated
    assert (list(tail_only), tail_only.bad_frames) == (list(every_read), every_read.bad_frames)
    if end in (40, 89, "huge"):
        assert not every_read.truncated  # a message boundary
    elif end in (1, 7, 38, 39, 41, "huge-1"):
        assert every_read.truncated


def test_ulog_with_a_bad_header_is_a_user_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"ULog\x00\x00")
    with pytest.raises(UserError, match="not a readable PX4 ULog"):
        iter_samples(bad)


# -- damaged files: a counted skip or one UserError, never anything else ------------------------


def _damaged(data: bytes, rng: random.Random) -> bytes:
    """The log cut short, with bytes overwritten, with junk spliced in, or with a zeroed run."""
    b = bytearray(data)
    mode = rng.choice(["cut", "flip", "splice", "zero"])
    at = rng.randrange(1, len(b))
    if mode == "cut":
        return bytes(b[:at])
    if mode == "flip":
        for _ in range(rng.randrange(1, 50)):
            b[rng.randrange(len(b))] = rng.randrange(256)
    elif mode == "splice":
        b[at:at] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 300)))
    else:
        n = rng.randrange(1, 2000)
        b[at : at + n] = bytes(len(b[at : at + n]))
    return bytes(b)


@pytest.mark.parametrize("writer", [write_bin, write_ulg], ids=["dataflash", "ulog"])
def test_damaged_logs_read_in_time_order_or_fail_with_a_user_error(
    tmp_path: Path, truth: Truth, writer: object
) -> None:
    data = writer(tmp_path / "whole", truth).read_bytes()  # type: ignore[operator]
    rng = random.Random(7)
    for case in range(40):
        path = tmp_path / f"damaged{case}"
        path.write_bytes(_damaged(data, rng))
        try:
            samples, _ = _read(path)
        except UserError:
            continue
        assert _in_time_order(samples), case


# -- a DataFlash log of current ArduCopter ------------------------------------------------------

ARDUCOPTER_BIN = Path(__file__).parent / "data" / "arducopter_guided.bin"
ARDUCOPTER_TLOG = ARDUCOPTER_BIN.with_suffix(".tlog")


def test_current_arducopter_log_opened_at_arming_is_armed_from_its_start() -> None:
    """ArduCopter (LOG_DISARMED 0) opens the log at arming and writes no ARM record of it:
    the first arming record is the disarm. The reader says armed at the first record, and a
    replay scores the airborne part like the tlog of the same flight does."""
    from dataclasses import replace

    from estimator.analysis.replay import replay_log, summarize
    from estimator.physics.vehicle import BatterySpec, default_vehicle

    log = DFReader_binary(str(ARDUCOPTER_BIN))
    arm_states = []
    while (msg := log.recv_match(type=["ARM"])) is not None:
        arm_states.append(msg.ArmState)
    assert arm_states == [0]  # the disarm only

    samples, stream = _read(ARDUCOPTER_BIN)
    armed = _of(samples, ArmedSample)
    assert [a.armed for a in armed] == [True, False]
    assert armed[0].time_s == pytest.approx(samples[0].time_s)
    assert armed[1].time_s == pytest.approx(93.787, abs=0.01)
    assert stream.velocity_source == "XKF1.VD"

    vehicle = replace(default_vehicle(), battery=BatterySpec(3.3, 3, 0.2))
    from_bin = summarize([replay_log(ARDUCOPTER_BIN, vehicle)])
    from_tlog = summarize([replay_log(ARDUCOPTER_TLOG, vehicle)])
    assert from_bin.airborne_s == pytest.approx(from_tlog.airborne_s, abs=2.0)
    assert from_bin.airborne_s > 40
    assert from_bin.power_rmse_w == pytest.approx(from_tlog.power_rmse_w, rel=0.05)
