"""Model files (TOML) and logs (CSV) with validation; CSV output of estimates.

Model file (all times in seconds)::

    [model]
    A = [[0, 1], [0, 0]]            # continuous-time state matrix [1/s]
    B = [[0], [0.37]]               # input matrix
    C = [[1, 0]]                    # output matrix
    states = ["phi", "phi_dot"]     # optional names (default x1, x2, ...)
    dt = 0.008333                   # optional; must match the log's sample time

    [outputs]
    columns = ["meas_phi"]          # CSV columns holding the outputs, one per row of C

    [[inputs]]                      # one table per column of B, in order
    name = "motor_1"
    column = "motor_1"              # known input: measured in this CSV column
    operating_point = 170.0         # optional: subtracted from the column (linearisation point)
    [[inputs]]
    name = "wind"
    prior_mean = 0.0                # unknown input: prior mean eta ...
    prior_precision = 1.0           # ... and prior precision P_v [1/unit^2]

    [observer]
    method = "kalman"               # "kalman" (default: coloured-noise Kalman smoother) or "dem"
    kernel_width = 0.006            # s, Gaussian noise kernel width of both noises (0: white)
    # process_kernel_width = 0.01   # s, or separately for w and z (each overrides kernel_width)
    # sensor_kernel_width = 0.0
    # input_kernel_width = 0.05     # s, smoothness of the unknown inputs' prior (default: process width)
    sensor_precision = 1.2e8        # Pi_z: scalar, per-output list, or matrix
    process_precision = [1e3, 1e2]  # Pi_w: scalar, per-state list, or matrix
    # initial_state = [0.0, 0.0]    # prior mean of x[0] (default: unknown, a broad prior) ...
    # initial_state_std = 0.1       # ... and its std (default 0 when initial_state is given)
    embedding_order = "auto"        # DEM only: p (default "auto": the largest stable, well-conditioned p <= 6)
    input_order = 2                 # DEM only: d
    precision_convention = "size"   # DEM only: "size" (SPM) or "max" (Meera)
    known_input_precision = 7.9e13  # DEM only: prior precision given to measured inputs when some
                                    # inputs are unknown (default exp(32))

    [log]
    time_column = "t"               # CSV column with time stamps [s], uniform spacing

    [learning]                      # only for `attend identify` (all inputs measured)
    free = ["A[2,1]", "A[2,2]", "B[2,1]", "B[2,2]", "B[2,3]", "B[2,4]"]   # entries to learn (1-based)
    free_prior_precision = 1.0      # P_theta of the free entries (their prior means: [model])
    known_prior_precision = inf     # P_theta of the other entries: inf holds them fixed (exp(15) = 3.3e6: nearly)
    noise_prior_mean = [0.0, 0.0]   # eta_lambda of [lambda_z, lambda_w] (log-precisions)
    noise_prior_precision = 1.0     # P_lambda
    max_iterations = 50
    tolerance = 1e-3                # stop when an iteration raises F by less
    states = "sample"               # "sample" (paper's eq. 8) or "path" (one state path, data counted once)
    top_order = "marginal"          # top-order motion error: "marginal" (default) or "truncate" (eq. 8)

Nonlinear models: in [model], instead of A, B, C::

    python = "model.py"             # beside the model file: defines f(x, v) -> dx/dt and g(x, v) -> y
    n_states = 2                    # (or f(x, v, parameters), g(x, v, parameters) with a dict
    n_inputs = 1                    #  `parameters` in model.py; [model] parameters = {...} overrides it)
    n_outputs = 2
    parameters = { damping = 0.3 }  # optional

[outputs], [[inputs]] (one per input of f and g; none when n_inputs = 0), [observer] (one
kernel_width; method "ukf", the default, or "dem") and [log] as above. Errors in f or g name the
Python file, the line and the function.

Log file: CSV with a header row; the time column, the output columns and the known-input
columns named in the model file (other columns are ignored).
"""

from __future__ import annotations

import csv
import io as _text_io
import math
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from attend._validation import (
    LARGEST_MAGNITUDE,
    AttendInputError,
    as_matrix,
    number,
    numeric_array,
    order,
    positive_scalar,
    precision_matrix,
    require_finite,
    require_moderate,
    unique_names,
)
from attend.perception.dem import DEMEstimate, DEMObserver
from attend.perception.nonlinear import NonlinearSystem
from attend.systems import LinearSystem

from attend.constants import KNOWN_INPUT_PRECISION  # noqa: E402 (named once there)
#: Nonlinear DEM's default prior precision of measured inputs beside unknown ones (exp(32) overflows
#: the linear algebra of its flow; 1e8 pins them to the measurement to ~1e-8 on the pendulum).
NONLINEAR_KNOWN_INPUT_PRECISION = 1e8
#: The estimator of nonlinear models when [observer] method is not given (see NONLINEAR_METHODS).
NONLINEAR_METHOD = "ukf"

_LINEAR_KEYS = {"A", "B", "C"}
_NONLINEAR_KEYS = {"python", "n_states", "n_inputs", "n_outputs", "parameters"}
_SECTIONS = {
    "model": _LINEAR_KEYS | _NONLINEAR_KEYS | {"states", "dt"},
    "outputs": {"columns"},
    "inputs": None,  # array of tables, checked separately
    "observer": {
        "method", "kernel_width", "process_kernel_width", "sensor_kernel_width", "input_kernel_width",
        "embedding_order", "input_order", "sensor_precision", "process_precision", "precision_convention",
        "known_input_precision", "initial_state", "initial_state_std",
    },
    "log": {"time_column"},
    "learning": {
        "free", "free_prior_precision", "known_prior_precision", "noise_prior_mean",
        "noise_prior_precision", "max_iterations", "tolerance", "states", "top_order",
    },
    # written by `attend identify`; informative, not used by the observer
    "learned": {
        "parameter_names", "parameters", "parameter_precision", "log_precision", "free_energy",
        "converged", "iterations", "message",
    },
}
_INPUT_KEYS = {"name", "column", "operating_point", "prior_mean", "prior_precision"}


@dataclass(frozen=True)
class InputSpec:
    """One input: measured in ``column`` (known) or estimated with a Gaussian prior."""

    name: str
    column: str | None
    prior_mean: float = 0.0
    prior_precision: float = 1.0
    operating_point: float = 0.0

    @property
    def known(self) -> bool:
        """True when the input is measured (read from a CSV column)."""
        return self.column is not None


@dataclass(frozen=True)
class ModelFile:
    """A parsed model file: the system, its CSV mapping and the observer settings."""

    system: LinearSystem
    dt: float | None
    output_columns: tuple[str, ...]
    inputs: tuple[InputSpec, ...]
    kernel_width: float | None
    embedding_order: int | str
    input_order: int
    sensor_precision: object
    process_precision: object
    precision_convention: str
    known_input_precision: float
    time_column: str
    learning: dict = None
    path: str = ""
    method: str = "kalman"
    process_kernel_width: float | None = None
    sensor_kernel_width: float | None = None
    input_kernel_width: float | None = None
    initial_state: tuple | None = None
    initial_state_std: object = None
    python_path: str = ""  # the Python file of a nonlinear model ([model] python), resolved

    @property
    def nonlinear(self) -> bool:
        """True for a model given by f and g in a Python file ([model] python)."""
        return isinstance(self.system, NonlinearSystem)

    @property
    def learning_order(self) -> int:
        """The file's embedding order, or 6 (the largest that "auto" picks) when it says "auto"."""
        return 6 if self.embedding_order == "auto" else int(self.embedding_order)

    def observer(self, dt: float):
        """The estimator the file describes (``[observer] method``), for logs sampled every ``dt`` s."""
        if self.nonlinear:
            return self.nonlinear_estimator(dt)
        if self.method == "kalman":
            return self.kalman(dt)
        return self.dem(dt)

    def nonlinear_order(self, dt: float) -> int:
        """The DEM embedding order of a nonlinear model: the file's, or under "auto" the largest
        p <= 6 whose S(s) stays well conditioned (cond <= 1e8 in sample units; the stability check
        of the linear "auto" needs A, B, C)."""
        from attend.generalized import smoothness_condition
        from attend.perception.dem import AUTO_MAX_CONDITION, AUTO_MAX_ORDER

        if self.embedding_order != "auto":
            return int(self.embedding_order)
        for p in range(AUTO_MAX_ORDER, 0, -1):
            if smoothness_condition(p + 1, self.kernel_width, dt) <= AUTO_MAX_CONDITION:
                return p
        return 0

    def nonlinear_estimator(self, dt: float) -> "NonlinearFileEstimator":
        """The estimator of a nonlinear model file (see :class:`NonlinearFileEstimator`)."""
        estimator = NonlinearFileEstimator(self, dt, self.method, self.nonlinear_order(dt),
                                           self.embedding_order == "auto")
        try:
            estimator.dem()  # the settings are checked here, whichever method runs
        except AttendInputError as error:
            raise AttendInputError(f"{self.path}: [observer] {error}") from None
        return estimator

    def kalman(self, dt: float):
        """The coloured-noise Kalman smoother: measured inputs drive the model, the others are estimated."""
        from attend.perception.kalman import KalmanEstimator

        known = [spec.known for spec in self.inputs]
        prior = None if all(known) else np.array([1.0 if s.known else s.prior_precision for s in self.inputs])
        try:
            return KalmanEstimator(
                self.system, dt, self.sensor_precision, self.process_precision, kernel_width=self.kernel_width,
                process_kernel_width=self.process_kernel_width, sensor_kernel_width=self.sensor_kernel_width,
                input_prior_precision=prior, input_kernel_width=self.input_kernel_width,
                known_inputs=known if self.inputs else True,
                initial_state=self.initial_state, initial_state_std=self.initial_state_std,
            )
        except AttendInputError as error:
            raise AttendInputError(f"{self.path}: [observer] {error}") from None

    def dem(self, dt: float) -> DEMObserver:
        """The DEM observer the file describes, for logs sampled every ``dt`` seconds.

        All inputs measured: the known-input observer. Otherwise inputs are unknowns; measured
        ones get their measurement as prior mean with precision ``known_input_precision``.
        """
        all_known = all(spec.known for spec in self.inputs)
        prior = None if all_known else np.array(
            [self.known_input_precision if s.known else s.prior_precision for s in self.inputs]
        )
        try:
            return DEMObserver(
                self.system, dt, self.kernel_width, self.sensor_precision, self.process_precision,
                prior, self.embedding_order, self.input_order, known_inputs=all_known,
                precision_convention=self.precision_convention,
                process_kernel_width=self.process_kernel_width, sensor_kernel_width=self.sensor_kernel_width,
                input_kernel_width=self.input_kernel_width,
                initial_state=None if self.initial_state is None else np.array(self.initial_state),
            )
        except AttendInputError as error:
            raise AttendInputError(f"{self.path}: [observer] {error}") from None


@dataclass(frozen=True)
class NonlinearFileEstimator:
    """The estimator of a nonlinear model file ([model] python), for logs sampled every ``dt`` s.

    method "ukf": the unscented Kalman (RTS) smoother on a white-noise model with the coloured
    noises' per-sample variance (Q = dt^2 inv(Pi_w), R = inv(Pi_z)); unknown inputs ride in the
    state as random walks whose one-sample increments have the variance of their prior's
    (:func:`attend.perception.nonlinear_baselines.input_random_walk_variance`), started at the prior mean; measured inputs drive f and g.
    Without [observer] initial_state the smoother starts from DEM's estimate of the first sample
    and its std. method "dem": :class:`attend.perception.nonlinear.NonlinearDEM` (measured inputs,
    when some are unknown, get their measurement as prior mean with precision known_input_precision).
    """

    model: "ModelFile"
    dt: float
    method: str
    embedding_order: int
    automatic_order: bool

    @property
    def system(self) -> NonlinearSystem:
        return self.model.system

    @property
    def known(self) -> np.ndarray:
        return np.array([spec.known for spec in self.model.inputs], dtype=bool)

    def dem(self):
        """The NonlinearDEM of the file's settings."""
        from attend.perception.nonlinear import NonlinearDEM

        model, known = self.model, self.known
        all_known = bool(known.all())
        prior = None if all_known else np.array(
            [model.known_input_precision if spec.known else spec.prior_precision for spec in model.inputs])
        return NonlinearDEM(
            self.system, self.dt, model.kernel_width, model.sensor_precision, model.process_precision, prior,
            self.embedding_order, model.input_order, known_inputs=all_known,
            precision_convention=model.precision_convention, input_kernel_width=model.input_kernel_width,
        )

    @property
    def input_kernel_width(self) -> float:
        return self.model.input_kernel_width or self.model.kernel_width

    def estimate(self, outputs, signals):
        """Estimates (time, states, inputs, state_std, input_std, ...) on outputs (N, m); signals
        (N, r): measured inputs (operating point removed) or the prior means of the unknown ones."""
        model = self.model
        initial = None if model.initial_state is None else np.array(model.initial_state)
        if self.method == "dem":
            return self.dem().estimate(outputs, signals, initial_state=initial)
        from attend.perception.nonlinear_baselines import input_random_walk_variance, unscented_kalman

        n, r = self.system.n_states, self.system.n_inputs
        Pi_w = precision_matrix(model.process_precision, n, "process_precision")
        Pi_z = precision_matrix(model.sensor_precision, self.system.n_outputs, "sensor_precision")
        covariances = {}
        for key, matrix in (("process_precision", Pi_w), ("sensor_precision", Pi_z)):
            if np.linalg.eigvalsh(matrix).min() <= 0:
                raise AttendInputError(f"{key}: method \"ukf\" needs a positive definite precision (it is "
                                       "inverted into a covariance); every entry > 0")
            covariances[key] = np.linalg.inv(matrix)
        options = dict(process_covariance=self.dt**2 * covariances["process_precision"],
                       measurement_covariance=covariances["sensor_precision"])
        known = self.known
        if r and not known.all():
            precisions = np.array([spec.prior_precision for spec in model.inputs])
            bad = [spec.name for spec in model.inputs if not spec.known and not spec.prior_precision > 0]
            if bad:
                raise AttendInputError(f"[[inputs]] {', '.join(map(repr, bad))} prior_precision: method \"ukf\" "
                                       "needs a prior precision > 0 (it sets the random walk of the input)")
            variance = input_random_walk_variance(np.where(known, 1.0, precisions), self.input_kernel_width, self.dt)
            options.update(input_variance=np.diag(np.where(known, 0.0, variance)), input_mean=signals[0],
                           known_inputs=known)
            inputs = signals if known.any() else None
        else:
            inputs = signals if r else None
        if initial is None:
            mean, std = self._start(outputs, signals)
        else:
            mean = initial
            std = np.broadcast_to(np.asarray(0.0 if model.initial_state_std is None else model.initial_state_std,
                                             dtype=float), (n,))
        return unscented_kalman(self.system, self.dt, outputs, inputs, initial_mean=mean,
                                initial_covariance=np.diag(np.asarray(std, dtype=float) ** 2), **options)

    def _start(self, outputs, signals):
        """x[0] and its std from DEM on the first samples (the smoother's prior on the initial state)."""
        dem = self.dem()
        count = min(len(outputs), 4 * (max(self.embedding_order, self.model.input_order) + 1))
        try:
            first = dem.estimate(outputs[:count], signals[:count])
        except AttendInputError as error:
            if self.model.python_path and str(error).startswith(self.model.python_path):
                raise
            raise AttendInputError(f"the smoother starts from DEM's estimate of the first sample, which failed "
                                   f"({error}); give initial_state and initial_state_std") from None
        return first.states[0], first.state_std[0]


def _check_keys(table: dict, allowed: set[str], where: str, path: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise AttendInputError(
            f"{path}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} "
            f"in [{where}]; expected one of {', '.join(sorted(allowed))}"
        )


def _read_text(path: str | Path, what: str) -> str:
    """The text of a user's file (UTF-8, an optional BOM dropped); a missing file, a directory,
    a permission problem or binary content is an AttendInputError naming the file."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise AttendInputError(f"{what}: {path} does not exist") from None
    except IsADirectoryError:
        raise AttendInputError(f"{what}: {path} is a directory; expected a file") from None
    except PermissionError:
        raise AttendInputError(f"{what}: {path} cannot be read (permission denied)") from None
    except OSError as error:
        raise AttendInputError(f"{what}: {path} cannot be read ({error.strerror or error})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise AttendInputError(
            f"{path}: expected a UTF-8 text {what}, found byte 0x{raw[error.start]:02x} at byte {error.start} "
            "(a binary file, or text in another encoding: save it as UTF-8)"
        ) from None
    if "\x00" in text:
        raise AttendInputError(f"{path}: expected a text {what}, found a NUL byte (a binary file?)")
    return text


def _matrix(value, field: str) -> np.ndarray:
    """A model-file matrix: numbers (no text), finite and within +-1e150."""
    array = numeric_array(value, field, "a matrix of numbers (a list of rows)")
    require_finite(array, field)
    require_moderate(array, field)
    return array


def _file_number(table: dict, key: str, field: str, default: float, *, minimum: float | None = None,
                 positive: bool = False, allow_inf: bool = False) -> float:
    """table[key] as a finite (or, with ``allow_inf``, infinite) number within +-1e150 and the bounds."""
    if key not in table:
        return default
    value = number(table[key], field)
    if math.isnan(value) or (math.isinf(value) and not (allow_inf and value > 0)):
        raise AttendInputError(f"{field}: expected a finite number, got {value}")
    if math.isfinite(value):
        require_moderate(np.array([value]), field)
    if positive and not value > 0:
        raise AttendInputError(f"{field}: expected a number > 0, got {value}")
    if minimum is not None and value < minimum:
        raise AttendInputError(f"{field}: expected a number >= {minimum:g}, got {value}")
    return value


def _text(value, field: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise AttendInputError(f"{field}: expected a non-empty text (in quotes), got {value!r}")
    return value


def _text_list(value, field: str, size: int | None = None, what: str = "names") -> tuple[str, ...]:
    if not isinstance(value, list):
        raise AttendInputError(f"{field}: expected a list of {what} in quotes, got {value!r}")
    names = unique_names(value, field)
    if size is not None and len(names) != size:
        raise AttendInputError(f"{field}: expected {size} {what}, got {len(names)}")
    return names


# --- nonlinear models: f and g from the user's Python file ----------------------------------

def _model_size(model: dict, key: str, path) -> int:
    """[model] n_states / n_inputs / n_outputs of a nonlinear model: an integer (n_inputs may be 0)."""
    low = 0 if key == "n_inputs" else 1
    if key not in model:
        raise AttendInputError(f"{path}: [model] needs {key} (an integer >= {low}) with python = ... (a nonlinear model)")
    value = model[key]
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= 10_000:
        raise AttendInputError(f"{path}: [model] {key}: expected an integer in {low}..10000, got {value!r}")
    return value


def _takes_parameters(function, name: str, source) -> bool:
    """Whether the user's function takes a third argument (the parameters)."""
    import inspect

    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):
        return False
    positional = [p for p in signature.parameters.values()
                  if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    required = [p for p in positional if p.default is p.empty]
    if any(p.kind == p.VAR_POSITIONAL for p in signature.parameters.values()):
        return True
    if len(required) > 3 or len(positional) < 2:
        raise AttendInputError(f"{source}: {name}{signature}: expected {name}(x, v) or {name}(x, v, parameters)")
    return len(positional) >= 3


class _UserShapeError(AttendInputError):
    """f or g returned something of the wrong shape or type (reported when the model is read)."""


class _UserFunction:
    """f or g of the user's file: called with (x, v) [and the parameters]; every value checked.

    An exception inside the user's code, a wrong shape or a non-finite value is an
    AttendInputError naming the file, the line of the user's code, the function and the point."""

    def __init__(self, function, name: str, size: int, what: str, source: Path, parameters):
        self.function, self.name, self.size, self.what = function, name, size, what
        self.source, self.parameters = source, parameters

    def _where(self, error: BaseException) -> str:
        import traceback

        lines = [frame.lineno for frame in traceback.extract_tb(error.__traceback__)
                 if Path(frame.filename).resolve() == self.source.resolve()]
        return f" (line {lines[-1]})" if lines else ""

    def __call__(self, x, v, *unused):
        try:
            with np.errstate(all="ignore"):
                value = self.function(x, v) if self.parameters is None else self.function(x, v, self.parameters)
        except Exception as error:  # the user's code failed: say so, with its own message
            raise AttendInputError(
                f"{self.source}: {self.name}(x, v) failed{self._where(error)}: {type(error).__name__}: "
                f"{_one_line(error)} (at x = {_short(x)}, v = {_short(v)}); this is an error in the model's code"
            ) from None
        try:
            if value is None:
                raise TypeError("None")
            value = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise _UserShapeError(f"{self.source}: {self.name}(x, v) returned {type(value).__name__} "
                                   f"{_short(value)}; expected {self.size} numbers ({self.what})") from None
        if value.shape != (self.size,):
            if value.size == self.size and value.ndim <= 2:
                value = value.reshape(self.size)
            else:
                raise _UserShapeError(
                    f"{self.source}: {self.name}(x, v) returned shape {value.shape}; expected {self.size} "
                    f"values ({self.what})")
        if not np.all(np.isfinite(value)):
            raise AttendInputError(
                f"{self.source}: {self.name}(x, v) returned non-finite values {_short(value)} at x = {_short(x)}, "
                f"v = {_short(v)}; expected finite numbers")
        return value


def _short(value) -> str:
    text = np.array2string(np.asarray(value), precision=4, separator=", ", threshold=8) \
        if isinstance(value, (np.ndarray, list, tuple)) else repr(value)
    return _one_line(text)[:200]


def _one_line(text) -> str:
    return " ".join(str(text).split())


def _toml_parameters(value, where: str) -> dict:
    """[model] parameters: a table of numbers, lists of numbers (as float arrays), text or booleans."""
    if not isinstance(value, dict):
        raise AttendInputError(f"{where}: expected a table, e.g. parameters = {{ gravity = 9.81, damping = 0.3 }}, "
                               f"got {value!r}")
    out = {}
    for key, item in value.items():
        if isinstance(item, list):
            array = numeric_array(item, f"{where} {key}", "a number, a list of numbers or a matrix")
            require_finite(array, f"{where} {key}")
            out[key] = array
        else:
            out[key] = item
    return out


def _python_model(path: Path, model: dict, n_states: int, n_inputs: int, n_outputs: int, state_names, input_names):
    """The NonlinearSystem of [model] python = "file.py" (relative to the model file)."""
    import importlib.util
    import sys

    where = f"{path}: [model] python"
    name = _text(model["python"], where)
    source = (path.parent / name)
    if not source.exists():
        raise AttendInputError(f"{where}: {source} does not exist (the path is relative to the model file's folder)")
    if not source.is_file():
        raise AttendInputError(f"{where}: {source} is not a file; expected a Python file defining f(x, v) and g(x, v)")
    _read_text(source, "Python model file")  # readable UTF-8 text, or an error naming it
    module_name = f"attend_user_model_{abs(hash(str(source.resolve())))}"
    spec = importlib.util.spec_from_file_location(module_name, source)
    if spec is None or spec.loader is None:
        raise AttendInputError(f"{where}: {source} cannot be loaded as Python (expected a .py file)")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling inside the user's file need it
    folder = str(source.parent.resolve())
    sys.path.insert(0, folder)  # the file may import helpers beside it
    try:
        spec.loader.exec_module(module)
    except SyntaxError as error:
        raise AttendInputError(f"{source}: line {error.lineno}: not valid Python ({error.msg})") from None
    except Exception as error:
        lines = [frame.lineno for frame in __import__("traceback").extract_tb(error.__traceback__)
                 if Path(frame.filename).resolve() == source.resolve()]
        at = f" (line {lines[-1]})" if lines else ""
        raise AttendInputError(f"{source}: the model's code failed when loaded{at}: {type(error).__name__}: "
                               f"{_one_line(error)}") from None
    finally:
        if sys.path and sys.path[0] == folder:
            sys.path.pop(0)
    functions = {}
    for key in ("f", "g"):
        function = getattr(module, key, None)
        if function is None:
            raise AttendInputError(
                f"{source}: defines no function {key}; expected f(x, v) -> dx/dt ({n_states} values) and "
                f"g(x, v) -> y ({n_outputs} values), optionally with a third argument, the parameters")
        if not callable(function):
            raise AttendInputError(f"{source}: {key} is a {type(function).__name__}; expected a function {key}(x, v)")
        functions[key] = function
    parameters = getattr(module, "parameters", None)
    if parameters is not None and not isinstance(parameters, dict):
        raise AttendInputError(f"{source}: parameters is a {type(parameters).__name__}; expected a dict of the "
                               "model's parameters (passed to f and g as their third argument)")
    if "parameters" in model:
        parameters = {**(parameters or {}), **_toml_parameters(model["parameters"], f"{path}: [model] parameters")}
    takes = {key: _takes_parameters(function, key, source) for key, function in functions.items()}
    if any(takes.values()) and parameters is None:
        needs = " and ".join(key for key, value in takes.items() if value)
        raise AttendInputError(f"{source}: {needs} take a third argument (the parameters) but neither the file nor "
                               f"the model file gives them; define parameters = {{...}} in {source.name} or "
                               "[model] parameters in the model file")
    if parameters is not None and not any(takes.values()):
        raise AttendInputError(f"{source}: parameters are given but neither f nor g takes them; write "
                               "f(x, v, parameters) and g(x, v, parameters)")
    f = _UserFunction(functions["f"], "f", n_states,
                      f"dx/dt, one per state: [model] n_states = {n_states}", source, parameters if takes["f"] else None)
    g = _UserFunction(functions["g"], "g", n_outputs,
                      f"y, one per output: [model] n_outputs = {n_outputs}", source, parameters if takes["g"] else None)
    try:
        return NonlinearSystem(f, g, n_states, n_inputs, n_outputs, state_names=state_names,
                               input_names=input_names)
    except AttendInputError as error:
        raise AttendInputError(f"{path}: [model] {error}") from None


def _probe(system: NonlinearSystem, initial_state, inputs) -> None:
    """Call f and g once (at initial_state or zeros, the inputs' prior means or operating points):
    a wrong output shape is reported when the model is read. An exception or a non-finite value
    there is left for the estimate (the point may be outside the model's domain)."""
    x = np.zeros(system.n_states) if initial_state is None else np.array(initial_state, dtype=float)
    v = np.array([spec.operating_point if spec.known else spec.prior_mean for spec in inputs], dtype=float)
    for function in (system.f, system.g):
        try:
            function(x, v)
        except _UserShapeError:
            raise
        except AttendInputError:
            pass


def read_model(path: str | Path) -> ModelFile:
    """Parse and validate a model TOML file (format in the module docstring)."""
    path = Path(path)
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
    model = data.get("model", {})
    nonlinear = "python" in model
    raw_inputs = data.get("inputs", [])
    if not isinstance(raw_inputs, list) or not all(isinstance(spec, dict) for spec in raw_inputs):
        per = "one per input of f and g" if nonlinear else "one per column of B"
        raise AttendInputError(f"{path}: expected [[inputs]] tables ({per}), got inputs = {raw_inputs!r}")
    if nonlinear:
        mixed = sorted(_LINEAR_KEYS & set(model))
        if mixed:
            raise AttendInputError(f"{path}: [model] has both python (a nonlinear model f, g) and {', '.join(mixed)} "
                                   "(a linear model); give one of them")
        n_states, n_inputs, n_outputs = (_model_size(model, key, path) for key in ("n_states", "n_inputs", "n_outputs"))
    else:
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
        B = _matrix(model["B"], f"{path}: [model] B")
        C = _matrix(model["C"], f"{path}: [model] C")
        n_states = A.shape[0]
        n_inputs = B.shape[1] if B.ndim == 2 else 1
        n_outputs = C.shape[0] if C.ndim == 2 else 1
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
    input_names = unique_names(
        [_text(spec.get("name", f"u{i + 1}"), f"{path}: [[inputs]] table {i + 1} name") for i, spec in enumerate(raw_inputs)],
        f"{path}: [[inputs]] name",
    )
    state_names = _text_list(model["states"], f"{path}: [model] states", n_states, "state names") if "states" in model else ()
    unique_names(state_names + input_names + ("t",), f"{path}: [model] states and [[inputs]] names (and 't', the time column of the estimates)")
    if nonlinear:
        system = _python_model(path, model, n_states, n_inputs, n_outputs, state_names, input_names)
    else:
        try:
            system = LinearSystem(A, B, C, state_names=state_names, input_names=input_names)
        except AttendInputError as error:
            raise AttendInputError(f"{path}: [model] {error}") from None
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
    per_output = "one per output of g: [model] n_outputs" if nonlinear else "one per row of C"
    outputs = data.get("outputs", {}).get("columns")
    if outputs is None:
        raise AttendInputError(f"{path}: [outputs] needs columns (the CSV columns of the {system.n_outputs} outputs, {per_output})")
    if not isinstance(outputs, list) or len(outputs) != system.n_outputs:
        raise AttendInputError(
            f"{path}: [outputs] columns: expected {system.n_outputs} column names ({per_output}), got {outputs!r}"
        )
    outputs = _text_list(outputs, f"{path}: [outputs] columns", what="column names")
    observer = data.get("observer", {})
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
    else:
        method = observer.get("method", "kalman")
        if method not in ("kalman", "dem"):
            hint = " (\"ukf\" is for nonlinear models: [model] python)" if method == "ukf" else ""
            raise AttendInputError(f"{path}: [observer] method: expected \"kalman\" or \"dem\"{hint}, got {method!r}")
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
    kernel_width = widths["kernel_width"]
    if kernel_width is None and (widths["process_kernel_width"] is None or widths["sensor_kernel_width"] is None):
        raise AttendInputError(f"{path}: [observer] needs kernel_width (seconds), or both process_kernel_width "
                               "and sensor_kernel_width")
    initial_state = observer.get("initial_state")
    if initial_state is not None:
        if not isinstance(initial_state, list) or len(initial_state) != system.n_states or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in initial_state):
            raise AttendInputError(f"{path}: [observer] initial_state: expected {system.n_states} finite numbers "
                                   f"(one per state), got {initial_state!r}")
        initial_state = tuple(float(v) for v in initial_state)
    initial_std = observer.get("initial_state_std")
    if initial_std is not None:
        values = initial_std if isinstance(initial_std, list) else [initial_std]
        if len(values) not in (1, system.n_states) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0 for v in values):
            raise AttendInputError(f"{path}: [observer] initial_state_std: expected a number >= 0 or "
                                   f"{system.n_states} of them, got {initial_std!r}")
        initial_std = float(values[0]) if len(values) == 1 else tuple(float(v) for v in values)
    _check_observer(observer, system, f"{path}: [observer]")
    if nonlinear:
        _probe(system, initial_state, inputs)
    dt = model.get("dt")
    if dt is not None:
        dt = positive_scalar(dt, f"{path}: [model] dt", "seconds")
    time_column = _text(data.get("log", {}).get("time_column", "t"), f"{path}: [log] time_column")
    learning = dict(data.get("learning", {}))
    _check_learning(learning, f"{path}: [learning]")
    return ModelFile(
        system=system,
        dt=dt,
        output_columns=tuple(outputs),
        inputs=tuple(inputs),
        kernel_width=kernel_width,
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
    )


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


def _check_learning(learning: dict, where: str) -> None:
    """The [learning] keys: types, ranges and lengths (the lambda pair has 2 entries)."""
    if "free" in learning:
        _text_list(learning["free"], f"{where} free", what='entries like "A[2,1]"')
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


@dataclass(frozen=True)
class Log:
    """A CSV log: time [s] (N,), and named columns."""

    time: np.ndarray
    columns: dict[str, np.ndarray]
    path: str = ""
    line_numbers: np.ndarray | None = None  # line of each sample in the file (errors name it)

    @property
    def dt(self) -> float:
        """Mean sample time [s]."""
        return float((self.time[-1] - self.time[0]) / (len(self.time) - 1))

    def matrix(self, names) -> np.ndarray:
        """Columns ``names`` side by side as an (N, len(names)) array; NaN, inf and values beyond
        +-1e150 in them are errors naming the file, line and column."""
        missing = [name for name in names if name not in self.columns]
        if missing:
            raise AttendInputError(
                f"{self.path}: CSV is missing the declared column{'s' if len(missing) > 1 else ''} "
                f"{', '.join(map(repr, missing))}; it has {', '.join(self.columns)}"
            )
        lines = self.line_numbers if self.line_numbers is not None else np.arange(len(self.time)) + 2
        for name in names:
            _check_log_column(self.columns[name], self.path, name, lines)
        return np.column_stack([self.columns[name] for name in names]) if names else np.zeros((len(self.time), 0))


def read_log(path: str | Path, time_column: str = "t", *, relative_tolerance: float = 1e-4) -> Log:
    """Read a CSV log with a header; check the time column is present, finite and uniform.

    UTF-8 with or without a BOM, LF or CRLF line ends. Every cell must be a number; values
    beyond +-1e150 are errors. Time stamps count as uniform when every step is within
    ``relative_tolerance`` of the mean step.
    """
    path = Path(path)
    text = _read_text(path, "log")
    try:
        lines = list(csv.reader(_text_io.StringIO(text, newline=None)))
    except csv.Error as error:
        raise AttendInputError(f"{path}: not a readable CSV ({error})") from None
    numbered = [(number_, row) for number_, row in enumerate(lines, start=1) if any(cell.strip() for cell in row)]
    if not numbered:
        raise AttendInputError(f"{path}: the CSV is empty (expected a header row and samples)")
    header = [name.strip() for name in numbered[0][1]]
    rows = numbered[1:]
    unique_names([name for name in header if name], f"{path}: header")
    if not rows:
        raise AttendInputError(f"{path}: the CSV has a header but no samples")
    if time_column not in header:
        raise AttendInputError(f"{path}: CSV is missing the time column {time_column!r}; it has {', '.join(header)}")
    try:
        values = np.array([row for _, row in rows], dtype=float)
    except ValueError:
        for line, row in rows:
            if len(row) != len(header):
                raise AttendInputError(f"{path}: line {line} has {len(row)} fields, the header has {len(header)}") from None
            for name, cell in zip(header, row):
                try:
                    float(cell)
                except ValueError:
                    raise AttendInputError(f"{path}: line {line}, column {name!r}: expected a number, got {cell!r}") from None
        raise
    line_numbers = np.array([line for line, _ in rows])
    columns = {name: values[:, j] for j, name in enumerate(header)}
    time = columns[time_column]
    _check_log_column(time, path, time_column, line_numbers)
    if len(time) >= 2:
        steps = np.diff(time)
        mean_step = (time[-1] - time[0]) / (len(time) - 1)
        if mean_step <= 0:
            raise AttendInputError(f"{path}: column {time_column!r}: time stamps must increase")
        worst = int(np.argmax(np.abs(steps - mean_step)))
        if abs(steps[worst] - mean_step) > relative_tolerance * mean_step:
            raise AttendInputError(
                f"{path}: column {time_column!r}: non-uniform time stamps (step {steps[worst]:.6g} s at line "
                f"{line_numbers[worst + 1]}, mean step {mean_step:.6g} s); resample the log to a uniform rate first"
            )
    return Log(time, columns, str(path), line_numbers)


def _check_log_column(values: np.ndarray, path, name: str, line_numbers: np.ndarray) -> None:
    """NaN, inf and values beyond +-1e150 are errors naming the file, line and column."""
    bad = ~np.isfinite(values) | (np.abs(values) > LARGEST_MAGNITUDE)
    if bad.any():
        row = int(np.argmax(bad))
        expected = "a finite number" if not np.isfinite(values[row]) else f"a value within +-{LARGEST_MAGNITUDE:.0e}"
        raise AttendInputError(
            f"{path}: line {line_numbers[row]} (sample {row + 1}), column {name!r}: expected {expected}, got {values[row]:.6g}"
        )


def _check_samples(model: ModelFile, log: Log, minimum: int, why: str) -> float:
    """The log's sample time, after checking its length and the model's dt against it."""
    if len(log.time) < minimum:
        raise AttendInputError(f"{log.path}: expected at least {minimum} samples ({why}), got {len(log.time)}")
    dt = log.dt
    if model.dt is not None and abs(model.dt - dt) > 1e-4 * dt:
        raise AttendInputError(
            f"{model.path}: [model] dt = {model.dt} s but the log {log.path} is sampled every {dt:.6g} s"
        )
    return dt


def _observer_of(model: ModelFile, dt: float) -> DEMObserver:
    try:
        return model.observer(dt)
    except AttendInputError as error:  # in the file's words: P_v is the [[inputs]] prior_precision
        message = str(error).replace("input_prior_precision", "[[inputs]] prior_precision")
        raise AttendInputError(f"{model.path}: [observer] {message}") from None


def estimate_from_files(model: ModelFile, log: Log) -> tuple[DEMObserver, DEMEstimate]:
    """Run the model file's observer on the log (checks columns, finiteness and sample time)."""
    outputs = log.matrix(model.output_columns)
    signals = np.zeros((len(log.time), model.system.n_inputs))
    for j, spec in enumerate(model.inputs):
        if spec.known:
            signals[:, j] = log.matrix([spec.column])[:, 0] - spec.operating_point
        else:
            signals[:, j] = spec.prior_mean
    if model.nonlinear and model.method == "dem":
        window = max(model.nonlinear_order(log.dt), model.input_order) + 1
        dt = _check_samples(model, log, max(2, window), f"the embedding window of order {window - 1}")
    elif model.nonlinear:
        dt = _check_samples(model, log, 2, "the unscented Kalman smoother")
    elif model.method == "dem":
        order = model.learning_order  # "auto" picks p <= 6
        window = max(order, model.input_order) + 1
        dt = _check_samples(model, log, max(2, window), f"the embedding window of order {window - 1}")
    else:
        dt = _check_samples(model, log, 2, "the Kalman smoother")
    observer = _observer_of(model, dt)
    with np.errstate(over="ignore", invalid="ignore"):
        if model.nonlinear:
            try:
                estimate = observer.estimate(outputs, signals)
            except AttendInputError as error:
                text = str(error)
                if model.python_path and text.startswith(model.python_path):
                    raise  # the user's f or g failed: the message names the file and the function
                raise AttendInputError(f"{model.path}: [observer] method {model.method!r}: {text}") from None
        else:
            estimate = observer.estimate(outputs, signals)
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


def write_estimates(path: str | Path, log: Log, system: LinearSystem, estimate: DEMEstimate) -> Path:
    """CSV with time, each state and input estimate, and their standard deviations."""
    path = Path(path)
    header = ["t"]
    header += list(system.state_names) + list(system.input_names)
    header += [f"{name}_std" for name in system.state_names] + [f"{name}_std" for name in system.input_names]
    table = np.column_stack([log.time, estimate.states, estimate.inputs, estimate.state_std, estimate.input_std])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    return path


def identify_from_files(model: ModelFile, log: Log, *, progress: bool = False):
    """Run attend's learning (D, E, M steps) on the log with the model file's [learning] settings.

    The model's A, B, C are the prior means; every input must be measured (a column). An
    [observer] embedding_order of "auto" means p = 6 here (the learning default).
    """
    from attend.perception.learning import identify

    if model.nonlinear:
        raise AttendInputError(f"{model.path}: identify needs a linear model (A, B, C in [model]); nonlinear models "
                               "([model] python) can be estimated (attend estimate) but not identified yet")
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
    settings = dict(model.learning or {})
    options = {key: settings[key] for key in (
        "free", "free_prior_precision", "known_prior_precision", "noise_prior_mean", "noise_prior_precision",
        "max_iterations", "tolerance", "states", "top_order") if key in settings}
    if "noise_prior_mean" in options:
        options["noise_prior_mean"] = tuple(np.atleast_1d(options["noise_prior_mean"]))
    if model.kernel_width is None or model.kernel_width == 0:
        raise AttendInputError(f"{model.path}: [observer] kernel_width: identify needs one kernel width > 0 [s] for "
                               "both noises (separate or white widths are for attend estimate only)")
    try:
        return identify(model.system, outputs, inputs, dt, kernel_width=model.kernel_width,
                        embedding_order=model.learning_order,
                        input_order=model.input_order,
                        precision_convention=model.precision_convention, progress=progress, **options)
    except AttendInputError as error:
        raise AttendInputError(_in_file_terms(str(error), model, log)) from None


_LEARNING_FIELDS = ("free", "prior_precision", "initial", "noise_prior_mean", "noise_prior_precision",
                    "max_iterations", "tolerance", "states")


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
    the learned A, B, C and precisions on the log: every estimate must be finite.
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
    [learned], ready for `attend estimate`."""
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
