"""Run every bench in this package (``python -m bench`` / ``make bench``), in name order.

Each ``bench/NAME.py`` runs as ``python -m bench.NAME`` would; one failing bench is reported
and the others still run. Give names to run only some: ``python -m bench daemon``.
"""

from __future__ import annotations

import runpy
import sys
import traceback
from pathlib import Path


def bench_names() -> list[str]:
    here = Path(__file__).parent
    return sorted(p.stem for p in here.glob("*.py") if not p.stem.startswith("_"))


def main(argv: list[str]) -> int:
    names = argv or bench_names()
    failed = []
    for name in names:
        print(f"== bench.{name}", flush=True)
        try:
            runpy.run_module(f"bench.{name}", run_name="__main__")
        except SystemExit as exc:
            if exc.code not in (0, None):
                failed.append(name)
        except Exception:
            traceback.print_exc()
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
