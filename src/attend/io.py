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

Log file: CSV with a header row; the time column, the output columns and the known-input
columns named in the model file (other columns are ignored).
"""

from __future__ import annotations

import csv
import math
try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError, require_finite
from attend.perception.dem import DEMEstimate, DEMObserver
from attend.systems import LinearSystem

KNOWN_INPUT_PRECISION = math.exp(32)

_SECTIONS = {
    "model": {"A", "B", "C", "states", "dt"},
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

    def observer(self, dt: float):
        """The estimator the file describes (``[observer] method``), for logs sampled every ``dt`` s."""
        if self.method == "kalman":
            return self.kalman(dt)
        return self.dem(dt)

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
                initial_state=None if self.initial_state is None else np.array(self.initial_state),
            )
        except AttendInputError as error:
            raise AttendInputError(f"{self.path}: [observer] {error}") from None


def _check_keys(table: dict, allowed: set[str], where: str, path: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise AttendInputError(
            f"{path}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} "
            f"in [{where}]; expected one of {', '.join(sorted(allowed))}"
        )


def read_model(path: str | Path) -> ModelFile:
    """Parse and validate a model TOML file (format in the module docstring)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise AttendInputError(f"model file: {path} does not exist") from None
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
    model = data.get("model", {})
    for key in ("A", "B", "C"):
        if key not in model:
            raise AttendInputError(f"{path}: [model] needs {key} (a matrix as a list of rows)")
    try:
        system = LinearSystem(
            model["A"], model["B"], model["C"],
            state_names=tuple(model.get("states", ())),
            input_names=tuple(spec.get("name", f"u{i + 1}") for i, spec in enumerate(data.get("inputs", []))),
        )
    except AttendInputError as error:
        raise AttendInputError(f"{path}: [model] {error}") from None
    raw_inputs = data.get("inputs", [])
    if not isinstance(raw_inputs, list) or len(raw_inputs) != system.n_inputs:
        raise AttendInputError(
            f"{path}: expected {system.n_inputs} [[inputs]] tables (one per column of B), "
            f"got {len(raw_inputs) if isinstance(raw_inputs, list) else 'a non-list'}"
        )
    inputs = []
    for i, spec in enumerate(raw_inputs):
        _check_keys(spec, _INPUT_KEYS, f"inputs {i + 1}", str(path))
        name = spec.get("name", f"u{i + 1}")
        if "column" in spec and ("prior_mean" in spec or "prior_precision" in spec):
            raise AttendInputError(
                f"{path}: input {name!r} has both a column (known input) and a prior (unknown input); give one"
            )
        precision = float(spec.get("prior_precision", 1.0))
        if not math.isfinite(precision) or precision < 0:
            raise AttendInputError(f"{path}: input {name!r} prior_precision: expected a finite number >= 0")
        if "operating_point" in spec and "column" not in spec:
            raise AttendInputError(f"{path}: input {name!r} has an operating_point but no column (only measured inputs have one)")
        inputs.append(InputSpec(
            name, spec.get("column"), float(spec.get("prior_mean", 0.0)), precision,
            float(spec.get("operating_point", 0.0)),
        ))
    outputs = data.get("outputs", {}).get("columns")
    if outputs is None or len(outputs) != system.n_outputs:
        raise AttendInputError(
            f"{path}: [outputs] columns: expected {system.n_outputs} column names (one per row of C), got {outputs!r}"
        )
    observer = data.get("observer", {})
    for key in ("sensor_precision", "process_precision"):
        if key not in observer:
            raise AttendInputError(f"{path}: [observer] needs {key}")
    method = observer.get("method", "kalman")
    if method not in ("kalman", "dem"):
        raise AttendInputError(f"{path}: [observer] method: expected \"kalman\" or \"dem\", got {method!r}")
    widths = {}
    for key in ("kernel_width", "process_kernel_width", "sensor_kernel_width", "input_kernel_width"):
        value = observer.get(key)
        if value is None:
            widths[key] = None
            continue
        positive_only = method == "dem" and key == "kernel_width"
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or value < 0 or (positive_only and value == 0):
            expected = "a number > 0" if positive_only else "a number >= 0 (0: white noise)"
            raise AttendInputError(f"{path}: [observer] {key}: expected {expected} (seconds), got {value!r}")
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
    dt = model.get("dt")
    if dt is not None and (not isinstance(dt, (int, float)) or not dt > 0):
        raise AttendInputError(f"{path}: [model] dt: expected a number > 0 (seconds), got {dt!r}")
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
        known_input_precision=float(observer.get("known_input_precision", KNOWN_INPUT_PRECISION)),
        time_column=data.get("log", {}).get("time_column", "t"),
        learning=dict(data.get("learning", {})),
        path=str(path),
        method=method,
        process_kernel_width=widths["process_kernel_width"],
        sensor_kernel_width=widths["sensor_kernel_width"],
        input_kernel_width=widths["input_kernel_width"],
        initial_state=initial_state,
        initial_state_std=initial_std,
    )


@dataclass(frozen=True)
class Log:
    """A CSV log: time [s] (N,), and named columns."""

    time: np.ndarray
    columns: dict[str, np.ndarray]
    path: str = ""

    @property
    def dt(self) -> float:
        """Mean sample time [s]."""
        return float((self.time[-1] - self.time[0]) / (len(self.time) - 1))

    def matrix(self, names) -> np.ndarray:
        """Columns ``names`` side by side as an (N, len(names)) array."""
        missing = [name for name in names if name not in self.columns]
        if missing:
            raise AttendInputError(
                f"{self.path}: CSV is missing the declared column{'s' if len(missing) > 1 else ''} "
                f"{', '.join(map(repr, missing))}; it has {', '.join(self.columns)}"
            )
        return np.column_stack([self.columns[name] for name in names]) if names else np.zeros((len(self.time), 0))


def read_log(path: str | Path, time_column: str = "t", *, relative_tolerance: float = 1e-4) -> Log:
    """Read a CSV log with a header; check the time column is present, finite and uniform.

    Time stamps count as uniform when every step is within ``relative_tolerance`` of the mean step.
    """
    path = Path(path)
    try:
        with path.open(newline="") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            rows = [row for row in reader if row]
    except FileNotFoundError:
        raise AttendInputError(f"log: {path} does not exist") from None
    if header is None:
        raise AttendInputError(f"{path}: the CSV is empty (expected a header row and samples)")
    header = [name.strip() for name in header]
    if not rows:
        raise AttendInputError(f"{path}: the CSV has a header but no samples")
    if time_column not in header:
        raise AttendInputError(f"{path}: CSV is missing the time column {time_column!r}; it has {', '.join(header)}")
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        for line, row in enumerate(rows, start=2):
            if len(row) != len(header):
                raise AttendInputError(f"{path}: line {line} has {len(row)} fields, the header has {len(header)}") from None
            for name, cell in zip(header, row):
                try:
                    float(cell)
                except ValueError:
                    raise AttendInputError(f"{path}: line {line}, column {name!r}: expected a number, got {cell!r}") from None
        raise
    columns = {name: values[:, j] for j, name in enumerate(header)}
    time = columns[time_column]
    require_finite(time, f"{path}: column {time_column!r}")
    if len(time) >= 2:
        steps = np.diff(time)
        mean_step = (time[-1] - time[0]) / (len(time) - 1)
        if mean_step <= 0:
            raise AttendInputError(f"{path}: column {time_column!r}: time stamps must increase")
        worst = int(np.argmax(np.abs(steps - mean_step)))
        if abs(steps[worst] - mean_step) > relative_tolerance * mean_step:
            raise AttendInputError(
                f"{path}: column {time_column!r}: non-uniform time stamps (step {steps[worst]:.6g} s at row "
                f"{worst + 2}, mean step {mean_step:.6g} s); resample the log to a uniform rate first"
            )
    return Log(time, columns, str(path))


def estimate_from_files(model: ModelFile, log: Log):
    """Run the model file's estimator on the log (checks columns, finiteness and sample time).

    Returns (estimator, estimate): a KalmanEstimator and its smoother estimate (method "kalman"),
    or a DEMObserver and its DEMEstimate (method "dem")."""
    if len(log.time) < 2:
        raise AttendInputError(f"{log.path}: expected at least 2 samples, got {len(log.time)}")
    dt = log.dt
    if model.dt is not None and abs(model.dt - dt) > 1e-4 * dt:
        raise AttendInputError(
            f"{model.path}: [model] dt = {model.dt} s but the log {log.path} is sampled every {dt:.6g} s"
        )
    outputs = log.matrix(model.output_columns)
    require_finite(outputs, f"{log.path}: output columns {', '.join(model.output_columns)}")
    signals = np.zeros((len(log.time), model.system.n_inputs))
    for j, spec in enumerate(model.inputs):
        if spec.known:
            column = log.matrix([spec.column])[:, 0]
            require_finite(column, f"{log.path}: input column {spec.column!r}")
            signals[:, j] = column - spec.operating_point
        else:
            signals[:, j] = spec.prior_mean
    observer = model.observer(dt)
    return observer, observer.estimate(outputs, signals)


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

    unknown = [spec.name for spec in model.inputs if not spec.known]
    if unknown:
        raise AttendInputError(
            f"{model.path}: identify needs measured inputs; input(s) {', '.join(map(repr, unknown))} have no column"
        )
    if len(log.time) < 2:
        raise AttendInputError(f"{log.path}: expected at least 2 samples, got {len(log.time)}")
    dt = log.dt
    if model.dt is not None and abs(model.dt - dt) > 1e-4 * dt:
        raise AttendInputError(f"{model.path}: [model] dt = {model.dt} s but the log {log.path} is sampled every {dt:.6g} s")
    outputs = log.matrix(model.output_columns)
    require_finite(outputs, f"{log.path}: output columns {', '.join(model.output_columns)}")
    inputs = np.column_stack([log.matrix([spec.column])[:, 0] - spec.operating_point for spec in model.inputs])
    require_finite(inputs, f"{log.path}: input columns")
    if not model.learning:
        raise AttendInputError(
            f"{model.path}: identify needs a [learning] section saying which entries to learn, e.g.\n"
            + LEARNING_EXAMPLE + "(see README.md, 'Identify your model')"
        )
    settings = dict(model.learning or {})
    options = {key: settings[key] for key in (
        "free", "free_prior_precision", "known_prior_precision", "noise_prior_mean", "noise_prior_precision",
        "max_iterations", "tolerance", "states", "top_order") if key in settings}
    if "noise_prior_mean" in options:
        options["noise_prior_mean"] = tuple(options["noise_prior_mean"])
    # [observer] embedding_order = "auto" (the default) picks the observer's order from its stability
    # analysis; learning has no such analysis and uses its own default p = 6 then
    order = 6 if model.embedding_order == "auto" else model.embedding_order
    return identify(model.system, outputs, inputs, dt, kernel_width=model.kernel_width,
                    embedding_order=order, input_order=model.input_order,
                    precision_convention=model.precision_convention, progress=progress, **options)


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
    data = tomllib.loads(Path(model.path).read_text()) if model.path else {}
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
