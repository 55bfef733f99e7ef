"""The online wind/mass tracker's settings (:class:`OnlineSettings`; the tracker is
:mod:`estimator.estimation.online_effects`, whose docstring explains each stage). SI units:
speeds m/s, masses kg, powers W, times s; process noises are random-walk densities per √s."""

from __future__ import annotations

from dataclasses import dataclass

from estimator.estimation.airborne import IDLE_FRACTION_OF_HOVER


@dataclass(frozen=True)
class OnlineSettings:
    """Tuning (SI units). Process noises are random-walk densities per √s."""

    wind_walk_mps_per_sqrt_s: float = 0.03
    mass_walk_kg_per_sqrt_s: float = 0.002
    initial_wind_sigma_mps: float = 3.0
    initial_mass_sigma_fraction: float = 0.15
    power_noise_w: float = 5.0
    #: The model's slow error b (:mod:`~estimator.estimation.online_effects`): 1σ as a
    #: fraction of the model's hover power where the vehicle file states none (``[model]
    #: slow_error_fraction``; 0: the model's errors are taken as white, as for a simulator's
    #: own model), and its correlation time (s).
    model_error_fraction: float = 0.0
    model_error_time_s: float = 30.0
    power_noise_fraction: float = 0.03
    gate_sigma: float = 5.0
    #: Readings in vertical motion are left out: beyond this climb or descent rate (m/s), or,
    #: where the model has the ``heave`` term, beyond this vertical acceleration (m/s²: 7 % of
    #: g, a thrust 7 % off hover), where the power leads the filtered kinematic state by about
    #: half a second (the thrust changes first, the velocity after), so the term is late.
    max_vertical_speed_mps: float = 1.0
    max_vertical_accel_mps2: float = 0.7
    #: A step whose readings these gates leave out more than this share of is a transition (a
    #: climb or descent starting or ending, the landing's descent): the power leads the
    #: filtered state by about half a second, so the readings kept are the transition's and
    #: read as a mass step (ArduCopter SITL: 0.5-1 kg at 7-8σ as a landing descent starts).
    #: The whole step is left out.
    max_vertical_share: float = 0.5
    #: Power below this fraction of the model's hover power is not flight (idle motors).
    min_power_fraction_of_hover: float = IDLE_FRACTION_OF_HOVER
    #: Gain of the adaptive measurement-noise estimate (per power sample).
    noise_gain: float = 0.02
    #: CUSUM on the normalised innovations (:mod:`~estimator.estimation.online_effects`): drift
    #: k and threshold h.
    cusum_drift_sigma: float = 0.5
    cusum_threshold_sigma: float = 7.0
    #: Below this ground speed (m/s) the vehicle hovers: the wind is held and a detected
    #: change is taken for mass; above it, for wind.
    moving_speed_mps: float = 2.0
    #: A wind known to this 1σ (m/s, both components) makes a mass learnt in hover final.
    wind_known_sigma_mps: float = 1.0
    #: A change in forward flight: the mass-step and wind-change hypotheses run until one is
    #: this much likelier (log-likelihood ratio, nats; 4.6 = 100:1) or for this many steps.
    hypothesis_nats: float = 4.6
    hypothesis_max_steps: int = 30
    #: What the model's form leaves unknown however long the filter runs, added to the 1σ it
    #: reports (:attr:`~estimator.estimation.online_effects.OnlineEffects.sigma`), not to
    #: its covariance: a mass difference is read off by the model's mass law (c3 ∝ W^1.5), off
    #: by this fraction of it where the airframe's power follows the thrust otherwise (on
    #: ArduCopter SITL a 1 kg payload reads 3.5–4.7 % heavy, with the speed term below
    #: carrying the rest; 5 % before it, when payload flights held the mass within 1σ on
    #: 81–94 % of the steps); a wind, by the shape of the model's P(V), whose error reads as a
    #: wind of this 1σ per component (m/s; on SITL's still-air flights 0.2–1.0 m/s). Set on
    #: the development recordings of ``replay/sitl`` and ``replay/sitl_held``
    #: (docs/residuals.md).
    mass_form_sigma_fraction: float = 0.03
    wind_form_sigma_mps: float = 0.5
    #: The model's P(V) shape error (:mod:`~estimator.estimation.form_error`), 1σ as a
    #: fraction of the hover power at the reference airspeed (m/s), growing with the airspeed
    #: squared: carried into the reported 1σ of the wind and the mass, not the covariance
    #: (SITL: −0.8 % of the hover power at 8–10 m/s on the flights the model was fitted on,
    #: −1.3 % on windy ones; set with the mass's term above on the same recordings).
    speed_form_sigma_fraction: float = 0.015
    speed_form_reference_mps: float = 10.0
    #: Mass may not drop below this fraction of the vehicle file's.
    min_mass_fraction: float = 0.3
    #: No multirotor flies in more wind than this (m/s): the estimate is held below it.
    max_wind_mps: float = 15.0
    #: The autopilot's own wind estimate (ArduPilot WIND, PX4 WIND_COV) as a measurement of
    #: the wind states: its 1σ per component (m/s), the time its errors stay correlated (s:
    #: each step takes it with the variance scaled by that time over the step's, so a minute
    #: of it weighs as one measurement), the age beyond which it is not used (s), and the speed
    #: (m/s) it must once have exceeded since boot (an autopilot that does not estimate the
    #: wind reports exactly zero).
    autopilot_wind_sigma_mps: float = 1.0
    autopilot_wind_correlation_s: float = 60.0
    autopilot_wind_max_age_s: float = 10.0
    autopilot_wind_active_mps: float = 0.1
    #: A wind change the autopilot saw: its report this far from the estimate (squared
    #: Mahalanobis distance with the report's own 1σ; 9.21 = χ²₂ at 1 %) on this many steps
    #: in a row reopens the wind's variance, as a change found in the power does. At χ²₂ at
    #: 0.1 % (13.8) a wind that stopped on slow legs was missed for minutes while the report
    #: said so at 10–11 (ArduCopter SITL: held8_gust_legs, held9_payload_stop_legs), where the
    #: power alone, its sign turning with each leg, never raised an alarm.
    autopilot_wind_change_chi2: float = 9.21
    autopilot_wind_change_steps: int = 3
    #: Added to the reported wind 1σ, not to the covariance: the report's lag behind the wind
    #: (``AutopilotWind.lag_mps``, to both components: found on held5_turn_legs, so every
    #: recording of replay/sitl_held up to held15 is development for it), the EKF's time
    #: constant (s; ArduCopter SITL's wind reports follow an onset with 9 s, a stop with 15 s)
    #: and the span (s) the report's rate is measured over; and its gap from the estimate,
    #: weighed by the probability that the two disagree, even odds at this squared Mahalanobis
    #: distance with both their variances (``AutopilotWind.gap_ne_mps``; 5.99 = χ²₂ at 5 %,
    #: the threshold of an all-or-nothing gap before; its smooth form found on
    #: held10_payload_gust_legs, so held10 is development for it). Set on the recordings of
    #: replay/sitl and replay/sitl_held. When the report stalls as it follows a change, the
    #: lag term decays at e^(−Δt/τ) rather than drop with its rate (found on
    #: held7_gust_fast_legs, so development for that rule), and not at all while the vehicle
    #: hovers, where the EKF holds its wind (found on held5_turn_legs and looked at on every
    #: recording up to held16, so development for that rule).
    autopilot_wind_lag_s: float = 10.0
    autopilot_wind_rate_span_s: float = 2.0
    autopilot_wind_gap_chi2: float = 5.99
    #: A wind in use this far from the estimate (squared Mahalanobis distance with the
    #: estimate's covariance; χ²₂ at 0.1 %) is refuted: the estimate replaces it even before
    #: it is identified (after a change, the old wind is worse than the new one's first guess).
    wind_refuted_chi2: float = 13.8
