"""Input validation shared by the public constructors: errors name the field and what was expected."""

from __future__ import annotations

from numbers import Real

import numpy as np


class AttendInputError(ValueError):
    """Bad input to attend: the message names the field and the expected form."""


#: Magnitude above which a value in a model file or log is taken for a corrupt entry: products
#: of two such values overflow float64 (1e308), so estimates would be inf or nonsense.
LARGEST_MAGNITUDE = 1e150


def numeric_array(value, field: str, what: str = "numbers") -> np.ndarray:
    """``value`` as a float64 array; text, booleans and ragged nesting are errors, not coerced."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        raise AttendInputError(f"{field}: expected {what} in rows of equal length, got {_short(value)}") from None
    if isinstance(value, (list, tuple, str, bytes, bool, np.bool_)) or raw.dtype.kind in "USOb":
        for item in _flatten(value):
            if isinstance(item, (str, bytes, bool, np.bool_, np.str_)):
                raise AttendInputError(f"{field}: expected {what}, got {_short(item)} (text and true/false are not numbers)")
            if not isinstance(item, Real):
                raise AttendInputError(f"{field}: expected {what}, got {_short(item)}")
    elif raw.dtype.kind not in "iuf":
        raise AttendInputError(f"{field}: expected {what}, got an array of {raw.dtype}")
    try:
        return np.array(raw, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise AttendInputError(f"{field}: expected {what}, got {_short(value)}") from None


def _flatten(value):
    if isinstance(value, np.ndarray) and value.dtype.kind in "iuf":
        return
    if isinstance(value, (list, tuple, np.ndarray)):
        for item in value:
            yield from _flatten(item)
    else:
        yield value


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def number(value, field: str) -> float:
    """One real number (int or float); text and booleans are errors."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real):
        raise AttendInputError(f"{field}: expected a number, got {_short(value)}")
    return float(value)


def require_moderate(array: np.ndarray, field: str, limit: float = LARGEST_MAGNITUDE) -> None:
    """Raise if ``array`` holds a value beyond +-``limit``, naming the first one."""
    huge = np.abs(array) > limit
    if huge.any():
        index = tuple(int(i) for i in np.argwhere(huge)[0])
        raise AttendInputError(
            f"{field}: expected values within +-{limit:.0e}, found {array[index]:.6g} at index {index}"
        )


def unique_names(names, field: str) -> tuple[str, ...]:
    """Names as a tuple of non-empty strings without repeats."""
    names = tuple(names)
    for name in names:
        if not isinstance(name, str) or not name.strip():
            raise AttendInputError(f"{field}: expected non-empty names (text), got {_short(name)}")
    seen = set()
    for name in names:
        if name in seen:
            raise AttendInputError(f"{field}: the name {name!r} appears twice; names must be unique")
        seen.add(name)
    return names


def as_matrix(value, field: str, *, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float64 2-D array, checking its shape."""
    array = numeric_array(value, field, "a matrix of numbers")
    if array.ndim == 1 and cols == 1:
        array = array[:, None]
    if array.ndim == 1 and rows == 1:
        array = array[None, :]
    if array.ndim != 2:
        raise AttendInputError(f"{field}: expected a 2-D matrix, got an array of shape {array.shape}")
    if rows is not None and array.shape[0] != rows:
        raise AttendInputError(
            f"{field}: expected {rows} rows, got shape {array.shape}"
        )
    if cols is not None and array.shape[1] != cols:
        raise AttendInputError(
            f"{field}: expected {cols} columns, got shape {array.shape}"
        )
    require_finite(array, field)
    return array


def require_finite(array: np.ndarray, field: str) -> None:
    """Raise if ``array`` holds NaN or inf, naming the first bad index."""
    bad = ~np.isfinite(array)
    if bad.any():
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        raise AttendInputError(
            f"{field}: expected finite numbers, found {array[index]} at index {index}"
        )


def stream_sample(output, input_value, n_outputs: int, n_inputs: int) -> tuple[np.ndarray, np.ndarray]:
    """One sample fed to an online estimator's ``step``: (y (m,), u (r,)) as float arrays, u zero
    when input_value is None; wrong counts or text raise, naming both expected counts (finiteness
    is the caller's rule: some estimators take NaN for a missing output)."""
    m, r = int(n_outputs), int(n_inputs)
    try:
        y = np.asarray(output, dtype=float).reshape(-1)
        u = np.zeros(r) if input_value is None else np.asarray(input_value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise AttendInputError(f"step: expected {m} output numbers and {r} input numbers") from None
    if y.shape != (m,) or u.shape != (r,):
        raise AttendInputError(f"step: expected {m} outputs and {r} inputs, got {y.shape[0]} and {u.shape[0]}")
    return y, u


def positive_scalar(value, field: str, unit: str = "") -> float:
    """A finite number > 0 (text is an error, not converted)."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real):
        raise AttendInputError(f"{field}: expected a number > 0{unit and ' (' + unit + ')'}, got {_short(value)}")
    number = float(value)
    if not np.isfinite(number) or number <= 0:
        raise AttendInputError(f"{field}: expected a finite number > 0{unit and ' (' + unit + ')'}, got {value!r}")
    return number


def kernel_width(value, field: str) -> float:
    """A noise kernel width >= 0 [s] (0: white noise)."""
    if isinstance(value, bool):
        raise AttendInputError(f"{field}: expected a number >= 0 (s; 0 for white noise), got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a number >= 0 (s; 0 for white noise), got {value!r}") from None
    if not np.isfinite(number) or number < 0:
        raise AttendInputError(f"{field}: expected a finite number >= 0 (s; 0 for white noise), got {value!r}")
    return number


def order(value, field: str, maximum: int = 24) -> int:
    """A non-negative integer embedding order."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, Real)
            or not np.isfinite(value) or int(value) != value or not 0 <= int(value) <= maximum):
        raise AttendInputError(f"{field}: expected an integer in 0..{maximum}, got {value!r}")
    return int(value)


def symmetric_matrix(value, size: int, field: str, what: str = "precisions") -> np.ndarray:
    """A PSD matrix given as a scalar (times I), a vector (diagonal) or a symmetric matrix.

    ``what`` names the entries in the messages ("precisions", "variances").
    """
    array = numeric_array(value, field, f"a number, vector or matrix of {what}")
    if not np.all(np.isfinite(array)):
        raise AttendInputError(f"{field}: expected finite {what}, got {value!r}")
    if array.ndim == 0:
        array = array * np.eye(size)
    elif array.ndim == 1:
        if array.shape[0] != size:
            raise AttendInputError(f"{field}: expected {size} diagonal entries, got {array.shape[0]}")
        array = np.diag(array)
    elif array.shape != (size, size):
        raise AttendInputError(f"{field}: expected a {size}x{size} matrix, got shape {array.shape}")
    if size == 0:  # nothing to check: e.g. the precision of zero causes
        return np.zeros((0, 0))
    scale = max(1.0, float(np.abs(array).max()))
    if not np.allclose(array, array.T, rtol=1e-10, atol=1e-12 * scale):
        raise AttendInputError(f"{field}: expected a symmetric matrix")
    if np.linalg.eigvalsh(array).min() < -1e-12 * scale:
        raise AttendInputError(f"{field}: expected non-negative {what} (positive semi-definite)")
    return 0.5 * (array + array.T)


def precision_matrix(value, size: int, field: str) -> np.ndarray:
    """A precision given as a scalar (times I), a vector (diagonal) or a symmetric PSD matrix."""
    return symmetric_matrix(value, size, field, "precisions")
