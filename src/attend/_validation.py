"""Input validation shared by the public constructors: errors name the field and what was expected."""

from __future__ import annotations

import numpy as np


class AttendInputError(ValueError):
    """Bad input to attend: the message names the field and the expected form."""


def as_matrix(value, field: str, *, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float64 2-D array, checking its shape."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise AttendInputError(f"{field}: expected a matrix of numbers ({error})") from None
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


def positive_scalar(value, field: str, unit: str = "") -> float:
    """A finite number > 0."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a number > 0{unit and ' ' + unit}, got {value!r}") from None
    if not np.isfinite(number) or number <= 0:
        raise AttendInputError(f"{field}: expected a finite number > 0{unit and ' (' + unit + ')'}, got {value!r}")
    return number


def order(value, field: str, maximum: int = 24) -> int:
    """A non-negative integer embedding order."""
    if isinstance(value, bool) or int(value) != value or not 0 <= int(value) <= maximum:
        raise AttendInputError(f"{field}: expected an integer in 0..{maximum}, got {value!r}")
    return int(value)


def symmetric_matrix(value, size: int, field: str, what: str = "precisions") -> np.ndarray:
    """A PSD matrix given as a scalar (times I), a vector (diagonal) or a symmetric matrix.

    ``what`` names the entries in the messages ("precisions", "variances").
    """
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a number, vector or matrix, got {value!r}") from None
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
    scale = max(1.0, float(np.abs(array).max()))
    if not np.allclose(array, array.T, rtol=1e-10, atol=1e-12 * scale):
        raise AttendInputError(f"{field}: expected a symmetric matrix")
    if np.linalg.eigvalsh(array).min() < -1e-12 * scale:
        raise AttendInputError(f"{field}: expected non-negative {what} (positive semi-definite)")
    return 0.5 * (array + array.T)


def precision_matrix(value, size: int, field: str) -> np.ndarray:
    """A precision given as a scalar (times I), a vector (diagonal) or a symmetric PSD matrix."""
    return symmetric_matrix(value, size, field, "precisions")
