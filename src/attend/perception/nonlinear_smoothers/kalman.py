"""Extended and unscented Kalman filters/smoothers for nonlinear models (white noise), the
discrete model of :mod:`attend.perception.nonlinear_smoothers`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from attend._progress import steps
from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, as_matrix, positive_scalar, require_finite, symmetric_matrix
from attend.models.noise import autocorrelation
from attend.models.noise_model import NoiseModel, resolve_noise
from attend.models.nonlinear import NonlinearSystem, evaluate_columns, finite_difference_jacobian
from attend.perception.references import KalmanEstimate

if TYPE_CHECKING:  # imported where used: the recursions' module is not needed on the nonlinear path otherwise
    from attend.perception.kalman_recursions import InnovationTerms


def white_noise_covariances(system: NonlinearSystem, dt: float, *, kernel_width: float, process_std,
                            measurement_std, match: str = "variance") -> tuple[np.ndarray, np.ndarray]:
    """(Q, R) of a white-noise model for coloured noise of kernel width s [s] and standard
    deviations sigma_w [state unit / s], sigma_z [output unit]. R = diag(sigma_z^2);
    match "variance": Q = dt^2 diag(sigma_w^2), the same variance per sample (the linear
    baselines' :func:`attend.perception.references.simulation_covariances`); "power":
    Q = dt^2 diag(sigma_w^2) sum_k rho(k dt), the white noise of the same low-frequency power
    (larger by ~sqrt(4 pi) s / dt). On the Lorenz and pendulum reproductions "variance" gives the
    better Kalman estimates, so it is the default.
    system: the NonlinearSystem (its sizes n, m); dt: sample time [s]; kernel_width: s [s];
    process_std: sigma_w (scalar or per state); measurement_std: sigma_z (scalar or per output);
    match: "variance" or "power"."""
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


def input_random_walk_variance(prior_precision, *, kernel_width: float, dt: float) -> np.ndarray:
    """Per-sample variance of the random walk that matches a smooth input prior: the variance of
    the one-sample increments v(t + dt) - v(t) of a Gaussian-kernel process of variance 1/P_v and
    width s_v [s], 2 (1 - rho(dt)) / P_v with rho(dt) = exp(-dt^2 / (4 s_v^2)). The Kalman
    baselines' random-walk input model then has the prior's local roughness.
    prior_precision: P_v (scalar or per input) [1/input unit^2]; kernel_width: s_v [s]; dt: sample time [s]."""
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    rho = float(autocorrelation(np.array([dt]), s)[0])
    return 2.0 * (1.0 - rho) / np.asarray(prior_precision, dtype=float)


def white_noise_options(dt: float, *, process_precision, sensor_precision, input_prior_precision=None,
                        input_kernel_width: float | None = None, known_inputs=None, input_mean=None,
                        who: str = "the white-noise smoother") -> dict:
    """Keyword arguments of :func:`unscented_kalman` / :func:`extended_kalman` for DEM's noise model
    given by its precisions: process_covariance Q = dt^2 inv(Pi_w), measurement_covariance
    R = inv(Pi_z) (white noise of the coloured noises' per-sample variance) and, with
    ``input_prior_precision`` P_v (r,), unknown inputs as random walks whose one-sample steps have
    their prior's variance (:func:`input_random_walk_variance`, width ``input_kernel_width`` s_v [s]),
    started at ``input_mean`` (r,); ``known_inputs`` (r,) marks measured inputs (no random walk).
    dt: sample time [s]; process_precision Pi_w (n, n), sensor_precision Pi_z (m, m): matrices.
    An AttendInputError names a precision that is not positive definite, prefixed by ``who``."""
    options = {}
    for key, field, precision in (("process_covariance", "process_precision", process_precision),
                                  ("measurement_covariance", "sensor_precision", sensor_precision)):
        precision = np.asarray(precision, dtype=float)
        if not np.all(np.isfinite(precision)) or np.linalg.eigvalsh(precision).min() <= 0:
            raise AttendInputError(f"{field}: {who} needs a positive definite precision (it is inverted into a "
                                   "covariance); every entry > 0")
        options[key] = np.linalg.inv(precision)
    options["process_covariance"] = dt**2 * options["process_covariance"]
    if input_prior_precision is None:
        return options
    precisions = np.asarray(input_prior_precision, dtype=float)
    known = np.zeros(precisions.shape, dtype=bool) if known_inputs is None else np.asarray(known_inputs, dtype=bool)
    if not np.all(precisions[~known] > 0):
        raise AttendInputError(f"input_prior_precision: {who} needs a prior precision > 0 for every unknown input "
                               "(it sets the random walk of the input)")
    variance = input_random_walk_variance(np.where(known, 1.0, precisions), kernel_width=input_kernel_width, dt=dt)
    options.update(input_variance=np.diag(np.where(known, 0.0, variance)), input_mean=input_mean)
    if known.any():
        options.update(known_inputs=known)
    return options


#: RK4 sub-steps are chosen so that h rho(df/dx) <= RK4_STEP_RATE (local error ~ (h rho)^5 / 120 ~ 3e-6 of
#: the state per sub-step). 0.1 until issue 29 (~1e-7, twice the sub-steps): on the 22 logs of
#: benchmarks/bench_nonlinear_start.py through `attend estimate` the estimates moved by at most 0.05 of
#: their std with x[0] known (median 0.003) and 0.006 with x[0] searched, their std by at most 0.3 %
RK4_STEP_RATE = 0.2


def rk4_substeps(system: NonlinearSystem, dt: float, states, inputs, limit: int = 1000) -> int:
    """RK4 sub-steps per sample for the Kalman baselines' transition: ceil(dt rho / RK4_STEP_RATE)
    with rho the largest spectral radius of df/dx over up to 50 of the given points (rows of
    states (N, n), inputs (N, r), e.g. a D-step estimate of the log), between 1 and ``limit``; 10
    (the baselines' default) where a Jacobian is not finite. Fast enough for slow systems (Lorenz
    at dt = 0.01 s: 1-2 instead of 10) and stable for stiff ones (10 fixed sub-steps diverge once
    dt rho > 28). system: the NonlinearSystem; dt: sample time [s]."""
    states, inputs = np.asarray(states, dtype=float), np.asarray(inputs, dtype=float)
    rows = np.unique(np.linspace(0, len(states) - 1, min(50, len(states))).astype(int))
    radii = [_fastest_rate(system, states[row], inputs[row].reshape(system.n_inputs)) for row in rows]
    if not np.all(np.isfinite(radii)):
        return 10
    return int(np.clip(np.ceil(dt * max(radii) / RK4_STEP_RATE), 1, limit))


def _fastest_rate(system: NonlinearSystem, x, u) -> float:
    """rho(df/dx) at (x, u) [1/s], the spectral radius of the state Jacobian (NaN where it is not finite)."""
    with np.errstate(all="ignore"):
        fx = system.evaluate_jacobians(np.asarray(x, dtype=float), np.asarray(u, dtype=float))[0]
    return float(np.max(np.abs(np.linalg.eigvals(fx)))) if np.all(np.isfinite(fx)) else np.nan


#: RK4 is stable for h |lambda| up to ~2.8 on the negative real axis; sub-steps beyond this are refused
RK4_STABLE_RATE = 2.5


def _check_substeps(system: NonlinearSystem, dt: float, substeps: int, x0, u0) -> None:
    """Refuse sub-steps too few for RK4 to be stable at the initial mean (h rho(df/dx) >
    RK4_STABLE_RATE): the filter would return huge values without an error."""
    if substeps < 1:
        raise AttendInputError(f"substeps: expected an integer >= 1, got {substeps}")
    try:
        radius = _fastest_rate(system, x0, u0)
    except (AttendInputError, np.linalg.LinAlgError):
        return  # the model's own errors are reported where it is integrated
    if dt / substeps * radius > RK4_STABLE_RATE:  # False for NaN
        raise AttendInputError(
            f"substeps: {substeps} RK4 sub-steps per sample are unstable for this model (dt rho(df/dx) = "
            f"{dt * radius:.3g} at the initial mean, a stiff mode); use substeps >= "
            f"{int(np.ceil(dt * radius / RK4_STABLE_RATE))} (rk4_substeps gives an accurate choice)")


# --- shared plumbing ----------------------------------------------------------------------------

def _rk4(system: NonlinearSystem, x, u, dt: float, substeps: int, w=None, call=None):
    """Integrate dx/dt = f(x, u) (+ w) over dt; x (n,) or (n, P) with a vectorized system, or any
    array that ``call`` takes (rows (P, n) in :func:`propagate_points`); call: f of the state
    (default: the system's f at u, unchecked for columns)."""
    h = dt / substeps
    if call is None and x.ndim == 2:
        call = lambda state: system.call_with_parameters(system.f, state, u)  # noqa: E731
    elif call is None:  # system.flow(state, u), with x and u converted once instead of at every stage
        x, v = np.asarray(x, dtype=float), system.input_vector(u)
        call = lambda state: system.evaluate("f", state, v)  # noqa: E731
    extra = 0.0 if w is None else w
    for _ in range(substeps):
        k1 = call(x) + extra
        k2 = call(x + 0.5 * h * k1) + extra
        k3 = call(x + 0.5 * h * k2) + extra
        k4 = call(x + h * k3) + extra
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def propagate_points(system: NonlinearSystem, x, u, dt: float, substeps: int, w=None) -> np.ndarray:
    """Rows x (P, n) of ``system`` (the NonlinearSystem) integrated over dt [s] (RK4, ``substeps``
    sub-steps) under inputs u (P, r) and held noise w (P, n) [state unit / s] (None: 0): (P, n). A vectorized system
    (``NonlinearSystem(vectorized=True)``) takes all rows in one call of f per RK4 stage (its
    output shape checked); for other systems every RK4 stage calls f at each row
    (:func:`evaluate_rows`) and advances all rows together (the same arithmetic, row by row, as
    integrating each row alone)."""
    if system.vectorized:
        columns = u.T

        def call(state):
            return evaluate_columns(system, "f", np.vstack([state, columns]))

        return _rk4(system, x.T, columns, dt, substeps, None if w is None else w.T, call).T
    x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float).reshape(len(x), system.n_inputs)
    return _rk4(system, x, u, dt, substeps, w, lambda state: evaluate_rows(system, "f", state, u))


def observe_points(system: NonlinearSystem, x, u) -> np.ndarray:
    """g of ``system`` (the NonlinearSystem) at the rows x (P, n), u (P, r): a (P, m) array (one
    call of g for a vectorized system)."""
    if system.vectorized:
        return evaluate_columns(system, "g", np.vstack([x.T, u.T])).T
    x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float).reshape(len(x), system.n_inputs)
    return evaluate_rows(system, "g", x, u)


def evaluate_rows(system: NonlinearSystem, which: str, x, u) -> np.ndarray:
    """f (``which`` "f") or g ("g") of ``system`` (not vectorized) at each row of x (P, n), u (P, r):
    a float (P, n) or (P, m) array, the values of :meth:`NonlinearSystem.evaluate` row by row. A
    function with an ``at_rows(x, u)`` method (a model file's f and g, :mod:`attend.io.python_model`)
    evaluates and checks all rows in one go; other functions are called row by row with one
    conversion of the values for all of them, and :meth:`NonlinearSystem.evaluate` (which names the
    failure) takes over where that fails or gives a wrong shape. Each value is copied when it is
    returned (a function may fill and return the same buffer at every call)."""
    function, size = (system.f, system.n_states) if which == "f" else (system.g, system.n_outputs)
    at_rows = getattr(function, "at_rows", None)
    if at_rows is not None and system.parameters is None:
        return at_rows(x, u)
    try:
        values = np.array([np.array(system.call_with_parameters(function, point, inputs), dtype=float)
                           for point, inputs in zip(x, u)], dtype=float)
        if values.shape == (len(x), size):
            return values
    except Exception:  # noqa: BLE001 - evaluate() below reports it
        pass
    return np.array([np.array(system.evaluate(which, point, inputs)) for point, inputs in zip(x, u)],
                    dtype=float).reshape(len(x), size)


def covariances_from_noise(system: NonlinearSystem, dt: float, noise, process_covariance, measurement_covariance,
                           who: str) -> tuple:
    """(process_covariance Q, measurement_covariance R) of the white-noise smoothers: the given ones,
    or those of ``noise`` (an :class:`attend.models.NoiseModel`) by :func:`white_noise_options`,
    Q = dt^2 inv(Pi_w), R = inv(Pi_z) (white noise of the coloured noises' per-sample variance; the
    model's kernel widths are not used by the white-noise filter). An AttendInputError when
    ``noise`` comes with either covariance, or when neither is given. system: the NonlinearSystem
    (its sizes); dt: sample time [s]; who: the smoother's name, for the messages."""
    given = dict(process_covariance=process_covariance, measurement_covariance=measurement_covariance)
    if resolve_noise(noise, given, who) is None:
        for name, value in given.items():
            if value is None:
                raise AttendInputError(f"{name}: required (or noise=NoiseModel(...))")
        return process_covariance, measurement_covariance
    if not isinstance(system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    process_precision, sensor_precision = noise.precision_matrices(system.n_states, system.n_outputs)
    options = white_noise_options(positive_scalar(dt, "dt", "s"), process_precision=process_precision,
                                  sensor_precision=sensor_precision, who=who)
    return options["process_covariance"], options["measurement_covariance"]


class _Model:
    """The discrete (possibly input-augmented) model z = [x; u] seen by the Kalman baselines."""

    def __init__(self, system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                 measurement_covariance, initial_mean, initial_covariance, substeps, known_inputs=None,
                 missing: bool = False, steps=None):
        """missing: NaN in ``outputs`` marks a missing value (the Kalman filters skip it); else every
        output must be finite. steps: (N - 1,) the lengths [s] of the steps between samples (None:
        dt each), for logs whose time stamps jitter: step k is integrated over its own length (RK4
        with the sub-steps scaled by h_k / dt) and its noise scaled to it (:meth:`step_noise`)."""
        if not isinstance(system, NonlinearSystem):
            raise AttendInputError("system: expected an attend NonlinearSystem")
        self.system = system
        self.dt = positive_scalar(dt, "dt", "s")
        n, r, m = system.n_states, system.n_inputs, system.n_outputs
        if missing:
            from attend.models.sample_times import matrix_with_gaps

            self.y = matrix_with_gaps(outputs, "outputs", m)
            if self.y.size and not np.isfinite(self.y).any():
                raise AttendInputError("outputs: every value is missing (NaN); expected some measured outputs")
        else:
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
        _check_substeps(system, self.dt, self.substeps, m0[:n], self.u[0] if N else np.zeros(r))
        self.Qz = np.zeros((size, size))
        self.Qz[:n, :n] = self.Q
        if self.augmented:
            self.Qz[n:, n:] = self.Qu
        self.steps, self._step_noise = None, None
        if steps is not None:
            self.steps = np.asarray(steps, dtype=float).reshape(-1)
            if self.steps.shape != (max(N - 1, 0),) or not np.all(np.isfinite(self.steps)) or np.any(self.steps <= 0):
                raise AttendInputError(f"step_lengths: expected {max(N - 1, 0)} step lengths > 0 [s] (one between each two "
                                       f"samples), got shape {self.steps.shape}")

    def step_noise(self):
        """The process noise of each step: Qz (d, d) for a uniform log, else (N, d, d) with step k's
        (from sample k - 1; row 0 unused) for its length h: Q (h / dt)^2 (the white-noise model holds
        w over the step: q = h w) and the unknown inputs' random walk Qu h / dt."""
        if self.steps is None:
            return self.Qz
        if self._step_noise is None:  # built once: the extended filter asks at every step
            n, ratio = self.system.n_states, np.concatenate([[1.0], self.steps / self.dt])
            noise = np.repeat(self.Qz[None], len(ratio), axis=0)
            noise[:, :n, :n] *= (ratio**2)[:, None, None]
            noise[:, n:, n:] *= ratio[:, None, None]
            self._step_noise = noise
        return self._step_noise

    def transition(self, z, k):
        """z[k] = F(z[k-1]) with the input of sample k - 1 (one point: :meth:`transition_points`)."""
        return self.transition_points(z[None], k)[0]

    def observation(self, z, k):
        """g at the point z of sample k (:meth:`observation_points`)."""
        return self.observation_points(z[None], k)[0]

    def split_points(self, Z, k):
        """(x (P, n), u (P, r)) of the rows Z (P, size) at sample k."""
        n = self.system.n_states
        if not self.augmented:
            return Z, np.broadcast_to(self.u[k], (len(Z), self.u.shape[1]))
        if self.known.any():
            return Z[:, :n], np.where(self.known, self.u[k], Z[:, n:])
        return Z[:, :n], Z[:, n:]

    def transition_points(self, Z, k):
        """:meth:`transition` of every row of Z (P, size) (:func:`propagate_points`)."""
        x, u = self.split_points(Z, k - 1)
        if self.steps is None:
            x_new = propagate_points(self.system, x, u, self.dt, self.substeps)
        else:  # a step of its own length h, with sub-steps no longer than dt / substeps
            h = self.steps[k - 1]
            x_new = propagate_points(self.system, x, u, h, max(1, int(np.ceil(self.substeps * h / self.dt - 1e-9))))
        return np.concatenate([x_new, u], axis=1) if self.augmented else x_new

    def observation_points(self, Z, k):
        """:meth:`observation` of every row of Z (P, size) (:func:`observe_points`)."""
        return observe_points(self.system, *self.split_points(Z, k))

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
        time = np.arange(N) * self.dt if self.steps is None else np.concatenate([[0.0], np.cumsum(self.steps)])
        return KalmanEstimate(time, means[:, :n], inputs, std[:, :n], input_std,
                              covs[:, :n, :n], float(ll))


def _update(mean, cov, y, predicted, H_cov_cross, S):
    """Kalman update from predicted output, cross covariance C = Cov(z, y) and S = Cov(y):
    (mean, covariance, log-likelihood of y, gain K = C inv(S), (nu' inv(S) nu, log det S)). A
    missing output (NaN in y) is left out: the update uses the measured ones o alone (S_oo, C_o),
    and the gain's columns of the missing ones are 0; with none measured, no update (log-likelihood 0)."""
    measured = np.isfinite(y)
    if not measured.all():
        gain = np.zeros_like(H_cov_cross)
        if not measured.any():
            return mean, cov, 0.0, gain, (0.0, 0.0)
        mean, cov, ll, gain[:, measured], parts = _update(mean, cov, y[measured], predicted[measured],
                                                          H_cov_cross[:, measured], S[np.ix_(measured, measured)])
        return mean, cov, ll, gain, parts
    gain = np.linalg.solve(S, H_cov_cross.T).T
    innovation = y - predicted
    mean = mean + gain @ innovation
    cov = cov - gain @ S @ gain.T
    sign, logdet = np.linalg.slogdet(S)
    quadratic = innovation @ np.linalg.solve(S, innovation)
    ll = -0.5 * (quadratic + logdet + len(y) * np.log(2 * np.pi))
    return mean, 0.5 * (cov + cov.T), ll, gain, (quadratic, logdet)


def _smooth(mf, Pf, mp, Pp, cross, smooth, gains=None):
    """smooth True: RTS over the whole log; False: the filter; an integer L >= 0: fixed-lag,
    row k = x[k] | y[0..min(k + L, N - 1)] (the RTS pass over samples k..k + L, from every k).
    gains: the RTS gains if already computed (:func:`smoother_gains`)."""
    if smooth is False or smooth == 0:
        return mf, Pf
    N = mf.shape[0]
    gains = smoother_gains(Pp, cross) if gains is None else gains
    if smooth is True:
        return _rts(mf, Pf, mp, Pp, gains)
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(N):
        window = slice(k, min(k + int(smooth), N - 1) + 1)
        means, covs = _rts(mf[window], Pf[window], mp[window], Pp[window], gains[window])
        ms[k], Ps[k] = means[0], covs[0]
    return ms, Ps


def smoother_gains(Pp, cross) -> list:
    """The RTS gains G_k = C_k inv(Pp[k+1]), C_k = Cov(z[k], z[k+1] | y[0..k]) (cross (N-1, d, d)),
    by least squares (Pp may be singular where a coordinate is known)."""
    return [np.linalg.lstsq(Pp[k + 1], cross[k].T, rcond=None)[0].T for k in range(len(cross))]


def _rts(mf, Pf, mp, Pp, gains):
    """Backward pass over the given samples with the gains G_k = C_k inv(Pp[k+1]),
    C_k = Cov(z[k], z[k+1] | y[0..k])."""
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(mf.shape[0] - 2, -1, -1):
        G = gains[k]
        ms[k] = mf[k] + G @ (ms[k + 1] - mp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
        Ps[k] = 0.5 * (Ps[k] + Ps[k].T)
    return ms, Ps


@with_single_blas_thread
def extended_kalman(system: NonlinearSystem, dt: float, outputs, inputs=None, *, process_covariance=None,
                    measurement_covariance=None, input_variance=None, input_mean=None, initial_mean=None,
                    initial_covariance=None, smooth: bool | int = True, substeps: int = 10,
                    noise_kernel_width: float | None = None, input_prior=None, spread_draws: int | None = 200,
                    seed: int = 0, noise: NoiseModel | None = None, step_lengths=None) -> KalmanEstimate:
    """Extended Kalman filter (``smooth=False``), filter + RTS smoother (``True``) or fixed-lag
    smoother (``smooth=L`` samples: row k uses y[0..k+L], e.g. the DEM estimator's delay).

    system: NonlinearSystem; dt [s]; outputs (N, m), NaN where a value is missing (no update for
    that output at that sample; a sample of a log's uniform grid without a row is a row of NaN);
    inputs (N, r) measured inputs (None: zero,
    or unknown with ``input_variance``); Q, R: white-noise covariances (scalar, diagonal or
    matrix); input_variance: random-walk variance of unknown inputs per sample [input unit^2];
    input_mean: their initial value; initial_mean/initial_covariance of x[0] (default 0, 0).
    process_covariance: Q [state unit^2], the covariance of q per sample; measurement_covariance:
    R [output unit^2]; substeps: RK4 sub-steps of F per sample.
    Jacobians of F and g by central differences at the filtered / predicted means.
    noise_kernel_width, input_prior, spread_draws, seed: the std as the error spread under coloured
    noise of that width (as :func:`unscented_kalman`).
    noise: an :class:`attend.models.NoiseModel` instead of process_covariance and
    measurement_covariance: Q = dt^2 inv(Pi_w), R = inv(Pi_z) (:func:`white_noise_options`; its kernel
    widths are not used: give noise_kernel_width for the error spread under coloured noise).
    step_lengths: (N - 1,) the lengths [s] of the steps between samples when the log's time stamps jitter
    (None: dt each): each step is integrated over its own length and its process noise scaled to it
    (Q (h / dt)^2, an unknown input's random walk Qu h / dt); the error spread under coloured noise
    takes the steps as dt (within the jitter: +-10 % in the noise's variance for +-5 % steps).
    """
    process_covariance, measurement_covariance = covariances_from_noise(
        system, dt, noise, process_covariance, measurement_covariance, "extended_kalman")
    model = _Model(system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                   measurement_covariance, initial_mean, initial_covariance, substeps, missing=True, steps=step_lengths)
    spread = _spread_settings(model, smooth, noise_kernel_width, input_prior, spread_draws)
    N, d = model.y.shape[0], model.size
    mf, Pf = np.empty((N, d)), np.empty((N, d, d))
    mp, Pp = np.empty((N, d)), np.empty((N, d, d))
    cross = np.empty((max(N - 1, 0), d, d))
    Cy, K = np.empty((N, d, model.R.shape[0])), np.empty((N, d, model.R.shape[0]))
    mean, cov, ll = model.m0.copy(), model.P0.copy(), 0.0
    for k in steps(range(N), "extended_kalman"):
        if k > 0:
            mean, cov, cross[k - 1] = _extended_predict(model, mean, cov, k)
        mp[k], Pp[k] = mean, cov
        mean, cov, step_ll, K[k], Cy[k] = _extended_update(model, mean, cov, model.y[k], k)
        ll += step_ll
        mf[k], Pf[k] = mean, cov
    _check(mf, "extended_kalman")
    gains = smoother_gains(Pp, cross) if smooth is True else None
    means, covs = _smooth(mf, Pf, mp, Pp, cross, smooth, gains)
    record = dict(Pf=Pf, Pp=Pp, cross=cross, Cy=Cy, K=K, gains=gains)
    return model.result(means, _error_spread(model, smooth, spread, record, spread_draws, seed, covs), ll)


def _extended_predict(model, mean, cov, k):
    """The extended filter's prediction of sample k from the filtered (mean, cov) of k - 1:
    (mean, cov, Cov(z[k-1], z[k]) = cov Fz') with Fz the transition's Jacobian by central differences."""
    Fz = finite_difference_jacobian(lambda Z: model.transition_points(Z.T, k).T, mean, vectorized=True)
    cross = cov @ Fz.T
    mean = model.transition(mean, k)
    noise = model.step_noise()
    cov = Fz @ cov @ Fz.T + (noise if noise.ndim == 2 else noise[k])
    return mean, cov, cross


def _extended_update(model, mean, cov, y, k):
    """The extended filter's update at sample k with its outputs y (m,): (mean, cov, log-likelihood
    of y, gain, Cov(z[k], y[k]))."""
    H = finite_difference_jacobian(lambda Z: model.observation_points(Z.T, k).T, mean, vectorized=True)
    S = H @ cov @ H.T + model.R
    Cy = cov @ H.T
    mean, cov, step_ll, gain, _ = _update(mean, cov, y, model.observation(mean, k), Cy, S)
    return mean, cov, step_ll, gain, Cy


def _sigma_points(mean, cov, alpha, beta, kappa):
    """The 2d + 1 sigma points of N(mean, cov) and their mean and covariance weights; an
    AttendInputError where mean or cov is not finite (the filter's covariance left the floating-point
    range: f and g would be called at NaN, and the error blamed on them)."""
    if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(cov))):
        raise AttendInputError("the filter's mean or covariance is not finite (beyond the floating-point range); check "
                               "the covariances (process_precision, sensor_precision, initial_state_std)")
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
def unscented_kalman(system: NonlinearSystem, dt: float, outputs, inputs=None, *, process_covariance=None,
                     measurement_covariance=None, input_variance=None, input_mean=None, initial_mean=None,
                     initial_covariance=None, smooth: bool | int = True, substeps: int = 10, alpha: float = 1.0,
                     beta: float = 2.0, kappa: float = 0.0, known_inputs=None, noise_kernel_width: float | None = None,
                     input_prior=None, spread_draws: int | None = 200, seed: int = 0,
                     noise: NoiseModel | None = None, evidence_floor: float | None = None, step_lengths=None) -> KalmanEstimate:
    """Unscented Kalman filter (``smooth=False``), filter + unscented RTS smoother (``True``,
    Sarkka 2008) or fixed-lag smoother (``smooth=L`` samples).

    system, dt, outputs, inputs, process_covariance, measurement_covariance, input_variance,
    input_mean, initial_mean, initial_covariance, smooth, substeps: as :func:`extended_kalman`;
    alpha, beta, kappa: the sigma-point spread
    (lambda = alpha^2 (d + kappa) - d; the defaults put the 2d points at +-sqrt(d) std with equal
    weights and none on the mean). known_inputs: with ``input_variance``, a mask (r,) of the inputs
    that are measured (their values from ``inputs``, no random walk); the others are estimated.
    noise_kernel_width: s [s] when the real noises are coloured (Q / dt^2 and R their per-sample
    covariances): the reported std and covariances are then the filter's or smoother's error
    spread under that noise, from ``spread_draws`` draws seeded by ``seed`` (relative error of
    the std ~1 / sqrt(2 draws): 5 % at the default 200), or with ``spread_draws=None`` its exact
    covariance, the draws' limit, without draws (what ``attend estimate`` reports; as fast as 200
    draws, and it does not import scipy.signal: 0.6-0.9 s of a 128-sample run)
    (:mod:`attend.perception.nonlinear_smoothers.error_spread`; the estimates are unchanged);
    input_prior: with unknown inputs, (per-sample covariance (r, r) or variances (r,), kernel
    width s_v [s]) of the prior their truth is drawn from there. None (default): the white-noise
    model's own covariance. noise: an :class:`attend.models.NoiseModel` instead of
    process_covariance and measurement_covariance (as :func:`extended_kalman`).
    evidence_floor: a log-likelihood [nats] below which the caller has no use for the run (comparing
    starts or models by their evidence): the filter stops with :class:`EvidenceBelowFloor` as soon as
    its log-likelihood so far plus the most the remaining samples can add
    (:func:`evidence_bound_per_sample`) is below it. None (default): never; also ignored for a spread
    (alpha, beta, kappa) with a negative covariance weight, where the bound does not hold (a sample
    adds at most that bound for its measured outputs, nothing where all are missing).
    step_lengths: the lengths of the steps between samples of a jittered log (as :func:`extended_kalman`).
    """
    process_covariance, measurement_covariance = covariances_from_noise(
        system, dt, noise, process_covariance, measurement_covariance, "unscented_kalman")
    model = _Model(system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                   measurement_covariance, initial_mean, initial_covariance, substeps, known_inputs, missing=True,
                   steps=step_lengths)
    spread = _spread_settings(model, smooth, noise_kernel_width, input_prior, spread_draws)
    record = {}
    means, covs, ll = _unscented(model.transition_points, model.observation_points, model.y, model.m0, model.P0,
                                 model.step_noise(),
                                 model.R, smooth, (alpha, beta, kappa), "unscented_kalman", record, evidence_floor)
    return model.result(means, _error_spread(model, smooth, spread, record, spread_draws, seed, covs), ll)


def unscented_innovation_terms(system: NonlinearSystem, dt: float, outputs, inputs=None, *, process_covariance,
                               measurement_covariance, input_variance=None, input_mean=None, initial_mean=None,
                               initial_covariance=None, substeps: int = 10, known_inputs=None, alpha: float = 1.0,
                               beta: float = 2.0, kappa: float = 0.0, step_lengths=None) -> InnovationTerms:
    """The unscented filter's prediction-error decomposition of log p(y): the sums over samples of
    log det S[k] and nu[k]' inv(S[k]) nu[k] and the number of outputs, an
    :class:`attend.perception.kalman_recursions.InnovationTerms` (the criterion of
    :func:`attend.perception.input_width.choose_input_width`). One filter pass, no smoother.

    system, dt [s], outputs (N, m), inputs (N, r) or None, process_covariance, measurement_covariance,
    input_variance, input_mean, initial_mean, initial_covariance, substeps, known_inputs, the sigma-point
    spread alpha, beta, kappa and step_lengths: as :func:`unscented_kalman`."""
    model = _Model(system, dt, outputs, inputs, input_variance, input_mean, process_covariance,
                   measurement_covariance, initial_mean, initial_covariance, substeps, known_inputs, missing=True,
                   steps=step_lengths)
    record = {}
    _unscented(model.transition_points, model.observation_points, model.y, model.m0, model.P0, model.step_noise(), model.R,
               False, (alpha, beta, kappa), "unscented_kalman", record)
    return record["innovation_terms"]


def _error_spread(model, smooth, spread, record: dict, draws: int, seed: int, covs):
    """The covariances to report: the error spread under coloured noise where ``spread`` (from
    :func:`_spread_settings`) is given, else the white-noise model's own ``covs``."""
    if spread is None:
        return covs
    from attend.perception.nonlinear_smoothers import error_spread

    if draws is None:  # no draws: the covariance they estimate, exactly
        return error_spread.smoother_error_covariance(model, record, *spread, bool(smooth))
    return error_spread.smoother_error_spread(model, record, *spread, bool(smooth), int(draws), seed)


def _spread_settings(model, smooth, kernel_width, input_prior, draws):
    """(s, input prior) of the error spread after checking them, or None (no coloured noise given)."""
    if kernel_width is None:
        return None
    if smooth not in (True, False):
        raise AttendInputError("noise_kernel_width: the error spread is computed for the filter (smooth=False) "
                               "and the RTS smoother (smooth=True), not for a fixed lag")
    if not (np.isscalar(kernel_width) and np.isfinite(kernel_width) and kernel_width >= 0):
        raise AttendInputError(f"noise_kernel_width: expected a kernel width >= 0 [s], got {kernel_width!r}")
    if draws is not None and not (isinstance(draws, (int, np.integer)) and draws >= 2):
        raise AttendInputError(f"spread_draws: expected an integer >= 2 or None (no draws: the exact covariance), "
                               f"got {draws!r}")
    if not (model.augmented and not model.known.all()):
        return float(kernel_width), None
    r = model.system.n_inputs
    if input_prior is None or len(input_prior) != 2:
        raise AttendInputError("input_prior: with unknown inputs and noise_kernel_width, give (per-sample "
                               "covariance (r, r) or variances (r,), kernel width s_v [s]) of the inputs' prior")
    covariance = symmetric_matrix(input_prior[0], r, "input_prior", "variances")
    width = positive_scalar(input_prior[1], "input_prior kernel width", "s")
    return float(kernel_width), (covariance, width)


def _unscented_predict(transition, mean, cov, Qz, spread, k):
    """The unscented filter's prediction of sample k from the filtered (mean, cov) of k - 1:
    (mean, cov, Cov(z[k-1], z[k]), the covariance the sigma points stand for); transition, Qz and
    spread (alpha, beta, kappa) as :func:`_unscented`."""
    points, wm, wc = _sigma_points(mean, cov, *spread)
    moved = transition(points, k)
    new_mean = wm @ moved
    cross = ((points - mean).T * wc) @ (moved - new_mean)
    points_cov = ((points - mean).T * wc) @ (points - mean)
    cov = ((moved - new_mean).T * wc) @ (moved - new_mean) + Qz
    return new_mean, cov, cross, points_cov


def _unscented_update(observation, mean, cov, R, spread, y, k):
    """The unscented filter's update at sample k with its outputs y (m,): (mean, cov, log-likelihood
    of y, gain, Cov(z[k], y[k]), the covariance the sigma points stand for, (nu' inv(S) nu, log det S))."""
    points, wm, wc = _sigma_points(mean, cov, *spread)
    observed = observation(points, k)
    predicted = wm @ observed
    S = ((observed - predicted).T * wc) @ (observed - predicted) + R
    Cy = ((points - mean).T * wc) @ (observed - predicted)
    points_cov = ((points - mean).T * wc) @ (points - mean)
    mean, cov, step_ll, gain, parts = _update(mean, cov, y, predicted, Cy, S)
    return mean, cov, step_ll, gain, Cy, points_cov, parts


class EvidenceBelowFloor(Exception):
    """The unscented filter stopped early: its log-likelihood can no longer reach the evidence_floor
    it was given (:func:`unscented_kalman`). samples: how many samples it had filtered."""

    def __init__(self, samples: int):
        super().__init__(f"the log-likelihood fell below the evidence floor after {samples} samples")
        self.samples = samples


def evidence_bound_per_sample(measurement_covariance) -> float:
    """The most one sample can add to an unscented filter's log-likelihood with sensor noise
    covariance R (m, m) [nats]: -1/2 (log|R| + m log 2 pi). Each sample adds
    -1/2 (e' inv(S) e + log|S| + m log 2 pi) with S = sum_i w_i (Y_i - y)(Y_i - y)' + R >= R when
    the covariance weights w_i are >= 0 (the default spread: 2 on the mean, 1 / 2d on the others),
    so log|S| >= log|R| and e' inv(S) e >= 0."""
    R = np.atleast_2d(np.asarray(measurement_covariance, dtype=float))
    return float(-0.5 * (np.linalg.slogdet(R)[1] + R.shape[0] * np.log(2 * np.pi)))


def _remaining_bounds(y, R) -> np.ndarray:
    """(N,) the most samples k + 1 .. N - 1 of the outputs y (N, m) (NaN: missing) can add to an
    unscented filter's log-likelihood: the sum of :func:`evidence_bound_per_sample` of the measured
    outputs' sensor covariance R_oo at each (0 where none is measured)."""
    measured = np.isfinite(y)
    if measured.all():
        return np.arange(len(y) - 1, -1, -1) * evidence_bound_per_sample(R)
    per_sample = np.array([evidence_bound_per_sample(R[np.ix_(row, row)]) if row.any() else 0.0 for row in measured])
    return np.concatenate([np.cumsum(per_sample[::-1])[::-1][1:], [0.0]])


def _nonnegative_weights(spread, d: int) -> bool:
    """Whether the sigma points of (alpha, beta, kappa) in d dimensions have covariance weights >= 0."""
    alpha, beta, kappa = spread
    lam = alpha**2 * (d + kappa) - d
    return d + lam > 0 and lam / (d + lam) + 1 - alpha**2 + beta >= 0


def _unscented(transition, observation, y, m0, P0, Qz, R, smooth, spread, name, record=None, floor=None):
    """Unscented filter (+ RTS smoother) for z[k] = transition(z[k-1], k) + q, y[k] = observation(z[k], k) + r
    (Cov(q) = Qz (d, d), or Qz[k] of an (N, d, d) stack of the steps' own);
    transition and observation take the sigma points as rows (P, d) and return rows. record: a
    dict that receives the filter's statistical linearisation (:mod:`.error_spread`): the
    covariances Pf, Pp, cross (k -> k + 1), the output cross covariances Cy = Cov(z_k, y_k), the
    gains K, the RTS gains (None for the filter), and the covariances the sigma points of the
    transition (Pf_points, samples 0..N-2) and of the observation (Pp_points) stand for. floor: the
    evidence_floor of :func:`unscented_kalman` (EvidenceBelowFloor), or None."""
    N, d = y.shape[0], m0.shape[0]
    # the most the samples after k can add to the log-likelihood (each by its measured outputs)
    remaining = None if floor is None or not _nonnegative_weights(spread, d) else _remaining_bounds(y, R)
    mf, Pf = np.empty((N, d)), np.empty((N, d, d))
    mp, Pp = np.empty((N, d)), np.empty((N, d, d))
    cross = np.empty((max(N - 1, 0), d, d))
    Cy, K = np.empty((N, d, y.shape[1])), np.empty((N, d, y.shape[1]))
    # the covariances the sigma points stand for (Pf_k-1 and Pp_k plus the Cholesky's jitter): the
    # regressions of the error spread divide cross and Cy by these, not by Pf and Pp
    Pf_points, Pp_points = np.empty((max(N - 1, 0), d, d)), np.empty((N, d, d))
    mean, cov, ll = m0.copy(), P0.copy(), 0.0
    quadratic = log_determinant = 0.0
    for k in steps(range(N), name):
        if k > 0:
            mean, cov, cross[k - 1], Pf_points[k - 1] = _unscented_predict(transition, mean, cov,
                                                                           Qz if Qz.ndim == 2 else Qz[k], spread, k)
        mp[k], Pp[k] = mean, 0.5 * (cov + cov.T)
        mean, cov, step_ll, K[k], Cy[k], Pp_points[k], parts = _unscented_update(observation, mean, cov, R, spread,
                                                                                 y[k], k)
        ll += step_ll
        quadratic += parts[0]
        log_determinant += parts[1]
        mf[k], Pf[k] = mean, cov
        if remaining is not None and ll + remaining[k] < floor:  # False for NaN: _check reports it
            raise EvidenceBelowFloor(k + 1)
    _check(mf, name)
    gains = smoother_gains(Pp, cross) if smooth is True else None
    if record is not None:
        from attend.perception.kalman_recursions import InnovationTerms

        record.update(Pf=Pf, Pp=Pp, cross=cross, Cy=Cy, K=K, gains=gains, Pf_points=Pf_points,
                      Pp_points=Pp_points, innovation_terms=InnovationTerms(float(log_determinant), float(quadratic),
                                                                            int(np.isfinite(y).sum())))
    means, covs = _smooth(mf, Pf, mp, Pp, cross, smooth, gains)
    return means, covs, ll



#: estimates beyond this (in the states' own units) are a filter that diverged, not a state
DIVERGED_MAGNITUDE = 1e100


def _check(means, name):
    """Refuse a filter that diverged: non-finite means, or means beyond DIVERGED_MAGNITUDE (a process
    or start covariance of ~1e300, e.g. a precision of 1e-300, puts the sigma points at ~1e150, where
    f and g give finite nonsense)."""
    if not np.all(np.isfinite(means)):
        raise AttendInputError(f"{name}: the filter diverged (non-finite estimates); check the covariances")
    if np.max(np.abs(means), initial=0.0) > DIVERGED_MAGNITUDE:
        raise AttendInputError(f"{name}: the filter diverged (estimates beyond {DIVERGED_MAGNITUDE:g}); check the "
                               "covariances (process_precision, initial_state_std)")

