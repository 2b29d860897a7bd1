"""The exact Gaussian posterior under simulate()'s generative model (coloured w and z, optional
Gaussian-process prior on the inputs): the minimum-mean-square-error limit no estimator can beat."""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_triangular

from attend._validation import AttendInputError, positive_scalar, require_finite
from attend._validation import kernel_width as checked_width
from attend.models.noise import autocorrelation, gaussian_kernel
from attend.models.noise_model import NoiseModel, resolve_noise
from attend.perception.estimate import Estimate, as_estimate
from attend.perception.references.filters import _inputs, _std_vector, _system


class ConditioningWarning(UserWarning):
    """exact_posterior's float64 covariance form is not trustworthy on this model.

    On models whose outputs are much more precise than their prior spread (tiny sensor noise,
    broad input priors or x[0], integrators, long windows, smooth noise) the Cholesky jitter,
    scaled by the outputs' mean prior variance, can exceed the sensor noise or the small
    eigenvalues of the outputs' covariance, and the variances are differences of numbers up to
    1e14 apart. exact_posterior checks itself (:class:`PosteriorAccuracy`, its result's
    ``accuracy``) and warns when the jitter moves the mean by more than JITTER_SHIFT_LIMIT posterior
    std, or cannot be bounded, or the std is uncertain by more than STD_ROUNDING_LIMIT. Then use
    :func:`attend.perception.references.exact_oracle.oracle_posterior` (square-root form, checked in
    double-double) on a short window, or the Kalman smoother: on benchmarks/bench_unknown_inputs.py
    both are at the posterior where this form is off by up to 10 std."""


class PosteriorAccuracy(NamedTuple):
    """exact_posterior's own estimate of how far its float64 result may be from the model's posterior.

    jitter_shift: max over states and inputs of |the mean's change were the Cholesky jitter
    removed| / posterior std, |S_zy (inv(S) - inv(S + j I)) (y - m_y)| summed as a series in
    j inv(S + j I) (j = jitter * mean(diag S_yy), the white variance the jitter adds to every
    output); when the series does not converge (jitter_dominates: the jitter is as large as the
    smallest eigenvalues of S, which float64 cannot resolve) the partial sum, at least the limit;
    jitter_share: j over the smallest per-sample sensor variance (the jitter read as extra sensor
    noise); std_rounding: max of eps prior variance / posterior variance / 2, the relative error
    of a std computed as prior variance minus explained variance (inf where that difference
    rounds to 0 or below)."""

    jitter_shift: float
    jitter_share: float
    std_rounding: float
    jitter_dominates: bool = False


JITTER_SHIFT_LIMIT = 0.1
"""exact_posterior warns (ConditioningWarning) when its jitter moves the mean by more than this
many posterior std (first order), or when rounding leaves its std uncertain by more than
STD_ROUNDING_LIMIT (relative)."""
STD_ROUNDING_LIMIT = 0.01
JITTER_TERMS = 12


class ExactPosterior(NamedTuple):
    """Exact Gaussian posterior given all outputs.

    time (N,) [s]; states (N, n), inputs (N, r) posterior means (inputs are the given ones when
    known); state_std, input_std their marginal standard deviations; covariance: the joint
    posterior covariance of the stacked vector [x[0]; ...; x[N-1]; u[0]; ...; u[N-1]] (time-major
    within each block; inputs only when unknown) when requested, else None; log_likelihood:
    log p(y[0..N-1]) under the model; causal_states, causal_inputs: E[. at k | y[0..k]] (the best
    causal estimates) when requested with causal=True, else None.
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    covariance: np.ndarray | None
    log_likelihood: float
    causal_states: np.ndarray | None = None
    causal_inputs: np.ndarray | None = None
    accuracy: PosteriorAccuracy | None = None

    def as_estimate(self) -> Estimate:
        """This result as the common :class:`attend.perception.estimate.Estimate` (details: this result)."""
        return as_estimate(self)

def coloured_noise_correlation(n_samples: int, dt: float, kernel_width: float) -> np.ndarray:
    """(N, N) correlation matrix of n_samples = N samples of attend.models.noise.coloured_noise.

    The noise is white noise convolved with the unit-energy kernel h = gaussian_kernel(dt, s), so
    Corr(e[i], e[j]) = sum_l h[l] h[l + |i - j|] (the kernel's discrete self-correlation,
    ~ rho(|i - j| dt) = exp(-((i-j) dt)^2 / (4 s^2)), zero beyond the kernel's length).
    kernel_width 0 is white noise (the identity).
    """
    if kernel_width == 0:
        return np.eye(n_samples)
    h = gaussian_kernel(dt, kernel_width)
    self_correlation = np.correlate(h, h, mode="full")[len(h) - 1:]  # lags 0, 1, ...
    lags = np.abs(np.arange(n_samples)[:, None] - np.arange(n_samples)[None, :])
    values = np.zeros(n_samples)
    count = min(n_samples, len(self_correlation))
    values[:count] = self_correlation[:count]
    return values[lags]


def _irregular_transfer_matrix(transitions: list, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`_transfer_matrix` with step k's own transition: block (k, j) = Ad_(k-1) ... Ad_(j+1)
    for j < k (Ad_i: the transition out of sample i), block k of Phi = Ad_(k-1) ... Ad_0."""
    n = transitions[0].shape[0]
    L = np.zeros((n_samples * n, n_samples * n))
    Phi = np.zeros((n_samples * n, n))
    Phi[:n] = np.eye(n)
    for k in range(1, n_samples):
        rows, previous = slice(k * n, (k + 1) * n), slice((k - 1) * n, k * n)
        Ad = transitions[k - 1]
        Phi[rows] = Ad @ Phi[previous]
        L[rows, : (k - 1) * n] = Ad @ L[previous, : (k - 1) * n]
        L[rows, previous] = np.eye(n)
    return L, Phi


def _transfer_matrix(Ad: np.ndarray, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """L (N n, N n) with block (k, j) = Ad^(k-1-j) for j < k (else 0), and Phi (N n, n) with
    block k = Ad^k: stacked x = Phi x[0] + L [drive[0]; drive[1]; ...]."""
    n = Ad.shape[0]
    powers = np.empty((n_samples, n, n))
    powers[0] = np.eye(n)
    for k in range(1, n_samples):
        powers[k] = Ad @ powers[k - 1]
    k = np.arange(n_samples)[:, None]
    j = np.arange(n_samples)[None, :]
    index = np.clip(k - 1 - j, 0, None)
    blocks = powers[index] * (k > j)[:, :, None, None]  # (N, N, n, n)
    L = blocks.transpose(0, 2, 1, 3).reshape(n_samples * n, n_samples * n)
    return L, powers.reshape(n_samples * n, n)


def exact_posterior(system, dt, outputs, inputs=None, *, kernel_width=None, process_std=None, measurement_std=None,
                    input_prior_mean=None, input_prior_std=None, initial_mean=None, initial_std=0.0,
                    jitter: float = 1e-12, return_covariance: bool = False,
                    process_kernel_width=None, sensor_kernel_width=None, input_kernel_width=None,
                    causal: bool = False, time=None, white_floor: float = 0.0,
                    noise: NoiseModel | None = None) -> ExactPosterior:
    """Exact posterior of the states (and inputs) under simulate()'s generative model.

        x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1],   y[k] = C x[k] + z[k],   x[0] ~ N(m0, diag(s0^2))
        Cov(w_c[i], w_c[j]) = process_std_c^2 K_ij,  Cov(z_c[i], z_c[j]) = measurement_std_c^2 K_ij
        K = coloured_noise_correlation(N, dt, kernel_width)  (the simulator's exact covariance)
        unknown inputs: u_c ~ GP(input_prior_mean, input_prior_std_c^2 rho(|t - t'|)),
                        rho(tau) = exp(-tau^2 / (4 s^2))  (the smoothness DEM assumes)
    process_kernel_width / sensor_kernel_width override kernel_width for w / z (0 = white noise);
    input_kernel_width (default: the process width) is the s of the inputs' prior.

    With stacked x = Phi x[0] + L (Bd u + dt w) (time-major), y = (I_N kron C) x + z is Gaussian;
    conditioning gives mean = m_x + S_xy inv(S_yy) (y - m_y), cov = S_xx - S_xy inv(S_yy) S_yx,
    with a Cholesky factor of S_yy + jitter * mean(diag S_yy) I (coloured noise makes S_yy
    numerically singular at high frequencies; the jitter adds white noise of that tiny variance).
    When m > n the outputs are first reduced, exactly, to the n whitened channels that span
    range(C) (the others are pure noise independent of x and u).

    system; dt [s]; outputs (N, m); inputs (N, r) known inputs, or None with input_prior_mean
    (scalar, (r,) or (N, r)) and input_prior_std (scalar or (r,)) [input unit]; kernel_width s [s];
    process_std, measurement_std: per-sample standard deviations as passed to simulate() (required
    unless ``noise`` is given); noise: an :class:`attend.models.NoiseModel` instead of process_std,
    measurement_std and the kernel widths (kernel_width, process_kernel_width, sensor_kernel_width):
    its standard deviations (:attr:`~attend.models.NoiseModel.process_std`, exact for a model made
    by from_std) and widths, as simulate(noise=...) takes them;
    initial_mean m0 (default 0) and initial_std s0 (default 0: x[0] known, as simulate() starts).
    return_covariance=True also returns the joint posterior covariance (``covariance``).
    causal=True also returns ``causal_states`` / ``causal_inputs``: E[x[k] | y[0..k]] for every k,
    the best causal estimate under the model, read from the same Cholesky factor (the innovations
    of y in time order).
    NaN outputs are left out of the conditioning (missing). time (N,) [s]: irregular sample times
    (dt unused): x[k] = Ad(h_k) x[k-1] + Bd(h_k) u[k-1] + h_k w[k-1], h_k = t_k - t_(k-1), noises
    continuous-time: K_ij = rho(t_i - t_j) (w, z, the inputs' prior). white_floor f: coloured noises
    get a white part, K -> (1 - f) K + f I (the Kalman smoother's noise models have f = 1e-8).
    Cost O((N min(m, n))^3) time, O((N (n + m + r))^2) memory: for logs up to a few thousand samples.
    Ill-conditioned models: see :class:`ConditioningWarning` (``accuracy`` holds the self-check).
    """
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    given = dict(process_std=process_std, measurement_std=measurement_std, kernel_width=kernel_width,
                 process_kernel_width=process_kernel_width, sensor_kernel_width=sensor_kernel_width)
    if resolve_noise(noise, given, "exact_posterior") is not None:
        process_std, measurement_std = noise.process_std, noise.sensor_std
        process_kernel_width, sensor_kernel_width = noise.process_kernel_width, noise.sensor_kernel_width
    for value, name in ((process_std, "process_std"), (measurement_std, "measurement_std")):
        if value is None:
            raise AttendInputError(f"{name}: required (or noise=NoiseModel(...))")
    s_w, s_z, s_u = noise_widths(kernel_width, process_kernel_width, sensor_kernel_width, input_kernel_width)
    y, observed = _measured_outputs(system, outputs)
    N = y.shape[0]
    times = _sample_times(time, N, dt)
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    sw = _std_vector(process_std, n, "process_std")
    sz = _std_vector(measurement_std, m, "measurement_std")
    m0 = _initial_mean(initial_mean, n)
    s0 = _std_vector(initial_std, n, "initial_std")
    _check_regularisation(jitter, white_floor)
    known = inputs is not None
    u_mean, su = _input_prior(system, inputs, input_prior_mean, input_prior_std, N)
    x_mean, x_cov, LB, input_cov, K = _state_prior(system, dt, N, m0, s0, sw, u_mean, su, s_w, s_u, known, times,
                                                   white_floor)
    K_z = K if s_z == s_w else _correlation(N, dt, s_z, times, white_floor)
    chol, white, xy_cov, Cbig, q, log_likelihood, added = _condition_on_outputs(system, y, sz, x_mean, x_cov, K_z,
                                                                                 jitter, observed)
    # latent z = [x; u] (u only when unknown)
    if known:
        z_mean, zy_cov, z_var = x_mean, xy_cov, np.diag(x_cov)
    else:
        uy_cov = input_cov @ LB.T @ Cbig.T  # Cov(u, y_q)
        z_mean = np.concatenate([x_mean, u_mean.reshape(-1)])
        zy_cov = np.vstack([xy_cov, uy_cov])
        z_var = np.concatenate([np.diag(x_cov), np.diag(input_cov)])
    G = solve_triangular(chol, zy_cov.T, lower=True)  # inv(chol) S_yz
    post_mean = z_mean + G.T @ white
    explained = np.sum(G**2, axis=0)
    post_var = np.clip(z_var - explained, 0, None)
    accuracy = _accuracy(chol, white, zy_cov, z_var, post_var, added, _smallest_noise_variance(system, sz, q, observed))
    covariance = _posterior_covariance(x_cov, LB, input_cov, G) if return_covariance else None
    causal_states = causal_inputs = None
    if causal:
        causal_states, causal_inputs = _causal_means(G, white, z_mean, u_mean, q, n, known, observed)
    states = post_mean[: N * n].reshape(N, n)
    state_std = np.sqrt(post_var[: N * n]).reshape(N, n)
    if known:
        est_inputs, input_std = u_mean, np.zeros((N, r))
    else:
        est_inputs = post_mean[N * n:].reshape(N, r)
        input_std = np.sqrt(post_var[N * n:]).reshape(N, r)
    return ExactPosterior(np.arange(N) * dt if times is None else times, states, est_inputs, state_std, input_std,
                          covariance, float(log_likelihood), causal_states, causal_inputs, accuracy)


def _smallest_noise_variance(system, sz, q, observed) -> float:
    """The smallest per-sample sensor variance of the channels conditioned on (the rotated
    channels of the reduction to range(C) have unit variance)."""
    if q < system.n_outputs and (observed is None or observed.all()):
        return 1.0
    positive = sz[sz > 0]
    return float(np.min(positive) ** 2) if positive.size else 0.0


def _accuracy(chol, white, zy_cov, z_var, post_var, added, noise_variance) -> PosteriorAccuracy:
    """:class:`PosteriorAccuracy` of the covariance form, and a ConditioningWarning when it is poor.

    The mean's change were the jitter j removed: S_zy (inv(S) - inv(S + j I)) r = S_zy sum_k j^k
    inv(S + j I)^(k+1) r (k >= 1), summed from the same Cholesky factor (two triangular solves a
    term) up to JITTER_TERMS terms, then the remainder as a geometric series; one whose terms do
    not fall (the jitter is as large as the small eigenvalues of S) counts as a shift above the
    limit."""
    std = np.sqrt(post_var)
    spread = std > 0
    shift, dominates = 0.0, False
    if added > 0 and spread.any():
        vector = solve_triangular(chol, white, lower=True, trans="T")  # inv(S + j I) r
        total = np.zeros_like(vector)
        previous = np.inf
        for _ in range(JITTER_TERMS):
            vector = added * solve_triangular(chol, solve_triangular(chol, vector, lower=True), lower=True, trans="T")
            total += vector
            term = float(np.max(np.abs(zy_cov @ vector)[spread] / std[spread]))
            ratio = term / previous if previous > 0 else 0.0
            previous = term
            if term < 1e-3 * JITTER_SHIFT_LIMIT:
                break
        shift = float(np.max(np.abs(zy_cov @ total)[spread] / std[spread]))
        dominates = term >= 1e-3 * JITTER_SHIFT_LIMIT and ratio >= 0.95
        if dominates:  # diverging or stalling: the change cannot be told from inside float64
            shift = max(shift, JITTER_SHIFT_LIMIT * 1.0001)
        elif term >= 1e-3 * JITTER_SHIFT_LIMIT:  # converging slowly: add the geometric remainder
            shift += term * ratio / (1 - ratio)
    with np.errstate(divide="ignore", invalid="ignore"):
        rounding = np.where(post_var > 0, 0.5 * np.finfo(float).eps * z_var / post_var, np.inf)
    informative = z_var > 0
    std_rounding = float(np.max(rounding[informative])) if informative.any() else 0.0
    share = added / noise_variance if noise_variance > 0 else np.inf
    accuracy = PosteriorAccuracy(shift, float(share), std_rounding, bool(dominates))
    if shift > JITTER_SHIFT_LIMIT or std_rounding > STD_ROUNDING_LIMIT:
        moved = ("is as large as the smallest eigenvalues of the outputs' covariance (the model's noise is "
                 "smoother or smaller than float64 resolves there), so its effect on the mean cannot be bounded"
                 if dominates else f"moves the mean by ~{shift:.2g} posterior std")
        warnings.warn(
            f"exact_posterior: the float64 covariance form is not trustworthy on this model: its Cholesky jitter "
            f"(white output noise of variance {added:.2g}, {share:.2g} x the smallest sensor variance) {moved}; "
            f"rounding leaves the std uncertain by up to {min(std_rounding, 1e300):.2g} (relative); use "
            "exact_oracle.oracle_posterior on a short window, or the Kalman smoother", ConditioningWarning, stacklevel=3)
    return accuracy


def _input_prior(system, inputs, input_prior_mean, input_prior_std, N):
    """Mean (N, r) and std (r,) of the inputs: the given inputs (std 0) or their prior."""
    r = system.n_inputs
    if inputs is not None:
        return _inputs(system, inputs, N), np.zeros(r)
    if input_prior_mean is None or input_prior_std is None:
        raise AttendInputError(
            "input_prior_mean, input_prior_std: required when the inputs are unknown (inputs=None)"
        )
    return _inputs(system, input_prior_mean, N, "input_prior_mean"), _std_vector(input_prior_std, r, "input_prior_std")


def _measured_outputs(system, outputs) -> tuple[np.ndarray, np.ndarray]:
    """(y (N, m) with 0 where missing, observed (N, m)): NaN marks a missing output."""
    from attend.models.sample_times import matrix_with_gaps

    y = matrix_with_gaps(outputs, "outputs", system.n_outputs)
    if y.shape[0] < 1:
        raise AttendInputError("outputs: expected at least 1 sample")
    observed = ~np.isnan(y)
    if not observed.any():
        raise AttendInputError("outputs: every value is missing (NaN)")
    return np.where(observed, y, 0.0), observed


def _check_regularisation(jitter, white_floor) -> None:
    """jitter >= 0 and 0 <= white_floor < 1, finite."""
    for value, field, upper in ((jitter, "jitter", np.inf), (white_floor, "white_floor", 1.0)):
        if not (np.isfinite(value) and 0 <= value < upper):
            bound = " and < 1" if upper == 1 else ""
            raise AttendInputError(f"{field}: expected a finite number >= 0{bound}, got {value!r}")


def _initial_mean(initial_mean, n: int) -> np.ndarray:
    """m0 (n,), default 0, checked."""
    m0 = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(-1)
    if m0.shape != (n,):
        raise AttendInputError(f"initial_mean: expected {n} numbers, got shape {np.shape(initial_mean)}")
    require_finite(m0, "initial_mean")
    return m0


def _sample_times(time, N: int, dt: float):
    """The (N,) irregular sample times [s], checked (None: uniform, k dt)."""
    if time is None:
        return None
    from attend.models.sample_times import check_time_stamps

    return check_time_stamps(time, N, float(np.min(np.diff(time))) if N > 1 else dt)


def _correlation(N: int, dt: float, width: float, times, white_floor: float = 0.0) -> np.ndarray:
    """Correlation of N samples of a noise of kernel width ``width``: the simulator's on the
    uniform grid (times None), rho(t_i - t_j) at irregular times (the identity for width 0);
    a coloured noise's white part of relative variance white_floor added."""
    if width == 0:
        return np.eye(N)
    K = coloured_noise_correlation(N, dt, width) if times is None else \
        autocorrelation(times[:, None] - times[None, :], width)
    return (1 - white_floor) * K + white_floor * np.eye(N) if white_floor else K


def _state_prior(system, dt, N, m0, s0, sw, u_mean, su, s_w, s_u, known, times=None, white_floor=0.0):
    """Prior mean and covariance of the stacked states x = Phi x[0] + L (Bd u + h w), and with
    unknown inputs L Bbig (x = ... + L Bbig u) and the inputs' prior covariance; K the process
    noise's correlation. times: irregular sample times (None: uniform, step dt); white_floor: as
    :func:`_correlation`."""
    if times is None:
        steps = np.full(N, dt)
        Ad, Bd = system.discretize(dt)
        L, Phi = _transfer_matrix(Ad, N)
        holds = np.broadcast_to(Bd, (N, *Bd.shape))
    else:  # steps[k] = t[k+1] - t[k] carries drive k into sample k + 1 (the last one enters no sample)
        steps = np.append(np.diff(times), 1.0)
        pairs = [system.discretize(h) for h in steps]
        L, Phi = _irregular_transfer_matrix([Ad for Ad, _ in pairs], N)
        holds = np.array([Bd for _, Bd in pairs])
    K = _correlation(N, dt, s_w, times, white_floor)
    # prior of the stacked drive d[k] = Bd(h) u[k] + h w[k] and of the states
    drive_mean = np.einsum("kij,kj->ki", holds, u_mean).reshape(-1)
    scale = np.repeat(steps, system.n_states) * np.tile(sw, N)  # h_k sigma_w per stacked entry
    drive_cov = np.kron(K, np.eye(system.n_states)) * np.outer(scale, scale) \
        if times is not None else np.kron(K, np.diag((dt * sw) ** 2))
    if not known:
        if s_u <= 0:
            raise AttendInputError("input_kernel_width: expected a width > 0 [s] for the inputs' prior")
        lags = dt * (np.arange(N)[:, None] - np.arange(N)[None, :]) if times is None \
            else times[:, None] - times[None, :]
        Ku = autocorrelation(lags, s_u)
        input_cov = np.kron(Ku, np.diag(su**2))  # (N r, N r)
        Bbig = np.zeros((N * system.n_states, N * system.n_inputs))  # d = Bbig u + h w
        for k in range(N):
            rows, columns = slice(k * system.n_states, (k + 1) * system.n_states), \
                slice(k * system.n_inputs, (k + 1) * system.n_inputs)
            Bbig[rows, columns] = holds[k]
        drive_cov = drive_cov + Bbig @ input_cov @ Bbig.T
    x_mean = Phi @ m0 + L @ drive_mean
    x_cov = L @ drive_cov @ L.T + Phi @ np.diag(s0**2) @ Phi.T
    LB = None if known else L @ Bbig
    return x_mean, x_cov, LB, (None if known else input_cov), K


def _condition_on_outputs(system, y, sz, x_mean, x_cov, K_z, jitter, observed=None):
    """Cholesky factor of Cov(y_q), whitened residual, Cov(x, y_q), the stacked output map, the
    number q of channels kept and log p(y). observed (N, m): the measured entries (with missing
    ones the rows of the stacked y are the measured entries, time-major, and q = m)."""
    N, m = y.shape
    n = system.n_states
    if observed is not None and not observed.all():
        return _condition_on_measured(system, y, sz, x_mean, x_cov, K_z, jitter, observed)
    # Exact reduction to a sufficient statistic: the measurement noise has covariance
    # K kron diag(sz^2), so with the whitened channels diag(1/sz) y and the QR factor
    # diag(1/sz) C = Qc Rc, the rotated channels Qc' diag(1/sz) y beyond the first q = n are
    # noise with covariance K kron I, independent of x, u and of the first q channels.
    if m > n and np.all(sz > 0):
        Qc = np.linalg.qr(system.C / sz[:, None], mode="complete")[0]
        transform, q = Qc.T / sz[None, :], n  # (m, m)
    else:
        transform, q = np.eye(m), m
    rotated = y @ transform.T
    Cq = transform[:q] @ system.C
    Cbig = np.kron(np.eye(N), Cq)
    y_mean = Cbig @ x_mean
    xy_cov = x_cov @ Cbig.T  # Cov(x, y_q)
    channel_cov = (transform[:q] * sz**2) @ transform[:q].T
    y_cov = Cbig @ xy_cov + np.kron(K_z, channel_cov)
    y_cov = 0.5 * (y_cov + y_cov.T)
    added = jitter * np.mean(np.diag(y_cov))
    y_cov[np.diag_indices_from(y_cov)] += added
    try:
        chol = np.linalg.cholesky(y_cov)
        chol_noise = np.linalg.cholesky(K_z + jitter * np.eye(N)) if q < m else None
    except np.linalg.LinAlgError:
        raise AttendInputError(
            "jitter: the output covariance is not numerically positive definite; increase jitter"
        ) from None
    residual = rotated[:, :q].reshape(-1) - y_mean
    white = solve_triangular(chol, residual, lower=True)
    log_likelihood = -0.5 * (white @ white) - np.sum(np.log(np.diag(chol))) - 0.5 * N * m * np.log(2 * np.pi)
    if q < m:  # the pure-noise channels and the Jacobian of the transform
        noise = solve_triangular(chol_noise, rotated[:, q:], lower=True)
        log_likelihood += -0.5 * np.sum(noise**2) - (m - q) * np.sum(np.log(np.diag(chol_noise)))
        log_likelihood -= N * np.sum(np.log(sz))
    return chol, white, xy_cov, Cbig, q, log_likelihood, float(added)


def _condition_on_measured(system, y, sz, x_mean, x_cov, K_z, jitter, observed):
    """:func:`_condition_on_outputs` for the measured entries of y only (no channel reduction)."""
    N, m = y.shape
    keep = observed.reshape(-1)
    Cbig = np.kron(np.eye(N), system.C)[keep]
    xy_cov = x_cov @ Cbig.T
    noise_cov = np.kron(K_z, np.diag(sz**2))[np.ix_(keep, keep)]
    y_cov = Cbig @ xy_cov + noise_cov
    y_cov = 0.5 * (y_cov + y_cov.T)
    added = jitter * np.mean(np.diag(y_cov))
    y_cov[np.diag_indices_from(y_cov)] += added
    try:
        chol = np.linalg.cholesky(y_cov)
    except np.linalg.LinAlgError:
        raise AttendInputError(
            "jitter: the output covariance is not numerically positive definite; increase jitter"
        ) from None
    white = solve_triangular(chol, y.reshape(-1)[keep] - Cbig @ x_mean, lower=True)
    log_likelihood = -0.5 * (white @ white) - np.sum(np.log(np.diag(chol))) - 0.5 * keep.sum() * np.log(2 * np.pi)
    return chol, white, xy_cov, Cbig, m, log_likelihood, float(added)


def _posterior_covariance(x_cov, LB, input_cov, G):
    """Posterior covariance of z = [x; u] (u only when unknown: LB is None when known)."""
    if LB is None:
        z_cov = x_cov
    else:
        xu_cov = LB @ input_cov  # Cov(x, u)
        z_cov = np.block([[x_cov, xu_cov], [xu_cov.T, input_cov]])
    covariance = z_cov - G.T @ G
    return 0.5 * (covariance + covariance.T)


def _causal_means(G, white, z_mean, u_mean, q, n, known, observed=None):
    """E[z at k | y[0..k]]: only the innovations of samples <= k. Returns (states, inputs).
    observed (N, m): the measured entries when some are missing (the rows of G are those)."""
    N, r = u_mean.shape
    if observed is not None and not observed.all():
        sample = np.nonzero(observed)[0]  # time of each measured entry (time-major order)
        contributions = np.zeros((N, G.shape[1]))
        np.add.at(contributions, sample, G * white[:, None])
    else:
        contributions = (G * white[:, None]).reshape(N, q, -1).sum(axis=1)  # (time of y, latent)
    latent_time = np.concatenate([np.repeat(np.arange(N), n), [] if known else np.repeat(np.arange(N), r)])
    mask = np.arange(N)[:, None] <= latent_time[None, :].astype(int)
    causal_mean = z_mean + np.sum(contributions * mask, axis=0)
    return causal_mean[: N * n].reshape(N, n), (u_mean if known else causal_mean[N * n:].reshape(N, r))


def noise_widths(kernel_width, process_kernel_width, sensor_kernel_width, input_kernel_width):
    """(s_w, s_z, s_u) [s], the widths of the process noise, the sensor noise and the inputs'
    prior: kernel_width for both noises unless process_kernel_width or sensor_kernel_width is
    given, and input_kernel_width (default: the process width); 0 = white."""
    widths = []
    for value, field in ((process_kernel_width, "process_kernel_width"), (sensor_kernel_width, "sensor_kernel_width")):
        if value is None and kernel_width is None:
            raise AttendInputError(f"{field}: required (or kernel_width for both noises)")
        widths.append(checked_width(kernel_width if value is None else value, field))
    s_u = widths[0] if input_kernel_width is None else checked_width(input_kernel_width, "input_kernel_width")
    return widths[0], widths[1], s_u
