"""The parameter vector theta = [vec(A); vec(B); vec(C)] (row-major) and its maps to and from
(A, B, C): names, per-entry masks and the learner's internal order [vec([A B]); vec(C)]."""

from __future__ import annotations

from typing import Iterable

import numpy as np

from attend._validation import AttendInputError
from attend.models.linear import LinearSystem


def parameter_names(system: LinearSystem) -> tuple[str, ...]:
    """Names of theta = [vec(A); vec(B); vec(C)] of the system (row-major, 1-based): 'A[2,1]', ..."""
    names = []
    for label, matrix in (("A", system.A), ("B", system.B), ("C", system.C)):
        rows, cols = matrix.shape
        names += [f"{label}[{i + 1},{j + 1}]" for i in range(rows) for j in range(cols)]
    return tuple(names)


def parameter_vector(system: LinearSystem) -> np.ndarray:
    """theta = [vec(A); vec(B); vec(C)] of the system, row-major (the paper's theta_1 .. theta_8 for eq. 2)."""
    return np.concatenate([system.A.ravel(), system.B.ravel(), system.C.ravel()])


def system_from_parameters(theta, like: LinearSystem) -> LinearSystem:
    """The LinearSystem whose (A, B, C) are the entries of theta, labels copied from ``like``."""
    n, r, m = like.n_states, like.n_inputs, like.n_outputs
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (n * n + n * r + m * n,):
        raise AttendInputError(f"theta: expected {n * n + n * r + m * n} entries, got shape {theta.shape}")
    return LinearSystem(
        A=theta[: n * n].reshape(n, n),
        B=theta[n * n: n * n + n * r].reshape(n, r),
        C=theta[n * n + n * r:].reshape(m, n),
        state_names=like.state_names,
        input_names=like.input_names,
        output_names=like.output_names,
    )


def internal_parameter_order(n: int, r: int, m: int) -> np.ndarray:
    """Index map public theta -> internal [vec([A B]); vec(C)] (row-major over [A B]) for n states,
    r inputs and m outputs."""
    index = []
    for a in range(n):
        index += [a * n + b for b in range(n)]
        index += [n * n + a * r + k for k in range(r)]
    index += list(range(n * n + n * r, n * n + n * r + m * n))
    return np.array(index, dtype=int)


def parameter_array(value, system: LinearSystem, field_name: str, dtype=bool, default=None) -> np.ndarray:
    """A per-entry array over theta of ``system`` from ``value``: None (gives ``default``), a
    vector, a dict {"A": ..., "B": ..., "C": ...} (missing matrices from ``default``), or (for
    masks, dtype bool) an iterable of parameter names. field_name: the argument's name in errors;
    dtype: bool for masks, float for values."""
    names = parameter_names(system)
    size = len(names)
    if value is None:
        return default
    if isinstance(value, dict):
        unknown = set(value) - {"A", "B", "C"}
        if unknown:
            raise AttendInputError(f"{field_name}: expected keys 'A', 'B', 'C', got {sorted(unknown)}")
        parts = []
        for label, matrix in (("A", system.A), ("B", system.B), ("C", system.C)):
            if label in value:
                part = np.broadcast_to(np.asarray(value[label], dtype=dtype), matrix.shape)
            else:
                part = np.broadcast_to(default.reshape(-1)[parameter_slice(system, label)].reshape(matrix.shape), matrix.shape)
            parts.append(np.asarray(part, dtype=dtype).ravel())
        return np.concatenate(parts)
    if dtype is bool and not isinstance(value, np.ndarray) and isinstance(value, Iterable) \
            and all(isinstance(v, str) for v in value):
        mask = np.zeros(size, dtype=bool)
        for v in value:
            if v not in names:
                raise AttendInputError(f"{field_name}: unknown parameter {v!r}; expected names like {names[:3]}")
            mask[names.index(v)] = True
        return mask
    try:
        array = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field_name}: expected {size} values, a dict of A/B/C matrices or names") from None
    if array.ndim == 0 and dtype is not bool:
        return np.full(size, float(array))
    if array.shape != (size,):
        raise AttendInputError(f"{field_name}: expected {size} entries ({', '.join(names)}), got shape {array.shape}")
    return array


def parameter_slice(system: LinearSystem, label: str) -> slice:
    """The slice of theta holding the entries of matrix ``label`` ("A", "B" or "C") of ``system``."""
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    return {"A": slice(0, n * n), "B": slice(n * n, n * n + n * r), "C": slice(n * n + n * r, n * n + n * r + m * n)}[label]
