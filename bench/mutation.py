"""Mutated input files: 5,250 damaged copies of valid vehicle files, daemon configurations,
missions and logs (tlog, DataFlash .bin, PX4 .ulg, CMU CSV), each used as the CLI would
(``tests/fixtures/mutation.py``: a vehicle or a configuration replays a flight and plans a
mission, a mission is planned, a log is replayed).

Prints, per kind and in total, how many ended in sane figures (ok), in a one-sentence user
error, in a traceback, in a hang (over :data:`HANG_S`) or in silent nonsense (non-finite or
absurd figures without an error), each distinct failure once, and the runtime. Then
``fleet replay`` on two worker processes over :data:`FLEET_LOGS` further mutated logs:
failed rows, distinct reasons, and those of no known cause ("unexpected error", which name
the exception). Seeded: the same files every run. Run: ``python -m bench mutation`` (or
``make bench``).
"""

from __future__ import annotations

import random
import re
import sys
import tempfile
import time
import traceback
from collections import Counter
from pathlib import Path

import pyarrow.parquet as pq

from estimator.analysis.fleet import connect, run_fleet
from estimator.analysis.fleet_flight import FleetJob
from estimator.physics.vehicle import default_vehicle

REPO = Path(__file__).resolve().parent.parent
#: Mutated files per seed file (21 seeds: 5,250 files).
PER_SEED = 250
#: A file still being read after this many seconds is a hang.
HANG_S = 20.0
SEED = 20_240_519
#: Mutated logs given to ``fleet replay``.
FLEET_LOGS = 400


def main() -> int:
    sys.path.insert(0, str(REPO / "tests"))
    from fixtures.mutation import judge, mutate, seed_files, time_limit

    rng = random.Random(SEED)
    counts: dict[str, Counter[str]] = {}
    shown: Counter[tuple[str, str, str]] = Counter()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        seeds = seed_files(directory)
        seed_log, seed_mission = seeds["log"][2], seeds["mission"][0]
        for kind, paths in seeds.items():
            tally = counts.setdefault(kind, Counter())
            for seed in paths:
                data = seed.read_bytes()
                text = kind != "log" or seed.suffix == ".csv"
                for n in range(PER_SEED):
                    path = directory / f"mutated-{n}{seed.suffix}"
                    path.write_bytes(mutate(data, rng, text))
                    try:
                        with time_limit(HANG_S):
                            outcome = judge(kind, path, seed_log, seed_mission)
                    except TimeoutError:
                        outcome, detail = "hang", f"{seed.name} #{n}"
                    except Exception as exc:
                        line = traceback.format_exception_only(exc)[-1].strip()[:200]
                        outcome, detail = "traceback", f"{seed.name} #{n}: {line}"
                    else:
                        detail = f"{seed.name} #{n}: {outcome}"
                        if outcome.startswith("nonsense"):
                            outcome = "silent-nonsense"
                    tally[outcome] += 1
                    case = (outcome, kind, detail.split(": ", 1)[-1][:60])
                    if outcome in ("hang", "traceback", "silent-nonsense") and not shown[case]:
                        shown[case] += 1
                        print(f"  {outcome}: {kind}: {detail}", flush=True)
    wall_s = time.perf_counter() - start
    total: Counter[str] = sum(counts.values(), Counter())
    for kind, tally in [*counts.items(), ("all", total)]:
        print(
            f"{kind:8s} files={sum(tally.values())} ok={tally['ok']} "
            f"user-error={tally['user-error']} tracebacks={tally['traceback']} "
            f"hangs={tally['hang']} silent-nonsense={tally['silent-nonsense']}"
        )
    print(f"runtime {wall_s:.1f} s")
    unexpected = fleet_reasons(rng)
    return 1 if total["traceback"] + total["hang"] + total["silent-nonsense"] + unexpected else 0


def fleet_reasons(rng: random.Random) -> int:
    """Run ``fleet replay`` over :data:`FLEET_LOGS` mutated logs; print the counts and the
    distinct reasons; return how many failures had no known cause."""
    from fixtures.mutation import mutate, seed_files

    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        logs = seed_files(directory)["log"]
        paths = []
        for n in range(FLEET_LOGS):
            seed = logs[n % len(logs)]
            path = directory / f"fleet-{n}{seed.suffix}"
            path.write_bytes(mutate(seed.read_bytes(), rng, seed.suffix == ".csv"))
            paths.append(path)
        out = directory / "results.parquet"
        with connect(None, 2) as client:
            counts = run_fleet(client, paths, FleetJob("replay", default_vehicle()), out)
        errors = Counter(
            e for e in pq.read_table(out, columns=["error"]).column("error").to_pylist() if e
        )
    reasons = Counter(re.sub(r"\S*fleet-\d+\.\w+", "LOG", e) for e in errors)
    print(
        f"fleet    logs={counts.logs} ok={counts.ok} failed={counts.failed} "
        f"reasons={len(reasons)} unexpected={counts.unexpected} "
        f"({time.perf_counter() - start:.1f} s)"
    )
    for reason in sorted(r for r in reasons if r.startswith("unexpected")):
        print(f"  {reason}")
    return counts.unexpected


if __name__ == "__main__":
    sys.exit(main())
