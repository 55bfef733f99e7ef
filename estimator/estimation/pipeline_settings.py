"""The pipeline's settings (:class:`PipelineSettings`): its periods, the staleness of the
battery telemetry, and the settings of each stage it runs (kinematics, fusion, pack, return
home). Times on the sample clock (s)."""

from __future__ import annotations

from dataclasses import dataclass, field

from estimator.estimation.fusion import FusionSettings
from estimator.estimation.pack_state import PackSettings
from estimator.estimation.return_home import ReturnSettings
from estimator.physics.kinematics import KinematicsSettings


@dataclass(frozen=True, slots=True)
class PipelineSettings:
    """battery_stale_s: estimates are ``stale`` when the newest battery sample is older than
    this on the sample clock. add_climb_effect: add a default :class:`Climb` effect when the
    vehicle file has none (climbing costs m·g·v_c/η). track_effects: follow wind and mass
    online from measured power (:class:`~estimator.estimation.online_effects.OnlineEffects`),
    starting from the vehicle file's values; off keeps those values for the whole flight.
    estimate_period_s: one estimate per this much sample clock (s); see
    :mod:`estimator.estimation.pipeline`. track_period_s: the online tracker takes one reading
    per this much sample clock (s): wind and payload change over tens of seconds, and readings
    close together share their errors (gusts, ESC ripple). endurance_valid_after_s: endurance
    figures are published once flying readings (:mod:`estimator.estimation.airborne`) have
    been fused for this long (s, sample clock): the bias then rests on them, not on its prior
    (a payload carried from take-off puts the measured power 30–40 % above the model's).
    return_home: the return and mission figures (:mod:`estimator.estimation.return_home`)."""

    kinematics: KinematicsSettings = field(default_factory=KinematicsSettings)
    fusion: FusionSettings = field(default_factory=FusionSettings)
    pack: PackSettings = field(default_factory=PackSettings)
    battery_stale_s: float = 5.0
    add_climb_effect: bool = True
    track_effects: bool = True
    estimate_period_s: float = 1.0
    track_period_s: float = 2.0
    endurance_valid_after_s: float = 2.0
    return_home: ReturnSettings = field(default_factory=ReturnSettings)
