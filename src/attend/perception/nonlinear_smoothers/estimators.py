"""The nonlinear smoothers in the estimators' shape: ``Smoother(system, dt, *, noise=..., ...)``, then
``.estimate(outputs, inputs=None)`` for the whole log and ``.online()`` for the filter fed one
sample at a time, as :class:`attend.perception.kalman.KalmanEstimator` and the DEM observers.

- :class:`UnscentedSmoother` and :class:`ExtendedSmoother` hold the settings of
  :func:`attend.perception.nonlinear_smoothers.unscented_kalman` / ``extended_kalman``; their
  ``estimate`` calls them (the same numbers), their ``online()`` gives :class:`OnlineUnscented` /
  :class:`OnlineExtended`, the forward (filter) pass of those functions step by step: the same
  prediction and update code, so sample k's result equals row k of ``estimate`` with
  ``smooth=False``.
- :class:`ParticleSmoother` holds the settings of
  :func:`attend.perception.nonlinear_smoothers.particle_smoother`; ``online()`` gives
  :class:`OnlineParticle`, the same particles and draws fed one sample at a time (a fixed-lag
  smoother: sample k's estimate comes out with sample k + lag; lag=0 is the particle filter).

Results: ``estimate`` returns an :class:`attend.perception.estimate.Estimate`, its ``details`` the
functions' own result (:class:`attend.perception.references.KalmanEstimate`,
:class:`attend.perception.nonlinear_smoothers.ParticleEstimate`), whose extra fields
(state_covariance, log_likelihood, effective_sample_size) the Estimate reads too.
"""

from __future__ import annotations

from collections import deque
from dataclasses import KW_ONLY, InitVar, dataclass

import numpy as np

from attend._validation import AttendInputError, positive_scalar, require_finite, stream_sample
from attend.models.noise_model import NoiseModel
from attend.models.nonlinear import NonlinearSystem
from attend.perception.nonlinear_smoothers.coloured import _noise_model, std_from_noise
from attend.perception.nonlinear_smoothers.kalman import (
    _extended_predict,
    _extended_update,
    _Model,
    _unscented_predict,
    _unscented_update,
    covariances_from_noise,
    extended_kalman,
    unscented_kalman,
)
from attend.perception.nonlinear_smoothers.particle import ParticleRun, particle_smoother
from attend.perception.estimate import Estimate, as_estimate

__all__ = ["UnscentedSmoother", "ExtendedSmoother", "ParticleSmoother", "OnlineUnscented", "OnlineExtended",
           "OnlineParticle"]


def _white_noise_settings(smoother, noise, who: str) -> None:
    """Check the system and dt, and write ``noise`` (a NoiseModel or None) into the smoother's
    process_covariance and measurement_covariance (:func:`covariances_from_noise`)."""
    if not isinstance(smoother.system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    object.__setattr__(smoother, "dt", positive_scalar(smoother.dt, "dt", "s"))
    Q, R = covariances_from_noise(smoother.system, smoother.dt, noise, smoother.process_covariance,
                                  smoother.measurement_covariance, who)
    object.__setattr__(smoother, "process_covariance", Q)
    object.__setattr__(smoother, "measurement_covariance", R)


@dataclass(frozen=True, eq=False)
class _WhiteNoiseSmoother:
    """The settings the unscented and extended smoothers share (their classes document them);
    ``kind`` names the filter in :attr:`method`."""

    kind = "white-noise"

    system: NonlinearSystem
    dt: float
    _: KW_ONLY
    process_covariance: np.ndarray | None = None
    measurement_covariance: np.ndarray | None = None
    input_variance: np.ndarray | None = None
    input_mean: np.ndarray | None = None
    initial_mean: np.ndarray | None = None
    initial_covariance: np.ndarray | None = None
    smooth: bool | int = True
    substeps: int = 10
    noise_kernel_width: float | None = None
    input_prior: tuple | None = None
    spread_draws: int | None = 200
    seed: int = 0
    noise: InitVar[NoiseModel | None] = None

    def __post_init__(self, noise):
        _white_noise_settings(self, noise, type(self).__name__)

    @property
    def method(self) -> str:
        """A short name of the estimator for reports."""
        return f"{self.kind} kalman " + ("filter" if self.smooth is False else "smoother")

    def _settings(self) -> dict:
        """The keyword arguments this smoother gives its function (unscented_kalman or
        extended_kalman): the fields both take."""
        return dict(process_covariance=self.process_covariance, measurement_covariance=self.measurement_covariance,
                    input_variance=self.input_variance, input_mean=self.input_mean, initial_mean=self.initial_mean,
                    initial_covariance=self.initial_covariance, smooth=self.smooth, substeps=self.substeps,
                    noise_kernel_width=self.noise_kernel_width, input_prior=self.input_prior,
                    spread_draws=self.spread_draws, seed=self.seed)


@dataclass(frozen=True, eq=False)
class UnscentedSmoother(_WhiteNoiseSmoother):
    """The unscented Kalman smoother (white-noise model) as an estimator:
    ``UnscentedSmoother(system, dt, *, noise=NoiseModel(...), ...)`` or with
    ``process_covariance`` / ``measurement_covariance`` instead of ``noise``; then
    :meth:`estimate` (the whole log) and :meth:`online` (the filter, one sample at a time).

    system: the NonlinearSystem; dt: sample time [s]; noise: an :class:`attend.models.NoiseModel`,
    converted to Q = dt^2 inv(Pi_w), R = inv(Pi_z) (:func:`~attend.perception.nonlinear_smoothers.white_noise_options`;
    its kernel widths are not used by the white-noise filter); process_covariance Q [state unit^2]
    and measurement_covariance R [output unit^2] per sample instead of noise (not both);
    input_variance, input_mean, initial_mean, initial_covariance, smooth, substeps, alpha, beta,
    kappa, known_inputs, noise_kernel_width, input_prior, spread_draws, seed: as
    :func:`~attend.perception.nonlinear_smoothers.unscented_kalman`, which :meth:`estimate` calls.
    """

    kind = "unscented"

    _: KW_ONLY
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    known_inputs: np.ndarray | None = None

    def estimate(self, outputs, inputs=None) -> Estimate:
        """The estimates over a whole log: :func:`~attend.perception.nonlinear_smoothers.unscented_kalman`
        with this smoother's settings, as an :class:`attend.perception.estimate.Estimate` (method:
        :attr:`method`; details: the KalmanEstimate, with state_covariance and log_likelihood).
        outputs (N, m); inputs (N, r): the measured inputs (None: zero, or unknown with input_variance)."""
        result = unscented_kalman(self.system, self.dt, outputs, inputs, alpha=self.alpha, beta=self.beta,
                                  kappa=self.kappa, known_inputs=self.known_inputs, **self._settings())
        return as_estimate(result, self.method)

    def online(self) -> "OnlineUnscented":
        """The unscented filter fed one sample at a time (:class:`OnlineUnscented`)."""
        return OnlineUnscented(self)


@dataclass(frozen=True, eq=False)
class ExtendedSmoother(_WhiteNoiseSmoother):
    """The extended Kalman smoother (white-noise model) as an estimator:
    ``ExtendedSmoother(system, dt, *, noise=NoiseModel(...), ...)`` or with ``process_covariance``
    / ``measurement_covariance`` instead of ``noise``; then :meth:`estimate` and :meth:`online`.

    system: the NonlinearSystem; dt: sample time [s]; noise, process_covariance,
    measurement_covariance: as :class:`UnscentedSmoother`; input_variance, input_mean,
    initial_mean, initial_covariance, smooth, substeps, noise_kernel_width, input_prior,
    spread_draws, seed: as :func:`~attend.perception.nonlinear_smoothers.extended_kalman`, which
    :meth:`estimate` calls.
    """

    kind = "extended"

    def estimate(self, outputs, inputs=None) -> Estimate:
        """The estimates over a whole log: :func:`~attend.perception.nonlinear_smoothers.extended_kalman`
        with this smoother's settings, as an :class:`attend.perception.estimate.Estimate` (method:
        :attr:`method`; details: the KalmanEstimate, with state_covariance and log_likelihood).
        outputs (N, m); inputs (N, r): the measured inputs (None: zero, or unknown with input_variance)."""
        result = extended_kalman(self.system, self.dt, outputs, inputs, **self._settings())
        return as_estimate(result, self.method)

    def online(self) -> "OnlineExtended":
        """The extended filter fed one sample at a time (:class:`OnlineExtended`)."""
        return OnlineExtended(self)


class _OnlineFilter:
    """The forward pass of the white-noise smoothers, one sample at a time (shared by
    :class:`OnlineUnscented` and :class:`OnlineExtended`)."""

    def __init__(self, smoother, known_inputs=None):
        self.smoother = smoother
        system = smoother.system
        m, r = system.n_outputs, system.n_inputs
        unknown = smoother.input_variance is not None and r > 0
        mask = np.zeros(r, dtype=bool) if known_inputs is None else \
            np.broadcast_to(np.asarray(known_inputs, dtype=bool), (r,))
        # the discrete model of one sample (its inputs are replaced at every step)
        measured = np.zeros((1, r)) if unknown and mask.any() else None
        self._model = _Model(system, smoother.dt, np.zeros((1, m)), measured,
                             smoother.input_variance, smoother.input_mean, smoother.process_covariance,
                             smoother.measurement_covariance, smoother.initial_mean, smoother.initial_covariance,
                             smoother.substeps, known_inputs)
        self._count = 0
        self._mean, self._cov = self._model.m0.copy(), self._model.P0.copy()
        self._previous_input = None

    def _predict(self, mean, cov, k):  # pragma: no cover - defined by the subclasses
        raise NotImplementedError

    def _update(self, mean, cov, y, k):  # pragma: no cover - defined by the subclasses
        raise NotImplementedError

    def step(self, output, input_value=None):
        """Feed sample k (output: the outputs (m,); input_value: the measured inputs (r,), default 0;
        ignored for inputs estimated as random walks); return (states (n,), inputs (r,), state_std
        (n,), input_std (r,)) of sample k given the outputs up to k (the filter)."""
        model = self._model
        system = model.system
        n, m, r = system.n_states, system.n_outputs, system.n_inputs
        y, u = stream_sample(output, input_value, m, r)
        require_finite(y, "step output")
        require_finite(u, "step input_value")
        mean, cov = self._mean, self._cov
        if self._count == 0:
            model.u = u[None, :]
            k = 0
        else:
            model.u = np.vstack([self._previous_input, u])
            k = 1
            mean, cov = self._predict(mean, cov, k)
        mean, cov = self._update(mean, cov, y, k)
        if not np.all(np.isfinite(mean)):
            raise AttendInputError(f"{type(self).__name__}: the filter diverged (non-finite estimates); check the "
                                   "covariances")
        self._mean, self._cov, self._previous_input = mean, cov, u
        self._count += 1
        std = np.sqrt(np.clip(np.diagonal(cov), 0, None))
        if model.augmented:
            inputs, input_std = mean[n:].copy(), std[n:].copy()
            inputs[model.known] = u[model.known]
            input_std[model.known] = 0.0
        else:
            inputs, input_std = u.copy(), np.zeros(r)
        return mean[:n].copy(), inputs, std[:n].copy(), input_std


class OnlineUnscented(_OnlineFilter):
    """The unscented filter fed one sample at a time: ``step(y, u)`` returns (states, inputs,
    state_std, input_std) of that sample, equal to row k of ``UnscentedSmoother.estimate`` with
    smooth=False (the same prediction and update functions as
    :func:`~attend.perception.nonlinear_smoothers.unscented_kalman`). The std is the filter's own
    covariance (the error spread under coloured noise, ``noise_kernel_width``, needs the whole log).
    Memory does not grow with the stream.

    smoother: the :class:`UnscentedSmoother` whose settings it runs.
    """

    def __init__(self, smoother: UnscentedSmoother):
        super().__init__(smoother, smoother.known_inputs)
        self._spread = (smoother.alpha, smoother.beta, smoother.kappa)

    def _predict(self, mean, cov, k):
        model = self._model
        mean, cov, _, _ = _unscented_predict(model.transition_points, mean, cov, model.Qz, self._spread, k)
        return mean, cov

    def _update(self, mean, cov, y, k):
        model = self._model
        mean, cov, *_ = _unscented_update(model.observation_points, mean, cov, model.R, self._spread, y, k)
        return mean, cov


class OnlineExtended(_OnlineFilter):
    """The extended filter fed one sample at a time: ``step(y, u)`` returns (states, inputs,
    state_std, input_std) of that sample, equal to row k of ``ExtendedSmoother.estimate`` with
    smooth=False (the same prediction and update functions as
    :func:`~attend.perception.nonlinear_smoothers.extended_kalman`). The std is the filter's own
    covariance. Memory does not grow with the stream.

    smoother: the :class:`ExtendedSmoother` whose settings it runs.
    """

    def __init__(self, smoother: ExtendedSmoother):
        super().__init__(smoother)

    def _predict(self, mean, cov, k):
        mean, cov, _ = _extended_predict(self._model, mean, cov, k)
        return mean, cov

    def _update(self, mean, cov, y, k):
        mean, cov, *_ = _extended_update(self._model, mean, cov, y, k)
        return mean, cov


@dataclass(frozen=True, eq=False)
class ParticleSmoother:
    """The particle smoother (the slow nonlinear reference) as an estimator:
    ``ParticleSmoother(system, dt, *, noise=NoiseModel(...), ...)`` or with kernel_width,
    process_std and measurement_std instead of ``noise``; then :meth:`estimate` (the whole log)
    and :meth:`online` (one sample at a time).

    system: the NonlinearSystem; dt: sample time [s]; noise: an :class:`attend.models.NoiseModel`
    (its standard deviations and its one kernel width: a model whose widths differ is an error);
    kernel_width s [s], process_std sigma_w [state unit / s], measurement_std sigma_z [output unit]
    instead of noise (not both); input_prior_std, initial_mean, initial_std, n_particles, ar_order,
    lag, substeps, seed, input_kernel_width: as
    :func:`~attend.perception.nonlinear_smoothers.particle_smoother`, which :meth:`estimate` calls.
    """

    system: NonlinearSystem
    dt: float
    _: KW_ONLY
    kernel_width: float | None = None
    process_std: np.ndarray | float | None = None
    measurement_std: np.ndarray | float | None = None
    input_prior_std: np.ndarray | float | None = None
    initial_mean: np.ndarray | None = None
    initial_std: np.ndarray | float | None = None
    n_particles: int = 2000
    ar_order: int = 3
    lag: int = 20
    substeps: int = 4
    seed: int = 0
    input_kernel_width: float | None = None
    noise: InitVar[NoiseModel | None] = None

    def __post_init__(self, noise):
        if not isinstance(self.system, NonlinearSystem):
            raise AttendInputError("system: expected an attend NonlinearSystem")
        values = std_from_noise(noise, self.kernel_width, self.process_std, self.measurement_std, "ParticleSmoother")
        for name, value in zip(("kernel_width", "process_std", "measurement_std"), values):
            object.__setattr__(self, name, value)

    @property
    def method(self) -> str:
        """A short name of the estimator for reports."""
        return "particle smoother"

    def estimate(self, outputs, inputs=None) -> Estimate:
        """The estimates over a whole log: :func:`~attend.perception.nonlinear_smoothers.particle_smoother`
        with these settings, as an :class:`attend.perception.estimate.Estimate` (method "particle
        smoother"; details: the ParticleEstimate, with effective_sample_size). outputs (N, m);
        inputs (N, r): the measured inputs, or, with input_prior_std (unknown inputs), their prior
        mean eta (default 0)."""
        unknown = self.input_prior_std is not None
        result = particle_smoother(self.system, self.dt, outputs, None if unknown else inputs,
                                   kernel_width=self.kernel_width, process_std=self.process_std,
                                   measurement_std=self.measurement_std, input_prior_std=self.input_prior_std,
                                   input_prior_mean=inputs if unknown else None, initial_mean=self.initial_mean,
                                   initial_std=self.initial_std, n_particles=self.n_particles, ar_order=self.ar_order,
                                   lag=self.lag, substeps=self.substeps, seed=self.seed,
                                   input_kernel_width=self.input_kernel_width)
        return as_estimate(result, self.method)

    def online(self) -> "OnlineParticle":
        """The same particle smoother fed one sample at a time (:class:`OnlineParticle`)."""
        return OnlineParticle(self)


class OnlineParticle:
    """The particle smoother fed one sample at a time: ``step(y, u)`` takes sample k (outputs (m,),
    and the measured inputs or, with input_prior_std, the inputs' prior mean eta (r,); default 0)
    and returns (states, inputs, state_std, input_std) of sample k - lag once lag samples have
    followed it (None before); ``finish()`` returns the last ``lag`` samples' estimates, with the last
    weights, as :meth:`ParticleSmoother.estimate` does at the end of a log. The same particles and
    draws as the batch smoother (:class:`attend.perception.nonlinear_smoothers.particle.ParticleRun`
    runs both): the rows equal the batch rows exactly. lag=0 gives the particle filter.
    Memory O(lag n n_particles), fixed.

    smoother: the :class:`ParticleSmoother` whose settings it runs.
    """

    def __init__(self, smoother: ParticleSmoother):
        system = smoother.system
        self.smoother = smoother
        unknown = smoother.input_prior_std is not None and system.n_inputs > 0
        q = int(smoother.ar_order)
        model = _noise_model(system, smoother.dt, np.zeros((1, system.n_outputs)),
                             None if unknown else np.zeros((1, system.n_inputs)), smoother.kernel_width,
                             smoother.process_std, smoother.measurement_std, smoother.input_prior_std, None,
                             smoother.input_kernel_width, q)
        self._unknown = unknown
        self._given = deque()  # measured inputs of the samples still waiting for their lag
        self._run = ParticleRun(system, model, smoother.initial_mean, smoother.initial_std, smoother.n_particles, q,
                                smoother.lag, smoother.substeps, smoother.seed)

    def _row(self, sample, moments):
        n = self.smoother.system.n_states
        if self._unknown:
            return moments[0, :n], moments[0, n:], moments[1, :n], moments[1, n:]
        given = self._given.popleft()  # measured inputs: the given values, as the batch smoother returns them
        return moments[0, :n], given, moments[1, :n], np.zeros_like(given)

    def step(self, output, input_value=None):
        """Feed sample k (output: the outputs (m,); input_value: the measured inputs or the inputs'
        prior mean (r,), default 0); return (states, inputs, state_std, input_std) of sample
        k - lag, or None while the first lag samples arrive."""
        system = self.smoother.system
        m, r = system.n_outputs, system.n_inputs
        y, u = stream_sample(output, input_value, m, r)
        require_finite(y, "step output")
        require_finite(u, "step input_value")
        if not self._unknown:
            self._given.append(u)
        ready, _ = self._run.push(y, u)
        return self._row(*ready[0]) if ready else None

    def finish(self) -> list:
        """The estimates of the samples still waiting for their lag (the end of the stream)."""
        return [self._row(*item) for item in self._run.finish()]
