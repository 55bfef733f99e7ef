"""Start an ArduCopter SITL binary in a scratch directory on a free instance.

The binary is ``$ARDUPILOT_SITL_BINARY`` or, by default, ``<repo>/../shared/tools/
ardupilot-sitl/arducopter``; its parameter defaults are ``copter.parm`` beside it (or
``$ARDUPILOT_SITL_DEFAULTS``): without them SITL refuses to arm ("Check frame class and
type"). Instance ``N`` serves MAVLink on tcp:127.0.0.1:5760+10N (SERIAL0; SITL waits for this
first client before it runs) and 5762+10N (SERIAL1).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from estimator.errors import UserError

REPO = Path(__file__).resolve().parents[2]
DEFAULT_BINARY = REPO.parent / "shared/tools/ardupilot-sitl/arducopter"
#: CMAC, ArduPilot's usual SITL home: lat, lon (deg), alt (m AMSL), heading (deg).
HOME = (-35.363261, 149.165230, 584.0, 353.0)
#: Instances tried for a free one (ports 5760+10N … 5763+10N); low ones are left to people.
INSTANCES = range(20, 90)
#: Wall seconds SITL may take to open its ports.
LISTEN_WALL_S = 30.0


def sitl_binary() -> Path | None:
    """The SITL binary to use, or None when there is none (the variable wins if set)."""
    env = os.environ.get("ARDUPILOT_SITL_BINARY")
    path = Path(env).expanduser() if env else DEFAULT_BINARY
    return path if path.is_file() and os.access(path, os.X_OK) else None


def sitl_defaults(binary: Path) -> Path:
    """The parameter defaults SITL needs (frame class and type, calibrations)."""
    env = os.environ.get("ARDUPILOT_SITL_DEFAULTS")
    path = Path(env).expanduser() if env else binary.with_name("copter.parm")
    if not path.is_file():
        raise UserError(f"SITL parameter defaults {path} not found (set ARDUPILOT_SITL_DEFAULTS)")
    return path


def serial_port(instance: int, serial: int = 0) -> int:
    """TCP port of SERIAL0 (5760+10N) or SERIAL1 (5762+10N) of instance N."""
    return 5760 + 10 * instance + 2 * serial


def _bindable(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


def free_instance(candidates: Iterable[int] = INSTANCES) -> int:
    """The first instance whose TCP ports are free, starting at a place set by our pid (so
    parallel runs rarely try the same one)."""
    pool = list(candidates)
    start = os.getpid() % len(pool)
    for instance in pool[start:] + pool[:start]:
        if all(_bindable(5760 + 10 * instance + k) for k in range(4)):
            return instance
    raise UserError("no free SITL instance (TCP ports 5960–6653 all in use)")


@dataclass(frozen=True)
class SitlOptions:
    """How to start one SITL: model (``quad``, ``hexa``, ``quad:FILE.json``), model JSON
    written into the scratch directory, extra parameter defaults, speedup, instance."""

    binary: Path
    workdir: Path
    instance: int
    model: str = "quad"
    model_json: dict[str, Any] | None = None
    params: dict[str, float] | None = None
    speedup: float = 10.0


def command(opts: SitlOptions) -> list[str]:
    """The arducopter command line (paths relative to ``opts.workdir``)."""
    defaults = [str(sitl_defaults(opts.binary))]
    if opts.params:
        defaults.append("extra.parm")
    model = opts.model
    if opts.model_json is not None:
        model = f"{opts.model}:model.json"
    home = ",".join(str(v) for v in HOME)
    return [
        str(opts.binary),
        "--model", model,
        "--speedup", f"{opts.speedup:g}",
        "--defaults", ",".join(defaults),
        f"-I{opts.instance}",
        "--home", home,
    ]  # fmt: skip


def wait_listening(proc: subprocess.Popen[bytes], log_path: Path, serial: int = 0) -> None:
    """Until SITL says SERIALn listens (SERIAL1 opens once SERIAL0 has its client; SITL
    exits at once on a port in use or a bad flag)."""
    deadline = time.monotonic() + LISTEN_WALL_S
    while f"SERIAL{serial} on TCP port".encode() not in log_path.read_bytes():
        if proc.poll() is not None or time.monotonic() > deadline:
            tail = log_path.read_text(errors="replace").strip().splitlines()[-3:]
            raise UserError(f"SITL did not start: {' / '.join(tail) or 'no output'}")
        time.sleep(0.05)


@contextlib.contextmanager
def running_sitl(opts: SitlOptions) -> Iterator[subprocess.Popen[bytes]]:
    """SITL running in ``opts.workdir`` (its output in ``sitl.log`` there); stopped on exit."""
    opts.workdir.mkdir(parents=True, exist_ok=True)
    if opts.params:
        lines = [f"{name} {value:g}\n" for name, value in opts.params.items()]
        (opts.workdir / "extra.parm").write_text("".join(lines))
    if opts.model_json is not None:
        (opts.workdir / "model.json").write_text(json.dumps(opts.model_json, indent=1))
    log_path = opts.workdir / "sitl.log"
    with log_path.open("wb") as log:
        proc = subprocess.Popen(command(opts), cwd=opts.workdir, stdout=log, stderr=log)
    try:
        wait_listening(proc, log_path)
        yield proc
    finally:
        stop_process(proc, timeout_s=10.0)


def stop_process(proc: subprocess.Popen[bytes], timeout_s: float) -> None:
    """SIGTERM, then SIGKILL if ``proc`` has not ended within ``timeout_s`` (s)."""
    proc.terminate()
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
