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
- action (UAV search, :mod:`attend.action`): :func:`make_field` / :class:`SearchField`,
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

from attend._progress import progress_bars
from attend._validation import AttendInputError
from attend.action import OccupancyMap, SearchField, fly, make_field, make_planner, run_search
from attend.generalized import block_precisions, embed, embedding_weights, shift_operator, smoothness_precision
from attend.noise import coloured_noise
from attend.perception.dem import DEMEstimate, DEMObserver, OnlineDEM
from attend.perception.kalman import KalmanEstimator, OnlineKalman, StateEstimate
from attend.perception.learning import IdentificationResult, identify
from attend.perception.nonlinear import NonlinearDEM, NonlinearSystem, simulate_nonlinear
from attend.problems import convolution_model, identification_system, mass_spring_damper, quadrotor_roll
from attend.rhythm import (ActiveVisionAgent, FixedSchedule, PrecisionDrivenSchedule, PrecisionOscillator,
                           RhythmicSchedule, drive)
from attend.systems import LinearSystem, ModelWarning, Trajectory, simulate

__version__ = "0.1.0"

__all__ = [
    "ActiveVisionAgent",
    "AttendInputError",
    "DEMEstimate",
    "DEMObserver",
    "FixedSchedule",
    "IdentificationResult",
    "KalmanEstimator",
    "LinearSystem",
    "ModelWarning",
    "NonlinearDEM",
    "NonlinearSystem",
    "OccupancyMap",
    "OnlineDEM",
    "OnlineKalman",
    "PrecisionDrivenSchedule",
    "PrecisionOscillator",
    "RhythmicSchedule",
    "SearchField",
    "StateEstimate",
    "Trajectory",
    "block_precisions",
    "coloured_noise",
    "convolution_model",
    "drive",
    "embed",
    "embedding_weights",
    "fly",
    "identification_system",
    "identify",
    "make_field",
    "make_planner",
    "mass_spring_damper",
    "progress_bars",
    "quadrotor_roll",
    "run_search",
    "shift_operator",
    "simulate",
    "simulate_nonlinear",
    "smoothness_precision",
]
