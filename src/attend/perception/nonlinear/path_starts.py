"""Where path mode's optimiser starts (:mod:`attend.perception.nonlinear.path`).

Path mode's free energy is not concave for nonlinear f, g (a sinusoidal sensor, saturating
dynamics): Levenberg-Marquardt finds the maximum nearest its start. The D-step's estimate, a
filter, can sit in a poorer basin than a smoother's (on the random nonlinear bank of
``benchmarks/bench_nonlinear_bank.py``, -F 25957 from the D-step against 23829 from the
unscented smoother on case 1, state SSE 2101 against 258). So path mode also starts from the
unscented RTS smoother on the white-noise model of the same per-sample variances and keeps the
larger F: the same objective, a better maximiser.
"""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError


def smoother_start(dem, signals: np.ndarray, prior, start) -> tuple[np.ndarray, np.ndarray] | None:
    """(states (N, n), inputs (N, r)) of the unscented RTS smoother on the white-noise model
    Q = dt^2 inv(Pi_w), R = inv(Pi_z), unknown inputs as random walks with their prior's one-sample
    steps (:func:`attend.perception.nonlinear_baselines.white_noise_options`), x[0] from
    ``prior`` (mean, precision) or else from the D-step's first estimate with the states' spread
    over the log as its variance; None where it does not apply (a precision that is not positive
    definite) or fails.

    dem: the NonlinearDEM; signals: (N, m + r) outputs then inputs (measured, or the prior mean
    eta); prior: path mode's prior on x[0] or None; start: the D-step's DEMEstimate of the log."""
    from attend.perception.nonlinear_baselines import unscented_kalman, white_noise_options

    m, r = dem.system.n_outputs, dem.system.n_inputs
    unknown = bool(r) and not dem.known_inputs
    try:
        options = white_noise_options(
            dem.dt, dem.process_precision, dem.sensor_precision, np.diag(dem.input_prior_precision) if unknown else None,
            dem.input_kernel_width or dem.kernel_width, input_mean=signals[0, m:] if unknown else None)
    except AttendInputError:
        return None
    if prior is None:
        spread = np.var(start.states, axis=0) + np.finfo(float).eps
        options.update(initial_mean=start.states[0], initial_covariance=np.diag(spread))
    else:
        options.update(initial_mean=prior[0], initial_covariance=np.diag(1.0 / prior[1]))
    inputs = signals[:, m:] if r and not unknown else None
    try:
        with np.errstate(all="ignore"):
            estimate = unscented_kalman(dem.system, dem.dt, signals[:, :m], inputs, smooth=True, **options)
    except (AttendInputError, np.linalg.LinAlgError, ValueError):
        return None
    states, estimated_inputs = estimate.states, estimate.inputs
    if not (np.all(np.isfinite(states)) and np.all(np.isfinite(estimated_inputs))):
        return None
    return states, estimated_inputs.reshape(len(states), r)
