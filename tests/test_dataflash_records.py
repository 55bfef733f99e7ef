"""The column-wise DataFlash decode gives, field by field, what pymavlink's messages give."""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import pytest
from fixtures.dataflash_writer import DataFlashWriter
from fixtures.flight import make_truth, write_bin, write_copter32_bin
from pymavlink.DFReader import DFReader_binary

from estimator.logs import dataflash_records, iter_samples
from estimator.telemetry.samples import BatterySample

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).parent.parent
REAL_LOGS = [
    DATA / "arducopter_guided.bin",
    DATA / "corpus" / "adgfuzz_sitl_copter.bin",
    *sorted((REPO / "replay" / "sitl").glob("*/flight.BIN")),
]
#: Every format character of pymavlink's table, in one message of the test log below.
EVERY_CHAR = "abBhHiIfgdnNZcCeELMqQ"


def _same(a: Any, b: Any) -> bool:
    """Equal values of the same type (NaN equal to NaN)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and math.isnan(a):
        return math.isnan(b)
    return bool(a == b)


def _compare_every_type(path: Path) -> set[str]:
    """Rows of each message type against pymavlink's messages, every column; the format
    characters compared."""
    index = DFReader_binary(str(path))
    compared: set[str] = set()
    for type_id, fmt in sorted(index.formats.items()):
        if not index.counts[type_id] or fmt.name in ("FMT", "FILE"):
            continue  # FILE: pymavlink gives its Z column as bytes, never read here
        columns = tuple(c for c in fmt.columns if fmt.colhash[c] < len(fmt.msg_fmts))
        plan = dataflash_records.plan(index, {fmt.name}, columns)
        assert plan is not None, fmt.name
        rows = list(itertools.chain.from_iterable(plan.rows()))
        reader = DFReader_binary(str(path))
        messages = []
        while (msg := reader.recv_match(type={fmt.name}, strict=True)) is not None:
            messages.append(msg)
        assert len(rows) == len(messages), fmt.name
        for row, msg in zip(rows, messages, strict=True):
            assert row.get_type() == msg.get_type()
            for column in columns:
                mine, theirs = getattr(row, column), getattr(msg, column)
                assert _same(mine, theirs), (fmt.name, column, mine, theirs)
        compared.update(fmt.format[fmt.colhash[c]] for c in columns)
    return compared


@pytest.mark.parametrize("path", REAL_LOGS, ids=[p.parent.name + "/" + p.name for p in REAL_LOGS])
def test_rows_equal_pymavlink_messages_on_real_logs(path: Path) -> None:
    compared = _compare_every_type(path)
    assert set("BCHILMNQZcdefh") <= compared  # scaled, text, integer and float columns


def test_rows_equal_pymavlink_messages_for_every_format_character(tmp_path: Path) -> None:
    log = DataFlashWriter()
    layouts = {"TSTA": EVERY_CHAR[:16], "TSTB": EVERY_CHAR[16:]}  # FMT holds 16 characters
    for name, chars in layouts.items():
        log.define(name, chars, ",".join(f"{c}{i}" for i, c in enumerate(chars)))
    text = {"n": b"ab\0c", "N": b"caf\xc3\xa9 \xff", "Z": "Gripper load released: 1.5 µs".encode()}
    for k, value in enumerate([0.0, -1.5, math.nan, 1234.56789, -1e-3]):
        for name, chars in layouts.items():
            values: dict[str, Any] = {}
            for i, char in enumerate(chars):
                column = f"{char}{i}"
                if char == "a":
                    values[column] = bytes(range(k, k + 64))
                elif char in text:
                    values[column] = text[char][k % 3 :]
                elif char in "fgd":
                    values[column] = value
                elif char in "cehiqL":
                    values[column] = -(k + 1) * 37
                else:
                    values[column] = (k + 1) * 23
            log.write(name, **values)
    compared = _compare_every_type(log.save(tmp_path / "every.bin"))
    assert compared == set(EVERY_CHAR)


@pytest.mark.parametrize("writer", [write_bin, write_copter32_bin])
def test_rows_equal_pymavlink_messages_on_the_fixture_flights(tmp_path: Path, writer: Any) -> None:
    _compare_every_type(writer(tmp_path / "f.bin", make_truth()))


def test_a_format_that_does_not_fill_its_record_is_read_by_the_library(tmp_path: Path) -> None:
    """A forged FMT whose struct is shorter than its declared length: no column-wise plan;
    the reader reads the library's messages and gives the samples of the other types."""
    data = bytearray(write_bin(tmp_path / "f.bin", make_truth()).read_bytes())
    index = DFReader_binary(str(tmp_path / "f.bin"))
    bat = index.name_to_id["BAT"]
    fmt_at = next(o for o in index.offsets[0x80] if data[o + 3] == bat)
    data[fmt_at + 4] += 1  # the declared length, one byte more than its fields
    forged = tmp_path / "forged.bin"
    forged.write_bytes(bytes(data))
    log = DFReader_binary(str(forged))
    assert dataflash_records.plan(log, {"BAT"}, ("Volt",)) is None
    assert dataflash_records.plan(log, {"XKF1"}, ("VN",)) is not None
    stream = iter_samples(forged)
    samples = list(stream)
    assert samples and stream.bad_frames > 0


def test_a_column_named_beyond_its_format_is_a_bad_frame_not_a_crash(tmp_path: Path) -> None:
    """A forged FMT naming more columns than it has fields, RemPct among the extra ones:
    pymavlink's message raises IndexError on reading it (the reader used to stop with that
    traceback); a row has no such column, and each BAT record is a counted bad frame."""
    data = bytearray(write_bin(tmp_path / "f.bin", make_truth()).read_bytes())
    columns = b"TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,Pad,RemPct"
    at = data.index(columns.replace(b",Pad", b""))
    data[at : at + len(columns)] = columns  # over the column string's NUL padding
    forged = tmp_path / "forged.bin"
    forged.write_bytes(bytes(data))
    stream = iter_samples(forged)
    samples = list(stream)
    bat = DFReader_binary(str(forged))
    assert stream.bad_frames == bat.counts[bat.name_to_id["BAT"]]
    assert samples and not any(isinstance(s, BatterySample) for s in samples)
