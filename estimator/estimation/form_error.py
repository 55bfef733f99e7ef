"""What the power model's P(V) shape leaves in the online tracker's estimate: a consider term.

The model's P(V) is a fitted form, and its shape misses the airframe's curve by an amount that
grows with airspeed, the same on every flight (ArduCopter SITL's stock quad, its level
readings against the vehicle file's model with the true wind: measured − predicted +0.4 % of
the hover power below 2 m/s, −0.8 % at 8–10 m/s on the three flights it was fitted on, −1.3 %
on 21 windy ones; docs/residuals.md). The tracker reads that as a wind or a mass: a flight
without a payload flown fast is read 0.02–0.06 kg light, confidently, because the error is a
bias the readings share, not noise that averages out.

It is taken as a power bias h·θ the filter does not estimate: θ ~ N(0, 1), one draw for the
whole flight, and h = ``fraction`` × the hover power × (airspeed / ``reference_mps``)² at each
reading (zero in hover, where the fit is pinned). The filter's estimate then carries an error
c·θ, with c the state's sensitivity to θ, carried step by step as in Schmidt's consider
analysis (G. J. Bierman, *Factorization Methods for Discrete Sequential Estimation*, 1977,
ch. VIII; B. D. Tapley, B. E. Schutz, G. H. Born, *Statistical Orbit Determination*, 2004,
§6.3):

    prior:   c ← F c                 (the model error b decays, the random walks keep theirs)
    update:  c ← (I − K H) c + K h = P⁺ (P⁻)⁻¹ c + K h

with K the step's gain and P⁻, P⁺ its covariance before and after (for a Kalman update
I − K H = P⁺ (P⁻)⁻¹; the same carries through the autopilot's wind reports, with no h). The
1σ the tracker reports adds c_i² to each state's variance; the estimate and the covariance
the filter runs on are unchanged.

It is a first-order account of an unscented filter. Flown twice over a box of 10 m/s legs,
with the measured power off by h and without (tests/test_form_error.py), the tracker's
estimates end apart by its c to 5 % for the mass; early on, with the wind still wide, it
falls 25 % short, and the wind's c is off by up to 0.06 m/s (a tenth of its form term).
Neither the slope of the model at the estimate nor the sigma points' mean slope did better.

Units: c in the state's units per unit θ (m/s, kg, W), h in W, airspeed m/s.
"""

from __future__ import annotations

import numpy as np


def form_power_w(
    rows: np.ndarray,
    wind_ne_mps: np.ndarray,
    hover_power_w: float,
    fraction: float,
    reference_mps: float,
) -> float:
    """The model form's power error h (W, 1σ) of a step: its mean over the readings ``rows``
    (k × 9, the FlightState fields: velocity north and east over ground in columns 1 and 2,
    m/s) flown through the air mass moving at ``wind_ne_mps`` (north, east; m/s)."""
    air_n = rows[:, 1] - wind_ne_mps[0]
    air_e = rows[:, 2] - wind_ne_mps[1]
    airspeed2 = float((air_n * air_n + air_e * air_e).sum()) / len(rows)  # the mean
    return fraction * hover_power_w * airspeed2 / reference_mps**2


def carried(c: np.ndarray, p_before: np.ndarray, p_after: np.ndarray) -> np.ndarray:
    """The sensitivity ``c`` through a Kalman update that took the covariance from
    ``p_before`` to ``p_after``: (I − K H) c = P⁺ (P⁻)⁻¹ c; ``c`` as it was when ``p_before``
    is singular or either is not finite (damaged input never makes it NaN)."""
    try:
        moved = p_after @ np.linalg.solve(p_before, c)
    except np.linalg.LinAlgError:
        return c
    return moved if np.isfinite(moved).all() else c
