"""The finite (autoregressive) model of the coloured noises shared by the coloured unscented
smoother and the particle smoother, and :func:`coloured_unscented_smoother`.

Each noise channel (process w, sensor z, and the unknown inputs' prior v) is a unit-variance
Gaussian-kernel process with autocorrelation rho(tau) = exp(-tau^2 / (4 s^2)), approximated by
the AR(q) process x[k] = sum_i a_i x[k-i] + e[k] whose autocorrelation matches rho at lags
0..q samples (Yule-Walker), e ~ N(0, 1 - a' rho[1..q]).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_toeplitz

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, as_matrix, positive_scalar
from attend.models.noise import autocorrelation
from attend.models.noise_model import NoiseModel, resolve_noise
from attend.models.nonlinear import NonlinearSystem
from attend.perception.nonlinear_smoothers.kalman import _unscented, observe_points, propagate_points
from attend.perception.references import KalmanEstimate


def std_from_noise(noise, kernel_width, process_std, measurement_std, who: str) -> tuple:
    """(kernel_width, process_std, measurement_std) of the smoothers that take standard deviations
    and one kernel width (the coloured unscented and particle smoothers): those of ``noise`` (an
    :class:`attend.models.NoiseModel`, or None: the given ones, each required) with an
    AttendInputError when it comes with any of them or has two different widths. who: the
    smoother's name, for the messages."""
    given = dict(kernel_width=kernel_width, process_std=process_std, measurement_std=measurement_std)
    if resolve_noise(noise, given, who) is None:
        for name, value in given.items():
            if value is None:
                raise AttendInputError(f"{name}: required (or noise=NoiseModel(...))")
        return kernel_width, process_std, measurement_std
    if noise.kernel_width is None:
        raise AttendInputError(f"noise: {who} uses one kernel width for both noises; this model has "
                               f"process_kernel_width {noise.process_kernel_width:g} s and sensor_kernel_width "
                               f"{noise.sensor_kernel_width:g} s")
    return noise.kernel_width, noise.process_std, noise.sensor_std


def _yule_walker(rho: np.ndarray, q: int):
    """AR coefficients a (q,) and innovation variance for unit variance, autocorrelation rho[0..q].

    Raises AttendInputError when the fitted model is not stationary (a root of
    z^q - a_1 z^(q-1) - ... - a_q on or outside the unit circle): for a noise much smoother than
    the sample time the Toeplitz system is ill-conditioned at high q, and the AR process would
    grow without bound (the estimates blow up silently)."""
    if q == 0:
        return np.zeros(0), 1.0
    a = solve_toeplitz(rho[:q], rho[1: q + 1])
    if np.max(np.abs(np.roots(np.concatenate([[1.0], -a])))) >= 1.0:
        raise AttendInputError(f"ar_order: an AR({q}) model of this noise (correlation {rho[1]:.6f} at one sample) is "
                               "not stationary (ill-conditioned Yule-Walker system); lower ar_order")
    return a, float(max(1.0 - a @ rho[1: q + 1], 1e-12))


class _NoiseModel(NamedTuple):
    """The checked data and coloured-noise settings of one log (see :func:`_noise_model`)."""

    dt: float
    y: np.ndarray            # outputs (N, m)
    unknown: bool            # the inputs are estimated under the prior (mean eta, std sv)
    u_known: np.ndarray      # measured inputs (N, r) (zeros when unknown)
    eta: np.ndarray          # input prior mean (N, r)
    sw: np.ndarray           # process std (n,)
    sz: np.ndarray           # sensor std (m,)
    sv: np.ndarray           # input prior std (r,) (zeros when the inputs are known)
    rho: np.ndarray          # autocorrelation of w and z at lags 0..q samples
    rho_v: np.ndarray        # autocorrelation of the input prior at lags 0..q samples


def _noise_model(system, dt, outputs, inputs, kernel_width, process_std, measurement_std, input_prior_std,
                 input_prior_mean, input_kernel_width, q) -> _NoiseModel:
    if not isinstance(system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
    N = y.shape[0]
    unknown = inputs is None and r > 0 and input_prior_std is not None
    u_known = np.zeros((N, r)) if inputs is None else np.asarray(inputs, dtype=float).reshape(N, r)
    s_v = s if input_kernel_width is None else positive_scalar(input_kernel_width, "input_kernel_width", "s")
    mean = 0.0 if input_prior_mean is None else np.asarray(input_prior_mean, dtype=float)
    eta = np.broadcast_to(mean.reshape(-1, r) if np.ndim(mean) else mean, (N, r)).copy()
    return _NoiseModel(
        dt, y, unknown, u_known, eta,
        np.broadcast_to(np.asarray(process_std, dtype=float), (n,)).copy(),
        np.broadcast_to(np.asarray(measurement_std, dtype=float), (m,)).copy(),
        np.broadcast_to(np.asarray(input_prior_std if unknown else 0.0, dtype=float), (r,)).copy(),
        autocorrelation(np.arange(q + 1) * dt, s), autocorrelation(np.arange(q + 1) * dt, s_v))


def _initial_covariance(system, model: _NoiseModel, q, initial_mean, initial_std):
    """Mean and covariance of [x; AR blocks] at sample 0, and per channel (w: n, v: rv, z: m)
    the AR coefficients (q, channels) and innovation variances."""
    n, m = system.n_states, system.n_outputs
    rv = system.n_inputs if model.unknown else 0
    channels = n + rv + m
    size = n + q * channels
    a, innovation = _yule_walker(model.rho, q)
    a_v, innovation_v = _yule_walker(model.rho_v, q)
    m0, P0 = np.zeros(size), np.zeros((size, size))
    m0[:n] = 0.0 if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(n)
    P0[:n, :n] = np.diag(np.broadcast_to(np.asarray(0.0 if initial_std is None else initial_std, dtype=float),
                                         (n,)) ** 2)
    is_input = np.zeros(channels, dtype=bool)
    is_input[n: n + rv] = True
    coefficients = np.where(is_input[None, :], a_v[:, None], a[:, None])  # (q, channels)
    innovations = np.where(is_input, innovation_v, innovation)
    # AR block layout: index n + lag * channels + channel (lag 0 = newest)
    for c in range(channels):
        r_c = model.rho_v if is_input[c] else model.rho
        P0[n + c::channels, n + c::channels] = [[r_c[abs(i - j)] for j in range(q)] for i in range(q)]
    return m0, P0, coefficients, innovations


@with_single_blas_thread
def coloured_unscented_smoother(system: NonlinearSystem, dt: float, outputs, inputs=None, *,
                                kernel_width: float | None = None, process_std=None, measurement_std=None,
                                input_prior_std=None, input_prior_mean=None,
                                initial_mean=None, initial_std=None, ar_order: int = 3, substeps: int = 4,
                                smooth: bool = True, input_kernel_width: float | None = None,
                                noise: NoiseModel | None = None) -> KalmanEstimate:
    """Unscented RTS smoother on the state augmented with AR(ar_order) models of the coloured
    noises (the same finite noise model as :func:`particle_smoother`): a Gaussian approximation of
    the posterior under the coloured-noise model, the strong reference beside the particle one.

    State [x; w~ (q values per state, newest first); v~ (unknown inputs); z~]: x[k] integrates
    f(x, v[k-1]) + sigma_w w~[k-1] over dt; each AR block advances by its Yule-Walker
    coefficients plus an innovation; y[k] = g(x[k], v[k]) + sigma_z z~[k] (+ white noise of
    variance 1e-6 sigma_z^2 for numerical stability).
    system: the NonlinearSystem; dt: sample time [s]; outputs: (N, m); inputs: measured inputs
    (N, r), or None with input_prior_std for unknown inputs; kernel_width: s [s] of w and z;
    process_std: sigma_w [state unit / s]; measurement_std: sigma_z [output unit];
    input_prior_std: the unknown inputs' prior std 1/sqrt(P_v); input_prior_mean: their prior mean
    eta (scalar, (r,) or (N, r); default 0); initial_mean, initial_std: the Gaussian of x[0];
    ar_order: q (at least 1); substeps: RK4 sub-steps per sample; smooth: RTS smoother (True),
    the filter (False) or a fixed lag (int); input_kernel_width: the unknown inputs' own
    smoothness s_v [s] (default kernel_width).
    noise: an :class:`attend.models.NoiseModel` instead of kernel_width, process_std and
    measurement_std (its standard deviations, as :func:`attend.models.simulate_nonlinear` takes
    them; one kernel width for both noises here: a model whose widths differ is an error).
    """
    kernel_width, process_std, measurement_std = std_from_noise(noise, kernel_width, process_std, measurement_std,
                                                                "coloured_unscented_smoother")
    q = max(int(ar_order), 1)
    model = _noise_model(system, dt, outputs, inputs, kernel_width, process_std, measurement_std, input_prior_std,
                         input_prior_mean, input_kernel_width, q)
    n, r = system.n_states, system.n_inputs
    rv = r if model.unknown else 0
    sv = model.sv[:rv]
    m0, P0, coefficients, innovations = _initial_covariance(system, model, q, initial_mean, initial_std)
    channels = len(innovations)
    Qz = np.zeros((m0.size, m0.size))
    Qz[n: n + channels, n: n + channels] = np.diag(innovations)

    def inputs_at(newest, k):
        """The inputs of the rows ``newest`` (P, channels) at sample k: eta + sv v, or the measured ones."""
        if model.unknown:
            return model.eta[k] + sv * newest[:, n: n + rv]
        return np.broadcast_to(model.u_known[k], (len(newest), r))

    def transition(Z, k):
        newest = Z[:, n: n + channels]
        x_new = propagate_points(system, Z[:, :n], inputs_at(newest, k - 1), model.dt, substeps,
                                 w=model.sw * newest[:, :n])
        history = Z[:, n:].reshape(len(Z), q, channels)
        advanced = np.sum(coefficients * history, axis=1)
        return np.concatenate([x_new, advanced, history[:, :-1].reshape(len(Z), -1)], axis=1)

    def observation(Z, k):
        newest = Z[:, n: n + channels]
        return observe_points(system, Z[:, :n], inputs_at(newest, k)) + model.sz * newest[:, n + rv:]

    R = np.diag(1e-6 * model.sz**2)
    means, covs, ll = _unscented(transition, observation, model.y, m0, P0, Qz, R, smooth, (1.0, 2.0, 0.0),
                                 "coloured_unscented_smoother")
    std = np.sqrt(np.clip(np.diagonal(covs, axis1=1, axis2=2), 0, None))
    N = model.y.shape[0]
    if model.unknown:
        inputs_out = model.eta + sv * means[:, n + n: n + n + rv]
        input_std = sv * std[:, n + n: n + n + rv]
    else:
        inputs_out, input_std = model.u_known, np.zeros((N, r))
    return KalmanEstimate(np.arange(N) * model.dt, means[:, :n], inputs_out, std[:, :n], input_std,
                          covs[:, :n, :n], float(ll))
