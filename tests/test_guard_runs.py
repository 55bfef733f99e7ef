"""SampleGuard.check_many (clean runs found column-wise) gives what check gives one by one."""

from __future__ import annotations

import math
import random
from dataclasses import astuple
from pathlib import Path

import pytest
from fixtures.flight import make_truth, write_bin, write_ulg

from estimator.logs import dataflash, ulog
from estimator.telemetry.plausibility import InputLimits, SampleGuard
from estimator.telemetry.sample_columns import SampleColumns
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    LandedSample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
    of_columns,
)

LIMITS = [
    InputLimits(),
    InputLimits(min_voltage_v=11.0, max_voltage_v=12.5, max_speed_mps=5.0, max_power_w=1000.0),
]


def _one_by_one(samples: list[Sample], limits: InputLimits) -> tuple[list[str], dict[str, int]]:
    guard = SampleGuard(limits)
    out = [s for sample in samples for s in guard.check(sample)] + guard.flush()
    return [repr(s) for s in out], dict(guard.counts)


def _batched(
    samples: list[Sample], limits: InputLimits, size: int, columns: SampleColumns | None = None
) -> tuple[list[str], dict[str, int]]:
    guard = SampleGuard(limits)
    out = [
        s
        for i in range(0, len(samples), size)
        for s in guard.check_many(
            samples[i : i + size], None if columns is None else columns.rows(slice(i, i + size))
        )
    ]
    return [repr(s) for s in out + guard.flush()], dict(guard.counts)


def _value(rng: random.Random, scale: float) -> float:
    return rng.choice([math.nan, math.inf, -math.inf, *[rng.gauss(0.0, scale)] * 37])


def _stream(rng: random.Random) -> list[Sample]:
    """Samples of every kind; clock steps at the window's edges, reboots, jumps, values at
    the limits (a horizontal speed of exactly 200 m/s), NaN and infinities."""
    trouble = rng.random()
    time_s, v = rng.uniform(0.0, 100.0), [0.0, 0.0, 0.0]
    steps = [0.0, 0.05, 0.1, 2.5, -1.0, -2.0]
    jumps = [-50.0, -2.0000001, 2.5000001, 3.0, 200.0, 1e9, math.nan]
    samples: list[Sample] = []
    for _ in range(rng.randrange(1, 1200)):
        time_s += rng.choice(jumps if rng.random() < 0.05 * trouble else steps)
        kind = rng.random()
        if kind < 0.5:
            if rng.random() < 0.1 * trouble:
                v = [_value(rng, 30.0), _value(rng, 30.0), _value(rng, 10.0)]
            elif rng.random() < 0.01:
                v = [120.0, 160.0, rng.choice([100.0, -100.0, 5.0])]
            else:
                v = [x + rng.gauss(0.0, 1.0) for x in v]
            alt = None if rng.random() < 0.1 else _value(rng, 100.0)
            samples.append(VelocitySample(time_s, v[0], v[1], v[2], alt))
        elif kind < 0.8:
            volt = rng.choice([12.0, 11.0, 0.0, 150.0, 150.00001, _value(rng, 20.0)])
            amp = rng.choice([None, 10.0, -20.0, 1000.0, _value(rng, 100.0)])
            mah = rng.choice([None, 0.0, -1.0, 1e6, _value(rng, 1000.0)])
            samples.append(BatterySample(time_s, volt, amp, mah))
        elif kind < 0.88:
            samples.append(WindSample(time_s, rng.choice([36.0, _value(rng, 40.0)]), 48.0))
        else:
            other = rng.choice([ArmedSample, LandedSample, GripperSample, RebootSample])
            samples.append(other(time_s) if other is RebootSample else other(time_s, True))
    return samples


@pytest.mark.parametrize("seed", range(40))
def test_check_many_equals_check_on_random_streams(seed: int) -> None:
    rng = random.Random(seed)
    samples, limits = _stream(rng), rng.choice(LIMITS)
    expected = _one_by_one(samples, limits)
    for size in (512, 7):
        assert _batched(samples, limits, size) == expected, size
    assert _batched(samples, limits, 512, SampleColumns.of_samples(samples)) == expected


@pytest.mark.parametrize("writer", [write_bin, write_ulg], ids=["dataflash", "ulog"])
def test_check_many_equals_check_on_reader_streams(tmp_path: Path, writer: object) -> None:
    path = writer(tmp_path / "flight", make_truth())  # type: ignore[operator]
    reader = dataflash if path.read_bytes().startswith(b"\xa3\x95") else ulog
    stream = reader.iter_samples(path)
    samples = list(stream._it)
    for limits in LIMITS:
        expected = _one_by_one(samples, limits)
        assert _batched(samples, limits, 512) == expected
        if stream.columns is not None:  # the ULog reader's own columns
            assert _batched(samples, limits, len(samples), stream.columns) == expected


def test_a_readers_columns_are_its_samples_columns(tmp_path: Path) -> None:
    stream = ulog.iter_samples(write_ulg(tmp_path / "flight.ulg", make_truth()))
    assert stream.columns is not None
    samples = list(stream._it)
    read = SampleColumns.of_samples(samples)
    mine = stream.columns
    assert (mine.kinds == read.kinds).all() and (mine.time_s == read.time_s).all()
    assert mine.values.keys() == read.values.keys() and mine.known.keys() == read.known.keys()
    for name, column in read.values.items():
        assert (mine.values[name] == column).all(), name
    for name, flags in read.known.items():
        assert (mine.known[name] == flags).all(), name


@pytest.mark.parametrize("seed", range(5))
def test_samples_built_column_wise_equal_the_constructors(seed: int) -> None:
    rng = random.Random(seed)
    samples = _stream(rng)
    for sample_type in {type(s) for s in samples}:
        same = [s for s in samples if type(s) is sample_type]
        columns = [list(column) for column in zip(*(astuple(s) for s in same), strict=True)]
        built = of_columns(sample_type, *columns)
        assert [repr(s) for s in built] == [repr(s) for s in same]
        assert built == same
    with pytest.raises(ValueError):
        of_columns(VelocitySample, [1.0], [2.0])
