"""Reading and validating a model file (TOML): one reader per section."""

from __future__ import annotations

import math
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from pathlib import Path

import numpy as np

from attend._validation import (
    AttendInputError,
    as_matrix,
    numeric_array,
    order,
    positive_scalar,
    precision_matrix,
    require_moderate,
    unique_names,
)
from attend.constants import KNOWN_INPUT_PRECISION
from attend.io.bags import bag_layout
from attend.io.fields import _check_keys, _file_number, _matrix, _read_text, _text, _text_list
from attend.io.model import InputSpec, ModelFile
from attend.io.python_model import _model_size, _probe, _python_model
from attend.models.linear import LinearSystem

#: Nonlinear DEM's default prior precision of measured inputs beside unknown ones (exp(32) overflows
#: the linear algebra of its flow; 1e8 pins them to the measurement to ~1e-8 on the pendulum).
NONLINEAR_KNOWN_INPUT_PRECISION = 1e8
#: The estimator of nonlinear models when [observer] method is not given (see NONLINEAR_METHODS).
NONLINEAR_METHOD = "ukf"

_LINEAR_KEYS = {"A", "B", "C"}
_NONLINEAR_KEYS = {"python", "n_states", "n_inputs", "n_outputs", "parameters", "vectorized"}
_SECTIONS = {
    "model": _LINEAR_KEYS | _NONLINEAR_KEYS | {"states", "dt"},
    "outputs": {"columns"},
    "inputs": None,  # array of tables, checked separately
    "observer": {
        "method", "kernel_width", "process_kernel_width", "sensor_kernel_width", "input_kernel_width",
        "embedding_order", "input_order", "sensor_precision", "process_precision", "precision_convention",
        "known_input_precision", "initial_state", "initial_state_std", "integration", "edges", "states",
        "backend", "motion",
    },
    "log": {"time_column", "rate_hz", "dt", "grid_topic", "resample", "stamps", "max_gap", "columns"},  # io.bags
    "learning": {
        "free", "free_prior_precision", "known_prior_precision", "noise_prior_mean",
        "noise_prior_precision", "max_iterations", "tolerance", "states", "top_order",
    },
    # written by `attend identify`; informative, not used by the observer
    "learned": {
        "parameter_names", "parameters", "parameter_precision", "parameter_std", "log_precision", "free_energy",
        "converged", "iterations", "message",
    },
}
_INPUT_KEYS = {"name", "column", "operating_point", "prior_mean", "prior_precision"}



def read_model(path: str | Path) -> ModelFile:
    """Parse and validate the model TOML file at ``path`` (format in the docstring of attend.io)."""
    path = Path(path)
    data = _read_sections(path)
    model = data.get("model", {})
    nonlinear = "python" in model
    raw_inputs = _raw_inputs(data, nonlinear, path)
    matrices = None if nonlinear else _linear_matrices(model, path)
    if nonlinear:
        n_states, n_inputs, n_outputs = _nonlinear_sizes(model, path)
    else:
        A, B, C = matrices
        n_states, n_inputs, n_outputs = A.shape[0], B.shape[1] if B.ndim == 2 else 1, C.shape[0] if C.ndim == 2 else 1
    _check_input_count(raw_inputs, n_inputs, nonlinear, path)
    state_names, input_names = _names(model, raw_inputs, n_states, path)
    if nonlinear:
        system = _python_model(path, model, n_states, n_inputs, n_outputs, state_names, input_names)
    else:
        try:
            system = LinearSystem(*matrices, state_names=state_names, input_names=input_names)
        except AttendInputError as error:
            raise AttendInputError(f"{path}: [model] {error}") from None
    inputs = _input_specs(raw_inputs, input_names, path)
    outputs = _output_columns(data, system.n_outputs, nonlinear, path)
    observer = data.get("observer", {})
    method = _observer_method(observer, nonlinear, path)
    _check_dem_conventions(observer, method, nonlinear, f"{path}: [observer]")
    widths = _kernel_widths(observer, method, nonlinear, path)
    initial_state, initial_std = _initial_state(observer, system.n_states, path)
    _check_observer(observer, system, f"{path}: [observer]")
    if nonlinear:
        _probe(system, initial_state, inputs)
    dt = model.get("dt")
    if dt is not None:
        dt = positive_scalar(dt, f"{path}: [model] dt", "seconds")
    time_column = _text(data.get("log", {}).get("time_column", "t"), f"{path}: [log] time_column")
    used = {name: "[outputs] columns" for name in outputs}
    used.update({spec.column: f"[[inputs]] {spec.name!r} column" for spec in inputs if spec.known})
    layout = bag_layout(data.get("log", {}), path, dt, used)  # None: no [log.columns] (CSV logs only)
    learning = dict(data.get("learning", {}))
    _check_learning(learning, f"{path}: [learning]", nonlinear)
    return ModelFile(
        system=system,
        dt=dt,
        output_columns=tuple(outputs),
        inputs=tuple(inputs),
        kernel_width=widths["kernel_width"],
        embedding_order=observer.get("embedding_order", "auto"),
        input_order=observer.get("input_order", 2),
        sensor_precision=observer["sensor_precision"],
        process_precision=observer["process_precision"],
        precision_convention=observer.get("precision_convention", "size"),
        known_input_precision=_file_number(observer, "known_input_precision", f"{path}: [observer] known_input_precision",
                                           NONLINEAR_KNOWN_INPUT_PRECISION if nonlinear else KNOWN_INPUT_PRECISION,
                                           positive=True),
        time_column=time_column,
        learning=learning,
        path=str(path),
        method=method,
        process_kernel_width=widths["process_kernel_width"],
        sensor_kernel_width=widths["sensor_kernel_width"],
        input_kernel_width=widths["input_kernel_width"],
        initial_state=initial_state,
        initial_state_std=initial_std,
        python_path=str(system.f.source) if nonlinear else "",
        integration=observer.get("integration", "attend"),
        edges=observer.get("edges", "order0"),
        dem_states=observer.get("states", "sample"),
        dem_backend=observer.get("backend", "numpy"),
        dem_motion=observer.get("motion"),
        bag_layout=layout,
    )


def _read_sections(path: Path) -> dict:
    """The file's TOML tables, after checking the section names and the keys of each section."""
    try:
        data = tomllib.loads(_read_text(path, "model file"))
    except tomllib.TOMLDecodeError as error:
        raise AttendInputError(f"{path}: not valid TOML ({error})") from None
    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise AttendInputError(
            f"{path}: unknown section or key {', '.join(map(repr, unknown))}; "
            f"expected the sections {', '.join('[' + s + ']' for s in _SECTIONS)}"
        )
    for section, allowed in _SECTIONS.items():
        if allowed is not None and not isinstance(data.get(section, {}), dict):
            raise AttendInputError(f"{path}: [{section}] must be a table")
        if allowed is not None:
            _check_keys(data.get(section, {}), allowed, section, str(path))
    if not data:
        raise AttendInputError(f"{path}: the model file is empty; expected [model], [outputs] and [observer] sections")
    return data


def _raw_inputs(data: dict, nonlinear: bool, path: Path) -> list:
    """The [[inputs]] tables as given (a list of tables)."""
    raw_inputs = data.get("inputs", [])
    if not isinstance(raw_inputs, list) or not all(isinstance(spec, dict) for spec in raw_inputs):
        per = "one per input of f and g" if nonlinear else "one per column of B"
        raise AttendInputError(f"{path}: expected [[inputs]] tables ({per}), got inputs = {raw_inputs!r}")
    return raw_inputs


def _nonlinear_sizes(model: dict, path: Path) -> tuple[int, int, int]:
    """[model] n_states, n_inputs, n_outputs of a nonlinear model (no A, B, C beside python)."""
    mixed = sorted(_LINEAR_KEYS & set(model))
    if mixed:
        raise AttendInputError(f"{path}: [model] has both python (a nonlinear model f, g) and {', '.join(mixed)} "
                               "(a linear model); give one of them")
    return tuple(_model_size(model, key, path) for key in ("n_states", "n_inputs", "n_outputs"))


def _linear_matrices(model: dict, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """[model] A (square), B and C of a linear model (no nonlinear keys beside them)."""
    extra = sorted((_NONLINEAR_KEYS - {"python"}) & set(model))
    if extra:
        raise AttendInputError(
            f"{path}: [model] {', '.join(extra)}: only for nonlinear models ([model] python = \"model.py\" "
            "with f and g); a linear model's sizes come from A, B and C"
        )
    for key in ("A", "B", "C"):
        if key not in model:
            raise AttendInputError(f"{path}: [model] needs {key} (a matrix as a list of rows), or python = "
                                   "\"model.py\" (a nonlinear model: f, g and n_states, n_inputs, n_outputs)")
    A = as_matrix(model["A"], f"{path}: [model] A")
    require_moderate(A, f"{path}: [model] A")
    if A.shape[0] != A.shape[1]:
        raise AttendInputError(f"{path}: [model] A: expected a square matrix, got shape {A.shape}")
    return A, _matrix(model["B"], f"{path}: [model] B"), _matrix(model["C"], f"{path}: [model] C")


def _check_input_count(raw_inputs: list, n_inputs: int, nonlinear: bool, path: Path) -> None:
    """One [[inputs]] table per input (column of B, or input of f and g), each with known keys only."""
    if len(raw_inputs) != n_inputs:
        if nonlinear:
            raise AttendInputError(
                f"{path}: [model] n_inputs = {n_inputs} but the file has {len(raw_inputs)} [[inputs]] "
                f"table{'s' if len(raw_inputs) != 1 else ''}; expected one table per input of f and g"
            )
        raise AttendInputError(
            f"{path}: [model] B has {n_inputs} column{'s' if n_inputs != 1 else ''} but the file has "
            f"{len(raw_inputs)} [[inputs]] table{'s' if len(raw_inputs) != 1 else ''}; expected one table per column of B"
        )
    for i, spec in enumerate(raw_inputs):
        _check_keys(spec, _INPUT_KEYS, f"inputs {i + 1}", str(path))


def _names(model: dict, raw_inputs: list, n_states: int, path: Path) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(state names, input names): [model] states (or none) and the [[inputs]] names, all distinct."""
    input_names = unique_names(
        [_text(spec.get("name", f"u{i + 1}"), f"{path}: [[inputs]] table {i + 1} name") for i, spec in enumerate(raw_inputs)],
        f"{path}: [[inputs]] name",
    )
    state_names = _text_list(model["states"], f"{path}: [model] states", n_states, "state names") if "states" in model else ()
    unique_names(state_names + input_names + ("t",), f"{path}: [model] states and [[inputs]] names (and 't', the time column of the estimates)")
    return state_names, input_names


def _input_specs(raw_inputs: list, input_names, path: Path) -> list[InputSpec]:
    """One InputSpec per [[inputs]] table: a column (measured) or a prior (estimated), not both."""
    inputs = []
    for i, spec in enumerate(raw_inputs):
        name = input_names[i]
        where = f"{path}: [[inputs]] {name!r}"
        if "column" in spec and ("prior_mean" in spec or "prior_precision" in spec):
            raise AttendInputError(
                f"{path}: input {name!r} has both a column (known input) and a prior (unknown input); give one"
            )
        if "operating_point" in spec and "column" not in spec:
            raise AttendInputError(f"{path}: input {name!r} has an operating_point but no column (only measured inputs have one)")
        column = _text(spec["column"], f"{where} column") if "column" in spec else None
        precision = _file_number(spec, "prior_precision", f"{where} prior_precision", 1.0, minimum=0.0)
        inputs.append(InputSpec(
            name, column, _file_number(spec, "prior_mean", f"{where} prior_mean", 0.0), precision,
            _file_number(spec, "operating_point", f"{where} operating_point", 0.0),
        ))
    return inputs


def _output_columns(data: dict, n_outputs: int, nonlinear: bool, path: Path) -> tuple[str, ...]:
    """[outputs] columns: one CSV column name per output."""
    per_output = "one per output of g: [model] n_outputs" if nonlinear else "one per row of C"
    outputs = data.get("outputs", {}).get("columns")
    if outputs is None:
        raise AttendInputError(f"{path}: [outputs] needs columns (the CSV columns of the {n_outputs} outputs, {per_output})")
    if not isinstance(outputs, list) or len(outputs) != n_outputs:
        raise AttendInputError(
            f"{path}: [outputs] columns: expected {n_outputs} column names ({per_output}), got {outputs!r}"
        )
    return _text_list(outputs, f"{path}: [outputs] columns", what="column names")


def _observer_method(observer: dict, nonlinear: bool, path: Path) -> str:
    """[observer] method ("kalman" or "dem"; "ukf" or "dem" for nonlinear models), after checking the
    precisions are given (and, for nonlinear models, one kernel_width)."""
    for key in ("sensor_precision", "process_precision"):
        if key not in observer:
            raise AttendInputError(f"{path}: [observer] needs {key}")
    if nonlinear:
        method = observer.get("method", NONLINEAR_METHOD)
        if method not in ("ukf", "dem"):
            raise AttendInputError(f"{path}: [observer] method: expected \"ukf\" or \"dem\" for a nonlinear model "
                                   f"([model] python), got {method!r}")
        separate = sorted({"process_kernel_width", "sensor_kernel_width"} & set(observer))
        if separate:
            raise AttendInputError(f"{path}: [observer] {', '.join(separate)}: nonlinear models take one kernel_width "
                                   "[s] for both noises (separate widths are for linear models)")
        if "kernel_width" not in observer:
            raise AttendInputError(f"{path}: [observer] needs kernel_width (seconds, > 0): the smoothness of the noises")
        return method
    method = observer.get("method", "kalman")
    if method not in ("kalman", "dem"):
        hint = " (\"ukf\" is for nonlinear models: [model] python)" if method == "ukf" else ""
        raise AttendInputError(f"{path}: [observer] method: expected \"kalman\" or \"dem\"{hint}, got {method!r}")
    return method


def _kernel_widths(observer: dict, method: str, nonlinear: bool, path: Path) -> dict:
    """The [observer] kernel widths [s] by key (None where not given); kernel_width or both
    process_kernel_width and sensor_kernel_width must be given."""
    widths = {}
    for key in ("kernel_width", "process_kernel_width", "sensor_kernel_width", "input_kernel_width"):
        value = observer.get(key)
        if value is None:
            widths[key] = None
            continue
        positive_only = (method == "dem" or nonlinear) and key == "kernel_width"
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or value < 0 or (positive_only and value == 0):
            expected = "a number > 0" if positive_only else "a number >= 0 (0: white noise)"
            raise AttendInputError(f"{path}: [observer] {key}: expected {expected} (seconds), got {value!r}")
        if nonlinear and key == "input_kernel_width" and value == 0:
            raise AttendInputError(f"{path}: [observer] input_kernel_width: expected a number > 0 (seconds) for a "
                                   "nonlinear model, got 0")
        widths[key] = float(value)
    if widths["kernel_width"] is None and (widths["process_kernel_width"] is None
                                           or widths["sensor_kernel_width"] is None):
        raise AttendInputError(f"{path}: [observer] needs kernel_width (seconds), or both process_kernel_width "
                               "and sensor_kernel_width")
    return widths


def _initial_state(observer: dict, n_states: int, path: Path) -> tuple:
    """([observer] initial_state as a tuple or None, initial_state_std as a number, a tuple or None)."""
    initial_state = observer.get("initial_state")
    if initial_state is not None:
        if not isinstance(initial_state, list) or len(initial_state) != n_states or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in initial_state):
            raise AttendInputError(f"{path}: [observer] initial_state: expected {n_states} finite numbers "
                                   f"(one per state), got {initial_state!r}")
        initial_state = tuple(float(v) for v in initial_state)
    initial_std = observer.get("initial_state_std")
    if initial_std is not None:
        values = initial_std if isinstance(initial_std, list) else [initial_std]
        if len(values) not in (1, n_states) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0 for v in values):
            raise AttendInputError(f"{path}: [observer] initial_state_std: expected a number >= 0 or "
                                   f"{n_states} of them, got {initial_std!r}")
        initial_std = float(values[0]) if len(values) == 1 else tuple(float(v) for v in values)
    return initial_state, initial_std


def _check_observer(observer: dict, system: LinearSystem, where: str) -> None:
    """The [observer] orders, precisions and convention, with the file's key names in errors."""
    for key in ("embedding_order", "input_order"):
        if key in observer and not (key == "embedding_order" and observer[key] == "auto"):
            order(observer[key], f"{where} {key}")
    for key, size in (("sensor_precision", system.n_outputs), ("process_precision", system.n_states)):
        matrix = precision_matrix(observer[key], size, f"{where} {key}")
        require_moderate(matrix, f"{where} {key}")
    convention = observer.get("precision_convention", "size")
    if convention not in ("size", "max"):
        raise AttendInputError(f"{where} precision_convention: expected \"size\" or \"max\", got {convention!r}")


def _check_dem_conventions(observer: dict, method: str, nonlinear: bool, where: str) -> None:
    """[observer] integration ("attend" or "spm": how the data enter DEM's one-sample step, see
    docs/spm.md) and edges ("order0" or "clamp"), which only method = "dem" has, and states
    ("sample" or "path"), backend ("numpy" or "jax") and motion ("linearized" or "path"), nonlinear
    DEM only. nonlinear: the model is f, g ([model] python)."""
    for key, allowed in (("integration", ("attend", "spm")), ("edges", ("order0", "clamp"))):
        if key not in observer:
            continue
        if observer[key] not in allowed:
            raise AttendInputError(f"{where} {key}: expected {' or '.join(map(repr, allowed))}, got {observer[key]!r}")
        if method != "dem":
            raise AttendInputError(f"{where} {key}: a setting of DEM; add method = \"dem\" (the {method} "
                                   "estimator has no such choice)")
    nonlinear_only = (("states", ("sample", "path"), "DEM's path mode is for nonlinear models with method = \"dem\" "
                       "(for a linear model, method = \"kalman\" is already the exact smoother)"),
                      ("backend", ("numpy", "jax"), "the JAX D-step is for nonlinear models with method = \"dem\" "
                       "(f and g written with jax.numpy)"),
                      ("motion", ("linearized", "path"), "the generalised motion f~ of nonlinear DEM (method = \"dem\"; "
                       "for a linear model both are the same)"))
    for key, allowed, scope in nonlinear_only:
        if key not in observer:
            continue
        if observer[key] not in allowed:
            raise AttendInputError(f"{where} {key}: expected {' or '.join(map(repr, allowed))}, got {observer[key]!r}")
        if method != "dem" or not nonlinear:
            raise AttendInputError(f"{where} {key}: {scope}")


def _check_learning(learning: dict, where: str, nonlinear: bool = False) -> None:
    """The [learning] keys: types, ranges and lengths (the lambda pair has 2 entries); nonlinear:
    the model is f, g (free then names parameters, not matrix entries)."""
    if "free" in learning:
        _text_list(learning["free"], f"{where} free",
                   what='parameter names like "damping"' if nonlinear else 'entries like "A[2,1]"')
    for key in ("free_prior_precision", "known_prior_precision"):
        _file_number(learning, key, f"{where} {key}", 1.0, minimum=0.0, allow_inf=key == "known_prior_precision")
    for key, positive in (("noise_prior_mean", False), ("noise_prior_precision", True)):
        if key not in learning:
            continue
        value = learning[key]
        values = numeric_array(value, f"{where} {key}")
        if values.ndim > 1 or (values.ndim == 1 and len(values) != 2):
            raise AttendInputError(
                f"{where} {key}: expected a number or a pair [lambda_z, lambda_w] "
                f"(sensor, process), got {value!r}"
            )
        finite_or_inf = np.isfinite(values) | (positive & np.isposinf(values))
        if not finite_or_inf.all() or (positive and np.any(values <= 0)):
            raise AttendInputError(f"{where} {key}: expected {'numbers > 0 (inf holds lambda fixed)' if positive else 'finite numbers'}, got {value!r}")
        require_moderate(values[np.isfinite(values)], f"{where} {key}")
    if "max_iterations" in learning:
        iterations = learning["max_iterations"]
        if isinstance(iterations, bool) or not isinstance(iterations, int) or not 1 <= iterations <= 100_000:
            raise AttendInputError(f"{where} max_iterations: expected an integer in 1..100000, got {iterations!r}")
    _file_number(learning, "tolerance", f"{where} tolerance", 1e-3, minimum=0.0)
    if learning.get("states", "sample") not in ("sample", "path"):
        raise AttendInputError(f'{where} states: expected "sample" or "path", got {learning["states"]!r}')

