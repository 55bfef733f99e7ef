"""The figures of docs/pack.md's summaries of the ArduCopter SITL pack flights
(``replay/sitl_packs``), pooled from the flights ``python scripts/pack_state_sitl.py``
tabulates: each flight replayed with the LABELLED capacity
(:func:`estimator.analysis.pack_flights.replay_pack_flight`, 15 s of CPU for the 27), scored
from 60 s after take-off until 60 s before the true reserve, and replayed as a daemon
restarted 90 s after take-off (:func:`~estimator.analysis.pack_flights.replay_restarted`).
The simulator's ensemble of drawn packs is ``scripts/ensemble_figures.py``'s.

``scripts/figures.py`` registers the blocks; ``tests/test_figures.py`` checks them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from functools import cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from estimator.analysis.pack_flights import (
    PackFlight,
    Restart,
    half_used_s,
    replay_pack_flight,
    replay_restarted,
)
from estimator.mavlink.pack_alerts import PackLabelAlert
from estimator.physics.vehicle import load_vehicle

REPO = Path(__file__).resolve().parent.parent
FLIGHTS = REPO / "replay" / "sitl_packs"
VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: How each set of ``split.json`` is named in the prose.
SET_NAMES = {
    "tuning": "tuning",
    "held_out": "held out",
    "held_out_2": "held-out 2",
    "held_out_3": "held-out 3",
    "held_out_4": "held-out 4",
    "held_out_5": "held-out 5",
    "held_out_6": "held-out 6",
    "held_out_7": "held-out 7",
}
#: The label warning's deadline after take-off (s) that ``tests/test_pack_state.py`` holds.
WARNING_WITHIN_S = 90.0
#: Per flight: the test's bounds on the median and worst |error| of the endurance (%).
MEDIAN_BOUND_PCT, WORST_BOUND_PCT = 3.0, 8.0
#: The test's bound on a restarted daemon's endurance error 60 s after the restart.
RESTART_BOUND = 0.08
#: Flights flown in at least this wind (m/s) are told apart in the misses.
STRONG_WIND_MPS = 5.0


@cache
def flights() -> dict[str, tuple[PackFlight, ...]]:
    """Every flight of ``split.json`` replayed under its label, per set."""
    vehicle = load_vehicle(VEHICLE)
    split = json.loads((FLIGHTS / "split.json").read_text())
    return {
        half: tuple(replay_pack_flight(FLIGHTS / name, vehicle) for name in names)
        for half, names in split.items()
    }


def _all() -> list[PackFlight]:
    return [f for half in flights().values() for f in half]


def _held_out() -> list[PackFlight]:
    """Every flight of the held-out sets (all but the tuning set)."""
    return [f for half, pooled in flights().items() if half != "tuning" for f in pooled]


def _scored(pooled: Sequence[PackFlight]) -> list[PackFlight]:
    return [f for f in pooled if len(f.errors)]


def _abs_pct(pooled: Sequence[PackFlight], which: str = "errors") -> np.ndarray:
    """|relative error| (%) of ``which`` (``errors``, ``px4_errors``, ``ardupilot_errors``)
    pooled over the flights' scored estimates."""
    values = 100 * np.abs(np.concatenate([getattr(f, which) for f in pooled]))
    return values[np.isfinite(values)]


def _z(pooled: Sequence[PackFlight]) -> np.ndarray:
    z = np.concatenate([f.z for f in pooled])
    return z[np.isfinite(z)]


def _median_pct(flight: PackFlight) -> float:
    """One flight's median |error| (%)."""
    return float(np.median(_abs_pct([flight])))


def _worst_pct(flight: PackFlight) -> float:
    """One flight's largest |error| (%)."""
    return float(_abs_pct([flight]).max())


def _within(pooled: Sequence[PackFlight], sigmas: float) -> float:
    """Share (%) of the scored estimates whose truth lies within ``sigmas``."""
    return float(100 * np.mean(np.abs(_z(pooled)) <= sigmas))


def _wind_mps(flight: PackFlight) -> float:
    return max(
        (e["speed_mps"] for e in flight.truth["effects"] if e["effect"] == "wind"), default=0
    )


def charge_and_capacity() -> str:
    """The worst error of the charge at power-up (fraction of the pack) and of the capacity
    once half the charge is used (% of the truth), over every flight, as bounds."""
    charge, capacity = [], []
    for flight in _all():
        battery = flight.truth["battery"]
        first = next(e for e in flight.estimates if np.isfinite(e.pack_soc))
        charge.append(abs(first.pack_soc - battery["start_soc"]))
        half_s = half_used_s(flight.readings, battery)
        at_half = [e for e in flight.estimates if e.time_s <= half_s][-1]
        capacity.append(abs(at_half.capacity_ah / battery["capacity_ah"] - 1))
    return (
        f"The charge at power-up is found to within {_bound(max(charge), 3)}. The capacity is "
        f"within {_bound(100 * max(capacity), 1)} % of the truth once half the charge is used"
    )


#: The charges at power-up (fractions) whose voltage on the ground docs/sitl.md quotes.
GROUND_SOCS = (0.75, 0.5)


def ground_voltage() -> str:
    """docs/sitl.md: the voltage (V) SITL's pack is powered up at for each charge of
    :data:`GROUND_SOCS`, and the largest difference (mV) of a reading before arming from it
    over the flights powered up so."""
    started: dict[float, set[float]] = {soc: set() for soc in GROUND_SOCS}
    worst_v, count = 0.0, 0
    for flight in _all():
        battery = flight.truth["battery"]
        soc, start_v = round(battery["start_soc"], 2), battery["start_voltage_v"]
        if soc not in started:
            continue
        started[soc].add(start_v)
        armed_s = flight.truth["events"]["armed_s"]
        ground_v = [r.voltage_v for r in flight.readings if r.time_s < armed_s]
        worst_v = max(worst_v, *(abs(v - start_v) for v in ground_v))
        count += 1
    voltages = " or ".join(
        f"{start_v:.3f} V ({100 * soc:.0f} %)" for soc, (start_v,) in started.items()
    )
    return (
        f"started at {voltages}, every reading before arming is within "
        f"{1000 * worst_v:.0f} mV of it on the {count} flights powered up so"
    )


def _bound(worst: float, decimals: int) -> str:
    """``worst`` rounded up to ``decimals``: a bound that holds as written."""
    return f"{math.ceil(worst * 10**decimals) / 10**decimals:.{decimals}f}"


def warning() -> str:
    """When the ground station's label warning first goes out after take-off, per flight: the
    mislabelled flights warned in time, those that hold their label never warned."""
    in_time, mislabelled, false_alarms, label_right = 0, 0, 0, 0
    late: list[str] = []
    for half, pooled in flights().items():
        for flight in pooled:
            battery = flight.truth["battery"]
            alert = PackLabelAlert(battery["labelled_capacity_ah"])
            sent_s = [e.time_s for e in flight.estimates if alert.update(e) is not None]
            after_s = sent_s[0] - flight.truth["events"]["takeoff_s"] if sent_s else np.inf
            if battery["capacity_ah"] >= battery["labelled_capacity_ah"]:
                label_right += 1
                false_alarms += bool(sent_s)
                continue
            mislabelled += 1
            if after_s <= WARNING_WITHIN_S:
                in_time += 1
                continue
            share = battery["capacity_ah"] / battery["labelled_capacity_ah"]
            late.append(
                f"{SET_NAMES[half]}'s pack at {100 * share:.0f} % of its label powered up at "
                f"{100 * battery['start_soc']:.0f} %, is announced after {after_s:.0f} s"
            )
    never = "never" if false_alarms == 0 else f"on {false_alarms}"
    return (
        f"It reaches the ground station within {WARNING_WITHIN_S:.0f} s of take-off on "
        f"{in_time} of the {mislabelled} mislabelled flights, and {never} on the {label_right} "
        f"that hold their label" + "".join(f"; {text}" for text in late)
    )


def endurance() -> str:
    """Our pooled median |error| per set, the worst, how many flights exceed the per-flight
    bounds, and the autopilots' pooled medians."""
    medians = ", ".join(
        f"{np.median(_abs_pct(pooled)):.1f} % ({SET_NAMES[half]})"
        for half, pooled in flights().items()
    )
    scored = _scored(_all())
    over_median = [f for f in scored if _median_pct(f) > MEDIAN_BOUND_PCT]
    over_worst = [f for f in scored if _worst_pct(f) > WORST_BOUND_PCT]
    missed = {f.name: f for f in (*over_median, *over_worst)}
    windy = sum(_wind_mps(f) > 0 for f in missed.values())
    peers = [
        np.median(_abs_pct(pooled, which))
        for pooled in flights().values()
        for which in ("px4_errors", "ardupilot_errors")
    ]
    return (
        f"Ours has a median |error| of {medians}; the worst is "
        f"{_abs_pct(scored).max():.1f} % ({len(over_worst)} of the {len(scored)} scored flights "
        f"above {WORST_BOUND_PCT:.0f} % worst, {len(over_median)} above "
        f"{MEDIAN_BOUND_PCT:.0f} % median; {windy} of these in wind). The autopilots count "
        f"against the label and miss by {min(peers):.0f}–{max(peers):.0f} % at the median"
    )


def sigma() -> str:
    """The 1σ coverage per set and pooled, the 3σ coverage and the highest z."""
    per_set = ", ".join(
        f"{_within(pooled, 1):.0f} % ({SET_NAMES[half]})" for half, pooled in flights().items()
    )
    return (
        f"Within 1σ: {per_set}, {pooled_one_sigma()}; within 3σ: {_within(_all(), 3):.1f} %. "
        f"No estimate lies more than {np.max(_z(_all())):.1f}σ above the truth"
    )


def pooled_one_sigma() -> str:
    return f"{_within(_all(), 1):.0f} % over all {len(_all())} flights"


def set_one_sigma(half: str) -> str:
    return f"{_within(flights()[half], 1):.0f} % within 1σ"


def set_summary(half: str) -> str:
    """How many of a set's scored flights are within the per-flight bounds (and the largest
    median and worst), its 1σ coverage, its highest |error|/σ above the truth, and how many
    of its restarted flights stay within 3σ."""
    scored = _scored(flights()[half])
    medians = [_median_pct(f) for f in scored]
    worsts = [_worst_pct(f) for f in scored]
    within = sum(
        m <= MEDIAN_BOUND_PCT and w <= WORST_BOUND_PCT for m, w in zip(medians, worsts, strict=True)
    )
    every = "All" if within == len(scored) else f"{within} of the"
    judged = restarts()[half]
    sure, unsure = _sure_restarts(judged, ", ")
    return (
        f"{every} {len(scored)} within {MEDIAN_BOUND_PCT:.0f} % median (at most "
        f"{max(medians):.1f} %) and {WORST_BOUND_PCT:.0f} % worst (at most {max(worsts):.1f} %), "
        f"{_within(scored, 1):.0f} % within 1σ, at most {float(np.max(_z(scored))):.2f}σ above "
        f"the truth; restarted 90 s after take-off, {len(sure)} of its {len(judged)} flights "
        f"long enough stay within 3σ throughout{unsure}"
    )


def wind_medians() -> str:
    """The range of the per-flight median |error| in a strong wind and in the others."""
    windy: list[float] = []
    calm: list[float] = []
    for flight in _scored(_all()):
        median = _median_pct(flight)
        (windy if _wind_mps(flight) >= STRONG_WIND_MPS else calm).append(median)
    return (
        f"The {len(windy)} flights with a wind of {STRONG_WIND_MPS:.0f} m/s or more have "
        f"medians of {min(windy):.1f}–{max(windy):.1f} %; the other {len(calm)}, "
        f"{min(calm):.1f}–{max(calm):.1f} %"
    )


def flight_table(table: ModuleType) -> str:
    """docs/pack.md's per-flight table, rows as ``table`` (``scripts/pack_state_sitl.py``)
    prints them."""
    return _table(table.TABLE_HEADER, table.table_row, flights())


def restart_table(table: ModuleType) -> str:
    """docs/pack.md's table of the flights restarted 90 s after take-off, rows as ``table``
    prints them."""
    return _table(table.RESTART_HEADER, table.restart_row, restarts())


def _table(header: str, row: Callable[[Any, str], str], groups: Mapping[str, Any]) -> str:
    """``header`` and one ``row(item, set label)`` per item of each set of ``groups``."""
    rows = [row(item, half.replace("_", "-")) for half, items in groups.items() for item in items]
    return "\n".join([header, *rows])


def readme() -> str:
    """The README's sentence (a table cell: its pipes escaped): how many flights, the range of
    their real capacity (% of the label), and over the held-out sets' scored estimates the
    median |error| (%) of ours, the PX4-style figure and ArduPilot's."""
    shares = [
        100 * f.truth["battery"]["capacity_ah"] / f.truth["battery"]["labelled_capacity_ah"]
        for f in _all()
    ]
    held = _held_out()
    ours, px4, ardupilot = (
        np.median(_abs_pct(held, which)) for which in ("errors", "px4_errors", "ardupilot_errors")
    )
    return (
        f"on {len(_all())} ArduCopter SITL flights with packs of {min(shares):.0f}–"
        f"{max(shares):.0f} % of their label (told the resting curve, not the capacity), "
        f"endurance median \\|error\\| {ours:.1f} % on {len(held)} held-out flights "
        f"(PX4-style {px4:.0f} %, ArduPilot {ardupilot:.0f} %)"
    )


def _flight(name: str) -> PackFlight:
    """The flight ``name`` of ``split.json``, replayed."""
    [flight] = [f for f in _all() if f.name == name]
    return flight


def flight_worst(name: str, with_median: bool = True) -> str:
    """One flight's worst |error| (and median |error|), %."""
    flight = _flight(name)
    median = f", median {_median_pct(flight):.1f} %" if with_median else ""
    return f"worst {_worst_pct(flight):.1f} %{median}"


def flight_scores(name: str) -> str:
    """One flight's median |error| and 1σ coverage."""
    flight = _flight(name)
    return f"median {_median_pct(flight):.1f} %, {_within([flight], 1):.0f} % within 1σ"


#: Flights whose errors docs/pack.md names as lying mostly outside 1σ, and when after take-off
#: it reads their capacity (s).
OUTSIDE_ONE_SIGMA = ("pack_c100_r3", "pack_c65_r1_payload")
CAPACITY_READ_AFTER_S = 75.0


def outside_one_sigma() -> str:
    """Per flight of :data:`OUTSIDE_ONE_SIGMA`: its signed errors' 10th–90th percentile and
    median (%), its 1σ coverage, and the capacity learnt :data:`CAPACITY_READ_AFTER_S` after
    take-off (Ah ± 1σ) against the truth."""
    parts = []
    for name in OUTSIDE_ONE_SIGMA:
        flight = _flight(name)
        errors = flight.errors[np.isfinite(flight.errors)]
        low, median, high = (_signed(e, 1) for e in np.percentile(errors, [10, 50, 90]))
        read_s = flight.truth["events"]["takeoff_s"] + CAPACITY_READ_AFTER_S
        read = [e for e in flight.estimates if e.time_s <= read_s][-1]
        parts.append(
            f"{name}'s {low} to {high} % (10th–90th percentile, median {median} %; "
            f"{_within([flight], 1):.0f} % within 1σ; a capacity of {read.capacity_ah:.2f} ± "
            f"{read.capacity_sigma_ah:.2f} Ah {CAPACITY_READ_AFTER_S:.0f} s after take-off, "
            f"against {flight.truth['battery']['capacity_ah']:.2f})"
        )
    return " and ".join(parts)


@cache
def restarts() -> dict[str, tuple[Restart, ...]]:
    """Every flight of ``split.json`` long enough to judge, replayed as a daemon restarted
    under load (:func:`replay_restarted`; 8 s of CPU for the 22), per set."""
    vehicle = load_vehicle(VEHICLE)
    out: dict[str, tuple[Restart, ...]] = {}
    for half, pooled in flights().items():
        judged = (replay_restarted(FLIGHTS / f.name, vehicle) for f in pooled)
        out[half] = tuple(r for r in judged if r is not None)
    return out


def _signed(fraction: float, decimals: int = 0) -> str:
    """``fraction`` as a signed percentage (without the %), with the documents' minus sign."""
    return f"{100 * fraction:+.{decimals}f}".replace("-", "−")


def restarts_held_out() -> str:
    """How many of the first two held-out sets' restarts are within the test's bound at 60
    s, and the others' errors and largest |z| then."""
    judged = [r for half in ("held_out", "held_out_2") for r in restarts()[half]]
    near = [r for r in judged if abs(r.error_at) <= RESTART_BOUND]
    others = [r for r in judged if abs(r.error_at) > RESTART_BOUND]
    errors = " and ".join(_signed(r.error_at) for r in sorted(others, key=lambda r: -r.error_at))
    return (
        f"now {len(near)} of the {len(judged)}; the others are {errors} %, inside "
        f"{max(abs(r.z_at) for r in others):.1f}σ"
    )


def _sure_restarts(judged: Sequence[Restart], separator: str) -> tuple[list[Restart], str]:
    """The restarts that stay within 3σ throughout, and the others as text (each after
    ``separator``: its name and largest |z|)."""
    sure = [r for r in judged if r.worst_abs_z <= 3.0]
    unsure = "".join(
        f"{separator}{r.name} reaches {r.worst_abs_z:.2f}σ" for r in judged if r.worst_abs_z > 3.0
    )
    return sure, unsure


def restarts_sure() -> str:
    """How many restarted flights stay within 3σ throughout (and their largest |z|), those
    that do not, and the median |error| of all 60 s after the restart."""
    judged = [r for half in restarts().values() for r in half]
    sure, unsure = _sure_restarts(judged, "; ")
    median = 100 * float(np.median([abs(r.error_at) for r in judged]))
    return (
        f"{len(sure)} of the {len(judged)} restarted flights stay within "
        f"{max(r.worst_abs_z for r in sure):.1f}σ "
        f"throughout{unsure}; 60 s after the restart their median |error| is {median:.1f} %"
    )


def restart_scores(name: str) -> str:
    """One restarted flight's error at 60 s and its σ (% of the true time left)."""
    [restart] = [r for half in restarts().values() for r in half if r.name == name]
    return f"{_signed(restart.error_at)} % at 60 s (σ {100 * restart.error_at / restart.z_at:.0f} %"


#: Flights whose scores the misses of docs/pack.md quote.
QUOTED_FLIGHTS = (
    "pack_c75_r2_wind",
    "pack_c80_r2_soc85_wind",
    "pack_c100_r2_soc70_wind",
    "pack_c95_r3_wind",
)


#: Flights whose worst |error| docs/pack.md's misses quote (beyond the test's bound).
MISSED_WORST = ("pack_c90_r1_wind", "pack_c100_r3")


def generators(table: ModuleType) -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it (``scripts/figures.py`` registers them);
    ``table``: ``scripts/pack_state_sitl.py`` as a module, whose table rows and pooled lines
    some print."""
    out: dict[str, Callable[[], str]] = {
        "pack-sitl-pooled": lambda: "\n\n".join(
            table.pooled_line(half, pooled) for half, pooled in flights().items()
        ),
        "pack-sitl-charge-capacity": charge_and_capacity,
        "pack-sitl-ground-voltage": ground_voltage,
        "pack-sitl-warning": warning,
        "pack-sitl-endurance": endurance,
        "pack-sitl-sigma": sigma,
        "pack-sitl-pooled-1sigma": pooled_one_sigma,
        "pack-sitl-wind": wind_medians,
        "pack-sitl-table": partial(flight_table, table),
        "pack-sitl-restart-table": partial(restart_table, table),
        "pack-sitl-readme": readme,
    }
    out["pack-sitl-1sigma-held-out"] = partial(set_one_sigma, "held_out")
    out["pack-sitl-held-out-7"] = partial(set_summary, "held_out_7")
    out["pack-sitl-restarts-held-out"] = restarts_held_out
    out["pack-sitl-restarts-sure"] = restarts_sure
    out["pack-sitl-outside-1sigma"] = outside_one_sigma
    for half in ("tuning", "held_out_2", "held_out_6"):
        out[f"pack-sitl-1sigma-{half.replace('_', '-')}"] = partial(set_one_sigma, half)
    out["pack-sitl-restart-pack-c65-r1"] = partial(restart_scores, "pack_c65_r1")
    for name in QUOTED_FLIGHTS:
        out[f"pack-sitl-{name.replace('_', '-')}"] = partial(flight_scores, name)
    for name in MISSED_WORST:
        out[f"pack-sitl-worst-{name.replace('_', '-')}"] = partial(flight_worst, name)
    out["pack-sitl-worst-pack-c100-r2-soc70-wind"] = partial(
        flight_worst, "pack_c100_r2_soc70_wind", with_median=False
    )
    return out
