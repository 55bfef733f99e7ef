"""The autopilot's clock (s since its boot), believed to jump only when several frames agree.

:class:`AutopilotClock` keeps it. A frame stamped within ``max_step_s`` ahead of it or
``backstep_s`` behind it is accepted (behind: reordering; the clock does not go back). Any
other stamp — the first ones, a reboot, a link gap, or one forged or corrupt frame — is a
candidate new clock, believed only after ``confirm_frames`` frames agree with it with no frame
of the current clock in between; until then those frames are skipped. Believed, it starts the
clock (:attr:`ClockVerdict.START`) or, when there was one:

- behind the clock: a reboot (:attr:`ClockVerdict.REBOOT`);
- ahead by at most ``max_gap_s``: a link gap, the clock moves on (:attr:`ClockVerdict.GAP`);
- further ahead, or back at (or beyond) the clock held before a believed reboot — the old clock
  was alive: the reboot was not real — a new reference (:attr:`ClockVerdict.JUMP`).

:class:`ClockFilter` puts a stream of samples through that clock without losing any: samples
of frames whose stamp is not believed yet are held, and delivered once the new clock is
confirmed (a real reboot or gap loses nothing) or dropped when it is refuted (a forged or
corrupt stamp leaves the samples exactly as if the frame had never come). Samples stamped
with the clock itself (a battery reading without its own stamp) are held meanwhile too, and
delivered on the clock they belong to.
"""

from __future__ import annotations

import enum
import math
from collections import Counter
from dataclasses import dataclass, replace

from estimator.telemetry.samples import RebootSample, Sample


class ClockVerdict(enum.Enum):
    """What :meth:`AutopilotClock.check` made of a stamp."""

    ACCEPT = "accept"  # consistent with the clock (which moved forward if it is newer)
    SKIP = "skip"  # far from the clock, not (yet) confirmed by other frames: skip the frame
    START = "start"  # the first clock, confirmed
    REBOOT = "reboot"  # confirmed clock behind the old one: the autopilot rebooted
    GAP = "gap"  # confirmed clock ahead by at most max_gap_s: telemetry was lost meanwhile
    JUMP = "jump"  # confirmed clock far ahead, or the pre-reboot clock back: a new reference


@dataclass(frozen=True, slots=True)
class ClockSettings:
    """Seconds of autopilot clock and frame counts; see the module docstring.
    ``max_candidates``: candidate new clocks followed at once (a stray stamp among the frames
    of a real reboot does not make it start over). ``confirm_wall_s``: wall seconds a
    candidate must also run alone (no frame of the clock since its first), where the caller
    gives wall times (a live link: a burst of forged frames cannot prove a new clock, the
    autopilot's own clock falling silent does); 0 for a log, where frames have no wall time."""

    max_step_s: float = 2.5
    backstep_s: float = 2.0
    confirm_frames: int = 5
    max_gap_s: float = 120.0
    max_candidates: int = 4
    confirm_wall_s: float = 0.0


@dataclass(slots=True)
class _Candidate:
    """A candidate new clock: its first and newest stamps (s), frames so far, an id, the
    tag of the samples it holds (one source of a kind per clock, e.g. a velocity message),
    and the wall time (s) of its first frame."""

    first_s: float
    last_s: float
    frames: int
    ident: int
    tag: str | None = None
    first_wall_s: float = 0.0


class AutopilotClock:
    """The autopilot's clock (s since its boot), moved only by stamps it believes."""

    def __init__(self, settings: ClockSettings | None = None) -> None:
        self.settings = settings or ClockSettings()
        self.time_s: float | None = None
        self.candidates: list[_Candidate] = []
        #: The candidate the last checked stamp joined or started (None when accepted).
        self.joined: _Candidate | None = None
        self._next_ident = 0
        self._before_reboot_s: float | None = None  # the clock a believed reboot replaced

    def _near(self, time_s: float, reference_s: float) -> bool:
        s = self.settings
        return reference_s - s.backstep_s <= time_s <= reference_s + s.max_step_s

    def forget_candidates(self) -> None:
        """Drop every pending candidate (their frames stay skipped)."""
        self.candidates = []

    def check(self, time_s: float, wall_s: float = 0.0) -> ClockVerdict:
        """Judge one frame's stamp (s), received at wall time ``wall_s`` (s); the clock moves
        on ACCEPT (forward only) and on every confirmed change (:attr:`joined` is then the
        confirmed candidate)."""
        now = self.time_s
        self.joined = None
        if now is not None and self._near(time_s, now):
            self.candidates = []
            self.advance(time_s)
            return ClockVerdict.ACCEPT
        joined = next((c for c in self.candidates if self._near(time_s, c.last_s)), None)
        if joined is None:
            if len(self.candidates) >= self.settings.max_candidates:
                self.candidates.remove(min(self.candidates, key=lambda c: c.frames))
            joined = _Candidate(time_s, time_s, 0, self._next_ident, first_wall_s=wall_s)
            self._next_ident += 1
            self.candidates.append(joined)
        joined.frames += 1
        joined.last_s = max(joined.last_s, time_s)
        self.joined = joined
        if not self._proven(joined, wall_s):
            return ClockVerdict.SKIP
        return self._believe(joined)

    def advance(self, time_s: float) -> None:
        """Move a running clock forward to an accepted stamp ``time_s`` (s), never back."""
        if self.time_s is None or time_s <= self.time_s:
            return
        self.time_s = time_s
        if self._before_reboot_s is not None and time_s > self._before_reboot_s:
            self._before_reboot_s = None  # the old clock can no longer be told apart

    def due(self, wall_s: float) -> ClockVerdict | None:
        """At wall time ``wall_s`` (s), with no new frame: believe the candidate of most frames
        when it is proven by now (see :attr:`ClockSettings.confirm_wall_s`; :attr:`joined` is
        then it), else None."""
        self.joined = None
        if not self.candidates:
            return None
        best = max(self.candidates, key=lambda c: c.frames)
        if not self._proven(best, wall_s):
            return None
        self.joined = best
        return self._believe(best)

    def _proven(self, candidate: _Candidate, wall_s: float) -> bool:
        s = self.settings
        return (
            candidate.frames >= s.confirm_frames
            and wall_s - candidate.first_wall_s >= s.confirm_wall_s
        )

    def _believe(self, joined: _Candidate) -> ClockVerdict:
        """``joined`` becomes the clock: what it means relative to the one it replaces."""
        now = self.time_s
        self.candidates = []
        new_s = self.time_s = joined.last_s
        if now is None:
            return ClockVerdict.START
        before = self._before_reboot_s
        if new_s < now:
            self._before_reboot_s = now if before is None else max(before, now)
            return ClockVerdict.REBOOT
        if before is not None and new_s >= before - self.settings.backstep_s:
            self._before_reboot_s = None
            return ClockVerdict.JUMP
        return ClockVerdict.JUMP if new_s - now > self.settings.max_gap_s else ClockVerdict.GAP


#: At most this many samples are held while candidate new clocks are pending.
MAX_HELD_SAMPLES = 256


@dataclass(frozen=True, slots=True)
class _Held:
    """A sample held while candidate new clocks are pending: one stamped by a candidate frame
    (``candidate`` its id), or one stamped with the clock (``candidate`` None) with the newest
    stamp of each candidate when it arrived (s, by id)."""

    sample: Sample
    candidate: int | None
    stamps: dict[int, float]


class ClockFilter:
    """Samples through an :class:`AutopilotClock` (see the module docstring). Counts into
    ``counts``: ``time_jump`` (frames whose stamp was off the running clock when they came),
    ``clock_gaps``, ``reboots``, ``clock_jumps``. ``verdict`` is the last stamp's."""

    def __init__(self, counts: Counter[str], settings: ClockSettings | None = None) -> None:
        self.clock = AutopilotClock(settings)
        self.counts = counts
        self.verdict = ClockVerdict.ACCEPT
        self._held: list[_Held] = []
        self._pending_out: list[Sample] = []  # released by refuted candidates, not yet given

    def stamped(
        self, time_s: float, sample: Sample | None = None, tag: str | None = None
    ) -> list[Sample] | None:
        """A frame stamped ``time_s`` (s), carrying ``sample`` (or nothing but its stamp) from
        the source ``tag``.

        None: the stamp is not believed (yet); the frame is skipped and its sample held
        (unless its candidate clock already holds samples of another tag: the candidate's
        ``tag`` names the source it confirms, see :attr:`AutopilotClock.joined`).
        Else the samples to deliver before the frame's own: those refuted candidates held
        back, or a confirmed candidate's (after a RebootSample when the clock was
        re-referenced)."""
        clock = self.clock
        verdict = self.verdict = clock.check(time_s)
        if verdict is ClockVerdict.ACCEPT:
            return self._refuted()
        joined = clock.joined
        assert joined is not None
        if verdict is ClockVerdict.SKIP:
            if clock.time_s is not None:  # the first frames wait for the clock: no skip
                self.counts["time_jump"] += 1
            if sample is not None and joined.tag in (None, tag):
                joined.tag = tag
                self._held.append(_Held(sample, joined.ident, {}))
            if len(self._held) > MAX_HELD_SAMPLES:
                clock.forget_candidates()
                self._pending_out += self._refuted()
            return None
        out: list[Sample] = []
        if verdict is ClockVerdict.GAP:
            self.counts["clock_gaps"] += 1
        elif verdict is not ClockVerdict.START:
            self.counts["reboots" if verdict is ClockVerdict.REBOOT else "clock_jumps"] += 1
            out.append(RebootSample(min(joined.first_s, time_s)))
        return self._confirmed(joined, out)

    @property
    def holding(self) -> bool:
        """Whether samples are held for a pending clock or released and not yet given."""
        return bool(self._held or self._pending_out)

    def clocked(self, sample: Sample) -> list[Sample]:
        """A sample stamped with the clock (no stamp of its own): held while candidate new
        clocks are pending, else delivered."""
        if self.clock.candidates:
            stamps = {c.ident: c.last_s for c in self.clock.candidates}
            self._held.append(_Held(sample, None, stamps))
            return []
        return [sample]

    def flush(self) -> list[Sample]:
        """End of input: the held samples as if every pending candidate were refuted; but a
        clock that never started starts with the candidate of most frames (a short log)."""
        clock = self.clock
        candidates, clock.candidates = clock.candidates, []
        if clock.time_s is None and candidates:
            best = max(candidates, key=lambda c: c.frames)
            clock.time_s = best.last_s
            self.verdict = ClockVerdict.START
            return self._confirmed(best, [])
        return self._refuted()

    def take_pending(self) -> list[Sample]:
        """Samples refuted candidates released that no call has delivered yet."""
        out, self._pending_out = self._pending_out, []
        return out

    def _refuted(self) -> list[Sample]:
        """The held clock-stamped samples on the clock they came on; the frames that carried
        the candidates' stamps are dropped."""
        held, self._held = self._held, []
        return [*self.take_pending(), *(h.sample for h in held if h.candidate is None)]

    def _confirmed(self, chosen: _Candidate, out: list[Sample]) -> list[Sample]:
        """The held samples once ``chosen`` is believed, in order after ``out``: the
        clock-stamped ones moved to its newest stamp when they came (those older than it stay
        on the old clock, before ``out``), its own frames' samples while their times do not
        fall; other candidates' are dropped."""
        held, self._held = self._held, []
        old: list[Sample] = self.take_pending()
        last_s = -math.inf
        for h in held:
            if h.candidate is None:
                stamp_s = h.stamps.get(chosen.ident)
                if stamp_s is not None:
                    out.append(replace(h.sample, time_s=stamp_s))
                elif self.verdict is ClockVerdict.START:
                    out.append(replace(h.sample, time_s=chosen.first_s))
                else:
                    old.append(h.sample)
            elif h.candidate == chosen.ident and last_s <= h.sample.time_s:
                last_s = h.sample.time_s
                out.append(h.sample)
        return old + out
