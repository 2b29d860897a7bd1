"""A particle smoother under (a finite model of) the true coloured noise: the reference for the
posterior mean of the nonlinear reproductions (see :mod:`attend.perception.nonlinear_smoothers`)."""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

import numpy as np

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError
from attend.models.noise_model import NoiseModel
from attend.models.nonlinear import NonlinearSystem
from attend.perception.estimate import Estimate, as_estimate
from attend.perception.nonlinear_smoothers.coloured import _noise_model, _yule_walker, std_from_noise
from attend.perception.nonlinear_smoothers.kalman import _rk4


class ParticleEstimate(NamedTuple):
    """Particle smoother estimates: time (N,), states (N, n), inputs (N, r) posterior means,
    state_std, input_std their standard deviations, effective_sample_size (N,) after each update."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    effective_sample_size: np.ndarray

    def as_estimate(self) -> Estimate:
        """This result as the common :class:`attend.perception.estimate.Estimate` (details: this result)."""
        return as_estimate(self)


class _ARHistory:
    """The last q values (newest first) of unit-variance AR noises of ``channels`` channels, per
    particle; ``draw`` samples the next value given the history available so far."""

    def __init__(self, rho, q, channels, particles, rng):
        self.table = [_yule_walker(rho, j) for j in range(q + 1)]
        self.values = np.zeros((q, channels, particles))
        self.q, self.rng = q, rng

    def predict(self, available: int):
        """(conditional mean, innovation variance) of the next value given ``available`` values."""
        j = min(available, self.q)
        a, variance = self.table[j]
        return (np.tensordot(a, self.values[:j], axes=(0, 0)) if j else 0.0), variance

    def draw(self, available: int):
        mean, variance = self.predict(available)
        return mean + np.sqrt(variance) * self.rng.standard_normal(self.values.shape[1:])

    def push(self, value):
        if self.q:
            self.values[1:] = self.values[:-1].copy()
            self.values[0] = value

    def resample(self, index):
        self.values = self.values[:, :, index]


def _weighted_moments(samples, weights):
    """Weighted mean and std over particles of samples (channels, P)."""
    samples = np.array(samples)  # a fresh aligned copy: the same rounding as a gathered array
    mean = samples @ weights
    std = np.sqrt(np.clip(((samples - mean[:, None]) ** 2) @ weights, 0, None))
    return mean, std


@with_single_blas_thread
def particle_smoother(system: NonlinearSystem, dt: float, outputs, inputs=None, *, kernel_width: float | None = None,
                      process_std=None, measurement_std=None, input_prior_std=None, input_prior_mean=None,
                      initial_mean=None, initial_std=None, n_particles: int = 2000, ar_order: int = 3,
                      lag: int = 20, substeps: int = 4, seed=0,
                      input_kernel_width: float | None = None, noise: NoiseModel | None = None) -> ParticleEstimate:
    """Bootstrap particle filter + fixed-lag ancestry smoother under AR(q) coloured noise.

    The generative model is :func:`attend.models.simulate_nonlinear`'s: w, z (and,
    for unknown inputs, v with mean input_prior_mean and standard deviation input_prior_std, the
    DEM input prior) are Gaussian-kernel coloured noises of width kernel_width [s], each channel
    approximated by an AR(ar_order) process with the autocorrelation of the true noise at lags
    0..ar_order. The sensor noise is marginalised: a particle's weight is the AR predictive density
    of its residual y[k] - g(x[k], v[k]). Row k is the weighted mean over the ancestry at sample
    min(k + lag, N - 1) (only the last lag + 1 samples of particles are kept: memory
    O(lag n n_particles)). The system's f and g must accept (n, n_particles) columns
    (NonlinearSystem(vectorized=True) or functions written with x[0], x[1], ... and
    np.array([...]) on arrays). O(N n_particles) model evaluations: slow, a reference.

    system: the NonlinearSystem; dt: sample time [s]; outputs: (N, m); inputs: measured inputs
    (N, r), or None with input_prior_std for unknown inputs; process_std: sigma_w [state unit / s];
    measurement_std: sigma_z [output unit]; input_prior_mean: eta (scalar, (r,) or (N, r));
    initial_mean / initial_std: the Gaussian of x[0]; n_particles: P; lag: L samples;
    substeps: RK4 sub-steps per sample; seed: seed of the particle draws (independent seeds give
    independent runs: their spread measures the Monte Carlo error); input_kernel_width: the unknown
    inputs' own smoothness s_v [s] (default kernel_width).
    noise: an :class:`attend.models.NoiseModel` instead of kernel_width, process_std and
    measurement_std (its standard deviations, as :func:`attend.models.simulate_nonlinear` takes
    them; one kernel width for both noises here: a model whose widths differ is an error).
    """
    kernel_width, process_std, measurement_std = std_from_noise(noise, kernel_width, process_std, measurement_std,
                                                                "particle_smoother")
    q = int(ar_order)
    model = _noise_model(system, dt, outputs, inputs, kernel_width, process_std, measurement_std, input_prior_std,
                         input_prior_mean, input_kernel_width, q)
    n, r = system.n_states, system.n_inputs
    N = model.y.shape[0]
    run = ParticleRun(system, model, initial_mean, initial_std, n_particles, q, lag, substeps, seed)
    rows = np.empty((N, 2, n + r))  # per sample: (mean, std) of [x; v]
    ess = np.empty(N)
    signals = model.eta if model.unknown else model.u_known
    for k in range(N):
        ready, ess[k] = run.push(model.y[k], signals[k])
        if k == N - 1:  # the log ends: every kept sample, with the last weights
            ready += run.finish()
        for sample, moments in ready:
            rows[sample] = moments
    if not model.unknown:
        return ParticleEstimate(np.arange(N) * model.dt, rows[:, 0, :n], model.u_known, rows[:, 1, :n],
                                np.zeros((N, r)), ess)
    return ParticleEstimate(np.arange(N) * model.dt, rows[:, 0, :n], rows[:, 0, n:], rows[:, 1, :n], rows[:, 1, n:],
                            ess)


class ParticleRun:
    """The particle filter with its fixed-lag ancestry, one sample at a time: the loop of
    :func:`particle_smoother` (which runs it) and of :class:`OnlineParticle`.

    system: the NonlinearSystem; model: the noise settings of the log (from the coloured module's
    noise model: std, autocorrelations, whether the inputs are estimated); initial_mean,
    initial_std: the Gaussian of x[0] (None: 0); n_particles: P; q: the AR order; lag: L samples;
    substeps: RK4 sub-steps per sample; seed: seed of the draws.

    :meth:`push` takes sample k and returns the samples whose lag has passed (sample k - L), each
    with the (mean, std) of [x; v] over the particles' ancestry, and the effective sample size;
    :meth:`finish` returns the samples still kept, with the last weights (the end of a log).
    Resampling (when the effective sample size falls below P / 2) is drawn at the start of the
    next push, so a log's last sample is not resampled: the draws are those of one loop over the log.
    """

    def __init__(self, system, model, initial_mean, initial_std, n_particles, q, lag, substeps, seed):
        n, r, m = system.n_states, system.n_inputs, system.n_outputs
        self.system, self.model, self.lag, self.substeps = system, model, int(lag), substeps
        rng = np.random.default_rng(seed)
        P = int(n_particles)
        m0 = np.zeros(n) if initial_mean is None else np.asarray(initial_mean, dtype=float).reshape(n)
        s0 = np.zeros(n) if initial_std is None else np.broadcast_to(np.asarray(initial_std, dtype=float), (n,))
        self.w_hist = _ARHistory(model.rho, q, n, P, rng)
        self.v_hist = _ARHistory(model.rho_v, q, r, P, rng)
        self.z_hist = _ARHistory(model.rho, q, m, P, rng)  # residuals (sensor noise) of each particle's path
        self.x = m0[:, None] + s0[:, None] * rng.standard_normal((n, P))
        self.noises = [self.w_hist.draw(0), self.v_hist.draw(0)]
        self.recent = deque()  # (sample, particles [x; v] (n + r, P)) of the last lag + 1 samples
        self.log_w = np.zeros(P)
        self.weights = None
        self.rng, self.count, self.resample_next, self.previous_signal = rng, 0, False, None

    def push(self, y, signal) -> tuple[list, float]:
        """Sample k: outputs y (m,) and signal (r,), the measured inputs or the inputs' prior mean eta;
        returns ([(sample, (2, n + r) mean and std of [x; v]) of the samples whose lag has passed],
        effective sample size after the update)."""
        system, model, k = self.system, self.model, self.count
        n = system.n_states
        P = self.x.shape[1]
        if self.resample_next:
            self._resample()
        if k > 0:
            self.x = _propagate(system, model, self.x, self.noises, self.previous_signal, k, self.substeps,
                                (self.w_hist, self.v_hist))
        u_now = _inputs(model, self.noises[1], signal, P)
        x = self.x
        predicted_outputs = np.asarray(system.call_with_parameters(system.g, x, u_now), dtype=float)
        residual = (y[:, None] - predicted_outputs) / model.sz[:, None]
        predicted, variance = self.z_hist.predict(k)
        log_w = self.log_w - 0.5 * np.sum((residual - predicted) ** 2, axis=0) / variance
        self.z_hist.push(residual)
        log_w -= log_w.max()
        weights = np.exp(log_w)
        weights /= weights.sum()
        self.log_w, self.weights = log_w, weights
        if not np.all(np.isfinite(x)):
            raise AttendInputError("particle_smoother: non-finite particles; check the model and the noise levels")
        ess = 1.0 / np.sum(weights**2)
        self.recent.append((k, np.vstack([x, u_now])))
        ready = []
        while self.recent and k - self.recent[0][0] >= self.lag:  # the oldest kept sample has seen its lag
            ready.append(self._moments(*self.recent.popleft(), n))
        self.resample_next = ess < P / 2
        self.previous_signal, self.count = signal, k + 1
        return ready, ess

    def finish(self) -> list:
        """The samples still kept (the last ``lag``), with the last weights: the end of a log."""
        n = self.system.n_states
        ready = [self._moments(*self.recent.popleft(), n) for _ in range(len(self.recent))]
        return ready

    def _moments(self, sample, particles, n):
        return sample, np.hstack([_weighted_moments(particles[:n], self.weights),
                                  _weighted_moments(particles[n:], self.weights)])

    def _resample(self):
        """Systematic resampling: every carried quantity (and the kept past samples) follows its ancestor."""
        weights, P = self.weights, self.x.shape[1]
        index = np.minimum(np.searchsorted(np.cumsum(weights), (self.rng.random() + np.arange(P)) / P), P - 1)
        self.x = self.x[:, index]
        self.noises = [noise[:, index] for noise in self.noises]
        for history in (self.w_hist, self.v_hist, self.z_hist):
            history.resample(index)
        self.recent = deque((sample, particles[:, index]) for sample, particles in self.recent)
        self.log_w = np.zeros(P)
        self.resample_next = False


def _inputs(model, v_now, signal, P):
    """The particles' inputs at a sample: eta + sv v (unknown) or the measured ones; signal: that
    sample's eta (unknown inputs) or measured inputs (r,)."""
    if model.unknown:
        return signal[:, None] + model.sv[:, None] * v_now
    return signal[:, None] * np.ones((1, P))


def _propagate(system, model, x, noises, previous_signal, k, substeps, histories):
    """x[k] from x[k-1] under the noises of sample k - 1 (previous_signal: its eta or measured
    inputs); then draw the noises of sample k (``noises`` is updated in place)."""
    w_now, v_now = noises
    x = _rk4(system, x, _inputs(model, v_now, previous_signal, x.shape[1]), model.dt, substeps,
             w=model.sw[:, None] * w_now)
    w_hist, v_hist = histories
    w_hist.push(w_now)
    v_hist.push(v_now)
    noises[0], noises[1] = w_hist.draw(k), v_hist.draw(k)
    return x
