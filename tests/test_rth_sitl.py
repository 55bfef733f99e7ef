"""The live return-home energy against real RTLs in ArduCopter SITL with wind.

SITL with a steady wind serves the daemon (SERIAL0, vehicle file fitted to SITL's quad) and a
pilot (SERIAL1). For each point the pilot takes off to 20 m, flies a GUIDED velocity leg away
from home, sets RTL_SPEED to the ground speed home the daemon recommends (``RTH_VG``) and
switches to RTL; the autopilot flies home at that speed, lands and disarms. Compared: the
daemon's ``RTH_WH`` of the last estimate before the switch, and the energy the autopilot
measured from the switch to the disarm (BATTERY_STATUS.energy_consumed, its own ∫V·I); beside
it a PX4-style figure: (distance / RTL speed + climb, loiter and descent at their set rates) ×
the power measured at the switch.

``python tests/test_rth_sitl.py`` flies :data:`POINTS` (four directions against the wind) and
prints the table docs/daemon.md gives; the test flies two of them.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

import pytest
from doc_rows import DocRows
from test_ardupilot_sitl import FITTED_VEHICLE, REPO, LiveDaemon, live_daemon, needs_sitl

from estimator.analysis.replay import replay_log
from estimator.logs.mission_files import M_PER_DEG
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.launch import HOME
from estimator.sitl.pilot import Pilot

#: SITL's wind: speed m/s, direction it blows from (deg).
WIND = (5.0, 0.0)
#: The live returns and mission: each figure lies in its row of docs/daemon.md's table.
doc_figure = DocRows("docs/daemon.md").check
#: Legs flown away from home before each RTL: name, north and east ground velocity m/s,
#: duration s.
POINTS = (
    ("north: out upwind", 8.0, 0.0, 40.0),
    ("south: out downwind", -8.0, 0.0, 40.0),
    ("east: crosswind", 0.0, 8.0, 40.0),
    ("south-west: quartering", -4.6, -4.6, 70.0),
)
#: ArduCopter defaults the daemon's return model follows (docs/daemon.md): RTL_ALT 15 m,
#: RTL_LOIT_TIME 5 s, WPNAV_SPEED_UP 2.5, WPNAV_SPEED_DN 1.5, LAND_ALT_LOW 10 m, LAND_SPEED 0.5.
RTL_ALT_M, LOITER_S, UP_MPS, DOWN_MPS, LAND_LOW_M, LAND_MPS = 15.0, 5.0, 2.5, 1.5, 10.0, 0.5
TAKEOFF_M = 20.0
#: The warm-up before the first point: north, south, east and west at 8 m/s, 15 s each (the
#: online tracker sees the wind in every direction; ArduCopter's EKF starts its drag wind).
WARM_UP_V_MPS, WARM_UP_S = ((8.0, 0.0), (-8.0, 0.0), (0.0, 8.0), (0.0, -8.0)), 15.0
#: The wind the daemon's return assumes: "tracked" (the online tracker's, the default) or
#: "autopilot" (its EKF's, from drag). The airspeed limit is the vehicle file's.
DAEMON_CONFIG = '[return]\nwind = "{wind}"\n'


@dataclass(frozen=True)
class RtlPoint:
    """One RTL: the daemon's figures at the switch, what the autopilot used, the PX4-style
    figure; energies Wh, distance m, speed m/s, power W, times s (autopilot clock)."""

    name: str
    switch_s: float
    distance_m: float
    predicted_wh: float
    predicted_sigma_wh: float
    predicted_time_s: float
    rtl_speed_mps: float
    power_w: float
    used_wh: float
    flown_s: float
    px4_wh: float

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.predicted_wh / self.used_wh - 1.0)

    @property
    def px4_error_pct(self) -> float:
        return 100.0 * (self.px4_wh / self.used_wh - 1.0)


def _latest(live: LiveDaemon, before_s: float) -> dict:
    """The daemon's last estimate at or before ``before_s`` (autopilot clock) with return
    figures."""
    estimates = [
        e for e in live.estimates() if e["time_s"] <= before_s and e["rth_energy_wh"] is not None
    ]
    if not estimates:
        raise AssertionError(f"no estimate with return figures before {before_s:.1f} s")
    return estimates[-1]


def px4_style_wh(distance_m: float, alt_m: float, speed_mps: float, power_w: float) -> float:
    """Distance over the RTL speed plus the vertical phases at their set rates and the loiter,
    times the power now (what a distance-and-set-speed estimate knows)."""
    height = max(alt_m, RTL_ALT_M)
    time_s = (
        (height - alt_m) / UP_MPS
        + distance_m / speed_mps
        + LOITER_S
        + max(height - LAND_LOW_M, 0.0) / DOWN_MPS
        + min(height, LAND_LOW_M) / LAND_MPS
    )
    return power_w * time_s / 3600.0


def warm_up(pilot: Pilot) -> None:
    """Take off and fly a cross: the online tracker learns the wind from the power in each
    direction, and ArduCopter's EKF starts estimating it from drag only after some flight
    (its WIND said 0 m/s for the first 200 s without this)."""
    pilot.arm_guided()
    pilot.takeoff(TAKEOFF_M)
    for vn, ve in WARM_UP_V_MPS:
        pilot.hold(WARM_UP_S, pilot.every(0.5, lambda n=vn, e=ve: pilot.send_velocity(n, e)))


@contextmanager
def warmed_up_in_wind(live: LiveDaemon) -> Iterator[Pilot]:
    """A pilot on ``live``'s SITL with :data:`WIND` set, after :func:`warm_up`; closed after.
    What the pilot receives goes to ``pilot.tlog`` beside the estimates (for a replay)."""
    pilot = live.pilot(live.estimates_path.with_name("pilot.tlog"))
    try:
        pilot.connect()
        pilot.set_param("SIM_WIND_SPD", WIND[0])
        pilot.set_param("SIM_WIND_DIR", WIND[1])
        warm_up(pilot)
        yield pilot
    finally:
        pilot.close()


def fly_rtl(
    live: LiveDaemon, pilot: Pilot, name: str, vn: float, ve: float, dur_s: float
) -> RtlPoint:
    if not pilot.state.armed:
        pilot.arm_guided()
        pilot.takeoff(TAKEOFF_M)
    velocity = pilot.every(0.5, lambda: pilot.send_velocity(vn, ve))
    pilot.hold(dur_s - 3.0, velocity)
    speed_mps = _latest(live, pilot.state.boot_s)["rth_speed_mps"]
    pilot.set_param("RTL_SPEED", round(speed_mps * 100.0))
    pilot.hold(max(0.0, 3.0 - 1.0), velocity)
    switch_s, consumed_wh = pilot.state.boot_s, pilot.state.consumed_wh
    pilot.set_mode("RTL")
    pilot.wait_for(lambda: not pilot.state.armed, 300.0, "RTL to the disarm")
    used_wh = pilot.state.consumed_wh - consumed_wh
    flown_s = pilot.state.boot_s - switch_s
    pilot.hold(2.0)
    at = _latest(live, switch_s)
    power_w = at["power_measured_w"]
    return RtlPoint(
        name=name,
        switch_s=switch_s,
        distance_m=at["home_distance_m"],
        predicted_wh=at["rth_energy_wh"],
        predicted_sigma_wh=at["rth_sigma_wh"],
        predicted_time_s=at["rth_time_s"],
        rtl_speed_mps=round(speed_mps * 100.0) / 100.0,
        power_w=power_w,
        used_wh=used_wh,
        flown_s=flown_s,
        px4_wh=px4_style_wh(at["home_distance_m"], TAKEOFF_M, speed_mps, power_w),
    )


def fly_points(
    tmp_path: Path, points: tuple[tuple[str, float, float, float], ...], wind: str = "tracked"
) -> list[RtlPoint]:
    """Every point in one SITL run (one take-off and RTL each), with the wind set first."""
    out = []
    config = tmp_path / "daemon.toml"
    config.write_text(DAEMON_CONFIG.format(wind=wind))
    with live_daemon(tmp_path, FITTED_VEHICLE, daemon_args=("--config", str(config))) as live:
        with warmed_up_in_wind(live) as pilot:
            for point in points:
                out.append(fly_rtl(live, pilot, *point))
        log = live.log_path.read_text()
    assert live.daemon.returncode == 0, log
    (tmp_path / "points.json").write_text(json.dumps([asdict(p) for p in out], indent=1))
    return out


def table(points: list[RtlPoint]) -> str:
    lines = [
        "| point | distance m | RTL speed m/s | RTH_WH predicted ± 1σ | used (∫V·I) | error | "
        "PX4-style | error | time predicted / flown s |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for p in points:
        lines.append(
            f"| {p.name} | {p.distance_m:.0f} | {p.rtl_speed_mps:.1f} | "
            f"{p.predicted_wh:.2f} ± {p.predicted_sigma_wh:.2f} | {p.used_wh:.2f} | "
            f"{p.error_pct:+.1f} % | {p.px4_wh:.2f} | {p.px4_error_pct:+.1f} % | "
            f"{p.predicted_time_s:.0f} / {p.flown_s:.0f} |"
        )
    return "\n".join(lines)


@needs_sitl
def test_live_return_energy_is_within_10_percent_of_real_rtls_in_wind(tmp_path: Path) -> None:
    """Two RTLs in a 5 m/s north wind, one from upwind, one from crosswind: the daemon's
    RTH_WH at the switch is within 10 % of the energy the autopilot used to get home and land."""
    points = fly_points(tmp_path, (POINTS[0], POINTS[2]))
    print(table(points))
    for p in points:
        assert p.distance_m > 150
        doc_figure("ArduCopter SITL: RTH_WH against the energy used home, error", p.error_pct)
        doc_figure("ArduCopter SITL: PX4-style return energy, error", p.px4_error_pct)


#: A pilot's tlog of the first two points (``replay/rtl/``, see its SOURCE.md) in which the
#: tracker, from power alone, had the wind at 3.4 m/s from 76° at the north switch (RTL_SPEED
#: 9.3 m/s, +13.6 %); the switch time s on the autopilot's clock.
RECORDED_RTL = (REPO / "replay/rtl/north_upwind.tlog", 154.577)


def test_a_recorded_rtl_flight_has_the_wind_and_speed_home_right_at_the_switch() -> None:
    """With the autopilot's WIND reports the tracker has SITL's 5 m/s from 0° at the north
    switch, and the speed home is the airspeed limit plus that tail wind."""
    path, switch_s = RECORDED_RTL
    flight = replay_log(path, load_vehicle(FITTED_VEHICLE))
    at = [e for e in flight.estimates if e.time_s <= switch_s][-1]
    assert switch_s - at.time_s < 1.0
    assert at.rth_wind_mps == pytest.approx(WIND[0], abs=0.5)
    assert abs((at.rth_wind_from_deg - WIND[1] + 180.0) % 360.0 - 180.0) < 10.0
    assert at.rth_speed_mps > 14.0


#: The live mission check: waypoints (north, east m from home) at 20 m, then RTL.
MISSION_WAYPOINTS = ((300.0, 0.0), (300.0, 300.0), (0.0, 300.0))


def fly_mission(tmp_path: Path) -> dict[str, float]:
    """After the warm-up, upload :data:`MISSION_WAYPOINTS` + RTL while hovering (the daemon
    reads the changed mission), fly it in AUTO to the disarm: the daemon's MIS_WH at the switch
    against the energy the autopilot used."""
    lat0, lon0 = HOME[0], HOME[1]
    with live_daemon(tmp_path, FITTED_VEHICLE) as live:
        with warmed_up_in_wind(live) as pilot:
            items = [(16, 0, 0.0, 0.0, lat0, lon0, HOME[2])]
            for north, east in MISSION_WAYPOINTS:
                lat = lat0 + north / M_PER_DEG
                lon = lon0 + east / (M_PER_DEG * math.cos(math.radians(lat0)))
                items.append((16, 3, 0.0, 0.0, lat, lon, TAKEOFF_M))
            items.append((20, 3, 0.0, 0.0, 0.0, 0.0, 0.0))
            pilot.upload_mission(items)
            pilot.hold(8.0)
            switch_s, consumed_wh = pilot.state.boot_s, pilot.state.consumed_wh
            pilot.set_mode("AUTO")
            pilot.wait_for(lambda: not pilot.state.armed, 600.0, "mission to the disarm")
            used_wh = pilot.state.consumed_wh - consumed_wh
        at = _latest(live, switch_s)
    return {
        "mission_wh": at["mission_energy_wh"],
        "mission_sigma_wh": at["mission_sigma_wh"],
        "used_wh": used_wh,
        "error_pct": 100.0 * (at["mission_energy_wh"] / used_wh - 1.0),
    }


@needs_sitl
def test_live_mission_energy_is_within_10_percent_of_the_flown_mission_in_wind(
    tmp_path: Path,
) -> None:
    """The daemon reads a mission uploaded while hovering in a 5 m/s wind; its MIS_WH when AUTO
    starts is within 10 % of the energy the autopilot used to fly it and land."""
    flown = fly_mission(tmp_path)
    error_pct = flown["error_pct"]
    doc_figure("ArduCopter SITL: MIS_WH against the energy the mission used, error", error_pct)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--mission"]:
        mission_dir = Path(sys.argv[2] if len(sys.argv) > 2 else "out/rth_sitl_mission")
        mission_dir.mkdir(parents=True, exist_ok=True)
        print(json.dumps(fly_mission(mission_dir), indent=1))
        sys.exit(0)
    out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/rth_sitl")
    out_dir.mkdir(parents=True, exist_ok=True)
    wind_source = sys.argv[2] if len(sys.argv) > 2 else "tracked"
    flown = fly_points(out_dir, POINTS, wind_source)
    print(table(flown))
    json.dump([asdict(p) for p in flown], sys.stdout, indent=1)
    errors = [abs(p.error_pct) for p in flown]
    print(f"\nmedian |error| {sorted(errors)[len(errors) // 2]:.1f} %, worst {max(errors):.1f} %")
