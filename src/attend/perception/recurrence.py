"""Fast evaluation of the linear recurrence X[k] = Phi X[k-1] + drive[k].

A Python loop over samples costs ~1 µs of interpreter time per step. The blocked scheme here
does the same arithmetic in O(sqrt(N)) vectorised steps:

1. cut the N samples into K chunks of L;
2. run the recurrence inside every chunk at once from a zero start (L steps of a (K, n) @ (n, n)
   product): Z[c, j] = sum_{i <= j} Phi^(j-i) drive[c, i];
3. carry the chunk-end states across chunks (K steps): E[c] = Phi^L E[c-1] + Z[c, L-1];
4. add the carried start: X[c, j] = Z[c, j] + Phi^(j+1) E[c-1].

The result equals the sequential recurrence up to floating-point rounding.
"""

from __future__ import annotations

import numpy as np


def linear_recurrence(transition: np.ndarray, drive: np.ndarray, initial: np.ndarray) -> np.ndarray:
    """X[k] = transition @ X[k-1] + drive[k] for k = 0..N-1 with X[-1] = initial; returns X (N, n)."""
    n_samples, size = drive.shape
    if n_samples == 0:
        return drive.copy()
    if n_samples <= 64:
        return _sequential(transition, drive, initial)
    chunk = max(16, int(np.sqrt(n_samples / 4)))
    n_chunks = -(-n_samples // chunk)
    padded = np.zeros((n_chunks * chunk, size))
    padded[:n_samples] = drive
    # layout (position in chunk, chunk, state) so that each step touches contiguous memory
    local = np.ascontiguousarray(padded.reshape(n_chunks, chunk, size).transpose(1, 0, 2))
    transpose = transition.T
    for j in range(1, chunk):
        local[j] += local[j - 1] @ transpose
    powers = np.empty((chunk, size, size))  # powers[j] = Phi^(j+1)
    powers[0] = transition
    for j in range(1, chunk):
        np.matmul(transition, powers[j - 1], out=powers[j])
    starts = np.empty((n_chunks, size))  # state just before each chunk
    state = np.asarray(initial, dtype=float)
    chunk_power = powers[-1]
    ends = local[-1]
    for c in range(n_chunks):
        starts[c] = state
        state = chunk_power @ state + ends[c]
    # X[c, j] = local[j, c] + Phi^(j+1) starts[c], the carried part as one (K, n) @ (n, L n) product
    carried = starts @ powers.transpose(2, 0, 1).reshape(size, chunk * size)
    carried = carried.reshape(n_chunks, chunk, size)
    carried += local.transpose(1, 0, 2)
    return carried.reshape(-1, size)[:n_samples]


def _sequential(transition: np.ndarray, drive: np.ndarray, initial: np.ndarray) -> np.ndarray:
    out = np.empty_like(drive)
    state = np.asarray(initial, dtype=float)
    for k in range(drive.shape[0]):
        state = transition @ state + drive[k]
        out[k] = state
    return out
