"""ArduPilot SITL: a recorded ArduCopter SITL flight through the pipeline (always, when the
shared data is there), and live ArduCopter SITL flights (whenever the binary is there: by
default ``../shared/tools/ardupilot-sitl/arducopter``, or ``ARDUPILOT_SITL_BINARY``; see
docs/sitl.md): into the daemon and a ground station, through the recorder, and to the
battery reserve against the daemon's endurance. Live flights run on a free SITL instance and
are driven by the autopilot's clock, so a loaded machine only makes them slower.

The recording (``../shared/data/ardupilot_sitl/run1_default_quad.tlog``, ArduPilot master of
July 2025, stock ``quad`` model) is a modern MAVLink 2 stream with ~25 message types the
daemon does not use, ardupilotmega-only ids, and a ground station's own messages (system 0)
mixed in. SITL's battery is "unlimited": 12.6 V (3S) throughout, current linear in thrust.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import struct
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from doc_rows import DocRows
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink
from test_sitl import GroundStation, daemon_subprocess

from estimator.analysis.replay import replay_log, summarize
from estimator.logs import iter_samples
from estimator.logs.tlog import STAMP_BYTES, frame_length
from estimator.mavlink.link import MavlinkLink
from estimator.mavlink.publish import json_line
from estimator.physics.vehicle import BatterySpec, Vehicle, default_vehicle, load_vehicle
from estimator.sim.demo import wait_for_daemon
from estimator.sitl.launch import (
    DEFAULT_BINARY,
    SitlOptions,
    free_instance,
    running_sitl,
    serial_port,
    sitl_binary,
    stop_process,
    wait_listening,
)
from estimator.sitl.pack import Pack
from estimator.sitl.pilot import Pilot
from estimator.sitl.recorder import Flight, Truth, record
from estimator.sitl.scenarios import (
    DRAINING_PACK,
    Grip,
    Hover,
    Leg,
    LegsToReserve,
    Scenario,
    SetWind,
    Takeoff,
    out_and_back,
    pack_scenario,
)
from estimator.telemetry.decode import BATTERY_STATUS_CONFIRM, TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import ArmedSample, BatterySample, RebootSample, VelocitySample

REPO = Path(__file__).resolve().parent.parent
SITL_TLOG = REPO.parent / "shared/data/ardupilot_sitl/run1_default_quad.tlog"
EXE = Path(sys.executable).with_name("uav-energy")
#: SITL's stock quad: a 3S pack; BATT_CAPACITY defaults to 3300 mAh.
SITL_BATTERY = BatterySpec(capacity_ah=3.3, cells=3, reserve_fraction=0.2)

needs_tlog = pytest.mark.needs(SITL_TLOG.exists(), f"{SITL_TLOG} is not there (shared data)")


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

SITL_BINARY = sitl_binary()
#: SITL runs in lockstep at up to this speedup; every wait is in the autopilot's clock.
SITL_SPEEDUP = float(os.environ.get("ARDUPILOT_SITL_SPEEDUP", "10"))
FITTED_VEHICLE = REPO / "config/vehicles/ardupilot_sitl_quad.toml"
#: The live flight to the reserve: each figure lies in its row of docs/sitl.md's table.
doc_figure = DocRows("docs/sitl.md").check

needs_sitl = pytest.mark.needs(
    SITL_BINARY is not None,
    f"no ArduCopter SITL binary at {DEFAULT_BINARY} and ARDUPILOT_SITL_BINARY unset",
)


@dataclass
class LiveDaemon:
    """SITL on a free instance with ``uav-energy run`` on SERIAL0 (SITL waits for it), a UDP
    ground station for what the daemon publishes, and a pilot on SERIAL1."""

    instance: int
    sitl: subprocess.Popen[bytes]
    sitl_log: Path
    daemon: subprocess.Popen[bytes]
    gcs: GroundStation
    estimates_path: Path
    log_path: Path

    def pilot(self, tlog: Path | None = None) -> Pilot:
        wait_listening(self.sitl, self.sitl_log, serial=1)
        return Pilot(f"tcp:127.0.0.1:{serial_port(self.instance, 1)}", tlog, source_system=250)

    def estimates(self) -> list[dict]:
        return [json.loads(line) for line in self.estimates_path.read_text().splitlines()]


@contextlib.contextmanager
def live_daemon(
    tmp_path: Path,
    vehicle: Path,
    model_json: dict | None = None,
    daemon_args: tuple[str, ...] = (),
    params: dict[str, float] | None = None,
) -> Iterator[LiveDaemon]:
    """SITL (``model_json``, parameters: the scenarios' base, then ``params``) with the daemon
    on its SERIAL0 publishing to a UDP ground station."""
    assert SITL_BINARY is not None
    opts = SitlOptions(
        binary=SITL_BINARY,
        workdir=tmp_path / "sitl",
        instance=free_instance(),
        model_json=model_json,
        params=Scenario("live", "", (), model_json=model_json, params=params or {}).all_params(),
        speedup=SITL_SPEEDUP,
    )
    gcs = GroundStation()
    out, log = tmp_path / "estimates.jsonl", tmp_path / "daemon.log"
    args = [str(EXE), "run", "--connect", f"tcp:127.0.0.1:{serial_port(opts.instance)}"]
    args += ["--json", "-", "--vehicle", str(vehicle), "--rate", "5"]
    args += ["--publish", f"udpout:127.0.0.1:{gcs.port}", *daemon_args]
    with running_sitl(opts) as sitl, out.open("wb") as out_fh, log.open("wb") as log_fh:
        daemon = subprocess.Popen(args, stdout=out_fh, stderr=log_fh)
        gcs.start()
        try:
            yield LiveDaemon(opts.instance, sitl, opts.workdir / "sitl.log", daemon, gcs, out, log)
        finally:
            stop_process(daemon, timeout_s=20.0)
            gcs.close()


@needs_sitl
def test_live_arducopter_sitl_flight_reaches_the_ground_station(tmp_path: Path) -> None:
    """SITL serves SERIAL0 to the daemon; a client on SERIAL1 flies it (GUIDED, take-off to
    20 m, 8 m/s north for 20 s, hover 20 s, LAND) by the autopilot's clock; the daemon
    publishes to a UDP ground station; estimates arrive and follow the flight."""
    vehicle = tmp_path / "sitl.toml"
    sitl_vehicle().save(vehicle)
    with live_daemon(tmp_path, vehicle) as live:
        pilot = live.pilot()
        try:
            flight = Flight(pilot, Scenario("live", "", ()), truth=_truth("live"))
            pilot.connect()
            for step in (Takeoff(20), Leg(8, 0, 20), Hover(20)):
                flight.step(step)
            alt_m = pilot.state.alt_m
            pilot.land()
            pilot.hold(3.0)
        finally:
            pilot.close()
    assert alt_m >= 18.0
    daemon_log = live.log_path.read_text()
    assert live.daemon.returncode == 0, daemon_log
    assert "autopilot found: system 1 component 1" in daemon_log, daemon_log
    # asked, the autopilot tells its version: a Copter 4 sends vz as MAVLink defines it
    said = re.findall(
        r"autopilot firmware (\d+)\.\d+\.\d+ \(its AUTOPILOT_VERSION\): (.*)", daemon_log
    )
    assert said == [("4", "GLOBAL_POSITION_INT.vz read positive down")], daemon_log
    estimates = live.estimates()
    flying = [e for e in estimates if e["power_measured_w"] and e["power_measured_w"] > 100]
    assert flying, "no estimate with measured flight power"
    assert max(e["speed_mps"] for e in flying) > 6.0  # the leg north
    assert all(e["voltage_v"] == pytest.approx(12.6, abs=0.5) for e in flying)
    assert np.all(np.diff([e["time_s"] for e in estimates]) >= 0)
    kinds = Counter(m.get_type() for m in live.gcs.messages)
    assert kinds["HEARTBEAT"] and kinds["NAMED_VALUE_FLOAT"] and kinds["BATTERY_STATUS"]
    ours = [m for m in live.gcs.messages if m.get_type() == "BATTERY_STATUS" and m.id == 9]
    assert any(m.time_remaining > 0 for m in ours)


def _truth(name: str) -> Truth:
    return Truth(name, "", "quad", None, {}, SITL_SPEEDUP)


#: A short recorder flight: a gripper payload from take-off, wind switched on, the payload
#: released, each in a hover of 25-30 s.
RECORDER_CHECK = Scenario(
    "recorder_check",
    "payload from take-off, wind onset, release",
    (Grip(True), Hover(3), Takeoff(10), Hover(25), SetWind(6, 60), Hover(30), Grip(False),
     Hover(25), Leg(5, 0, 10)),
    dataflash=True,
)  # fmt: skip


@needs_sitl
def test_recorder_truth_matches_what_the_autopilot_measured(tmp_path: Path) -> None:
    """``record`` flies a scenario and writes tlog, DataFlash and truth; the truth's times
    agree with the pack current (the 1 kg load from 2 m up until its release) and with the
    autopilot's own wind estimate (WIND), and both logs replay."""
    truth = record(RECORDER_CHECK, tmp_path / "out", SITL_SPEEDUP)
    out = tmp_path / "out"
    saved = json.loads((out / "truth.json").read_text())
    assert saved["scenario"] == "recorder_check" and saved["params"]["SIM_GRPS_ENABLE"] == 1
    ev = truth.events
    assert ev["armed_s"] <= ev["takeoff_s"] < ev["landed_s"] <= ev["disarmed_s"]
    (payload,) = [e for e in truth.effects if e["effect"] == "payload"]
    (wind,) = [e for e in truth.effects if e["effect"] == "wind"]
    assert payload["mass_kg"] == 1.0 and ev["takeoff_s"] < payload["start_s"] < wind["start_s"]
    assert wind["start_s"] < payload["end_s"] < ev["landed_s"]
    assert wind["end_s"] == pytest.approx(ev["disarmed_s"], abs=3.0)

    samples = list(iter_samples(out / "flight.tlog"))
    battery = [s for s in samples if isinstance(s, BatterySample)]

    def mean_current(t0: float, t1: float) -> float:
        return float(np.mean([s.current_a for s in battery if t0 <= s.time_s <= t1]))

    # hovers: with the load, then without it (the wind adds little in a hover)
    loaded = mean_current(payload["start_s"] + 5, wind["start_s"] - 1)
    released = mean_current(payload["end_s"] + 5, payload["end_s"] + 20)
    assert loaded / released == pytest.approx(4.0 / 3.0, abs=0.08)  # 3 kg quad + 1 kg

    winds = [(t, m) for t, m in _boot_stamped(out / "flight.tlog") if m.get_type() == "WIND"]
    settled = [m for t, m in winds if wind["start_s"] + 15 <= t <= payload["end_s"]]
    assert settled and np.median([m.speed for m in settled]) == pytest.approx(6.0, abs=1.5)
    assert np.median([m.direction for m in settled]) == pytest.approx(60.0, abs=15.0)
    before = [m.speed for t, m in winds if ev["takeoff_s"] + 5 <= t <= wind["start_s"]]
    assert before and max(before) < 1.0

    tlog = replay_log(out / "flight.tlog", sitl_vehicle())
    binary = replay_log(out / "flight.BIN", sitl_vehicle())
    flown_s = ev["landed_s"] - ev["takeoff_s"]
    for flight in (tlog, binary):
        assert summarize([flight]).airborne_s == pytest.approx(flown_s, abs=5.0)


def _boot_stamped(tlog: Path) -> Iterator[tuple[float, Any]]:
    """(autopilot clock s, message) for the autopilot's messages, read with pymavlink's
    ardupilotmega dialect (WIND is not in common): the latest time_boot_ms."""
    log = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    boot_s = 0.0
    while (msg := log.recv_match()) is not None:
        if (msg.get_srcSystem(), msg.get_srcComponent()) != (1, 1):
            continue
        boot_s = getattr(msg, "time_boot_ms", boot_s * 1000) / 1000
        yield boot_s, msg


#: The flight to the reserve: hover, then 6 m/s north/south legs of 20 s on the draining pack.
TO_RESERVE = Scenario(
    "to_reserve",
    "hover 60 s, 6 m/s legs to the 20 % reserve",
    (Takeoff(20), Hover(60), LegsToReserve(out_and_back(6, 20))),
    model_json=DRAINING_PACK,
)


#: The endurance counts as learnt once its 1σ is within this fraction of the time left: half
#: the 8 % bound, so that its 2σ fits in the bound (until then its own σ, 12 % at take-off +
#: 30 s, is the claim the test holds it to).
LEARNT_SIGMA_FRACTION = 0.04


@dataclass(frozen=True)
class EnduranceErrors:
    """The daemon's endurance against the real time to the reserve (autopilot clock)."""

    #: From the first estimate after take-off + 30 s whose 1σ is within
    #: :data:`LEARNT_SIGMA_FRACTION` of the time left (the capacity learnt) to 30 s before
    #: the reserve: error % of the real time left.
    median_pct: float
    worst_pct: float
    #: Seconds after take-off of that first estimate.
    learnt_s: float
    #: From take-off to 30 s before the reserve: the worst |error| / its 1σ.
    worst_z: float
    #: Take-off to 30 s after it: the worst error % (None: nothing published then).
    worst_before_pct: float | None
    n: int
    #: Error % at 10, 30, 60 and 120 s after take-off (None: not published then).
    at_pct: dict[int, float | None]
    #: Seconds after take-off of the first published endurance, and its error %.
    first_published_s: float | None
    first_pct: float | None


def endurance_errors(estimates: list[dict], takeoff_s: float, reserve_s: float) -> EnduranceErrors:
    """Errors of the published endurances (``endurance_s`` null: not yet valid, skipped)."""

    def pct(e: dict) -> float:
        left_s = reserve_s - e["time_s"]
        return 100.0 * (e["endurance_s"] - left_s) / left_s

    published = [e for e in estimates if e["endurance_s"] is not None]
    flown = [e for e in published if takeoff_s <= e["time_s"] <= reserve_s - 30]
    learnt = next(
        e
        for e in flown
        if e["time_s"] >= takeoff_s + 30
        and e["endurance_sigma_s"] <= LEARNT_SIGMA_FRACTION * (reserve_s - e["time_s"])
    )
    settled = [pct(e) for e in flown if e["time_s"] >= learnt["time_s"]]
    z = [abs(e["endurance_s"] - (reserve_s - e["time_s"])) / e["endurance_sigma_s"] for e in flown]
    early = [pct(e) for e in published if takeoff_s <= e["time_s"] < takeoff_s + 30]
    at_pct: dict[int, float | None] = {}
    for after_s in (10, 30, 60, 120):
        at = min(estimates, key=lambda e: abs(e["time_s"] - takeoff_s - after_s))
        at_pct[after_s] = None if at["endurance_s"] is None else round(pct(at), 2)
    airborne = [e for e in published if e["time_s"] >= takeoff_s]
    return EnduranceErrors(
        median_pct=float(np.median(np.abs(settled))),
        worst_pct=float(np.max(np.abs(settled))),
        worst_before_pct=max(early, key=abs) if early else None,
        n=len(settled),
        learnt_s=learnt["time_s"] - takeoff_s,
        worst_z=max(z),
        at_pct=at_pct,
        first_published_s=airborne[0]["time_s"] - takeoff_s if airborne else None,
        first_pct=pct(airborne[0]) if airborne else None,
    )


@needs_sitl
@pytest.mark.slow
def test_daemon_live_against_sitl_to_the_reserve(tmp_path: Path) -> None:
    """The daemon with the vehicle file fitted to SITL's quad (and SITL's pack curve), live on
    SITL's draining 3S 2.2 Ah pack, flown to its 20 % reserve (consumed charge as the autopilot
    counts it): the endurance against the real time from each moment to the reserve (to 30 s
    before the reserve, where the time left gets short) is within 3σ from take-off, within
    8 % once the pack is learnt (its 1σ within 4 % of the time left, from 30 s after take-off
    on), those of the first 30 s within 25 %, and nothing absurd before. The figures go to
    ``endurance.json`` (docs/sitl.md has them)."""
    truth = Truth("to_reserve", "", "quad", DRAINING_PACK, {}, SITL_SPEEDUP)
    with live_daemon(tmp_path, FITTED_VEHICLE, DRAINING_PACK) as live:
        pilot = live.pilot(tmp_path / "pilot.tlog")
        try:
            Flight(pilot, TO_RESERVE, truth).fly()
        finally:
            pilot.close()
    daemon_log = live.log_path.read_text()
    assert live.daemon.returncode == 0, daemon_log
    estimates = live.estimates()
    takeoff_s, reserve_s = truth.events["takeoff_s"], truth.events["reserve_s"]
    assert reserve_s - takeoff_s == pytest.approx(200.0, abs=30.0)  # 1.76 Ah at 28-35 A
    errors = endurance_errors(estimates, takeoff_s, reserve_s)
    ours = [m for m in live.gcs.messages if m.get_type() == "BATTERY_STATUS" and m.id == 9]
    published = [m.time_remaining for m in ours if m.time_remaining > 0]
    report = {"errors": errors.__dict__, "takeoff_s": takeoff_s, "reserve_s": reserve_s}
    report["gcs_time_remaining_max_s"] = max(published, default=None)
    (tmp_path / "endurance.json").write_text(json.dumps(report, indent=1))
    print(json.dumps(report))
    assert errors.n > 100
    # each figure within its row of docs/sitl.md's table (the worst once learnt: 8 %, the
    # issue's bound on replays; the first 30 s, while the pack's capacity is still being
    # learnt: 25 %, the capacity prior's 1σ; every one within 3σ)
    assert errors.worst_before_pct is not None and errors.first_published_s is not None
    assert errors.first_pct is not None
    doc_figure("endurance error, learnt … reserve − 30 s, median", errors.median_pct)
    doc_figure("endurance error, learnt … reserve − 30 s, worst", errors.worst_pct)
    doc_figure("endurance learnt (1σ ≤ 4 % of the time left) after take-off", errors.learnt_s)
    doc_figure("endurance error over its 1σ, take-off … reserve − 30 s, worst", errors.worst_z)
    doc_figure("endurance error in the first 30 s, worst", errors.worst_before_pct)
    doc_figure("first endurance published after take-off", errors.first_published_s)
    doc_figure("first endurance published, error", errors.first_pct)
    assert published and len(ours) > 50
    doc_figure("BATTERY_STATUS time_remaining at the ground station, max", max(published))
    # never absurd: nothing published says more than SITL's pack could ever give (an hour)
    assert max(e["endurance_s"] for e in estimates if e["endurance_s"] is not None) < 3600.0
    assert max(published) < 3600


#: A 3S pack labelled 5.0 Ah that holds 3.25 Ah (65 %), 10 mΩ, full at power-up.
MISLABELLED = Pack(true_capacity_ah=3.25, resistance_ohm=0.01)


@needs_sitl
@pytest.mark.slow
def test_daemon_live_warns_of_a_mislabelled_pack_and_learns_its_capacity(tmp_path: Path) -> None:
    """The daemon with the vehicle file's pack labelled 5.0 Ah, live on SITL's pack that
    holds 3.25 Ah (BATT_CAPACITY 5000 too): the ground station gets "pack holds ~3.2Ah,
    configured 5.0Ah" within 90 s of take-off, once, and the capacity
    it publishes is within 5 % of the truth before half of the pack's charge is used."""
    scenario = pack_scenario(MISLABELLED)
    vehicle = load_vehicle(FITTED_VEHICLE)
    labelled = tmp_path / "labelled.toml"
    replace(vehicle, battery=replace(vehicle.battery, capacity_ah=5.0)).save(labelled)
    truth = Truth(scenario.name, "", "quad", scenario.model_json, {}, SITL_SPEEDUP)
    with live_daemon(tmp_path, labelled, scenario.model_json, params=scenario.params) as live:
        pilot = live.pilot(tmp_path / "pilot.tlog")
        try:
            Flight(pilot, scenario, truth).fly()
        finally:
            pilot.close()
    assert live.daemon.returncode == 0, live.log_path.read_text()
    takeoff_s = truth.events["takeoff_s"]
    # the ground station's clock: the time_boot_ms of our values before each message
    boot_s, warned_s = 0.0, []
    for msg in live.gcs.messages:
        if msg.get_type() == "NAMED_VALUE_FLOAT":
            boot_s = msg.time_boot_ms / 1000.0
        elif msg.get_type() == "STATUSTEXT" and msg.text.startswith("pack holds"):
            warned_s.append(boot_s)
            assert msg.text.endswith("configured 5.0Ah") and msg.severity == 4
    assert len(warned_s) == 1 and warned_s[0] - takeoff_s <= 90.0, (warned_s, takeoff_s)
    consumed = [
        s
        for s in iter_samples(tmp_path / "pilot.tlog")
        if isinstance(s, BatterySample) and s.consumed_mah is not None
    ]
    half_s = next(s.time_s for s in consumed if s.consumed_mah >= 500.0 * 3.25)
    before = [e for e in live.estimates() if takeoff_s <= e["time_s"] <= half_s]
    learned = before[-1]["capacity_ah"], before[-1]["capacity_sigma_ah"]
    print(json.dumps({"warned_after_takeoff_s": warned_s[0] - takeoff_s, "at_half": learned}))
    assert abs(learned[0] - 3.25) <= 0.05 * 3.25, learned


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
