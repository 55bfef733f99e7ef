"""What trust costs: MAVLink 2 signing per frame, and writing the state file.

1. A 120 s simulated flight's frames (4,680) parsed as the daemon parses a UDP datagram (a
   fresh :class:`~estimator.telemetry.decode.FrameParser` each), unsigned and signed with the
   signature checked (:class:`~estimator.mavlink.signing.SigningCodec`), and packed unsigned
   and signed; µs per frame, best of 3.
2. The state file of that flight written 50 times (temporary file, fsync, ``os.replace``,
   directory fsync) in a temporary directory: size, median and worst write time.

Run: ``python -m bench.trust``.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.pipeline import Pipeline
from estimator.mavlink.signing import LinkSigning, SigningCodec
from estimator.mavlink.state_file import SavedState, write_state
from estimator.physics.vehicle import default_vehicle
from estimator.sim.run import SimConfig
from estimator.sim.simulator import simulate
from estimator.telemetry.decode import FrameParser, TelemetryDecoder

KEY = bytes(range(32))
REPEATS = 3
WRITES = 50


def best_us_per_item(items: list, work: Callable[[list], None]) -> float:  # type: ignore[type-arg]
    best = float("inf")
    for _ in range(REPEATS):
        start = time.perf_counter()
        work(items)
        best = min(best, time.perf_counter() - start)
    return best / len(items) * 1e6


def main() -> None:
    messages = [m for _, m in simulate(SimConfig(plan="hover-cruise", duration_s=120.0)).messages]
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
            assert FrameParser(SigningCodec(signing)).feed(frame)

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
    state = SavedState(1, 1, time.time(), float(snapshot["energy"]["time_s"]), snapshot)
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


if __name__ == "__main__":
    main()
