"""Daemon configuration: a TOML file (``config/default.toml`` documents every key) overlaid by
command-line flags, validated into a frozen :class:`ServiceConfig`.

Every problem is one sentence in a :class:`~estimator.errors.UserError` naming the key.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from estimator.errors import UserError
from estimator.file_checks import number_in_range
from estimator.mavlink.link_address import parse_url
from estimator.physics.route_energy import DEFAULT_MAX_GROUND_SPEED_MPS, DEFAULT_RTL_ALT_M
from estimator.toml_files import read_toml

if TYPE_CHECKING:
    from estimator.estimation.pipeline_settings import PipelineSettings

LOG_LEVELS = ("debug", "info", "warning", "error")


@dataclass(frozen=True)
class ServiceConfig:
    """What ``uav-energy run`` does. Rates in Hz, times in s (wall clock of the daemon).

    connect: autopilot link.  publish: links towards ground stations / other programs.
    target_system/target_component: the autopilot (0: the first autopilot HEARTBEAT).
    system_id: our MAVLink system id (component is always 191, onboard computer).
    request_streams: ask the autopilot for telemetry (REQUEST_DATA_STREAM and
    SET_MESSAGE_INTERVAL) at velocity_rate_hz and battery_rate_hz.
    publish_rate_hz: NAMED_VALUE_FLOAT and BATTERY_STATUS rate (0: with every estimate).
    battery_id: BATTERY_STATUS id of our estimate (distinct from the autopilot's 0).
    values_to_autopilot: also send NAMED_VALUE_FLOAT on the connect link.
    battery_status_to_autopilot: also send BATTERY_STATUS there (PX4 then treats it as a
    battery of its own: only if you mean it).
    heartbeat_to_autopilot: send our 1 Hz HEARTBEAT on the connect link too.
    signing_key_file: MAVLink 2 signing key (:func:`~estimator.mavlink.signing.load_key`;
    "" = no signing); require_signing: reject unsigned frames.
    state_file: where the estimator's state is kept across restarts ("" = nowhere);
    state_max_age_s: an older state file is ignored; state_period_s: seconds between writes.
    pack_id, pack_dir: the pack flown and the packs' memory (an id needs a dir; a dir without
    an id: the pack's serial number from the autopilot names it): the flight starts from what
    the pack was learnt to hold and stores what it learns
    (:mod:`estimator.estimation.pack_identity`).
    json: "" (off), "-" (stdout) or "udp:HOST:PORT"; json_rate_hz 0: every estimate.
    stale_after_s: no telemetry for this long marks estimates stale.
    vehicle: vehicle TOML file ("" = the built-in default vehicle). Paths in a config file
    (vehicle, signing key, state file) are relative to that file's directory.
    track_effects: follow wind and mass online (:mod:`estimator.estimation.online_effects`) instead
    of
    keeping the vehicle file's values for the whole flight.
    log_level: debug, info, warning or error.
    return_alt_m: height over home (m) the return flies at (ArduPilot's RTL_ALT; 15 m; PX4's
    RTL takes its own default).
    return_speed_mps: the autopilot's return ground speed (m/s; 0: the wind-optimal one, which
    the ground station may then set as RTL_SPEED). max_airspeed_mps: the vehicle's fastest
    airspeed (lean-angle limit; 0: the vehicle file's), max_ground_speed_mps: the autopilot's
    fastest return speed.
    return_wind: "tracked" (the online tracker's wind) or "autopilot" (its WIND / WIND_COV).
    return_autopilot: whose RTL the return figures follow: "ardupilot" (ArduCopter's, with the
    settings above), "px4" (PX4 v1.16's at its defaults,
    :func:`~estimator.estimation.rtl_profiles.px4_rtl`; return_speed_mps, when set, stands for
    MPC_XY_CRUISE) or "auto" (the autopilot's HEARTBEAT says which).
    warning_margin_pct / critical_margin_pct: STATUSTEXT WARNING / CRITICAL to the ground
    stations when the return margin (energy above the reserve after the return) falls below
    this share (%) of a full pack's usable energy; hysteresis_pct: it must rise this much above
    the threshold before the next crossing warns again.  statustext_to_autopilot: also send
    those STATUSTEXTs on the connect link.  download_mission: read the autopilot's mission
    (MAVLink mission protocol, read-only) for the mission energy.
    fusion: noise figures overriding :class:`~estimator.estimation.fusion.FusionSettings` defaults
    (the ``[fusion]`` table), as (name, value) pairs.
    """

    connect: str = "udpin:0.0.0.0:14550"
    publish: tuple[str, ...] = ()
    target_system: int = 0
    target_component: int = 0
    system_id: int = 1
    request_streams: bool = True
    velocity_rate_hz: float = 10.0
    battery_rate_hz: float = 5.0
    publish_rate_hz: float = 1.0
    battery_id: int = 9
    values_to_autopilot: bool = False
    battery_status_to_autopilot: bool = False
    heartbeat_to_autopilot: bool = False
    signing_key_file: str = ""
    require_signing: bool = False
    state_file: str = ""
    state_max_age_s: float = 120.0
    state_period_s: float = 2.0
    pack_id: str = ""
    pack_dir: str = ""
    json: str = ""
    json_rate_hz: float = 0.0
    stale_after_s: float = 3.0
    vehicle: str = ""
    track_effects: bool = True
    log_level: str = "info"
    return_alt_m: float = DEFAULT_RTL_ALT_M
    return_speed_mps: float = 0.0
    max_airspeed_mps: float = 0.0
    max_ground_speed_mps: float = DEFAULT_MAX_GROUND_SPEED_MPS
    return_wind: str = "tracked"
    return_autopilot: str = "auto"
    warning_margin_pct: float = 15.0
    critical_margin_pct: float = 5.0
    hysteresis_pct: float = 2.0
    statustext_to_autopilot: bool = False
    download_mission: bool = True
    fusion: tuple[tuple[str, float], ...] = ()

    def pipeline_settings(self) -> PipelineSettings:
        """The pipeline's settings this configuration asks for."""
        from estimator.estimation.fusion import FusionSettings
        from estimator.estimation.pipeline_settings import PipelineSettings
        from estimator.estimation.return_home import ReturnSettings

        return PipelineSettings(
            fusion=FusionSettings(**dict(self.fusion)),
            track_effects=self.track_effects,
            return_home=ReturnSettings(
                return_alt_m=self.return_alt_m,
                return_speed_mps=self.return_speed_mps,
                max_airspeed_mps=self.max_airspeed_mps or None,
                max_ground_speed_mps=self.max_ground_speed_mps,
                wind_source=self.return_wind,
            ),
        )

    @property
    def log_level_number(self) -> int:
        return int(getattr(logging, self.log_level.upper()))


#: TOML section and key → ServiceConfig field.
_KEYS = {
    ("link", "connect"): "connect",
    ("link", "target_system"): "target_system",
    ("link", "target_component"): "target_component",
    ("link", "system_id"): "system_id",
    ("link", "request_streams"): "request_streams",
    ("link", "velocity_rate_hz"): "velocity_rate_hz",
    ("link", "battery_rate_hz"): "battery_rate_hz",
    ("link", "stale_after_s"): "stale_after_s",
    ("link", "heartbeat_to_autopilot"): "heartbeat_to_autopilot",
    ("signing", "key_file"): "signing_key_file",
    ("signing", "require_signing"): "require_signing",
    ("state", "file"): "state_file",
    ("state", "max_age_s"): "state_max_age_s",
    ("state", "period_s"): "state_period_s",
    ("pack", "id"): "pack_id",
    ("pack", "dir"): "pack_dir",
    ("publish", "urls"): "publish",
    ("publish", "rate_hz"): "publish_rate_hz",
    ("publish", "battery_id"): "battery_id",
    ("publish", "values_to_autopilot"): "values_to_autopilot",
    ("publish", "battery_status_to_autopilot"): "battery_status_to_autopilot",
    ("publish", "json"): "json",
    ("publish", "json_rate_hz"): "json_rate_hz",
    ("vehicle", "file"): "vehicle",
    ("vehicle", "track_effects"): "track_effects",
    ("log", "level"): "log_level",
    ("return", "alt_m"): "return_alt_m",
    ("return", "speed_mps"): "return_speed_mps",
    ("return", "max_airspeed_mps"): "max_airspeed_mps",
    ("return", "max_ground_speed_mps"): "max_ground_speed_mps",
    ("return", "wind"): "return_wind",
    ("return", "autopilot"): "return_autopilot",
    ("return", "warning_margin_pct"): "warning_margin_pct",
    ("return", "critical_margin_pct"): "critical_margin_pct",
    ("return", "hysteresis_pct"): "hysteresis_pct",
    ("return", "statustext_to_autopilot"): "statustext_to_autopilot",
    ("return", "download_mission"): "download_mission",
}
#: Allowed range of each ``[fusion]`` noise figure (FusionSettings units: fractions, V, Ω,
#: A, W, 1/√s): from 0 to a value no real sensor or pack comes near.
FUSION_RANGES = {
    "bias_prior_sigma": (0.0, 1.0),
    "bias_walk_per_sqrt_s": (0.0, 1.0),
    "model_power_noise_fraction": (0.0, 1.0),
    "power_noise_fraction": (0.0, 1.0),
    "power_noise_floor_w": (0.0, 1000.0),
    "rest_voltage_sigma_v_per_cell": (0.0, 1.0),
    "capacity_sigma_fraction": (0.0, 1.0),
    "charge_sigma_fraction": (0.0, 1.0),
    "internal_resistance_ohm": (0.0, 2.0),
    "voltage_noise_v": (0.0, 10.0),
    "resistance_prior_ohm_per_cell": (0.0, 1.0),
    "resistance_walk_ohm_per_sqrt_s": (0.0, 1.0),
    "resistance_min_current_a": (0.0, 1000.0),
    "ocv_curve_sigma_v_per_cell": (0.0, 1.0),
    "current_gain_sigma_fraction": (0.0, 1.0),
    "state_change_step": (0.0, 1.0),
    "state_change_bias_sigma": (0.0, 10.0),
}
#: Longest text value (a path, a connection string; Linux's PATH_MAX).
MAX_TEXT_CHARS = 4096
#: Fields holding file paths: relative ones in a config file are relative to its directory.
_PATH_FIELDS = frozenset({"vehicle", "signing_key_file", "state_file", "pack_dir"})


def load_config_file(path: str | Path) -> dict[str, Any]:
    """Read a config TOML into ServiceConfig field values (unknown keys are errors); relative
    paths become paths relative to the file's directory."""
    doc = read_toml(path, "config")
    base = Path(path).resolve().parent
    values: dict[str, Any] = {}
    for section, table in doc.items():
        if not isinstance(table, dict):
            raise UserError(f"config file {path}: '{section}' must be a [section]")
        if section == "fusion":
            values["fusion"] = table
            continue
        for key, value in table.items():
            name = _KEYS.get((section, key))
            if name is None:
                raise UserError(f"config file {path}: unknown key [{section}] {key}")
            if name in _PATH_FIELDS and isinstance(value, str) and value:
                value = str(base / Path(value).expanduser())
            values[name] = value
    return values


def build_config(file_values: dict[str, Any], overrides: dict[str, Any]) -> ServiceConfig:
    """Defaults ← file values ← command-line overrides (None = not given), validated."""
    merged = {**file_values, **{k: v for k, v in overrides.items() if v is not None}}
    types = {f.name: str(f.type) for f in fields(ServiceConfig)}
    checked = {name: _coerce(name, value, types[name]) for name, value in merged.items()}
    config = replace(ServiceConfig(), **checked)
    validate(config)
    return config


def _coerce(name: str, value: Any, type_name: str) -> Any:
    if name == "fusion":
        return _fusion_pairs(value)
    if type_name == "tuple[str, ...]":
        items = [value] if isinstance(value, str) else value
        if not isinstance(items, list | tuple) or not all(isinstance(x, str) for x in items):
            raise UserError(f"config '{name}' must be a list of connection strings")
        for item in items:
            _check_length(name, item)
        return tuple(items)
    if type_name == "bool":
        if not isinstance(value, bool):
            raise UserError(f"config '{name}' must be true or false, got {value!r}")
        return value
    if type_name == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise UserError(f"config '{name}' must be an integer, got {value!r}")
        return value
    if type_name == "float":
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise UserError(f"config '{name}' must be a finite number, got {value!r}")
        return float(value)
    if not isinstance(value, str):
        raise UserError(f"config '{name}' must be a string, got {value!r}")
    _check_length(name, value)
    return value


def _check_length(name: str, text: str) -> None:
    if len(text) > MAX_TEXT_CHARS:
        raise UserError(
            f"config '{name}' must be at most {MAX_TEXT_CHARS} characters, got {len(text)}"
        )


def _fusion_pairs(table: Any) -> tuple[tuple[str, float], ...]:
    """Validate a ``[fusion]`` table: known FusionSettings names, numbers within
    :data:`FUSION_RANGES`."""
    from estimator.estimation.fusion import FusionSettings

    if isinstance(table, tuple):
        table = dict(table)
    if not isinstance(table, dict):
        raise UserError("config [fusion] must be a table of noise figures")
    known = {f.name for f in fields(FusionSettings)}
    pairs = []
    for key in table:
        if key not in known:
            raise UserError(
                f"config [fusion] has no setting '{key}' (known: {', '.join(sorted(known))})"
            )
        pairs.append((key, number_in_range(table, key, "config [fusion]", FUSION_RANGES[key])))
    return tuple(sorted(pairs))


def validate(config: ServiceConfig) -> None:
    """Check ranges and connection strings; one UserError per first problem found."""
    from estimator.estimation.pack_memory import check_pack_id
    from estimator.estimation.rtl_profiles import RTL_AUTOPILOTS

    if config.pack_id and not config.pack_dir:
        raise UserError("config [pack] id (--pack) needs [pack] dir")
    if config.pack_id:
        check_pack_id(config.pack_id)
    parse_url(config.connect)
    for url in config.publish:
        parse_url(url, listen=False)
    for name, lo, hi in (
        ("target_system", 0, 255),
        ("target_component", 0, 255),
        ("system_id", 1, 255),
        ("battery_id", 0, 255),
    ):
        value = getattr(config, name)
        if not lo <= value <= hi:
            raise UserError(f"config '{name}' must be in [{lo}, {hi}], got {value}")
    for name in ("velocity_rate_hz", "battery_rate_hz"):
        if not 0 < getattr(config, name) <= 100:
            raise UserError(f"config '{name}' must be in (0, 100] Hz")
    for name in ("publish_rate_hz", "json_rate_hz"):
        if not 0 <= getattr(config, name) <= 100:
            raise UserError(f"config '{name}' must be in [0, 100] Hz (0: every estimate)")
    for name in ("stale_after_s", "state_max_age_s", "state_period_s"):
        if getattr(config, name) <= 0:
            raise UserError(f"config '{name}' must be > 0")
    if config.require_signing and not config.signing_key_file:
        raise UserError("config 'require_signing' needs a signing key_file")
    if not 0 <= config.return_alt_m <= 1000:
        raise UserError("config 'return_alt_m' must be in [0, 1000] m")
    if not 0 <= config.return_speed_mps <= 50:
        raise UserError("config 'return_speed_mps' must be in [0, 50] m/s (0: wind-optimal)")
    if not (config.max_airspeed_mps == 0 or 1 <= config.max_airspeed_mps <= 50):
        raise UserError("config 'max_airspeed_mps' must be 0 (the vehicle file's) or in [1, 50]")
    if not 1 <= config.max_ground_speed_mps <= 50:
        raise UserError("config 'max_ground_speed_mps' must be in [1, 50] m/s")
    if config.return_wind not in ("tracked", "autopilot"):
        raise UserError("config 'return_wind' must be 'tracked' or 'autopilot'")
    if config.return_autopilot not in ("auto", *RTL_AUTOPILOTS):
        raise UserError("config 'return_autopilot' must be 'auto', 'ardupilot' or 'px4'")
    if not config.critical_margin_pct <= config.warning_margin_pct <= 100:
        raise UserError(
            "config 'critical_margin_pct' ≤ 'warning_margin_pct' ≤ 100 % of the usable energy"
        )
    if not 0 <= config.hysteresis_pct <= 50:
        raise UserError("config 'hysteresis_pct' must be in [0, 50] %")
    if config.json not in ("", "-") and not config.json.startswith("udp:"):
        raise UserError(f"config 'json' must be '', '-' or udp:HOST:PORT, got {config.json!r}")
    if config.json.startswith("udp:"):
        parse_url("udpout:" + config.json[4:])
    if config.log_level not in LOG_LEVELS:
        raise UserError(f"config 'log_level' must be one of {', '.join(LOG_LEVELS)}")
