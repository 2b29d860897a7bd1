"""Double-double arithmetic on numpy arrays: about 32 significant digits from float64 alone.

A double-double number is an unevaluated sum hi + lo of two float64 with |lo| <= ulp(hi) / 2;
its unit roundoff is about 2^-104 ~ 5e-32 (float64: 1.1e-16). The arithmetic is built on the
error-free transformations of Knuth (two_sum: a + b = s + e exactly) and Dekker (two_prod with
Veltkamp's split: a b = p + e exactly), which hold in IEEE round-to-nearest float64 as numpy
evaluates it (no fused multiply-add, no extended intermediates). Values must stay below ~1e300
in magnitude (the split multiplies by 2^27 + 1).

Only what :mod:`attend.perception.references.exact_oracle` needs, vectorised: elementwise
add / multiply / divide / sqrt, sums along an axis (pairwise), matrix products, a Cholesky
factor and triangular solves. A :class:`DD` holds two arrays of the same shape.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

_SPLITTER = 134217729.0  # 2^27 + 1


class DD(NamedTuple):
    """An array of double-double numbers: value = hi + lo elementwise."""

    hi: np.ndarray
    lo: np.ndarray

    @property
    def shape(self) -> tuple:
        return self.hi.shape

    def at(self, index) -> "DD":
        """The entries at ``index`` (numpy indexing of both parts)."""
        return DD(self.hi[index], self.lo[index])

    @property
    def T(self) -> "DD":
        return DD(self.hi.T, self.lo.T)

    def value(self) -> np.ndarray:
        """The float64 nearest to each value."""
        return self.hi + self.lo


def dd(array) -> DD:
    """A double-double array equal to the float64 ``array`` (lo = 0)."""
    hi = np.array(array, dtype=float)
    return DD(hi, np.zeros_like(hi))


def zeros(shape) -> DD:
    return DD(np.zeros(shape), np.zeros(shape))


def _two_sum(a, b):
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _quick_two_sum(a, b):  # |a| >= |b|
    s = a + b
    return s, b - (s - a)


def _split(a):
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


def _two_prod(a, b):
    p = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def add(a: DD, b: DD) -> DD:
    """a + b (the accurate double-double sum: relative error ~1e-32 even under cancellation)."""
    s, e = _two_sum(a.hi, b.hi)
    t, f = _two_sum(a.lo, b.lo)
    e = e + t
    s, e = _quick_two_sum(s, e)
    e = e + f
    return DD(*_quick_two_sum(s, e))


def negative(a: DD) -> DD:
    return DD(-a.hi, -a.lo)


def subtract(a: DD, b: DD) -> DD:
    return add(a, negative(b))


def multiply(a: DD, b: DD) -> DD:
    """a b elementwise (broadcasting)."""
    p, e = _two_prod(a.hi, b.hi)
    e = e + (a.hi * b.lo + a.lo * b.hi)
    return DD(*_quick_two_sum(p, e))


def multiply_float(a: DD, b) -> DD:
    """a b with b a float64 array (exact b, broadcasting)."""
    p, e = _two_prod(a.hi, b)
    e = e + a.lo * b
    return DD(*_quick_two_sum(p, e))


def divide(a: DD, b: DD) -> DD:
    """a / b elementwise: three float64 quotient digits, each correcting the remainder."""
    q1 = a.hi / b.hi
    r = subtract(a, multiply_float(b, q1))
    q2 = r.hi / b.hi
    r = subtract(r, multiply_float(b, q2))
    q3 = r.hi / b.hi
    s, e = _quick_two_sum(q1, q2)
    return add(DD(s, e), dd(q3))


def sqrt(a: DD) -> DD:
    """sqrt(a) for a >= 0: one Newton step from the float64 root, residual in double-double."""
    x = np.sqrt(a.hi)
    safe = np.where(x > 0, x, 1.0)
    residual = subtract(a, multiply(dd(x), dd(x)))
    correction = residual.hi / (2 * safe)
    return add(dd(x), dd(np.where(x > 0, correction, 0.0)))


def sum_along(a: DD, axis: int = -1) -> DD:
    """Sum along ``axis`` by pairwise halving (each level one vectorised double-double add)."""
    hi, lo = np.moveaxis(a.hi, axis, -1), np.moveaxis(a.lo, axis, -1)
    if hi.shape[-1] == 0:
        return zeros(hi.shape[:-1])
    current = DD(hi, lo)
    while current.hi.shape[-1] > 1:
        size = current.hi.shape[-1]
        half = size // 2
        paired = add(DD(current.hi[..., :half], current.lo[..., :half]),
                     DD(current.hi[..., half: 2 * half], current.lo[..., half: 2 * half]))
        if size % 2:
            paired = DD(np.concatenate([paired.hi, current.hi[..., -1:]], axis=-1),
                        np.concatenate([paired.lo, current.lo[..., -1:]], axis=-1))
        current = paired
    return DD(current.hi[..., 0], current.lo[..., 0])


def _pairwise_sum(p: np.ndarray, e: np.ndarray) -> DD:
    """sum(p + e) along the last axis: the p summed pairwise with two_sum, every rounding error
    and the e (already ~1e-16 of p) summed in float64 (Ogita, Rump and Oishi's Sum2, pairwise):
    as accurate as a sum in twice the working precision."""
    err = e.sum(axis=-1)
    while p.shape[-1] > 1:
        size = p.shape[-1]
        half = size // 2
        s, t = _two_sum(p[..., :half], p[..., half: 2 * half])
        err = err + t.sum(axis=-1)
        p = np.concatenate([s, p[..., -1:]], axis=-1) if size % 2 else s
    return DD(*_two_sum(p[..., 0], err))


def matmul(a: DD, b: DD, chunk_elements: int = 400_000, symmetric: bool = False) -> DD:
    """a @ b for 2-d double-double arrays (p, k) @ (k, q): every product hi_a hi_b split exactly
    (Dekker), the cross terms hi lo added in float64, each chunk of the inner dimension summed as
    :func:`_pairwise_sum` and the chunks accumulated in double-double (relative error ~1e-31 of
    sum |a||b|). symmetric=True: the result is known to be symmetric (b = a'), only the blocks on
    and above the diagonal are computed."""
    p, k = a.shape
    q = b.shape[1]
    ah, al = _split(a.hi)
    bh, bl = _split(b.hi)
    out = zeros((p, q))
    rows = max(1, min(p, 8))
    for r0 in range(0, p, rows):
        r1 = min(p, r0 + rows)
        c0 = r0 if symmetric else 0
        width = q - c0
        step = max(1, chunk_elements // max((r1 - r0) * width, 1))
        acc = zeros((r1 - r0, width))
        for k0 in range(0, k, step):
            k1 = min(k, k0 + step)
            x_hi, x_lo = a.hi[r0:r1, None, k0:k1], a.lo[r0:r1, None, k0:k1]
            x_h, x_l = ah[r0:r1, None, k0:k1], al[r0:r1, None, k0:k1]
            y_hi, y_lo = b.hi[k0:k1, c0:].T[None], b.lo[k0:k1, c0:].T[None]
            y_h, y_l = bh[k0:k1, c0:].T[None], bl[k0:k1, c0:].T[None]
            prod = x_hi * y_hi
            err = ((x_h * y_h - prod) + x_h * y_l + x_l * y_h) + x_l * y_l + (x_hi * y_lo + x_lo * y_hi)
            acc = add(acc, _pairwise_sum(prod, err))
        out.hi[r0:r1, c0:], out.lo[r0:r1, c0:] = acc.hi, acc.lo
    if symmetric:
        upper = np.triu(np.ones((p, q), dtype=bool), 1)
        out.hi[upper.T], out.lo[upper.T] = out.hi.T[upper.T], out.lo.T[upper.T]
    return out


def matvec(a: DD, x: DD) -> DD:
    """a @ x for a (p, k) and x (k,)."""
    return sum_along(multiply(a, DD(x.hi[None, :], x.lo[None, :])), axis=-1)


def cholesky(a: DD) -> DD:
    """Lower Cholesky factor L (L L' = a) of a symmetric positive definite double-double matrix
    (left-looking: column j from the finished columns 0..j-1). Raises numpy's LinAlgError when a
    pivot is not positive."""
    size = a.shape[0]
    L = zeros((size, size))
    for j in range(size):
        if j:
            row = DD(L.hi[j, :j], L.lo[j, :j])
            below = DD(L.hi[j:, :j], L.lo[j:, :j])
            column = subtract(DD(a.hi[j:, j], a.lo[j:, j]),
                              sum_along(multiply(below, DD(row.hi[None, :], row.lo[None, :])), axis=-1))
        else:
            column = DD(a.hi[:, 0].copy(), a.lo[:, 0].copy())
        pivot = DD(column.hi[:1], column.lo[:1])
        if not pivot.hi[0] > 0:
            raise np.linalg.LinAlgError(f"double-double Cholesky: pivot {j} is {pivot.hi[0]:.3g} (not positive)")
        root = sqrt(pivot)
        scaled = divide(column, DD(np.broadcast_to(root.hi, column.shape), np.broadcast_to(root.lo, column.shape)))
        L.hi[j:, j], L.lo[j:, j] = scaled.hi, scaled.lo
        L.hi[j, j], L.lo[j, j] = root.hi[0], root.lo[0]
    return L


def solve_lower(L: DD, b: DD) -> DD:
    """inv(L) b for lower-triangular L (size, size) and b (size,) or (size, q) (forward substitution)."""
    vector = b.hi.ndim == 1
    rhs = DD(b.hi.reshape(b.hi.shape[0], -1), b.lo.reshape(b.hi.shape[0], -1))
    size, q = rhs.shape
    x = zeros((size, q))
    for i in range(size):
        value = DD(rhs.hi[i], rhs.lo[i])
        if i:
            products = multiply(DD(L.hi[i, :i, None], L.lo[i, :i, None]), DD(x.hi[:i], x.lo[:i]))
            value = subtract(value, sum_along(products, axis=0))
        diagonal = DD(np.full(q, L.hi[i, i]), np.full(q, L.lo[i, i]))
        solved = divide(value, diagonal)
        x.hi[i], x.lo[i] = solved.hi, solved.lo
    return DD(x.hi[:, 0], x.lo[:, 0]) if vector else x


def solve_upper_transposed(L: DD, b: DD) -> DD:
    """inv(L') b for lower-triangular L and b (size,) (back substitution)."""
    size = L.shape[0]
    x = zeros(size)
    for i in range(size - 1, -1, -1):
        value = DD(b.hi[i:i + 1], b.lo[i:i + 1])
        if i < size - 1:
            products = multiply(DD(L.hi[i + 1:, i], L.lo[i + 1:, i]), DD(x.hi[i + 1:], x.lo[i + 1:]))
            value = subtract(value, DD(*[np.atleast_1d(v) for v in sum_along(products)]))
        solved = divide(value, DD(L.hi[i, i: i + 1], L.lo[i, i: i + 1]))
        x.hi[i], x.lo[i] = solved.hi[0], solved.lo[0]
    return x
