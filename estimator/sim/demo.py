"""The live demo: the simulator flies a mission with a hidden wind into the daemon over loopback.

:func:`run_demo` simulates a mission (a built-in plan followed by an endless cruise leg, flown
for ``duration_s``) with a wind the estimator is not told about, plays it over a real TCP
socket on 127.0.0.1 (the simulator serves like ArduPilot SITL's tcp:5760) into a
:class:`~estimator.mavlink.service.Service` — the daemon itself, in this process — and reads every
estimate from the daemon's JSON-lines output (``json = "-"``, captured from stdout while it
runs). A rich table on
stderr shows predicted vs measured power and remaining energy / endurance ± σ against the
simulator's truth. It ends with a :class:`DemoSummary`:

- power: the model's prediction vs measured V·I while airborne (RMSE, MAPE) and the energies
  both integrate to, from a replay of the tlog the flight wrote (the definitions of
  :mod:`estimator.analysis.replay`; the replay gives the daemon's numbers, which the SITL tests
  check);
- remaining energy vs the truth (error at the end, RMS, share of estimates within 1σ);
- endurance at a few points of the final cruise vs the truth's time left to the reserve (the
  simulator continues the cruise past the flight to find it);
- the wind's cost: the extra energy drawn and how much earlier the reserve comes than in the
  same mission without wind (a truth-only simulation). The daemon learns the wind online
  (:mod:`estimator.estimation.online_effects`), so the model's power error falls once it is known.

:func:`serve_flight` and :func:`fly_live` are the loopback plumbing the SITL tests share.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from pymavlink.dialects.v20 import common as mavlink
from rich import box
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from estimator.analysis.replay import replay_stream, summarize
from estimator.errors import UserError
from estimator.estimation.airborne import AIRBORNE_ALT_M
from estimator.logs import iter_samples
from estimator.mavlink.config import ServiceConfig, validate
from estimator.mavlink.link import MavlinkLink, open_link
from estimator.mavlink.service import OWN_COMPONENT, Service
from estimator.physics.effects import Wind
from estimator.physics.vehicle import Vehicle, default_vehicle
from estimator.sim.files import write_truth_csv
from estimator.sim.link import SimPlayer
from estimator.sim.plans import Leg, Plan, builtin_plan
from estimator.sim.run import SimConfig, SimRun, SimTruth
from estimator.sim.simulator import simulate

#: The demo's hidden wind: 6 m/s from 030°, a head-wind component on the 045° cruise.
DEFAULT_WIND = Wind(speed_mps=6.0, from_deg=30.0)
CRUISE_SPEED_MPS = 10.0
CRUISE_HEADING_DEG = 45.0
#: Seconds into the final cruise at which endurance is scored against the truth.
ENDURANCE_CHECKS_S = (10.0, 30.0, 60.0, 120.0)
#: Seconds of simulated flight between two history rows of the live table.
TABLE_ROW_EVERY_S = 30.0
#: Wall seconds to wait for the daemon's first frame (it reconnects every second).
DAEMON_WAIT_S = 20.0
#: Wall seconds between checks whether the daemon has caught up after playback.
POLL_S = 0.05
#: Wall seconds without a frame read by the daemon that mean it is stuck.
STALL_S = 10.0

Row = dict[str, Any]


# -- loopback plumbing (shared with tests/test_sitl.py) ---------------------------------------


async def wait_for_daemon(link: MavlinkLink, timeout_s: float = DAEMON_WAIT_S) -> None:
    """Send an autopilot's HEARTBEAT once a second on ``link`` until a frame of component
    191 arrives (the daemon's stream requests, or its HEARTBEAT when configured to send one
    to the autopilot); TimeoutError if none does."""
    heartbeat = link.mav.heartbeat_encode(
        mavlink.MAV_TYPE_QUADROTOR,
        mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
        0,
        0,
        mavlink.MAV_STATE_STANDBY,
    )
    async with asyncio.timeout(timeout_s):
        while True:
            link.send(heartbeat)
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(1.0):
                    while True:
                        received = await link.recv()
                        if not received and link.closed:
                            raise ConnectionError("link closed before the daemon connected")
                        if any(m.get_srcComponent() == OWN_COMPONENT for m in received):
                            return


async def serve_flight(
    run: SimRun,
    link: MavlinkLink,
    speedup: float,
    tlog: Path | None = None,
    on_progress: Callable[[float], None] | None = None,
) -> SimPlayer:
    """Wait for the daemon on ``link`` (opened as system 1 component 1), then play ``run``;
    ``tlog`` receives the messages actually sent, and the truth beside it (.truth.csv)."""
    await wait_for_daemon(link)
    fh: BinaryIO | None = None
    try:
        if tlog is not None:
            tlog.parent.mkdir(parents=True, exist_ok=True)
            fh = tlog.open("wb")
        player = SimPlayer(run, link, speedup, fh, on_progress)
        await player.play()
    finally:
        if fh is not None:
            fh.close()
    if tlog is not None:
        write_truth_csv(run, tlog.with_name(tlog.stem + ".truth.csv"))
    return player


class _JsonLines(io.TextIOBase):
    """A text stream that parses the daemon's JSON lines (``--json -``) as they are written.

    Its file descriptor is an anonymous regular file (never written): the daemon then writes
    lines with plain ``sys.stdout.write`` calls, as it does for a stdout redirected to a
    file, instead of trying a non-blocking pipe transport on it."""

    def __init__(self, on_row: Callable[[Row], None] | None, regular_fd: int) -> None:
        self.rows: list[Row] = []
        self.on_row = on_row
        self._partial = ""
        self._fd = regular_fd

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def write(self, text: str) -> int:
        *lines, self._partial = (self._partial + text).split("\n")
        for line in lines:
            row = json.loads(line)
            self.rows.append(row)
            if self.on_row is not None:
                self.on_row(row)
        return len(text)


@dataclass
class LiveFlight:
    """What the daemon published during one loopback flight."""

    estimates: list[Row]
    counters: dict[str, int]
    sent: int
    wall_s: float
    wind_learnt: str = "not tracked"


async def fly_live(
    run: SimRun,
    speedup: float,
    *,
    vehicle: Vehicle | None = None,
    tlog: Path | None = None,
    publish: tuple[str, ...] = (),
    publish_rate_hz: float = 1.0,
    on_estimate: Callable[[Row], None] | None = None,
    on_progress: Callable[[float], None] | None = None,
) -> LiveFlight:
    """Simulator (tcpin on an ephemeral port) → in-process daemon (tcp client, as to
    ArduPilot SITL), all on 127.0.0.1; every estimate from the daemon's JSON lines (stdout is
    captured meanwhile: lossless, unlike a socket under bursts). ``publish`` adds the daemon's
    MAVLink output links (e.g. towards a test's ground station)."""
    loop = asyncio.get_running_loop()
    sim_link = await open_link("tcpin:127.0.0.1:0", source_system=1, source_component=1)
    sim_address = sim_link.local_address
    assert sim_address is not None
    config = ServiceConfig(
        connect=f"tcp:127.0.0.1:{sim_address[1]}",
        publish=publish,
        publish_rate_hz=publish_rate_hz,
        json="-",
        log_level="warning",
        download_mission=False,  # the simulator flies its own plan: no MAVLink mission to read
    )
    validate(config)
    service = Service(config, vehicle or default_vehicle())
    stop = asyncio.Event()
    start = time.monotonic()
    with (
        tempfile.TemporaryFile() as regular_file,
        contextlib.redirect_stdout(_JsonLines(on_estimate, regular_file.fileno())) as sink,
    ):
        daemon = loop.create_task(service.run(stop))
        try:
            flight = loop.create_task(serve_flight(run, sim_link, speedup, tlog, on_progress))
            await asyncio.wait([flight, daemon], return_when=asyncio.FIRST_COMPLETED)
            if not flight.done():  # the daemon stopped (a signal): stop playing
                flight.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await flight
                raise UserError("interrupted: the daemon stopped before the flight ended")
            player = flight.result()
            await _caught_up(service, sim_link, daemon)
        finally:
            stop.set()
            with contextlib.suppress(asyncio.CancelledError):
                await daemon
            await sim_link.close()
    online = service.pipeline.online
    return LiveFlight(
        sink.rows,
        service.counters(),
        player.counts["sent"],
        time.monotonic() - start,
        "not tracked" if online is None else _wind_text(online.wind),
    )


async def _caught_up(service: Service, sim_link: MavlinkLink, daemon: asyncio.Task[int]) -> None:
    """Return once the daemon has read (or skipped by header) every frame the simulator sent
    (RuntimeError when it makes no progress for :data:`STALL_S`)."""
    last, stalled_s = -1, 0.0
    while not daemon.done():
        link = service.link
        received = 0 if link is None else link.counts["rx_messages"] + link.counts["skipped_frames"]
        if received >= sim_link.counts["tx_messages"]:
            return
        stalled_s = 0.0 if received != last else stalled_s + POLL_S
        if stalled_s > STALL_S:
            raise RuntimeError(
                f"the daemon read {received} of {sim_link.counts['tx_messages']} frames"
            )
        last = received
        await asyncio.sleep(POLL_S)


# -- the mission and its scoring ----------------------------------------------------------------


def demo_plan(base: str | Plan = "mixed") -> Plan:
    """A plan (built-in name or Plan), then an endless cruise at 10 m/s towards 045° (the
    endurance check)."""
    plan = builtin_plan(base) if isinstance(base, str) else base
    if plan.endless:
        raise UserError(f"plan '{plan.name}' never ends: the demo appends its own cruise")
    cruise = Leg("straight", CRUISE_SPEED_MPS, heading_deg=CRUISE_HEADING_DEG)
    return replace(plan, name=f"{plan.name}+cruise", legs=(*plan.legs, cruise))


def cruise_start_s(truth: SimTruth, speed_mps: float = CRUISE_SPEED_MPS) -> float:
    """Start (autopilot s) of the final steady flight at ``speed_mps``: the last time the
    ground speed was more than 0.3 m/s off it. NaN if the flight does not end cruising."""
    off = np.nonzero(np.abs(truth.speed_mps - speed_mps) > 0.3)[0]
    if len(off) == 0:
        return float(truth.time_s[0])
    if off[-1] >= len(truth.time_s) - 1:
        return math.nan
    return float(truth.time_s[off[-1] + 1])


@dataclass(frozen=True)
class EnduranceCheck:
    """Endurance ``after_s`` into the final cruise: estimate ± 1σ vs the truth, s."""

    after_s: float
    estimate_s: float
    sigma_s: float
    truth_s: float

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.estimate_s - self.truth_s) / self.truth_s


@dataclass(frozen=True)
class DemoSummary:
    """The demo's accuracy figures. Powers W, energies Wh, times s (autopilot clock)."""

    plan: str
    wind: str
    wind_learnt: str
    speedup: float
    flight_s: float
    wall_s: float
    estimates: int
    power_rmse_w: float | None
    power_mape_pct: float | None
    energy_measured_wh: float
    energy_predicted_wh: float
    energy_error_end_wh: float
    energy_error_rms_wh: float
    energy_within_1sigma_pct: float
    final_bias: float
    endurance: tuple[EnduranceCheck, ...]
    reserve_s: float
    reserve_without_wind_s: float
    wind_cost_wh: float
    counters: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Every figure, with the derived wind costs, for JSON."""
        doc = asdict(self)
        doc["endurance"] = [{**asdict(c), "error_pct": c.error_pct} for c in self.endurance]
        doc.update(wind_cost_reserve_s=self.wind_cost_reserve_s)
        return doc

    @property
    def wind_cost_reserve_s(self) -> float:
        """How much earlier the reserve is reached than without the wind (truth)."""
        return self.reserve_without_wind_s - self.reserve_s


def score(
    run: SimRun, rows: list[Row], tlog: Path, vehicle: Vehicle, without_wind: SimRun
) -> dict[str, Any]:
    """The summary figures of one live flight (see the module docstring)."""
    truth = run.truth
    t = np.array([r["time_s"] for r in rows], dtype=float)
    k = truth.at(t)
    energy = np.array([r["energy_remaining_wh"] for r in rows], dtype=float)
    sigma = np.array([r["energy_remaining_sigma_wh"] for r in rows], dtype=float)
    error = energy - truth.energy_remaining_wh[k]
    flight = replay_stream(iter_samples(tlog), vehicle, tlog.stem)
    power = summarize([flight])
    start = cruise_start_s(truth)
    checks = []
    for after in ENDURANCE_CHECKS_S:
        at = start + after
        if not math.isfinite(at) or at > t[-1]:
            continue
        i = int(np.searchsorted(t, at))
        checks.append(
            EnduranceCheck(
                after_s=after,
                estimate_s=float(rows[i]["endurance_s"]),
                sigma_s=float(rows[i]["endurance_sigma_s"]),
                truth_s=float(truth.time_to_reserve_s[k[i]]),
            )
        )
    airborne = truth.flying[k] & (truth.alt_m[k] > AIRBORNE_ALT_M)
    return {
        "power_rmse_w": power.power_rmse_w,
        "power_mape_pct": power.power_mape_pct,
        "energy_measured_wh": power.energy_measured_wh,
        "energy_predicted_wh": power.energy_predicted_wh,
        "energy_error_end_wh": float(error[-1]),
        "energy_error_rms_wh": float(np.sqrt(np.mean(error[airborne] ** 2))),
        "energy_within_1sigma_pct": float(100.0 * np.mean(np.abs(error) <= sigma)),
        "final_bias": float(rows[-1]["bias"]),
        "endurance": tuple(checks),
        "reserve_s": run.reserve_time_s,
        "reserve_without_wind_s": without_wind.reserve_time_s,
        "wind_cost_wh": _energy_drawn_wh(run, t[-1]) - _energy_drawn_wh(without_wind, t[-1]),
    }


def _energy_drawn_wh(run: SimRun, until_s: float) -> float:
    """Energy the simulated pack delivered (truth) up to ``until_s``, Wh."""
    truth = run.truth
    keep = truth.time_s <= until_s
    return float(np.trapezoid(truth.power_w[keep], truth.time_s[keep]) / 3600.0)


# -- the live table -----------------------------------------------------------------------------


class LiveTable:
    """Rows every :data:`TABLE_ROW_EVERY_S` of flight plus the latest estimate, with truth."""

    #: Header → meaning: time s; ground speed m/s; centripetal accel m/s²; model power,
    #: fused (bias × model) and measured V·I in W; remaining energy estimate ± 1σ and truth
    #: in Wh; endurance at the current power ± 1σ and the truth's time to reserve flying the
    #: rest of the mission in min (:data:`CAPTION`).
    COLUMNS = (
        "t s",
        "V",
        "a⊥",
        "P mod",
        "P fus",
        "P meas",
        "E Wh ±σ",
        "E true",
        "end min",
        "mission min",
    )
    #: What the two endurance columns measure, under the table.
    CAPTION = (
        "end min: endurance at the present power ± 1σ (what the daemon publishes); mission "
        "min: the simulator's time to the reserve flying the rest of the mission. They differ "
        "while the power changes and meet in the final cruise."
    )

    def __init__(self, run: SimRun, title: str) -> None:
        self.run, self.title = run, title
        self.history: list[tuple[str, ...]] = []
        self.latest: Row | None = None
        self._next_row_s = 0.0

    def add(self, row: Row) -> None:
        self.latest = row
        if row["time_s"] >= self._next_row_s:
            self.history.append(self._cells(row))
            self._next_row_s = row["time_s"] + TABLE_ROW_EVERY_S

    def _cells(self, r: Row) -> tuple[str, ...]:
        k = int(self.run.truth.at(r["time_s"]))
        truth = self.run.truth
        measured = r["power_measured_w"]
        return (
            f"{r['time_s']:.0f}",
            f"{r['speed_mps']:.1f}",
            f"{r['accel_centripetal_mps2']:.1f}",
            f"{r['power_model_w']:.0f}",
            f"{r['bias'] * r['power_model_w']:.0f}",
            "—" if measured is None else f"{measured:.0f}",
            f"{r['energy_remaining_wh']:.1f}±{r['energy_remaining_sigma_wh']:.1f}",
            f"{truth.energy_remaining_wh[k]:.1f}",
            _minutes(r["endurance_s"], r["endurance_sigma_s"]),
            f"{truth.time_to_reserve_s[k] / 60:.1f}",
        )

    def render(self) -> Group:
        table = Table(
            title=self.title,
            title_justify="left",
            box=box.SIMPLE_HEAD,
            pad_edge=False,
            collapse_padding=True,
            caption=self.CAPTION,
            caption_justify="left",
        )
        for name in self.COLUMNS:
            table.add_column(name, justify="right", no_wrap=True)
        for cells in self.history:
            table.add_row(*cells)
        if self.latest is not None:
            table.add_row(*self._cells(self.latest), style="bold")
        duration = self.run.duration_s
        now = 0.0 if self.latest is None else self.latest["time_s"]
        bias = "" if self.latest is None else f"   fused bias {self.latest['bias']:.3f}"
        return Group(table, Text(f"flight {now:.0f} / {duration:.0f} s{bias}"))


def _minutes(value_s: float | None, sigma_s: float | None) -> str:
    if value_s is None or not math.isfinite(value_s):
        return "—"
    if value_s >= 99.5 * 60:
        return ">99"
    sigma = "" if sigma_s is None or not math.isfinite(sigma_s) else f"±{sigma_s / 60:.1f}"
    return f"{value_s / 60:.1f}{sigma}"


# -- the demo -----------------------------------------------------------------------------------


def run_demo(
    *,
    base_plan: str | Plan = "mixed",
    duration_s: float = 600.0,
    wind: Wind | None = DEFAULT_WIND,
    speedup: float = 20.0,
    seed: int = 0,
    out_dir: Path = Path("out/demo"),
    console: Console | None = None,
) -> DemoSummary:
    """Fly the demo mission live and score it (see the module docstring).

    ``duration_s`` of flight (the plan, then the cruise); ``speedup`` × real time; the tlog
    and truth go to ``out_dir``/demo.tlog (replay it with ``uav-energy replay``), the figures
    to ``out_dir``/summary.json. The live table goes to ``console`` (default: stderr).
    """
    if not (math.isfinite(speedup) and speedup > 0):
        raise UserError(f"the demo's speedup must be a positive number, got {speedup}")
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise UserError(f"the demo's duration must be a positive number of s, got {duration_s}")
    console = console or Console(stderr=True)
    vehicle = default_vehicle()
    effects = () if wind is None else (wind,)
    config = SimConfig(
        vehicle=vehicle,
        plan=demo_plan(base_plan),
        effects=effects,
        duration_s=duration_s,
        seed=seed,
    )
    with console.status("simulating the mission"):
        run = simulate(config)
        without_wind = simulate(replace(config, effects=()))
    wind_text = "none" if wind is None else _wind_text(wind)
    table = LiveTable(
        run, f"uav-energy demo: '{run.plan.name}', hidden wind {wind_text}, ×{speedup:g}"
    )
    tlog = out_dir / "demo.tlog"
    live = Live(table.render(), console=console, refresh_per_second=4, transient=False)

    def on_estimate(row: Row) -> None:
        table.add(row)
        live.update(table.render())

    try:
        with live:
            flight = asyncio.run(fly_live(run, speedup, tlog=tlog, on_estimate=on_estimate))
    finally:
        console.line()
    if not flight.estimates:
        raise RuntimeError("the daemon published no estimate")
    with console.status("scoring the flight against the truth"):
        figures = score(run, flight.estimates, tlog, vehicle, without_wind)
    summary = DemoSummary(
        plan=run.plan.name,
        wind=wind_text,
        wind_learnt=flight.wind_learnt,
        speedup=speedup,
        flight_s=run.duration_s,
        wall_s=flight.wall_s,
        estimates=len(flight.estimates),
        counters=flight.counters,
        **figures,
    )
    (out_dir / "summary.json").write_text(json.dumps(summary.as_dict(), indent=2) + "\n")
    return summary


def _wind_text(wind: Wind) -> str:
    return f"{wind.speed_mps:.3g} m/s from {wind.from_deg:.0f}°"


def summary_table(summary: DemoSummary) -> Table:
    """The accuracy summary as a rich table (fits 80 columns)."""
    s = summary
    table = Table(
        title=f"accuracy summary ('{s.plan}', hidden wind {s.wind})",
        show_header=False,
        title_justify="left",
    )
    table.add_column("what")
    table.add_column("value", justify="right")
    rmse = "—" if s.power_rmse_w is None else f"{s.power_rmse_w:.1f} W"
    mape = "—" if s.power_mape_pct is None else f"{s.power_mape_pct:.1f} %"
    table.add_row("flight / wall time", f"{s.flight_s:.0f} s / {s.wall_s:.1f} s")
    table.add_row("estimates from the daemon", f"{s.estimates}")
    table.add_row("model vs measured power: RMSE, MAPE", f"{rmse}, {mape}")
    table.add_row(
        "energy measured / model", f"{s.energy_measured_wh:.1f} / {s.energy_predicted_wh:.1f} Wh"
    )
    table.add_row("fused bias (measured/model) at the end", f"{s.final_bias:.3f}")
    table.add_row(
        "energy left vs truth: at the end, RMS",
        f"{s.energy_error_end_wh:+.2f} Wh, {s.energy_error_rms_wh:.2f} Wh",
    )
    table.add_row("energy left within 1σ of truth", f"{s.energy_within_1sigma_pct:.0f} %")
    for c in s.endurance:
        table.add_row(
            f"endurance {c.after_s:.0f} s into the cruise",
            f"{c.estimate_s / 60:.2f}±{c.sigma_s / 60:.2f} min, true {c.truth_s / 60:.2f} "
            f"({c.error_pct:+.1f} %)",
        )
    measured = s.energy_measured_wh
    share = 100.0 * s.wind_cost_wh / measured if measured > 0 else math.nan
    table.add_row(
        "hidden wind: extra energy drawn (truth)", f"{s.wind_cost_wh:+.1f} Wh ({share:+.0f} %)"
    )
    table.add_row("wind learnt online by the daemon", s.wind_learnt)
    table.add_row(
        "hidden wind: reserve reached earlier",
        f"{s.wind_cost_reserve_s / 60:.1f} min ({s.reserve_s / 60:.1f} vs "
        f"{s.reserve_without_wind_s / 60:.1f})",
    )
    return table
