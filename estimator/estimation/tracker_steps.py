"""The online wind/mass tracker as the pipeline steps it: the flying readings queued since its
last step, one step per ``track_period_s`` of the sample clock (after the fusion step, so each
reading is fused with the effects that predicted it), and the effects to use after each step
(:meth:`~estimator.estimation.flight_power.FlightPower.choose`: tracked and file effects are
scored on the step's readings, as predicted before it).

Times on the sample clock (s).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from estimator.estimation.flight_power import FlightPower
from estimator.estimation.online_effects import OnlineEffects
from estimator.estimation.tracker_readings import TrackerReading
from estimator.physics.effects import Effect
from estimator.physics.vehicle import Vehicle


class TrackerSteps:
    """The tracker (None when the pipeline does not track effects) and its queue."""

    def __init__(
        self, vehicle: Vehicle, effects: tuple[Effect, ...], period_s: float, enabled: bool
    ) -> None:
        self._vehicle = vehicle
        self.period_s = period_s
        self.online = self._new(effects) if enabled else None
        self._bin: int | None = None  # period_s bin of the last step
        self._queue: list[TrackerReading] = []  # readings for the next step

    def _new(self, effects: tuple[Effect, ...]) -> OnlineEffects:
        vehicle = self._vehicle
        return OnlineEffects(
            vehicle.model,
            vehicle.mass_kg,
            effects,
            slow_error_fraction=vehicle.slow_error_fraction,
        )

    def queue(self, readings: Iterable[TrackerReading]) -> None:
        """Flying readings for the next step (dropped when nothing is tracked)."""
        if self.online is not None:
            self._queue += readings

    def step(self, time_s: float, power: FlightPower) -> tuple[Effect, ...] | None:
        """At ``time_s``, once per period, a step with the readings queued: the effects to use
        from now on; None without a step, when it used no reading (idle, vertical motion, bad
        values) or when those in use stay."""
        online = self.online
        if online is None or not self._queue:
            return None
        track_bin = math.floor(time_s / self.period_s)
        if track_bin == self._bin:
            return None
        self._bin = track_bin
        readings, self._queue = self._queue, []
        steps = online.steps
        online.update_readings(readings)
        if online.steps == steps:
            return None
        return power.choose(online)

    def restart_clock(self) -> None:
        """The autopilot's clock restarted: the queue and the period are forgotten."""
        self._queue, self._bin = [], None
        if self.online is not None:
            self.online.restart_clock()

    def renew(self, effects: tuple[Effect, ...]) -> None:
        """Continued from a snapshot with ``effects`` in use: a tracker that starts from them."""
        if self.online is not None:
            self.online = self._new(effects)
