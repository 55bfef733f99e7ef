"""Files of a simulated flight: the tlog (8-byte µs stamp + frame) and the truth CSV beside
it, and a one-line summary of the hidden effects.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from estimator.physics.effects import (
    Effect,
)
from estimator.sim.run import SimRun

#: tlog stamps are Unix µs; the simulated boot happens at this Unix time.
TLOG_EPOCH_S = 1_700_000_000.0


TRUTH_CSV_STRIDE = 5  # 50 Hz physics → 10 Hz rows


TRUTH_COLUMNS = (
    "time_s",
    "armed",
    "alt_m",
    "vn_mps",
    "ve_mps",
    "vd_mps",
    "speed_mps",
    "airspeed_mps",
    "accel_tangential_mps2",
    "accel_centripetal_mps2",
    "mass_kg",
    "power_w",
    "power_model_w",
    "voltage_v",
    "current_a",
    "soc",
    "energy_remaining_wh",
    "time_to_reserve_s",
)


def tlog_records(run: SimRun, epoch_s: float = TLOG_EPOCH_S) -> list[tuple[int, bytes]]:
    """(Unix µs, frame bytes) per message: the tlog layout (8-byte big-endian µs + frame);
    the simulated boot happens at Unix time ``epoch_s``."""
    return [(round((epoch_s + t) * 1e6), bytes(m.get_msgbuf())) for t, m in run.messages]


def write_tlog(
    run: SimRun, path: str | Path, truth_csv: bool = True, epoch_s: float = TLOG_EPOCH_S
) -> Path:
    """Write the messages as a .tlog (boot at Unix time ``epoch_s``) and, unless told not to,
    ``<stem>.truth.csv`` beside it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        for usec, frame in tlog_records(run, epoch_s):
            fh.write(struct.pack(">Q", usec) + frame)
    if truth_csv:
        write_truth_csv(run, path.with_name(path.stem + ".truth.csv"))
    return path


def write_truth_csv(run: SimRun, path: str | Path, stride: int = TRUTH_CSV_STRIDE) -> Path:
    """The truth at 10 Hz (every ``stride``-th physics step), columns :data:`TRUTH_COLUMNS`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tr = run.truth
    cols = np.column_stack([np.asarray(getattr(tr, c), dtype=float) for c in TRUTH_COLUMNS])
    np.savetxt(
        path,
        cols[::stride],
        delimiter=",",
        header=",".join(TRUTH_COLUMNS),
        comments="",
        fmt="%.6g",
    )
    return path


def hidden_effects_summary(effects: Sequence[Effect]) -> str:
    """One line naming the hidden effects and their parameters (open time-window ends left
    out), for logs and the CLI."""
    if not effects:
        return "none"
    return "; ".join(
        f"{e.name}(" + ", ".join(f"{k}={v}" for k, v in e.params.items() if v is not None) + ")"
        for e in effects
    )
