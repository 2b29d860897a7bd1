"""Baselines for nonlinear models: extended and unscented Kalman filters/smoothers, and a particle
smoother under (a finite model of) the true coloured noise.

Kalman-type baselines (white noise) work on the discrete model that
:func:`attend.perception.nonlinear.simulate_nonlinear` samples without noise::

    x[k] = F(x[k-1], u[k-1]) + q[k-1],  q ~ N(0, Q)        (Q = process_covariance)
    y[k] = g(x[k], u[k]) + r[k],        r ~ N(0, R)        (R = measurement_covariance)
    x[0] ~ N(m0, P0)

F integrates dx/dt = f(x, u) over one sample dt by RK4 with ``substeps`` sub-steps (u held).
Unknown inputs: pass ``input_variance`` instead of inputs; the state is augmented with
u[k] = u[k-1] + e, e ~ N(0, input_variance) (a random walk), started at ``input_mean``.
:func:`white_noise_covariances` gives the Q, R matching coloured noise (same variance per sample,
or same low-frequency power).

Results are :class:`attend.perception.baselines.KalmanEstimate` (time, states, inputs, state_std,
input_std first, as :class:`attend.perception.dem.DEMEstimate`).

:func:`particle_smoother`: a bootstrap particle filter whose state carries the coloured noises
(each channel an autoregressive model AR(q) fitted by Yule-Walker to rho(tau) =
exp(-tau^2/(4 s^2)) at lags 0..q samples), with the sensor noise marginalised exactly (given a
particle's path, z is known up to its AR innovation), and fixed-lag smoothing by tracing the
particles' ancestry. Its mean approximates the posterior mean under the coloured-noise model
(exact as the number of particles grows, up to the AR(q) fit of rho and the lag): a slow
reference, not an estimator for use.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_toeplitz

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, as_matrix, positive_scalar, require_finite, symmetric_matrix
from attend.noise import autocorrelation
from attend.perception.baselines import KalmanEstimate
from attend.perception.nonlinear import NonlinearSystem

__all__ = [
    "white_noise_covariances",
    "input_random_walk_variance",
    "extended_kalman",
    "unscented_kalman",
    "particle_smoother",
    "coloured_unscented_smoother",
    "ParticleEstimate",
]


def white_noise_covariances(system: NonlinearSystem, dt: float, kernel_width: float, process_std,
                            measurement_std, match: str = "variance") -> tuple[np.ndarray, np.ndarray]:
    """(Q, R) of a white-noise model for coloured noise of kernel width s [s] and standard
    deviations sigma_w [state unit / s], sigma_z [output unit]. R = diag(sigma_z^2);
    match "variance": Q = dt^2 diag(sigma_w^2), the same variance per sample (the linear
    baselines' :func:`attend.perception.baselines.simulation_covariances`); "power":
    Q = dt^2 diag(sigma_w^2) sum_k rho(k dt), the white noise of the same low-frequency power
    (larger by ~sqrt(4 pi) s / dt). On the Lorenz and pendulum reproductions "variance" gives the
    better Kalman estimates, so it is the default."""
    dt = positive_scalar(dt, "dt", "s")
    power = 1.0
    if match == "power":
        half = int(np.ceil(10 * kernel_width / dt))
        power = float(np.sum(autocorrelation(np.arange(-half, half + 1) * dt, kernel_width)))
    elif match != "variance":
        raise AttendInputError(f"match: expected 'variance' or 'power', got {match!r}")
    sw = np.broadcast_to(np.asarray(process_std, dtype=float), (system.n_states,))
    sz = np.broadcast_to(np.asarray(measurement_std, dtype=float), (system.n_outputs,))
    return np.diag(dt**2 * sw**2 * power), np.diag(sz**2)


def input_random_walk_variance(prior_precision, kernel_width: float, dt: float) -> np.ndarray:
    """Per-sample variance of the random walk that matches a smooth input prior: the variance of
    the one-sample increments v(t + dt) - v(t) of a Gaussian-kernel process of variance 1/P_v and
    width s_v [s], 2 (1 - rho(dt)) / P_v with rho(dt) = exp(-dt^2 / (4 s_v^2)). The Kalman
    baselines' random-walk input model then has the prior's local roughness.
    prior_precision: P_v (scalar or per input) [1/input unit^2]; kernel_width: s_v [s]; dt: sample time [s]."""
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    rho = float(autocorrelation(np.array([dt]), s)[0])
    return 2.0 * (1.0 - rho) / np.asarray(prior_precision, dtype=float)


# --- shared plumbing ----------------------------------------------------------------------------

def _rk4(system: NonlinearSystem, x, u, dt: float, substeps: int, w=None):
    """Integrate dx/dt = f(x, u) (+ w) over dt; x (n,) or (n, P) with a vectorized system."""
    h = dt / substeps
    call = (lambda state: system._call(system.f, state, u)) if x.ndim == 2 else (lambda state: system.flow(state, u))
    extra = 0.0 if w is None else w
    for _ in range(substeps):
        k1 = call(x) + extra
        k2 = call(x + 0.5 * h * k1) + extra
        k3 = call(x + 0.5 * h * k2) + extra
        k4 = call(x + h * k3) + extra
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


class _Model:
    """The discrete (possibly input-augmented) model z = [x; u] seen by the Kalman baselines."""

    def __init__(self, system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                 measurement_covariance, initial_mean, initial_covariance, substeps, known_inputs=None):
        if not isinstance(system, NonlinearSystem):
            raise AttendInputError("system: expected an attend NonlinearSystem")
        self.system = system
        self.dt = positive_scalar(dt, "dt", "s")
        n, r, m = system.n_states, system.n_inputs, system.n_outputs
        self.y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
        if self.y.shape[1] != m:
            raise AttendInputError(f"outputs: expected {m} columns, got {self.y.shape[1]}")
        N = self.y.shape[0]
        self.augmented = input_variance is not None and r > 0
        self.known = np.zeros(r, dtype=bool)
        if known_inputs is not None and r > 0:
            self.known = np.broadcast_to(np.asarray(known_inputs, dtype=bool), (r,)).copy()
        if self.augmented and not self.known.any():
            if inputs is not None:
                raise AttendInputError("inputs: give either measured inputs or input_variance (unknown inputs), not "
                                       "both (or say which are measured with known_inputs)")
            self.Qu = symmetric_matrix(input_variance, r, "input_variance", "variances")
            self.u = np.zeros((N, r))
        elif self.augmented and inputs is None:
            raise AttendInputError("inputs: known_inputs marks measured inputs: pass their values (N, r)")
        elif inputs is None:
            self.u = np.zeros((N, r))
        else:
            u = np.asarray(inputs, dtype=float).reshape(N, r) if np.size(inputs) == N * r else None
            if u is None:
                raise AttendInputError(f"inputs: expected shape ({N}, {r})")
            require_finite(u, "inputs")
            self.u = u
            if self.augmented:  # some measured, some unknown: the measured ones have no random walk
                Qu = symmetric_matrix(input_variance, r, "input_variance", "variances").copy()
                Qu[self.known, :] = 0.0
                Qu[:, self.known] = 0.0
                self.Qu = Qu
        self.Q = symmetric_matrix(process_covariance, n, "process_covariance", "variances")
        self.R = symmetric_matrix(measurement_covariance, m, "measurement_covariance", "variances")
        if np.linalg.eigvalsh(self.R).min() <= 0:
            raise AttendInputError("measurement_covariance: expected a positive definite covariance")
        size = n + (r if self.augmented else 0)
        self.size = size
        m0 = np.zeros(size)
        P0 = np.zeros((size, size))
        if initial_mean is not None:
            m0[:n] = np.asarray(initial_mean, dtype=float).reshape(n)
        if initial_covariance is not None:
            P0[:n, :n] = symmetric_matrix(initial_covariance, n, "initial_covariance", "variances")
        if self.augmented:
            if input_mean is not None:
                m0[n:] = np.asarray(input_mean, dtype=float).reshape(r)
            P0[n:, n:] = self.Qu
        self.m0, self.P0 = m0, P0
        self.substeps = int(substeps)
        self.Qz = np.zeros((size, size))
        self.Qz[:n, :n] = self.Q
        if self.augmented:
            self.Qz[n:, n:] = self.Qu

    def split(self, z, k):
        n = self.system.n_states
        if not self.augmented:
            return z, self.u[k]
        if self.known.any():
            return z[:n], np.where(self.known, self.u[k], z[n:])
        return z[:n], z[n:]

    def transition(self, z, k):
        """z[k] = F(z[k-1]) with the input of sample k - 1."""
        x, u = self.split(z, k - 1)
        x_new = _rk4(self.system, x, u, self.dt, self.substeps)
        return np.concatenate([x_new, u]) if self.augmented else x_new

    def observation(self, z, k):
        x, u = self.split(z, k)
        return self.system.observe(x, u)

    def result(self, means, covs, ll):
        n = self.system.n_states
        N = means.shape[0]
        std = np.sqrt(np.clip(np.diagonal(covs, axis1=1, axis2=2), 0, None))
        if self.augmented:
            inputs, input_std = means[:, n:].copy(), std[:, n:].copy()
            inputs[:, self.known] = self.u[:, self.known]
            input_std[:, self.known] = 0.0
        else:
            inputs, input_std = self.u, np.zeros_like(self.u)
        return KalmanEstimate(np.arange(N) * self.dt, means[:, :n], inputs, std[:, :n], input_std,
                              covs[:, :n, :n], float(ll))


def _jacobian(function, z):
    from attend.perception.nonlinear import finite_difference_jacobian

    return finite_difference_jacobian(function, z)


def _update(mean, cov, y, predicted, H_cov_cross, S):
    """Kalman update from predicted output, cross covariance C = Cov(z, y) and S = Cov(y)."""
    gain = np.linalg.solve(S, H_cov_cross.T).T
    innovation = y - predicted
    mean = mean + gain @ innovation
    cov = cov - gain @ S @ gain.T
    sign, logdet = np.linalg.slogdet(S)
    ll = -0.5 * (innovation @ np.linalg.solve(S, innovation) + logdet + len(y) * np.log(2 * np.pi))
    return mean, 0.5 * (cov + cov.T), ll


def _smooth(mf, Pf, mp, Pp, cross, smooth):
    """smooth True: RTS over the whole log; False: the filter; an integer L >= 0: fixed-lag,
    row k = x[k] | y[0..min(k + L, N - 1)] (an RTS pass of L steps from every sample)."""
    if smooth is True:
        return _rts(mf, Pf, mp, Pp, cross)
    if smooth is False or smooth == 0:
        return mf, Pf
    lag = int(smooth)
    N = mf.shape[0]
    gains = [np.linalg.lstsq(Pp[k + 1], cross[k].T, rcond=None)[0].T for k in range(N - 1)]
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(N):
        end = min(k + lag, N - 1)
        mean, cov = mf[end], Pf[end]
        for j in range(end - 1, k - 1, -1):
            G = gains[j]
            mean = mf[j] + G @ (mean - mp[j + 1])
            cov = Pf[j] + G @ (cov - Pp[j + 1]) @ G.T
        ms[k], Ps[k] = mean, 0.5 * (cov + cov.T)
    return ms, Ps


def _rts(mf, Pf, mp, Pp, cross):
    """Backward pass with G_k = C_k inv(Pp[k+1]), C_k = Cov(z[k], z[k+1] | y[0..k])."""
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(mf.shape[0] - 2, -1, -1):
        G = np.linalg.lstsq(Pp[k + 1], cross[k].T, rcond=None)[0].T
        ms[k] = mf[k] + G @ (ms[k + 1] - mp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
        Ps[k] = 0.5 * (Ps[k] + Ps[k].T)
    return ms, Ps


@with_single_blas_thread
def extended_kalman(system: NonlinearSystem, dt: float, outputs, inputs=None, *, process_covariance,
                    measurement_covariance, input_variance=None, input_mean=None, initial_mean=None,
                    initial_covariance=None, smooth: bool | int = True, substeps: int = 10) -> KalmanEstimate:
    """Extended Kalman filter (``smooth=False``), filter + RTS smoother (``True``) or fixed-lag
    smoother (``smooth=L`` samples: row k uses y[0..k+L], e.g. the DEM estimator's delay).

    system: NonlinearSystem; dt [s]; outputs (N, m); inputs (N, r) measured inputs (None: zero,
    or unknown with ``input_variance``); Q, R: white-noise covariances (scalar, diagonal or
    matrix); input_variance: random-walk variance of unknown inputs per sample [input unit^2];
    input_mean: their initial value; initial_mean/initial_covariance of x[0] (default 0, 0).
    Jacobians of F and g by central differences at the filtered / predicted means.
    """
    model = _Model(system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                   measurement_covariance, initial_mean, initial_covariance, substeps)
    N, d = model.y.shape[0], model.size
    mf, Pf = np.empty((N, d)), np.empty((N, d, d))
    mp, Pp = np.empty((N, d)), np.empty((N, d, d))
    cross = np.empty((max(N - 1, 0), d, d))
    mean, cov, ll = model.m0.copy(), model.P0.copy(), 0.0
    for k in range(N):
        if k > 0:
            Fz = _jacobian(lambda z: model.transition(z, k), mean)
            cross[k - 1] = cov @ Fz.T
            mean = model.transition(mean, k)
            cov = Fz @ cov @ Fz.T + model.Qz
        mp[k], Pp[k] = mean, cov
        H = _jacobian(lambda z: model.observation(z, k), mean)
        S = H @ cov @ H.T + model.R
        mean, cov, step_ll = _update(mean, cov, model.y[k], model.observation(mean, k), cov @ H.T, S)
        ll += step_ll
        mf[k], Pf[k] = mean, cov
    _check(mf, "extended_kalman")
    means, covs = _smooth(mf, Pf, mp, Pp, cross, smooth)
    return model.result(means, covs, ll)


def _sigma_points(mean, cov, alpha, beta, kappa):
    d = mean.shape[0]
    lam = alpha**2 * (d + kappa) - d
    try:
        root = np.linalg.cholesky((d + lam) * cov + 1e-12 * np.eye(d) * max(1.0, np.trace(cov)))
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh((d + lam) * cov)
        root = vectors * np.sqrt(np.clip(values, 0, None))
    points = np.vstack([mean, mean + root.T, mean - root.T])
    wm = np.full(2 * d + 1, 1 / (2 * (d + lam)))
    wc = wm.copy()
    wm[0] = lam / (d + lam)
    wc[0] = lam / (d + lam) + 1 - alpha**2 + beta
    return points, wm, wc


@with_single_blas_thread
def unscented_kalman(system: NonlinearSystem, dt: float, outputs, inputs=None, *, process_covariance,
                     measurement_covariance, input_variance=None, input_mean=None, initial_mean=None,
                     initial_covariance=None, smooth: bool | int = True, substeps: int = 10, alpha: float = 1.0,
                     beta: float = 2.0, kappa: float = 0.0, known_inputs=None) -> KalmanEstimate:
    """Unscented Kalman filter (``smooth=False``), filter + unscented RTS smoother (``True``,
    Sarkka 2008) or fixed-lag smoother (``smooth=L`` samples).

    Arguments as :func:`extended_kalman`; alpha, beta, kappa: the sigma-point spread
    (lambda = alpha^2 (d + kappa) - d; the defaults put the 2d points at +-sqrt(d) std with equal
    weights and none on the mean). known_inputs: with ``input_variance``, a mask (r,) of the inputs
    that are measured (their values from ``inputs``, no random walk); the others are estimated.
    """
    model = _Model(system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                   measurement_covariance, initial_mean, initial_covariance, substeps, known_inputs)
    means, covs, ll = _unscented(model.transition, model.observation, model.y, model.m0, model.P0, model.Qz,
                                 model.R, smooth, (alpha, beta, kappa), "unscented_kalman")
    return model.result(means, covs, ll)


def _unscented(transition, observation, y, m0, P0, Qz, R, smooth, spread, name):
    """Unscented filter (+ RTS smoother) for z[k] = transition(z[k-1], k) + q, y[k] = observation(z[k], k) + r."""
    N, d = y.shape[0], m0.shape[0]
    mf, Pf = np.empty((N, d)), np.empty((N, d, d))
    mp, Pp = np.empty((N, d)), np.empty((N, d, d))
    cross = np.empty((max(N - 1, 0), d, d))
    mean, cov, ll = m0.copy(), P0.copy(), 0.0
    for k in range(N):
        if k > 0:
            points, wm, wc = _sigma_points(mean, cov, *spread)
            moved = np.array([transition(point, k) for point in points])
            new_mean = wm @ moved
            cross[k - 1] = ((points - mean).T * wc) @ (moved - new_mean)
            cov = ((moved - new_mean).T * wc) @ (moved - new_mean) + Qz
            mean = new_mean
        mp[k], Pp[k] = mean, 0.5 * (cov + cov.T)
        points, wm, wc = _sigma_points(mean, cov, *spread)
        observed = np.array([observation(point, k) for point in points])
        predicted = wm @ observed
        S = ((observed - predicted).T * wc) @ (observed - predicted) + R
        C = ((points - mean).T * wc) @ (observed - predicted)
        mean, cov, step_ll = _update(mean, cov, y[k], predicted, C, S)
        ll += step_ll
        mf[k], Pf[k] = mean, cov
    _check(mf, name)
    means, covs = _smooth(mf, Pf, mp, Pp, cross, smooth)
    return means, covs, ll


@with_single_blas_thread
def coloured_unscented_smoother(system: NonlinearSystem, dt: float, outputs, inputs=None, *, kernel_width: float,
                                process_std, measurement_std, input_prior_std=None, input_prior_mean=None,
                                initial_mean=None, initial_std=None, ar_order: int = 3, substeps: int = 4,
                                smooth: bool = True, input_kernel_width: float | None = None) -> KalmanEstimate:
    """Unscented RTS smoother on the state augmented with AR(ar_order) models of the coloured
    noises (the same finite noise model as :func:`particle_smoother`): a Gaussian approximation of
    the posterior under the coloured-noise model, the strong reference beside the particle one.

    State [x; w~ (q values per state, newest first); v~ (unknown inputs); z~]: x[k] integrates
    f(x, v[k-1]) + sigma_w w~[k-1] over dt; each AR block advances by its Yule-Walker
    coefficients plus an innovation; y[k] = g(x[k], v[k]) + sigma_z z~[k] (+ white noise of
    variance 1e-6 sigma_z^2 for numerical stability). Arguments as :func:`particle_smoother`;
    input_kernel_width: the unknown inputs' own smoothness s_v [s] (default kernel_width).
    """
    if not isinstance(system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
    N = y.shape[0]
    unknown = inputs is None and r > 0 and input_prior_std is not None
    u_known = np.zeros((N, r)) if inputs is None else np.asarray(inputs, dtype=float).reshape(N, r)
    q = max(int(ar_order), 1)
    rho = autocorrelation(np.arange(q + 1) * dt, s)
    a, innovation = _yule_walker(rho, q)
    s_v = s if input_kernel_width is None else positive_scalar(input_kernel_width, "input_kernel_width", "s")
    rho_v = autocorrelation(np.arange(q + 1) * dt, s_v)
    a_v, innovation_v = _yule_walker(rho_v, q)
    sw = np.broadcast_to(np.asarray(process_std, dtype=float), (n,)).copy()
    sz = np.broadcast_to(np.asarray(measurement_std, dtype=float), (m,)).copy()
    rv = r if unknown else 0
    sv = np.broadcast_to(np.asarray(input_prior_std if unknown else 0.0, dtype=float), (r,))[:rv].copy()
    eta = np.zeros((N, r)) if input_prior_mean is None else np.broadcast_to(
        np.asarray(input_prior_mean, dtype=float), (N, r)).copy()
    channels = n + rv + m
    size = n + q * channels
    m0 = np.zeros(size)
    P0 = np.zeros((size, size))
    m0[:n] = 0.0 if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(n)
    P0[:n, :n] = np.diag(np.broadcast_to(np.asarray(0.0 if initial_std is None else initial_std, dtype=float), (n,)) ** 2)
    # per channel (w: n, v: rv, z: m) its AR coefficients, innovation variance and autocorrelation
    is_input = np.zeros(channels, dtype=bool)
    is_input[n: n + rv] = True
    coefficients = np.where(is_input[None, :], a_v[:, None], a[:, None])  # (q, channels)
    innovations = np.where(is_input, innovation_v, innovation)
    # AR block layout: index n + lag * channels + channel (lag 0 = newest)
    block = np.zeros((q * channels, q * channels))
    for c in range(channels):
        r_c = rho_v if is_input[c] else rho
        block[c::channels, c::channels] = [[r_c[abs(i - j)] for j in range(q)] for i in range(q)]
    P0[n:, n:] = block
    Qz = np.zeros((size, size))
    Qz[n: n + channels, n: n + channels] = np.diag(innovations)

    def noise(z):
        return z[n: n + channels]

    def transition(z, k):
        x = z[:n]
        newest = noise(z)
        w = sw * newest[:n]
        v = eta[k - 1] + sv * newest[n: n + rv] if unknown else u_known[k - 1]
        x_new = _rk4(system, x, v, dt, substeps, w=w)
        history = z[n:].reshape(q, channels)
        advanced = np.sum(coefficients * history, axis=0)
        return np.concatenate([x_new, advanced, history[:-1].ravel()])

    def observation(z, k):
        newest = noise(z)
        v = eta[k] + sv * newest[n: n + rv] if unknown else u_known[k]
        return system.observe(z[:n], v) + sz * newest[n + rv:]

    R = np.diag(1e-6 * sz**2)
    means, covs, ll = _unscented(transition, observation, y, m0, P0, Qz, R, smooth, (1.0, 2.0, 0.0),
                                 "coloured_unscented_smoother")
    std = np.sqrt(np.clip(np.diagonal(covs, axis1=1, axis2=2), 0, None))
    if unknown:
        inputs_out = eta + sv * means[:, n + n: n + n + rv]
        input_std = sv * std[:, n + n: n + n + rv]
    else:
        inputs_out, input_std = u_known, np.zeros((N, r))
    return KalmanEstimate(np.arange(N) * dt, means[:, :n], inputs_out, std[:, :n], input_std, covs[:, :n, :n], float(ll))


def _check(means, name):
    if not np.all(np.isfinite(means)):
        raise AttendInputError(f"{name}: the filter diverged (non-finite estimates); check the covariances")


# --- particle smoother ----------------------------------------------------------------------------

class ParticleEstimate(NamedTuple):
    """Particle smoother estimates: time (N,), states (N, n), inputs (N, r) posterior means,
    state_std, input_std their standard deviations, effective_sample_size (N,) after each update."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    effective_sample_size: np.ndarray


def _yule_walker(rho: np.ndarray, q: int):
    """AR coefficients a (q,) and innovation variance for unit variance, autocorrelation rho[0..q]."""
    if q == 0:
        return np.zeros(0), 1.0
    a = solve_toeplitz(rho[:q], rho[1: q + 1])
    return a, float(max(1.0 - a @ rho[1: q + 1], 1e-12))


@with_single_blas_thread
def particle_smoother(system: NonlinearSystem, dt: float, outputs, inputs=None, *, kernel_width: float,
                      process_std, measurement_std, input_prior_std=None, input_prior_mean=None,
                      initial_mean=None, initial_std=None, n_particles: int = 2000, ar_order: int = 3,
                      lag: int = 20, substeps: int = 4, seed=0,
                      input_kernel_width: float | None = None) -> ParticleEstimate:
    """Bootstrap particle filter + fixed-lag ancestry smoother under AR(q) coloured noise.

    The generative model is :func:`attend.perception.nonlinear.simulate_nonlinear`'s: w, z (and,
    for unknown inputs, v with mean input_prior_mean and standard deviation input_prior_std, the
    DEM input prior) are Gaussian-kernel coloured noises of width kernel_width [s], each channel
    approximated by an AR(ar_order) process with the autocorrelation of the true noise at lags
    0..ar_order. The sensor noise is marginalised: a particle's weight is the AR predictive density
    of its residual y[k] - g(x[k], v[k]). Row k is the weighted mean over the ancestry at sample
    min(k + lag, N - 1). inputs: measured inputs (N, r), or None with input_prior_std for unknown
    inputs. initial_mean / initial_std: the Gaussian of x[0]. The system's f and g must accept
    (n, n_particles) columns (NonlinearSystem(vectorized=True) or functions written with x[0],
    x[1], ... and np.array([...]) on arrays). O(N n_particles) model evaluations: slow, a reference.
    input_kernel_width: the unknown inputs' own smoothness s_v [s] (default kernel_width).
    """
    if not isinstance(system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
    N = y.shape[0]
    unknown = inputs is None and r > 0 and input_prior_std is not None
    u_known = np.zeros((N, r)) if inputs is None else np.asarray(inputs, dtype=float).reshape(N, r)
    rng = np.random.default_rng(seed)
    P = int(n_particles)
    q = int(ar_order)
    rho = autocorrelation(np.arange(q + 1) * dt, s)
    coefficients = [_yule_walker(rho, j) for j in range(q + 1)]
    s_v = s if input_kernel_width is None else positive_scalar(input_kernel_width, "input_kernel_width", "s")
    rho_v = autocorrelation(np.arange(q + 1) * dt, s_v)
    coefficients_v = [_yule_walker(rho_v, j) for j in range(q + 1)]
    sw = np.broadcast_to(np.asarray(process_std, dtype=float), (n,)).copy()
    sz = np.broadcast_to(np.asarray(measurement_std, dtype=float), (m,)).copy()
    sv = np.broadcast_to(np.asarray(input_prior_std if unknown else 0.0, dtype=float), (r,)).copy()
    eta = np.zeros((N, r)) if input_prior_mean is None else np.broadcast_to(
        np.asarray(input_prior_mean, dtype=float).reshape(-1, r) if np.ndim(input_prior_mean) else
        np.asarray(input_prior_mean, dtype=float), (N, r)).copy()
    m0 = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(n)
    s0 = np.zeros(n) if initial_std is None else np.broadcast_to(np.asarray(initial_std, dtype=float), (n,))

    # AR histories (newest first) of the unit-variance noises: process (n), inputs (r), per particle
    w_hist = np.zeros((q, n, P))
    v_hist = np.zeros((q, r, P))
    z_hist = np.zeros((q, m, P))  # residuals (sensor noise) of each particle's path, newest first

    def draw(history, k_available, table=coefficients):
        """Next unit-variance AR sample given the history (newest first) of k_available values."""
        j = min(k_available, q)
        a, variance = table[j]
        mean = np.tensordot(a, history[:j], axes=(0, 0)) if j else 0.0
        return mean + np.sqrt(variance) * rng.standard_normal(history.shape[1:])

    def push(history, value):
        if q:
            history[1:] = history[:-1].copy()
            history[0] = value

    x = m0[:, None] + s0[:, None] * rng.standard_normal((n, P))
    w_now = draw(w_hist, 0)
    v_now = draw(v_hist, 0, coefficients_v)
    states = np.empty((N, n, P))
    inputs_p = np.empty((N, r, P))
    weights = np.empty((N, P))
    ancestors = np.empty((N, P), dtype=int)
    ess = np.empty(N)
    log_w = np.zeros(P)
    for k in range(N):
        if k > 0:
            u_prev = (eta[k - 1][:, None] + sv[:, None] * v_now) if unknown else u_known[k - 1][:, None]
            x = _rk4(system, x, u_prev, dt, substeps, w=sw[:, None] * w_now)
            push(w_hist, w_now)
            push(v_hist, v_now)
            w_now = draw(w_hist, k)
            v_now = draw(v_hist, k, coefficients_v)
        u_now = (eta[k][:, None] + sv[:, None] * v_now) if unknown else u_known[k][:, None] * np.ones((1, P))
        residual = (y[k][:, None] - np.asarray(system._call(system.g, x, u_now), dtype=float)) / sz[:, None]
        j = min(k, q)
        a, variance = coefficients[j]
        predicted = np.tensordot(a, z_hist[:j], axes=(0, 0)) if j else 0.0
        log_w = log_w - 0.5 * np.sum((residual - predicted) ** 2, axis=0) / variance
        push(z_hist, residual)
        log_w -= log_w.max()
        w = np.exp(log_w)
        w /= w.sum()
        if not np.all(np.isfinite(x)):
            raise AttendInputError("particle_smoother: non-finite particles; check the model and the noise levels")
        states[k], inputs_p[k], weights[k] = x, u_now, w
        ess[k] = 1.0 / np.sum(w**2)
        ancestors[k] = np.arange(P)
        if ess[k] < P / 2 and k < N - 1:
            # systematic resampling: every carried quantity follows its ancestor
            index = np.searchsorted(np.cumsum(w), (rng.random() + np.arange(P)) / P)
            index = np.minimum(index, P - 1)
            ancestors[k] = index
            x = x[:, index]
            w_now, v_now = w_now[:, index], v_now[:, index]
            w_hist, v_hist, z_hist = w_hist[:, :, index], v_hist[:, :, index], z_hist[:, :, index]
            log_w = np.zeros(P)
    # fixed-lag smoothing: the particles of sample k are states[k][:, lineage] for the lineage of
    # the particles at sample end = k + lag (ancestors[j] maps particles after resampling at j).
    mean_x, std_x = np.empty((N, n)), np.empty((N, n))
    mean_v, std_v = np.empty((N, r)), np.empty((N, r))
    for k in range(N):
        end = min(k + lag, N - 1)
        lineage = np.arange(P)
        for j in range(end - 1, k - 1, -1):
            lineage = ancestors[j][lineage]
        w = weights[end]
        xs, vs = states[k][:, lineage], inputs_p[k][:, lineage]
        mean_x[k] = xs @ w
        std_x[k] = np.sqrt(np.clip(((xs - mean_x[k][:, None]) ** 2) @ w, 0, None))
        mean_v[k] = vs @ w
        std_v[k] = np.sqrt(np.clip(((vs - mean_v[k][:, None]) ** 2) @ w, 0, None))
    if not unknown:
        mean_v, std_v = u_known, np.zeros((N, r))
    return ParticleEstimate(np.arange(N) * dt, mean_x, mean_v, std_x, std_v, ess)
