"""The 1σ the online tracker reports (:mod:`estimator.estimation.online_effects`,
``OnlineEffects.sigma``: the daemon's return figures, the scoring against a truth) beyond its
covariance.

The covariance says how far the readings have pinned the state *within the model*. The 1σ the
tracker reports adds:

- what the model's form leaves unknown however long it runs: its mass law reads a payload a few
  percent off, its P(V) shape reads as a wind of half a metre per second (``OnlineSettings``
  ``mass_form_sigma_fraction``, ``wind_form_sigma_mps``), and its P(V) shape's error, which
  grows with the airspeed, is shared by the readings and so read as a wind and a mass the
  readings pin ever tighter (a consider term, :mod:`~estimator.estimation.form_error`). On
  ArduCopter SITL's stock quad, without them, a 1 kg payload was read 0.03–0.05 kg heavy at
  σ 0.02, a still-air flight found 0.8–1.0 m/s of wind at σ 0.4, and flights without a
  payload flown fast in wind were read 0.02–0.06 kg light at σ 0.01;
- for the wind, what the autopilot's report says is on its way: its lag and its gap from the
  estimate (:mod:`~estimator.estimation.autopilot_wind`);
- for a mass learnt in hover, what the wind held there leaves unknown. In hover the tracker
  holds the wind at its estimate and learns the mass from the power alone: at zero airspeed
  the power has no slope in the wind, so the covariance never couples the two, and the mass
  learnt is the one *at the wind held*, only as good as that wind. ArduCopter SITL,
  held20_strong_wind_hovers: a take-off into a 9.6 m/s wind, the tracker's wind starting at
  the vehicle file's (none) and following the autopilot's report over half a minute; the
  hover's 24 W of wind went to the mass, read +0.15 kg at a 1σ of 0.03 kg (4.8σ, no payload)
  while the wind's reported 1σ was metres per second. The term is the spread of the masses
  the step's power implies across the wind's reported uncertainty: the power at the wind's
  sigma points (van der Merwe's, :mod:`~estimator.estimation.kalman`), each wind held below
  the tracker's ``max_wind_mps``, its variance over the power's slope in the mass squared. A
  wind known to a fraction of a metre per second near zero adds next to nothing (the power's
  curvature in the wind is small there); a wind metres per second off does.

Which parts are identified, and applied, still follows the covariance alone. Units: m/s (NED
north, east), kg, W, s of the autopilot's clock.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from estimator.estimation.autopilot_wind import AutopilotWind
from estimator.estimation.kalman import MerweSigmaPoints
from estimator.estimation.online_settings import OnlineSettings

#: The wind's sigma points: two states (north, east). β = 1 (with α = 1, κ = 0) makes the
#: variance of a power quadratic in the wind exact, radial or along one axis; β = 2, the
#: Gaussian choice for one state's fourth moment, doubles it for a radial one in two states.
_WIND_POINTS = MerweSigmaPoints(2, alpha=1.0, beta=1.0, kappa=0.0)
#: The mass step (kg) the power's slope in the mass is measured over.
_MASS_STEP_KG = 0.05


def reported_variances(
    x: np.ndarray,
    p: np.ndarray,
    form: np.ndarray,
    settings: OnlineSettings,
    autopilot: AutopilotWind,
    time_s: float,
) -> tuple[np.ndarray, float]:
    """The wind's covariance (2 × 2, m²/s²) and the mass's variance (kg²) reported for the
    tracker's state ``x`` [w_n, w_e, δm, …] of covariance ``p``, its sensitivity ``form`` to
    the model form's error (:mod:`~estimator.estimation.form_error`) and the autopilot's
    reports at ``time_s``: all the terms above but the held wind's."""
    s = settings
    c_n, c_e, c_m = (float(v) for v in form[:3])
    lag_var = autopilot.lag_mps(time_s) ** 2  # either way: both components
    gap_n, gap_e = autopilot.gap_ne_mps(x, p, time_s)
    extra = s.wind_form_sigma_mps**2 + lag_var + np.array([c_n**2 + gap_n**2, c_e**2 + gap_e**2])
    mass_var = float(p[2, 2]) + (s.mass_form_sigma_fraction * float(x[2])) ** 2 + c_m**2
    return p[:2, :2] + np.diag(extra), mass_var


def held_wind_mass_var_kg2(
    powers_w: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x: np.ndarray,
    wind_cov: np.ndarray,
    rows: np.ndarray,
    max_wind_mps: float,
) -> float:
    """The variance (kg²) of the mass a hover step's power implies over the wind's
    uncertainty: ``powers_w(points, rows)`` the tracker's model power (W, points × rows) at
    each state of ``points`` (rows as ``x``: [w_n, w_e, δm, …]) for the step's flight-state
    ``rows``; ``x`` the estimate, ``wind_cov`` (2 × 2, m²/s²) the wind's reported covariance
    (its variances alone where it lost positive definiteness: the tracker restarts such a
    covariance at its next draw). Zero where the power does not grow with the mass (the mass's
    floor)."""
    wind_x = np.asarray(x[:2], dtype=float)
    try:
        winds = _WIND_POINTS.points(wind_x, wind_cov)
    except np.linalg.LinAlgError:
        winds = _WIND_POINTS.points(wind_x, np.diag(np.maximum(np.diag(wind_cov), 1e-9)))
    speed = np.hypot(winds[:, 0], winds[:, 1])
    winds *= np.minimum(1.0, max_wind_mps / np.maximum(speed, 1e-9))[:, None]
    points = np.tile(np.asarray(x, dtype=float), (len(winds) + 1, 1))
    points[:-1, :2] = winds
    points[-1, 2] += _MASS_STEP_KG  # the slope: the estimate with a little more mass
    powers = powers_w(points, rows).mean(axis=1)
    slope_w_per_kg = (powers[-1] - powers[0]) / _MASS_STEP_KG
    if not slope_w_per_kg > 0.0:
        return 0.0
    return _WIND_POINTS.variance(powers[:-1]) / slope_w_per_kg**2
