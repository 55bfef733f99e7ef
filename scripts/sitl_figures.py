"""The figures of the ArduCopter SITL recordings of ``replay/sitl`` in docs/sitl.md,
docs/residuals.md and README.md: each recording replayed with the SITL vehicle file, and what
``uav-energy residuals`` names on the effect recordings against their truth; the same for the
held-out flights of ``replay/sitl_held``.

The tables are functions of results the tests compute anyway (``tests/test_sitl_recordings.py``
replays every recording, ``tests/test_sitl_effects.py`` analyses and scores every effect
recording), so those tests check them; ``scripts/figures.py`` registers them as blocks.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from fractions import Fraction
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from estimator.analysis.replay import FlightReplay, summarize
from estimator.logs import load_flights
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.truth_check import Match, RecordingCheck, angle_deg, score_recording, span_s

REPO = Path(__file__).resolve().parent.parent
SITL_RECORDINGS = REPO / "replay" / "sitl"
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: The held-out effect flights, recorded after the rules were frozen (docs/residuals.md).
HELD_RECORDINGS = REPO / "replay" / "sitl_held"
#: The issue's limit for the held-out RMSE after selection, in noise floors.
HELD_FLOOR_LIMIT = 2.5
#: The clean recordings the SITL vehicle file was fitted on.
CLEAN_RECORDINGS = ("clean_legs", "clean_circles", "clean_mission")
#: Recordings of ``replay/sitl`` flown for something else than effects.
NOT_EFFECT_RECORDINGS = {"battery_reserve"}
#: README.md's wind bullet: a wind all flight, switched on (also during circles), stopped.
STEADY_WINDS = ("wind_constant", "wind_onset", "wind_onset_circles", "wind_stop")
#: README.md's payload bullet: carried from take-off, released, with a wind.
PAYLOADS = ("payload_takeoff", "payload_release", "payload_wind")
#: README.md's turning wind and its missed airframe.
TURNING_WIND, HEAVY_AIRFRAME = "wind_turn", "heavy_quad"


def recordings(folder: Path = SITL_RECORDINGS) -> list[str]:
    """The recordings of ``folder`` (each flown once, with its truth)."""
    return sorted(p.parent.name for p in folder.glob("*/truth.json"))


def _truth(name: str, recordings: Path = SITL_RECORDINGS) -> dict[str, Any]:
    return dict(json.loads((recordings / name / "truth.json").read_text()))


def recordings_table(replays: Mapping[str, FlightReplay]) -> str:
    """docs/sitl.md's table: per recording its airborne span (s, autopilot clock) and effects
    (the truth's description), whether it has a DataFlash log, its size (MB), and its tlog
    replayed with the SITL vehicle file: power RMSE against V·I (W), energy measured / model
    (Wh)."""
    lines = [
        "| scenario | airborne s | effects (truth) | .BIN | MB "
        "| power RMSE W | energy measured / model Wh |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, flight in replays.items():
        folder = SITL_RECORDINGS / name
        truth, s = _truth(name), summarize([flight])
        events = truth["events"]
        size_mb = sum(f.stat().st_size for f in folder.iterdir() if f.is_file()) / 1e6
        dataflash = "yes" if (folder / "flight.BIN").is_file() else ""
        lines.append(
            f"| {name} | {events['takeoff_s']:.0f}–{events['landed_s']:.0f} "
            f"| {truth['description']} | {dataflash} | {size_mb:.2f} | {s.power_rmse_w:.1f} "
            f"| {s.energy_measured_wh:.2f} / {s.energy_predicted_wh:.2f} |"
        )
    return "\n".join(lines)


#: docs/sitl.md: SITL's built-in hexa, and the steady wind compared with the clean legs.
HEXA, STEADY_WIND, CLEAN_LEGS = "hexa_clean", "wind_constant", "clean_legs"


def hexa_energy(replays: Mapping[str, FlightReplay]) -> str:
    """docs/sitl.md: how close the SITL quad's vehicle file predicts the hexa's energy (%)."""
    s = summarize([replays[HEXA]])
    return f"{100 * abs(s.energy_predicted_wh / s.energy_measured_wh - 1):.1f} %"


def wind_cost(replays: Mapping[str, FlightReplay]) -> str:
    """docs/sitl.md: the steady wind's measured energy against the clean legs' (%)."""
    wind, clean = (
        summarize([replays[name]]).energy_measured_wh for name in (STEADY_WIND, CLEAN_LEGS)
    )
    return f"{STEADY_WIND} {100 * (wind / clean - 1):+.1f} % energy over {CLEAN_LEGS}"


#: docs/sitl.md's payload figure: the recording that releases its load in a hover.
PAYLOAD_RELEASE = "payload_release"
#: A hover, for that figure: horizontal and vertical speed below these (m/s).
HOVER_SPEED_MPS, HOVER_CLIMB_MPS = 0.3, 0.2
#: Seconds left out of the hovers on either side of the truth's payload switches (the
#: gripper's jaw opens about 1 s after the release's acknowledgement).
SWITCH_MARGIN_S = 3.0


def payload_hover_current() -> str:
    """docs/sitl.md: the median hover current (A) of :data:`PAYLOAD_RELEASE` without its load
    (after the release) and with it, their ratio, and the weights' ratio (its truth)."""
    truth = _truth(PAYLOAD_RELEASE)
    [payload] = [e for e in truth["effects"] if e["effect"] == "payload"]
    tlog = SITL_RECORDINGS / PAYLOAD_RELEASE / "flight.tlog"
    flight = max(load_flights([tlog]), key=len)
    t, events = flight.time_s, truth["events"]
    hover = (
        (t > events["takeoff_s"])
        & (t < events["landed_s"])
        & (flight.speed_mps < HOVER_SPEED_MPS)
        & (np.abs(flight.vd_mps) < HOVER_CLIMB_MPS)
    )
    loaded = (t > payload["start_s"] + SWITCH_MARGIN_S) & (t < payload["end_s"] - SWITCH_MARGIN_S)
    empty = t > payload["end_s"] + SWITCH_MARGIN_S
    without_a, with_a = (float(np.median(flight.current_a[hover & m])) for m in (empty, loaded))
    weights = Fraction((truth["mass_kg"] + payload["mass_kg"]) / truth["mass_kg"])
    return (
        f"hover current rises from {without_a:.1f} A to {with_a:.1f} A "
        f"({100 * (with_a / without_a - 1):+.0f} %, the {weights.limit_denominator(10)} of "
        f"the weight)"
    )


def effect_scenarios() -> list[str]:
    return [s for s in recordings() if s not in NOT_EFFECT_RECORDINGS]


def _checks(folder: Path, names: list[str]) -> dict[str, RecordingCheck]:
    """``uav-energy residuals`` on each recording ``names`` of ``folder``, scored against its
    truth (≈ 5 s of CPU a recording)."""
    vehicle = load_vehicle(SITL_VEHICLE)
    return {s: score_recording(folder / s, vehicle) for s in names}


@cache
def effect_checks() -> dict[str, RecordingCheck]:
    """:func:`_checks` of the effect recordings of ``replay/sitl``."""
    return _checks(SITL_RECORDINGS, effect_scenarios())


@cache
def held_checks() -> dict[str, RecordingCheck]:
    """:func:`_checks` of the held-out flights of ``replay/sitl_held``."""
    return _checks(HELD_RECORDINGS, recordings(HELD_RECORDINGS))


def held_sets(names: Iterable[str]) -> dict[str, list[str]]:
    """The held-out flights ``names`` per set (the name before the first "_": ``held``,
    ``held2``, …), newest set first."""
    sets: dict[str, list[str]] = {}
    for name in names:
        sets.setdefault(name.split("_")[0], []).append(name)
    return dict(sorted(sets.items(), key=lambda kv: (len(kv[0]), kv[0]), reverse=True))


def held_count() -> str:
    """README.md: how many held-out flights ``replay/sitl_held`` has, in how many sets."""
    sets = held_sets(recordings(HELD_RECORDINGS))
    return f"{sum(len(names) for names in sets.values())} flights in {len(sets)} sets"


def held_summary(checks: Mapping[str, RecordingCheck]) -> str:
    """Per held-out set (:func:`held_sets`), newest first, how many name a true effect first
    and end within the limit. Only the newest set is held out for the current rules: the older
    ones were looked at before those were chosen."""
    parts = []
    for k, (label, names) in enumerate(held_sets(checks).items()):
        scores = [checks[name].score for name in names]
        within = sum(s.rmse_to_floor <= HELD_FLOOR_LIMIT for s in scores)
        ratios = [s.rmse_to_floor for s in scores]
        status = "held out for the current rules" if k == 0 else "recorded for earlier rules"
        parts.append(
            f"{label}_* ({status}): the first named effect is right on "
            f"{sum(s.first_right for s in scores)} of {len(scores)}, the held-out RMSE after "
            f"within {HELD_FLOOR_LIMIT:g} noise floors on {within} of {len(scores)} "
            f"({min(ratios):.2f}–{max(ratios):.2f}×)"
        )
    return "; ".join(parts)


def effects_table(checks: Mapping[str, RecordingCheck], recordings: Path = SITL_RECORDINGS) -> str:
    """docs/residuals.md's table: per recording of ``recordings`` its truth (the recording's
    own description), what was named, whether the first named is right, held-out RMSE and its
    noise floor (W)."""
    lines = [
        "| flight | truth | named | right? | held-out RMSE before → after (W) "
        "| noise floor (W) | × floor |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, check in checks.items():
        score, summary = check.score, check.summary
        named = "; then ".join(e["description"] for e in summary["effects"]) or "nothing"
        lines.append(
            f"| {name} | {_truth(name, recordings)['description']} | {named} "
            f"| {'yes' if score.first_right else '**no**'} "
            f"| {score.rmse_before_w:.1f} → {score.rmse_after_w:.1f} "
            f"| {score.noise_floor_w:.1f} | {score.rmse_to_floor:.2f} |"
        )
    return "\n".join(lines)


def effects_right(checks: Mapping[str, RecordingCheck]) -> str:
    right = sum(c.score.first_right for c in checks.values())
    return f"names the right effect first on {right} of {len(checks)}"


def effects_clean(checks: Mapping[str, RecordingCheck]) -> str:
    """README.md: the clean recordings (no effect in their truth) that name nothing, and how
    many of them the SITL vehicle file was fitted on."""
    clean = [name for name, c in checks.items() if not c.score.truth.effects]
    silent = [name for name in clean if not checks[name].score.matches]
    fitted = [name for name in clean if name in CLEAN_RECORDINGS]
    every = "All" if len(silent) == len(clean) else f"{len(silent)} of the"
    return (
        f"{every} {len(clean)} clean flights name nothing ({', '.join(clean)}); {len(fitted)} "
        f"of them are the flights the SITL vehicle file was fitted on (in-sample)"
    )


def effects_floors(checks: Mapping[str, RecordingCheck]) -> str:
    """The held-out RMSE over the noise floor: on the clean flights, on the others."""
    spans = []
    for clean in (True, False):
        ratios = [
            c.score.rmse_to_floor for c in checks.values() if clean != bool(c.score.truth.effects)
        ]
        spans.append(f"{min(ratios):.2f}–{max(ratios):.2f}")
    return f"clean flights at {spans[0]}× their noise floor, the others at {spans[1]}×"


def _wind_misfit(check: RecordingCheck, match: Match) -> tuple[float, float, float]:
    """A named wind against the true one it matched: speed (m/s), direction (°) and the
    larger of the start and end errors (s, within the analysed span)."""
    truth, effect, params = check.score.truth, match.matched, match.params
    assert effect is not None
    named = span_s(truth, params.get("at_s"), params.get("until_s"))
    true = span_s(truth, effect.start_s, effect.end_s)
    return (
        abs(params["speed_mps"] - effect.values["speed_mps"]),
        angle_deg(params["from_deg"], effect.values["from_deg"]),
        max(abs(a - b) for a, b in zip(named, true, strict=True)),
    )


def effects_wind(checks: Mapping[str, RecordingCheck]) -> str:
    """README.md: the first named wind of each :data:`STEADY_WINDS` recording against the
    truth, the largest error of each kind."""
    right = [checks[n] for n in STEADY_WINDS if checks[n].score.first_right]
    misfits = [_wind_misfit(c, c.score.matches[0]) for c in right]
    speed, angle, time = (max(m[i] for m in misfits) for i in range(3))
    named = "" if len(right) == len(STEADY_WINDS) else f"{len(right)} of {len(STEADY_WINDS)} "
    return f"{named}within {speed:.1f} m/s, {angle:.0f}° and {time:.0f} s of the truth"


def effects_payload(checks: Mapping[str, RecordingCheck]) -> str:
    """README.md: the mass named on each :data:`PAYLOADS` recording, for the true payload."""
    masses, truths = [], set()
    for name in PAYLOADS:
        for match in checks[name].score.matches:
            if match.matched is not None and match.matched.kind == "payload":
                masses.append(match.params["delta_kg"])
                truths.add(match.matched.values["mass_kg"])
    [truth] = truths
    return f"{min(masses):+.2f}–{max(masses):.2f} kg for {truth:g} kg"


def effects_turn(checks: Mapping[str, RecordingCheck]) -> str:
    """README.md: the turning wind named through the autopilot's estimate, against the truth
    (its speed and the time it turns)."""
    check = checks[TURNING_WIND]
    first, second = (m.params for m in check.score.matches[:2])
    until = f"until {first['until_s']:.0f} s"
    legs = [f"{p['speed_mps']:.1f} m/s from {p['from_deg']:.0f}°" for p in (first, second)]
    turned_s = min(e.start_s for e in check.score.truth.effects if e.start_s)
    speeds = "/".join(
        f"{v:g}" for v in sorted({e.values["speed_mps"] for e in check.score.truth.effects})
    )
    truth = f"truth {speeds} m/s, {turned_s:.1f} s"
    return f"scaled by {first['scale']:.2f} ({legs[0]} {until}, then {legs[1]}; {truth})"


def effects_heavy(checks: Mapping[str, RecordingCheck]) -> str:
    """README.md: what the other airframe's extra weight was read as."""
    [match] = checks[HEAVY_AIRFRAME].score.matches
    return f"{match.params['delta_kg']:+.2f} kg"
