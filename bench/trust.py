"""What trust costs: MAVLink 2 signing per frame, and writing the state file.

1. A 120 s simulated flight's frames (4,680) parsed as the daemon parses a UDP datagram (a
   fresh :class:`~estimator.telemetry.decode.FrameParser` each), unsigned and signed with the
   signature checked (:class:`~estimator.mavlink.signing.SigningCodec`), and packed unsigned
   and signed; µs per frame, best of 3.
2. The state file of that flight written 50 times (temporary file, fsync, ``os.replace``,
   directory fsync) in a temporary directory: size, median and worst write time.
3. A restart mid-flight, in process: the flight replayed until 60 s, its snapshot through
   JSON, telemetry lost until 63 s, then a new pipeline continuing from the snapshot, and
   one starting from scratch, against the uninterrupted replay (energy, endurance): the table
   of docs/daemon.md (deterministic; ``scripts/figures.py`` writes it there).

Run: ``python -m bench.trust``.
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.estimate import Estimate
from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.signing import LinkSigning, SigningCodec
from estimator.mavlink.state_file import SavedState, vehicle_identity, write_state
from estimator.physics.vehicle import default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.frames import FrameParser

KEY = bytes(range(32))
RESTART_AT_S, DOWN_S = 60.0, 3.0
REPEATS = 3
WRITES = 50


def best_us_per_item(items: list, work: Callable[[list], None]) -> float:  # type: ignore[type-arg]
    best = float("inf")
    for _ in range(REPEATS):
        start = time.perf_counter()
        work(items)
        best = min(best, time.perf_counter() - start)
    return best / len(items) * 1e6


def replay(
    messages: list[tuple[float, mavlink.MAVLink_message]],
    snapshot: dict | None = None,  # type: ignore[type-arg]
) -> tuple[Pipeline, list[Estimate]]:
    decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle())
    if snapshot is not None:
        pipeline.resume(snapshot)
    estimates = []
    for _, msg in messages:
        for sample in decoder.decode(msg):
            if (estimate := pipeline.process(sample)) is not None:
                estimates.append(estimate)
    return pipeline, estimates


def flight() -> list[tuple[float, mavlink.MAVLink_message]]:
    """The bench's flight: the simulator's 120 s ``hover-cruise``, seed 3 (timed messages)."""
    return simulate(SimConfig(plan="hover-cruise", duration_s=120.0, seed=3)).messages


def _change(value: float, reference: float, spec: str) -> str:
    """``value`` against ``reference`` in %, with the documents' minus sign."""
    return f"{100 * (value / reference - 1):{spec}} %".replace("-", "\N{MINUS SIGN}")


def restart_table(timed: list[tuple[float, mavlink.MAVLink_message]]) -> str:
    """A restart mid-flight as docs/daemon.md gives it: the flight replayed until
    :data:`RESTART_AT_S`, its snapshot through JSON, telemetry lost for :data:`DOWN_S`, then a
    pipeline continued from the snapshot and one from scratch, against the uninterrupted
    replay: remaining energy (Wh) at the first and last estimate, endurance (s), and when the
    endurance is valid."""
    _, full = replay(timed)
    reference = {round(e.time_s, 3): e for e in full}
    before, _ = replay([(t, m) for t, m in timed if t <= RESTART_AT_S])
    snapshot = json.loads(json.dumps(before.snapshot()))
    after = [(t, m) for t, m in timed if t >= RESTART_AT_S + DOWN_S]
    runs = {
        "continued from the state file": replay(after, snapshot)[1],
        "from scratch (no state file)": replay(after)[1],
    }
    scratch = runs["from scratch (no state file)"]
    first_s, last_s = scratch[0].time_s, scratch[-1].time_s
    ref_first, ref_last = reference[round(first_s, 3)], reference[round(last_s, 3)]
    lines = [
        f"| restart at {RESTART_AT_S:.0f} s, {DOWN_S:.0f} s of telemetry lost "
        f"| first estimate ({first_s:.0f} s) | at {last_s:.0f} s | endurance at {last_s:.0f} s "
        "| endurance valid |",
        "|---|---:|---:|---:|---:|",
        f"| uninterrupted | {ref_first.energy_remaining_wh:.2f} Wh "
        f"| {ref_last.energy_remaining_wh:.2f} Wh | {ref_last.endurance_s:.0f} s | |",
    ]
    for name, estimates in runs.items():
        first, last = estimates[0], estimates[-1]
        valid_s = next(e.time_s for e in estimates if e.endurance_valid) - first.time_s
        e_first, e_last = first.energy_remaining_wh, last.energy_remaining_wh
        lines.append(
            f"| {name} | {e_first:.2f} Wh "
            f"({_change(e_first, ref_first.energy_remaining_wh, '+.2f')}), bias "
            f"{first.bias:.3f} ± {first.bias_sigma:.3f} "
            f"| {e_last:.2f} Wh ({_change(e_last, ref_last.energy_remaining_wh, '+.2f')}) "
            f"| {last.endurance_s:.0f} s "
            f"({_change(last.endurance_s, ref_last.endurance_s, '+.1f')}) "
            f"| {'at once' if valid_s == 0 else f'{valid_s:.0f} s later'} |"
        )
    return "\n".join(lines)


def main() -> None:
    timed = flight()
    messages = [m for _, m in timed]
    plain = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    signer = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    signer.signing = LinkSigning(KEY, 0, require=True)
    unsigned = [m.pack(plain) for m in messages]
    signed = [m.pack(signer) for m in messages]

    def parse_unsigned(frames: list[bytes]) -> None:
        for frame in frames:
            FrameParser().feed(frame)

    def parse_signed(frames: list[bytes]) -> None:
        signing = LinkSigning(KEY, 1, require=True)  # a fresh stream table: no replays
        for frame in frames:
            assert FrameParser(codec=SigningCodec(signing)).feed(frame)

    print(f"{len(messages)} frames, µs per frame (best of {REPEATS}):")
    print(
        f"  parse  unsigned {best_us_per_item(unsigned, parse_unsigned):6.1f}"
        f"   signed + checked {best_us_per_item(signed, parse_signed):6.1f}"
    )
    pack_unsigned = best_us_per_item(messages, lambda ms: [m.pack(plain) for m in ms])
    pack_signed = best_us_per_item(messages, lambda ms: [m.pack(signer) for m in ms])
    print(f"  pack   unsigned {pack_unsigned:6.1f}   signed {pack_signed:6.1f}")

    decoder, pipeline = TelemetryDecoder(), Pipeline(default_vehicle())
    for msg in messages:
        for sample in decoder.decode(msg):
            pipeline.process(sample)
    snapshot = pipeline.snapshot()
    assert snapshot is not None
    clock_s = float(snapshot["energy"]["time_s"])
    identity = vehicle_identity(default_vehicle())
    state = SavedState(1, 1, time.time(), clock_s, snapshot, identity)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "state.json"
        times_ms = []
        for _ in range(WRITES):
            start = time.perf_counter()
            write_state(path, state)
            times_ms.append((time.perf_counter() - start) * 1e3)
        times_ms.sort()
        print(
            f"state file: {path.stat().st_size} bytes; atomic write median "
            f"{times_ms[WRITES // 2]:.2f} ms, worst {times_ms[-1]:.2f} ms ({WRITES} writes, {tmp})"
        )
    print(restart_table(timed))


if __name__ == "__main__":
    main()
