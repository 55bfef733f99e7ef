"""The public log corpus: which logs, where they come from, and what a replay makes of each.

The manifest (``tests/data/corpus/manifest.toml``) lists every log: the public repository,
commit and path it was taken from, its sha256, the repository's licence, whether it is a real
flight or a simulation (``kind``), and, for the small logs whose licence allows it, the
committed copy (``fixture``, a file name beside the manifest). :func:`log_outcome` replays one
log as ``uav-energy replay LOG`` does, with the built-in vehicle given the log's cell count
(:func:`cells_of`; the corpus has no vehicle files): airborne seconds and estimates, or the
reason it gave none (the reader's, naming the message types found and lacking, or why no
reading counted as airborne). ``scripts/log_corpus.py`` writes the table of ``docs/logs.md``.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from estimator.analysis.replay import no_airborne_reason, replay_stream, summarize
from estimator.errors import UserError
from estimator.estimation.airborne import AIRBORNE_ALT_M
from estimator.logs import iter_samples
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.telemetry.plausibility import CELL_VOLTAGE_RANGE_V
from estimator.telemetry.samples import ArmedSample, BatterySample, Sample, VelocitySample

#: Percentile of a log's pack voltage (V) its cell count is read from (the pack near rest).
CELLS_PERCENTILE = 95.0
#: Most a lithium cell holds (V), charged.
CELLS_TOP_V = CELL_VOLTAGE_RANGE_V[1]
#: Seconds armed above home from which a log counts as a flight (:attr:`Outcome.flew`).
FLEW_MIN_S = 10.0
#: Heights above home beyond this (m) are an estimator gone astray, not flight.
MAX_FLIGHT_ALT_M = 500.0
#: Longer gaps (s) between velocity records are not counted as flown.
MAX_GAP_S = 5.0
#: Prefix of the outcome of a log whose replay raised something other than a UserError.
TRACEBACK = "traceback"


@dataclass(frozen=True)
class CorpusLog:
    """One manifest entry (see the module docstring)."""

    repo: str
    commit: str
    path: str
    sha256: str
    size_bytes: int
    licence: str
    kind: str
    fixture: str | None = None

    @property
    def cache_name(self) -> str:
        """Where the log lies below a cache folder: ``owner+name/path``."""
        return f"{self.repo.replace('/', '+')}/{self.path}"


@dataclass(frozen=True)
class Outcome:
    """What a replay of one log gave: ``reason`` is None when it flew (airborne s > 0).
    ``flew_s``: the time the log itself shows the vehicle armed (or its arming unknown) and
    more than :data:`~estimator.estimation.airborne.AIRBORNE_ALT_M` above home, from its
    velocity records' heights, whatever its battery says (:class:`FlightWatch`); None when
    those heights cannot be believed;
    ``current``: whether it gave a known, non-zero battery current."""

    format: str
    firmware: str | None
    cells: int | None
    estimates: int
    airborne_s: float
    reason: str | None
    flew_s: float | None = 0.0
    current: bool = False

    @property
    def flew(self) -> bool:
        """Whether the log shows a flight of at least :data:`FLEW_MIN_S`."""
        return self.flew_s is not None and self.flew_s >= FLEW_MIN_S

    def text(self) -> str:
        """One table cell: airborne seconds and estimates, else the reason."""
        if self.reason is None:
            return f"airborne {self.airborne_s:.0f} s, {self.estimates} estimates"
        return self.reason


def load_manifest(path: Path) -> list[CorpusLog]:
    """The manifest's ``[[log]]`` entries, in file order."""
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"cannot read the corpus manifest {path}: {exc}") from None
    return [
        CorpusLog(
            repo=entry["repo"],
            commit=entry["commit"],
            path=entry["path"],
            sha256=entry["sha256"],
            size_bytes=int(entry["bytes"]),
            licence=entry["licence"],
            kind=entry["kind"],
            fixture=entry.get("fixture"),
        )
        for entry in doc["log"]
    ]


def cells_of(path: Path) -> int | None:
    """The fewest lithium cells in series that hold the log's pack voltage (its
    :data:`CELLS_PERCENTILE` th percentile, each cell at most :data:`CELLS_TOP_V`); None
    without a voltage."""
    voltages = [s.voltage_v for s in iter_samples(path) if isinstance(s, BatterySample)]
    if not voltages:
        return None
    return max(1, math.ceil(float(np.percentile(voltages, CELLS_PERCENTILE)) / CELLS_TOP_V))


def log_outcome(path: Path, vehicle: Vehicle | None = None) -> Outcome:
    """Replay the log at ``path`` (``vehicle``: the built-in one) with the log's cell count;
    never raises for what the log holds."""
    base = default_vehicle() if vehicle is None else vehicle
    fmt, firmware, cells = "?", None, None
    try:
        cells = cells_of(path)
        if cells is not None:
            base = replace(base, battery=replace(base.battery, cells=cells))
        stream = iter_samples(path, "auto", base.input_limits())
        fmt = stream.format
        watch = FlightWatch()
        flight = replay_stream(stream, base, path.stem, samples=watch.watched(stream))
        firmware = stream.firmware
        airborne_s = summarize([flight]).airborne_s
        reason = None if airborne_s > 0 else no_airborne_reason(flight, stream, base.name)
        current = stream.coverage.currents_nonzero > 0
        n = len(flight.estimates)
        flew_s = None if watch.astray else watch.flew_s
        return Outcome(fmt, firmware, cells, n, airborne_s, reason, flew_s, current)
    except UserError as exc:
        reason = str(exc).replace(f"{path}: ", "").replace(str(path), "the log")
    except Exception as exc:  # the corpus records what a user would have met
        reason = f"{TRACEBACK}: {type(exc).__name__}: {exc}"
    return Outcome(fmt, firmware, cells, 0, 0.0, reason)


class FlightWatch:
    """Time armed (or of unknown arming) more than
    :data:`~estimator.estimation.airborne.AIRBORNE_ALT_M` and at most :data:`MAX_FLIGHT_ALT_M`
    above home, summed over successive velocity samples at most :data:`MAX_GAP_S` apart, both
    that high (s). ``astray``: a height was beyond :data:`MAX_FLIGHT_ALT_M` (the log's
    estimator went astray: none of its heights tells a flight)."""

    def __init__(self) -> None:
        self.flew_s = 0.0
        self.astray = False
        self._armed: bool | None = None
        self._last_high_s: float | None = None

    def watched(self, samples: Iterable[Sample]) -> Iterator[Sample]:
        """``samples`` unchanged, observed on their way."""
        for sample in samples:
            self.observe(sample)
            yield sample

    def observe(self, sample: Sample) -> None:
        if isinstance(sample, ArmedSample):
            self._armed = sample.armed
        elif isinstance(sample, VelocitySample):
            alt_m = sample.alt_m
            self.astray = self.astray or (alt_m is not None and abs(alt_m) > MAX_FLIGHT_ALT_M)
            high = self._armed is not False and alt_m is not None and alt_m > AIRBORNE_ALT_M
            last = self._last_high_s
            if high and last is not None and 0.0 < sample.time_s - last <= MAX_GAP_S:
                self.flew_s += sample.time_s - last
            self._last_high_s = sample.time_s if high else None
