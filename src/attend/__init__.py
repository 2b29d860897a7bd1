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
- errors: :class:`AttendInputError`, :class:`ModelWarning`
"""

from attend._validation import AttendInputError
from attend.generalized import block_precisions, embed, embedding_weights, shift_operator, smoothness_precision
from attend.noise import coloured_noise
from attend.perception.dem import DEMEstimate, DEMObserver, OnlineDEM
from attend.perception.kalman import KalmanEstimator, OnlineKalman, StateEstimate
from attend.perception.learning import IdentificationResult, identify
from attend.perception.nonlinear import NonlinearDEM, NonlinearSystem, simulate_nonlinear
from attend.systems import (
    LinearSystem,
    ModelWarning,
    Trajectory,
    convolution_model,
    identification_system,
    mass_spring_damper,
    quadrotor_roll,
    simulate,
)

__version__ = "0.1.0"

__all__ = [
    "AttendInputError",
    "DEMEstimate",
    "DEMObserver",
    "IdentificationResult",
    "KalmanEstimator",
    "LinearSystem",
    "ModelWarning",
    "NonlinearDEM",
    "NonlinearSystem",
    "OnlineDEM",
    "OnlineKalman",
    "StateEstimate",
    "Trajectory",
    "block_precisions",
    "coloured_noise",
    "convolution_model",
    "embed",
    "embedding_weights",
    "identification_system",
    "identify",
    "mass_spring_damper",
    "quadrotor_roll",
    "shift_operator",
    "simulate",
    "simulate_nonlinear",
    "smoothness_precision",
]
