"""The simulator: determinism, telemetry rates and quantisation, truth consistency, plans,
hidden effects, live playback over a real loopback UDP socket, and the command's errors."""

from __future__ import annotations

import asyncio
import socket
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from estimator import cli
from estimator.errors import UserError
from estimator.mavlink.link import open_link
from estimator.physics.battery import PackModel
from estimator.physics.effects import Mass, Wind, predict_power_w
from estimator.sim.files import tlog_records, write_tlog
from estimator.sim.link import FIRMWARE_VERSION, SimPlayer
from estimator.sim.plans import load_plan
from estimator.sim.run import DEFAULT_RATES_HZ, SimConfig, SimRun
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.samples import ArmedSample, BatterySample, VelocitySample


@pytest.fixture(scope="module")
def mixed_run() -> SimRun:
    return simulate(SimConfig(plan="mixed", duration_s=90.0, seed=7))


@pytest.fixture(scope="module")
def endurance_run() -> SimRun:
    """Hover, then cruise until the reserve, then the battery failsafe lands it."""
    return simulate(SimConfig(plan="hover-cruise", seed=2, initial_soc=0.45))


def decode(run: SimRun) -> list:
    parser, decoder = FrameParser(), TelemetryDecoder()
    messages = [m for _, frame in tlog_records(run) for m in parser.feed(frame)]
    assert parser.bad_frames == 0
    return decoder.decode_all(messages)


def test_same_seed_gives_the_same_bytes_and_another_seed_other_noise() -> None:
    a = simulate(SimConfig(plan="circles", duration_s=20.0, seed=1))
    b = simulate(SimConfig(plan="circles", duration_s=20.0, seed=1))
    c = simulate(SimConfig(plan="circles", duration_s=20.0, seed=2))
    assert tlog_records(a) == tlog_records(b)
    assert tlog_records(a) != tlog_records(c)
    assert np.array_equal(a.truth.power_w, c.truth.power_w)  # noise only, same physics


def test_streams_go_out_at_their_rates_with_autopilot_ids(mixed_run: SimRun) -> None:
    counts = Counter(m.get_type() for _, m in mixed_run.messages)
    for name, hz in DEFAULT_RATES_HZ.items():
        assert counts[name] == pytest.approx(hz * mixed_run.duration_s, abs=2), name
    assert {(m.get_srcSystem(), m.get_srcComponent()) for _, m in mixed_run.messages} == {(1, 1)}
    times = [t for t, _ in mixed_run.messages]
    assert times == sorted(times)
    hb = next(m for _, m in mixed_run.messages if m.get_type() == "HEARTBEAT")
    assert (hb.type, hb.autopilot) == (
        mavlink.MAV_TYPE_QUADROTOR,
        mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    )


def test_values_are_quantised_as_mavlink_carries_them(mixed_run: SimRun) -> None:
    tr = mixed_run.truth
    for t, m in mixed_run.messages:
        kind = m.get_type()
        if kind == "GLOBAL_POSITION_INT":
            assert isinstance(m.vx, int) and m.time_boot_ms == round(t * 1000)
            assert m.vx / 100 == pytest.approx(tr.vn_mps[tr.at(t)], abs=0.3)
        elif kind == "BATTERY_STATUS":
            assert m.voltages[0] / 1000 == pytest.approx(tr.voltage_v[tr.at(t)], abs=0.1)
            assert list(m.voltages[1:]) == [65535] * 9
            assert m.current_battery / 100 == pytest.approx(tr.current_a[tr.at(t)], abs=1.0)


def test_decoded_telemetry_matches_the_truth_within_noise(mixed_run: SimRun) -> None:
    samples = decode(mixed_run)
    tr = mixed_run.truth
    vel = [s for s in samples if isinstance(s, VelocitySample)]
    k = tr.at(np.array([s.time_s for s in vel]))
    err = np.array([s.vn_mps for s in vel]) - tr.vn_mps[k]
    assert len(vel) == pytest.approx(10 * mixed_run.duration_s, abs=2)
    assert np.sqrt(np.mean(err**2)) < 0.1
    bat = [s for s in samples if isinstance(s, BatterySample)]
    kb = tr.at(np.array([s.time_s for s in bat]))
    perr = np.array([s.power_w for s in bat]) - tr.power_w[kb]
    assert abs(perr.mean()) < 2.0 and perr.std() < 8.0
    armed = [s.armed for s in samples if isinstance(s, ArmedSample)]
    assert armed[:2] == [False, True]


def test_chemical_energy_drop_equals_terminal_energy_plus_resistive_loss(
    endurance_run: SimRun,
) -> None:
    tr, cfg = endurance_run.truth, endurance_run.config
    pack = PackModel(cfg.vehicle.battery, cfg.internal_resistance_ohm)
    dt = np.diff(tr.time_s)[0]
    drawn_wh = np.sum(tr.power_w + tr.current_a**2 * cfg.internal_resistance_ohm) * dt / 3600
    dropped_wh = float(pack.energy_wh(tr.soc[0]) - pack.energy_wh(tr.soc[-1]))
    assert drawn_wh == pytest.approx(dropped_wh, rel=0.005)


def test_voltage_sags_and_current_rises_at_constant_power(endurance_run: SimRun) -> None:
    tr = endurance_run.truth
    cruise = tr.flying & (tr.speed_mps > 9.9) & (np.abs(tr.accel_tangential_mps2) < 0.01)
    first, last = np.nonzero(cruise)[0][[0, -1]]
    assert tr.power_w[last] == pytest.approx(tr.power_w[first], rel=0.01)
    assert tr.voltage_v[last] < tr.voltage_v[first] - 0.3
    assert tr.current_a[last] > tr.current_a[first] * 1.02


def test_reserve_ends_the_flight_and_time_to_reserve_counts_down(endurance_run: SimRun) -> None:
    tr, reserve_s = endurance_run.truth, endurance_run.reserve_time_s
    at = tr.at(reserve_s)
    assert tr.energy_remaining_wh[at] < 0.2
    before = tr.time_s < reserve_s - 1
    assert np.allclose(tr.time_s[before] + tr.time_to_reserve_s[before], reserve_s)
    assert not tr.armed[-1] and tr.alt_m[-1] == 0.0  # landed and disarmed after the failsafe
    assert tr.time_s[-1] - reserve_s < 60.0


def test_time_to_reserve_extends_a_short_flight_with_the_plan(mixed_run: SimRun) -> None:
    run = simulate(SimConfig(plan="straight", duration_s=None, seed=0, initial_soc=0.7))
    tr = run.truth
    assert run.reserve_time_s > tr.time_s[-1]  # the flight ended before the reserve
    flying_w = float(tr.power_w[tr.flying].mean())
    expected_s = tr.energy_remaining_wh[0] * 3600 / flying_w
    assert tr.time_to_reserve_s[0] == pytest.approx(expected_s, rel=0.1)


def test_without_hidden_effects_truth_is_the_vehicle_model(mixed_run: SimRun) -> None:
    tr = mixed_run.truth
    assert np.allclose(tr.power_w[tr.flying], tr.power_model_w[tr.flying])
    assert (tr.power_w[~tr.flying] == mixed_run.config.idle_power_w).all()


def test_hidden_wind_and_payload_change_truth_power_only() -> None:
    wind, payload = Wind(6.0, 135.0), Mass(0.8, at_s=40.0)
    run = simulate(SimConfig(plan="mixed", duration_s=80.0, effects=(wind, payload)))
    tr, v = run.truth, run.config.vehicle
    expected = predict_power_w(v.model, v.mass_kg, tr.flight_state(), [wind, payload])
    assert np.allclose(tr.power_w[tr.flying], expected[tr.flying])
    assert not np.allclose(tr.power_w[tr.flying], tr.power_model_w[tr.flying], atol=5.0)
    assert tr.mass_kg[tr.time_s < 40.0] == pytest.approx(v.mass_kg)
    assert tr.mass_kg[tr.time_s >= 40.0] == pytest.approx(v.mass_kg + 0.8)


def test_plan_file_circle_has_the_commanded_radius_and_centripetal_accel(tmp_path: Path) -> None:
    plan = tmp_path / "orbit.toml"
    plan.write_text(
        'name = "orbit"\ntakeoff_alt_m = 15\n'
        '[[legs]]\nkind = "circle"\nspeed_mps = 6\nradius_m = 20\nturns = 2\n'
    )
    assert load_plan(plan).legs[0].radius_m == 20.0
    run = simulate(SimConfig(plan=str(plan), noise=SimConfig().noise))
    tr = run.truth
    steady = tr.flying & (np.abs(tr.speed_mps - 6.0) < 0.05) & (tr.alt_m > 14.5)
    assert steady.sum() > 500
    assert np.median(tr.accel_centripetal_mps2[steady]) == pytest.approx(36 / 20, rel=0.05)


def test_climb_option_flies_altitude_changes() -> None:
    run = simulate(SimConfig(plan="straight", climb_legs=True, duration_s=120.0))
    assert run.truth.alt_m.max() == pytest.approx(50.0, abs=1.0)
    assert run.truth.vd_mps.min() < -2.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[[legs]]\nkind = 'loop'\n", "kind must be"),
        ("[[legs]]\nkind = 'hover'\n", "needs duration_s"),
        ("[[legs]]\nkind = 'circle'\nspeed_mps = 10\nradius_m = 5\nturns = 1\n", "speed²"),
        (
            "[[legs]]\nkind = 'straight'\nspeed_mps = 5\n"
            "[[legs]]\nkind = 'hover'\nduration_s = 3\n",
            "endless",
        ),
        ("legs = 3\n", "at least one"),
        ("not toml [", "not valid TOML"),
    ],
)
def test_bad_plan_files_are_one_line_user_errors(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "plan.toml"
    path.write_text(text)
    with pytest.raises(UserError, match=message) as info:
        load_plan(path)
    assert "\n" not in str(info.value)


async def test_live_playback_over_udp_answers_rate_requests() -> None:
    run = simulate(SimConfig(plan="hover-cruise", duration_s=40.0, seed=4))
    loop = asyncio.get_running_loop()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.setblocking(False)
    codec = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    codec.robust_parsing = True
    link = await open_link(f"udpout:127.0.0.1:{client.getsockname()[1]}", source_component=1)
    player = SimPlayer(run, link, speedup=40.0)
    task = asyncio.create_task(player.play())
    received: list[mavlink.MAVLink_message] = []
    requested_at_ms: int | None = None
    try:
        async with asyncio.timeout(20):
            while not task.done() or received == []:
                try:
                    data, sim_addr = await asyncio.wait_for(loop.sock_recvfrom(client, 4096), 0.5)
                except TimeoutError:
                    continue
                received.extend(codec.parse_buffer(data) or [])
                stamped = [m for m in received if hasattr(m, "time_boot_ms")]
                if requested_at_ms is None and stamped and stamped[-1].time_boot_ms > 10_000:
                    requested_at_ms = stamped[-1].time_boot_ms
                    interval = codec.command_long_encode(
                        1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                        mavlink.MAVLINK_MSG_ID_ATTITUDE, 1_000_000, 0, 0, 0, 0, 0,
                    )  # fmt: skip
                    stream = codec.request_data_stream_encode(
                        1, 1, mavlink.MAV_DATA_STREAM_POSITION, 2, 1
                    )
                    version = codec.command_long_encode(
                        1, 1, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 0, 1, 0, 0, 0, 0, 0, 0
                    )
                    for msg in (interval, stream, version):
                        await loop.sock_sendto(client, msg.pack(codec), sim_addr)
        await task
    finally:
        await link.close()
        client.close()
    assert requested_at_ms is not None
    acks = [m for m in received if m.get_type() == "COMMAND_ACK"]
    assert [(a.command, a.result) for a in acks] == [
        (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAV_RESULT_ACCEPTED),
        (mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, mavlink.MAV_RESULT_ACCEPTED),
    ]
    late = requested_at_ms + 2000

    def rate_hz(kind: str, after: bool) -> float:
        ms = [m.time_boot_ms for m in received if m.get_type() == kind]
        ms = [t for t in ms if (t > late if after else 1000 < t < requested_at_ms)]
        return (len(ms) - 1) / ((ms[-1] - ms[0]) / 1000)

    assert rate_hz("ATTITUDE", after=False) == pytest.approx(10, rel=0.1)
    assert rate_hz("ATTITUDE", after=True) == pytest.approx(1, rel=0.15)
    assert rate_hz("GLOBAL_POSITION_INT", after=True) == pytest.approx(2, rel=0.15)
    assert rate_hz("LOCAL_POSITION_NED", after=True) == pytest.approx(2, rel=0.15)
    decoder = TelemetryDecoder()
    vel = [s for s in decoder.decode_all(received) if isinstance(s, VelocitySample)]
    # the simulator's vz is read by the version it answers: positive down
    assert decoder.vz_sense.firmware_version == FIRMWARE_VERSION
    assert decoder.vz_sense.down_sign == 1
    tr = run.truth
    k = tr.at(np.array([s.time_s for s in vel]))
    assert np.abs(np.array([s.ve_mps for s in vel]) - tr.ve_mps[k]).max() < 0.3


def test_sim_command_writes_tlog_and_truth(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    tlog = tmp_path / "flight.tlog"
    code = cli.main(
        ["sim", "--plan", "circles", "--duration", "15", "--wind", "4@200", "--tlog", str(tlog)]
    )
    assert code == 0
    assert "wind(speed_mps=4.0, from_deg=200.0)" in capsys.readouterr().out
    truth = np.genfromtxt(tlog.with_name("flight.truth.csv"), delimiter=",", names=True)
    assert truth["time_s"][-1] == pytest.approx(15.0, abs=0.1)
    data = tlog.read_bytes()
    assert FrameParser().feed(data[8:]) != []


@pytest.mark.parametrize(
    "flags",
    [
        ["--wind", "5"],
        ["--wind", "fast@90"],
        ["--payload", "1@-3"],
        ["--air-density", "0"],
        ["--speedup", "0"],
        ["--duration", "-1"],
        ["--plan", "nowhere"],
        ["--seed", "1.5"],
        ["--connect", "udp:nothing"],
        [],
    ],
)
def test_bad_flags_exit_2_with_one_line(flags: list[str], tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    extra = [] if flags == [] else ["--tlog", str(tmp_path / "x.tlog")]
    assert cli.main(["sim", *flags, *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("uav-energy sim: error:") and "\n" not in err


def test_write_tlog_puts_the_truth_beside_it(mixed_run: SimRun, tmp_path: Path) -> None:
    path = write_tlog(mixed_run, tmp_path / "m.tlog")
    rows = (tmp_path / "m.truth.csv").read_text().splitlines()
    assert rows[0].startswith("time_s,armed,")
    assert len(rows) - 1 == pytest.approx(10 * mixed_run.duration_s, abs=2)
    assert path.stat().st_size == sum(8 + len(f) for _, f in tlog_records(mixed_run))


def test_sim_command_plays_live_to_a_udp_listener(tmp_path: Path) -> None:
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(0.5)
    port = listener.getsockname()[1]
    exe = Path(sys.executable).with_name("uav-energy")
    args = [str(exe), "sim", "--connect", f"udpout:127.0.0.1:{port}", "--plan", "mixed"]
    args += ["--duration", "20", "--speedup", "40", "--tlog", str(tmp_path / "live.tlog")]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    codec = mavlink.MAVLink(None)
    kinds: Counter[str] = Counter()
    try:
        while proc.poll() is None or kinds.total() == 0:
            try:
                data = listener.recv(4096)
            except TimeoutError:
                if proc.poll() is not None:
                    break
                continue
            kinds.update(m.get_type() for m in codec.parse_buffer(data) or [])
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
        listener.close()
    assert proc.returncode == 0, err
    assert kinds["GLOBAL_POSITION_INT"] == pytest.approx(200, abs=3)
    assert kinds["HEARTBEAT"] == pytest.approx(20, abs=1)
    sent = FrameParser().feed((tmp_path / "live.tlog").read_bytes()[8:])
    assert sent and (tmp_path / "live.truth.csv").exists()


def test_with_a_duration_the_flight_goes_past_the_reserve_until_the_pack_is_empty() -> None:
    run = simulate(SimConfig(plan="hover-cruise", duration_s=5000.0, initial_soc=0.3))
    tr = run.truth
    assert run.reserve_time_s < run.duration_s < 5000.0
    assert tr.flying[-1] and tr.soc[-1] < 0.001
    assert tr.energy_remaining_wh[tr.time_s > run.reserve_time_s].max() == 0.0


def test_unknown_stream_and_bad_soc_are_rejected() -> None:
    with pytest.raises(ValueError, match="does not send"):
        simulate(SimConfig(rates_hz={"GPS_RAW_INT": 5.0}, duration_s=5.0))
    with pytest.raises(ValueError, match="initial_soc"):
        simulate(SimConfig(initial_soc=0.0, duration_s=5.0))
