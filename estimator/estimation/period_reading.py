"""The battery reading a period ends with, as the pack filter and the voltage model take it.

A reading without a time of its own (BATTERY_STATUS, SYS_STATUS) is stamped with the newest
autopilot time the link has seen: on PX4's onboard link within ±4 ms of the time PX4's ULog
gives the same reading, one in fifty up to 0.13 s late (measured on the PX4 SIH flights of
``tests/test_px4_sitl.py``). A pack that reports on a cadence locked to the autopilot's clock
can put a reading within those few ms of every period's end; then "the period's latest
reading" is one reading on one transport and the one before it on the other, and the pack
filter, which moves its capacity by ~0.2 % on a single reading early in a pack, learns another
pack from the same flight.

So a period ends with the mean of the readings *held* over its last :data:`STAMP_WINDOW_S`:
each reading holds from its time to the next one's (the last to the period's end). A period
whose latest reading came before that window ends with it, whole, as a plain "latest reading";
a latest reading inside the window is blended with the one it followed in proportion to how
long each held, so the reading taken moves continuously as a stamp moves across the period's
end. Times in seconds of the autopilot clock, volts, amperes, mAh.
"""

from __future__ import annotations

from collections.abc import Sequence

from estimator.telemetry.samples import BatterySample

#: Seconds before a period's end over which the held readings are averaged: how well an
#: untimed reading's stamp is known (the ±4 ms jitter above, with margin; the rare late ones
#: are not covered, and a wider window takes more from the reading before on every link).
STAMP_WINDOW_S = 0.05


def period_end_reading(
    held: BatterySample | None,
    readings: Sequence[BatterySample],
    end_s: float,
) -> BatterySample:
    """The reading a period ending at ``end_s`` (s) ends with: ``readings`` are the period's
    (in time order, at least one), ``held`` the last one before them (None: none on this
    clock). Its time, voltage, current and consumed charge are the hold-weighted means over
    the last :data:`STAMP_WINDOW_S` before ``end_s``; a value one of the weighted readings
    lacks (None) is the latest reading's, as is everything when the latest came before that
    window."""
    latest = readings[-1]
    low_s = end_s - STAMP_WINDOW_S
    if latest.time_s <= low_s:
        return latest
    chain = [held, *readings] if held is not None else list(readings)
    weighted: list[tuple[float, BatterySample]] = []
    stop_s = max(end_s, latest.time_s)
    for reading in reversed(chain):
        weight_s = stop_s - max(reading.time_s, low_s)
        if weight_s > 0.0:
            weighted.append((weight_s, reading))
        if reading.time_s <= low_s:
            break
        stop_s = reading.time_s
    total_s = sum(w for w, _ in weighted)
    if len(weighted) < 2 or not total_s > 0.0:
        return latest

    def mean(values: list[float | None]) -> float | None:
        """The hold-weighted mean of one field, None when a weighted reading lacks it."""
        known = [v for v in values if v is not None]
        if len(known) < len(values):
            return None
        return sum(w * v for (w, _), v in zip(weighted, known, strict=True)) / total_s

    current_a = mean([r.current_a for _, r in weighted])
    if current_a is None and latest.current_a is not None:
        return latest  # a reading without a current among them: the latest, whole
    consumed_mah = mean([r.consumed_mah for _, r in weighted])
    return BatterySample(
        time_s=sum(w * r.time_s for w, r in weighted) / total_s,
        voltage_v=sum(w * r.voltage_v for w, r in weighted) / total_s,
        current_a=current_a,
        consumed_mah=latest.consumed_mah if consumed_mah is None else consumed_mah,
        remaining_pct=latest.remaining_pct,
    )
