"""Our outputs: MAVLink messages of component 191 and JSON lines of the estimates.

MAVLink (encoded with each link's own codec, system id from the config, component
``MAV_COMP_ID_ONBOARD_COMPUTER`` = 191):

- HEARTBEAT at 1 Hz: MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID, system status
  STANDBY before the first estimate, ACTIVE after, CRITICAL while stale.
- NAMED_VALUE_FLOAT (``time_boot_ms`` = the estimate's autopilot time), names in
  :data:`NAMED_VALUES` (≤ 10 characters); the endurance and range figures are NaN until
  :attr:`Estimate.endurance_valid` (FLAGS bit 2 set until then).
- BATTERY_STATUS with our own ``id`` (default 9): ``time_remaining`` = endurance (s) at the
  current power (0, MAVLink's "not provided", until :attr:`Estimate.endurance_valid`),
  ``battery_remaining`` = the pack's charge learned in flight, % of the real pack (before the
  pack filter has a current: usable energy left above the reserve, % of a full pack's),
  pack voltage in ``voltages[0]`` (mV; UINT16_MAX if > 65.5 V), measured current
  (cA, −1 unknown); charge state OK/LOW/CRITICAL at 30 % / 10 % of the usable energy.

JSON lines carry every field of the estimate; the endurance and range figures are null until
``endurance_valid``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable

from pymavlink.dialects.v20 import common as mavlink

from estimator.estimation.estimate import Estimate
from estimator.mavlink.link import MavlinkLink

UINT16_MAX = 65535
INT16_MAX = 32767

#: NAMED_VALUE_FLOAT name → (unit, getter). Names are part of the output format.
NAMED_VALUES: dict[str, tuple[str, Callable[[Estimate], float]]] = {
    "PWR_MODEL": ("W", lambda e: e.power_model_w),
    "PWR_MEAS": ("W (NaN without current sensor)", lambda e: _nan(e.power_measured_w)),
    "ENERGY_WH": ("Wh usable above the reserve", lambda e: e.energy_remaining_wh),
    "ENERGY_SIG": ("Wh, 1σ", lambda e: e.energy_remaining_sigma_wh),
    "ENDUR_S": ("s at the current steady power", lambda e: e.endurance_s),
    "ENDUR_SIG": ("s, 1σ", lambda e: e.endurance_sigma_s),
    "ENDUR_HOV": ("s hovering", lambda e: e.hover_endurance_s),
    "HOV_SIG": ("s, 1σ of ENDUR_HOV", lambda e: e.hover_endurance_sigma_s),
    "ENDUR_VME": ("s at V_me", lambda e: e.vme_endurance_s),
    "VME_SIG": ("s, 1σ of ENDUR_VME", lambda e: e.vme_endurance_sigma_s),
    "V_ME": ("m/s, maximum-endurance speed", lambda e: e.v_me_mps),
    "RANGE_VMR": ("m at V_mr (no wind)", lambda e: e.range_vmr_m),
    "RANGE_SIG": ("m, 1σ of RANGE_VMR", lambda e: e.range_vmr_sigma_m),
    "PACK_AH": ("Ah, the pack's real capacity learned in flight", lambda e: e.capacity_ah),
    "PACK_SIG": ("Ah, 1σ of PACK_AH", lambda e: e.capacity_sigma_ah),
    "PACK_SOC": ("%, the pack's charge learned in flight", lambda e: 100.0 * e.pack_soc),
    "SOC_SIG": ("%, 1σ of PACK_SOC", lambda e: 100.0 * e.pack_soc_sigma),
    "BIAS": ("measured / model power", lambda e: e.bias),
    "BIAS_SIG": ("1σ of BIAS", lambda e: e.bias_sigma),
    "FLAGS": (
        "bit 0 model_only, bit 1 stale, bit 2 endurance not yet valid, bit 3 the pack voltage "
        "does not follow the load",
        lambda e: float(
            e.model_only
            + 2 * e.stale
            + 4 * (not e.endurance_valid)
            + 8 * (not e.voltage_follows_load)
        ),
    ),
    "HOME_M": ("m to home over ground", lambda e: e.home_distance_m),
    "RTH_WH": ("Wh to return home and land", lambda e: e.rth_energy_wh),
    "RTH_SIG": ("Wh, 1σ of RTH_WH", lambda e: e.rth_sigma_wh),
    "RTH_S": ("s to return home and land", lambda e: e.rth_time_s),
    "RTH_VG": ("m/s, ground speed home of least energy", lambda e: e.rth_speed_mps),
    "MARGIN_WH": ("Wh above the reserve after the return", lambda e: e.margin_wh),
    "MARGIN_SIG": ("Wh, 1σ of MARGIN_WH", lambda e: e.margin_sigma_wh),
    "PNR_S": ("s to the point of no return", lambda e: e.pnr_s),
    "MIS_WH": ("Wh for the rest of the mission and the return", lambda e: e.mission_energy_wh),
    "MIS_SIG": ("Wh, 1σ of MIS_WH", lambda e: e.mission_sigma_wh),
    "MIS_OK": (
        "1 mission + return feasible with the reserve, 0 not, NaN unknown",
        lambda e: _nan(None if e.mission_feasible is None else float(e.mission_feasible)),
    ),
    "RTH_FLAGS": (
        "bit 0 no home, 1 no position, 2 no mission, 3 not flying",
        lambda e: float(e.rth_flags),
    ),
}
#: Estimate fields not published before :attr:`Estimate.endurance_valid`.
ENDURANCE_FIELDS = frozenset(
    {
        "endurance_s",
        "endurance_sigma_s",
        "hover_endurance_s",
        "hover_endurance_sigma_s",
        "vme_endurance_s",
        "vme_endurance_sigma_s",
        "range_vmr_m",
        "range_vmr_sigma_m",
    }
)
#: NAMED_VALUES that carry those fields.
_ENDURANCE_NAMES = frozenset(
    {"ENDUR_S", "ENDUR_SIG", "ENDUR_HOV", "HOV_SIG", "ENDUR_VME", "VME_SIG", "RANGE_VMR"}
    | {"RANGE_SIG"}
)


def _nan(value: float | None) -> float:
    return math.nan if value is None else value


def heartbeat(link: MavlinkLink, estimate: Estimate | None) -> mavlink.MAVLink_message:
    if estimate is None:
        status = mavlink.MAV_STATE_STANDBY
    elif estimate.stale:
        status = mavlink.MAV_STATE_CRITICAL
    else:
        status = mavlink.MAV_STATE_ACTIVE
    return link.mav.heartbeat_encode(
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, status
    )


def named_values(link: MavlinkLink, estimate: Estimate) -> list[mavlink.MAVLink_message]:
    time_ms = _time_ms(estimate)
    hidden = set() if estimate.endurance_valid else _ENDURANCE_NAMES
    return [
        link.mav.named_value_float_encode(
            time_ms, name.encode(), math.nan if name in hidden else float(getter(estimate))
        )
        for name, (_, getter) in NAMED_VALUES.items()
    ]


def statustext(link: MavlinkLink, severity: int, text: str) -> mavlink.MAVLink_message:
    """A STATUSTEXT (MAV_SEVERITY, text of at most 50 characters)."""
    return link.mav.statustext_encode(severity, text.encode()[:50])


def remaining_percent(estimate: Estimate, full_usable_wh: float) -> int:
    """Usable energy left as % of a full pack's usable energy (0..100)."""
    if full_usable_wh <= 0:
        return -1
    return round(min(max(estimate.energy_remaining_wh / full_usable_wh, 0.0), 1.0) * 100)


def battery_status(
    link: MavlinkLink, estimate: Estimate, battery_id: int, full_usable_wh: float
) -> mavlink.MAVLink_message:
    voltages = [UINT16_MAX] * 10
    if math.isfinite(estimate.voltage_v) and 0 < estimate.voltage_v * 1000 < UINT16_MAX:
        voltages[0] = round(estimate.voltage_v * 1000)
    current_ca = -1
    if estimate.power_measured_w is not None and estimate.voltage_v > 0:
        current_ca = round(estimate.power_measured_w / estimate.voltage_v * 100)
    percent = remaining_percent(estimate, full_usable_wh)
    state_percent = percent
    if math.isfinite(estimate.pack_soc):
        percent = round(min(max(estimate.pack_soc, 0.0), 1.0) * 100)
    if state_percent < 0 or state_percent > 30:
        state = mavlink.MAV_BATTERY_CHARGE_STATE_OK
    elif state_percent > 10:
        state = mavlink.MAV_BATTERY_CHARGE_STATE_LOW
    else:
        state = mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL
    endurance = estimate.endurance_s
    known = estimate.endurance_valid and math.isfinite(endurance) and endurance > 0
    time_remaining = int(min(endurance, 2**31 - 1)) if known else 0
    return link.mav.battery_status_encode(
        battery_id,
        mavlink.MAV_BATTERY_FUNCTION_ALL,
        mavlink.MAV_BATTERY_TYPE_LIPO,
        INT16_MAX,
        voltages,
        max(min(current_ca, INT16_MAX), -1),
        -1,
        -1,
        percent,
        time_remaining,
        state,
    )


def json_line(estimate: Estimate) -> str:
    """One estimate as a JSON object on one line (NaN/inf, and the endurance figures before
    ``endurance_valid``, become null)."""
    hidden = frozenset() if estimate.endurance_valid else ENDURANCE_FIELDS
    doc = {
        k: (None if k in hidden or (isinstance(v, float) and not math.isfinite(v)) else v)
        for k, v in estimate.as_dict().items()
    }
    return json.dumps(doc, separators=(",", ":"))


def _time_ms(estimate: Estimate) -> int:
    return round(estimate.time_s * 1000) & 0xFFFFFFFF
