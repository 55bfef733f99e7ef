"""The daemon-only install for a Pi Zero 2: its size, and the daemon under a CPU quota.

1. Install size: ``python -m venv`` in a temporary directory, ``pip install`` of a copy of the
   package's source (pyproject.toml, README.md, estimator/: the build leaves the work tree
   alone) from the package index, and the bytes of each installed distribution as its RECORD
   lists them (the .pyc files pip compiles included; the venv's own pip and setuptools left
   out). At the end the same venv gets the ``analysis`` and ``fleet`` extras: what
   ``pip install uav-energy`` installed before the daemon-only core.
2. The installed ``uav-energy run`` (the venv's own entry point; the work tree's with
   ``--no-install``) inside a cgroup of its own whose CPU quota is each of QUOTAS (a share
   of one core per 100 ms period: cgroup v2 ``cpu.max``, or v1 ``cpu.cfs_quota_us`` /
   ``cpu.cfs_period_us`` where the cpu controller is mounted as v1; root needed), then without
   a quota for reference, fed :mod:`bench.daemon`'s stream (ArduCopter SITL telemetry, one
   frame a datagram over loopback UDP) at 50 messages/s for SECONDS after a warm-up. Figures:
   time from start to listening (imports under the quota), CPU share of one core and RSS
   (psutil), the quota's throttled periods over the whole run (start-up included; the
   cgroup's cpu.stat), and the latency from each estimate's closing datagram to its JSON line.
   The closing datagram is found by running the same frames through the daemon's path in
   process and matching the estimates by ``time_s``: an estimate delayed past the next
   datagram is still timed from the one that closed it.

Run: ``python -m bench.pi_zero [SECONDS] [--no-install]`` (SECONDS default 60).
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from bench.daemon import (
    RATE_MSG_S,
    REPO,
    TLOG,
    WARMUP_S,
    Run,
    at_50_msg_s,
    daemon_command,
    daemon_estimates,
    free_port,
    tlog_frames,
)

#: What ``pip install`` needs of the work tree.
SOURCE = ("pyproject.toml", "README.md", "estimator")
#: Distributions of the venv itself, not of the install.
VENV_OWN = frozenset({"pip", "setuptools"})
#: CPU quotas, share of one core (the Pi Zero 2 stand-in first).
QUOTAS = (0.15, 0.05, 0.02)
PERIOD_US = 100_000
LATENCY_GOAL_MS = 100.0
CGROUP_NAME = "uav-energy-bench"

SIZES = r"""
import json
from importlib.metadata import distributions
sizes = {}
for dist in distributions():
    paths = [f.locate() for f in dist.files or []]
    sizes[dist.metadata["Name"]] = sum(p.stat().st_size for p in paths if p.is_file())
print(json.dumps(sizes))
"""


def run_quiet(command: list[str]) -> None:
    """Run ``command``; its output only when it fails."""
    out = subprocess.run(command, capture_output=True, text=True)
    if out.returncode:
        sys.stderr.write(out.stdout + out.stderr)
        raise subprocess.CalledProcessError(out.returncode, command)


def installed_mb(python: Path) -> dict[str, float]:
    """MB on disk of each distribution installed for ``python`` (the venv's own left out)."""
    out = subprocess.run([str(python), "-c", SIZES], capture_output=True, text=True, check=True)
    sizes: dict[str, int] = json.loads(out.stdout)
    return {n: b / 1e6 for n, b in sizes.items() if n.lower() not in VENV_OWN}


def print_sizes(label: str, sizes_mb: dict[str, float], largest: int) -> None:
    ranked = sorted(sizes_mb.items(), key=lambda item: -item[1])
    print(f"  {label}: {sum(sizes_mb.values()):.1f} MB in {len(sizes_mb)} distributions")
    print("    " + ", ".join(f"{name} {mb:.1f}" for name, mb in ranked[:largest]))


def core_install(tmp: Path) -> Path:
    """A fresh venv in ``tmp`` with ``pip install uav-energy`` from a copy of the source; its
    python. Prints the install's size."""
    source = tmp / "source"
    source.mkdir()
    for name in SOURCE:
        path = REPO / name
        if path.is_dir():
            shutil.copytree(path, source / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(path, source / name)
    run_quiet([sys.executable, "-m", "venv", str(tmp / "venv")])
    python = tmp / "venv/bin/python"
    run_quiet([str(python), "-m", "pip", "install", "--quiet", str(source)])
    print("install size (python -m venv; pip install; RECORD bytes, .pyc included):")
    print_sizes("pip install uav-energy", installed_mb(python), largest=20)
    return python


def add_extras(python: Path) -> None:
    """The analysis and fleet extras into ``python``'s venv; prints the size after."""
    source = python.parent.parent.parent / "source"
    run_quiet([str(python), "-m", "pip", "install", "--quiet", f"{source}[analysis,fleet]"])
    print_sizes("pip install 'uav-energy[analysis,fleet]'", installed_mb(python), largest=8)


class CpuQuota:
    """A cgroup of its own holding its processes to ``share`` of one core."""

    def __init__(self, share: float) -> None:
        quota_us = round(share * PERIOD_US)
        unified = Path("/sys/fs/cgroup")
        controllers = unified / "cgroup.controllers"
        v1 = Path("/sys/fs/cgroup/cpu")
        if controllers.is_file() and "cpu" in controllers.read_text().split():
            (unified / "cgroup.subtree_control").write_text("+cpu")
            self.path = unified / CGROUP_NAME
            self.path.mkdir(exist_ok=True)
            (self.path / "cpu.max").write_text(f"{quota_us} {PERIOD_US}")
        elif (v1 / "cpu.cfs_quota_us").is_file():
            self.path = v1 / CGROUP_NAME
            self.path.mkdir(exist_ok=True)
            (self.path / "cpu.cfs_period_us").write_text(str(PERIOD_US))
            (self.path / "cpu.cfs_quota_us").write_text(str(quota_us))
        else:
            raise OSError("no cgroup cpu controller (v2 cpu.max or v1 cpu.cfs_quota_us) here")

    def join(self) -> None:
        """Move the calling process into the cgroup (a child's ``preexec_fn``)."""
        (self.path / "cgroup.procs").write_text(str(os.getpid()))

    def throttled(self) -> tuple[int, int]:
        """(periods, periods throttled) since the cgroup was made."""
        stat = dict(line.split() for line in (self.path / "cpu.stat").read_text().splitlines())
        return int(stat["nr_periods"]), int(stat["nr_throttled"])


@contextmanager
def cpu_quota(share: float) -> Iterator[CpuQuota]:
    """A :class:`CpuQuota`, removed after (its processes must have exited)."""
    quota = CpuQuota(share)
    try:
        yield quota
    finally:
        quota.path.rmdir()


def closing_latency_ms(run: Run, closed_by: dict[float, int], first: int) -> np.ndarray:
    """Latency (ms) of each JSON line whose estimate was closed by datagram ``first`` or a
    later one: from sending that datagram to the line's arrival."""
    latency = []
    for arrival, line in zip(run.answers.arrival_s, run.answers.lines, strict=True):
        time_s = line["time_s"]
        i = closed_by.get(time_s) if isinstance(time_s, float) else None
        if i is not None and i >= first:
            latency.append(1000 * (arrival - run.sent_s[i]))
    return np.array(latency)


async def quota_runs(program: tuple[str, ...], seconds: float) -> None:
    frames = list(tlog_frames(TLOG))[: int((WARMUP_S + seconds) * RATE_MSG_S)]
    closed_by = {e.time_s: i for i, e in daemon_estimates(frames)}
    first = int(WARMUP_S * RATE_MSG_S)
    expected = sum(i >= first for i in closed_by.values())
    print(
        f"uav-energy run ({' '.join(Path(p).name for p in program)}), {RATE_MSG_S:.0f} msg/s "
        f"of {TLOG.relative_to(REPO)} over loopback UDP for {seconds:.0f} s, "
        f"{expected} estimates expected"
    )
    for share in (*QUOTAS, None):
        listen, answer = free_port(), free_port()
        command = daemon_command(listen, answer, program)
        if share is None:
            label, run = "no quota", await at_50_msg_s(command, listen, answer, frames)
            throttled = ""
        else:
            with cpu_quota(share) as quota:
                run = await at_50_msg_s(command, listen, answer, frames, quota.join)
                periods, hits = quota.throttled()
            label, throttled = f"{100 * share:.0f} % quota", f"; throttled {hits}/{periods}"
        latency_ms = closing_latency_ms(run, closed_by, first)
        p50, p99, worst = (
            np.percentile(latency_ms, [50, 99, 100]) if len(latency_ms) else [np.nan] * 3
        )
        print(
            f"  {label:>11s}: listening after {run.start_up_s:.1f} s; CPU "
            f"{100 * run.cpu_share:.2f} % of one core; RSS idle {run.idle_rss_mb:.1f} MB, "
            f"after {run.rss_mb:.1f} MB{throttled}\n"
            f"               {len(latency_ms)}/{expected} estimates, latency p50 {p50:.1f} ms, "
            f"p99 {p99:.1f} ms, max {worst:.1f} ms: p99 ≤ "
            f"{LATENCY_GOAL_MS:.0f} ms {'met' if p99 <= LATENCY_GOAL_MS else 'NOT met'}"
        )


def main() -> int:
    numbers = [a for a in sys.argv[1:] if a.replace(".", "", 1).isdigit()]
    seconds = float(numbers[0]) if numbers else 60.0
    with tempfile.TemporaryDirectory() as tmp:
        if "--no-install" in sys.argv:
            program: tuple[str, ...] = (sys.executable, "-m", "estimator.cli")
            asyncio.run(quota_runs(program, seconds))
            return 0
        python = core_install(Path(tmp))
        asyncio.run(quota_runs((str(python.parent / "uav-energy"),), seconds))
        add_extras(python)
    return 0


if __name__ == "__main__":
    sys.exit(main())
