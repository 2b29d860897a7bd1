"""The local-linearisation step's exponential: the last column of expm(A) for A = [[B, c], [0, 0]] (in a preallocated
workspace, no validation), which is [phi_1(B) c; 1] with phi_1(B) = (expm(B) - I) inv(B).

Truncated Taylor series T_m with scaling and squaring, expm(A) = T_m(A / 2^s)^(2^s):

- Degree and accuracy. T_m(X) = expm(X) (I + E) with E = -expm(-X) sum_(j>m) X^j / j!, so T_m(X) = expm(X + dX), dX =
  log(I + E) (X and E commute), and |dX| / |X| <= e^theta sum_(j>m) theta^(j-1) / j! for |X|_1 <= theta. theta_m is
  the largest theta for which that bound is at most the unit roundoff u = 2^-53: squaring keeps the relative backward
  error, expm(A) computed = expm(A + dA) with |dA|_1 <= u |A|_1 (before rounding in the products), the guarantee of
  scipy.linalg.expm's Pade approximant. (theta_m: 2.4e-3 for m = 5, 1.25 for m = 19, 3.29 for m = 29.)
- Evaluation. Paterson-Stockmeyer: with q powers I, X, ..., X^(q-1) and Y = X^q, T_m(X) = sum_k C_k Y^k (m = q (K + 1)
  - 1, C_k = sum_(i<q) X^i / (k q + i)!), by Horner in Y: q - 1 + K products. For |A|_1 <= theta_29 the lowest
  degree whose theta_m covers it (s = 0; a lower degree with squarings costs no fewer products); above, m = 29
  (9 products) and s = ceil(log2(|A|_1 / theta_29)) squarings, which costs no more products than any other degree
  (|A|_1 = 200: 9 + 6; m = 19: 7 + 8; Pade 13: 6 + 6 and a solve).
- The column c enters the result linearly (phi_1(B) c): it is scaled by a power of two (exact) to a 1-norm no larger
  than B's before |A|_1 is taken, so that a large flow does not add squarings.
- Only the last column is formed in the last squaring (a product with a vector). Products of the small dense
  matrices go to BLAS dgemm directly (on the transposes of C-ordered arrays: no copies), cheaper than numpy's matmul
  at this size.
"""

from __future__ import annotations

import bisect
import math

import numpy as np
from scipy.linalg.blas import dgemm

UNIT_ROUNDOFF = 2.0**-53


def taylor_backward_error_bound(theta: float, degree: int) -> float:
    """e^theta sum_(j > degree) theta^(j - 1) / j!: the bound on |dX| / |X| of T_degree(X) = expm(X + dX) for
    |X|_1 = theta."""
    total, term = 0.0, theta**degree / math.factorial(degree + 1)  # theta^(j-1) / j! at j = degree + 1
    j = degree + 1
    while term > 1e-30 * max(total, 1e-300):
        total += term
        term *= theta / (j + 1)
        j += 1
    return math.exp(theta) * total


def taylor_theta(degree: int, tolerance: float = UNIT_ROUNDOFF) -> float:
    """The largest theta with :func:`taylor_backward_error_bound` (theta, degree) <= tolerance (bisection)."""
    low, high = 0.0, 64.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        if taylor_backward_error_bound(middle, degree) <= tolerance:
            low = middle
        else:
            high = middle
    return low


def _plans() -> list[tuple[float, int, int, np.ndarray]]:
    """(theta_m, q, K, C) per Paterson-Stockmeyer scheme, by increasing degree m = q (K + 1) - 1;
    C[k, i] = 1 / (k q + i)!, the coefficient of X^i in C_k."""
    plans = []
    for q, K in ((2, 1), (2, 2), (3, 2), (3, 3), (4, 3), (4, 4), (5, 4), (5, 5)):  # m = 3, 5, 8, 11, 15, 19, 24, 29
        coefficients = np.array([[1.0 / math.factorial(k * q + i) for i in range(q)] for k in range(K + 1)])
        plans.append((taylor_theta(q * (K + 1) - 1), q, K, coefficients))
    return plans


_PLANS = _plans()
_THETAS = [plan[0] for plan in _PLANS]
_LOG2_LARGEST_THETA = math.log2(_THETAS[-1])


class AugmentedExponential:
    """expm(A)[:, -1] for (size, size) matrices A = [[B, c], [0, 0]], in a preallocated workspace (one per size)."""

    def __init__(self, size: int):
        q_max = max(plan[1] for plan in _PLANS)
        K_max = max(plan[2] for plan in _PLANS)
        self.size = size
        self._powers = np.empty((q_max + 1, size, size))  # I, X, X^2, ..., X^q
        self._powers[0] = np.eye(size)
        self._blocks = np.empty((K_max + 1, size, size))  # C_0 .. C_K
        self._squares = np.empty((2, size, size))
        self._scales = np.empty(size)

    def last_column(self, A: np.ndarray) -> np.ndarray:
        """expm(A)[:, -1] (size,) for A (size, size) C-ordered whose last row is zero: [phi_1(B) c; 1]; None when A
        holds non-finite values."""
        sums = np.abs(A).sum(axis=0)
        norm = float(sums[:-1].max())
        norm_c = float(sums[-1])
        if not (math.isfinite(norm) and math.isfinite(norm_c)):
            return None
        shift = 0  # c / 2^shift: a 1-norm no larger than max(|B|_1, 1)
        if norm_c > max(norm, 1.0):
            shift = math.ceil(math.log2(norm_c / max(norm, 1.0)))
            norm_c = math.ldexp(norm_c, -shift)
        norm = max(norm, norm_c)
        index = bisect.bisect_left(_THETAS, norm)
        if index < len(_PLANS):
            squarings = 0
            _, q, K, coefficients = _PLANS[index]
        else:
            squarings = max(0, math.ceil(math.log2(norm) - _LOG2_LARGEST_THETA))
            _, q, K, coefficients = _PLANS[-1]
        powers = self._powers
        X = powers[1]
        scales = self._scales
        scales.fill(math.ldexp(1.0, -squarings))
        if shift:
            scales[-1] = math.ldexp(1.0, -squarings - shift)
        np.multiply(A, scales, out=X)  # X = A / 2^s, its last column also / 2^shift
        for i in range(2, q + 1):  # X^i = X^(i-1) X  (dgemm on transposes: (X^(i-1) X)' = X' X^(i-1)')
            dgemm(1.0, X.T, powers[i - 1].T, 0.0, powers[i].T, overwrite_c=1)
        Y = powers[q]
        blocks = self._blocks[: K + 1]
        np.dot(coefficients, powers[:q].reshape(q, -1), out=blocks.reshape(K + 1, -1))
        R = blocks[K]
        for k in range(K - 1, -1, -1):  # Horner in Y: R <- R Y + C_k (written over C_k)
            dgemm(1.0, Y.T, R.T, 1.0, blocks[k].T, overwrite_c=1)
            R = blocks[k]
        if squarings:
            for j in range(squarings - 1):
                square = self._squares[j % 2]
                dgemm(1.0, R.T, R.T, 0.0, square.T, overwrite_c=1)
                R = square
            column = R @ R[:, -1]
        else:
            column = R[:, -1].copy()
        if shift:
            column *= math.ldexp(1.0, shift)
            column[-1] = 1.0
        return column
