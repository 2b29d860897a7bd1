"""Baselines on the same data as DEM: Kalman filters/smoothers and the exact Gaussian posterior.

All functions work on the discrete zero-order-hold model that :func:`attend.systems.simulate`
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
  prior on the inputs). Its mean is the minimum-mean-square-error estimate under the model:
  the limit no estimator can beat. O((N m)^3): for logs up to a few thousand samples.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_discrete_are, solve_triangular

from attend._validation import AttendInputError, as_matrix, positive_scalar, require_finite, symmetric_matrix
from attend.noise import autocorrelation, gaussian_kernel
from attend.systems import LinearSystem

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
]


class KalmanEstimate(NamedTuple):
    """Kalman-type estimates at every sample.

    time (N,) [s]; states (N, n) posterior means; inputs (N, r) the inputs used (given, zero, or
    estimated by the augmented filter); state_std (N, n), input_std (N, r) posterior standard
    deviations (input_std is 0 for given inputs); state_covariance (N, n, n);
    log_likelihood: log p(y[0..N-1]) under the filter's model (innovations form).
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    state_covariance: np.ndarray
    log_likelihood: float


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


# --- validation helpers --------------------------------------------------------------------

def _system(system) -> LinearSystem:
    if not isinstance(system, LinearSystem):
        raise AttendInputError("system: expected an attend.LinearSystem")
    return system


def _covariance(value, size: int, field: str) -> np.ndarray:
    """A covariance given as a scalar (times I), a vector (diagonal) or a symmetric PSD matrix."""
    return symmetric_matrix(value, size, field, "variances")


def _std_vector(value, size: int, field: str) -> np.ndarray:
    try:
        array = np.broadcast_to(np.asarray(value, dtype=float), (size,)).copy()
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a number or {size} numbers, got {value!r}") from None
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise AttendInputError(f"{field}: expected finite standard deviations >= 0, got {value!r}")
    return array


def _outputs(system: LinearSystem, outputs) -> np.ndarray:
    m = system.n_outputs
    y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
    if y.shape[1] != m:
        raise AttendInputError(f"outputs: expected {m} columns (one per output), got {y.shape[1]}")
    if y.shape[0] < 1:
        raise AttendInputError("outputs: expected at least 1 sample")
    return y


def _inputs(system: LinearSystem, inputs, n_samples: int, field: str = "inputs") -> np.ndarray:
    r = system.n_inputs
    if inputs is None:
        return np.zeros((n_samples, r))
    u = np.asarray(inputs, dtype=float) if np.ndim(inputs) else np.full((n_samples, r), float(inputs))
    if u.ndim == 1 and u.shape[0] == r and n_samples != r:
        u = np.broadcast_to(u, (n_samples, r))
    u = as_matrix(u, field, cols=r if u.ndim == 2 else 1)
    if u.shape != (n_samples, r):
        raise AttendInputError(f"{field}: expected shape ({n_samples}, {r}), got {u.shape}")
    return u


def _initial(initial_mean, initial_covariance, n: int) -> tuple[np.ndarray, np.ndarray]:
    mean = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(-1)
    if mean.shape != (n,):
        raise AttendInputError(f"initial_mean: expected {n} numbers, got shape {np.shape(initial_mean)}")
    require_finite(mean, "initial_mean")
    cov = np.zeros((n, n)) if initial_covariance is None else _covariance(initial_covariance, n, "initial_covariance")
    return mean, cov


def _lag(lag) -> int:
    if isinstance(lag, bool) or int(lag) != lag or lag < 0:
        raise AttendInputError(f"lag: expected an integer number of samples >= 0, got {lag!r}")
    return int(lag)


def simulation_covariances(system: LinearSystem, dt: float, process_std, measurement_std
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(Q, R) of the white-noise model matching simulate(): Q = dt^2 diag(process_std^2)
    [state unit^2], R = diag(measurement_std^2) [output unit^2] (simulate adds dt w to x)."""
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    sw = _std_vector(process_std, system.n_states, "process_std")
    sz = _std_vector(measurement_std, system.n_outputs, "measurement_std")
    return np.diag((dt * sw) ** 2), np.diag(sz**2)


# --- the Kalman recursion (generic matrices) -----------------------------------------------

def _filter_core(F, offsets, Q, H, R, y, m0, P0):
    """Kalman filter for x[k] = F x[k-1] + offsets[k-1] + q, y[k] = H x[k] + r.

    Returns filtered means/covs (N, d), (N, d, d), predicted means/covs (x[k] | y[0..k-1]) and
    the log-likelihood.
    """
    N, d = y.shape[0], F.shape[0]
    mf = np.empty((N, d))
    Pf = np.empty((N, d, d))
    mp = np.empty((N, d))
    Pp = np.empty((N, d, d))
    mean, cov = m0, P0
    log_likelihood = 0.0
    m = y.shape[1]
    for k in range(N):
        if k > 0:
            mean = F @ mean + offsets[k - 1]
            cov = F @ cov @ F.T + Q
        mp[k], Pp[k] = mean, cov
        innovation = y[k] - H @ mean
        S = H @ cov @ H.T + R
        factor = cho_factor(S, lower=True)
        gain = cho_solve(factor, H @ cov).T  # cov H' inv(S)
        mean = mean + gain @ innovation
        cov = cov - gain @ H @ cov
        cov = 0.5 * (cov + cov.T)
        mf[k], Pf[k] = mean, cov
        log_likelihood -= 0.5 * (
            innovation @ cho_solve(factor, innovation)
            + 2 * np.sum(np.log(np.diag(factor[0])))
            + m * np.log(2 * np.pi)
        )
    return mf, Pf, mp, Pp, log_likelihood


def _smoother_gains(F, Pf, Pp):
    """RTS gains J[k] = Pf[k] F' inv(Pp[k+1]), k = 0..N-2."""
    N = Pf.shape[0]
    gains = np.empty((max(N - 1, 0),) + Pf.shape[1:])
    for k in range(N - 1):
        gains[k] = np.linalg.lstsq(Pp[k + 1], F @ Pf[k], rcond=None)[0].T
    return gains


def _rts(mf, Pf, mp, Pp, gains):
    N = mf.shape[0]
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(N - 2, -1, -1):
        J = gains[k]
        ms[k] = mf[k] + J @ (ms[k + 1] - mp[k + 1])
        Ps[k] = Pf[k] + J @ (Ps[k + 1] - Pp[k + 1]) @ J.T
    return ms, 0.5 * (Ps + np.swapaxes(Ps, 1, 2))


def _fixed_lag(mf, Pf, mp, Pp, gains, lag):
    """x[k] | y[0..min(k+lag, N-1)]: an RTS pass of ``lag`` steps started at every sample."""
    N = mf.shape[0]
    if lag == 0:
        return mf, Pf
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(N):
        end = min(k + lag, N - 1)
        mean, cov = mf[end], Pf[end]
        for j in range(end - 1, k - 1, -1):
            J = gains[j]
            mean = mf[j] + J @ (mean - mp[j + 1])
            cov = Pf[j] + J @ (cov - Pp[j + 1]) @ J.T
        ms[k], Ps[k] = mean, 0.5 * (cov + cov.T)
    return ms, Ps


def _kalman(system, dt, outputs, inputs, process_covariance, measurement_covariance,
            initial_mean, initial_covariance, mode, lag=0, inputs_field="inputs"):
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    y = _outputs(system, outputs)
    u = _inputs(system, inputs, y.shape[0], inputs_field)
    n = system.n_states
    Q = _covariance(process_covariance, n, "process_covariance")
    R = _covariance(measurement_covariance, system.n_outputs, "measurement_covariance")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise AttendInputError("measurement_covariance: expected a positive definite covariance")
    m0, P0 = _initial(initial_mean, initial_covariance, n)
    Ad, Bd = system.discretize(dt)
    mf, Pf, mp, Pp, ll = _filter_core(Ad, u @ Bd.T, Q, system.C, R, y, m0, P0)
    if mode == "smooth":
        means, covs = _rts(mf, Pf, mp, Pp, _smoother_gains(Ad, Pf, Pp))
    else:
        lag = _lag(lag)
        means, covs = _fixed_lag(mf, Pf, mp, Pp, _smoother_gains(Ad, Pf, Pp) if lag else None, lag)
    std = np.sqrt(np.clip(np.diagonal(covs, axis1=1, axis2=2), 0, None))
    return KalmanEstimate(np.arange(y.shape[0]) * dt, means, u, std, np.zeros_like(u), covs, float(ll))


def kalman_filter(system, dt, outputs, inputs=None, *, process_covariance, measurement_covariance,
                  initial_mean=None, initial_covariance=None, lag: int = 0) -> KalmanEstimate:
    """Kalman filter on the ZOH model x[k] = Ad x[k-1] + Bd u[k-1] + q, y[k] = C x[k] + r.

    system: LinearSystem; dt: sample time [s]; outputs: (N, m); inputs: (N, r) known inputs
    (None: zero); process_covariance Q [state unit^2 per step] and measurement_covariance R
    [output unit^2]: scalars (times I), vectors (diagonal) or matrices; initial_mean m0 and
    initial_covariance P0 of x[0] (default 0 and 0: x[0] = 0 known, as simulate() starts);
    lag: row k estimates x[k] from y[0..k+lag] (0: the filter; > 0: fixed-lag smoother, e.g. the
    DEM observer's embedding delay).
    """
    return _kalman(system, dt, outputs, inputs, process_covariance, measurement_covariance,
                   initial_mean, initial_covariance, "filter", lag)


def rts_smoother(system, dt, outputs, inputs=None, *, process_covariance, measurement_covariance,
                 initial_mean=None, initial_covariance=None) -> KalmanEstimate:
    """Rauch-Tung-Striebel smoother: x[k] | y[0..N-1] (same model and arguments as kalman_filter).

    Backward pass: J_k = P_k|k Ad' inv(P_k+1|k), m_k|N = m_k|k + J_k (m_k+1|N - m_k+1|k),
    P_k|N = P_k|k + J_k (P_k+1|N - P_k+1|k) J_k'.
    """
    return _kalman(system, dt, outputs, inputs, process_covariance, measurement_covariance,
                   initial_mean, initial_covariance, "smooth")


def kalman_filter_ignoring_input(system, dt, outputs, *, process_covariance, measurement_covariance,
                                 initial_mean=None, initial_covariance=None, lag: int = 0) -> KalmanEstimate:
    """The Kalman filter with the unknown input set to zero (u = 0), as the ACC 2020 paper compares.

    Same arguments as :func:`kalman_filter` without ``inputs``.
    """
    return _kalman(system, dt, outputs, None, process_covariance, measurement_covariance,
                   initial_mean, initial_covariance, "filter", lag)


def steady_state_kalman_filter(system, dt, outputs, inputs=None, *, process_covariance,
                               measurement_covariance, initial_mean=None) -> KalmanEstimate:
    """Constant-gain Kalman filter: P solves the discrete algebraic Riccati equation
    P = Ad P Ad' - Ad P C' inv(C P C' + R) C P Ad' + Q (prediction covariance),
    K = P C' inv(C P C' + R); x[k|k] = x[k|k-1] + K (y[k] - C x[k|k-1]),
    x[k+1|k] = Ad x[k|k] + Bd u[k]. State std from (I - K C) P. Arguments as kalman_filter.
    """
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    y = _outputs(system, outputs)
    u = _inputs(system, inputs, y.shape[0])
    n = system.n_states
    Q = _covariance(process_covariance, n, "process_covariance")
    R = _covariance(measurement_covariance, system.n_outputs, "measurement_covariance")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise AttendInputError("measurement_covariance: expected a positive definite covariance")
    m0, _ = _initial(initial_mean, None, n)
    Ad, Bd = system.discretize(dt)
    C = system.C
    P = solve_discrete_are(Ad.T, C.T, Q, R)
    S = C @ P @ C.T + R
    K = np.linalg.solve(S, C @ P).T
    Pf = P - K @ C @ P
    offsets = u @ Bd.T
    means = np.empty((y.shape[0], n))
    mean = m0
    for k in range(y.shape[0]):
        if k > 0:
            mean = Ad @ mean + offsets[k - 1]
        mean = mean + K @ (y[k] - C @ mean)
        means[k] = mean
    std = np.broadcast_to(np.sqrt(np.clip(np.diag(Pf), 0, None)), means.shape)
    covs = np.broadcast_to(Pf, (y.shape[0], n, n))
    return KalmanEstimate(np.arange(y.shape[0]) * dt, means, u, std, np.zeros_like(u), covs, float("nan"))


def augmented_kalman_filter(system, dt, outputs, *, process_covariance, measurement_covariance,
                            input_variance, initial_mean=None, initial_covariance=None,
                            initial_input=0.0, initial_input_std=1.0, lag: int = 0,
                            smooth: bool = False) -> KalmanEstimate:
    """Kalman filter on the augmented state [x; u] with the input a random walk:

        [x; u][k] = [[Ad, Bd], [0, I]] [x; u][k-1] + [q; e],  e ~ N(0, input_variance)
        y[k] = [C, 0] [x; u][k] + r

    input_variance: random-walk increment variance per sample [input unit^2] (scalar, vector or
    matrix); initial_input, initial_input_std: prior of u[0] [input unit]; smooth: RTS over the
    whole log instead of filtering; other arguments as kalman_filter. u[k] first acts on x[k+1],
    so the filtered input estimate lags one sample (use lag >= 1 or smooth to remove it).
    """
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    y = _outputs(system, outputs)
    n, r = system.n_states, system.n_inputs
    Q = _covariance(process_covariance, n, "process_covariance")
    R = _covariance(measurement_covariance, system.n_outputs, "measurement_covariance")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise AttendInputError("measurement_covariance: expected a positive definite covariance")
    Qu = _covariance(input_variance, r, "input_variance")
    m0, P0 = _initial(initial_mean, initial_covariance, n)
    u0 = np.broadcast_to(np.asarray(initial_input, dtype=float), (r,))
    require_finite(u0, "initial_input")
    su0 = _std_vector(initial_input_std, r, "initial_input_std")
    Ad, Bd = system.discretize(dt)
    F = np.block([[Ad, Bd], [np.zeros((r, n)), np.eye(r)]])
    H = np.hstack([system.C, np.zeros((system.n_outputs, r))])
    Qa = np.block([[Q, np.zeros((n, r))], [np.zeros((r, n)), Qu]])
    Pa = np.block([[P0, np.zeros((n, r))], [np.zeros((r, n)), np.diag(su0**2)]])
    ma = np.concatenate([m0, u0])
    offsets = np.zeros((y.shape[0], n + r))
    mf, Pf, mp, Pp, ll = _filter_core(F, offsets, Qa, H, R, y, ma, Pa)
    gains = _smoother_gains(F, Pf, Pp) if (smooth or lag) else None
    if smooth:
        means, covs = _rts(mf, Pf, mp, Pp, gains)
    else:
        means, covs = _fixed_lag(mf, Pf, mp, Pp, gains, _lag(lag))
    std = np.sqrt(np.clip(np.diagonal(covs, axis1=1, axis2=2), 0, None))
    return KalmanEstimate(np.arange(y.shape[0]) * dt, means[:, :n], means[:, n:], std[:, :n], std[:, n:],
                          covs[:, :n, :n], float(ll))


# --- exact Gaussian posterior --------------------------------------------------------------

def coloured_noise_correlation(n_samples: int, dt: float, kernel_width: float) -> np.ndarray:
    """(N, N) correlation matrix of the samples of attend.noise.coloured_noise.

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


def exact_posterior(system, dt, outputs, inputs=None, *, kernel_width=None, process_std, measurement_std,
                    input_prior_mean=None, input_prior_std=None, initial_mean=None, initial_std=0.0,
                    jitter: float = 1e-12, return_covariance: bool = False,
                    process_kernel_width=None, sensor_kernel_width=None, input_kernel_width=None,
                    causal: bool = False) -> ExactPosterior:
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
    process_std, measurement_std: per-sample standard deviations as passed to simulate();
    initial_mean m0 (default 0) and initial_std s0 (default 0: x[0] known, as simulate() starts).
    causal=True also returns ``causal_states`` / ``causal_inputs``: E[x[k] | y[0..k]] for every k,
    the best causal estimate under the model, read from the same Cholesky factor (the innovations
    of y in time order).
    Cost O((N min(m, n))^3) time, O((N (n + m + r))^2) memory: for logs up to a few thousand samples.
    """
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    s_w, s_z, s_u = _noise_widths(kernel_width, process_kernel_width, sensor_kernel_width, input_kernel_width)
    y = _outputs(system, outputs)
    N = y.shape[0]
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    sw = _std_vector(process_std, n, "process_std")
    sz = _std_vector(measurement_std, m, "measurement_std")
    m0 = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(-1)
    if m0.shape != (n,):
        raise AttendInputError(f"initial_mean: expected {n} numbers, got shape {np.shape(initial_mean)}")
    require_finite(m0, "initial_mean")
    s0 = _std_vector(initial_std, n, "initial_std")
    if not (np.isfinite(jitter) and jitter >= 0):
        raise AttendInputError(f"jitter: expected a finite number >= 0, got {jitter!r}")
    known = inputs is not None
    if known:
        u_mean = _inputs(system, inputs, N)
        su = np.zeros(r)
    else:
        if input_prior_mean is None or input_prior_std is None:
            raise AttendInputError(
                "input_prior_mean, input_prior_std: required when the inputs are unknown (inputs=None)"
            )
        u_mean = _inputs(system, input_prior_mean, N, "input_prior_mean")
        su = _std_vector(input_prior_std, r, "input_prior_std")

    Ad, Bd = system.discretize(dt)
    L, Phi = _transfer_matrix(Ad, N)
    K = coloured_noise_correlation(N, dt, s_w)
    K_z = K if s_z == s_w else coloured_noise_correlation(N, dt, s_z)
    # prior of the stacked drive d[k] = Bd u[k] + dt w[k] and of the states
    drive_mean = (u_mean @ Bd.T).reshape(-1)
    drive_cov = np.kron(K, np.diag((dt * sw) ** 2))
    if not known:
        if s_u <= 0:
            raise AttendInputError("input_kernel_width: expected a width > 0 [s] for the inputs' prior")
        Ku = autocorrelation(dt * (np.arange(N)[:, None] - np.arange(N)[None, :]), s_u)
        input_cov = np.kron(Ku, np.diag(su**2))  # (N r, N r)
        Bbig = np.kron(np.eye(N), Bd)  # d = Bbig u + dt w
        drive_cov = drive_cov + Bbig @ input_cov @ Bbig.T
    x_mean = Phi @ m0 + L @ drive_mean
    x_cov = L @ drive_cov @ L.T + Phi @ np.diag(s0**2) @ Phi.T
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
    y_cov[np.diag_indices_from(y_cov)] += jitter * np.mean(np.diag(y_cov))
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
    # latent z = [x; u] (u only when unknown)
    if known:
        z_mean, zy_cov, z_var = x_mean, xy_cov, np.diag(x_cov)
    else:
        LB = L @ Bbig
        uy_cov = input_cov @ LB.T @ Cbig.T  # Cov(u, y_q)
        z_mean = np.concatenate([x_mean, u_mean.reshape(-1)])
        zy_cov = np.vstack([xy_cov, uy_cov])
        z_var = np.concatenate([np.diag(x_cov), np.diag(input_cov)])
    G = solve_triangular(chol, zy_cov.T, lower=True)  # inv(chol) S_yz
    post_mean = z_mean + G.T @ white
    post_var = np.clip(z_var - np.sum(G**2, axis=0), 0, None)
    covariance = None
    if return_covariance:
        if known:
            z_cov = x_cov
        else:
            xu_cov = LB @ input_cov  # Cov(x, u)
            z_cov = np.block([[x_cov, xu_cov], [xu_cov.T, input_cov]])
        covariance = z_cov - G.T @ G
        covariance = 0.5 * (covariance + covariance.T)
    causal_states = causal_inputs = None
    if causal:  # E[z at k | y[0..k]]: only the innovations of samples <= k
        contributions = (G * white[:, None]).reshape(N, q, -1).sum(axis=1)  # (time of y, latent)
        latent_time = np.concatenate([np.repeat(np.arange(N), n), [] if known else np.repeat(np.arange(N), r)])
        mask = np.arange(N)[:, None] <= latent_time[None, :].astype(int)
        causal_mean = z_mean + np.sum(contributions * mask, axis=0)
        causal_states = causal_mean[: N * n].reshape(N, n)
        causal_inputs = u_mean if known else causal_mean[N * n:].reshape(N, r)
    states = post_mean[: N * n].reshape(N, n)
    state_std = np.sqrt(post_var[: N * n]).reshape(N, n)
    if known:
        est_inputs, input_std = u_mean, np.zeros((N, r))
    else:
        est_inputs = post_mean[N * n:].reshape(N, r)
        input_std = np.sqrt(post_var[N * n:]).reshape(N, r)
    return ExactPosterior(np.arange(N) * dt, states, est_inputs, state_std, input_std, covariance,
                          float(log_likelihood), causal_states, causal_inputs)


def _noise_widths(kernel_width, process_kernel_width, sensor_kernel_width, input_kernel_width):
    """(s_w, s_z, s_u) [s] from the shared width and the per-noise overrides (0 = white)."""
    def width(value, field):
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise AttendInputError(f"{field}: expected a number >= 0 [s], got {value!r}") from None
        if not np.isfinite(number) or number < 0:
            raise AttendInputError(f"{field}: expected a finite number >= 0 [s], got {value!r}")
        return number

    widths = []
    for value, field in ((process_kernel_width, "process_kernel_width"), (sensor_kernel_width, "sensor_kernel_width")):
        if value is None and kernel_width is None:
            raise AttendInputError(f"{field}: required (or kernel_width for both noises)")
        widths.append(width(kernel_width if value is None else value, field))
    s_u = widths[0] if input_kernel_width is None else width(input_kernel_width, "input_kernel_width")
    return widths[0], widths[1], s_u
