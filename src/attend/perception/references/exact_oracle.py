"""The exact Gaussian posterior of states and unknown inputs on ill-conditioned models, computed
twice — a square-root form in float64 and the covariance form in double-double (~32 digits) —
so that its accuracy is shown, not assumed.

The model is :func:`attend.perception.references.exact_posterior`'s (simulate()'s process, the
inputs' Gaussian-process prior)::

    x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1],      y[k] = C x[k] + z[k],      x[0] ~ N(m0, diag(s0^2))
    w_c = sigma_w,c (h_w * e_w,c),  z_c = sigma_z,c (h_z * e_z,c)    h: gaussian_kernel(dt, s) (simulate()'s kernel)
    u_c = eta_c + sigma_u,c f_c,  Cov(f_c[i], f_c[j]) = rho((i - j) dt) = exp(-((i - j) dt)^2 / (4 s_u^2))

Every random quantity is a linear map of one white vector v ~ N(0, I): v = [v0 (x[0]); e_w
(the process noise's white samples, with the kernel's margins); f (the inputs, through a
symmetric square root of the N x N correlation rho); e_z]. Then y = G v + y_mean exactly and
[x; u] = M v + mean, so

    posterior mean of v = G^+ (y - y_mean) (the minimum-norm solution),  posterior Cov(v) = I - G^+ G.

Square-root form (float64, :func:`oracle_posterior`'s ``states`` etc.): a complete QR factor of
G' = [Q1 Q2] [R; 0] gives G^+ = Q1 inv(R'), and the posterior covariance of [x; u] is
(M Q2)(M Q2)' (no difference of large numbers). Householder QR is backward stable row by row
of G, so each output's scale does not matter; the error grows with cond(G), the square root of
the covariance form's cond(G G').

Covariance form (double-double, the check): G and M built again in double-double from the same
float64 model (Ad, Bd, C, the kernels, the square root of rho, taken as exact), S = G G' (no
jitter), its Cholesky factor, mean = mean + M G' inv(S) (y - y_mean), and on a subset of
samples the variances diag(M M') - diag(M G' inv(S) G M'). With unit roundoff ~5e-32 it holds
up to cond(S) ~ 1e25.

The two agree (``agreement``) when neither is spoiled by rounding: their mean difference in
units of the posterior std and their std's relative difference are printed by the benchmark
(benchmarks/bench_unknown_inputs.py) for every case. Cost: O(N m D^2) time with D = dim(v) ~
N (n + r + m); the double-double part ~1-10 s at N m ~ 300 (for windows of 40-100 samples).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import qr, solve_triangular

from attend._validation import AttendInputError, positive_scalar
from attend.models.noise import autocorrelation, gaussian_kernel
from attend.perception.references import double_double as dd
from attend.perception.references.exact import noise_widths
from attend.perception.references.filters import _inputs, _outputs, _std_vector, _system


class OracleAgreement(NamedTuple):
    """How far the square-root (float64) and covariance (double-double) computations are apart.

    mean_in_std: max over samples and channels of |mean_64 - mean_dd| / std (states and inputs);
    std_relative: max |std_64 / std_dd - 1| over the checked samples (``variance_samples``);
    condition: cond(G G') (the covariance form's condition number, from G's singular values,
    after scaling each output row of G to unit norm); variance_samples: the samples checked."""

    mean_in_std: float
    std_relative: float
    condition: float
    variance_samples: np.ndarray


class OraclePosterior(NamedTuple):
    """The exact posterior's means and marginal std (square-root form, float64) and its check.

    time (N,) [s]; states (N, n), inputs (N, r) (the given ones when known), state_std,
    input_std; extended_states, extended_inputs: the double-double covariance form's means
    (rounded to float64), None when not computed; agreement: :class:`OracleAgreement` (None
    without the check)."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    extended_states: np.ndarray | None
    extended_inputs: np.ndarray | None
    agreement: OracleAgreement | None


class _Model(NamedTuple):
    """The float64 primitives both computations take as exact."""

    Ad: np.ndarray
    Bd: np.ndarray
    C: np.ndarray
    process_kernel: np.ndarray   # h_w (odd length), [1] when white
    sensor_kernel: np.ndarray
    input_root: np.ndarray | None  # (N, N) symmetric square root of rho, None when inputs are known
    process_scale: np.ndarray    # dt sigma_w (n,)
    sensor_std: np.ndarray       # sigma_z (m,)
    input_std: np.ndarray        # sigma_u of the estimated inputs (e,)
    estimated: np.ndarray        # indices of the estimated inputs
    initial_std: np.ndarray      # s0 (n,)
    floor: tuple = (0.0, 0.0, 0.0)  # white parts' std (relative) of w, z, u: sqrt(white_floor) where coloured


def _kernel(dt: float, width: float) -> np.ndarray:
    return np.ones(1) if width == 0 else gaussian_kernel(dt, width)


def correlation_root(N: int, dt: float, width: float) -> np.ndarray:
    """Symmetric square root V sqrt(max(lambda, 0)) V' of the (N, N) correlation rho((i - j) dt)."""
    lags = dt * (np.arange(N)[:, None] - np.arange(N)[None, :])
    values, vectors = np.linalg.eigh(autocorrelation(lags, width))
    return (vectors * np.sqrt(np.clip(values, 0, None))) @ vectors.T


class _Layout(NamedTuple):
    """Column blocks of the white vector v: x[0]; e_w (per state, time-major: column n*j + c);
    the inputs' white vector (per estimated input, column e*i + c); e_z; then the white floors'
    own white samples of w, z, u (column blocks floor_w, floor_z, floor_u; -1 when absent)."""

    x0: np.ndarray       # columns of v0 (states with s0 > 0)
    initial: np.ndarray  # the states they belong to
    w: int               # first column of e_w
    u: int
    z: int
    floor_w: int
    floor_z: int
    floor_u: int
    size: int


def _layout(model: _Model, N: int) -> _Layout:
    n, m = model.Ad.shape[0], model.C.shape[0]
    e = 0 if model.input_root is None else model.estimated.size
    initial = np.flatnonzero(model.initial_std > 0)
    w = initial.size
    u = w + n * (N - 1 + model.process_kernel.size - 1)
    z = u + e * N
    end = z + m * (N + model.sensor_kernel.size - 1)
    starts = []
    for std, count in zip(model.floor, (n * (N - 1), m * N, e * N)):
        starts.append(end if std > 0 and count else -1)
        end += count if std > 0 else 0
    return _Layout(np.arange(initial.size), initial, w, u, z, *starts, end)


def _placed(shape, rows, columns, left, right) -> dd.DD:
    """A double-double array of ``shape`` holding the products left * right (exact, broadcast to
    the index arrays rows, columns) there and 0 elsewhere."""
    out = dd.zeros(shape)
    product = dd.multiply(dd.dd(left), dd.dd(right))
    out.hi[rows, columns], out.lo[rows, columns] = product.hi, product.lo
    return out


def _stack(blocks: list, extended: bool):
    if extended:
        return dd.DD(np.stack([b.hi for b in blocks]), np.stack([b.lo for b in blocks]))
    return np.stack(blocks)


def _maps(model: _Model, N: int, lay: _Layout, extended: bool):
    """(X (N, n, D), U (N, e, D), Y (N, m, D)): x[k] = X[k] v, u[k] - eta[k] = U[k] v, y[k] - y_mean[k] = Y[k] v,
    in float64 or (extended) double-double. Every entry placed from the model is a product of two
    float64 numbers (exact in double-double, rounded once in float64); the recursions
    x[k] = Ad x[k-1] + Bd u[k-1] + drive and y[k] = C x[k] + noise run in the chosen arithmetic."""
    n, m = model.Ad.shape[0], model.C.shape[0]
    e = model.estimated.size
    D = lay.size
    hw, hz = model.process_kernel, model.sensor_kernel
    add, matmul = (dd.add, dd.matmul) if extended else (np.add, np.matmul)

    def cast(value):
        return value if extended else value.value()

    def lift(array):
        return dd.dd(array) if extended else array

    U = []
    for k in range(N):  # u_c[k] - eta_c[k] = sigma_u,c (sum_i root[k, i] f_c[i] + sqrt(f) g_c[k])
        row = dd.zeros((e, D))
        if e:
            columns = lay.u + np.arange(e)[:, None] + e * np.arange(N)[None, :]
            row = _placed((e, D), np.arange(e)[:, None], columns, model.input_std[:, None],
                          model.input_root[k][None, :])
            if lay.floor_u >= 0:
                row = dd.add(row, _placed((e, D), np.arange(e), lay.floor_u + e * k + np.arange(e), model.input_std,
                                          model.floor[2]))
        U.append(cast(row))
    x0 = np.zeros((n, D))
    x0[lay.initial, lay.x0] = model.initial_std[lay.initial]
    X = [lift(x0)]
    Ad, Bd = lift(model.Ad), lift(model.Bd[:, model.estimated])
    for k in range(1, N):  # drive into x[k]: dt sigma_w (h_w * e_w)[k-1] (taps over e_w[k-1 .. k-1+2h]) + floor
        columns = lay.w + n * (k - 1 + np.arange(hw.size))[None, :] + np.arange(n)[:, None]
        drive = _placed((n, D), np.arange(n)[:, None], columns, model.process_scale[:, None], hw[None, :])
        if lay.floor_w >= 0:
            drive = dd.add(drive, _placed((n, D), np.arange(n), lay.floor_w + n * (k - 1) + np.arange(n),
                                          model.process_scale, model.floor[0]))
        value = add(matmul(Ad, X[k - 1]), cast(drive))
        X.append(add(value, matmul(Bd, U[k - 1])) if e else value)
    Y = []
    C = lift(model.C)
    for k in range(N):  # y[k] = C x[k] + sigma_z (h_z * e_z)[k] + floor
        columns = lay.z + m * (k + np.arange(hz.size))[None, :] + np.arange(m)[:, None]
        noise = _placed((m, D), np.arange(m)[:, None], columns, model.sensor_std[:, None], hz[None, :])
        if lay.floor_z >= 0:
            noise = dd.add(noise, _placed((m, D), np.arange(m), lay.floor_z + m * k + np.arange(m), model.sensor_std,
                                          model.floor[1]))
        Y.append(add(matmul(C, X[k]), cast(noise)))
    return _stack(X, extended), _stack(U, extended), _stack(Y, extended)


def _prior_means(model: _Model, u_mean: np.ndarray, m0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x mean (N, n), y mean (N, m)) under the inputs' prior mean (or the known inputs), float64
    (the means are not where the conditioning is lost)."""
    N = u_mean.shape[0]
    x = np.zeros((N, model.Ad.shape[0]))
    x[0] = m0
    for k in range(1, N):
        x[k] = model.Ad @ x[k - 1] + model.Bd @ u_mean[k - 1]
    return x, x @ model.C.T


def oracle_posterior(system, dt, outputs, inputs=None, *, process_std, measurement_std, kernel_width=None,
                     process_kernel_width=None, sensor_kernel_width=None, input_kernel_width=None,
                     input_prior_mean=None, input_prior_std=None, initial_mean=None, initial_std=0.0,
                     white_floor: float = 0.0, check: bool = True, variance_every: int = 5) -> OraclePosterior:
    """The exact posterior of x[0..N-1] (and the unknown inputs u[0..N-1]) given y[0..N-1], in the
    square-root form (float64) and, with check=True, again in double-double (see the module).

    Arguments as :func:`attend.perception.references.exact_posterior` (no jitter, no white floor:
    the model exactly as stated): system; dt [s]; outputs (N, m) (no missing values); inputs (N, r)
    known inputs or None with input_prior_mean (scalar, (r,) or (N, r)) and input_prior_std
    (scalar or (r,)); process_std, measurement_std per channel; kernel_width [s] of both noises,
    or process_kernel_width and sensor_kernel_width each; input_kernel_width [s] of the inputs'
    prior (default: the process width); initial_mean m0 and initial_std s0 of x[0]; check: also
    compute in double-double and report the agreement.
    white_floor f: every coloured noise (w, z of width > 0 and the inputs' prior) gets a white part
    of variance f times its own, K -> K + f I, or three values (f for w, z, u): the Kalman
    smoother's noise models (:attr:`attend.perception.kalman.KalmanEstimator.noise_floors`); 0
    (default): the model as stated.
    variance_every: the double-double check of the std runs on every variance_every-th sample
    (and the last). For windows of up to a few hundred samples.
    """
    system = _system(system)
    dt = positive_scalar(dt, "dt", "s")
    y = _outputs(system, outputs)
    N = y.shape[0]
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    s_w, s_z, s_u = noise_widths(kernel_width, process_kernel_width, sensor_kernel_width, input_kernel_width)
    widths = [s_w, s_z]
    known = inputs is not None
    if known:
        u_mean, su = _inputs(system, inputs, N), np.zeros(r)
    else:
        if input_prior_mean is None or input_prior_std is None:
            raise AttendInputError("input_prior_mean, input_prior_std: required when the inputs are unknown")
        if s_u <= 0:
            raise AttendInputError("input_kernel_width: expected a width > 0 [s] for the inputs' prior")
        u_mean = _inputs(system, input_prior_mean, N, "input_prior_mean")
        su = _std_vector(input_prior_std, r, "input_prior_std")
    estimated = np.flatnonzero(su > 0)
    Ad, Bd = system.discretize(dt)
    m0 = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(n)
    model = _Model(Ad, Bd, system.C, _kernel(dt, widths[0]), _kernel(dt, widths[1]),
                   correlation_root(N, dt, s_u) if estimated.size else None,
                   dt * _std_vector(process_std, n, "process_std"), _std_vector(measurement_std, m, "measurement_std"),
                   su[estimated], estimated, _std_vector(initial_std, n, "initial_std"),
                   _floors(white_floor, widths[0], widths[1], s_u))
    lay = _layout(model, N)
    x_mean, y_mean = _prior_means(model, u_mean, m0)
    residual = (y - y_mean).reshape(-1)
    X, U, Y = _maps(model, N, lay, extended=False)
    G = Y.reshape(N * m, lay.size)
    M = np.concatenate([X.reshape(N * n, lay.size), U.reshape(N * estimated.size, lay.size)])
    Q, R = qr(G.T, mode="full")
    q = G.shape[0]
    v = Q[:, :q] @ solve_triangular(R[:q].T, residual, lower=True)
    mean = M @ v
    spread = M @ Q[:, q:]
    std = np.sqrt(np.sum(spread**2, axis=1))
    states = x_mean + mean[: N * n].reshape(N, n)
    state_std = std[: N * n].reshape(N, n)
    est_inputs, input_std = u_mean.copy(), np.zeros((N, r))
    est_inputs[:, estimated] += mean[N * n:].reshape(N, estimated.size)
    input_std[:, estimated] = std[N * n:].reshape(N, estimated.size)
    time = np.arange(N) * dt
    if not check:
        return OraclePosterior(time, states, est_inputs, state_std, input_std, None, None, None)
    ext_states, ext_inputs, agreement = _extended_check(model, lay, N, residual, x_mean, u_mean, std,
                                                        G, variance_every)
    return OraclePosterior(time, states, est_inputs, state_std, input_std, ext_states, ext_inputs,
                           agreement._replace(mean_in_std=_mean_gap(states, ext_states, state_std, est_inputs,
                                                                    ext_inputs, input_std, estimated)))


def _floors(white_floor, s_w: float, s_z: float, s_u: float) -> tuple:
    """sqrt of the white floor of w, z, u (0 where the noise is white already)."""
    floors = np.broadcast_to(np.asarray(white_floor, dtype=float), (3,)) if np.ndim(white_floor) == 0 \
        else np.asarray(white_floor, dtype=float)
    if floors.shape != (3,) or not np.all(np.isfinite(floors)) or np.any(floors < 0) or np.any(floors >= 1):
        raise AttendInputError(f"white_floor: expected a number in [0, 1) or three (w, z, u), got {white_floor!r}")
    return tuple(float(np.sqrt(f)) if width > 0 else 0.0 for f, width in zip(floors, (s_w, s_z, s_u)))


def _mean_gap(states, ext_states, state_std, inputs, ext_inputs, input_std, estimated) -> float:
    gaps = [np.max(np.abs(states - ext_states) / np.maximum(state_std, 1e-300))]
    if estimated.size:
        gaps.append(np.max(np.abs(inputs - ext_inputs)[:, estimated] / np.maximum(input_std[:, estimated], 1e-300)))
    return float(max(gaps))


def _extended_check(model: _Model, lay: _Layout, N: int, residual, x_mean, u_mean, std64, G64, every: int):
    """The covariance form in double-double: (states, inputs, OracleAgreement without mean_in_std)."""
    n, m = model.Ad.shape[0], model.C.shape[0]
    e = model.estimated.size
    X, U, Y = _maps(model, N, lay, extended=True)
    G = dd.DD(Y.hi.reshape(N * m, lay.size), Y.lo.reshape(N * m, lay.size))
    S = dd.matmul(G, G.T, symmetric=True)
    L = dd.cholesky(S)
    alpha = dd.solve_upper_transposed(L, dd.solve_lower(L, dd.dd(residual)))
    v = dd.matvec(G.T, alpha)
    Xf = dd.DD(X.hi.reshape(N * n, lay.size), X.lo.reshape(N * n, lay.size))
    states = x_mean + dd.matvec(Xf, v).value().reshape(N, n)
    inputs = u_mean.copy()
    if e:
        Uf = dd.DD(U.hi.reshape(N * e, -1), U.lo.reshape(N * e, -1))
        inputs[:, model.estimated] += dd.matvec(Uf, v).value().reshape(N, e)
    samples = np.unique(np.append(np.arange(0, N, max(1, every)), N - 1))
    rows = np.concatenate([(samples[:, None] * n + np.arange(n)[None, :]).reshape(-1),
                           N * n + (samples[:, None] * e + np.arange(e)[None, :]).reshape(-1)])
    Mf = dd.DD(np.concatenate([Xf.hi, U.hi.reshape(N * e, lay.size)]),
               np.concatenate([Xf.lo, U.lo.reshape(N * e, lay.size)]))
    selected = Mf.at(rows)
    prior = dd.sum_along(dd.multiply(selected, selected), axis=-1)
    W = dd.solve_lower(L, dd.matmul(G, selected.T))
    explained = dd.sum_along(dd.multiply(W, W), axis=0)
    variance = dd.subtract(prior, explained).value()
    std_dd = np.sqrt(np.clip(variance, 0, None))
    positive = std_dd > 0
    std_relative = float(np.max(np.abs(std64[rows][positive] / std_dd[positive] - 1))) if positive.any() else 0.0
    scaled = G64 / np.maximum(np.linalg.norm(G64, axis=1, keepdims=True), 1e-300)
    singular = np.linalg.svd(scaled, compute_uv=False)
    condition = float((singular[0] / max(singular[-1], 1e-300)) ** 2)
    return states, inputs, OracleAgreement(np.nan, std_relative, condition, samples)
