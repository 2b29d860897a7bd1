"""Small dense linear algebra of the nonlinear D-step, lean enough to run once per sample.

The matrices are ~20-60 rows, so NumPy's and SciPy's per-call checks cost more than the
arithmetic; these helpers give the same numbers as the general routines with fewer calls.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import bandwidth, expm
from scipy.linalg.blas import dgemm

try:  # SciPy's own Pade kernels (scipy.linalg.expm calls them); absent in other SciPy versions
    from scipy.linalg._matfuncs_expm import pade_UV_calc, pick_pade_structure
except ImportError:  # pragma: no cover - depends on the installed SciPy
    pade_UV_calc = pick_pade_structure = None


def diagonal_blocks(block, rows: int, cols: int) -> np.ndarray:
    """kron(eye(rows, cols), block) without the multiplications: ``block`` on the first
    min(rows, cols) diagonal places of a rows x cols grid of blocks (4x faster than np.kron).

    block: (a, b) matrix; rows, cols: the number of block rows and block columns."""
    a, b = block.shape
    if a == 0 or b == 0:
        return np.zeros((rows * a, cols * b))
    out = np.zeros((rows, a, cols, b))
    places = np.arange(min(rows, cols))
    out[places, :, places, :] = block
    return out.reshape(rows * a, cols * b)


def block_diagonal_positions(shape: tuple, row0: int, col0: int, block: tuple, count: int) -> np.ndarray:
    """Flat indices (count, a, b) into a C-ordered array of ``shape`` of ``count`` blocks of
    ``block`` = (a, b) on a block diagonal starting at (row0, col0): the places that
    kron(eye(count), J) fills, so that ``flat[indices] = J`` writes all of them in one call.

    shape: (rows, cols) of the whole matrix; row0, col0: top-left corner of the first block;
    block: (a, b) size of one block; count: how many blocks."""
    a, b = block
    k = np.arange(count)[:, None, None]
    rows = row0 + k * a + np.arange(a)[None, :, None]
    cols = col0 + k * b + np.arange(b)[None, None, :]
    return rows * shape[1] + cols


def jacobi_scaling(matrix) -> np.ndarray:
    """1 / sqrt|diag(matrix)| (1 where the diagonal is 0). matrix: square."""
    diagonal = np.sqrt(np.abs(np.diag(matrix)))
    return np.where(diagonal > 0, 1.0 / np.where(diagonal > 0, diagonal, 1.0), 1.0)


def scaled_solve(matrix, vector):
    """inv(matrix) vector with Jacobi scaling (units of the coordinates may differ by 1e12); a
    LinAlgError where the scaled system is not finite.

    matrix: square (k, k); vector: (k,)."""
    d = jacobi_scaling(matrix)
    with np.errstate(over="ignore", invalid="ignore"):
        scaled, right = matrix * np.outer(d, d), vector * d
    if not (np.all(np.isfinite(scaled)) and np.all(np.isfinite(right))):  # LAPACK would print and return NaN
        raise np.linalg.LinAlgError("scaled_solve: the scaled system is not finite (diagonal entries near 0 or "
                                    "beyond the floating-point range)")
    return d * np.linalg.lstsq(scaled, right, rcond=None)[0]


def inverse_diagonals(matrices, indices) -> np.ndarray:
    """diag(inv(M))[indices] of each M in a stack.

    For positive definite M (the Gauss-Newton curvature E' Pi E), by Cholesky with the wanted
    coordinates ordered last: P' M P = L L', and the trailing block of inv(L) is inv(L_t) of L's
    trailing block L_t, so [inv(M)]_jj = sum_i inv(L_t)_ij^2 (no full inverse; Cholesky's error is
    relative to sqrt(M_ii M_jj), so the units of the coordinates, which may differ by 1e12, do not
    matter). Otherwise (a stack with a singular or indefinite M) with Jacobi scaling,
    d_i^2 [inv(D M D)]_ii with D = diag(d), d = 1 / sqrt|diag(M)|, by the inverse, or the
    pseudo-inverse of a singular D M D. matrices: (K, k, k) symmetric matrices; indices: integer
    array of the diagonal entries wanted. Returns (K, len(indices))."""
    indices = np.asarray(indices, dtype=int)
    others = np.ones(matrices.shape[1], dtype=bool)
    others[indices] = False
    last = np.concatenate([np.flatnonzero(others), indices])
    try:
        factor = np.linalg.cholesky(matrices[:, last[:, None], last])
        trailing = np.linalg.inv(factor[:, -len(indices):, -len(indices):])
        return (trailing * trailing).sum(axis=1)
    except np.linalg.LinAlgError:
        pass
    diagonal = np.sqrt(np.abs(np.diagonal(matrices, axis1=1, axis2=2)))
    d = np.where(diagonal > 0, 1.0 / np.where(diagonal > 0, diagonal, 1.0), 1.0)
    scaled = matrices * (d[:, :, None] * d[:, None, :])
    try:
        inverses = np.linalg.inv(scaled)
    except np.linalg.LinAlgError:
        inverses = np.array([_inverse_or_pseudo(matrix) for matrix in scaled])
    return np.diagonal(inverses, axis1=1, axis2=2)[:, indices] * (d * d)[:, indices]


def _inverse_or_pseudo(matrix) -> np.ndarray:
    try:
        return np.linalg.inv(matrix)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(matrix)


def _surely_not_triangular(matrix) -> bool:
    """True when ``matrix`` has nonzeros on both sides of its diagonal (cheap test on the first
    row and column, else scipy.linalg.bandwidth). matrix: square."""
    if matrix[1, 0] != 0 and matrix[0, 1] != 0:  # the common case, without array calls
        return True
    if matrix[1:, 0].any() and matrix[0, 1:].any():
        return True
    lower, upper = bandwidth(matrix)
    return lower > 0 and upper > 0


def _pade_last_column(work, squaring):
    """expm(block)[:-1, -1] by SciPy's Pade kernels (the steps of scipy.linalg.expm for a general
    matrix), or None if they report a failure. work: (5, k, k) scratch with the block (square,
    not triangular) in work[0]; overwritten. squaring: "dgemm" or "matmul" (below).

    "dgemm": the squarings A <- A A run on the transpose, (A A)' = A' A', which is Fortran-ordered,
    so SciPy's BLAS dgemm takes it without copies (the fastest call); "matmul": NumPy's A @ A, as
    scipy.linalg.expm squares (the same numbers where NumPy and SciPy share a BLAS kernel)."""
    order, squarings = pick_pade_structure(work)
    if order < 0 or pade_UV_calc(work, order) != 0:
        return None
    if squarings == 0:
        return work[0][:-1, -1].copy()
    if squaring == "matmul":
        result = work[0]
        for _ in range(squarings):  # all full products: the column alone would round differently
            result = result @ result
        return result[:-1, -1]
    transposed = work[0].T
    for _ in range(squarings):
        transposed = dgemm(1.0, transposed, transposed)
    return transposed[-1, :-1]  # a view of a new array: no copy


# the fast route is checked once against scipy.linalg.expm: dgemm squarings, else NumPy's, else none
_fast_path = {"checked": False, "usable": pick_pade_structure is not None, "squaring": "dgemm"}


def _checked_column(block, work):
    """The first use: the fast route's column if it equals scipy.linalg.expm's to the bit with
    either squaring (kept for later calls), else scipy.linalg.expm's. block, work: as below."""
    _fast_path["checked"] = True
    reference = expm(block)[:-1, -1]
    for squaring in ("dgemm", "matmul"):
        work[0] = block
        try:
            column = _pade_last_column(work, squaring)
        except (TypeError, ValueError):  # pragma: no cover - another SciPy's private signature
            column = None
        if column is not None and np.array_equal(column, reference, equal_nan=True):
            _fast_path["squaring"] = squaring
            return column
    _fast_path["usable"] = False
    return reference


def expm_last_column(block, work=None) -> np.ndarray:
    """expm(block)[:-1, -1], as scipy.linalg.expm computes it (the same Pade approximant and
    scaling, Al-Mohy & Higham 2009), without its per-call overhead when ``block`` is a general
    (not triangular) matrix; otherwise by scipy.linalg.expm itself. The first use compares the
    two on its block and keeps scipy.linalg.expm if they differ (another SciPy version or BLAS).

    block: square (k + 1, k + 1), the augmented matrix [[J dt, b dt], [0, 0]]; its last column of
    the exponential is (expm(J dt) - I) inv(J) b. work: optional (5, k + 1, k + 1) scratch reused
    between calls (overwritten; ``block`` is not)."""
    if not _fast_path["usable"] or not _surely_not_triangular(block):
        return expm(block)[:-1, -1]
    if work is None:
        work = np.empty((5,) + block.shape)
    if not _fast_path["checked"]:
        return _checked_column(block, work)
    work[0] = block
    column = _pade_last_column(work, _fast_path["squaring"])
    return expm(block)[:-1, -1] if column is None else column
