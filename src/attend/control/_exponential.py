"""The control step's exponentials (no validation): the local-linearisation step's, the last column of expm(A) for
A = [[B, c], [0, 0]] (in a preallocated workspace), which is [phi_1(B) c; 1] with phi_1(B) = (expm(B) - I) inv(B); and
the exact step of a linear flow, expm(J dt) and its integral (:func:`exponential_and_integral`, at the end).

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

The exact step of a linear flow (:func:`exponential_and_integral`): (expm(B), int_0^dt expm(J t) dt) for B = J dt, the
blocks of expm(A) for A = [[B, dt I], [0, 0]], from N x N products instead of 2N x 2N ones:

- Taylor. T_m(A) = [[I + X r(X), h r(X)], [0, I]] for A / 2^s = [[X, h I], [0, 0]] (h = dt / 2^s), with
  r(X) = sum_(j<m) X^j / (j + 1)!, the series of phi_1 to degree m - 1: one Paterson-Stockmeyer evaluation of r (the
  q and K of T_m, its top coefficient zero), then one product. The identity block enters linearly (scaled to a
  1-norm no larger than |B|_1, nothing computed changes but the final scale), so m and s are chosen from |B|_1 as
  above, with the same backward error u |A|_1.
- Squaring E - I. [[E, F], [0, I]]^2 = [[E^2, (I + E) F], [0, I]]; with H = (E - I) + 2 I, E^2 - I = H (E - I) and
  (I + E) F = H F: one product per squaring, [E - I, F] <- (E - I) [E - I, F] + 2 [E - I, F] (N x N times N x 2N,
  one dgemm on column-major arrays). A stiff J needs many squarings (|J dt|_1 = 1.3e9 on the two-link arm: s = 29).
  Squaring E itself, as scipy.linalg.expm does with the 2N x 2N block, keeps a slow mode's E_0 = 1 + x / 2^s only to
  u, and s squarings raise that relative error to 2^s u (6e-8 at s = 29; measured 2e-8 against a 60-digit mpmath
  exponential of the arm's block). E - I keeps the slow modes' increments to their own relative rounding (measured
  3e-10 there, the condition of the data: one ulp in J's entries moves E by 2e-10 to 1e-9). A mode that decays
  within dt keeps u of max(1, |E|) rather than u of its own size; both within the backward error u |A|_1.
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


def _phi_coefficients(q: int, K: int) -> np.ndarray:
    """C[k, i] = 1 / (k q + i + 1)!, the coefficient of X^i in C_k of r(X) = sum_(j<m) X^j / (j + 1)!, m = q (K + 1) - 1
    (the top one, j = m, zero): T_m's top-right block h r(X) by the same Paterson-Stockmeyer scheme as T_m."""
    degree = q * (K + 1) - 1
    return np.array([[1.0 / math.factorial(k * q + i + 1) if k * q + i < degree else 0.0 for i in range(q)]
                     for k in range(K + 1)])


_PHI_COEFFICIENTS = [_phi_coefficients(q, K) for _, q, K, _ in _PLANS]


def _scaling(norm: float) -> tuple[int, int]:
    """(plan index, s): the lowest degree whose theta_m covers |A|_1 = norm (s = 0), else the largest with
    s = ceil(log2(norm / theta_29)) squarings."""
    index = bisect.bisect_left(_THETAS, norm)
    if index < len(_PLANS):
        return index, 0
    return len(_PLANS) - 1, max(0, math.ceil(math.log2(norm) - _LOG2_LARGEST_THETA))


def exponential_and_integral(J: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(E, F) = (expm(J dt), int_0^dt expm(J t) dt) for J (N, N), the blocks of expm([[J, I], [0, 0]] dt) (the exact
    step of dZ/dt = J Z + c, c held: Z+ = E Z + F c), by Taylor series with scaling and squaring on N x N blocks::

        X = J dt / 2^s,   E_0 - I = X r(X),   F_0 = (dt / 2^s) r(X),   r(X) = sum_(j<m) X^j / (j + 1)!
        [E_(i+1) - I, F_(i+1)] = H_i [E_i - I, F_i],   H_i = (E_i - I) + 2 I   (i = 0 .. s - 1)

    (module docstring: degree, accuracy, why E - I is squared). E and F are column-major views of one (N, 2N) array;
    NaN-filled when J dt is not finite."""
    N = J.shape[0]
    X = np.multiply(J, dt)
    norm = float(np.abs(X).sum(axis=0).max(initial=0.0))
    if not math.isfinite(norm):
        return np.full((N, N), np.nan), np.full((N, N), np.nan)
    index, squarings = _scaling(norm)
    _, q, K, _ = _PLANS[index]
    coefficients = _PHI_COEFFICIENTS[index]
    X *= math.ldexp(1.0, -squarings)
    powers = np.empty((q + 1, N, N))  # I, X, X^2, ..., X^q
    powers[0] = np.eye(N)
    powers[1] = X
    for i in range(2, q + 1):  # X^i = X^(i-1) X (dgemm on transposes, as in AugmentedExponential)
        dgemm(1.0, X.T, powers[i - 1].T, 0.0, powers[i].T, overwrite_c=1)
    Y = powers[q]
    blocks = np.dot(coefficients, powers[:q].reshape(q, -1)).reshape(K + 1, N, N)
    R = blocks[K]
    for k in range(K - 1, -1, -1):  # Horner in Y: R <- R Y + C_k (written over C_k)
        dgemm(1.0, Y.T, R.T, 1.0, blocks[k].T, overwrite_c=1)
        R = blocks[k]
    W = np.empty((N, 2 * N), order="F")  # [E_i - I, F_i], column-major: E_i - I = W[:, :N] is contiguous for BLAS
    np.matmul(X, R, out=W[:, :N])
    np.multiply(R, math.ldexp(dt, -squarings), out=W[:, N:])
    following = np.empty_like(W, order="F")
    for _ in range(squarings):  # W <- H W = (E - I) W + 2 W
        np.copyto(following, W)
        dgemm(1.0, W[:, :N], W, 2.0, following, overwrite_c=1)
        W, following = following, W
    E = W[:, :N]
    E.reshape(-1, order="F")[:: N + 1] += 1.0  # the diagonal, in place (the view is column-major contiguous)
    return E, W[:, N:]


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
        index, squarings = _scaling(norm)
        _, q, K, coefficients = _PLANS[index]
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
