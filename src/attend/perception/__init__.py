"""Perception: estimating states and inputs (DEM, coloured-noise Kalman), learning parameters and
noise precisions, and the baselines they are compared with.

Entry points (re-exported here and from :mod:`attend`):

- :class:`DEMObserver` (batch) and :class:`OnlineDEM` (sample by sample); the observer's own
  result :class:`DEMEstimate` (:mod:`attend.perception.dem`);
- :class:`KalmanEstimator` and :class:`OnlineKalman`; the smoother's own result
  :class:`StateEstimate` (:mod:`attend.perception.kalman`);
- :func:`identify` and :func:`learn_batch` with their settings :class:`LearningSettings`, results
  :class:`IdentificationResult` (:mod:`attend.perception.learning`);
- :class:`NonlinearDEM` for a :class:`attend.models.NonlinearSystem` (:mod:`attend.perception.nonlinear`);
- :class:`Estimate`, the one result type every estimator's ``.estimate()`` returns, the
  estimator's own result in ``details`` (:mod:`attend.perception.estimate`); :func:`as_estimate`
  turns the results of the estimation functions into one.

Every estimator takes its noise as ``noise=``:class:`attend.models.NoiseModel` (or the separate
precision and kernel-width keywords), the system and dt first and the rest by keyword.

Smoothers for nonlinear models besides DEM (the unscented Kalman smoother, the default of a
nonlinear model file, and the particle smoother, the nonlinear reference):
:mod:`attend.perception.nonlinear_smoothers`. References the estimators are compared with on
linear models: :mod:`attend.perception.references` (Kalman filters and smoothers, the exact
posterior, N4SID and EM identification). A model file's estimator:
:mod:`attend.perception.file_estimators`. python-control export of the DEM observer:
:mod:`attend.perception.interop`.
"""

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562):
#: `attend estimate` loads the estimator it runs, not the others nor the learners.
_EXPORTS = {
    "DEMEstimate": "attend.perception.dem",
    "DEMObserver": "attend.perception.dem",
    "OnlineDEM": "attend.perception.dem",
    "IdentificationResult": "attend.perception.learning",
    "identify": "attend.perception.learning",
    "learn_batch": "attend.perception.learning",
    "LearningSettings": "attend.perception.learning",
    "KalmanEstimator": "attend.perception.kalman",
    "OnlineKalman": "attend.perception.kalman",
    "StateEstimate": "attend.perception.kalman",
    "NonlinearDEM": "attend.perception.nonlinear",
    "Estimate": "attend.perception.estimate",
    "as_estimate": "attend.perception.estimate",
}

__all__ = [
    "DEMEstimate",
    "DEMObserver",
    "Estimate",
    "IdentificationResult",
    "KalmanEstimator",
    "LearningSettings",
    "NonlinearDEM",
    "OnlineDEM",
    "OnlineKalman",
    "StateEstimate",
    "as_estimate",
    "identify",
    "learn_batch",
]

__getattr__, __dir__ = lazy_exports("attend.perception", _EXPORTS, globals())
