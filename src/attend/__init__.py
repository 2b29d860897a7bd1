"""attend: precision-modulated perception and action for robots.

Public API (everything else is private):

- models (:mod:`attend.models`): :class:`LinearSystem`, :func:`simulate`, presets
  :func:`mass_spring_damper`, :func:`convolution_model`, :func:`identification_system`,
  :func:`quadrotor_roll`; :class:`NonlinearSystem` (f, g), :func:`simulate_nonlinear`; noise
  :class:`NoiseModel` (precisions and kernel widths, taken by every estimator), :func:`coloured_noise`; generalised coordinates :func:`smoothness_precision`, :func:`embed`,
  :func:`shift_operator`
- perception: :class:`KalmanEstimator` (coloured-noise Kalman smoother/filter, the default of
  ``attend estimate``), :class:`StateEstimate`, :class:`DEMObserver`, :class:`DEMEstimate`;
  :class:`Estimate`, the one result type every estimator's ``.estimate()`` returns (the
  estimator's own StateEstimate or DEMEstimate in ``details``)
- learning: :func:`identify` (settings :class:`LearningSettings`), :class:`IdentificationResult`
- nonlinear perception: :class:`NonlinearDEM` for a :class:`NonlinearSystem`
- action (UAV search, :mod:`attend.action`): at field scale :func:`make_world`,
  :class:`ProbabilityMap`, :func:`fly_search` (several UAVs, the EFE planner); the paper's
  field :func:`make_field` / :class:`SearchField`,
  :class:`OccupancyMap` (precision map), :func:`make_planner`, :func:`fly` (one mission in code),
  :func:`run_search` (one mission with its files)
- rhythm (:mod:`attend.rhythm`): :class:`PrecisionOscillator`, the schedules
  :class:`RhythmicSchedule`, :class:`PrecisionDrivenSchedule`, :class:`FixedSchedule`,
  :func:`drive`, :class:`ActiveVisionAgent`
- errors: :class:`AttendInputError`, :class:`ModelWarning`
- progress: :func:`progress_bars` (``with attend.progress_bars(): ...`` shows the slower
  estimators' progress on stderr)

The presets also live in :mod:`attend.models.problems` with the paper's reference problems; named
precisions in :mod:`attend.constants`.
"""

from __future__ import annotations

from attend._lazy import lazy_exports

__version__ = "0.1.0"

#: public name -> the module that defines it; imported at the first use of the name (PEP 562), so
#: ``import attend`` itself loads neither SciPy nor any subpackage.
_EXPORTS = {
    "ActiveVisionAgent": "attend.rhythm",
    "AttendInputError": "attend._validation",
    "block_precisions": "attend.models.generalized",
    "coloured_noise": "attend.models.noise",
    "convolution_model": "attend.models.problems",
    "DEMEstimate": "attend.perception.dem",
    "DEMObserver": "attend.perception.dem",
    "Estimate": "attend.perception.estimate",
    "drive": "attend.rhythm",
    "embed": "attend.models.generalized",
    "embedding_weights": "attend.models.generalized",
    "FixedSchedule": "attend.rhythm",
    "fly": "attend.action",
    "fly_search": "attend.action",
    "identification_system": "attend.models.problems",
    "IdentificationResult": "attend.perception.learning",
    "identify": "attend.perception.learning",
    "KalmanEstimator": "attend.perception.kalman",
    "LearningSettings": "attend.perception.learning",
    "LinearSystem": "attend.models.linear",
    "make_field": "attend.action",
    "make_planner": "attend.action",
    "make_world": "attend.action",
    "mass_spring_damper": "attend.models.problems",
    "ModelWarning": "attend.models.linear",
    "NonlinearDEM": "attend.perception.nonlinear",
    "NonlinearSystem": "attend.models.nonlinear",
    "NoiseModel": "attend.models.noise_model",
    "OccupancyMap": "attend.action",
    "OnlineDEM": "attend.perception.dem",
    "OnlineKalman": "attend.perception.kalman",
    "PrecisionDrivenSchedule": "attend.rhythm",
    "PrecisionOscillator": "attend.rhythm",
    "ProbabilityMap": "attend.action",
    "Mission": "attend.action.mission",
    "progress_bars": "attend._progress",
    "quadrotor_roll": "attend.models.problems",
    "RhythmicSchedule": "attend.rhythm",
    "run_search": "attend.action",
    "SearchField": "attend.action",
    "shift_operator": "attend.models.generalized",
    "simulate": "attend.models.linear",
    "simulate_nonlinear": "attend.models.nonlinear",
    "smoothness_precision": "attend.models.generalized",
    "StateEstimate": "attend.perception.kalman",
    "Trajectory": "attend.models.linear",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports("attend", _EXPORTS, globals())
