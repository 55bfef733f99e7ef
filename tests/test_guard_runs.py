"""SampleGuard.check_many (clean runs found column-wise) gives what check gives one by one."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest
from fixtures.flight import make_truth, write_bin, write_ulg

from estimator.logs import dataflash, ulog
from estimator.telemetry.plausibility import InputLimits, SampleGuard
from estimator.telemetry.samples import (
    ArmedSample,
    BatterySample,
    GripperSample,
    LandedSample,
    RebootSample,
    Sample,
    VelocitySample,
    WindSample,
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
    samples: list[Sample], limits: InputLimits, size: int
) -> tuple[list[str], dict[str, int]]:
    guard = SampleGuard(limits)
    out = [s for i in range(0, len(samples), size) for s in guard.check_many(samples[i : i + size])]
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


@pytest.mark.parametrize("writer", [write_bin, write_ulg], ids=["dataflash", "ulog"])
def test_check_many_equals_check_on_reader_streams(tmp_path: Path, writer: object) -> None:
    path = writer(tmp_path / "flight", make_truth())  # type: ignore[operator]
    reader = dataflash if path.read_bytes().startswith(b"\xa3\x95") else ulog
    samples = list(reader.iter_samples(path)._it)
    for limits in LIMITS:
        assert _batched(samples, limits, 512) == _one_by_one(samples, limits)
