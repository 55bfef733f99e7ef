"""A pipeline's state as a restarted process continues it: what the pipeline writes
(:func:`take_snapshot`, JSON-ready) and what it takes back (:func:`parse_snapshot`, bounded:
a state file may be stale, damaged or forged).

Units: powers W, squared power errors W², times s on the autopilot's clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from estimator.errors import UserError
from estimator.estimation.flight_power import FlightPower
from estimator.estimation.fusion import EnergyFilter
from estimator.estimation.pack_bank import PackBank
from estimator.estimation.pack_learning import PackLearning
from estimator.physics.effect_tables import effects_from_tables, effects_to_tables
from estimator.physics.effects import Effect
from estimator.telemetry.plausibility import MAX_POWER_PER_HOVER


@dataclass(frozen=True, slots=True)
class Resume:
    """A parsed snapshot waiting for the first battery sample: the energy filter, the effects
    in use and their scores (W², tracked and the vehicle file's), whether the endurance was
    valid, the pack's filter (None: none was learnt) and whether it was refuted (the energy
    then counted against the label, and no pack learnt again)."""

    energy: EnergyFilter
    effects: tuple[Effect, ...]
    tracked_sq_w2: float
    file_sq_w2: float
    endurance_valid: bool
    pack: PackBank | None
    pack_refuted: bool


def take_snapshot(
    energy: EnergyFilter, power: FlightPower, endurance_valid: bool, packs: PackLearning
) -> dict[str, Any] | None:
    """The energy and resistance filters with the energy anchor, the effects in use
    (tracked wind and mass), their scores, whether endurance is valid, the pack's filter and
    whether it was refuted; None before the energy state starts."""
    if not energy.initialized:
        return None
    return {
        "energy": energy.snapshot(),
        "effects": effects_to_tables(power.effects),
        "tracked_sq_w2": power.tracked_sq_w2,
        "file_sq_w2": power.file_sq_w2,
        "endurance_valid": endurance_valid,
        "pack": None if packs.state is None else packs.state.snapshot(),
        "pack_refuted": packs.refuted,
    }


def parse_snapshot(
    snapshot: Mapping[str, Any],
    new_energy: Callable[[], EnergyFilter],
    new_pack: Callable[[], PackBank],
    hover_power_w: Callable[[tuple[Effect, ...]], float],
    file_hover_power_w: float,
) -> Resume:
    """``snapshot`` (:func:`take_snapshot`) restored into filters made by ``new_energy`` and
    ``new_pack``. ValueError for one that does not parse or holds a value out of its range
    (the energy and pack filters' ranges; the effects must keep the hover power,
    ``hover_power_w(effects)`` in W, finite and within
    :data:`~estimator.telemetry.plausibility.MAX_POWER_PER_HOVER` times the vehicle file's
    ``file_hover_power_w``; the power scores finite, ≥ 0; a refuted pack without a pack
    filter; a snapshot without ``pack_refuted``, from before it was kept, has none)."""
    try:
        energy = new_energy()
        energy.restore(snapshot["energy"])
        pack = None
        if snapshot.get("pack") is not None:
            pack = new_pack()
            pack.restore(snapshot["pack"])
        effects = tuple(effects_from_tables(snapshot["effects"]))
        hover_w = hover_power_w(effects)
        if not hover_w <= MAX_POWER_PER_HOVER * file_hover_power_w:
            raise ValueError(f"the effects make hovering take {hover_w:.0f} W")
        scores = (float(snapshot["tracked_sq_w2"]), float(snapshot["file_sq_w2"]))
        if not all(math.isfinite(v) and v >= 0 for v in scores):
            raise ValueError(f"power scores {scores} are not finite and ≥ 0")
        if not isinstance(valid := snapshot["endurance_valid"], bool):
            raise ValueError(f"endurance_valid is {valid!r}")
        if not isinstance(refuted := snapshot.get("pack_refuted", False), bool):
            raise ValueError(f"pack_refuted is {refuted!r}")
        if refuted and pack is not None:
            raise ValueError("a refuted pack with a pack filter")
        return Resume(energy, effects, *scores, valid, pack, refuted)
    except (
        KeyError,
        TypeError,
        AttributeError,
        ValueError,
        OverflowError,
        UserError,
        np.linalg.LinAlgError,
    ) as exc:
        raise ValueError(f"not a pipeline snapshot ({exc})") from None
