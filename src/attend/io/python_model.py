"""Nonlinear model files: f and g from the user's Python file ([model] python), every call checked."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from attend._validation import AttendInputError, numeric_array, require_finite
from attend.io.fields import _read_text, _text
from attend.models.nonlinear import NonlinearSystem


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

    def with_parameters(self, parameters) -> "_UserFunction":
        """The same function of the same file, checked the same way, called with ``parameters``
        (a dict) as its third argument instead of this one's (path-mode learning replaces the
        learned entries)."""
        return _UserFunction(self.function, self.name, self.size, self.what, self.source, parameters)

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
        if _traced(value):  # backend="jax" traces f and g: only the shape is known here
            if value.size != self.size or value.ndim > 2:
                raise _UserShapeError(f"{self.source}: {self.name}(x, v) returned shape {value.shape}; expected "
                                      f"{self.size} values ({self.what})")
            return value.reshape(self.size)
        try:
            if value is None:
                raise TypeError("None")
            value = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise _UserShapeError(f"{self.source}: {self.name}(x, v) returned {type(value).__name__} "
                                   f"{_short(value)}; expected {self.size} numbers ({self.what})") from None
        if np.ndim(x) == 2:  # [model] vectorized = true: one column per point
            return self._columns(value, x, v)
        if value.shape != (self.size,):
            if value.size == self.size and value.ndim <= 2:
                value = value.reshape(self.size)
            else:
                raise _UserShapeError(
                    f"{self.source}: {self.name}(x, v) returned shape {value.shape}; expected {self.size} "
                    f"values ({self.what})")
        if not np.isfinite(value).all():  # (half the time of np.all(...): called for every sigma point)
            raise AttendInputError(
                f"{self.source}: {self.name}(x, v) returned non-finite values {_short(value)} at x = {_short(x)}, "
                f"v = {_short(v)}; expected finite numbers")
        return value

    def at_rows(self, x, v) -> np.ndarray:
        """The values at the points given as rows, x (P, n) and v (P, r): a float (P, size) array,
        the same as ``P`` calls of this function (:meth:`__call__`) with the same checks, but with one
        error state and one check of the shape and finiteness for all of them (the smoothers call f
        at every sigma point of every RK4 stage). Anything unusual (an exception in the user's code,
        a wrong shape, a non-finite value) is left to the one-at-a-time calls, which report it. A
        value is copied when it is returned unless it is an array that owns its memory (a function
        may fill and return the same buffer at every call: such a buffer, returned twice, sends all
        the points to the one-at-a-time calls)."""
        count = len(x)
        function, parameters = self.function, self.parameters
        try:
            with np.errstate(all="ignore"):
                if parameters is None:
                    values = [_owned(function(point, inputs)) for point, inputs in zip(x, v)]
                else:
                    values = [_owned(function(point, inputs, parameters)) for point, inputs in zip(x, v)]
                distinct = len({id(item) for item in values}) == count
                value = np.array(values, dtype=float) if distinct else None
        except Exception:  # noqa: BLE001 - reported below, by the calls one at a time
            value = None
        if value is not None and value.shape != (count, self.size) and value.ndim <= 3 and count \
                and value.shape[0] == count and value[0].size == self.size:
            value = value.reshape(count, self.size)  # as __call__ takes (size, 1), (1, size) or a scalar
        if value is not None and value.shape == (count, self.size) and np.isfinite(value).all():
            return value
        return np.array([np.array(self(point, inputs), dtype=float) for point, inputs in zip(x, v)],
                        dtype=float).reshape(count, self.size)

    def _columns(self, value: np.ndarray, x, v) -> np.ndarray:
        """The value at K points given as columns x (n, K), v (r, K): a finite (size, K) array."""
        count = x.shape[1]
        if value.shape != (self.size, count):
            raise _UserShapeError(
                f"{self.source}: {self.name}(x, v) returned shape {value.shape} for {count} points given as columns; "
                f"[model] vectorized = true expects ({self.size}, {count}), one column per point ({self.what})")
        bad = ~np.all(np.isfinite(value), axis=0)
        if bad.any():
            k = int(np.argmax(bad))
            raise AttendInputError(
                f"{self.source}: {self.name}(x, v) returned non-finite values {_short(value[:, k])} at x = "
                f"{_short(x[:, k])}, v = {_short(np.asarray(v)[:, k])}; expected finite numbers")
        return value


def _owned(value):
    """``value`` itself if it is an array that owns its memory (a fresh result: np.array(...), J @ x),
    else a float copy of it, made before the next call of the user's function could change it."""
    return value if type(value) is np.ndarray and value.base is None else np.array(value, dtype=float)


def _traced(value) -> bool:
    """True for a JAX tracer (f or g called while backend="jax" compiles the D-step)."""
    kind = type(value)
    return kind.__name__.endswith("Tracer") and kind.__module__.startswith("jax")


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
    vectorized = model.get("vectorized", False)
    if not isinstance(vectorized, bool):
        raise AttendInputError(f"{path}: [model] vectorized: expected true or false (f and g accept (n, K) columns, "
                               f"one point per column), got {vectorized!r}")
    try:
        return NonlinearSystem(f, g, n_states, n_inputs, n_outputs, state_names=state_names,
                               input_names=input_names, vectorized=vectorized)
    except AttendInputError as error:
        raise AttendInputError(f"{path}: [model] {error}") from None


def _probe_point(system: NonlinearSystem, initial_state, inputs) -> tuple[np.ndarray, np.ndarray]:
    """The point where f and g are tried: initial_state (or zeros), the inputs' operating points
    (measured) or prior means (unknown)."""
    x = np.zeros(system.n_states) if initial_state is None else np.array(initial_state, dtype=float)
    v = np.array([spec.operating_point if spec.known else spec.prior_mean for spec in inputs], dtype=float)
    return x, v


def _probe(system: NonlinearSystem, initial_state, inputs) -> None:
    """Call f and g once (at initial_state or zeros, the inputs' prior means or operating points):
    a wrong output shape is reported when the model is read. An exception or a non-finite value
    there is left for the estimate (the point may be outside the model's domain). With [model]
    vectorized = true, f and g at three points as columns must equal three single calls."""
    x, v = _probe_point(system, initial_state, inputs)
    for function in (system.f, system.g):
        try:
            value = function(x, v)
        except _UserShapeError:
            raise
        except AttendInputError:
            continue
        if system.vectorized:
            try:
                difference = _columns_difference(function, x, v, value)
            except _UserShapeError:
                raise
            except AttendInputError:
                continue
            if difference is not None:
                raise AttendInputError(
                    f"{function.source}: [model] vectorized = true, but {function.name}(x, v) at 3 points given as "
                    f"columns differs from 3 calls at one point each (largest difference {difference:.3g}); write "
                    "it with x[0], x[1], ... so that each column is one point, or remove vectorized")


def _columns_difference(function, x, v, value) -> float | None:
    """The largest difference between ``function`` at three points near (x, v) given as columns and
    at each point alone (``value``: its value at (x, v)), or None where they agree to 1e-9
    relative."""
    shifts = np.array([0.0, 0.01, -0.02])
    xs = x[:, None] + shifts * (1.0 + np.abs(x))[:, None]
    vs = np.repeat(v[:, None], 3, axis=1)
    together = function(xs, vs)
    separately = np.column_stack([value] + [function(xs[:, k], v) for k in (1, 2)])
    difference = float(np.max(np.abs(together - separately)))
    return None if difference <= 1e-9 * (1.0 + np.max(np.abs(value))) else difference


def takes_columns(system: NonlinearSystem, initial_state, inputs) -> bool:
    """Whether the model file's f and g (``system``, not declared vectorized) already give the right
    values for points given as columns, so that [model] vectorized = true could be suggested;
    initial_state, inputs: the model file's (where f and g are tried)."""
    x, v = _probe_point(system, initial_state, inputs)
    for function in (system.f, system.g):
        try:
            value = function(x, v)
            with np.errstate(all="ignore"):
                if _columns_difference(function, x, v, value) is not None:
                    return False
        except Exception:  # noqa: BLE001 - any failure with columns: not column-safe
            return False
    return True
