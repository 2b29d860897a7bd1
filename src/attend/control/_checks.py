"""Validation shared by attend.control: errors name the field and the expected form."""

from __future__ import annotations

from typing import Callable

import numpy as np

from attend._validation import AttendInputError, as_matrix, numeric_array, precision_matrix


class ClosedLoopDivergence(AttendInputError):
    """The closed loop (world + agent) diverged: the message names the settings to change."""


def function(value, field: str, form: str) -> Callable:
    """``value`` if callable, else an error naming ``field`` and the expected ``form``."""
    if not callable(value):
        raise AttendInputError(f"{field}: expected a function {form}, got {type(value).__name__}")
    return value


def count(value, field: str, low: int = 0) -> int:
    """An integer >= ``low`` (booleans refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < low:
        raise AttendInputError(f"{field}: expected an integer >= {low}, got {value!r}")
    return int(value)


def vector(value, size: int, field: str, what: str = "numbers") -> np.ndarray:
    """A finite float64 vector of ``size`` entries (a scalar is broadcast)."""
    array = numeric_array(value, field, what)
    if array.ndim == 0:
        array = np.full(size, float(array))
    array = array.reshape(-1) if array.ndim == 2 and 1 in array.shape else array
    if array.ndim != 1 or array.shape[0] != size:
        raise AttendInputError(f"{field}: expected {size} {what}, got shape {np.shape(value)}")
    if not np.all(np.isfinite(array)):
        raise AttendInputError(f"{field}: expected finite {what}, got {array.tolist()}")
    return array


def evaluated(value, size: int, field: str) -> np.ndarray:
    """The output of a user function: a finite vector of ``size`` entries."""
    try:
        array = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected {size} numbers, got {value!r}") from None
    if array.shape[0] != size:
        raise AttendInputError(f"{field}: expected {size} values, got {array.shape[0]}")
    if not np.all(np.isfinite(array)):
        raise AttendInputError(f"{field}: returned non-finite values {array.tolist()}")
    return array


def jacobian_pair(value, rows: int, cols: tuple[int, int], field: str,
                  check_finite: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(d/dx, d/dv) returned by a user Jacobian: finite matrices of shapes (rows, cols[0]), (rows, cols[1]).
    check_finite: False leaves finiteness to the caller (shapes are still checked)."""
    try:
        first, second = value
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a pair (d/dx, d/dv) of matrices") from None
    return (_jacobian_part(first, rows, cols[0], field, "d/dx", check_finite),
            _jacobian_part(second, rows, cols[1], field, "d/dv", check_finite))


def _jacobian_part(part, rows: int, width: int, field: str, name: str, check_finite: bool) -> np.ndarray:
    """One matrix of a user Jacobian (reshaped when it holds rows * width values), checked finite."""
    array = np.asarray(part, dtype=float)
    if array.shape != (rows, width):
        if array.size == rows * width:
            array = array.reshape(rows, width)
        else:
            raise AttendInputError(f"{field}: expected {name} of shape {(rows, width)}, got {array.shape}")
    if check_finite and not np.isfinite(array).all():
        raise AttendInputError(f"{field}: {name} holds non-finite values")
    return array


def precision_value(value, size: int, field: str) -> np.ndarray:
    """A precision returned by a user function (vector: diagonal; matrix: symmetric), checked to be finite
    and positive definite; returns the (size, size) matrix."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected {size} precisions or a {size}x{size} matrix, got {value!r}") from None
    if not np.all(np.isfinite(array)):
        raise AttendInputError(f"{field}: returned non-finite precisions {array.tolist()}; expected finite values > 0")
    if array.ndim <= 1:
        array = np.broadcast_to(array, (size,)) if array.ndim == 0 or array.shape[0] == 1 else array
        if array.shape != (size,):
            raise AttendInputError(f"{field}: expected {size} precisions, got {array.shape[0]}")
        if np.any(array <= 0):
            raise AttendInputError(f"{field}: returned precisions {array.tolist()}; expected values > 0")
        return np.diag(array)
    matrix = precision_matrix(array, size, field)
    if np.linalg.eigvalsh(matrix).min() <= 0:
        raise AttendInputError(f"{field}: returned a precision matrix that is not positive definite")
    return matrix


def positive_precision(value, size: int, field: str) -> np.ndarray:
    """A constant precision (scalar, vector or matrix), positive definite."""
    matrix = precision_matrix(value, size, field)
    if size and np.linalg.eigvalsh(matrix).min() <= 0:
        raise AttendInputError(f"{field}: expected precisions > 0 (a positive definite matrix), got {np.diag(matrix).tolist()}")
    return matrix


def finite_difference(function_: Callable, point: np.ndarray, size: int) -> np.ndarray:
    """d function / d point (size, len(point)) by central differences, step eps^(1/3) max(1, |z|)."""
    point = np.asarray(point, dtype=float)
    out = np.empty((size, point.shape[0]))
    steps = np.cbrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(point))
    for j, h in enumerate(steps):
        up, down = point.copy(), point.copy()
        up[j] += h
        down[j] -= h
        out[:, j] = (np.asarray(function_(up), dtype=float).reshape(-1)
                     - np.asarray(function_(down), dtype=float).reshape(-1)) / (2 * h)
    return out


def linear_matrices(A, B, C, D=None, inputs_optional: bool = False):
    """(A, B, C, D) of dx/dt = A x + B u, y = C x + D u checked together: A (n, n), B (n, k),
    C (m, n), D (m, k) (None: zeros); inputs_optional: B may be None or empty (k = 0)."""
    A = as_matrix(A, "A")
    n = A.shape[0]
    if A.shape != (n, n):
        raise AttendInputError(f"A: expected a square matrix, got shape {A.shape}")
    if inputs_optional and (B is None or np.size(B) == 0):
        B = np.zeros((n, 0))
    else:
        B = as_matrix(B, "B", rows=n)
    C = as_matrix(C, "C", cols=n)
    k, m = B.shape[1], C.shape[0]
    D = np.zeros((m, k)) if D is None else as_matrix(D, "D", rows=m, cols=k)
    return A, B, C, D


def action_limits(value, k: int):
    """None, or (low, high) of k actions each, low < high elementwise; value: the pair given."""
    if value is None:
        return None
    try:
        low, high = value
    except (TypeError, ValueError):
        raise AttendInputError("action_limits: expected a pair (low, high)") from None
    low, high = vector(low, k, "action_limits low"), vector(high, k, "action_limits high")
    if np.any(low >= high):
        raise AttendInputError(f"action_limits: expected low < high, got {low.tolist()} and {high.tolist()}")
    return low, high
