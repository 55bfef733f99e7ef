"""The online tracker's recent mass estimates, to go back to when a wind change it did not see
comes to light (:mod:`estimator.estimation.online_effects`).

While the wind changes unseen (its report still lagging, no alarm in the power), the filter
reads the change of power against the old wind, and in part as mass: a gust's onset on a leg
or in a hover read as a mass step of 0.2-0.3 kg, held at a 1σ of 0.04-0.06 kg for 10-24 s
after the autopilot's report had shown the change (ArduCopter SITL, held17_gust_across_hover
and held3_gust_45s_legs). When the report shows the change
(:meth:`~estimator.estimation.autopilot_wind.AutopilotWind.saw_a_change`), the mass learnt
since the change likely began was learnt against the wrong wind: the tracker goes back to the
mass and variance it held ``autopilot_wind_mass_back_s`` before (:meth:`MassHistory.at`).

Units: s (the autopilot's clock), kg, kg².
"""

from __future__ import annotations

from collections import deque


class MassHistory:
    """The mass difference (kg) and its variance (kg²) after each tracker step, kept for
    ``span_s`` (s) back from the latest."""

    def __init__(self, span_s: float) -> None:
        self.span_s = span_s
        self._steps: deque[tuple[float, float, float]] = deque()

    def add(self, time_s: float, mass_kg: float, var_kg2: float) -> None:
        """Keep the estimate after the step at ``time_s``, dropping those no longer needed
        (the latest one at least ``span_s`` older is kept)."""
        self._steps.append((time_s, mass_kg, var_kg2))
        while len(self._steps) > 1 and self._steps[1][0] <= time_s - self.span_s:
            self._steps.popleft()

    def at(self, time_s: float) -> tuple[float, float] | None:
        """The mass difference (kg) and variance (kg²) after the last step at or before
        ``time_s``; None when none is kept."""
        then = [(mass_kg, var) for t, mass_kg, var in self._steps if t <= time_s]
        return then[-1] if then else None

    def clear(self) -> None:
        """Forget every step (the autopilot's clock restarted)."""
        self._steps.clear()
