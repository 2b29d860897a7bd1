"""`attend identify` for nonlinear model files: named entries of the model's ``parameters`` learned
with the trajectory by path mode (:func:`attend.perception.nonlinear.learn_path`).

The model file's [learning] ``free`` names scalar entries of the parameters dict that f and g
receive (from the Python file, or [model] parameters); their current values are the prior means,
``free_prior_precision`` their prior precision (default 0: flat). The noise precisions are the
[observer]'s (known, not learned); unknown inputs ([[inputs]] without a column) are estimated
under their priors while learning. The learned model file (:func:`attend.io.write_learned_nonlinear`)
holds the new values in [model] parameters, so `attend estimate` uses them, and their error bars
in [learned].
"""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.io import Log
from attend.workflows.estimate import checked_sample_time

#: [learning] keys that nonlinear identification reads (the others are the linear learner's)
NONLINEAR_LEARNING_KEYS = ("free", "free_prior_precision", "max_iterations", "tolerance")


class _WithFree:
    """The user's f or g with the free entries of its parameters replaced by theta (names: the
    free entries, in theta's order; user: the file's checked f or g, as :mod:`attend.io.python_model`
    reads it)."""

    def __init__(self, user, names: tuple[str, ...]):
        self.user, self.names = user, names

    def __call__(self, x, v, theta):
        if self.user.parameters is None:  # this function takes no parameters
            return self.user(x, v)
        free = {name: float(value) for name, value in zip(self.names, theta)}
        return self.user.with_parameters({**self.user.parameters, **free})(x, v)


def _free_names(model, learning: dict) -> tuple[tuple[str, ...], np.ndarray]:
    """([learning] free, their current values) after checking each names a scalar parameter."""
    where = f"{model.path}: [learning]"
    unknown = sorted(set(learning) - set(NONLINEAR_LEARNING_KEYS))
    if unknown:
        raise AttendInputError(f"{where} {unknown[0]}: not used for nonlinear models (expected only "
                               f"{', '.join(NONLINEAR_LEARNING_KEYS)}; the noise precisions are [observer]'s)")
    parameters = model.system.f.parameters or model.system.g.parameters
    if not parameters:
        raise AttendInputError(f"{model.path}: identify needs f(x, v, parameters) and a parameters dict (in the "
                               "Python file or [model] parameters) whose entries [learning] free names")
    free = learning.get("free")
    if not isinstance(free, list) or not free or not all(isinstance(name, str) for name in free):
        raise AttendInputError(f"{where} free: expected a list of parameter names, e.g. free = [\"damping\"] "
                               f"(the model's parameters: {', '.join(sorted(parameters))})")
    values = []
    for name in free:
        value = parameters.get(name)
        if name not in parameters:
            raise AttendInputError(f"{where} free: {name!r} is not a parameter of the model (its parameters: "
                                   f"{', '.join(sorted(parameters))})")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise AttendInputError(f"{where} free: {name!r} is {value!r}; only scalar numeric parameters can be learned")
        values.append(float(value))
    if len(set(free)) != len(free):
        raise AttendInputError(f"{where} free: names repeated in {free}")
    return tuple(free), np.array(values)


def identify_nonlinear(model, log: Log):
    """Learn the [learning] free parameters of a nonlinear model file on ``log`` (module docstring).

    model: the parsed :class:`attend.io.ModelFile` ([model] python); log: the CSV log. Returns
    (names, :class:`attend.perception.nonlinear.PathLearningResult`)."""
    from attend.perception.file_estimators import file_nonlinear_order
    from attend.perception.nonlinear import ParametrisedSystem, learn_path

    learning = dict(model.learning or {})
    names, values = _free_names(model, learning)
    system = model.system
    parametrised = ParametrisedSystem(_WithFree(system.f, names), _WithFree(system.g, names), system.n_states,
                                      system.n_inputs, system.n_outputs, parameter_names=names)
    order = 6 if model.embedding_order == "auto" else int(model.embedding_order)
    window = max(order, model.input_order) + 1
    dt = checked_sample_time(model, log, 3 * window, f"3 embedding windows of order {window - 1}")
    p = file_nonlinear_order(model, dt)
    outputs = log.matrix(model.output_columns)
    signals = np.zeros((len(log.time), system.n_inputs))
    known = np.array([spec.known for spec in model.inputs], dtype=bool)
    for j, spec in enumerate(model.inputs):
        signals[:, j] = log.matrix([spec.column])[:, 0] - spec.operating_point if spec.known else spec.prior_mean
    prior = None
    if system.n_inputs and not known.all():
        prior = np.array([model.known_input_precision if spec.known else spec.prior_precision for spec in model.inputs])
    precision = learning.get("free_prior_precision", 0.0)
    try:
        result = learn_path(parametrised, outputs, signals if system.n_inputs else None, dt,
                            kernel_width=model.kernel_width, sensor_precision=model.sensor_precision,
                            process_precision=model.process_precision, prior_mean=values,
                            prior_precision=np.broadcast_to(np.asarray(precision, dtype=float), values.shape),
                            input_prior_precision=prior, embedding_order=p, input_order=model.input_order,
                            input_kernel_width=model.input_kernel_width,
                            max_iterations=int(learning.get("max_iterations", 50)),
                            tolerance=float(learning.get("tolerance", 1e-10)), motion=model.dem_motion or "path")
    except AttendInputError as error:
        raise AttendInputError(f"{model.path}: identify: {error}") from None
    return names, result


def table(names, result) -> str:
    """The learned parameters with their error bars, one line each. names, result: of
    :func:`identify_nonlinear`."""
    rows = [f"{'parameter':>20s} {'learned':>14s} {'std':>12s}"]
    rows += [f"{name:>20s} {value:14.6g} {std:12.4g}" for name, value, std in
             zip(names, result.parameters, result.parameter_std)]
    return "\n".join(rows)

