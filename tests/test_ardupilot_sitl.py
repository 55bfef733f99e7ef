"""ArduPilot SITL: a recorded ArduCopter SITL flight through the pipeline (always, when the
shared data is there), and a live SITL flight into the daemon (only when
``ARDUPILOT_SITL_BINARY`` names an ``arducopter`` SITL binary; see docs/sitl.md).

The recording (``../shared/data/ardupilot_sitl/run1_default_quad.tlog``, ArduPilot master of
July 2025, stock ``quad`` model) is a modern MAVLink 2 stream with ~25 message types the
daemon does not use, ardupilotmega-only ids, and a ground station's own messages (system 0)
mixed in. SITL's battery is "unlimited": 12.6 V (3S) throughout, current linear in thrust.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import struct
import subprocess
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_sitl import GroundStation, daemon_subprocess

from estimator.decode import BATTERY_STATUS_CONFIRM, FrameParser, TelemetryDecoder
from estimator.demo import wait_for_daemon
from estimator.logs import iter_samples
from estimator.logs.tlog import STAMP_BYTES, frame_length
from estimator.mavlink_io import MavlinkLink
from estimator.publish import json_line
from estimator.replay import replay_log, summarize
from estimator.telemetry import ArmedSample, BatterySample, RebootSample, VelocitySample
from estimator.vehicle import BatterySpec, Vehicle, default_vehicle

REPO = Path(__file__).resolve().parent.parent
SITL_TLOG = REPO.parent / "shared/data/ardupilot_sitl/run1_default_quad.tlog"
EXE = Path(sys.executable).with_name("uav-energy")
#: SITL's stock quad: a 3S pack; BATT_CAPACITY defaults to 3300 mAh.
SITL_BATTERY = BatterySpec(capacity_ah=3.3, cells=3, reserve_fraction=0.2)

needs_tlog = pytest.mark.skipif(
    not SITL_TLOG.exists(), reason=f"{SITL_TLOG} is not there (shared data missing)"
)


def sitl_vehicle() -> Vehicle:
    """The built-in model on SITL's 3S 3.3 Ah pack (the model is not SITL's: see SOURCE.md)."""
    return replace(default_vehicle(), name="sitl-quad", battery=SITL_BATTERY)


def tlog_records(path: Path) -> list[tuple[int, bytes]]:
    """(receive stamp µs, frame bytes) of every record."""
    data = path.read_bytes()
    out, i = [], 0
    while i + STAMP_BYTES < len(data):
        (stamp,) = struct.unpack_from(">Q", data, i)
        found = frame_length(data, i + STAMP_BYTES)
        assert found is not None, f"no frame start at byte {i + STAMP_BYTES}"
        end = i + STAMP_BYTES + found[0]
        out.append((stamp, data[i + STAMP_BYTES : end]))
        i = end
    return out


# -- the recorded SITL flight ---------------------------------------------------------------------


@needs_tlog
def test_every_frame_is_mavlink2_and_parses_including_unknown_ardupilot_ids() -> None:
    records = tlog_records(SITL_TLOG)
    assert records and all(frame[0] == 0xFD for _, frame in records)
    parser = FrameParser()
    messages = [m for _, frame in records for m in parser.feed(frame)]
    assert parser.bad_frames == 0
    assert len(messages) == len(records)
    kinds = Counter(m.get_type() for m in messages)
    assert kinds["BATTERY_STATUS"] > 1000 and kinds["SYS_STATUS"] > 1000
    # ardupilotmega-only messages (e.g. 11030 ESC_TELEMETRY_1_TO_4) are not errors
    assert any(k.startswith("UNKNOWN_") for k in kinds)


@needs_tlog
def test_autopilot_is_selected_and_the_ground_stations_messages_ignored() -> None:
    parser, decoder = FrameParser(), TelemetryDecoder()
    sources: Counter[tuple[int, int]] = Counter()
    for _, frame in tlog_records(SITL_TLOG):
        for msg in parser.feed(frame):
            sources[(msg.get_srcSystem(), msg.get_srcComponent())] += 1
            decoder.decode(msg)
    assert sources[(0, 0)] > 0  # the recording client's own requests are in the log
    assert decoder.target == (1, 1)
    assert decoder.counts["reboots"] == 0


@needs_tlog
def test_clock_is_time_boot_ms_not_the_tlog_receive_stamps() -> None:
    samples = list(iter_samples(SITL_TLOG))
    times = np.array([s.time_s for s in samples])
    assert not any(isinstance(s, RebootSample) for s in samples)
    assert np.all(np.diff(times) >= 0)
    assert 0 < times[0] < 10  # seconds since the autopilot booted, not since 1970
    records = tlog_records(SITL_TLOG)
    stamps_s = (records[-1][0] - records[0][0]) / 1e6
    assert times[-1] - times[0] == pytest.approx(stamps_s, abs=2.0)  # SITL ran at speedup 1
    armed = [(s.time_s, s.armed) for s in samples if isinstance(s, ArmedSample)]
    assert [a for _, a in armed] == [False, True, False]
    assert armed[1][0] == pytest.approx(50.0, abs=1.0) and armed[2][0] > 350.0


@needs_tlog
def test_battery_status_and_sys_status_give_the_pack_readings() -> None:
    samples = list(iter_samples(SITL_TLOG))
    battery = [s for s in samples if isinstance(s, BatterySample)]
    assert len(battery) > 1500
    # voltages[0] = 12600 mV with the other cells UINT16_MAX; current in cA
    assert {round(s.voltage_v, 2) for s in battery} == {12.6}
    armed_at = next(s.time_s for s in samples if isinstance(s, ArmedSample) and s.armed)
    flying = [s for s in battery if armed_at + 10 < s.time_s < 350]
    current = np.array([s.current_a for s in flying], dtype=float)
    assert 25.0 < np.median(current) < 35.0  # SOURCE.md: 28.1 A hover … 32.7 A at 12 m/s
    consumed = np.array([s.consumed_mah for s in battery if s.consumed_mah is not None])
    assert np.all(np.diff(consumed) >= 0) and consumed[-1] > 2000
    # the consumed charge is the integral of the current (ArduPilot counts it)
    t = np.array([s.time_s for s in battery])
    amps = np.array([s.current_a for s in battery], dtype=float)
    integrated_mah = float(np.sum(0.5 * (amps[1:] + amps[:-1]) * np.diff(t))) / 3.6
    assert consumed[-1] == pytest.approx(integrated_mah, rel=0.02)
    velocity = [s for s in samples if isinstance(s, VelocitySample)]
    speeds = np.hypot([s.vn_mps for s in velocity], [s.ve_mps for s in velocity])
    assert speeds.max() == pytest.approx(12.0, abs=1.0)  # the fastest leg


@needs_tlog
def test_sys_status_alone_gives_the_same_pack_readings_without_consumed_charge() -> None:
    """With BATTERY_STATUS present the decoder takes the pack from it (one sample each, once
    BATTERY_STATUS_CONFIRM arrived); a stream without it falls back to SYS_STATUS with the
    same volts and amps."""
    parser = FrameParser()
    messages = [m for _, frame in tlog_records(SITL_TLOG) for m in parser.feed(frame)]

    def battery(msgs: list[mavlink.MAVLink_message]) -> list[BatterySample]:
        samples = TelemetryDecoder().decode_all(msgs)
        return [s for s in samples if isinstance(s, BatterySample)]

    both = battery(messages)
    sys_only = battery([m for m in messages if m.get_type() != "BATTERY_STATUS"])
    n_status = sum(m.get_type() == "BATTERY_STATUS" for m in messages)
    # SYS_STATUS only until BATTERY_STATUS is confirmed
    assert len(both) <= n_status + BATTERY_STATUS_CONFIRM
    assert all(s.consumed_mah is None for s in sys_only)
    assert sum(s.consumed_mah is not None for s in both) >= n_status - BATTERY_STATUS_CONFIRM
    from_status = {s.time_s: (s.voltage_v, s.current_a) for s in both if s.consumed_mah is not None}
    matched = [(from_status[s.time_s], (s.voltage_v, s.current_a)) for s in sys_only
               if s.time_s in from_status]  # fmt: skip
    assert len(matched) > 1000
    assert all(a == pytest.approx(b) for a, b in matched)


@needs_tlog
def test_replay_estimates_energy_from_the_pack_and_power_from_the_model() -> None:
    flight = replay_log(SITL_TLOG, sitl_vehicle())
    summary = summarize([flight])
    assert flight.bad_frames == 0 and not flight.truncated
    assert summary.airborne_s == pytest.approx(300.0, abs=15.0)
    assert summary.power_rmse_w is not None and summary.power_rmse_w < 80.0
    # the estimate of energy used follows what the pack measured (V·I while airborne)
    first = next(e for e in flight.estimates if e.power_measured_w and e.power_measured_w > 100)
    last = flight.estimates[-1]
    used_wh = first.energy_remaining_wh - last.energy_remaining_wh
    assert used_wh == pytest.approx(summary.energy_measured_wh, rel=0.1)
    assert not last.model_only and 0 < last.energy_remaining_sigma_wh < 5.0
    assert all(e.voltage_v == pytest.approx(12.6) for e in flight.estimates)


# -- a live ArduCopter SITL ------------------------------------------------------------------------

SITL_BINARY = os.environ.get("ARDUPILOT_SITL_BINARY", "")
SITL_SPEEDUP = float(os.environ.get("ARDUPILOT_SITL_SPEEDUP", "5"))
#: CMAC, ArduPilot's usual SITL home: lat, lon, alt (m AMSL), heading.
SITL_HOME = "-35.363261,149.165230,584,353"


def _port_free(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


needs_sitl = pytest.mark.skipif(
    not (SITL_BINARY and os.access(SITL_BINARY, os.X_OK)),
    reason="set ARDUPILOT_SITL_BINARY to an ArduCopter SITL binary (build: docs/sitl.md)",
)


def _guided_flight(sim_time_s: float) -> float:
    """As a second ground station on SERIAL1 (tcp:5762): GUIDED, arm, take off to 20 m, fly
    north at 8 m/s for half of ``sim_time_s``, hover the rest, LAND. Returns the height
    reached (m)."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection("tcp:127.0.0.1:5762", source_system=250)
    try:
        deadline = time.monotonic() + 60
        beat = None  # SITL also forwards the daemon's HEARTBEAT (component 191) to SERIAL1
        while beat is None or not conn.probably_vehicle_heartbeat(beat):
            assert time.monotonic() < deadline, "no autopilot HEARTBEAT on SERIAL1"
            beat = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=2)
        conn.target_system, conn.target_component = beat.get_srcSystem(), beat.get_srcComponent()
        sysid, compid = conn.target_system, conn.target_component
        conn.mav.request_data_stream_send(sysid, compid, mavlink.MAV_DATA_STREAM_ALL, 4, 1)
        said: list[str] = []
        deadline = time.monotonic() + 180  # EKF and GPS need a while after boot
        while not conn.motors_armed():
            assert time.monotonic() < deadline, f"SITL never armed: {said[-5:]}"
            conn.set_mode("GUIDED")
            conn.arducopter_arm()
            msg = conn.recv_match(type=["HEARTBEAT", "STATUSTEXT"], blocking=True, timeout=2)
            if msg is not None and msg.get_type() == "STATUSTEXT":
                said.append(msg.text)
        conn.mav.command_long_send(
            sysid, compid, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 20
        )
        alt_m, deadline = 0.0, time.monotonic() + 60
        while alt_m < 18.0:
            assert time.monotonic() < deadline, f"take-off stopped at {alt_m:.1f} m"
            msg = conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=2)
            if msg is not None:
                alt_m = msg.relative_alt / 1000
        leg_end = time.monotonic() + sim_time_s / 2 / SITL_SPEEDUP
        while time.monotonic() < leg_end:  # velocity only: position, accel, yaw ignored
            conn.mav.set_position_target_local_ned_send(
                0, sysid, compid, mavlink.MAV_FRAME_LOCAL_NED, 0b0000_1101_1100_0111,
                0, 0, 0, 8.0, 0, 0, 0, 0, 0, 0, 0,
            )  # fmt: skip
            time.sleep(0.2)
        time.sleep(sim_time_s / 2 / SITL_SPEEDUP)
        conn.set_mode("LAND")
        return alt_m
    finally:
        conn.close()


@needs_sitl
@pytest.mark.slow
def test_live_arducopter_sitl_flight_reaches_the_ground_station(tmp_path: Path) -> None:
    """SITL serves tcp:5760 (SERIAL0) to the daemon; a client on SERIAL1 flies it; the daemon
    publishes to a UDP ground station; estimates arrive and follow the flight."""
    if not (_port_free(5760) and _port_free(5762)):
        pytest.skip("tcp 5760/5762 are in use (another SITL running?)")
    vehicle = tmp_path / "sitl.toml"
    sitl_vehicle().save(vehicle)
    sitl_args = [SITL_BINARY, "--model", "quad", "--speedup", str(SITL_SPEEDUP)]
    sitl_args += ["--home", SITL_HOME, "-I0"]
    if os.environ.get("ARDUPILOT_SITL_DEFAULTS"):
        sitl_args += ["--defaults", os.environ["ARDUPILOT_SITL_DEFAULTS"]]
    daemon_args = [str(EXE), "run", "--connect", "tcp:127.0.0.1:5760", "--json", "-"]
    daemon_args += ["--vehicle", str(vehicle), "--rate", "5"]
    gcs = GroundStation()
    daemon_args += ["--publish", f"udpout:127.0.0.1:{gcs.port}"]
    out, log = tmp_path / "estimates.jsonl", tmp_path / "daemon.log"
    with (
        (tmp_path / "sitl.log").open("wb") as sitl_log,
        out.open("wb") as out_fh,
        log.open("wb") as log_fh,
    ):
        sitl = subprocess.Popen(sitl_args, cwd=tmp_path, stdout=sitl_log, stderr=sitl_log)
        daemon = subprocess.Popen(daemon_args, stdout=out_fh, stderr=log_fh)
        gcs.start()
        try:
            alt_m = _guided_flight(sim_time_s=40.0)
            time.sleep(2.0)
        finally:
            for proc in (daemon, sitl):
                proc.terminate()
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()
            gcs.close()
    assert alt_m >= 18.0
    daemon_log = log.read_text()
    assert daemon.returncode == 0, daemon_log
    assert "autopilot found: system 1 component 1" in daemon_log, daemon_log
    estimates = [json.loads(line) for line in out.read_text().splitlines()]
    flying = [e for e in estimates if e["power_measured_w"] and e["power_measured_w"] > 100]
    assert flying, "no estimate with measured flight power"
    assert max(e["speed_mps"] for e in flying) > 6.0  # the leg north
    assert all(e["voltage_v"] == pytest.approx(12.6, abs=0.5) for e in flying)
    assert np.all(np.diff([e["time_s"] for e in estimates]) >= 0)
    kinds = Counter(m.get_type() for m in gcs.messages)
    assert kinds["HEARTBEAT"] and kinds["NAMED_VALUE_FLOAT"] and kinds["BATTERY_STATUS"]
    ours = [m for m in gcs.messages if m.get_type() == "BATTERY_STATUS" and m.id == 9]
    assert any(m.time_remaining > 0 for m in ours)


# -- the recording played live into the daemon ---------------------------------------------------

#: Playback speed of the recording (362 s, 45 667 frames) into the daemon.
TLOG_SPEEDUP = 80.0


@needs_tlog
@pytest.mark.slow
def test_recording_played_live_into_the_daemon_equals_its_replay(tmp_path: Path) -> None:
    """The SITL recording sent frame by frame, at its own pace × 80, over TCP into
    ``uav-energy run`` (as from SITL's tcp:5760) gives exactly the replay's estimates."""
    records = tlog_records(SITL_TLOG)
    vehicle = tmp_path / "sitl.toml"
    sitl_vehicle().save(vehicle)

    async def serve(link: MavlinkLink) -> None:
        await wait_for_daemon(link)
        loop = asyncio.get_running_loop()
        start_wall, first_us = loop.time(), records[0][0]
        for stamp_us, frame in records:
            delay = start_wall + (stamp_us - first_us) / 1e6 / TLOG_SPEEDUP - loop.time()
            if delay > 0:
                await asyncio.sleep(delay)
            link.send_bytes(frame)

    def replay() -> list[dict]:
        estimates = replay_log(SITL_TLOG, sitl_vehicle()).estimates
        return [json.loads(json_line(e)) for e in estimates]

    live, replayed, log = asyncio.run(
        daemon_subprocess(serve, replay, tmp_path, "--vehicle", str(vehicle))
    )
    assert "autopilot found: system 1 component 1" in log
    assert "link_bad_frames=" not in log and "link_dropped=" not in log
    assert len(live) == len(replayed) > 300  # one a second
    assert live == replayed
