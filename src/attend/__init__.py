"""attend: precision-modulated perception and action for robots.

Public API (everything else is private):

- systems: :class:`LinearSystem`, :func:`simulate`, presets :func:`mass_spring_damper`,
  :func:`convolution_model`, :func:`identification_system`, :func:`quadrotor_roll`
- noise: :func:`coloured_noise`
- generalised coordinates: :func:`smoothness_precision`, :func:`embed`, :func:`shift_operator`
- perception: :class:`KalmanEstimator` (coloured-noise Kalman smoother/filter, the default of
  ``attend estimate``), :class:`StateEstimate`, :class:`DEMObserver`, :class:`DEMEstimate`
- nonlinear models: :class:`NonlinearSystem` (f, g), :class:`NonlinearDEM`, :func:`simulate_nonlinear`
- learning: :func:`identify`, :class:`IdentificationResult`
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

The presets also live in :mod:`attend.problems` with the paper's reference problems; named
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
    "block_precisions": "attend.generalized",
    "coloured_noise": "attend.noise",
    "convolution_model": "attend.problems",
    "DEMEstimate": "attend.perception.dem",
    "DEMObserver": "attend.perception.dem",
    "drive": "attend.rhythm",
    "embed": "attend.generalized",
    "embedding_weights": "attend.generalized",
    "FixedSchedule": "attend.rhythm",
    "fly": "attend.action",
    "fly_search": "attend.action",
    "identification_system": "attend.problems",
    "IdentificationResult": "attend.perception.learning",
    "identify": "attend.perception.learning",
    "KalmanEstimator": "attend.perception.kalman",
    "LinearSystem": "attend.systems",
    "make_field": "attend.action",
    "make_planner": "attend.action",
    "make_world": "attend.action",
    "mass_spring_damper": "attend.problems",
    "ModelWarning": "attend.systems",
    "NonlinearDEM": "attend.perception.nonlinear",
    "NonlinearSystem": "attend.perception.nonlinear",
    "OccupancyMap": "attend.action",
    "OnlineDEM": "attend.perception.dem",
    "OnlineKalman": "attend.perception.kalman",
    "PrecisionDrivenSchedule": "attend.rhythm",
    "PrecisionOscillator": "attend.rhythm",
    "ProbabilityMap": "attend.action",
    "Mission": "attend.action.mission",
    "progress_bars": "attend._progress",
    "quadrotor_roll": "attend.problems",
    "RhythmicSchedule": "attend.rhythm",
    "run_search": "attend.action",
    "SearchField": "attend.action",
    "shift_operator": "attend.generalized",
    "simulate": "attend.systems",
    "simulate_nonlinear": "attend.perception.nonlinear",
    "smoothness_precision": "attend.generalized",
    "StateEstimate": "attend.perception.kalman",
    "Trajectory": "attend.systems",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports("attend", _EXPORTS, globals())
