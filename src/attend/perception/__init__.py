"""Perception: estimating states and inputs (DEM, coloured-noise Kalman), learning parameters and
noise precisions, and the baselines they are compared with.

Entry points (re-exported here and from :mod:`attend`):

- :class:`DEMObserver` (batch) and :class:`OnlineDEM` (sample by sample), results
  :class:`DEMEstimate` (:mod:`attend.perception.dem`);
- :class:`KalmanEstimator` and :class:`OnlineKalman`, results :class:`StateEstimate`
  (:mod:`attend.perception.kalman`);
- :func:`identify` and :func:`learn_batch`, results :class:`IdentificationResult`
  (:mod:`attend.perception.learning`);
- :class:`NonlinearDEM` for a :class:`NonlinearSystem` (:mod:`attend.perception.nonlinear`).

Baselines: :mod:`attend.perception.baselines` (Kalman filters and smoothers, the exact posterior,
N4SID and EM identification) and :mod:`attend.perception.nonlinear_baselines`.
"""

from attend.perception.dem import DEMEstimate, DEMObserver, OnlineDEM
from attend.perception.kalman import KalmanEstimator, OnlineKalman, StateEstimate
from attend.perception.learning import IdentificationResult, identify, learn_batch
from attend.perception.nonlinear import NonlinearDEM, NonlinearSystem

__all__ = [
    "DEMEstimate",
    "DEMObserver",
    "IdentificationResult",
    "KalmanEstimator",
    "NonlinearDEM",
    "NonlinearSystem",
    "OnlineDEM",
    "OnlineKalman",
    "StateEstimate",
    "identify",
    "learn_batch",
]
