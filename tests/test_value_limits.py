"""Values within their MAVLink fields but beyond physics or the vehicle file: a pack at 1 mV,
−19 A of charge, a single 190 m/s frame, a velocity no multirotor reaches from the last, a
wind from an infinite direction. Over the replay path (real tlogs with forged frames) and a
real UDP socket into the daemon: each is skipped and counted under its reason, never an
exception, and the estimates stay the clean flight's; a sustained change is believed; the
committed flights give no such skip; random in-range values never publish energy out of the
pack (hypothesis).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega
from pymavlink.dialects.v20 import common as mavlink
from test_hostile_input import FLIGHT_TLOG, assert_same_estimates, sitl_vehicle
from test_service import play, running, wait_for

from estimator.analysis.replay import replay_log
from estimator.estimation.fusion import MAX_CAPACITY_PER_LABEL
from estimator.estimation.pipeline import Pipeline
from estimator.logs import iter_samples
from estimator.logs.tlog import STAMP_BYTES, frame_length
from estimator.mavlink.config import ServiceConfig
from estimator.physics.vehicle import load_vehicle
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser
from estimator.telemetry.plausibility import SampleGuard
from estimator.telemetry.samples import BatterySample, Sample, VelocitySample, WindSample


def flight_records() -> list[tuple[bytes, bytes]]:
    """The flight's tlog records: (8-byte receive stamp, frame)."""
    data, out, pos = FLIGHT_TLOG.read_bytes(), [], 0
    while pos + STAMP_BYTES < len(data):
        header = frame_length(data, pos + STAMP_BYTES)
        assert header is not None
        end = pos + STAMP_BYTES + header[0]
        out.append((data[pos : pos + STAMP_BYTES], data[pos + STAMP_BYTES : end]))
        pos = end
    return out


def forged_tlog(
    path: Path, forge: Callable[[mavlink.MAVLink_message], list[mavlink.MAVLink_message]]
) -> Path:
    """The flight as a tlog with ``forge(next GLOBAL_POSITION_INT)``'s frames (from the
    autopilot's ids) before each GLOBAL_POSITION_INT of the flight's 40th to 60th second."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser, out = FrameParser(), []
    for stamp, frame in flight_records():
        msg = parser.decode_frame(frame)
        position = msg is not None and msg.get_type() == "GLOBAL_POSITION_INT"
        if position and 40_000 <= msg.time_boot_ms < 60_000:
            out += [stamp + forged.pack(codec) for forged in forge(msg)]
        out.append(stamp + frame)
    path.write_bytes(b"".join(out))
    return path


def _battery_status(mv: int, centiamps: int) -> mavlink.MAVLink_message:
    cells = [mv] + [UINT16_MAX_CELL] * 9
    return mavlink.MAVLink_battery_status_message(0, 0, 0, 2_500, cells, centiamps, 500, -1, 80)


def _velocity(real: mavlink.MAVLink_message, vx_cmps: int) -> mavlink.MAVLink_message:
    """The next GLOBAL_POSITION_INT, 1 ms earlier, at another north speed."""
    return mavlink.MAVLink_global_position_int_message(
        real.time_boot_ms - 1, real.lat, real.lon, real.alt, real.relative_alt,
        vx_cmps, real.vy, real.vz, real.hdg,
    )  # fmt: skip


UINT16_MAX_CELL = 65_535
#: Attack → (the frames forged before each position frame, the counter that must skip them).
ABSURD_VALUES: dict[str, tuple[Callable[[mavlink.MAVLink_message], list], str]] = {
    "BATTERY_STATUS at 1 mV": (lambda m: [_battery_status(1, 2_000)] * 3, "voltage_implausible"),
    "BATTERY_STATUS at -19 A": (
        lambda m: [_battery_status(12_400, -1_900)] * 3,
        "current_implausible",
    ),
    "190 m/s": (lambda m: [_velocity(m, 19_000)], "velocity_beyond_limits"),
    "40 m/s (within the airframe's speed)": (lambda m: [_velocity(m, 4_000)], "velocity_jump"),
}


@pytest.mark.parametrize("attack", list(ABSURD_VALUES))
def test_in_limit_absurd_values_are_skipped_by_reason_in_replay(
    tmp_path: Path, attack: str
) -> None:
    """A real flight's tlog with forged frames from the autopilot's ids before each of 20 s
    of position frames, each value within its MAVLink field but beyond the vehicle's pack or
    airframe: the replay gives the clean flight's estimates and counts each skip under its
    reason (a single 190 m/s frame drove the energy to 0; 1 mV and −19 A were fused)."""
    forge, reason = ABSURD_VALUES[attack]
    vehicle = sitl_vehicle()
    clean = replay_log(FLIGHT_TLOG, vehicle).estimates
    path = forged_tlog(tmp_path / "forged.tlog", forge)
    hostile = replay_log(path, vehicle).estimates
    assert_same_estimates(hostile, clean)
    stream = iter_samples(path, "auto", vehicle.input_limits())
    for _ in stream:
        pass
    assert set(stream.checks) == {reason}, stream.checks
    assert stream.checks[reason] >= 50


def test_a_sustained_change_of_velocity_is_believed_after_three_samples() -> None:
    """A velocity that jumps from 1 to 20 m/s and stays there is two outliers, then a state;
    a single frame at 20 m/s among 1 m/s ones is one outlier; a new clock starts over."""
    codec = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    parser, decoder = FrameParser(), TelemetryDecoder(limits=sitl_vehicle().input_limits())
    speeds_cmps = [100] * 10 + [2_000] + [100] * 10 + [2_000] * 10
    for msg in parser.feed(codec.heartbeat_encode(2, 3, 0, 0, 4).pack(codec)):
        decoder.decode(msg)
    samples: list[Sample] = []
    for k, vx in enumerate(speeds_cmps):
        frame = codec.global_position_int_encode(1_000 + 100 * k, 0, 0, 0, 5_000, vx, 0, 0, 0)
        for msg in parser.feed(frame.pack(codec)):
            samples += decoder.decode(msg)
    speeds = [round(s.vn_mps) for s in samples if isinstance(s, VelocitySample)]
    assert speeds == [1] * 20 + [20] * 8
    assert decoder.counts["velocity_jump"] == 3


def test_wind_with_an_infinite_direction_is_counted_in_replay(tmp_path: Path) -> None:
    """ArduPilot WIND frames with direction inf, NaN or 1e30 and a speed of NaN or −3 m/s
    among a real flight's: the replay runs (it raised ValueError: math domain error) and
    counts each under ``wind_implausible``; plausible ones become wind samples."""
    codec = ardupilotmega.MAVLink(None, srcSystem=1, srcComponent=1)
    bad = [(math.inf, 3.0), (math.nan, 3.0), (1e30, 3.0), (90.0, math.nan), (90.0, -3.0)]
    cycle = iter(bad * 1000)
    path = forged_tlog(
        tmp_path / "wind.tlog",
        lambda m: [codec.wind_encode(*next(cycle), 0.0), codec.wind_encode(270.0, 4.0, 0.0)],
    )
    stream = iter_samples(path, "auto", sitl_vehicle().input_limits())
    winds = [s for s in stream if isinstance(s, WindSample)]
    assert stream.checks["wind_implausible"] >= 50
    assert winds and all(s.wind_e_mps == pytest.approx(4.0) for s in winds)  # from the west
    assert len(replay_log(path, sitl_vehicle()).estimates) > 60


async def test_wind_with_an_infinite_direction_is_counted_by_the_daemon_over_udp() -> None:
    """The same over a real UDP socket into the daemon: 150 WIND frames with direction inf
    among the flight's are counted (they were 150 "internal error" lines), none is an error."""
    config = ServiceConfig(stale_after_s=30.0)
    codec = ardupilotmega.MAVLink(None, srcSystem=1, srcComponent=1)
    parser, messages = FrameParser(), []
    forged = 0
    for _, frame in flight_records():
        msg = parser.decode_frame(frame)
        assert msg is not None
        if msg.get_type() == "GLOBAL_POSITION_INT" and forged < 150 and msg.time_boot_ms > 30_000:
            forged += 1
            messages.append(codec.wind_encode(math.inf, 3.0, 0.0))
        messages.append(msg)
    async with running(config, sitl_vehicle()) as (service, sender):
        await play(sender, messages)
        await wait_for(lambda: service.decoder.counts["wind_implausible"] == 150)
    assert service.internal_errors == 0


@settings(
    max_examples=100, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
@given(data=st.data())
def test_random_in_range_values_never_publish_energy_out_of_the_pack(data: st.DataObject) -> None:
    """Any sequence of battery and velocity readings each within the vehicle's limits (but
    absurd together: voltages that jump across the pack's range, currents from the charge
    allowance to full power, a consumed-charge counter that goes anywhere, velocities that
    jump) through the log readers' checks and the pipeline: every published energy is
    finite, ≥ 0 and at most the energy above its reserve of the largest pack the pack filter
    may learn (2.5 × its label: such readings do teach it a larger pack than the label's)."""
    vehicle = sitl_vehicle()
    limits = vehicle.input_limits()
    guard, pipeline = SampleGuard(limits), Pipeline(vehicle)
    most_wh = MAX_CAPACITY_PER_LABEL * float(pipeline.pack.usable_energy_wh(1.0))
    time_s = 1.0
    for _ in range(data.draw(st.integers(5, 120))):
        time_s += data.draw(st.floats(0.05, 2.0))
        if data.draw(st.booleans()):
            voltage_v = data.draw(st.floats(limits.min_voltage_v, limits.max_voltage_v))
            top_a = min(limits.max_current_a, limits.max_power_w / voltage_v)
            current_a = data.draw(st.none() | st.floats(limits.min_current_a, top_a))
            consumed = data.draw(st.none() | st.floats(0.0, limits.max_consumed_mah))
            sample: Sample = BatterySample(time_s, voltage_v, current_a, consumed)
        else:
            speed = st.floats(-limits.max_speed_mps / 1.5, limits.max_speed_mps / 1.5)
            climb = st.floats(-limits.max_vertical_speed_mps, limits.max_vertical_speed_mps)
            sample = VelocitySample(
                time_s, data.draw(speed), data.draw(speed), data.draw(climb), data.draw(climb)
            )
        for checked in guard.check(sample):
            if (estimate := pipeline.process(checked)) is not None:
                assert 0.0 <= estimate.energy_remaining_wh <= most_wh, estimate
                assert math.isfinite(estimate.energy_remaining_sigma_wh), estimate


def test_the_committed_flights_give_no_value_skips() -> None:
    """Every committed real and SITL log (replay/, tests/data/) read with its vehicle's
    limits: no velocity, jump, voltage, current, charge or wind skip (the checks hold what
    real flights do; the IRIS+ logs' few stamps off the clock were skipped before)."""
    root = Path(__file__).resolve().parent.parent
    iris = load_vehicle(root / "replay" / "vehicle.toml")
    logs = [p for p in (root / "replay").rglob("*") if p.suffix in (".tlog", ".log", ".BIN")]
    logs += [FLIGHT_TLOG, FLIGHT_TLOG.with_suffix(".bin")]
    assert len(logs) > 40
    for path in logs:
        vehicle = iris if "iris" in path.parts else sitl_vehicle()
        stream = iter_samples(path, "auto", vehicle.input_limits())
        for _ in stream:
            pass
        assert set(stream.checks) <= {"time_jump"}, (path, stream.checks)


@pytest.mark.parametrize(
    ("voltage_v", "counts"),
    [
        (12.6, [3]),  # full
        (16.2, [4]),  # 4.05 V a cell; 3.24 V at 5 cells is below any flyable pack's reserve
        (25.2, [6, 7]),  # 4.2 or 3.6 V a cell: a 6S full or a 7S near its reserve
        (0.001, []),
        (-12.0, []),
        (math.nan, []),
        (math.inf, []),
        (1e30, []),
    ],
)
def test_the_cell_counts_a_resting_pack_voltage_allows(voltage_v: float, counts: list[int]) -> None:
    """On PX4 SIH's curve (3.69 V a cell at its 20 % reserve, 4.05 V full): one count, several
    or none; nonsense is none."""
    vehicle = load_vehicle(Path(__file__).parent.parent / "config/vehicles/px4_sih_quad.toml")
    assert vehicle.flyable_cells(voltage_v) == counts
