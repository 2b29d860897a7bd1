"""One result type for every estimator (:class:`Estimate`), and the conversion to it.

Each estimator keeps the result it has always returned, with what only it computes:
:class:`attend.perception.kalman.StateEstimate` (Kalman smoother and filter),
:class:`attend.perception.dem.DEMEstimate` (linear and nonlinear DEM: the generalised states),
:class:`attend.perception.references.KalmanEstimate` (extended and unscented smoothers: the
state covariances and the log-likelihood), :class:`attend.perception.nonlinear_smoothers.ParticleEstimate`
(the effective sample size) and :class:`attend.perception.references.ExactPosterior` (the joint
covariance, the causal means). Their first five fields are the same (time, states, inputs,
state_std, input_std), so code written for one reads the others; :class:`Estimate` is that common
part as one type, with the method's name and the estimator's own result (``details``) beside it.

Why a conversion rather than a new return type: ``estimate()`` results are used as tuples (unpacked,
``_replace``-d, indexed by position) in the command line, the experiments and the tests, and their
extra fields differ; turning them into one type would break those uses or lose the extras. So
every result converts: ``result.as_estimate()`` on the result types of attend.perception's
estimators, or :func:`as_estimate` on any of them (the extended and unscented smoothers' results
included), and the Estimate keeps the original in ``details``: nothing is lost, no number changes.

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
    """The estimates of any estimator, in one type.

    The fields come in the order of every estimator's own result (time, states, inputs,
    state_std, input_std first), then the method and the result itself.

    time (N,) [s]: the samples' times; states (N, n): the state estimates (posterior means, or the
    DEM observer's); inputs (N, r): the inputs, the measured ones where they were given and the
    estimates of the unknown ones; state_std (N, n): the states' standard deviations; input_std (N, r):
    the unknown inputs' standard deviations (0 for measured ones), None when no input was estimated
    (all inputs measured, or none at all); method: which estimator produced them (e.g. "kalman
    smoother", "dem", "particle smoother"); details: the estimator's own result (a StateEstimate,
    DEMEstimate, KalmanEstimate, ParticleEstimate or ExactPosterior), with what only that estimator
    gives (generalised states, covariances, log-likelihood, effective sample size). The arrays are
    those of ``details``, not copies.
    """

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    state_std: np.ndarray
    input_std: np.ndarray | None
    method: str
    details: object


def as_estimate(result, method: str | None = None) -> Estimate:
    """``result``, the result of any attend estimator (or an Estimate, returned as it is), as an
    :class:`Estimate`: its time, states, state_std, inputs and input_std (None when every input's
    std is exactly 0: all measured, or no inputs), ``details`` the result itself.

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
    input_std = None if input_std is None or not np.any(input_std) else input_std
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
