"""Reference estimators on the same data as DEM (what DEM is compared with): Kalman
filters/smoothers and the exact Gaussian posterior.

All functions work on the discrete zero-order-hold model that :func:`attend.models.simulate`
samples (time index k = 0..N-1, time k dt [s])::

    x[k] = Ad x[k-1] + Bd u[k-1] + q[k-1],   q ~ N(0, Q)        (Q = process_covariance)
    y[k] = C x[k] + r[k],                    r ~ N(0, R)        (R = measurement_covariance)
    x[0] ~ N(m0, P0)                                            (initial_mean, initial_covariance)

Ad = expm(A dt), Bd = int_0^dt expm(A t) dt B. simulate() draws q[k] = dt w[k] with w of
standard deviation ``process_std``, so the matching white-noise covariances are
Q = dt^2 diag(process_std^2), R = diag(measurement_std^2) (:func:`simulation_covariances`).
The Kalman baselines treat q and r as white; :func:`exact_posterior` uses the coloured
covariances simulate() really produces.

Arrays are time-major: outputs (N, m), inputs (N, r); results are NamedTuples whose first
fields (time, states, inputs, state_std, input_std) match :class:`attend.perception.dem.DEMEstimate`.

- :func:`kalman_filter` / :func:`rts_smoother`: the standard filter (estimate of x[k] from
  y[0..k], or y[0..k+lag] with ``lag``) and Rauch-Tung-Striebel smoother (all of y). Own numpy
  implementation, cross-checked against pykalman in the tests.
- :func:`kalman_filter_ignoring_input`: the filter with u = 0 (the comparison of the ACC 2020
  observer paper).
- :func:`steady_state_kalman_filter`: constant gain from the discrete algebraic Riccati equation.
- :func:`augmented_kalman_filter`: state [x; u], the input a random walk u[k] = u[k-1] + e[k],
  e ~ N(0, input_variance).
- :func:`exact_posterior`: p(x[0..N-1], u[0..N-1] | y[0..N-1]) by dense Gaussian conditioning
  under the very generative model of simulate() (coloured w and z, optional Gaussian-process
  prior on the inputs). Its mean is the minimum-mean-square-error estimate under the mod

Identification baselines on the same logs as :func:`attend.perception.learning.identify`
(:mod:`.identification`): :func:`n4sid_baseline` (subspace identification), :func:`em_baseline`
(EM for a linear-Gaussian state-space model), and the basis-invariant errors
:func:`transfer_function_error` and :func:`eigenvalue_error`.

The reference for nonlinear models, the particle smoother, is
:func:`attend.perception.nonlinear_smoothers.particle_smoother`.

Layout: :mod:`.filters` (Kalman filters and smoothers), :mod:`.exact` (the exact posterior), :mod:`.exact_oracle` (the same posterior checked in two
precisions, for ill-conditioned models),
:mod:`.identification` (N4SID, EM, error metrics); every public name is re-exported here.
"""

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562).
_EXPORTS = {
    "ExactPosterior": "attend.perception.references.exact",
    "coloured_noise_correlation": "attend.perception.references.exact",
    "exact_posterior": "attend.perception.references.exact",
    "ConditioningWarning": "attend.perception.references.exact",
    "PosteriorAccuracy": "attend.perception.references.exact",
    "OraclePosterior": "attend.perception.references.exact_oracle",
    "OracleAgreement": "attend.perception.references.exact_oracle",
    "oracle_posterior": "attend.perception.references.exact_oracle",
    "KalmanEstimate": "attend.perception.references.filters",
    "augmented_kalman_filter": "attend.perception.references.filters",
    "kalman_filter": "attend.perception.references.filters",
    "kalman_filter_ignoring_input": "attend.perception.references.filters",
    "rts_smoother": "attend.perception.references.filters",
    "simulation_covariances": "attend.perception.references.filters",
    "steady_state_kalman_filter": "attend.perception.references.filters",
    "n4sid_baseline": "attend.perception.references.identification",
    "em_baseline": "attend.perception.references.identification",
    "continuous_from_discrete": "attend.perception.references.identification",
    "transfer_function_error": "attend.perception.references.identification",
    "eigenvalue_error": "attend.perception.references.identification",
}

__all__ = [
    "KalmanEstimate",
    "ExactPosterior",
    "simulation_covariances",
    "kalman_filter",
    "rts_smoother",
    "kalman_filter_ignoring_input",
    "steady_state_kalman_filter",
    "augmented_kalman_filter",
    "exact_posterior",
    "coloured_noise_correlation",
    "ConditioningWarning",
    "PosteriorAccuracy",
    "oracle_posterior",
    "OraclePosterior",
    "OracleAgreement",
    "n4sid_baseline",
    "em_baseline",
    "continuous_from_discrete",
    "transfer_function_error",
    "eigenvalue_error",
]

__getattr__, __dir__ = lazy_exports("attend.perception.references", _EXPORTS, globals())
