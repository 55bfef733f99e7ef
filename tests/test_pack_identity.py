"""The pack named by its serial number (estimator.estimation.pack_identity): the daemon over
real UDP sockets takes it from the autopilot's SMART_BATTERY_INFO and a second run starts from
that pack's memory; forged serials (path separators, junk bytes, empty, another battery's)
never crash, never write outside the memory directory and never move the pack mid-flight;
``replay --pack-dir`` without ``--pack`` takes the log's serial (ArduCopter SITL flights)."""

from __future__ import annotations

import json
import logging
import random
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink
from test_service import Messages, play, running, wait_for
from tlog_builder import smart_battery_info, with_pack

from estimator.estimation.pack_identity import FlightPack
from estimator.estimation.pack_memory import load_record, pack_id_from_serial, remember
from estimator.estimation.pack_state import PackEstimate
from estimator.estimation.pipeline import Pipeline
from estimator.logs import iter_samples
from estimator.mavlink.config import ServiceConfig
from estimator.physics.vehicle import default_vehicle, load_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.samples import BatterySample

ROOT = Path(__file__).resolve().parent.parent
FLIGHTS = ROOT / "replay" / "sitl_packs"
JUNK = random.Random(7).randbytes(16)


@pytest.fixture(scope="module")
def flight() -> Messages:
    return simulate(SimConfig(plan="hover-cruise", duration_s=30.0, seed=3)).messages


def with_serials(
    flight: Messages, infos: Iterable[mavlink.MAVLink_message]
) -> list[mavlink.MAVLink_message]:
    """The flight's messages with ``infos`` after each HEARTBEAT (a 1 Hz stream, as PX4 has
    for smart batteries)."""
    infos = list(infos)
    out = []
    for _, msg in flight:
        out.append(msg)
        if msg.get_type() == "HEARTBEAT":
            out.extend(infos)
    return out


async def fly(
    flight: Messages, infos: Iterable[mavlink.MAVLink_message], config: ServiceConfig
) -> tuple[FlightPack, list[mavlink.MAVLink_message]]:
    """One daemon run over UDP: the flight with ``infos``, until the pack filter learns; the
    daemon's flight pack and what the sender received from it."""
    async with running(config) as (service, sender):
        await play(sender, with_serials(flight, infos))
        await wait_for(lambda: service.pipeline.pack_state is not None)
        received = await sender.recv()
        assert service.internal_errors == 0
    return service.flight_pack, received


def pack_requests(received: list[mavlink.MAVLink_message]) -> int:
    return sum(
        1
        for m in received
        if m.get_type() == "COMMAND_LONG"
        and m.command == mavlink.MAV_CMD_REQUEST_MESSAGE
        and m.param1 == mavlink.MAVLINK_MSG_ID_SMART_BATTERY_INFO
    )


async def test_the_autopilots_serial_names_the_pack_and_the_next_run_starts_from_it(
    flight: Messages, tmp_path: Path
) -> None:
    config = ServiceConfig(pack_dir=str(tmp_path))
    pack, received = await fly(flight, [smart_battery_info(b"PACK-0042")], config)
    assert pack.pack_id == "PACK-0042" and pack.pipeline.pack_prior is None  # no memory yet
    assert pack_requests(received) >= 1  # asked for with the streams
    first = load_record(tmp_path, "PACK-0042")
    assert first is not None and len(first.history) == 1
    pack, _ = await fly(flight, [smart_battery_info(b"PACK-0042")], config)
    assert pack.pipeline.pack_prior == first.prior()  # the memory started the pack filter
    second = load_record(tmp_path, "PACK-0042")
    assert second is not None and len(second.history) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["PACK-0042.json"]


async def test_a_configured_pack_wins_over_the_serial_and_asks_for_none(
    flight: Messages, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    config = ServiceConfig(pack_id="pack-A", pack_dir=str(tmp_path))
    with caplog.at_level(logging.INFO, logger="uav_energy.service"):
        pack, received = await fly(flight, [smart_battery_info(b"PACK-0042")], config)
    assert pack.pack_id == "pack-A" and pack_requests(received) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pack-A.json"]
    said = [r.getMessage() for r in caplog.records if "reports serial PACK-0042" in r.getMessage()]
    assert said == ["pack pack-A is configured, the autopilot reports serial PACK-0042: the "
                    "memory of pack-A is used"]  # fmt: skip


async def test_forged_serials_never_escape_the_directory_nor_move_the_pack(
    flight: Messages, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    packs = tmp_path / "packs"
    forged = [
        smart_battery_info(b"OTHER-BATTERY", battery_id=1),  # not the battery decoded
        smart_battery_info(b""),
        smart_battery_info(JUNK),
        smart_battery_info(b"../../etc/passwd"),
        smart_battery_info(b"PACK-0042"),  # a second pack mid-flight
        smart_battery_info(b"/" * 32),
    ]
    with caplog.at_level(logging.INFO, logger="uav_energy.service"):
        pack, _ = await fly(flight, forged, ServiceConfig(pack_dir=str(packs)))
    assert pack.pack_id == "_.._etc_passwd" and pack.errors == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["packs"]
    assert sorted(p.name for p in packs.iterdir()) == ["_.._etc_passwd.json"]
    text = "\n".join(r.getMessage() for r in caplog.records)
    assert text.count("makes no pack id") == 1  # one line, however many forged serials
    assert "pack serial PACK-0042 reported while flying pack _.._etc_passwd" in text


async def test_without_a_serial_nothing_is_stored_and_one_line_says_so(
    flight: Messages, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.INFO, logger="uav_energy.service"):
        pack, _ = await fly(
            flight, [smart_battery_info(JUNK)], ServiceConfig(pack_dir=str(tmp_path))
        )
    assert pack.pack_id is None and list(tmp_path.iterdir()) == []
    lines = [r.getMessage() for r in caplog.records if "nothing stored" in r.getMessage()]
    assert len(lines) == 1


@pytest.mark.parametrize(
    ("serial", "pack_id"),
    [
        ("PACK-0042", "PACK-0042"),
        ("SN 12/34\x00\x00", "SN_12_34"),
        ("  7731  ", "7731"),
        ("..\\..\\x", "_.._x"),
        ("", None),
        ("\x00\x00", None),
        ("---", None),
        ("/", None),
        ("caf\u00e9", None),
        ("a\ufffdb", None),
        ("a\x07b", None),
        ("x" * 65, None),
    ],
)
def test_a_serial_becomes_a_file_name_or_nothing(serial: str, pack_id: str | None) -> None:
    assert pack_id_from_serial(serial) == pack_id


def _started_pipeline() -> Pipeline:
    pipeline = Pipeline(default_vehicle())
    for time_s, consumed_mah in ((1.0, 0.0), (2.1, 3.0), (3.2, 6.0)):
        # the first starts the energy state; the third closes the second's period: the
        # pack filter runs
        pipeline.process(BatterySample(time_s, 24.0, 10.0, consumed_mah))
    assert pipeline.pack_state is not None
    return pipeline


def _memory_of_pack_7(directory: Path, label_ah: float | None = None) -> None:
    learnt = PackEstimate(
        soc=0.3, soc_sigma=0.01, capacity_ah=3.2, capacity_sigma_ah=0.05, resistance_ohm=0.03,
        resistance_sigma_ohm=0.001, energy_wh=5.0, energy_sigma_wh=0.2,
    )  # fmt: skip
    label_ah = label_ah or default_vehicle().battery.capacity_ah
    remember(directory, "PACK-7", label_ah, learnt, when_s=1000.0)


def test_a_serial_on_the_ground_after_the_filter_started_restarts_it_from_memory(
    tmp_path: Path,
) -> None:
    _memory_of_pack_7(tmp_path)
    pipeline = _started_pipeline()
    pack = FlightPack(pipeline, tmp_path, None, when_s=2000.0)
    note = pack.reported("PACK-7")
    assert note is not None and "its memory says 3.20 Ah" in note
    assert pipeline.pack_prior is not None and pipeline.pack_state is None
    pipeline.process(BatterySample(4.3, 24.0, 10.0, 9.0))
    pipeline.process(BatterySample(5.4, 24.0, 10.0, 12.0))
    assert pipeline.pack_state is not None
    assert pipeline.pack_state.estimate().capacity_ah == pytest.approx(3.2, rel=0.05)


def test_a_serial_in_flight_names_the_pack_but_leaves_its_start(tmp_path: Path) -> None:
    flight = ROOT / "replay" / "sitl_packs" / "pack_c100_r1"
    takeoff_s = json.loads((flight / "truth.json").read_text())["events"]["takeoff_s"]
    vehicle = load_vehicle(ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml")
    _memory_of_pack_7(tmp_path, vehicle.battery.capacity_ah)
    pipeline = Pipeline(vehicle)
    for sample in iter_samples(flight / "flight.tlog", "auto", vehicle.input_limits()):
        if getattr(sample, "time_s", 0.0) > takeoff_s + 30.0:
            break
        pipeline.process(sample)
    pack = FlightPack(pipeline, tmp_path, None, when_s=2000.0)
    note = pack.reported("PACK-7")
    assert note is not None and "its memory is not applied" in note
    assert pipeline.pack_prior is None and pack.pack_id == "PACK-7"
    assert pack.remember() is None
    record = load_record(tmp_path, "PACK-7")
    assert record is not None and [row[0] for row in record.history] == [1000.0, 2000.0]


def test_a_broken_memory_of_a_reported_pack_is_a_note_not_a_crash(tmp_path: Path) -> None:
    (tmp_path / "PACK-7.json").write_text("[" * 50_000)
    pipeline = Pipeline(default_vehicle())
    pack = FlightPack(pipeline, tmp_path, None, when_s=2000.0)
    note = pack.reported("PACK-7")
    assert note is not None and "is not usable" in note and pack.errors == 1
    assert pipeline.pack_prior is None
    assert (tmp_path / "PACK-7.json").read_text() == "[" * 50_000  # never overwritten
    pipeline = _started_pipeline()
    pack = FlightPack(pipeline, tmp_path, None, when_s=2000.0)
    pack.reported("PACK-7")
    assert pack.remember() is not None and (tmp_path / "PACK-7.json").read_text() == "[" * 50_000


def _replay(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "estimator.cli", "replay", *args, "--json"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )


def test_replay_without_pack_takes_the_logs_serial(tmp_path: Path) -> None:
    """Two SITL flights of one 3.25 Ah pack labelled 5.0 Ah, each log naming it by its serial:
    the second starts from what the first learnt; a log without a serial stores nothing."""
    labelled = tmp_path / "labelled.toml"
    doc = (ROOT / "config" / "vehicles" / "ardupilot_sitl_quad.toml").read_text()
    assert "capacity_ah = 2.2" in doc
    labelled.write_text(doc.replace("capacity_ah = 2.2", "capacity_ah = 5.0"))
    packs = tmp_path / "packs"
    logs = []
    for k, name in enumerate(("pack_c65_r1", "pack_c65_r3_soc75")):
        log = tmp_path / f"{name}.tlog"
        log.write_bytes(with_pack((FLIGHTS / name / "flight.tlog").read_bytes(), b"SN 65/1", k))
        logs.append(log)
    common = ["--vehicle", str(labelled), "--pack-dir", str(packs)]
    first = _replay(str(logs[0]), *common)
    assert "pack SN_65_1 (its serial): no memory under this label yet" in first.stderr
    record = load_record(packs, "SN_65_1")
    assert record is not None and record.capacity_ah == pytest.approx(3.25, rel=0.03)
    _replay(str(logs[1]), *common, "--out", str(tmp_path / "second.csv"))
    rows = (tmp_path / "second.csv").read_text().splitlines()
    header = rows[0].split(",")
    first_capacity = float(rows[1].split(",")[header.index("capacity_ah")])
    assert first_capacity == pytest.approx(3.25, rel=0.05)  # the label says 5.0
    record = load_record(packs, "SN_65_1")
    assert record is not None and len(record.history) == 2
    bare = _replay(str(FLIGHTS / "pack_c65_r1" / "flight.tlog"), *common)
    assert "no usable pack serial reported: nothing stored" in bare.stderr
    assert json.loads(bare.stdout)["logs"] == 1
    assert sorted(p.name for p in packs.iterdir()) == ["SN_65_1.json"]
