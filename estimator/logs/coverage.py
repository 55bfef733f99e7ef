"""What a log's samples cover for an estimate, and the sentence saying what it lacks.

An estimate needs battery readings with a voltage (V) and a known, non-zero current (A), and a
velocity. :class:`Coverage` counts them as the samples stream past (after the plausibility and
time checks); :meth:`Coverage.gap` names the first thing missing, with the message types the
log holds among those its reader uses (a log with a battery monitor that reads 0 A throughout
has no current sensor: its power is unknown, not zero).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from itertools import compress, repeat
from operator import attrgetter, is_

from estimator.telemetry.samples import BatterySample, Sample, VelocitySample

_CURRENT = attrgetter("current_a")


@dataclass
class Coverage:
    """Counts of the samples an estimate needs, seen so far."""

    batteries: int = 0
    currents_known: int = 0
    currents_nonzero: int = 0
    velocities: int = 0

    def observe(self, sample: Sample) -> None:
        if isinstance(sample, BatterySample):
            self.batteries += 1
            if sample.current_a is not None:
                self.currents_known += 1
                self.currents_nonzero += sample.current_a != 0.0
        elif isinstance(sample, VelocitySample):
            self.velocities += 1

    def observe_many(self, samples: list[Sample]) -> None:
        """:meth:`observe` each of ``samples``, in C loops over its fields."""
        types = list(map(type, samples))
        batteries = compress(samples, map(is_, types, repeat(BatterySample)))
        currents = list(map(_CURRENT, batteries))
        self.batteries += len(currents)
        self.currents_known += len(currents) - currents.count(None)
        self.currents_nonzero += len(list(filter(None, currents)))  # not None, not 0 A
        self.velocities += types.count(VelocitySample)

    def gap(
        self,
        found: Iterable[str],
        battery_types: Sequence[str],
        velocity_types: Sequence[str],
    ) -> str | None:
        """What the samples lack for an estimate and the message types the log has (``found``:
        those of its reader's types it holds), as a sentence part; None when nothing lacks.
        ``battery_types`` and ``velocity_types``: the reader's sources, most preferred first."""
        batteries = " or ".join(battery_types)
        if not self.batteries:
            gap = f"no battery reading with a voltage ({batteries})"
        elif not self.currents_known:
            gap = f"no battery current ({batteries}: reported unknown)"
        elif not self.currents_nonzero:
            gap = f"the battery current is 0 A throughout ({batteries}: no current sensor)"
        elif not self.velocities:
            gap = f"no velocity ({' or '.join(velocity_types)})"
        else:
            return None
        names = sorted(set(found))
        return f"{gap}; it has {', '.join(names) if names else 'none of the types read'}"
