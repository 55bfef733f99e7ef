"""The daemon's state file: what a restarted daemon needs to continue a flight.

One small JSON document (about 2 kB): the autopilot's (system, component), the vehicle file
it was written under (:func:`vehicle_identity`), the wall time it was written (Unix s), and
:meth:`~estimator.estimation.pipeline.Pipeline.snapshot` (energy state and its covariance,
the energy anchor of the consumed-charge counter, bias, internal resistance, tracked wind
and mass, the pack filter). Written atomically: a temporary file in the same directory,
flushed and fsync'ed, ``os.replace``'d over the old one, the directory fsync'ed; a crash
leaves the old file or the new one, never half of one.

Read as data from anyone: only a regular file of at most :data:`MAX_STATE_BYTES`, nested at
most :data:`MAX_JSON_DEPTH` deep (counted before parsing, without recursion), every value
within its range (:meth:`~estimator.estimation.pipeline.Pipeline.check_snapshot`), written
under the same vehicle file. It is used only when it also fits (:func:`mismatch`): written
by the same autopilot (system id), not older than ``max_age_s``, and the autopilot's clock
now within [saved clock, saved clock + wall time since + :data:`CLOCK_SLACK_S`] — the same
boot; a rebooted autopilot (clock behind) or another flight does not fit. A missing,
unreadable, oversized, corrupt, out-of-range, foreign or unfitting file is ignored with one
log line and the daemon starts afresh, never an error.

:class:`StateKeeper` is the daemon's side: load at start, resume at the autopilot's first
samples, write every ``period_s`` (the write and fsync in a worker thread, off the event
loop) and at exit.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import math
import os
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from estimator.estimation.pipeline import Pipeline
    from estimator.physics.vehicle import Vehicle

log = logging.getLogger("uav_energy.service")

#: Format version of the state file.
STATE_VERSION = 2
#: Largest state file read (bytes; one is about 2 kB), and its deepest nesting of JSON
#: arrays and objects (one nests 5 deep).
MAX_STATE_BYTES = 64 * 1024
MAX_JSON_DEPTH = 16
#: Autopilot clock (s) allowed ahead of the saved clock plus the wall time since (link
#: latency, a slow restart).
CLOCK_SLACK_S = 5.0
#: Seconds between log lines about failing writes.
WRITE_ERROR_LOG_S = 10.0


@dataclass(frozen=True)
class SavedState:
    """A state file's content. ``clock_s``: the autopilot time (s since its boot) of the
    snapshot; ``wall_unix_s``: when it was written."""

    system: int
    component: int
    wall_unix_s: float
    clock_s: float
    pipeline: dict[str, Any]
    vehicle: str  # vehicle_identity() of the vehicle file it was written under

    def to_json(self) -> str:
        return json.dumps(
            {
                "version": STATE_VERSION,
                "autopilot": [self.system, self.component],
                "vehicle": self.vehicle,
                "wall_unix_s": self.wall_unix_s,
                "clock_s": self.clock_s,
                "pipeline": self.pipeline,
            },
            separators=(",", ":"),
        )


def write_state(path: str | Path, state: SavedState) -> None:
    """Write ``state`` to ``path`` atomically (tmp + fsync + os.replace + directory fsync)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    data = state.to_json().encode()
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def vehicle_identity(vehicle: Vehicle) -> str:
    """What a state file records of the vehicle file it was written under: the SHA-256 of
    the vehicle's parameters (model, mass, battery, effects) in canonical JSON."""
    canonical = json.dumps(vehicle.to_toml(), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def json_depth(text: bytes) -> int:
    """The deepest nesting of arrays and objects in a JSON document (bytes), counted in one
    pass without recursion (brackets inside strings do not count)."""
    depth = deepest = 0
    in_string = escaped = False
    for byte in text:
        if in_string:
            if escaped:
                escaped = False
            elif byte == 0x5C:  # backslash
                escaped = True
            elif byte == 0x22:  # quote
                in_string = False
        elif byte == 0x22:
            in_string = True
        elif byte in b"[{":
            depth += 1
            deepest = max(deepest, depth)
        elif byte in b"]}":
            depth -= 1
    return deepest


def _read_small(path: Path) -> bytes | str:
    """The bytes of a regular file of at most :data:`MAX_STATE_BYTES`, or why not."""
    # non-blocking: a FIFO opens at once (to be refused) instead of waiting for a writer
    with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK), "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            return "not a regular file"
        data = f.read(MAX_STATE_BYTES + 1)
    if len(data) > MAX_STATE_BYTES:
        return f"larger than {MAX_STATE_BYTES} bytes"
    return data


def read_state(path: str | Path, max_age_s: float, now_unix_s: float) -> SavedState | str:
    """The state in ``path``, or why it is not used (one line)."""
    try:
        data = _read_small(Path(path))
    except FileNotFoundError:
        return "no state file yet"
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if isinstance(data, str):
        return data
    if (depth := json_depth(data)) > MAX_JSON_DEPTH:
        return f"corrupt (nested {depth} deep, at most {MAX_JSON_DEPTH})"
    try:
        doc = json.loads(data)
    except ValueError as exc:  # JSON or UTF-8 errors
        return f"corrupt ({exc})"
    try:
        if doc["version"] != STATE_VERSION:
            return f"version {doc['version']!r}, not {STATE_VERSION}"
        system, component = (int(v) for v in doc["autopilot"])
        state = SavedState(
            system,
            component,
            float(doc["wall_unix_s"]),
            float(doc["clock_s"]),
            doc["pipeline"],
            doc["vehicle"],
        )
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        return f"corrupt ({type(exc).__name__}: {exc})"
    if not (0 <= state.system <= 255 and 0 <= state.component <= 255):
        return "corrupt (autopilot ids not MAVLink's)"
    if not (math.isfinite(state.wall_unix_s) and math.isfinite(state.clock_s)):
        return "corrupt (times not finite)"
    if not isinstance(state.pipeline, dict):
        return "corrupt (no pipeline state)"
    if not isinstance(state.vehicle, str):
        return "corrupt (no vehicle identity)"
    age_s = now_unix_s - state.wall_unix_s
    if not 0 <= age_s <= max_age_s:
        return f"{age_s:.0f} s old (at most {max_age_s:.0f} s)"
    return state


def mismatch(
    state: SavedState, autopilot: tuple[int, int], clock_s: float, now_unix_s: float
) -> str | None:
    """Why ``state`` does not belong to this autopilot boot (one line), or None when it does."""
    if autopilot != (state.system, state.component):
        return (
            f"written for system {state.system} component {state.component}, "
            f"the autopilot is system {autopilot[0]} component {autopilot[1]}"
        )
    latest_s = state.clock_s + max(now_unix_s - state.wall_unix_s, 0.0) + CLOCK_SLACK_S
    if not state.clock_s <= clock_s <= latest_s:
        return (
            f"autopilot clock {clock_s:.1f} s is not that of the saved flight "
            f"({state.clock_s:.1f} s to {latest_s:.1f} s): rebooted or another flight"
        )
    return None


class StateKeeper:
    """The daemon's state file ``path``: see the module docstring. ``writes`` and
    ``write_errors`` count what happened; a failing write is logged at most every
    :data:`WRITE_ERROR_LOG_S`, never fatal."""

    def __init__(self, path: str, max_age_s: float, period_s: float, pipeline: Pipeline) -> None:
        self.path, self.max_age_s, self.period_s = path, max_age_s, period_s
        self.pipeline = pipeline
        self._vehicle = vehicle_identity(pipeline.vehicle)
        self.saved: SavedState | None = None  # loaded, waiting for the autopilot
        self.writes = 0
        self.write_errors = 0
        self._error_logged_s = -math.inf

    def attach(self, pipeline: Pipeline) -> None:
        """Keep the flight state of ``pipeline`` from now on (the daemon's vehicle changed
        before its first estimate: a pack of other cells); a state loaded for the old vehicle
        no longer fits and is dropped."""
        self.pipeline = pipeline
        identity = vehicle_identity(pipeline.vehicle)
        if identity != self._vehicle:
            self._vehicle, self.saved = identity, None

    def load(self) -> None:
        """Read the file at start (one line either way): used only when it was written under
        this vehicle file and every value lies in its range."""
        state = read_state(self.path, self.max_age_s, time.time())
        if isinstance(state, SavedState):
            if state.vehicle != self._vehicle:
                state = "written under another vehicle file"
            else:
                try:
                    self.pipeline.check_snapshot(state.pipeline)
                except ValueError as exc:
                    state = str(exc)
        if isinstance(state, str):
            log.info("state file %s ignored: %s", self.path, state)
            return
        self.saved = state
        log.info(
            "state file %s: %.0f s old, used if system %d component %d is in the same flight",
            self.path,
            time.time() - state.wall_unix_s,
            state.system,
            state.component,
        )

    def resume(self, autopilot: tuple[int, int], clock_s: float | None) -> None:
        """The autopilot's first samples, its clock then (s): continue from the loaded state
        if it fits this boot, else say why not."""
        saved, self.saved = self.saved, None
        if saved is None:
            return
        why = "no autopilot clock" if clock_s is None else None
        if clock_s is not None:
            why = mismatch(saved, autopilot, clock_s, time.time())
        if why is None:
            try:
                self.pipeline.resume(saved.pipeline)
            except ValueError as exc:
                why = str(exc)
        if why is not None:
            log.warning("state file %s ignored: %s", self.path, why)
            return
        energy = saved.pipeline["energy"]
        log.info(
            "state file %s: continuing the flight from %.1f s (energy %.1f Wh, bias %.3f)",
            self.path,
            saved.clock_s,
            energy["x"][0],
            energy["x"][1],
        )

    def _state(self, autopilot: tuple[int, int] | None) -> SavedState | None:
        snapshot = self.pipeline.snapshot()
        if autopilot is None or snapshot is None:
            return None
        clock_s = float(snapshot["energy"]["time_s"])
        return SavedState(*autopilot, time.time(), clock_s, snapshot, self._vehicle)

    def save(self, autopilot: tuple[int, int] | None) -> None:
        """Write now (at exit), if there is a flight state."""
        if (state := self._state(autopilot)) is None:
            return
        try:
            write_state(self.path, state)
        except OSError as exc:
            self._failed(exc)
            return
        self.writes += 1

    async def run(self, autopilot: Callable[[], tuple[int, int] | None]) -> None:
        """Write every ``period_s`` while the daemon runs (``autopilot()``: its ids now)."""
        while True:
            await asyncio.sleep(self.period_s)
            if (state := self._state(autopilot())) is None:
                continue
            try:
                await asyncio.to_thread(write_state, self.path, state)
            except OSError as exc:
                self._failed(exc)
                continue
            self.writes += 1

    def _failed(self, exc: OSError) -> None:
        self.write_errors += 1
        now_s = time.monotonic()
        if now_s - self._error_logged_s >= WRITE_ERROR_LOG_S:
            self._error_logged_s = now_s
            log.warning(
                "cannot write state file %s: %s (%d failure(s))",
                self.path,
                exc.strerror or exc,
                self.write_errors,
            )
