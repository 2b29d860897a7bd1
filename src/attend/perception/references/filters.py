"""Kalman filters and smoothers on the discrete zero-order-hold model of simulate() (see
:mod:`attend.perception.references` for the model and the conventions), and the validation
helpers the baselines share."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError, as_matrix, positive_scalar, require_finite, symmetric_matrix
from attend.models.linear import LinearSystem, as_linear_system


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

# --- validation helpers --------------------------------------------------------------------

def _system(system) -> LinearSystem:
    return as_linear_system(system)


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
    [state unit^2], R = diag(measurement_std^2) [output unit^2] (simulate adds dt w to x).
    system: the LinearSystem simulated; dt [s]; process_std, measurement_std: as passed to simulate()."""
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
    from scipy.linalg import cho_factor, cho_solve  # here: the result types load without scipy.linalg

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


def _checked_problem(system, dt, outputs, inputs, process_covariance, measurement_covariance,
                     inputs_field: str = "inputs"):
    """(system, dt, y (N, m), u (N, r), Q, R) checked: R must be positive definite."""
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    y = _outputs(system, outputs)
    u = _inputs(system, inputs, y.shape[0], inputs_field)
    Q = _covariance(process_covariance, system.n_states, "process_covariance")
    R = _covariance(measurement_covariance, system.n_outputs, "measurement_covariance")
    if np.linalg.eigvalsh(R).min() <= 0:
        raise AttendInputError("measurement_covariance: expected a positive definite covariance")
    return system, dt, y, u, Q, R


def _kalman(system, dt, outputs, inputs, process_covariance, measurement_covariance,
            initial_mean, initial_covariance, mode, lag=0, inputs_field="inputs"):
    system, dt, y, u, Q, R = _checked_problem(system, dt, outputs, inputs, process_covariance,
                                              measurement_covariance, inputs_field)
    m0, P0 = _initial(initial_mean, initial_covariance, system.n_states)
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
    """Rauch-Tung-Striebel smoother: x[k] | y[0..N-1] (same model as kalman_filter).

    system, dt [s], outputs (N, m), inputs (N, r) or None, process_covariance Q,
    measurement_covariance R, initial_mean m0 and initial_covariance P0: as :func:`kalman_filter`.

    Backward pass: J_k = P_k|k Ad' inv(P_k+1|k), m_k|N = m_k|k + J_k (m_k+1|N - m_k+1|k),
    P_k|N = P_k|k + J_k (P_k+1|N - P_k+1|k) J_k'.
    """
    return _kalman(system, dt, outputs, inputs, process_covariance, measurement_covariance,
                   initial_mean, initial_covariance, "smooth")


def kalman_filter_ignoring_input(system, dt, outputs, *, process_covariance, measurement_covariance,
                                 initial_mean=None, initial_covariance=None, lag: int = 0) -> KalmanEstimate:
    """The Kalman filter with the unknown input set to zero (u = 0), as the ACC 2020 paper compares.

    system, dt [s], outputs (N, m), process_covariance Q, measurement_covariance R, initial_mean
    m0, initial_covariance P0 and lag: as :func:`kalman_filter` (there is no ``inputs``).
    """
    return _kalman(system, dt, outputs, None, process_covariance, measurement_covariance,
                   initial_mean, initial_covariance, "filter", lag)


def steady_state_kalman_filter(system, dt, outputs, inputs=None, *, process_covariance,
                               measurement_covariance, initial_mean=None) -> KalmanEstimate:
    """Constant-gain Kalman filter: P solves the discrete algebraic Riccati equation
    P = Ad P Ad' - Ad P C' inv(C P C' + R) C P Ad' + Q (prediction covariance),
    K = P C' inv(C P C' + R); x[k|k] = x[k|k-1] + K (y[k] - C x[k|k-1]),
    x[k+1|k] = Ad x[k|k] + Bd u[k]. State std from (I - K C) P. system, dt [s], outputs (N, m),
    inputs (N, r) or None, process_covariance Q, measurement_covariance R and initial_mean m0:
    as :func:`kalman_filter`.
    """
    system, dt, y, u, Q, R = _checked_problem(system, dt, outputs, inputs, process_covariance,
                                              measurement_covariance)
    n = system.n_states
    m0, _ = _initial(initial_mean, None, n)
    Ad, Bd = system.discretize(dt)
    C = system.C
    from scipy.linalg import solve_discrete_are

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
    matrix); initial_input, initial_input_std: prior of u[0] (in the input's unit); smooth: RTS over the
    whole log instead of filtering; system, dt [s], outputs (N, m), process_covariance Q,
    measurement_covariance R, initial_mean, initial_covariance (of x[0]) and lag: as
    :func:`kalman_filter`. u[k] first acts on x[k+1],
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
