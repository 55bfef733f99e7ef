"""Start PX4 SITL (v1.16, SIH: the quadrotor's physics inside PX4, headless) in a scratch
directory on a free instance.

The SITL folder is ``$PX4_SITL_DIR`` or, by default, ``<repo>/../shared/tools/px4-sitl`` (its
``run_px4_sitl.sh RUNDIR VAR=value…`` execs PX4; see its SOURCE.md). Instance ``N`` (MAVLink
system ``N+1``, component 1) sends its onboard link from UDP 14580+N to 127.0.0.1:14540+N,
and its ground-station link from UDP 18570+N to 127.0.0.1:14550 until a ground station speaks
to 18570+N: then to that station's address. PX4 runs in lockstep: all its time is simulated,
``speed_factor`` times the wall clock when the host keeps up.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import socket
import subprocess
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from estimator.errors import UserError
from estimator.sitl.launch import REPO, stop_process

DEFAULT_DIR = REPO.parent / "shared/tools/px4-sitl"
#: Instances tried for a free one; from 10 on PX4 sends every onboard link to one port (14549).
INSTANCES = range(1, 10)
#: UDP ports of instance N (N added): onboard link (ours, PX4's), ground station link (PX4's),
#: payload, gimbal and SIH display links (PX4's).
_PORTS = (14540, 14580, 18570, 14280, 13030, 19450)
#: Wall seconds PX4 may take to run its start-up script.
START_WALL_S = 30.0
#: PX4's line once its start-up script has run (modules and MAVLink links started).
STARTED_LINE = b"Startup script returned successfully"


def px4_dir() -> Path | None:
    """The PX4 SITL folder to use, or None when there is none (the variable wins if set)."""
    env = os.environ.get("PX4_SITL_DIR")
    path = Path(env).expanduser() if env else DEFAULT_DIR
    script = path / "run_px4_sitl.sh"
    return path if script.is_file() and (path / "bin/px4").is_file() else None


def onboard_port(instance: int) -> int:
    """The UDP port instance N's onboard (API) link sends to on 127.0.0.1: 14540+N."""
    return 14540 + instance


def gcs_port(instance: int) -> int:
    """PX4's own UDP port of instance N's ground-station link: 18570+N."""
    return 18570 + instance


def system_id(instance: int) -> int:
    """MAV_SYS_ID of instance N."""
    return instance + 1


def _udp_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _lock_free(instance: int) -> bool:
    """Whether no PX4 holds instance N's lock file (/tmp/px4_lock-N, flock)."""
    path = Path(f"/tmp/px4_lock-{instance}")
    if not path.exists():
        return True
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    finally:
        os.close(fd)  # closing releases the lock
    return True


def free_instance(candidates: Iterable[int] = INSTANCES) -> int:
    """The first instance whose ports and lock are free, starting at a place set by our pid
    (so parallel runs rarely try the same one)."""
    pool = list(candidates)
    start = os.getpid() % len(pool)
    for instance in pool[start:] + pool[:start]:
        if _lock_free(instance) and all(_udp_free(p + instance) for p in _PORTS):
            return instance
    raise UserError(f"no free PX4 SITL instance ({pool[0]}-{pool[-1]} all in use)")


@dataclass(frozen=True)
class Px4Options:
    """How to start one PX4: its folder, a fresh scratch directory (parameters persist in
    it), the instance, the lockstep speed factor and parameters set at start (name → value)."""

    root: Path
    workdir: Path
    instance: int
    speed_factor: float = 10.0
    params: dict[str, float] = field(default_factory=dict)


def command(opts: Px4Options) -> list[str]:
    """The run_px4_sitl.sh command line (ULog off unless a parameter says otherwise)."""
    params = {"SDLOG_MODE": -1.0, **opts.params}
    return [
        str(opts.root / "run_px4_sitl.sh"),
        str(opts.workdir / "rootfs"),
        f"PX4_INSTANCE={opts.instance}",
        f"PX4_SIM_SPEED_FACTOR={opts.speed_factor:g}",
        *(f"PX4_PARAM_{name}={value:g}" for name, value in params.items()),
    ]


@contextlib.contextmanager
def running_px4(opts: Px4Options) -> Iterator[subprocess.Popen[bytes]]:
    """PX4 running in ``opts.workdir`` (its output in ``px4.log`` there) once its start-up
    script has run; stopped (SIGTERM, then SIGKILL) on exit."""
    opts.workdir.mkdir(parents=True, exist_ok=True)
    log_path = opts.workdir / "px4.log"
    with log_path.open("wb") as log:
        proc = subprocess.Popen(
            command(opts), cwd=opts.workdir, stdout=log, stderr=log, stdin=subprocess.DEVNULL
        )
    try:
        deadline = time.monotonic() + START_WALL_S
        while STARTED_LINE not in log_path.read_bytes():
            if proc.poll() is not None or time.monotonic() > deadline:
                tail = log_path.read_text(errors="replace").strip().splitlines()[-3:]
                raise UserError(f"PX4 SITL did not start: {' / '.join(tail) or 'no output'}")
            time.sleep(0.05)
        yield proc
    finally:
        stop_process(proc, timeout_s=10.0)
