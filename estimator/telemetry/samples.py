"""Typed telemetry samples: what every source (socket, log, CSV, simulator) is decoded into.

Times are seconds on the autopilot's clock (``time_boot_ms`` / 1000, or a log's own time
base), never the wall clock of the process that reads them. Velocities are NED, m/s.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, fields
from itertools import repeat
from typing import Any, TypeVar


@dataclass(frozen=True, slots=True)
class VelocitySample:
    """Vehicle velocity over ground in the local NED frame (m/s), altitude above home (m)."""

    time_s: float
    vn_mps: float
    ve_mps: float
    vd_mps: float
    alt_m: float | None = None


@dataclass(frozen=True, slots=True)
class BatterySample:
    """Battery pack reading. ``None`` marks a value the autopilot reported as unknown."""

    time_s: float
    voltage_v: float
    current_a: float | None = None
    consumed_mah: float | None = None
    remaining_pct: float | None = None

    @property
    def power_w(self) -> float | None:
        """Electrical power drawn from the pack (W), or None without a current sensor."""
        return None if self.current_a is None else self.voltage_v * self.current_a


@dataclass(frozen=True, slots=True)
class ArmedSample:
    """Armed state from the autopilot's HEARTBEAT."""

    time_s: float
    armed: bool


@dataclass(frozen=True, slots=True)
class LandedSample:
    """The autopilot's own landed detector (EXTENDED_SYS_STATE ``landed_state``, PX4):
    ``on_ground`` for MAV_LANDED_STATE_ON_GROUND, False when taking off, in the air or
    landing."""

    time_s: float
    on_ground: bool


@dataclass(frozen=True, slots=True)
class RebootSample:
    """The autopilot's clock was re-referenced: it went backwards (a reboot), or jumped far
    ahead (confirmed by several frames). Carries the new clock time; what came before is
    not continued on the new clock."""

    time_s: float


@dataclass(frozen=True, slots=True)
class WindSample:
    """The autopilot's own wind estimate: air-mass velocity over ground, NED, m/s (the
    direction the wind blows towards; ArduPilot WIND, PX4 WIND_COV)."""

    time_s: float
    wind_n_mps: float
    wind_e_mps: float


@dataclass(frozen=True, slots=True)
class PositionSample:
    """Where the vehicle is (GLOBAL_POSITION_INT): WGS84 latitude and longitude (deg), height
    over home (m, None = unknown)."""

    time_s: float
    lat_deg: float
    lon_deg: float
    alt_m: float | None = None


@dataclass(frozen=True, slots=True)
class HomeSample:
    """The autopilot's home (HOME_POSITION): WGS84 latitude and longitude (deg), altitude
    above mean sea level (m)."""

    time_s: float
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float


@dataclass(frozen=True, slots=True)
class MissionCurrentSample:
    """The mission item the autopilot is flying to (MISSION_CURRENT.seq) and the mission's
    item count (``total``; None when the autopilot does not say)."""

    time_s: float
    seq: int
    total: int | None = None


@dataclass(frozen=True, slots=True)
class GripperSample:
    """The autopilot's gripper finished an action (ArduPilot STATUSTEXT "Gripper load
    released" / "Gripper load grabbed"): a payload let go of (``released``) or held."""

    time_s: float
    released: bool


Sample = (
    VelocitySample
    | BatterySample
    | ArmedSample
    | LandedSample
    | RebootSample
    | WindSample
    | PositionSample
    | HomeSample
    | MissionCurrentSample
    | GripperSample
)


SampleT = TypeVar("SampleT", bound=Sample)


def of_columns(sample_type: type[SampleT], *columns: Sequence[Any]) -> list[SampleT]:
    """Samples of ``sample_type``, one per row of ``columns`` (one column per field of the
    type, in its order, all of one length): each equal to ``sample_type(*row)``, built in C
    loops — every instance made empty, then each field set through its slot as the
    dataclass's own ``__init__`` sets it (``object.__setattr__``) — at about half the
    constructor's cost (0.25 against 0.6 µs for a velocity sample). For a reader that
    decodes a log column-wise."""
    names = [f.name for f in fields(sample_type)]
    count = len(columns[0]) if columns else 0
    if len(columns) != len(names) or any(len(c) != count for c in columns):
        raise ValueError(f"{sample_type.__name__} needs {len(names)} columns of one length")
    out: list[SampleT] = list(map(object.__new__, repeat(sample_type, count)))
    for name, column in zip(names, columns, strict=True):
        deque(map(getattr(sample_type, name).__set__, out, column), maxlen=0)
    return out
