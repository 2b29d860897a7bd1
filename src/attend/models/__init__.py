"""Models: what a system is, apart from how its states are estimated.

- :mod:`.linear`: :class:`LinearSystem` (dx/dt = A x + B u + w, y = C x + z), its zero-order-hold
  discretisation, :func:`simulate` (a :class:`Trajectory` under coloured noise), and
  :func:`from_statespace` (a python-control ``StateSpace`` as a LinearSystem);
- :mod:`.nonlinear`: :class:`NonlinearSystem` (dx/dt = f(x, v) + w, y = g(x, v) + z), its Jacobians
  and :func:`simulate_nonlinear`;
- :mod:`.noise_model`: :class:`NoiseModel`, the noise of a model as one value (process and sensor
  precisions, kernel widths; from standard deviations or covariances), taken by every estimator
  and by :func:`simulate`;
- :mod:`.noise`: coloured noise (white noise convolved with a Gaussian kernel of width s), its
  autocorrelation and finite state-space models of it;
- :mod:`.generalized`: generalised coordinates: the smoothness precision S(s), the shift operator
  D and the embedding of a sampled series;
- :mod:`.parameters`: the parameter vector theta = [vec(A); vec(B); vec(C)] and its names;
- :mod:`.problems`: the paper's reference systems (presets) and the mass-spring-damper bank.
- :mod:`.sample_times`: time stamps of sampled signals: gaps (missing samples), jitter and the
  grid the estimators run on (read by the log readers of attend.io and by the estimators).

This layer imports nothing from the rest of attend (perception, action, control, rhythm, io, the
experiments, the command line): estimators, learners and controllers build on it.
"""

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562).
_EXPORTS = {
    **dict.fromkeys(("LinearSystem", "ModelWarning", "Trajectory", "as_linear_system", "from_statespace",
                     "observability_rank", "simulate", "zero_order_hold"), "attend.models.linear"),
    **dict.fromkeys(("NonlinearSystem", "evaluate_many", "finite_difference_jacobian", "simulate_nonlinear"),
                    "attend.models.nonlinear"),
    **dict.fromkeys(("ContinuousNoiseStateSpace", "NoiseStateSpace", "autocorrelation", "coloured_noise",
                     "continuous_noise_state_space", "gaussian_kernel", "kernel_autocorrelation",
                     "noise_state_space", "sampled_autocorrelation", "white_state_space"), "attend.models.noise"),
    "NoiseModel": "attend.models.noise_model",
    **dict.fromkeys(("block_precisions", "embed", "embedding_weights", "shift_operator", "smoothness_condition",
                     "smoothness_precision", "temporal_covariance"), "attend.models.generalized"),
    **dict.fromkeys(("parameter_names", "parameter_vector", "system_from_parameters"), "attend.models.parameters"),
    **dict.fromkeys(("convolution_model", "identification_system", "mass_spring_damper", "quadrotor_roll"),
                    "attend.models.problems"),
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports("attend.models", _EXPORTS, globals())
