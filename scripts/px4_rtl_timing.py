"""PX4 as flown, on flights that are not RTLs: the two figures of
:mod:`estimator.estimation.rtl_profiles` that PX4's parameters do not give.

Flies PX4 SIH (``../shared/tools/px4-sitl`` or ``$PX4_SITL_DIR``; lockstep at 10×) N times
(default 8): take-off to 10 m, hover 10 s, a DO_REPOSITION 72 m away, 15 s at 10 m/s in
OFFBOARD, hold 5 s, NAV_LAND; and prints per flight

- the reposition, command to within 2 m of the target (PX4's clock), against one
  jerk-limited leg at MPC_XY_CRUISE with the profile's ramp (``PX4_FLOWN_ACCEL_MPS2``);
- the landing, NAV_LAND to ON_GROUND from the height it started at, against the profile's
  landing from that height with its touchdown (``PX4_TOUCHDOWN_S``);

then the mean of each difference. A mean near 0 s says the profile's figure holds for these
flights. Run: ``python scripts/px4_rtl_timing.py [N]`` (about 25 s a flight).
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path
from statistics import mean

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.return_home import ReturnHome, ReturnSettings
from estimator.estimation.rtl_profiles import (
    PX4_FLOWN_ACCEL_MPS2,
    PX4_TOUCHDOWN_S,
    PX4_XY_CRUISE_MPS,
    px4_rtl,
)
from estimator.physics.route_energy import Conditions, RouteVehicle
from estimator.physics.route_segments import leg_energy
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.px4 import (
    Px4Options,
    free_instance,
    gcs_port,
    px4_dir,
    running_px4,
    system_id,
)
from estimator.sitl.px4_pilot import Px4Pilot

REPO = Path(__file__).resolve().parent.parent
VEHICLE = REPO / "config/vehicles/px4_sih_quad.toml"
SPEED = 10.0
ALT_M = 10.0
#: The reposition (north, east m) and how close counts as there (the pilot's 2 m).
REPOSITION_NE_M = (60.0, 40.0)
THERE_M = 2.0


def fly_once(root: Path, workdir: Path) -> tuple[float, float, float]:
    """One flight: (reposition s, landing start height m, landing s), PX4's clock."""
    instance = free_instance()
    params = {"MIS_TAKEOFF_ALT": ALT_M}
    with running_px4(Px4Options(root, workdir, instance, SPEED, params)):
        pilot = Px4Pilot(gcs_port(instance), system_id(instance))
        try:
            pilot.connect()
            pilot.arm()
            pilot.take_off(ALT_M)
            pilot.hold(10.0)
            start_s = pilot.state.boot_s
            pilot.reposition(*REPOSITION_NE_M, ALT_M)
            reposition_s = pilot.state.boot_s - start_s
            pilot.velocity_leg(10.0, 15.0)
            pilot.hold(5.0)
            land_s, height_m = pilot.state.boot_s, pilot.state.alt_m
            pilot.land()
        finally:
            pilot.close()
    ground_s = next(
        t
        for t, s in pilot.state.landed_changes
        if t > land_s and s == mavlink.MAV_LANDED_STATE_ON_GROUND
    )
    return reposition_s, height_m, ground_s - land_s


def main(argv: list[str]) -> int:
    root = px4_dir()
    if root is None:
        print("PX4 SITL not found (../shared/tools/px4-sitl or $PX4_SITL_DIR)", file=sys.stderr)
        return 2
    flights = int(argv[0]) if argv else 8
    vehicle = load_vehicle(VEHICLE)
    settings = px4_rtl(ReturnSettings())
    returning = ReturnHome(vehicle, settings)
    still = Conditions()
    leg_m = math.hypot(*REPOSITION_NE_M) - THERE_M
    leg = leg_energy(
        RouteVehicle.from_vehicle(vehicle), still, distance_m=leg_m, track_deg=0.0,
        ground_speed_mps=PX4_XY_CRUISE_MPS, kinematics=settings.kinematics,
    )  # fmt: skip
    print(
        f"profile: ramp {PX4_FLOWN_ACCEL_MPS2} m/s², touchdown {PX4_TOUCHDOWN_S} s; "
        f"reposition {leg_m:.1f} m modelled in {leg.time_s:.1f} s"
    )
    reposition_err, landing_err = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(flights):
            reposition_s, height_m, landing_s = fly_once(root, Path(tmp) / str(i))
            model_s = sum(p.time_s for p in returning.landing(still, height_m))
            reposition_err.append(reposition_s - leg.time_s)
            landing_err.append(landing_s - model_s)
            print(
                f"flight {i + 1}/{flights}: reposition {reposition_s:.1f} s "
                f"(flown − model {reposition_err[-1]:+.1f} s); landing from {height_m:.1f} m "
                f"{landing_s:.1f} s (flown − model {landing_err[-1]:+.1f} s)",
                flush=True,
            )
    print(
        f"mean flown − model: reposition {mean(reposition_err):+.2f} s "
        f"({min(reposition_err):+.1f} to {max(reposition_err):+.1f}); landing "
        f"{mean(landing_err):+.2f} s ({min(landing_err):+.1f} to {max(landing_err):+.1f})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
