"""The figures of the ArduCopter SITL recordings of ``replay/sitl`` in docs/sitl.md,
docs/residuals.md and README.md: each recording replayed with the SITL vehicle file, and what
``uav-energy residuals`` names on the effect recordings against their truth; the same for the
held-out flights of ``replay/sitl_held``.

The tables are functions of results the tests compute anyway (``tests/test_sitl_recordings.py``
replays every recording, ``tests/test_sitl_effects.py`` analyses and scores every effect
recording, ``tests/test_sitl_held_out.py`` the held-out ones), so those tests check them;
``scripts/figures.py`` registers them as blocks (:func:`recordings_generators`,
:func:`effects_generators`, :func:`held_generators`; and :func:`generators`, which
``tests/test_figures.py`` checks: the hover current and power of the payload and
heavier-airframe recordings, how many held-out flights there are, and the SITL vehicle file's
slow model error).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from fractions import Fraction
from functools import cache, partial
from pathlib import Path
from typing import Any

import numpy as np

from estimator.analysis.replay import FlightReplay, replay_log, summarize
from estimator.logs import FlightSeries, load_flights
from estimator.physics.vehicle import load_vehicle
from estimator.sitl.truth_check import Match, RecordingCheck, angle_deg, score_recording, span_s

REPO = Path(__file__).resolve().parent.parent
SITL_RECORDINGS = REPO / "replay" / "sitl"
SITL_VEHICLE = REPO / "config" / "vehicles" / "ardupilot_sitl_quad.toml"
#: The held-out effect flights, recorded after the rules were frozen (docs/residuals.md).
HELD_RECORDINGS = REPO / "replay" / "sitl_held"
#: The issue's limit for the held-out RMSE after selection, in noise floors.
HELD_FLOOR_LIMIT = 2.5
#: The held-out sets recorded after the residual loop's current rules were frozen: held23_*
#: after its rank test over 2.5 s blocks and the autopilot's wind in a window, rules chosen
#: on every recording up to held22_*, which are all development flights for them now.
HELD_FOR_CURRENT_RULES = ("held23",)
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


def _hover(name: str) -> tuple[FlightSeries, np.ndarray]:
    """A recording of ``replay/sitl`` and the mask of its hover samples between take-off and
    landing (its truth's events)."""
    events = _truth(name)["events"]
    flight = max(load_flights([SITL_RECORDINGS / name / "flight.tlog"]), key=len)
    t = flight.time_s
    hover = (
        (t > events["takeoff_s"])
        & (t < events["landed_s"])
        & (flight.speed_mps < HOVER_SPEED_MPS)
        & (np.abs(flight.vd_mps) < HOVER_CLIMB_MPS)
    )
    return flight, hover


def payload_hover_current() -> str:
    """docs/sitl.md: the median hover current (A) of :data:`PAYLOAD_RELEASE` without its load
    (after the release) and with it, their ratio, and the weights' ratio (its truth)."""
    truth = _truth(PAYLOAD_RELEASE)
    [payload] = [e for e in truth["effects"] if e["effect"] == "payload"]
    flight, hover = _hover(PAYLOAD_RELEASE)
    t = flight.time_s
    loaded = (t > payload["start_s"] + SWITCH_MARGIN_S) & (t < payload["end_s"] - SWITCH_MARGIN_S)
    empty = t > payload["end_s"] + SWITCH_MARGIN_S
    without_a, with_a = (float(np.median(flight.current_a[hover & m])) for m in (empty, loaded))
    weights = Fraction((truth["mass_kg"] + payload["mass_kg"]) / truth["mass_kg"])
    return (
        f"hover current rises from {without_a:.1f} A to {with_a:.1f} A "
        f"({100 * (with_a / without_a - 1):+.0f} %, the {weights.limit_denominator(10)} of "
        f"the weight)"
    )


def hover_power_rise(name: str) -> str:
    """docs/sitl.md, docs/residuals.md: the median hover power of the recording ``name`` over
    the clean legs' (%)."""
    clean_w, hover_w = (
        float(np.median(flight.power_w[hover])) for flight, hover in map(_hover, (CLEAN_LEGS, name))
    )
    return f"{100 * (hover_w / clean_w - 1):+.0f} %"


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
    and end within the limit. Only the sets of :data:`HELD_FOR_CURRENT_RULES` are held out for
    the current rules: the older ones were looked at before those were chosen."""
    parts = []
    for label, names in held_sets(checks).items():
        scores = [checks[name].score for name in names]
        within = sum(s.rmse_to_floor <= HELD_FLOOR_LIMIT for s in scores)
        ratios = [s.rmse_to_floor for s in scores]
        status = (
            "held out for the current rules"
            if label in HELD_FOR_CURRENT_RULES
            else "recorded for earlier rules"
        )
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


#: The recording whose held-out RMSE after docs/residuals.md quotes (the window end earned).
ONSET_ON_CIRCLES = "wind_onset_circles"


def effects_onset_circles(checks: Mapping[str, RecordingCheck]) -> str:
    """docs/residuals.md: :data:`ONSET_ON_CIRCLES`'s held-out RMSE after (W)."""
    return f"{checks[ONSET_ON_CIRCLES].score.rmse_after_w:.1f} W"


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


# --- the held-out misses' candidates (docs/residuals.md, "Why the misses miss") -----------------

#: Held-out wind episodes whose windowed wind is found but not proven.
HELD_WINDOWS = ("held_gust_60s", "held2_gust_90s_hovers", "held3_gust_75s_vertical")
#: Held-out wind episodes the autopilot's wind does not prove either.
HELD_AUTOPILOT_WIND = ("held2_gust_70s_circles", "held2_gust_85s_legs")
#: Held-out flights on which no candidate gains much: a short episode in a hover, a short one
#: on legs, two episodes from opposite directions.
HELD_NO_GAIN = ("held_gust_30s_hover", "held3_gust_45s_legs", "held_two_gusts")
#: The held-out onset among climbs that falls short of z 3, and its candidates that find it.
HELD_SHORT_ONSET, ONSET_CANDIDATES = "held_onset_vertical", ("wind (window)", "wind (autopilot)")


def _first_step(check: RecordingCheck) -> list[dict[str, Any]]:
    """The candidates of the selection's first step (``residuals --json``)."""
    return [c for c in check.summary["selection"] if c["step"] == 1]


def _candidate(check: RecordingCheck, label: str) -> dict[str, Any]:
    """The first step's candidate ``label``."""
    [row] = [c for c in _first_step(check) if c["candidate"] == label]
    return row


def _range(values: Iterable[float], spec: str) -> str:
    """The range of ``values`` formatted by ``spec`` ("a–b", or "a" when both read the same)."""
    low, high = (format(v, spec) for v in (min(values), max(values)))
    return low if low == high else f"{low}–{high}"


def _blocks_within(check: RecordingCheck, start_s: float, end_s: float) -> int:
    """How many of the rank test's blocks have samples within ``start_s``..``end_s``."""
    samples = check.result.samples
    inside = (samples.state.time_s >= start_s) & (samples.state.time_s <= end_s)
    return len(np.unique(samples.block[inside]))


def _wind_episode(speed_mps: float, from_deg: float, start_s: float, end_s: float) -> str:
    return f"{speed_mps:.1f} m/s from {from_deg:.0f}°, {start_s:.0f}–{end_s:.0f} s"


def held_windows(checks: Mapping[str, RecordingCheck]) -> str:
    """Per :data:`HELD_WINDOWS` flight: its windowed wind candidate against the true episode,
    the candidate's held-out gain (%), z and the rank test's blocks within its window."""
    parts = []
    for name in HELD_WINDOWS:
        check = checks[name]
        row = _candidate(check, "wind (window)")
        params = row["params"]
        [true] = [e for e in check.score.truth.effects if e.kind == "wind"]
        named = _wind_episode(
            params["speed_mps"], params["from_deg"], params["at_s"], params["until_s"]
        )
        truth = _wind_episode(
            true.values["speed_mps"], true.values["from_deg"], true.start_s, true.end_s
        )
        blocks = _blocks_within(check, params["at_s"], params["until_s"])
        parts.append(
            f"{name}: {named} (truth {truth}) cuts the held-out error by "
            f"{row['gain_pct']:.0f} % at z {row['z']:.1f} over {blocks} blocks"
        )
    return "; ".join(parts)


def held_autopilot_wind(checks: Mapping[str, RecordingCheck]) -> str:
    """Per :data:`HELD_AUTOPILOT_WIND` flight: the autopilot's wind's held-out gain and z."""
    rows = {name: _candidate(checks[name], "wind (autopilot)") for name in HELD_AUTOPILOT_WIND}
    return ", ".join(
        f"{name} {row['gain_pct']:.0f} % at z {row['z']:.1f}" for name, row in rows.items()
    )


def held_no_gain(checks: Mapping[str, RecordingCheck], name: str) -> str:
    """A held-out flight that names nothing: the highest z of a candidate that gains (or that
    none gains) and its held-out RMSE in noise floors."""
    gaining = [c["z"] for c in _first_step(checks[name]) if c["gain_pct"] > 0]
    best = f"no candidate gains at z above {max(gaining):.1f}" if gaining else "no candidate gains"
    return f"{best}, {checks[name].score.rmse_to_floor:.1f} noise floors left"


def held_short_onset(checks: Mapping[str, RecordingCheck]) -> str:
    """:data:`HELD_SHORT_ONSET`'s :data:`ONSET_CANDIDATES`: their held-out gains (%) and z."""
    rows = [_candidate(checks[HELD_SHORT_ONSET], label) for label in ONSET_CANDIDATES]
    gains, zs = ([row[key] for row in rows] for key in ("gain_pct", "z"))
    return f"gains {_range(gains, '.0f')} %, at z {_range(zs, '.2f')}"


# --- the blocks -----------------------------------------------------------------------------------


@cache
def replays() -> dict[str, FlightReplay]:
    """Every recording of ``replay/sitl`` replayed with the SITL vehicle file."""
    vehicle = load_vehicle(SITL_VEHICLE)
    logs = {s: SITL_RECORDINGS / s / "flight.tlog" for s in recordings()}
    return {s: replay_log(log, vehicle) for s, log in logs.items()}


def slow_error() -> str:
    """The SITL vehicle file's slow model error, % of its hover power (measured on its fit
    flights; ``tests/test_sitl_effects.py`` checks it against them)."""
    return f"{100 * load_vehicle(SITL_VEHICLE).slow_error_fraction:.1f} %"


Checks = Mapping[str, RecordingCheck]


def _on(checks: Callable[[], Checks], figure: Callable[[Checks], str]) -> Callable[[], str]:
    """What ``figure`` prints of the checks ``checks`` gives."""
    return lambda: figure(checks())


def recordings_generators() -> dict[str, Callable[[], str]]:
    """Block name → the function that prints it, of the recordings replayed
    (:func:`replays`; ``tests/test_sitl_recordings.py`` checks them)."""
    return {
        "sitl-recordings-table": lambda: recordings_table(replays()),
        "sitl-hexa-energy": lambda: hexa_energy(replays()),
        "sitl-wind-cost": lambda: wind_cost(replays()),
    }


def effects_generators() -> dict[str, Callable[[], str]]:
    """The blocks of the effects named on the recordings (:func:`effect_checks`;
    ``tests/test_sitl_effects.py`` checks them)."""
    figures: dict[str, Callable[[Checks], str]] = {
        "sitl-effects-table": effects_table,
        "sitl-effects-right": effects_right,
        "sitl-effects-floors": effects_floors,
        "sitl-effects-clean": effects_clean,
        "sitl-effects-wind": effects_wind,
        "sitl-effects-payload": effects_payload,
        "sitl-effects-turn": effects_turn,
        "sitl-effects-heavy": effects_heavy,
        "sitl-effects-onset-circles": effects_onset_circles,
    }
    return {name: _on(effect_checks, figure) for name, figure in figures.items()}


def held_generators() -> dict[str, Callable[[], str]]:
    """The blocks of the effects named on the held-out flights (:func:`held_checks`;
    ``tests/test_sitl_held_out.py`` checks them)."""
    figures: dict[str, Callable[[Checks], str]] = {
        "sitl-held-table": partial(effects_table, recordings=HELD_RECORDINGS),
        "sitl-held-floors": effects_floors,
        "sitl-held-summary": held_summary,
        "sitl-held-windows": held_windows,
        "sitl-held-autopilot-wind": held_autopilot_wind,
        "sitl-held-short-onset": held_short_onset,
    }
    for flight in HELD_NO_GAIN:
        figures[f"sitl-held-no-gain-{flight.replace('_', '-')}"] = partial(
            held_no_gain, name=flight
        )
    return {name: _on(held_checks, figure) for name, figure in figures.items()}


def generators() -> dict[str, Callable[[], str]]:
    """The blocks ``tests/test_figures.py`` checks."""
    out = {"sitl-payload-hover-current": payload_hover_current, "sitl-held-count": held_count}
    for recording in (PAYLOADS[0], HEAVY_AIRFRAME):
        out[f"sitl-hover-power-{recording.replace('_', '-')}"] = partial(
            hover_power_rise, recording
        )
    out["sitl-slow-error"] = slow_error
    return out
