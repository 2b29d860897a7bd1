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
    steps (:func:`attend.perception.nonlinear_smoothers.white_noise_options`), x[0] from
    ``prior`` (mean, precision) or else from :func:`initial_state_prior`, RK4 sub-steps from
    :func:`smoother_substeps`, both read off :func:`d_step_basis`; None where it does not apply (a precision that is not positive
    definite) or fails.

    dem: the NonlinearDEM; signals: (N, m + r) outputs then inputs (measured, or the prior mean
    eta); prior: path mode's prior on x[0] or None; start: the D-step's DEMEstimate of the log."""
    from attend.perception.nonlinear_smoothers import unscented_kalman, white_noise_options

    m, r = dem.system.n_outputs, dem.system.n_inputs
    unknown = bool(r) and not dem.known_inputs
    try:
        options = white_noise_options(dem.dt, process_precision=dem.process_precision,
                                      sensor_precision=dem.sensor_precision,
                                      input_prior_precision=np.diag(dem.input_prior_precision) if unknown else None,
                                      input_kernel_width=dem.input_kernel_width or dem.kernel_width,
                                      input_mean=signals[0, m:] if unknown else None)
    except AttendInputError:
        return None
    inputs = signals[:, m:] if r and not unknown else None
    try:
        basis = d_step_basis(dem, signals, start)
        if prior is None:
            mean, std = initial_state_prior(dem, signals, basis)
            options.update(initial_mean=mean, initial_covariance=np.diag(std**2))
        else:
            options.update(initial_mean=prior[0], initial_covariance=np.diag(1.0 / prior[1]))
        substeps = smoother_substeps(dem, basis)
        with np.errstate(all="ignore"):
            estimate = unscented_kalman(dem.system, dem.dt, signals[:, :m], inputs, smooth=True, substeps=substeps,
                                        **options)
    except (AttendInputError, np.linalg.LinAlgError, ValueError):
        return None
    states, estimated_inputs = estimate.states, estimate.inputs
    if not (np.all(np.isfinite(states)) and np.all(np.isfinite(estimated_inputs))):
        return None
    return states, estimated_inputs.reshape(len(states), r)


def d_step_basis(dem, signals: np.ndarray, start):
    """(estimate, whole): the D-step estimate the unscented smoother's start is read from. The
    D-step's estimate of the log ``start`` (a DEMEstimate with generalised states) when it is
    finite, keeps its predicted outputs near the data and has a misfit ratio within MISFIT_LIMIT
    (:mod:`attend.perception.nonlinear.misfit`), whole = True; else its estimate of the first
    4 (max(p, d) + 1) samples, whole = False. dem: the NonlinearDEM; signals: (N, m + r)."""
    from attend.perception.nonlinear.misfit import MISFIT_LIMIT, check_excursion, sample_misfit

    if start is not None and start.generalized is not None and np.all(np.isfinite(start.states)):
        try:
            check_excursion(dem, signals, start.states, start.inputs, "NonlinearDEM")
            if sample_misfit(dem, signals, start.generalized) <= MISFIT_LIMIT:
                return start, True
        except AttendInputError:
            pass
    count = min(len(signals), 4 * (max(dem.embedding_order, dem.input_order) + 1))
    return dem.dstep_estimate(signals[:count], True, None, check=False), False


def initial_state_prior(dem, signals: np.ndarray, basis) -> tuple[np.ndarray, np.ndarray]:
    """A weak Gaussian prior (mean (n,), std (n,)) on x[0] for an unscented smoother when none is
    given, from the D-step's ``basis`` (:func:`d_step_basis`). From the whole log: its first
    estimate, with the spread of its states over the log (their std per state) as the std, a prior
    as wide as the range the states take. From the first samples (the estimate of the log is not
    to be trusted, so its spread means nothing): its Laplace std, widened by sqrt(rho) where those
    samples are far from DEM's generalised model (misfit ratio rho = e' Pi~ e / dim(e) > 1, the
    usual variance-factor correction), and no wider than the largest |x_i| the D-step gives any
    state there (a wider prior lets the sigma points alias on periodic sensors: 23-25 against
    25-665 state SSE on bank case 24); an estimate that leaves the data there, or whose misfit
    ratio exceeds MISFIT_LIMIT^2, is an AttendInputError (no usable start). On the random
    nonlinear bank written as model files (``benchmarks/bench_nonlinear_cli.py``) this took the
    unscented smoother from median 1.004 / 90th percentile 1.64 / worst 11.8 times the smoother
    told the true prior of x[0] (first samples only) to 1.000 / 1.17 / 8.0 (a case where every
    prior tried failed).

    dem: the NonlinearDEM; signals: (N, m + r) outputs then inputs; basis: (estimate, whole)."""
    from attend.perception.nonlinear.misfit import MISFIT_LIMIT, check_excursion, sample_misfit

    estimate, whole = basis
    if whole:
        return estimate.states[0], np.std(estimate.states, axis=0) + 1e-9 * (1.0 + np.abs(estimate.states[0]))
    count = len(estimate.states)
    check_excursion(dem, signals[:count], estimate.states, estimate.inputs, "NonlinearDEM on the first samples")
    ratio = sample_misfit(dem, signals[:count], estimate.generalized)
    if ratio > MISFIT_LIMIT**2:  # not a start to widen: the flow failed on these samples too
        raise AttendInputError(f"NonlinearDEM on the first {count} samples: its estimate is far from the data "
                               f"(misfit ratio {ratio:.3g}, above {MISFIT_LIMIT**2:g}), so it gives no usable x[0]")
    widening = np.sqrt(ratio) if np.isfinite(ratio) and ratio > 1.0 else 1.0
    # one scale for the state vector, so that a state estimated near 0 is not pinned there
    size = float(np.max(np.abs(estimate.states)))
    std = estimate.state_std[0] * widening
    return estimate.states[0], np.minimum(std, size) if size > 0 else std


def smoother_substeps(dem, basis) -> int:
    """RK4 sub-steps per sample of the unscented smoother's transition at the D-step's ``basis``
    (:func:`d_step_basis`; :func:`attend.perception.nonlinear_smoothers.kalman.rk4_substeps`).
    dem: the NonlinearDEM."""
    from attend.perception.nonlinear_smoothers.kalman import rk4_substeps

    return rk4_substeps(dem.system, dem.dt, basis[0].states, basis[0].inputs)
