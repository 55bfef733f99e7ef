"""The daemon's warnings that could repeat, each at most once per period (s, the event loop's
clock), so a flood of bad frames or reboots gives a line every few seconds, not one per
frame: counters of bad input (:func:`warn_input_counts`) and repeated events."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

from estimator.mavlink.autopilot_lock import AutopilotLock
from estimator.mavlink.link import MavlinkLink
from estimator.telemetry.decode import TelemetryDecoder
from estimator.telemetry.skip_counters import SKIP_COUNTERS


class ThrottledLog:
    """Warnings on ``logger`` at most once per ``period_s`` (s) per key."""

    def __init__(self, logger: logging.Logger, period_s: float) -> None:
        self._log = logger
        self.period_s = period_s
        self._counts: dict[str, tuple[int, float]] = {}  # key → (value, s) last logged
        self._events_s: dict[str, float] = {}  # key → s last logged

    def count(self, key: str, value: int, now_s: float, what: str) -> None:
        """Warn "<value> <what>" when the counter ``key`` moved since its last line."""
        logged_value, logged_s = self._counts.get(key, (0, -math.inf))
        if value != logged_value and now_s - logged_s >= self.period_s:
            self._log.warning("%d %s", value, what)
            self._counts[key] = (value, now_s)

    def due(self, key: str, now_s: float, period_s: float | None = None) -> bool:
        """Whether the event ``key`` may be told now (at most once per ``period_s``, default
        the log's); marks it told."""
        period = self.period_s if period_s is None else period_s
        if now_s - self._events_s.get(key, -math.inf) < period:
            return False
        self._events_s[key] = now_s
        return True

    def event(self, key: str, now_s: float, fmt: str, *args: object) -> None:
        """Warn ``fmt % args`` for the event ``key`` when :meth:`due` (the counters say how
        many there were)."""
        if self.due(key, now_s):
            self._log.warning(fmt, *args)


def format_counts(counts: Mapping[str, int]) -> str:
    """``a=1, b=2`` of the counters that are not 0, by name."""
    return ", ".join(f"{k}={v}" for k, v in sorted(counts.items()) if v) or "nothing received"


def warn_input_counts(
    throttled: ThrottledLog,
    now_s: float,
    decoder: TelemetryDecoder,
    link: MavlinkLink | None,
    lock: AutopilotLock,
) -> None:
    """The counters of input skipped or dropped so far, each when it moved: implausible
    values (the decoder's), bad frames and floods (the link's), frames the lock refused, and
    frames signing rejected."""
    skipped = {k: decoder.counts[k] for k in SKIP_COUNTERS if decoder.counts[k]}
    throttled.count(
        "implausible",
        sum(skipped.values()),
        now_s,
        f"implausible inputs skipped so far ({format_counts(skipped)})",
    )
    if link is None:
        return
    for key, what in (
        ("bad_frames", "bad frames"),
        ("dropped", "messages dropped (flood)"),
    ):
        throttled.count(key, link.counts[key], now_s, f"{what} so far (input skipped)")
    for key, what in (
        ("foreign_peer", "frames with the autopilot's ids from another address"),
        ("off_clock_frames", "frames off the autopilot's clock, never proven (forged?)"),
        ("unsigned_frames", "unsigned frames from a sender that signs"),
    ):
        throttled.count(key, lock.counts[key], now_s, f"{what} so far (dropped)")
    if link.signing is not None:
        rejected = link.signing.rejected
        throttled.count(
            "signing",
            sum(rejected.values()),
            now_s,
            f"frames rejected by signing so far ({format_counts(dict(rejected))})",
        )
