"""Smoothers for nonlinear models besides DEM: extended and unscented Kalman filters/smoothers (the
unscented smoother is the default estimator of a nonlinear model file), the unscented smoother
under a finite model of the coloured noise, the smoothers' error spread under coloured noise, and
the particle smoother (the slow reference they are compared with).

The Kalman-type smoothers (white noise) work on the discrete model that
:func:`attend.models.simulate_nonlinear` samples without noise::

    x[k] = F(x[k-1], u[k-1]) + q[k-1],  q ~ N(0, Q)        (Q = process_covariance)
    y[k] = g(x[k], u[k]) + r[k],        r ~ N(0, R)        (R = measurement_covariance)
    x[0] ~ N(m0, P0)

F integrates dx/dt = f(x, u) over one sample dt by RK4 with ``substeps`` sub-steps (u held).
Unknown inputs: pass ``input_variance`` instead of inputs; the state is augmented with
u[k] = u[k-1] + e, e ~ N(0, input_variance) (a random walk), started at ``input_mean``.
:func:`white_noise_covariances` gives the Q, R matching coloured noise (same variance per sample,
or same low-frequency power).

The functions return :class:`attend.perception.references.KalmanEstimate` (time, states, inputs,
state_std, input_std first, as :class:`attend.perception.dem.DEMEstimate`). With ``noise_kernel_width``, the
unscented filter's or smoother's std is its error spread under coloured noise of that width
(:mod:`attend.perception.nonlinear_smoothers.error_spread`) instead of the white-noise model's own
covariance, which is too small there.

:func:`particle_smoother`: a bootstrap particle filter whose state carries the coloured noises
(each channel an autoregressive model AR(q) fitted by Yule-Walker to rho(tau) =
exp(-tau^2/(4 s^2)) at lags 0..q samples), with the sensor noise marginalised exactly (given a
particle's path, z is known up to its AR innovation), and fixed-lag smoothing by tracing the
particles' ancestry. Its mean approximates the posterior mean under the coloured-noise model
(exact as the number of particles grows, up to the AR(q) fit of rho and the lag): a slow
reference, not an estimator for use.

The same as estimators (``Smoother(system, dt, *, noise=NoiseModel(...), ...)``, ``.estimate(outputs,
inputs)`` -> :class:`attend.perception.estimate.Estimate`, ``.online()``): :class:`UnscentedSmoother`, :class:`ExtendedSmoother` (their online
filters :class:`OnlineUnscented`, :class:`OnlineExtended`) and :class:`ParticleSmoother` (online:
:class:`OnlineParticle`, the same draws one sample at a time) (:mod:`.estimators`).

Layout: :mod:`.kalman` (extended and unscented filters and smoothers, white-noise models),
:mod:`.coloured` (the finite model of the coloured noises and the unscented smoother under it),
:mod:`.particle` (the particle smoother), :mod:`.error_spread` (the smoothers' error covariance
under coloured noise).
"""

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562).
_EXPORTS = {
    "coloured_unscented_smoother": "attend.perception.nonlinear_smoothers.coloured",
    "extended_kalman": "attend.perception.nonlinear_smoothers.kalman",
    "EvidenceBelowFloor": "attend.perception.nonlinear_smoothers.kalman",
    "input_random_walk_variance": "attend.perception.nonlinear_smoothers.kalman",
    "unscented_kalman": "attend.perception.nonlinear_smoothers.kalman",
    "unscented_innovation_terms": "attend.perception.nonlinear_smoothers.kalman",
    "white_noise_covariances": "attend.perception.nonlinear_smoothers.kalman",
    "white_noise_options": "attend.perception.nonlinear_smoothers.kalman",
    "ParticleEstimate": "attend.perception.nonlinear_smoothers.particle",
    **dict.fromkeys(("UnscentedSmoother", "ExtendedSmoother", "ParticleSmoother", "OnlineUnscented", "OnlineExtended",
                     "OnlineParticle"), "attend.perception.nonlinear_smoothers.estimators"),
    "particle_smoother": "attend.perception.nonlinear_smoothers.particle",
}

__all__ = [
    "white_noise_covariances",
    "white_noise_options",
    "input_random_walk_variance",
    "extended_kalman",
    "unscented_kalman",
    "unscented_innovation_terms",
    "EvidenceBelowFloor",
    "particle_smoother",
    "coloured_unscented_smoother",
    "ParticleEstimate",
    "UnscentedSmoother",
    "ExtendedSmoother",
    "ParticleSmoother",
    "OnlineUnscented",
    "OnlineExtended",
    "OnlineParticle",
]

__getattr__, __dir__ = lazy_exports("attend.perception.nonlinear_smoothers", _EXPORTS, globals())
