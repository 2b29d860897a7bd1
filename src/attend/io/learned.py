"""Learning from files (`attend identify`): the run, its check and the learned model file."""

from __future__ import annotations

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError
from attend.io.estimates import _check_samples, estimate_from_files
from attend.io.logs import Log
from attend.io.model import ModelFile


def identify_from_files(model: ModelFile, log: Log, *, progress: bool = False):
    """Run attend's learning (D, E, M steps) on the log with the model file's [learning] settings.

    The model's A, B, C are the prior means; every input must be measured (a column). An
    [observer] embedding_order of "auto" means :func:`auto_identification_order` here. model: the
    parsed model file; log: the CSV log; progress: show a progress bar over the iterations.
    """
    from attend.perception.learning import LearningSettings, identify

    if model.nonlinear:
        raise AttendInputError(f"{model.path}: this is a nonlinear model ([model] python): use "
                               "attend.io.learned_nonlinear.identify_nonlinear (what `attend identify` runs for it)")
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
    dt = _check_samples(model, log, 3 * window, f"3 embedding windows of order {window - 1}")
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


def write_learned_model(path: str | Path, model: ModelFile, result) -> Path:
    """A model file with the learned A, B, C and noise precisions, their posterior precisions in
    [learned], ready for `attend estimate`. path: the TOML file to write (parent folders created);
    model: the model file learned from (its other sections are kept); result: the identification
    result of :func:`identify_from_files`. Returns the path."""
    import tomli_w

    system = result.system()
    data = tomllib.loads(Path(model.path).read_text(encoding="utf-8-sig")) if model.path else {}
    data.setdefault("model", {})
    data["model"]["A"] = system.A.tolist()
    data["model"]["B"] = system.B.tolist()
    data["model"]["C"] = system.C.tolist()
    observer = data.setdefault("observer", {})
    observer["sensor_precision"] = float(result.sensor_precision)
    observer["process_precision"] = float(result.process_precision)
    learned = {
        "parameter_names": list(result.parameter_names),
        "parameters": [float(v) for v in result.parameters],
        "parameter_precision": [float(v) for v in np.diag(np.atleast_2d(result.parameter_precision))]
        if np.ndim(result.parameter_precision) == 2 else [float(v) for v in result.parameter_precision],
        "log_precision": [float(v) for v in result.log_precision],
        "free_energy": [float(v) for v in result.free_energy],
        "converged": bool(result.converged),
        "iterations": int(result.iterations),
        "message": str(result.message),
    }
    learned_section = {"learned": learned}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = "# Learned by `attend identify`: [model] holds the posterior means; [learned] the details.\n"
    data.pop("learned", None)
    body = tomli_w.dumps(data) + "\n# posterior parameter precisions (Pi_theta diagonal), noise log-precisions\n"
    body += "# [lambda_z, lambda_w], free energy per iteration\n" + tomli_w.dumps(learned_section)
    path.write_text(header + body)
    return path
