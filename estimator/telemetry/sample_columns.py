"""Samples column-wise: what the value and time checks read, one row per sample.

:class:`SampleColumns` holds each sample's type (a code of :data:`KINDS`), its stamp (s) and
the fields the value checks read, as numpy columns; it is what
:func:`estimator.telemetry.guard_runs.clean_run` judges. It is made from sample objects
(:meth:`SampleColumns.of_samples`: a reader that gives objects one by one), or straight from
the arrays of a reader that decodes a whole log column-wise (:meth:`SampleColumns.of_type`
per message type, then :meth:`~SampleColumns.joined` and :meth:`~SampleColumns.rows` into the
samples' time order: the PX4 ULog reader), without reading any object's fields.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import repeat
from operator import attrgetter, is_not

import numpy as np

from estimator.telemetry import samples as sample_types
from estimator.telemetry.samples import BatterySample, Sample, VelocitySample, WindSample

#: Code of a sample type a clean run may not hold (a RebootSample among them).
OTHER = -1
#: Sample types a clean run may hold, by code: those with value checks, and those without.
KINDS: dict[type, int] = {
    VelocitySample: 1,
    BatterySample: 2,
    WindSample: 3,
    **dict.fromkeys(
        (
            sample_types.ArmedSample,
            sample_types.LandedSample,
            sample_types.GripperSample,
            sample_types.PositionSample,
            sample_types.HomeSample,
            sample_types.MissionCurrentSample,
        ),
        0,
    ),
}
#: The fields the value checks read (NED m/s, m; V, A, mAh; NED m/s), by sample type.
CHECKED_FIELDS: dict[type, tuple[str, ...]] = {
    VelocitySample: ("vn_mps", "ve_mps", "vd_mps", "alt_m"),
    BatterySample: ("voltage_v", "current_a", "consumed_mah"),
    WindSample: ("wind_n_mps", "wind_e_mps"),
}
#: Checked fields that may be None (unknown): their column is 0 there, ``known`` False.
OPTIONAL_FIELDS = frozenset({"alt_m", "current_a", "consumed_mah"})

_TIME = attrgetter("time_s")


@dataclass(frozen=True, slots=True)
class SampleColumns:
    """One row per sample: ``kinds`` (int8, :data:`KINDS` codes, :data:`OTHER` for the rest),
    ``time_s`` (the stamps, s), ``values`` (each field of :data:`CHECKED_FIELDS` of the types
    present, float64; 0 in the rows of other types and where an optional field is None) and
    ``known`` (each optional field of those: bool, False where None or another type)."""

    kinds: np.ndarray
    time_s: np.ndarray
    values: dict[str, np.ndarray]
    known: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.kinds)

    @classmethod
    def of_samples(cls, samples: Sequence[Sample]) -> SampleColumns:
        """The columns of sample objects, each field read once."""
        n = len(samples)
        kinds = np.fromiter(map(KINDS.get, map(type, samples), repeat(OTHER)), np.int8, n)
        time_s = np.fromiter(map(_TIME, samples), np.float64, n)
        values: dict[str, np.ndarray] = {}
        known: dict[str, np.ndarray] = {}
        for sample_type, names in CHECKED_FIELDS.items():
            rows = np.flatnonzero(kinds == KINDS[sample_type])
            if not len(rows):
                continue
            picked = list(map(samples.__getitem__, rows.tolist()))
            for name in names:
                column = values[name] = np.zeros(n)
                fields = list(map(attrgetter(name), picked))
                if name in OPTIONAL_FIELDS:
                    has = known[name] = np.zeros(n, dtype=bool)
                    has[rows], column[rows] = _optional(fields)
                else:
                    column[rows] = fields
        return cls(kinds, time_s, values, known)

    @classmethod
    def of_type(
        cls,
        sample_type: type,
        time_s: np.ndarray,
        values: dict[str, np.ndarray] | None = None,
        known: dict[str, np.ndarray] | None = None,
    ) -> SampleColumns:
        """The columns of samples all of ``sample_type``, stamped ``time_s`` (s): ``values``
        holds each of its checked fields, 0 where ``known`` (by optional field; absent: all
        known) is False."""
        n = len(time_s)
        names = CHECKED_FIELDS.get(sample_type, ())
        values = values or {}
        if set(values) != set(names):
            raise ValueError(f"{sample_type.__name__}'s checked fields are {names}")
        kinds = np.full(n, KINDS.get(sample_type, OTHER), dtype=np.int8)
        flags = {
            name: (known or {}).get(name, np.ones(n, dtype=bool))
            for name in names
            if name in OPTIONAL_FIELDS
        }
        return cls(kinds, np.asarray(time_s, dtype=np.float64), values, flags)

    @staticmethod
    def joined(parts: Sequence[SampleColumns]) -> SampleColumns:
        """``parts`` one after the other (a field a part lacks is 0 there, not known)."""
        sizes = [len(part) for part in parts]

        def join(name: str, pick: str, dtype: type) -> np.ndarray:
            return np.concatenate(
                [
                    getattr(part, pick).get(name, np.zeros(size, dtype=dtype))
                    for part, size in zip(parts, sizes, strict=True)
                ]
            )

        return SampleColumns(
            np.concatenate([part.kinds for part in parts]).astype(np.int8),
            np.concatenate([part.time_s for part in parts]).astype(np.float64),
            {name: join(name, "values", float) for name in {n for p in parts for n in p.values}},
            {name: join(name, "known", bool) for name in {n for p in parts for n in p.known}},
        )

    def rows(self, index: slice | np.ndarray) -> SampleColumns:
        """The rows ``index`` selects (a slice: views), in its order."""
        return SampleColumns(
            self.kinds[index],
            self.time_s[index],
            {name: column[index] for name, column in self.values.items()},
            {name: column[index] for name, column in self.known.items()},
        )


def _optional(values: list[float | None]) -> tuple[np.ndarray, np.ndarray]:
    """(known, value): which of ``values`` are not None, and the values (0 where None)."""
    known = np.fromiter(map(is_not, values, repeat(None)), dtype=bool, count=len(values))
    if known.all():
        return known, np.array(values, dtype=np.float64)
    return known, np.array([0.0 if x is None else x for x in values], dtype=np.float64)
