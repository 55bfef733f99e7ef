"""Log readers: format by content, tlog speed path and damage handling, CMU CSV layout,
plausibility skips and sanity warnings."""

from __future__ import annotations

import contextlib
import math
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink
from tlog_builder import EPOCH_US, flight_frames, without_firmware_text, write_tlog

from estimator.cli import main as cli_main
from estimator.errors import UserError
from estimator.logs import detect_format, iter_samples, line_endings, load_flights
from estimator.logs.cmu import REQUIRED_COLUMNS, rotate
from estimator.logs.line_endings import CRLF_MIN_PAIRS
from estimator.logs.sanity import flight_warnings
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.plausibility import InputLimits
from estimator.telemetry.samples import BatterySample, GripperSample, VelocitySample

REPO = Path(__file__).resolve().parent.parent
IRIS_MARCH = REPO / "replay/iris/2016-03-14/004/004-F2.log"
IRIS_AUGUST = REPO / "replay/iris/2016-08-03/002/002.log"


# -- format detection ---------------------------------------------------------------------------


def test_iris_log_with_log_extension_is_recognised_as_tlog() -> None:
    assert detect_format(IRIS_MARCH) == "tlog"


def test_formats_are_recognised_by_content_not_name(tmp_path: Path) -> None:
    tlog = write_tlog(tmp_path / "flight.csv", flight_frames(5))
    csv = _cmu_csv(tmp_path / "flight.tlog", [_cmu_row(0.0, 0.0)])
    (tmp_path / "a.log").write_bytes(b"\xa3\x95\x80\x80" + bytes(100))
    (tmp_path / "b.bin").write_bytes(b"ULog\x01\x12\x35" + bytes(100))
    assert detect_format(tlog) == "tlog"
    assert detect_format(csv) == "cmu-csv"
    assert detect_format(tmp_path / "a.log") == "dataflash"
    assert detect_format(tmp_path / "b.bin") == "ulog"


@pytest.mark.parametrize(
    "content", [b"", b"hello world, this is not a flight log\n" * 10, bytes(range(256)) * 4]
)
def test_unrecognised_or_empty_files_are_user_errors(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "x.tlog"
    path.write_bytes(content)
    with pytest.raises(UserError):
        load_flights([path])


def test_directory_and_missing_file_are_user_errors(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="directory"):
        load_flights([tmp_path])
    with pytest.raises(UserError, match="does not exist"):
        load_flights([tmp_path / "nope.tlog"])


# -- tlog -------------------------------------------------------------------------------------


def test_real_iris_log_gives_power_and_velocity_in_autopilot_time() -> None:
    stream = iter_samples(IRIS_MARCH)
    samples = list(stream)
    battery = [s for s in samples if isinstance(s, BatterySample)]
    velocity = [s for s in samples if isinstance(s, VelocitySample)]
    assert len(battery) > 100 and len(velocity) > 100
    assert all(b.current_a is not None for b in battery)
    # arrival order, as the daemon sees it: stamps only step back by link reordering (< 0.2 s)
    times = np.array([s.time_s for s in samples])
    assert np.min(np.diff(times)) > -0.2
    assert np.all(np.diff([b.time_s for b in battery]) >= 0)
    assert stream.skipped > 1000  # unused message types passed over unparsed
    assert not stream.truncated and stream.bad_frames == 0
    flight = load_flights([IRIS_MARCH])[0]
    airborne = flight.alt_m > 1.0
    # March configuration hovers near 135–150 W (source SOURCE.md)
    assert 120 < np.median(flight.power_w[airborne]) < 160
    assert np.all(np.isfinite(flight.power_w))


def test_header_skipping_gives_the_same_samples_as_parsing_every_frame() -> None:
    data = IRIS_AUGUST.read_bytes()
    parser, decoder = FrameParser(), TelemetryDecoder()
    pos, reference = 0, []
    while pos + 8 < len(data):
        length = data[pos + 9] + (8 if data[pos + 8] == 0xFE else 12)
        reference.extend(decoder.decode_all(parser.feed(data[pos + 8 : pos + 8 + length])))
        pos += 8 + length
    assert list(iter_samples(IRIS_AUGUST)) == reference


def test_logs_read_in_several_processes_give_the_same_flights_in_order() -> None:
    logs = sorted((REPO / "replay/iris").glob("*/*/*.log"))
    assert len(logs) == 5
    serial, forked = load_flights(logs), load_flights(logs, workers=2)
    assert [f.flight_id for f in forked] == [f.flight_id for f in serial]
    for a, b in zip(serial, forked, strict=True):
        np.testing.assert_array_equal(a.time_s, b.time_s)
        np.testing.assert_array_equal(a.power_w, b.power_w)
        np.testing.assert_array_equal(a.vn_mps, b.vn_mps)


def test_truncated_tlog_reads_up_to_the_damage(tmp_path: Path) -> None:
    full = list(iter_samples(IRIS_AUGUST))
    cut = tmp_path / "cut.tlog"
    cut.write_bytes(IRIS_AUGUST.read_bytes()[:100_003])
    stream = iter_samples(cut)
    partial = list(stream)
    assert stream.truncated
    assert 0 < len(partial) < len(full)
    assert partial == full[: len(partial)]


def test_corrupt_records_are_counted_and_skipped(tmp_path: Path) -> None:
    data = bytearray(IRIS_AUGUST.read_bytes())
    data[50_000:50_040] = b"\x00" * 40
    bad = tmp_path / "bad.tlog"
    bad.write_bytes(bytes(data))
    stream = iter_samples(bad)
    samples = list(stream)
    assert stream.bad_frames >= 1
    assert not stream.truncated
    assert samples[-1] == list(iter_samples(IRIS_AUGUST))[-1]  # reading resumed after damage


def test_a_tlog_converted_to_crlf_line_endings_is_read_whole_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A text-mode transfer put a CR before every LF byte (a public SITL tlog read 15 s of its
    80 s flight so, and 781 bad frames): read with it undone, the samples are the original's
    (the CR LF pairs the log held itself too), and the replay warns once."""
    original = IRIS_AUGUST.read_bytes()
    assert original.count(b"\n") > 100 and original.count(b"\r\n") > 0
    converted = tmp_path / "crlf.tlog"
    converted.write_bytes(original.replace(b"\n", b"\r\n"))
    stream = iter_samples(converted)
    assert list(stream) == list(iter_samples(IRIS_AUGUST))
    assert stream.bad_frames == 0 and stream.problems()[0][0] == "repaired file"
    assert iter_samples(IRIS_AUGUST).problems() == []
    assert cli_main(["replay", str(converted)]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if "CRLF" in line]
    pairs = original.count(b"\n")
    assert len(said) == 1 and f"follows a CR ({pairs} of them)" in said[0]


@pytest.mark.parametrize(
    "log", ["data/arducopter_guided.bin", "data/corpus/roboto_px4_v1_12.ulg"], ids=["bin", "ulg"]
)
def test_a_binary_log_converted_to_crlf_line_endings_is_read_from_a_repaired_copy(
    log: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """DataFlash and ULog, whose libraries read a file by name or handle: a converted log read
    cryptic errors or nothing at all before (pymavlink: "Unsupported format char"; pyulog: 0
    samples, one bad frame, truncated). Read from a repaired copy, the samples are the
    original's, the repair is said, and the copy is gone once the log is read."""
    original = Path(__file__).parent / log
    data = original.read_bytes()
    pairs = data.count(b"\n")
    assert pairs > 100
    converted = tmp_path / f"crlf{original.suffix}"
    converted.write_bytes(data.replace(b"\n", b"\r\n"))
    copies = tmp_path / "tmp"
    copies.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(copies))
    stream = iter_samples(converted)
    samples = list(stream)
    assert samples == list(iter_samples(original)) and len(samples) > 50
    assert [cause for cause, _ in stream.problems()] == ["repaired file"]
    assert f"follows a CR ({pairs} of them)" in stream.warnings()[0]
    assert iter_samples(original).problems() == [] and not any(copies.iterdir())


def test_a_conversion_is_undone_across_every_chunk_boundary_and_only_when_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The copy is written a chunk at a time: a CR LF split between two chunks comes back as
    LF, a CR of the log itself before one too. A file whose LF bytes follow a CR only at its
    start (the probe) is read as it is."""
    rng = np.random.default_rng(7)
    original = bytes(rng.choice([10, 13, 65], size=400).astype(np.uint8))
    pairs = original.count(b"\n")
    assert original.count(b"\r\n") > 0 and pairs >= 2 * CRLF_MIN_PAIRS
    converted = tmp_path / "converted.bin"
    converted.write_bytes(original.replace(b"\n", b"\r\n"))
    for chunk_bytes in (97, 100, 101, 128):
        monkeypatch.setattr(line_endings, "PROBE_BYTES", chunk_bytes)
        with line_endings.repaired_copy(converted) as (copy, note):
            assert copy != converted and copy.read_bytes() == original
            assert note is not None and f"follows a CR ({pairs} of them)" in note
    partly = tmp_path / "partly.bin"
    partly.write_bytes(converted.read_bytes() + b"A\n")
    monkeypatch.setattr(line_endings, "PROBE_BYTES", 100)
    with line_endings.repaired_copy(partly) as (copy, note):
        assert (copy, note) == (partly, None)


def test_mavlink2_frames_are_read(tmp_path: Path) -> None:
    path = write_tlog(tmp_path / "v2.tlog", flight_frames(10, mavlink1=False))
    assert path.read_bytes()[8] == 0xFD
    flight = load_flights([path])[0]
    assert len(flight) > 10
    assert flight.power_w[0] == pytest.approx(11.8 * 15.0)
    assert flight.vn_mps[0] == pytest.approx(3.0)


def test_log_without_battery_current_is_a_user_error(tmp_path: Path) -> None:
    path = write_tlog(tmp_path / "nocurrent.tlog", flight_frames(10, current_ca=-1))
    with pytest.raises(UserError, match="no battery current"):
        load_flights([path])


def test_log_without_velocity_is_a_user_error(tmp_path: Path) -> None:
    path = write_tlog(tmp_path / "novel.tlog", flight_frames(10, velocity=False))
    with pytest.raises(UserError, match="no velocity"):
        load_flights([path])


def test_battery_samples_get_the_previous_velocity_within_the_age_limit(tmp_path: Path) -> None:
    frames = flight_frames(10)
    # drop the position reports of the middle 3 seconds: battery rows there have stale velocity
    kept = []
    for us, frame in frames:
        t_s = (us - frames[0][0]) / 1e6
        is_position = frame[5] == 33  # MAVLink 1 msgid byte: GLOBAL_POSITION_INT
        if not (is_position and 4.0 < t_s < 7.0):
            kept.append((us, frame))
    flight = load_flights([write_tlog(tmp_path / "gap.tlog", kept)])[0]
    all_rows = load_flights([write_tlog(tmp_path / "full.tlog", frames)])[0]
    assert len(flight) < len(all_rows)
    assert np.all(np.diff(flight.time_s) > 0)


# -- CMU CSV ----------------------------------------------------------------------------------

CMU_HEADER = (
    '"","time","wind_speed","wind_angle","position_x","position_y","position_z",'
    '"orientation_x","orientation_y","orientation_z","orientation_w","twist_linear_x",'
    '"twist_linear_y","twist_linear_z","angular_x","angular_y","angular_z","acceleration_x",'
    '"acceleration_y","acceleration_z","y","payload","flight"'
)


def _cmu_row(t: float, yaw_enu_rad: float, flight: int = 268, forward_mps: float = 5.0) -> str:
    qz, qw = math.sin(yaw_enu_rad / 2), math.cos(yaw_enu_rad / 2)
    values = [
        1,
        t,
        6.0,
        80,
        -79.78,
        40.45,
        20.0,
        0.0,
        0.0,
        qz,
        qw,
        forward_mps,
        0.0,
        0.5,
        0,
        0,
        0,
        0,
        0,
        -9.8,
        500.0,
        250,
        flight,
    ]
    return ",".join(str(v) for v in values)


def test_cmu_orientation_rotates_body_velocity_as_scipy_does() -> None:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    quat = rng.normal(size=(500, 4)) * 2.0  # not normalised: the reader normalises
    body = rng.normal(size=(500, 3)) * 10.0
    expected = Rotation.from_quat(quat).apply(body)
    assert np.allclose(rotate(quat, body), expected, rtol=0.0, atol=1e-12)


def _cmu_csv(path: Path, rows: list[str], header: str = CMU_HEADER) -> Path:
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def test_cmu_body_velocity_becomes_ned_through_the_quaternion(tmp_path: Path) -> None:
    rows = [_cmu_row(0.0, 0.0), _cmu_row(0.2, math.pi / 2)]
    flight = load_flights([_cmu_csv(tmp_path / "c.csv", rows)])[0]
    # ENU yaw 0: nose east → NED (0, 5, -0.5); yaw 90°: nose north → NED (5, 0, -0.5)
    np.testing.assert_allclose([flight.vn_mps[0], flight.ve_mps[0]], [0.0, 5.0], atol=1e-9)
    np.testing.assert_allclose([flight.vn_mps[1], flight.ve_mps[1]], [5.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(flight.vd_mps, -0.5)
    assert flight.power_w[0] == 500.0
    assert math.isnan(flight.voltage_v[0])
    assert flight.extras["payload_kg"][0] == pytest.approx(0.25)


def test_cmu_regime_files_join_into_whole_flights(tmp_path: Path) -> None:
    takeoff = _cmu_csv(tmp_path / "x_takeoff.csv", [_cmu_row(t / 5, 0) for t in range(5)])
    cruise = _cmu_csv(
        tmp_path / "x_cruise.csv",
        [_cmu_row(1 + t / 5, 0) for t in range(5)] + [_cmu_row(t / 5, 0, 269) for t in range(3)],
    )
    flights = load_flights([cruise, takeoff])
    assert [f.flight_id for f in flights] == ["cmu-268", "cmu-269"]
    assert len(flights[0]) == 10
    assert np.all(np.diff(flights[0].time_s) > 0)
    assert list(np.unique(flights[0].extras["regime"])) == [0.0, 1.0]


def test_cmu_sample_stream_keeps_power_exact(tmp_path: Path) -> None:
    path = _cmu_csv(tmp_path / "c.csv", [_cmu_row(t / 5, 0) for t in range(4)])
    batteries = [s for s in iter_samples(path) if isinstance(s, BatterySample)]
    assert len(batteries) == 4
    assert batteries[0].power_w == pytest.approx(500.0)


def test_cmu_csv_missing_columns_is_a_user_error(tmp_path: Path) -> None:
    header = CMU_HEADER.replace('"position_z",', "")
    row = _cmu_row(0, 0).split(",")
    del row[6]
    path = _cmu_csv(tmp_path / "c.csv", [",".join(row)], header)
    with pytest.raises(UserError, match="position_z"):
        load_flights([path], fmt="cmu-csv")


def test_cmu_csv_with_text_in_numbers_is_a_user_error(tmp_path: Path) -> None:
    path = _cmu_csv(tmp_path / "c.csv", [_cmu_row(0, 0), _cmu_row(0.2, 0).replace("500.0", "NA?")])
    with pytest.raises(UserError, match="line 3"):
        load_flights([path])


def test_cmu_csv_header_only_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="no data rows"):
        load_flights([_cmu_csv(tmp_path / "c.csv", [])])


def test_required_cmu_columns_are_in_the_header() -> None:
    names = {c.strip('"') for c in CMU_HEADER.split(",")}
    assert set(REQUIRED_COLUMNS) <= names


def test_forced_format_on_wrong_content_is_a_user_error(tmp_path: Path) -> None:
    path = _cmu_csv(tmp_path / "c.csv", [_cmu_row(0, 0)])
    with pytest.raises(UserError):
        load_flights([path], fmt="tlog")
    with pytest.raises(UserError):
        load_flights([IRIS_MARCH], fmt="cmu-csv")


def test_stamp_layout_is_big_endian_microseconds() -> None:
    data = IRIS_MARCH.read_bytes()
    (stamp,) = struct.unpack_from(">Q", data, 0)
    assert 1_457_000_000_000_000 < stamp < 1_460_000_000_000_000  # March 2016


# -- plausibility and sanity --------------------------------------------------------------------

ARDUCOPTER_TLOG = Path(__file__).parent / "data" / "arducopter_guided.tlog"


def _statustext(codec: mavlink.MAVLink, t_ms: int, words: str) -> tuple[int, bytes]:
    """(receive µs, frame) of a STATUSTEXT ``words`` sent at ``t_ms`` of the flight."""
    msg = codec.statustext_encode(mavlink.MAV_SEVERITY_INFO, words.encode())
    return EPOCH_US + t_ms * 1000, msg.pack(codec)


def test_a_copter_before_3_6_has_its_vz_read_positive_up(tmp_path: Path) -> None:
    """Copter before 3.6 sent GLOBAL_POSITION_INT.vz positive up (ArduPilot pull request
    7672): after its firmware text the decoder reads it so. A later Copter, another vehicle,
    or no firmware text leave MAVLink's positive down."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)

    def vd_mps(words: str) -> set[float]:
        frames = flight_frames(seconds=10.0, vz_cmps=150)
        if words:
            frames = sorted([*frames, _statustext(codec, 1_100, words)], key=lambda f: f[0])
        path = write_tlog(tmp_path / f"{len(words)}.tlog", frames)
        samples = iter_samples(path)
        return {s.vd_mps for s in samples if isinstance(s, VelocitySample) and s.time_s > 1.5}

    assert vd_mps("APM:Copter V3.3 (d3e14c1c)") == {-1.5}
    assert vd_mps("ArduCopter V3.5.7 (b11c6af3)") == {-1.5}
    assert vd_mps("ArduCopter V3.6.12 (c2e4a3c3)") == {1.5}
    assert vd_mps("ArduPlane V3.8.5 (6a2c5e34)") == {1.5}
    assert vd_mps("") == {1.5}


def test_iris_vertical_velocity_is_read_up_and_without_the_firmware_text_said_once(
    tmp_path: Path,
) -> None:
    """The IRIS+ logs (APM:Copter V3.3) name their firmware: read positive up, their vz agrees
    with the altitude rate. The same log without that text is read as MAVLink defines it until
    its height has shown the other way on three climbing or descending pairs, and as the named
    log from then on; the reader says so once. Current ArduCopter agrees."""
    stream = iter_samples(IRIS_MARCH)
    named = [s for s in stream if isinstance(s, VelocitySample)]
    assert stream.warnings(cells=3) == []
    stream = iter_samples(without_firmware_text(IRIS_MARCH, tmp_path / "unnamed.tlog"))
    unnamed = [s for s in stream if isinstance(s, VelocitySample)]
    (warning,) = stream.warnings(cells=3)
    assert warning.startswith("GLOBAL_POSITION_INT.vz disagrees in sign with the altitude rate")
    assert "read positive up from then on" in warning
    differ = [a.time_s for a, b in zip(named, unnamed, strict=True) if a != b]
    assert differ and named[-1].time_s - differ[-1] > 10.0  # the flight's last 18 s alike
    # the firmware as the tlog states it (as a DataFlash log's MSG or a ULog's info says it)
    assert (iter_samples(IRIS_MARCH).firmware, stream.firmware) == (None, None)  # not yet read
    named_stream = iter_samples(IRIS_MARCH)
    list(named_stream)
    assert (named_stream.firmware, stream.firmware) == ("APM:Copter V3.3 (d3e14c1c)", None)
    modern = iter_samples(ARDUCOPTER_TLOG)
    list(modern)
    assert modern.warnings(cells=3) == []


def test_a_firmware_text_sent_before_the_first_heartbeat_counts(tmp_path: Path) -> None:
    """An autopilot's boot text may come before its first HEARTBEAT (a public ArduSub tlog's
    does): it is kept until the HEARTBEAT names its sender, and then counts as the firmware's
    word (the name, and an old Copter's vz read positive up from the first sample)."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    text = codec.statustext_encode(mavlink.MAV_SEVERITY_INFO, b"APM:Copter V3.3 (d3e14c1c)")
    flight = flight_frames(10, vz_cmps=100)  # vz as sent: 1 m/s

    def read(frames: list[tuple[int, bytes]], name: str) -> tuple[str | None, set[float]]:
        stream = iter_samples(write_tlog(tmp_path / name, frames))
        downs = {s.vd_mps for s in stream if isinstance(s, VelocitySample)}
        return stream.firmware, downs

    assert read([(EPOCH_US, text.pack(codec)), *flight], "early.tlog") == (
        "APM:Copter V3.3 (d3e14c1c)",
        {-1.0},
    )
    assert read(flight, "none.tlog") == (None, {1.0})


def test_vehicle_file_for_another_cell_count_is_a_warning_not_a_silent_zero() -> None:
    stream = iter_samples(ARDUCOPTER_TLOG)
    list(stream)
    (warning,) = stream.warnings(cells=6)
    assert "2.10 V per cell for the vehicle file's 6 cells" in warning
    assert "(3 cells would fit)" in warning
    flights = load_flights([ARDUCOPTER_TLOG])
    assert flight_warnings(flights, cells=6) == [warning]
    assert flight_warnings(flights, cells=3) == []


def test_replay_prints_one_warning_line_per_problem(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["replay", str(IRIS_MARCH)]) == 0  # built-in vehicle: 6 cells on a 3S log
    lines = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(lines) == 1
    assert all(line.startswith("uav-energy replay: warning: ") for line in lines)
    assert any("[battery] cells right? (3 cells would fit)" in line for line in lines)


def test_log_values_beyond_the_limits_are_skipped_and_counted(tmp_path: Path) -> None:
    """A tlog with an impossible voltage and a stamp hours away: the samples of those frames
    are dropped and counted; the rest of the log reads as without them."""
    frames = flight_frames(seconds=10.0, mavlink1=False)
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    bad = [
        codec.sys_status_encode(0, 0, 0, 500, 60_000, 1500, 80, 0, 0, 0, 0, 0, 0),
        codec.global_position_int_encode(5_000 + 3 * 3_600_000, 0, 0, 0, 0, 300, 0, 0, 0),
    ]
    stamp = frames[20][0]
    hostile = frames[:21] + [(stamp, m.pack(codec)) for m in bad] + frames[21:]
    clean = list(iter_samples(write_tlog(tmp_path / "clean.tlog", frames)))
    stream = iter_samples(
        write_tlog(tmp_path / "hostile.tlog", hostile), limits=InputLimits.for_pack(3, 200.0)
    )
    assert list(stream) == clean
    assert stream.checks == {"voltage_implausible": 1, "time_jump": 1}


def test_gripper_texts_become_a_released_channel(tmp_path: Path) -> None:
    """ArduPilot's STATUSTEXT of a finished release marks the rows after it; before the first
    report the gripper held (a release says so); other texts that mention it are not read."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = [
        *flight_frames(seconds=30.0),
        _statustext(codec, 10_100, "Gripper load releasing"),
        _statustext(codec, 15_100, "Gripper load released"),
        _statustext(codec, 20_100, "PreArm: Gripper load released"),
    ]
    frames.sort(key=lambda f: f[0])
    path = write_tlog(tmp_path / "gripper.tlog", frames)
    events = [s for s in iter_samples(path) if isinstance(s, GripperSample)]
    assert events == [GripperSample(15.0, True)]
    (flight,) = load_flights([path])
    released = flight.extras["gripper_released"]
    assert np.all(released[flight.time_s <= 15.0] == 0.0)
    assert np.all(released[flight.time_s >= 15.5] == 1.0)


def test_random_bytes_are_not_taken_for_a_tlog(tmp_path: Path) -> None:
    """One random head in 128 has a MAVLink STX at byte 8; the record's receive time must
    also be plausible (an unreadable "tlog" would replay to nothing, without an error)."""
    rng = np.random.default_rng(5)
    heads = [rng.bytes(64) for _ in range(2000)]
    with_stx = [h[:8] + b"\xfe" + h[9:] for h in heads]
    taken = 0
    for i, head in enumerate(with_stx):
        path = tmp_path / f"r{i}.bin"
        path.write_bytes(head)
        with contextlib.suppress(UserError):
            taken += detect_format(path) == "tlog"
    assert taken <= 2
