"""`attend identify` on a linear model file: attend's learning (D, E and M steps) run on the log
with the file's [learning] settings, and the check that the learned model is usable. The learned
model file is written by :func:`attend.io.write_learned_model`."""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.io import Log, ModelFile
from attend.workflows.estimate import checked_sample_time, estimate_from_files


def identify_from_files(model: ModelFile, log: Log, *, progress: bool = False):
    """Run attend's learning (D, E, M steps) on the log with the model file's [learning] settings.

    The model's A, B, C are the prior means; every input must be measured (a column). An
    [observer] embedding_order of "auto" means :func:`auto_identification_order` here. model: the
    parsed model file; log: the CSV log; progress: show a progress bar over the iterations.
    """
    from attend.perception.learning import LearningSettings, identify

    if model.nonlinear:
        raise AttendInputError(f"{model.path}: this is a nonlinear model ([model] python): use "
                               "attend.workflows.identify_nonlinear (what `attend identify` runs for it)")
    unknown = [spec.name for spec in model.inputs if not spec.known]
    if unknown:
        raise AttendInputError(
            f"{model.path}: identify needs measured inputs; input(s) {', '.join(map(repr, unknown))} have no column"
        )
    if model.system.n_inputs == 0:
        raise AttendInputError(
            f"{model.path}: identify needs at least one measured input (an [[inputs]] table with a column "
            "and a column of B); models without inputs cannot be identified yet"
        )
    outputs = log.matrix(model.output_columns)
    inputs = np.zeros((len(log.time), model.system.n_inputs))
    for j, spec in enumerate(model.inputs):
        inputs[:, j] = log.matrix([spec.column])[:, 0] - spec.operating_point
    if not model.learning:
        raise AttendInputError(
            f"{model.path}: identify needs a [learning] section saying which entries to learn, e.g.\n"
            + LEARNING_EXAMPLE + "(see README.md, 'Identify your model')"
        )
    window = max(model.learning_order, model.input_order) + 1
    dt = checked_sample_time(model, log, 3 * window, f"3 embedding windows of order {window - 1}")
    learning = dict(model.learning or {})
    problem = {key: learning[key] for key in ("free", "free_prior_precision", "known_prior_precision")
               if key in learning}
    options = {key: learning[key] for key in ("noise_prior_mean", "noise_prior_precision", "max_iterations",
                                              "tolerance", "states", "top_order") if key in learning}
    if model.kernel_width is None or model.kernel_width == 0:
        raise AttendInputError(f"{model.path}: [observer] kernel_width: identify needs one kernel width > 0 [s] for "
                               "both noises (separate or white widths are for attend estimate only)")
    try:
        order = (auto_identification_order(model.kernel_width, dt) if model.embedding_order == "auto"
                 else model.learning_order)
        settings = LearningSettings(embedding_order=order, input_order=model.input_order,
                                    precision_convention=model.precision_convention, **options)
        return identify(model.system, outputs, inputs, dt, kernel_width=model.kernel_width, settings=settings,
                        progress=progress, **problem)
    except AttendInputError as error:
        raise AttendInputError(_in_file_terms(str(error), model, log)) from None


#: Kernel width in samples (s / dt) from which identify's "auto" embedding order is 2, not 6.
SMOOTH_KERNEL_SAMPLES = 2.0


def auto_identification_order(kernel_width: float, dt: float) -> int:
    """The embedding order p of identify under "auto": 6, or 2 when the noise kernel spans
    s / dt >= ``SMOOTH_KERNEL_SAMPLES`` samples. There the smoothness precision weighs the p-th
    derivative of the prediction errors by about (s / dt)^(2 p): a few samples rougher than the
    noise model (rounding, white sensor noise, an interpolated gap) dominate, the M-step reads them
    as noise and the parameters drift (docs/command-line.md, "Where it is fragile"); order 2 learns
    as accurately on clean logs and is not moved by them. kernel_width: s [s]; dt: sample time [s]."""
    return 2 if kernel_width / dt >= SMOOTH_KERNEL_SAMPLES else 6


_LEARNING_FIELDS = ("free", "prior_precision", "initial", "noise_prior_mean", "noise_prior_precision",
                    "max_iterations", "tolerance", "states", "top_order")


def _in_file_terms(message: str, model: ModelFile, log: Log) -> str:
    """A learning error in the words of the files: which file, which section or key."""
    field = message.split(":", 1)[0]
    if field in ("outputs", "inputs"):
        return f"{log.path}: {field} columns: {message.split(':', 1)[1].strip()}"
    if field in ("embedding_order", "input_order", "kernel_width", "precision_convention"):
        return f"{model.path}: [observer] {message}"
    if field in ("system_prior", "A", "B", "C"):
        return f"{model.path}: [model] {message}"
    if field in _LEARNING_FIELDS:
        return f"{model.path}: [learning] {message}"
    return f"{model.path}: {message}"


LEARNING_EXAMPLE = """\
    [learning]
    free = ["A[2,1]", "A[2,2]", "B[2,1]", "B[2,2]", "B[2,3]", "B[2,4]"]   # entries to learn (1-based)
    free_prior_precision = 1.0
    known_prior_precision = inf             # hold the other entries fixed
    noise_prior_mean = [0.0, 0.0]
    noise_prior_precision = 1.0
    max_iterations = 50
    tolerance = 1e-3
"""


def check_learned_model(model: ModelFile, log: Log, result) -> list[str]:
    """Problems that make a learned model unusable by `attend estimate` (empty list: usable).

    Checks finite matrices, finite positive noise precisions, and runs the model file's observer with
    the learned A, B, C and precisions on the log: every estimate must be finite. model: the
    model file learned from; log: the log to test on; result: the identification result of
    :func:`identify_from_files` (learned system and noise precisions exp(lambda)).
    """
    from dataclasses import replace

    problems = []
    system = result.system()
    if not all(np.all(np.isfinite(M)) for M in (system.A, system.B, system.C)):
        problems.append("the learned A, B or C has non-finite entries")
    precisions = np.array([result.sensor_precision, result.process_precision])
    if not np.all(np.isfinite(precisions)) or np.any(precisions <= 0):
        problems.append(f"the learned noise precisions exp(lambda) = {precisions.tolist()} are not finite and positive")
    if problems:
        return problems
    learned = replace(model, system=system, sensor_precision=float(result.sensor_precision),
                      process_precision=float(result.process_precision))
    try:
        with np.errstate(all="ignore"):
            _, estimate = estimate_from_files(learned, log)
    except (np.linalg.LinAlgError, AttendInputError, ValueError) as error:
        return [f"the observer of the learned model fails on this log ({error})"]
    bad = ~np.all(np.isfinite(estimate.states), axis=1) | ~np.all(np.isfinite(estimate.state_std), axis=1)
    if bad.any():
        problems.append(f"the learned model gives non-finite state estimates on {int(bad.sum())} of {len(bad)} "
                        "samples of this log")
    return problems

