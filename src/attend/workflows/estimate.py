"""`attend estimate` on a uniform, complete log: the model file's estimator run on it, its
result checked (finite estimates, every state and unknown input informed by the outputs)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from attend._validation import AttendInputError
from attend.io import Log, ModelFile
from attend.perception.file_estimators import file_estimator, file_nonlinear_order
from attend.perception.nonlinear.start_search import AmbiguousStartError

if TYPE_CHECKING:  # only named in annotations: each estimator is imported where the model file picks it
    from attend.perception.dem import DEMObserver
    from attend.perception.estimate import Estimate


def checked_sample_time(model: ModelFile, log: Log, minimum: int, why: str) -> float:
    """The log's sample time [s], after checking that the log has at least ``minimum`` samples
    (``why``: what needs them, named in the error) and that the model file's [model] dt, when
    given, is the log's (to 1e-4 relative). model: the parsed model file; log: the uniform log."""
    if len(log.time) < minimum:
        raise AttendInputError(f"{log.path}: expected at least {minimum} samples ({why}), got {len(log.time)}")
    dt = log.dt
    if model.dt is not None and abs(model.dt - dt) > 1e-4 * dt:
        raise AttendInputError(
            f"{model.path}: [model] dt = {model.dt} s but the log {log.path} is sampled every {dt:.6g} s"
        )
    return dt


def _observer_of(model: ModelFile, dt: float, outputs=None, signals=None) -> DEMObserver:
    try:  # the log lets the Kalman smoother choose the unknown inputs' prior width when the file gives none
        return file_estimator(model, dt, outputs, signals)
    except AttendInputError as error:  # in the file's words: P_v is the [[inputs]] prior_precision
        message = str(error).replace("input_prior_precision", "[[inputs]] prior_precision")
        raise AttendInputError(message if message.startswith(str(model.path)) else
                               f"{model.path}: [observer] {message}") from None


def located(error: Exception, model: ModelFile, log: Log) -> str:
    """An estimator's error message prefixed with the model file (and naming the log) unless it names a file."""
    text = str(error)
    if text.startswith((str(model.path), str(log.path))):
        return text
    return f"{model.path}: [observer] {text} (on the log {log.path})"


def estimate_from_files(model: ModelFile, log: Log) -> tuple[DEMObserver, Estimate]:
    """Run the model file's observer on the log (checks columns, finiteness and sample time)."""
    outputs = log.matrix(model.output_columns)
    signals = np.zeros((len(log.time), model.system.n_inputs))
    for j, spec in enumerate(model.inputs):
        if spec.known:
            signals[:, j] = log.matrix([spec.column])[:, 0] - spec.operating_point
        else:
            signals[:, j] = spec.prior_mean
    if model.nonlinear and model.method == "dem":
        checked_sample_time(model, log, 2, "nonlinear DEM")  # the order "auto" needs the log's dt
        window = max(file_nonlinear_order(model, log.dt), model.input_order) + 1
        dt = checked_sample_time(model, log, max(2, window), f"the embedding window of order {window - 1}")
    elif model.nonlinear:
        dt = checked_sample_time(model, log, 2, "the unscented Kalman smoother")
    elif model.method == "dem":
        order = model.learning_order  # "auto" picks p <= 6
        window = max(order, model.input_order) + 1
        dt = checked_sample_time(model, log, max(2, window), f"the embedding window of order {window - 1}")
    else:
        dt = checked_sample_time(model, log, 2, "the Kalman smoother")
    observer = _observer_of(model, dt, outputs, signals)
    with np.errstate(over="ignore", invalid="ignore"):
        if model.nonlinear:
            try:
                estimate = observer.estimate(outputs, signals)
            except AmbiguousStartError as error:  # names the setting that decides: [observer] initial_state
                raise AttendInputError(f"{model.path}: [observer] {error}") from None
            except AttendInputError as error:
                text = str(error)
                if model.python_path and text.startswith(model.python_path):
                    raise  # the user's f or g failed: the message names the file and the function
                raise AttendInputError(f"{model.path}: [observer] method {model.method!r}: {text}") from None
        else:
            try:
                estimate = observer.estimate(outputs, signals)
            except AttendInputError as error:  # a failure of the recursion itself names the files
                raise AttendInputError(located(error, model, log)) from None
    for name, values in (("states", estimate.states), ("inputs", estimate.inputs)):
        if not np.all(np.isfinite(values)):
            raise AttendInputError(
                f"{model.path}: [observer] the estimated {name} are not finite on the log {log.path}: the "
                "observer is numerically unstable for these settings; expected smaller precisions, "
                "lower embedding orders or a kernel_width of a few sample times"
            )
    names = list(model.system.state_names) + list(model.system.input_names)
    undefined = ~np.all(np.isfinite(np.hstack([estimate.state_std, estimate.input_std])), axis=0)
    if undefined.any():
        hidden = ", ".join(name for name, bad in zip(names, undefined) if bad)
        remedy = ("check the precisions and that g depends on them" if model.nonlinear else
                  "or give [observer] initial_state and initial_state_std with method = \"kalman\" (their "
                  "estimate is then the prior's)")
        raise AttendInputError(
            f"{model.path}: [observer] {hidden}: not informed by the outputs under these settings (no finite "
            f"standard deviation); add outputs that see them, {remedy}"
        )
    return observer, estimate
