"""Which pack a flight flies, and its memory (:mod:`estimator.estimation.pack_memory`) around
that flight's :class:`~estimator.estimation.pipeline.Pipeline`.

The pack is the configured one (``[pack] id``, ``--pack``), else the one whose serial number
the flight reports (the autopilot's SMART_BATTERY_INFO, a log's ``pack_id``), made a pack id
by :func:`~estimator.estimation.pack_memory.pack_id_from_serial`:

- a configured id wins over a serial (a serial naming another pack gives one note);
- the first usable serial names the pack for the whole flight: a later, different one gives
  one note and changes nothing (a swapped or forged report never moves the memory mid-flight);
  a serial that makes no pack id gives one note and names nothing;
- the pack's memory becomes the pack filter's prior until the first flying reading
  (:meth:`Pipeline.adopt_pack_prior`: a filter started on the ground starts again from it). A
  serial that comes in flight still names the pack: the flight goes on learning from the label
  and what it learns is stored under that pack;
- without a memory directory nothing is read or stored; without a pack id nothing is stored.

Notes are one line each, for the caller to log (the daemon) or print (replay).
"""

from __future__ import annotations

from pathlib import Path

from estimator.errors import UserError
from estimator.estimation.pack_memory import load_prior, pack_id_from_serial, remember
from estimator.estimation.pipeline import Pipeline

#: Characters of a reported serial shown in a note.
_SHOWN_CHARS = 40


class FlightPack:
    """The pack of one flight through ``pipeline`` (see the module docstring)."""

    def __init__(
        self,
        pipeline: Pipeline,
        directory: Path | None,
        configured_id: str | None,
        when_s: float,
    ) -> None:
        """``directory``: the packs' memory (None: none); ``configured_id``: the pack flown,
        already checked (it needs ``directory``), whose memory becomes the prior now (UserError
        for a memory file that is not one); ``when_s``: the flight's start (Unix s), its row
        of the pack's history."""
        self.pipeline = pipeline
        self.directory = directory
        self.pack_id = configured_id
        self.configured = configured_id is not None
        self.when_s = when_s
        #: Memory files that could not be read (a serial's pack) or written.
        self.errors = 0
        self._noted: set[str] = set()
        if directory is not None and configured_id is not None:
            pipeline.pack_prior = load_prior(directory, configured_id, self.label_ah)

    @property
    def label_ah(self) -> float:
        """The capacity the pack flies under (its label, Ah)."""
        return self.pipeline.pack.spec.capacity_ah

    @property
    def wants_serial(self) -> bool:
        """Whether a reported serial would name the pack (a memory directory, no pack yet)."""
        return self.directory is not None and self.pack_id is None

    def reported(self, serial: str) -> str | None:
        """A serial number reported for the pack flown; a note when it names the pack or
        when it is not used (at most one note of each kind a flight)."""
        if self.directory is None:
            return None
        pack_id = pack_id_from_serial(serial)
        if pack_id is None:
            shown = repr(serial[:_SHOWN_CHARS])
            return self._once("unusable", f"pack serial {shown} makes no pack id: not used")
        if self.pack_id is None:
            self.pack_id = pack_id
            return self._named(self.directory, pack_id)
        if pack_id == self.pack_id:
            return None
        if self.configured:
            return self._once(
                "configured",
                f"pack {self.pack_id} is configured, the autopilot reports serial {pack_id}: "
                f"the memory of {self.pack_id} is used",
            )
        return self._once(
            "changed",
            f"pack serial {pack_id} reported while flying pack {self.pack_id}: the memory of "
            f"{self.pack_id} is kept for this flight",
        )

    def remember(self) -> str | None:
        """Store what the pack filter holds under the pack (nothing without a directory, a
        pack id or a started filter); a note when it cannot be written."""
        pack = self.pipeline.pack_state
        if self.directory is None or self.pack_id is None or pack is None:
            return None
        try:
            remember(self.directory, self.pack_id, self.label_ah, pack.estimate(), self.when_s)
        except (OSError, UserError) as exc:
            self.errors += 1
            return f"pack memory not written: {exc}"
        return None

    def unnamed(self) -> str | None:
        """At the end of a flight: a note when a memory directory was given but no pack was
        named (nothing was stored)."""
        if not self.wants_serial:
            return None
        return (
            f"no pack id configured and no usable pack serial reported: nothing stored in "
            f"{self.directory}"
        )

    def _named(self, directory: Path, pack_id: str) -> str:
        try:
            prior = load_prior(directory, pack_id, self.label_ah)
        except UserError as exc:
            self.errors += 1
            return f"pack {pack_id} (its serial): {exc}"
        if prior is None:
            return f"pack {pack_id} (its serial): no memory under this label yet"
        if not self.pipeline.adopt_pack_prior(prior):
            return (
                f"pack {pack_id} (its serial), reported in flight: its memory is not applied, "
                "what this flight learns is stored under it"
            )
        return f"pack {pack_id} (its serial): its memory says {prior.capacity_ah:.2f} Ah"

    def _once(self, kind: str, text: str) -> str | None:
        if kind in self._noted:
            return None
        self._noted.add(kind)
        return text
