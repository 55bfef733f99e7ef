"""Which autopilot's RTL the return figures follow: ArduCopter's (the settings as given) or
PX4's (:func:`px4_rtl`), chosen by configuration or by the autopilot's HEARTBEAT.

PX4 v1.16 defaults, from that build's parameter list (``etc/extras/parameters.json`` of the
SITL folder; docs.px4.io/v1.16/en/flight_modes_mc/return.html and the parameter reference):
RTL_RETURN_ALT 60 m and RTL_DESCEND_ALT 30 m, which the multicopter start-up script
(``init.d/rc.mc_defaults``) sets to 30 m and 10 m; RTL_LAND_DELAY 0 s: a multicopter then lands
straight from its return height (navigator's ``rtl_direct.cpp``: no descent to RTL_DESCEND_ALT,
no loiter); MPC_XY_CRUISE 5 m/s, MPC_JERK_AUTO 4 m/s³ (on every axis: the auto-mode trajectory
is jerk-limited in 3-D), MPC_XY_VEL_MAX 12 m/s; MPC_Z_V_AUTO_UP 3 m/s, MPC_Z_V_AUTO_DN 1.5 m/s,
MPC_ACC_DOWN_MAX 3 m/s²; the landing at MPC_Z_V_AUTO_DN above MPC_LAND_ALT1 10 m, then linearly
down to MPC_LAND_SPEED 0.7 m/s at MPC_LAND_ALT2 5 m, to the ground (MPC_LAND_CRWL applies only
over a distance sensor, which the profile does not assume). RTL climbs at once (no pause
before it turns home).

Two figures are PX4 as flown, measured on flights that are not RTLs (PX4 SIH's NAV_LAND
flights and their DO_REPOSITION moves; ``scripts/px4_rtl_timing.py`` flies and prints them):
the horizontal ramp to the cruise speed, which PX4 flies as a quick rise to about 70 % of it
and a slow approach rather than at MPC_ACC_HOR 3 m/s² (one ramp at
:data:`PX4_FLOWN_ACCEL_MPS2`), and the touchdown, from the ground to the land detector's
ON_GROUND (:data:`PX4_TOUCHDOWN_S`: the thrust falls before the detector's three stages of
LNDMC_TRIG_TIME / 3 start). Not modelled: the return-height cone within RTL_MIN_DIST (10 m) of
home, and a PX4 whose parameters differ from these defaults (only ``return_speed_mps`` stands
for MPC_XY_CRUISE).
"""

from __future__ import annotations

from dataclasses import replace

from estimator.estimation.return_home import ReturnSettings

#: The autopilots whose RTL the return figures can follow.
RTL_AUTOPILOTS = ("ardupilot", "px4")
#: PX4 v1.16 multicopter RTL_RETURN_ALT (m), MPC_XY_CRUISE and MPC_XY_VEL_MAX (m/s).
PX4_RTL_RETURN_ALT_M = 30.0
PX4_XY_CRUISE_MPS = 5.0
PX4_XY_VEL_MAX_MPS = 12.0
#: PX4's horizontal ramp to and from its cruise speed as flown, as one ramp (m/s²), and the
#: time from touching the ground to ON_GROUND (s): measured on PX4 SIH flights that are not
#: RTLs (module docstring).
PX4_FLOWN_ACCEL_MPS2 = 1.25
PX4_TOUCHDOWN_S = 6.0


def px4_rtl(settings: ReturnSettings) -> ReturnSettings:
    """``settings`` with PX4 v1.16's multicopter RTL (RTL_TYPE 0: straight home) at its
    defaults and as flown (module docstring), the return speed kept when set; wind, airspeed
    limit, σ and smoothing as given."""
    return replace(
        settings,
        return_alt_m=PX4_RTL_RETURN_ALT_M,
        return_speed_mps=settings.return_speed_mps or PX4_XY_CRUISE_MPS,
        max_ground_speed_mps=min(settings.max_ground_speed_mps, PX4_XY_VEL_MAX_MPS),
        accel_mps2=PX4_FLOWN_ACCEL_MPS2,
        jerk_mps3=4.0,
        vertical_accel_mps2=3.0,
        vertical_jerk_mps3=4.0,
        pause_s=0.0,
        climb_rate_mps=3.0,
        descent_rate_mps=1.5,
        loiter_s=0.0,
        descend_alt_m=10.0,
        blend_alt_m=10.0,
        land_alt_low_m=5.0,
        land_speed_mps=0.7,
        crawl_alt_m=0.0,
        crawl_speed_mps=0.0,
        touchdown_s=PX4_TOUCHDOWN_S,
    )


def rtl_settings(autopilot: str, settings: ReturnSettings) -> ReturnSettings:
    """The return settings for ``autopilot``'s RTL (one of :data:`RTL_AUTOPILOTS`) from those
    configured (ArduCopter's)."""
    if autopilot not in RTL_AUTOPILOTS:
        raise ValueError(f"no RTL model for autopilot {autopilot!r}")
    return px4_rtl(settings) if autopilot == "px4" else settings
