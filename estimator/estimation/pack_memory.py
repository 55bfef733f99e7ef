"""Per-pack memory: what each pack was learned to hold, kept between flights.

A directory holds one JSON file per pack, ``<pack id>.json``: the pack's real capacity (Ah)
and internal resistance (Ω) as the last flight with it ended, each with its 1σ, the label
it flew under (Ah), and its history (one row per flight: Unix time s, capacity Ah, its σ,
resistance Ω), which ``fleet`` can plot as capacity fade. The next flight with the pack starts
from it (:class:`~estimator.estimation.pack_state.PackPrior`), its σ widened by what a pack
may change between flights (:data:`BETWEEN_FLIGHTS_FRACTION`).

Pack ids come from the user (``--pack ID``, ``[pack] id``) or from the pack's serial number
as the autopilot reports it (:func:`pack_id_from_serial`); a memory file is read as hostile
input: bounded by schema and physics; a bad one is a user mistake
(:class:`~estimator.errors.UserError`) and never becomes a prior.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from estimator.errors import UserError
from estimator.estimation.pack_state import PackEstimate, PackPrior

#: A pack id: letters, digits, ``._-``, 1–64 characters, not starting with a dot.
PACK_ID = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")
#: Runs of characters a pack id may not hold (a serial's spaces, slashes, colons).
_NOT_IN_PACK_ID = re.compile(r"[^A-Za-z0-9._-]+")
#: What a pack may change between two flights (capacity and resistance, fraction, 1σ):
#: a cycle's fade, a colder or warmer day.
BETWEEN_FLIGHTS_FRACTION = 0.03
#: Largest memory file read (bytes) and history rows kept.
MAX_FILE_BYTES = 256 * 1024
MAX_HISTORY = 1000
#: Physical bounds of what a memory may say (Ah, Ω, Unix s).
CAPACITY_RANGE_AH = (0.01, 1000.0)
RESISTANCE_MAX_OHM = 2.0
TIME_MAX_S = 4e9


@dataclass(frozen=True, slots=True)
class PackRecord:
    """One pack's memory (see the module docstring)."""

    pack_id: str
    label_ah: float
    capacity_ah: float
    capacity_sigma_ah: float
    resistance_ohm: float
    resistance_sigma_ohm: float
    history: tuple[tuple[float, float, float, float], ...] = ()

    def prior(self) -> PackPrior:
        """The next flight's prior: this memory, its σ widened for the time between."""
        widen = BETWEEN_FLIGHTS_FRACTION
        return PackPrior(
            capacity_ah=self.capacity_ah,
            capacity_sigma_ah=math.hypot(self.capacity_sigma_ah, widen * self.capacity_ah),
            resistance_ohm=self.resistance_ohm,
            resistance_sigma_ohm=math.hypot(self.resistance_sigma_ohm, widen * self.resistance_ohm),
        )


def check_pack_id(pack_id: str) -> str:
    """``pack_id`` if it is one (:data:`PACK_ID`), else UserError."""
    if not PACK_ID.fullmatch(pack_id):
        raise UserError(
            f"pack id {pack_id!r} must be 1–64 letters, digits, '.', '_' or '-' "
            "(not starting with '.')"
        )
    return pack_id


def pack_id_from_serial(serial: str) -> str | None:
    """The pack id of a reported serial number (forged or garbage ones included): trimmed of
    NULs and spaces; printable ASCII only, else None; each run of other characters than
    letters, digits and ``._-`` becomes ``_``, leading dots go; None when no letter or digit
    is left or it is longer than :data:`PACK_ID` allows. ``SN 12/34`` → ``SN_12_34``."""
    text = serial.strip("\x00 ")
    if not text.isascii() or not text.isprintable():
        return None
    pack_id = _NOT_IN_PACK_ID.sub("_", text).lstrip(".")
    if not PACK_ID.fullmatch(pack_id) or not any(c.isalnum() for c in pack_id):
        return None
    return pack_id


def memory_path(directory: Path, pack_id: str) -> Path:
    return directory / f"{check_pack_id(pack_id)}.json"


def load_record(directory: Path, pack_id: str) -> PackRecord | None:
    """The pack's memory, None when it has none yet; UserError for a file that is not one."""
    path = memory_path(directory, pack_id)
    if not path.exists():
        return None
    try:
        if not path.is_file() or path.stat().st_size > MAX_FILE_BYTES:
            raise ValueError(f"not a file of at most {MAX_FILE_BYTES} bytes")
        doc = json.loads(path.read_text(encoding="utf-8"))
        return _record(doc, pack_id)
    except (OSError, UnicodeDecodeError, RecursionError, ValueError, TypeError, KeyError) as exc:
        raise UserError(f"pack memory {path} is not usable ({exc}); move it away") from None


def load_prior(directory: Path | None, pack_id: str | None, label_ah: float) -> PackPrior | None:
    """The prior of a flight with pack ``pack_id`` (None without a directory or an id, or
    for a pack last flown under another label: that memory is of another configuration)."""
    if directory is None or pack_id is None:
        return None
    record = load_record(directory, pack_id)
    if record is None or not math.isclose(record.label_ah, label_ah, rel_tol=1e-6):
        return None
    return record.prior()


def remember(
    directory: Path, pack_id: str, label_ah: float, pack: PackEstimate, when_s: float
) -> PackRecord:
    """Store what the flight that started at ``when_s`` (Unix s) learned of the pack: its
    row of the history is replaced while the flight goes on (the daemon stores as it learns),
    a new flight adds one. Atomic: a crash leaves the old file."""
    old = load_record(directory, pack_id)
    history = () if old is None else old.history
    if history and history[-1][0] == when_s:
        history = history[:-1]
    row = (when_s, pack.capacity_ah, pack.capacity_sigma_ah, pack.resistance_ohm)
    record = PackRecord(
        pack_id=pack_id,
        label_ah=label_ah,
        capacity_ah=pack.capacity_ah,
        capacity_sigma_ah=pack.capacity_sigma_ah,
        resistance_ohm=pack.resistance_ohm,
        resistance_sigma_ohm=pack.resistance_sigma_ohm,
        history=(*history, row)[-MAX_HISTORY:],
    )
    directory.mkdir(parents=True, exist_ok=True)
    path = memory_path(directory, pack_id)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(asdict(record), indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    return record


def _number(value: Any, name: str, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"'{name}' is not a number")
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"'{name}' = {value!r} is not within [{low:g}, {high:g}]")
    return float(value)


def _record(doc: Any, pack_id: str) -> PackRecord:
    if not isinstance(doc, dict):
        raise ValueError("not a JSON object")
    if doc.get("pack_id") != pack_id:
        raise ValueError(f"it is the memory of pack {doc.get('pack_id')!r}")
    lo_ah, hi_ah = CAPACITY_RANGE_AH
    capacity = _number(doc["capacity_ah"], "capacity_ah", lo_ah, hi_ah)
    rows = doc.get("history", [])
    if not isinstance(rows, list) or len(rows) > MAX_HISTORY:
        raise ValueError(f"'history' is not a list of at most {MAX_HISTORY} rows")
    history = []
    for row in rows:
        if not (isinstance(row, list) and len(row) == 4):
            raise ValueError("a history row is not [time, capacity, σ, resistance]")
        t, c, cs, r = (
            _number(v, "history", 0.0, hi)
            for v, hi in zip(row, (TIME_MAX_S, hi_ah, hi_ah, RESISTANCE_MAX_OHM), strict=True)
        )
        history.append((t, c, cs, r))
    return PackRecord(
        pack_id=pack_id,
        label_ah=_number(doc["label_ah"], "label_ah", lo_ah, hi_ah),
        capacity_ah=capacity,
        capacity_sigma_ah=_number(doc["capacity_sigma_ah"], "capacity_sigma_ah", 0.0, capacity),
        resistance_ohm=_number(doc["resistance_ohm"], "resistance_ohm", 0.0, RESISTANCE_MAX_OHM),
        resistance_sigma_ohm=_number(
            doc["resistance_sigma_ohm"], "resistance_sigma_ohm", 0.0, RESISTANCE_MAX_OHM
        ),
        history=tuple(history),
    )
