"""One result type for every estimator: :class:`Estimate`.

Every estimator's ``.estimate(outputs, inputs=None, ...)`` returns an :class:`Estimate`:
:class:`attend.perception.kalman.KalmanEstimator` ("kalman smoother"),
:class:`attend.perception.dem.DEMObserver` ("dem"), :class:`attend.perception.nonlinear.NonlinearDEM`
("nonlinear dem"), :class:`attend.perception.nonlinear_smoothers.UnscentedSmoother` and
``ExtendedSmoother`` ("unscented kalman smoother", "extended kalman smoother"; "... filter" with
smooth=False), :class:`attend.perception.nonlinear_smoothers.ParticleSmoother` ("particle
smoother") and :class:`attend.perception.file_estimators.NonlinearFileEstimator` (its method's).
Code written for one estimator reads the others' results: time, states, inputs, state_std,
input_std, method.

What only one estimator computes stays in ``details``, that estimator's own result:
:class:`attend.perception.kalman.StateEstimate` (Kalman smoother and filter),
:class:`attend.perception.dem.DEMEstimate` (linear and nonlinear DEM: the generalised states
``generalized``), :class:`attend.perception.references.KalmanEstimate` (extended and unscented
smoothers: ``state_covariance``, ``log_likelihood``),
:class:`attend.perception.nonlinear_smoothers.ParticleEstimate` (``effective_sample_size``) and
:class:`attend.perception.references.ExactPosterior` (``covariance``, ``causal_states``, ...).
Those extra fields are read on the Estimate itself too (``estimate.generalized`` is
``estimate.details.generalized``): :meth:`Estimate.__getattr__` falls back to ``details`` for a
name the Estimate does not have. They are read-only there: ``_replace`` takes the Estimate's own
fields; replace an extra on ``details`` (``estimate.details._replace(...)``).

The arrays of an Estimate are those of ``details``, not copies: the numbers are the estimator's.
Functions (not estimators) keep their own result types (:func:`attend.perception.references.kalman_filter`,
:func:`attend.perception.references.exact_posterior`, ``unscented_kalman``, ...); :func:`as_estimate`
(or ``result.as_estimate()``) turns any of them into an Estimate the same way.

:func:`take_noise` is the estimators' side of ``noise=``: it writes an
:class:`attend.models.NoiseModel` into an estimator's separate precision and width fields before
they are checked, so both forms give the same numbers.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError
from attend.models.noise_model import resolve_noise

__all__ = ["Estimate", "as_estimate", "take_noise"]

#: method names of the result types that do not carry one (the type's name -> the method).
METHODS = {
    "DEMEstimate": "dem",
    "KalmanEstimate": "kalman-type smoother (extended or unscented)",
    "ParticleEstimate": "particle smoother",
    "ExactPosterior": "exact posterior",
}


class Estimate(NamedTuple):
    """The estimates of any estimator, in one type (every estimator's ``.estimate()`` returns one).

    time (N,) [s]: the samples' times; states (N, n): the state estimates (posterior means, or the
    DEM observer's); inputs (N, r): the inputs, the measured ones where they were given and the
    estimates of the unknown ones; state_std (N, n): the states' standard deviations; input_std
    (N, r): the inputs' standard deviations, 0 for measured inputs; method: which estimator
    produced them (e.g. "kalman smoother", "dem", "particle smoother"); details: the estimator's
    own result (a StateEstimate, DEMEstimate, KalmanEstimate, ParticleEstimate or ExactPosterior),
    with what only that estimator gives (generalised states, covariances, log-likelihood,
    effective sample size). The arrays are those of ``details``, not copies.

    A name the Estimate does not have is looked up on ``details`` (read-only; see
    :meth:`__getattr__`): ``estimate.generalized``, ``estimate.log_likelihood``,
    ``estimate.effective_sample_size`` where the estimator gives them.
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray
    method: str
    details: object

    def __getattr__(self, name: str):
        """The field ``name`` of ``details`` (the estimator's own result), for the fields only it
        has (e.g. ``generalized`` of a DEMEstimate, ``log_likelihood`` of a KalmanEstimate); an
        AttributeError naming the Estimate and its details' type when neither has it. Called only
        for names the Estimate itself does not have; private and special names are not looked up."""
        if name.startswith("_"):
            raise AttributeError(name)
        details = tuple.__getitem__(self, 6)  # the field, without a new attribute lookup
        try:
            return getattr(details, name)
        except AttributeError:
            raise AttributeError(f"{name!r}: neither an Estimate field nor one of its details "
                                 f"({type(details).__name__})") from None


def as_estimate(result, method: str | None = None) -> Estimate:
    """``result``, the result of any attend estimator or estimation function (or an Estimate,
    returned as it is), as an :class:`Estimate`: its time, states, inputs, state_std and
    input_std (the same arrays), ``details`` the result itself. The estimators' ``.estimate()``
    return what this gives for their own results.

    method: the estimator's name for ``Estimate.method``; default the result's own ``method`` field
    where it has one (StateEstimate), else the name of its type's estimator (METHODS).
    """
    if isinstance(result, Estimate):
        return result if method is None else result._replace(method=method)
    try:
        time, states, inputs = result.time, result.states, result.inputs
        state_std, input_std = result.state_std, result.input_std
    except AttributeError:
        raise AttendInputError(f"result: expected an estimator's result (time, states, inputs, state_std, input_std), "
                               f"got {type(result).__name__}") from None
    if method is None:
        method = getattr(result, "method", None) or METHODS.get(type(result).__name__, type(result).__name__)
    return Estimate(time, states, inputs, state_std, input_std, str(method), result)


#: the separate noise keywords of the estimators' constructors that ``noise=`` stands for.
NOISE_FIELDS = ("sensor_precision", "process_precision", "kernel_width", "process_kernel_width", "sensor_kernel_width")


def take_noise(estimator, noise, who: str, required: tuple = ("sensor_precision", "process_precision")) -> None:
    """Write ``noise`` (an :class:`attend.models.NoiseModel` given as ``noise=``, or None) into the
    separate fields of ``estimator`` (a frozen dataclass with the fields NOISE_FIELDS it has), as a
    caller would have written them (:meth:`attend.models.NoiseModel.precision_keywords`), before the
    estimator checks them: the same numbers follow as from the separate keywords. An
    AttendInputError when it comes with any of those fields, or when there is no noise model and a
    field of ``required`` is missing. who: the estimator's name, for the messages."""
    names = [name for name in NOISE_FIELDS if hasattr(estimator, name)]
    model = resolve_noise(noise, {name: getattr(estimator, name) for name in names}, who)
    if model is None:
        for name in required:
            if getattr(estimator, name) is None:
                raise AttendInputError(f"{name}: required (or noise=NoiseModel(...) for all the noise settings)")
        return
    for name, value in model.precision_keywords().items():
        if name in names:
            object.__setattr__(estimator, name, value)
