"""Effects to and from a vehicle file's ``[effects.NAME]`` tables, checked against each effect's
parameters and ranges (:mod:`estimator.physics.effects`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import fields
from typing import Any

from estimator.errors import UserError
from estimator.physics.effects import EFFECT_TYPES, Effect, Heave


def effect_from_params(name: str, params: Mapping[str, Any], where: str = "effects") -> Effect:
    """Build an effect from its name and parameter table; UserError on unknown names/values."""
    cls = EFFECT_TYPES.get(name)
    if cls is None:
        known = ", ".join(EFFECT_TYPES)
        raise UserError(f"{where}: unknown effect '{name}' (known: {known})")
    allowed = {f.name for f in fields(cls)}
    unknown = set(params) - allowed
    if unknown:
        raise UserError(
            f"{where}.{name}: unknown parameter(s) {', '.join(sorted(unknown))} "
            f"(allowed: {', '.join(sorted(allowed))})"
        )
    values: dict[str, Any] = {}
    for key, value in params.items():
        if value is None and key in _TIME_KEYS:
            values[key] = None
            continue
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not math.isfinite(value):
            raise UserError(f"{where}.{name}.{key} must be a finite number, got {value!r}")
        values[key] = float(value)
    effect = cls(**values)
    _validate(effect, f"{where}.{name}")
    return effect


_TIME_KEYS = ("at_s", "until_s")


def _validate(effect: Effect, where: str) -> None:
    checks = {
        "speed_mps": lambda v: v >= 0,
        "rho_kgpm3": lambda v: v > 0,
        "efficiency": lambda v: 0 < v <= 1,
        # a gain beyond the fitters' bound is no rotor's: it would swamp the prediction
        "gain": lambda v: Heave.bounds["gain"][0] <= v <= Heave.bounds["gain"][1],
        "recovery": lambda v: 0 <= v <= 1,
        "resistance_ohm": lambda v: v >= 0,
        "reference_v": lambda v: v > 0,
    }
    for key, value in effect.params.items():
        check = checks.get(key)
        if check is not None and not check(value):
            raise UserError(f"{where}.{key} is out of range: {value!r}")
    at_s, until_s = effect.params.get("at_s"), effect.params.get("until_s")
    if at_s is not None and until_s is not None and until_s <= at_s:
        raise UserError(f"{where}.until_s ({until_s!r}) must be after at_s ({at_s!r})")


def effects_from_tables(tables: Mapping[str, Mapping[str, Any]]) -> list[Effect]:
    """Effects from a vehicle file's ``[effects.NAME]`` tables (``Vehicle.effects``), in order."""
    return [effect_from_params(name, params) for name, params in tables.items()]


def effects_to_tables(effects: Sequence[Effect]) -> dict[str, dict[str, Any]]:
    """The ``Vehicle.effects`` dict for ``effects`` (one table per name; None values kept)."""
    tables: dict[str, dict[str, Any]] = {}
    for effect in effects:
        if effect.name in tables:
            raise ValueError(f"effect '{effect.name}' given twice")
        tables[effect.name] = effect.params
    return tables
