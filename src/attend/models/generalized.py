"""Generalised coordinates: shift operator, smoothness precision S(p, s) and embedding of samples.

A variable in generalised coordinates stacks its value and derivatives order-major,
x~ = [x; x'; ...; x^(p)] (p + 1 orders, all variables of order 0 first).

Smoothness: for noise with autocorrelation rho(tau) = exp(-tau^2/(4 s^2)),
Cov(e^(i), e^(j)) = V_ij = (-1)^i rho^(i+j)(0), with
rho^(2k)(0) = (-1)^k (2k-1)!! / (2 s^2)^k and odd derivatives zero. The temporal precision is
S = inv(V). Writing V = L V0 L with L = diag((2 s^2)^(-k/2)), V0 is an integer matrix, so
S = inv(L) inv(V0) inv(L) is computed with inv(V0) in exact rational arithmetic: no loss of
accuracy at any order (V itself has condition number ~1e29 at s = 0.006 s, 7 orders).
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache
from math import factorial

import numpy as np

from attend._validation import AttendInputError, order, positive_scalar


def shift_operator(n_orders: int, dimension: int) -> np.ndarray:
    """D = kron(U, I_dimension), U the (n_orders x n_orders) upper shift: D x~ = [x'; x''; ...; 0]
    (dimension: the size of each order, e.g. the number of states)."""
    upper_shift = np.eye(n_orders, k=1)
    return np.kron(upper_shift, np.eye(dimension))


def _double_factorial_odd(k: int) -> int:
    """(2k - 1)!! with (-1)!! = 1."""
    result = 1
    for value in range(2 * k - 1, 0, -2):
        result *= value
    return result


def _exact_inverse(matrix: list[list[Fraction]]) -> list[list[Fraction]]:
    """Gauss-Jordan inverse in rational arithmetic."""
    size = len(matrix)
    work = [row[:] + [Fraction(int(i == j)) for j in range(size)] for i, row in enumerate(matrix)]
    for column in range(size):
        pivot = next(r for r in range(column, size) if work[r][column] != 0)
        work[column], work[pivot] = work[pivot], work[column]
        scale = work[column][column]
        work[column] = [value / scale for value in work[column]]
        for r in range(size):
            if r != column and work[r][column] != 0:
                factor = work[r][column]
                work[r] = [a - factor * b for a, b in zip(work[r], work[column])]
    return [row[size:] for row in work]


@lru_cache(maxsize=64)
def _unit_covariance_core(n_orders: int) -> tuple[tuple[Fraction, ...], ...]:
    """V0_ij = (-1)^i * (-1)^((i+j)/2) (i+j-1)!! for even i+j, else 0 (V at 2 s^2 = 1)."""
    return tuple(
        tuple(
            Fraction((-1) ** i * (-1) ** ((i + j) // 2) * _double_factorial_odd((i + j) // 2))
            if (i + j) % 2 == 0
            else Fraction(0)
            for j in range(n_orders)
        )
        for i in range(n_orders)
    )


@lru_cache(maxsize=64)
def _unit_precision_core(n_orders: int) -> np.ndarray:
    inverse = _exact_inverse([list(row) for row in _unit_covariance_core(n_orders)])
    return np.array([[float(value) for value in row] for row in inverse])


def temporal_covariance(n_orders: int, kernel_width: float) -> np.ndarray:
    """V(s): covariance of a Gaussian-smoothed noise and its first n_orders - 1 derivatives.

    kernel_width: s [s], the width of the noise's Gaussian kernel (in the derivatives' time unit).
    Returns (n_orders, n_orders); order i carries (2 s^2)^(-i/2), so V(s) = inv(S(s)).
    """
    n_orders = order(n_orders, "n_orders", maximum=40)
    s = positive_scalar(kernel_width, "kernel_width")
    core = np.array([[float(v) for v in row] for row in _unit_covariance_core(n_orders)])
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        scale = (2 * np.float64(s) ** 2) ** (-np.arange(n_orders) / 2)
        covariance = scale[:, None] * core * scale[None, :]
    return _finite_scales(covariance, s, n_orders)


def _finite_scales(matrix: np.ndarray, s: float, n_orders: int) -> np.ndarray:
    """``matrix`` (V(s) or S(s)) if its entries are finite, else an AttendInputError naming the kernel
    width s [s], whose powers up to (2 s^2)^((n_orders - 1) / 2) left the floating-point range."""
    if np.all(np.isfinite(matrix)):
        return matrix
    raise AttendInputError(f"kernel_width: a width of {s:g} (in the unit of time of the derivatives: seconds, or "
                           f"sample times where the flow runs in samples) with {n_orders} orders of motion gives "
                           "(2 s^2)^k outside the floating-point range; expected a kernel width of about the sample "
                           "time (a few sample times at most)")


def smoothness_precision(n_orders: int, kernel_width: float) -> np.ndarray:
    """S(s) = inv(V(s)) for n_orders orders (embedding order p = n_orders - 1).

    ``kernel_width`` s in the same time unit as the derivatives (seconds in attend).
    Check (s = 1, 3 orders): S = [[1.5, 0, 1], [0, 2, 0], [1, 0, 2]].
    """
    n_orders = order(n_orders, "n_orders", maximum=40)
    if n_orders < 1:
        raise AttendInputError("n_orders: expected at least 1 order")
    s = positive_scalar(kernel_width, "kernel_width")
    with np.errstate(over="ignore", invalid="ignore"):
        inverse_scale = (2 * np.float64(s) ** 2) ** (np.arange(n_orders) / 2)
        precision = inverse_scale[:, None] * _unit_precision_core(n_orders) * inverse_scale[None, :]
    return _finite_scales(precision, s, n_orders)


def block_precisions(
    embedding_order: int, input_order: int, kernel_width: float, convention: str = "size"
) -> tuple[np.ndarray, np.ndarray]:
    """Temporal precisions (S_p, S_d) for states/outputs (p + 1 orders) and inputs (d + 1 orders),
    p = embedding_order, d = input_order, for noise of kernel_width s [s].

    convention "size": each inverts V at the size used (SPM).
    convention "max": invert V at max(p, d) + 1 orders, then take the top-left blocks (Meera's
    code, needed to reproduce the published quadrotor numbers).
    """
    p = order(embedding_order, "embedding_order")
    d = order(input_order, "input_order")
    if convention == "size":
        return smoothness_precision(p + 1, kernel_width), smoothness_precision(d + 1, kernel_width)
    if convention == "max":
        full = smoothness_precision(max(p, d) + 1, kernel_width)
        return full[: p + 1, : p + 1], full[: d + 1, : d + 1]
    raise AttendInputError(f"precision_convention: expected 'size' or 'max', got {convention!r}")


@lru_cache(maxsize=64)
def _unit_taylor_inverse(window: int, centre: Fraction) -> np.ndarray:
    """inv(T) for T_ij = (i - c)^j / j! (unit sample spacing), exactly."""
    taylor = [
        [Fraction((Fraction(i) - centre) ** j) / factorial(j) for j in range(window)]
        for i in range(window)
    ]
    return np.array([[float(v) for v in row] for row in _exact_inverse(taylor)])


def embedding_weights(n_orders: int, dt: float, centre: float | None = None) -> np.ndarray:
    """E = inv(T), T_ij = ((i - c) dt)^j / j!: row j maps a window of n_orders samples to the
    j-th derivative at window position c (default n_orders // 2: the centre sample, or for an
    even window the later of the two middle samples, so the window leans on the past).

    For 7 orders, row 1 is [-1/60, 3/20, -3/4, 0, 3/4, -3/20, 1/60] / dt (central differences).
    """
    n_orders = order(n_orders, "n_orders", maximum=40)
    dt = positive_scalar(dt, "dt", "s")
    c = Fraction(n_orders // 2) if centre is None else Fraction(centre).limit_denominator(1000)
    unit = _unit_taylor_inverse(n_orders, c)
    return unit * (dt ** -np.arange(n_orders))[:, None]


def embed(series, n_orders: int, dt: float, *, edges: str = "clamp", shift: int = 0) -> np.ndarray:
    """Generalised coordinates of a sampled series.

    series: (N, k) samples at spacing dt [s]. Returns (N, n_orders * k), order-major per row:
    row t holds [y; y'; ...] at sample t + shift, estimated from the window of n_orders samples
    around it: n_orders // 2 samples before and the rest after (an even window reaches one
    sample further into the past than into the future, as in the authors' DEM code).
    ``shift`` = -1 centres row t on sample t - 1 (the convention of the authors' quadrotor code).

    Edges (windows reaching past the log): "clamp" repeats the end samples (SPM);
    "order0" keeps the sample value and sets the derivatives to zero (Meera); set by ``edges``.
    """
    y = np.asarray(series, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n_samples, width = y.shape
    weights = embedding_weights(n_orders, dt)
    before = n_orders // 2
    after = n_orders - 1 - before
    centres = np.arange(n_samples) + shift
    # shifted[i] = y at sample centre - before + i, clamped to the log (repeat end samples)
    shifted = np.stack([y[np.clip(centres - before + i, 0, n_samples - 1)] for i in range(n_orders)])
    derivatives = np.tensordot(weights, shifted, axes=(1, 0))  # (n_orders, N, k)
    derivatives = np.moveaxis(derivatives, 0, 1)  # (N, n_orders, k)
    if edges == "order0":
        outside = (centres - before < 0) | (centres + after > n_samples - 1)
        derivatives[outside, 1:, :] = 0.0
        derivatives[outside, 0, :] = y[np.clip(centres[outside], 0, n_samples - 1)]
    elif edges != "clamp":
        raise AttendInputError(f"edges: expected 'clamp' or 'order0', got {edges!r}")
    return derivatives.reshape(n_samples, n_orders * width)


def embed_newest(samples, n_orders: int, dt: float) -> np.ndarray:
    """[y; y'; ...; y^(n_orders - 1)] ((n_orders, k)) at the newest of ``samples`` ((N, k) or a list of
    N vectors of k, N >= 1, spacing dt [s]): the last row of :func:`embed` with edges "clamp" (the window
    of n_orders samples with n_orders // 2 before the newest, the newest repeated past it and the first
    before the start), from the window's own samples, for a loop that embeds as it goes."""
    before = n_orders // 2
    y = np.asarray(samples[-(before + 1):], dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    last = y.shape[0] - 1
    window = y[np.clip(np.arange(n_orders) + last - before, 0, last)]
    return embedding_weights(n_orders, dt) @ window


def fold_orders(generalised, n_kept: int, kernel_width: float) -> np.ndarray:
    """A prior given at p + 1 orders ``generalised`` ((N, p + 1, r)) folded onto its first d + 1 =
    ``n_kept`` orders ((N, d + 1, r)): with the errors at orders d + 1..p taken where the estimate is 0
    (-eta^(d+1..p)) and S = S(s) at p + 1 orders (s = ``kernel_width`` [s]), their gradient on orders 0..d is that of a prior mean
    eta^(0..d) + inv(S_00) S_01 eta^(d+1..p) (S_00, S_01 the blocks of S on orders 0..d and d + 1..p),
    as SPM weighs a cause prior embedded at more orders than the causes it estimates."""
    table = np.asarray(generalised, dtype=float)
    S = smoothness_precision(table.shape[1], kernel_width)
    gain = np.linalg.solve(S[:n_kept, :n_kept], S[:n_kept, n_kept:])
    return table[:, :n_kept] + np.einsum("ij,kjr->kir", gain, table[:, n_kept:])


def smoothness_condition(n_orders: int, kernel_width: float, dt: float) -> float:
    """cond(S) of the temporal precision in sample units (kernel width s / dt samples).

    n_orders: p + 1 orders of S; kernel_width: s [s], the width of the noise's Gaussian kernel;
    dt: sample time [s].

    Unit-free: how unequally S weights the orders once derivatives are measured per sample, i.e.
    how precisely finite differences of the data would have to resolve the highest order. It
    grows like (2 (s/dt)^2)^p for smooth noise and like (dt/s)^(2p) for nearly white noise.
    """
    dt = positive_scalar(dt, "dt", "s")
    return float(np.linalg.cond(smoothness_precision(n_orders, positive_scalar(kernel_width, "kernel_width") / dt)))
