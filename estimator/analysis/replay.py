"""Replay: a recorded flight through the daemon's own pipeline
(:class:`~estimator.estimation.pipeline.Pipeline`).

A log is read by :func:`estimator.logs.iter_samples` (format by content) and every sample is
fed, in the log's order and on the log's own clock, to one ``Pipeline`` object — the class
the daemon uses, with the same settings — so a replay gives exactly the estimates the daemon
would have published. No wall clock is read here: pacing (``--speed``) and timing belong to
the caller.

Power error is measured where the model is meant to hold: at each battery sample with a
current reading while the vehicle is *airborne* (armed, more than
:data:`~estimator.estimation.airborne.AIRBORNE_ALT_M` above home and drawing more than idle
power, the online tracker's 30 % of the model's hover power; a log without arming state or
altitude is judged on the rest): the measured V·I against the model power in force when that
reading arrived (:class:`~estimator.estimation.pipeline.PowerReading`) — a prediction, never
informed by the reading it is scored on (the pipeline fuses readings and tracks wind and mass
only after). Energies integrate both powers over the same airborne intervals (gaps longer than
:data:`MAX_GAP_S` are not integrated).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from estimator.estimation.airborne import AIRBORNE_ALT_M
from estimator.estimation.estimate import Estimate, PowerReading
from estimator.estimation.online_settings import OnlineSettings
from estimator.estimation.pipeline import Pipeline
from estimator.estimation.pipeline_settings import PipelineSettings
from estimator.estimation.return_home import MissionSample
from estimator.logs import SampleStream, iter_samples
from estimator.physics.vehicle import Vehicle
from estimator.telemetry.samples import BatterySample, Sample

#: Below this measured power (W) a MAPE term is not formed (a pack on the bench).
MAPE_FLOOR_W = 1.0
#: Intervals between power points longer than this (s) are not integrated (link dropouts).
MAX_GAP_S = 5.0

FloatArray = NDArray[np.float64]


@dataclass
class PowerTrace:
    """At each battery sample with a current reading: time (s), measured power and the model
    power in force when it arrived (W), the armed state then (1/0, NaN unknown) and the
    height over home (m, NaN unknown)."""

    time_s: list[float] = field(default_factory=list)
    measured_w: list[float] = field(default_factory=list)
    model_w: list[float] = field(default_factory=list)
    armed: list[float] = field(default_factory=list)
    alt_m: list[float] = field(default_factory=list)
    #: Measured power (W) below which the motors are idling: not flight, whatever the flags.
    idle_below_w: float = 0.0

    def extend(self, readings: Iterable[PowerReading]) -> None:
        """Add the readings the pipeline scored in a period (see :class:`PowerReading`)."""
        for r in readings:
            if not math.isfinite(r.model_w):
                continue
            self.time_s.append(r.time_s)
            self.measured_w.append(r.measured_w)
            self.model_w.append(r.model_w)
            self.armed.append(math.nan if r.armed is None else float(r.armed))
            self.alt_m.append(math.nan if r.alt_m is None else r.alt_m)

    def airborne(self) -> NDArray[np.bool_]:
        """Armed, above :data:`~estimator.estimation.airborne.AIRBORNE_ALT_M` and drawing more
        than ``idle_below_w`` (a barometer drifting on the ground while the motors spin up at
        arming is not flight).
        A log that never gives the armed state (or the altitude) is judged on the rest."""
        armed, high, powered = self.conditions()
        return armed & high & powered

    def conditions(self) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
        """Per reading, the three tests of :meth:`airborne`: armed (all true when the log
        never gives the state), high (likewise for the altitude), powered."""
        armed = np.asarray(self.armed, dtype=float)
        alt = np.asarray(self.alt_m, dtype=float)
        powered = np.asarray(self.measured_w, dtype=float) >= self.idle_below_w
        every = np.ones(len(powered), dtype=bool)
        armed_ok = armed == 1.0 if np.isfinite(armed).any() else every
        high = alt > AIRBORNE_ALT_M if np.isfinite(alt).any() else every
        return armed_ok, high, powered

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
        """(time, measured, model, airborne)."""
        return (
            np.asarray(self.time_s, dtype=float),
            np.asarray(self.measured_w, dtype=float),
            np.asarray(self.model_w, dtype=float),
            self.airborne(),
        )


@dataclass
class FlightReplay:
    """What one log gave: every estimate, the power trace, and the reader's counters;
    ``missing``: what the log lacks for an estimate, as its reader says (None: nothing, or
    the reader cannot tell)."""

    name: str
    path: Path | None
    format: str
    estimates: list[Estimate]
    power: PowerTrace
    samples: int
    skipped: int = 0
    bad_frames: int = 0
    truncated: bool = False
    missing: str | None = None


@dataclass(frozen=True)
class Summary:
    """Figures of one flight or of several together (see the module docstring)."""

    messages: int
    duration_s: float
    airborne_s: float
    power_points: int
    power_rmse_w: float | None
    power_mape_pct: float | None
    energy_measured_wh: float
    energy_predicted_wh: float

    def as_dict(self) -> dict[str, float | int | None]:
        return asdict(self)


def run(
    samples: Iterable[Sample | MissionSample],
    pipeline: Pipeline,
    on_sample: Callable[[int], None] | None = None,
) -> tuple[list[Estimate], PowerTrace, int]:
    """Feed samples to the pipeline in order: (estimates, power trace, samples fed).

    ``on_sample(n)`` is called after every sample (progress display).
    """
    estimates: list[Estimate] = []
    idle_fraction = OnlineSettings().min_power_fraction_of_hover  # the tracker's idle rule
    power = PowerTrace(idle_below_w=idle_fraction * pipeline.vehicle.model.hover_power_w)
    count = 0
    for sample in samples:
        estimate = pipeline.process(sample)
        if estimate is not None:
            estimates.append(estimate)
            power.extend(pipeline.readings)
        count += 1
        if on_sample is not None:
            on_sample(count)
    last = pipeline.flush()  # the log ends inside a period: close it
    if last is not None:
        estimates.append(last)
        power.extend(pipeline.readings)
    return estimates, power, count


def replay_stream(
    stream: SampleStream,
    vehicle: Vehicle,
    name: str,
    settings: PipelineSettings | None = None,
    samples: Iterable[Sample | MissionSample] | None = None,
    on_sample: Callable[[int], None] | None = None,
    pipeline: Pipeline | None = None,
) -> FlightReplay:
    """Replay one opened log through a fresh pipeline (or ``pipeline``, fresh, whose final
    state the caller reads). ``samples`` replaces the stream as the source of samples (e.g. a
    paced or observed view of it); counters still come from ``stream``."""
    estimates, power, count = run(
        stream if samples is None else samples,
        Pipeline(vehicle, settings) if pipeline is None else pipeline,
        on_sample,
    )
    return FlightReplay(
        name=name,
        path=stream.path,
        format=stream.format,
        estimates=estimates,
        power=power,
        samples=count,
        skipped=stream.skipped,
        bad_frames=stream.bad_frames,
        truncated=stream.truncated,
        missing=stream.missing,
    )


def replay_log(
    path: str | Path,
    vehicle: Vehicle,
    settings: PipelineSettings | None = None,
    fmt: str = "auto",
) -> FlightReplay:
    """Replay one log file (format by content unless ``fmt`` says)."""
    path = Path(path)
    stream = iter_samples(path, fmt, vehicle.input_limits())
    return replay_stream(stream, vehicle, path.stem, settings)


def summarize(flights: Iterable[FlightReplay]) -> Summary:
    """Figures over one or several flights (errors pooled over all their airborne points)."""
    flights = list(flights)
    sq_err: list[FloatArray] = []
    pct_err: list[FloatArray] = []
    energy_measured_wh = energy_predicted_wh = airborne_s = duration_s = 0.0
    for flight in flights:
        t, measured, model, airborne = flight.power.arrays()
        sq_err.append((model[airborne] - measured[airborne]) ** 2)
        valid = airborne & (measured > MAPE_FLOOR_W)
        pct_err.append(np.abs(model[valid] - measured[valid]) / measured[valid] * 100.0)
        if len(t) > 1:
            dt = np.diff(t)
            use = airborne[:-1] & airborne[1:] & (dt > 0) & (dt <= MAX_GAP_S)
            airborne_s += float(np.sum(dt[use]))
            energy_measured_wh += float(np.sum(0.5 * (measured[1:] + measured[:-1])[use] * dt[use]))
            energy_predicted_wh += float(np.sum(0.5 * (model[1:] + model[:-1])[use] * dt[use]))
        duration_s += _duration_s(flight)
    sq = np.concatenate(sq_err) if sq_err else np.empty(0)
    pct = np.concatenate(pct_err) if pct_err else np.empty(0)
    return Summary(
        messages=sum(f.samples for f in flights),
        duration_s=duration_s,
        airborne_s=airborne_s,
        power_points=len(sq),
        power_rmse_w=float(np.sqrt(np.mean(sq))) if len(sq) else None,
        power_mape_pct=float(np.mean(pct)) if len(pct) else None,
        energy_measured_wh=energy_measured_wh / 3600.0,
        energy_predicted_wh=energy_predicted_wh / 3600.0,
    )


def _duration_s(flight: FlightReplay) -> float:
    """Log time spanned by the estimates (s), summed over autopilot boots."""
    times = np.asarray([e.time_s for e in flight.estimates], dtype=float)
    if len(times) < 2:
        return 0.0
    steps = np.diff(times)
    return float(np.sum(steps[steps > 0]))


def with_batteries(
    samples: Iterable[Sample | MissionSample], batteries: list[BatterySample]
) -> Iterator[Sample | MissionSample]:
    """``samples`` unchanged, with the battery readings copied into ``batteries`` as they
    pass (a replay that needs them afterwards reads the log once)."""
    for sample in samples:
        if isinstance(sample, BatterySample):
            batteries.append(sample)
        yield sample


def no_airborne_reason(flight: FlightReplay, stream: SampleStream, vehicle_name: str) -> str:
    """Why a replay of ``stream`` with no airborne time had none (no two successive power
    readings airborne as :meth:`PowerTrace.airborne` judges: armed, above
    :data:`~estimator.estimation.airborne.AIRBORNE_ALT_M`, above idle power): the reader's
    ``missing``, else which of these never held, with the message types the log has."""
    if stream.missing is not None:
        return stream.missing
    power = flight.power
    measured = np.asarray(power.measured_w, dtype=float)
    armed_ok, high, powered = power.conditions()
    if not len(measured):
        why = "no power reading (a battery current with a velocity) reached the estimator"
    elif not armed_ok.any():
        why = "never armed while the battery reported"
    elif not (armed_ok & high).any():
        why = f"never more than {AIRBORNE_ALT_M:.0f} m above home while armed (did not fly)"
    elif not (flying := armed_ok & high & powered).any():
        top = float(np.nanmax(measured[armed_ok & high]))
        why = (
            f"power never above idle while armed and above {AIRBORNE_ALT_M:.0f} m ({top:.0f} W "
            f"at most, idle below {power.idle_below_w:.0f} W for the '{vehicle_name}' vehicle)"
        )
    else:
        n = np.count_nonzero(flying)
        why = f"airborne for {n} isolated power reading{'s' if n > 1 else ''} only"
    types = sorted(stream.message_types)
    return f"{why}; it has {', '.join(types) if types else 'none of the types read'}"
