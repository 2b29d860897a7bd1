"""Block-tridiagonal symmetric positive-definite systems, batched over a leading axis.

A matrix Pi with diagonal blocks D_k (b x b) and sub-diagonal blocks O_k (block k + 1, k) is
factored as Pi = L L' with L block lower bidiagonal (diagonal L_k, sub-diagonal B_k)::

    L_k L_k' = D_k - B_{k-1} B_{k-1}',   B_k = O_k L_k^{-T}

in O(K b^3) for K blocks. Used by path-mode learning (:mod:`attend.perception.learning.path`)
and path-mode nonlinear DEM (:mod:`attend.perception.nonlinear.path`), whose precisions couple
only neighbouring blocks of samples.
"""

from __future__ import annotations

import numpy as np


def cholesky(Dg: np.ndarray, Off: np.ndarray):
    """Batched block Cholesky of a block-tridiagonal SPD matrix: diagonal blocks Dg (R, K, b, b),
    sub-diagonal blocks Off (R, K - 1, b, b) (block k + 1, k). Returns L_k, B_k and L_k^{-1} with
    Pi = L L', L block lower bidiagonal (diagonal L_k, sub-diagonal B_k)."""
    R, K, b, _ = Dg.shape
    Lk = np.empty_like(Dg)
    Linv = np.empty_like(Dg)
    Bk = np.empty_like(Off)
    prev = np.zeros((R, b, b))
    eye = np.broadcast_to(np.eye(b), (R, b, b))
    for k in range(K):
        Lk[:, k] = np.linalg.cholesky(Dg[:, k] - prev)
        Linv[:, k] = np.linalg.solve(Lk[:, k], eye)
        if k + 1 < K:
            Bk[:, k] = Off[:, k] @ np.swapaxes(Linv[:, k], 1, 2)  # B_k = Off_k L_k^{-T}
            prev = Bk[:, k] @ np.swapaxes(Bk[:, k], 1, 2)
    return Lk, Bk, Linv


def solve(Linv: np.ndarray, Bk: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve (L L') x = rhs for block lower bidiagonal L. Linv: the inverses L_k^{-1} (R, K, b, b)
    and Bk: the sub-diagonal blocks B_k (R, K - 1, b, b), both from :func:`cholesky`; rhs (R, K, b)."""
    R, K, b = rhs.shape
    y = np.empty_like(rhs)
    for k in range(K):
        v = rhs[:, k] - (np.einsum("rab,rb->ra", Bk[:, k - 1], y[:, k - 1]) if k else 0.0)
        y[:, k] = np.einsum("rab,rb->ra", Linv[:, k], v)
    x = np.empty_like(rhs)
    for k in range(K - 1, -1, -1):
        v = y[:, k] - (np.einsum("rba,rb->ra", Bk[:, k], x[:, k + 1]) if k < K - 1 else 0.0)
        x[:, k] = np.einsum("rba,rb->ra", Linv[:, k], v)
    return x


def selected_inverse(Linv: np.ndarray, Bk: np.ndarray):
    """Diagonal blocks Sigma_kk and super-diagonal blocks Sigma_k,k+1 of inv(L L') (Takahashi):
    Sigma_k,k+1 = -L_k^{-T} B_k' Sigma_k+1,k+1,  Sigma_kk = L_k^{-T} (L_k^{-1} - B_k' Sigma_k+1,k).
    Linv (R, K, b, b) and Bk (R, K - 1, b, b): from :func:`cholesky`. Returns (Sd (R, K, b, b),
    Su (R, K - 1, b, b))."""
    R, K, b, _ = Linv.shape
    Sd = np.empty_like(Linv)
    Su = np.empty((R, max(K - 1, 0), b, b))
    for k in range(K - 1, -1, -1):
        Li, LiT = Linv[:, k], np.swapaxes(Linv[:, k], 1, 2)
        if k == K - 1:
            Sd[:, k] = LiT @ Li
        else:
            upper = -LiT @ np.swapaxes(Bk[:, k], 1, 2) @ Sd[:, k + 1]
            Su[:, k] = upper
            Sd[:, k] = LiT @ (Li - np.swapaxes(Bk[:, k], 1, 2) @ np.swapaxes(upper, 1, 2))
        Sd[:, k] = 0.5 * (Sd[:, k] + np.swapaxes(Sd[:, k], 1, 2))
    return Sd, Su
