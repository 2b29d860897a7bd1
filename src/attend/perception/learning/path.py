"""Path mode: one state trajectory x with X_t = G x_window(t); its posterior precision is block
tridiagonal in blocks of p + 1 samples (batched block Cholesky, selected inverse and solve, O(T))."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend.perception.block_tridiagonal import cholesky as _block_tridiagonal_cholesky
from attend.perception.block_tridiagonal import selected_inverse as _block_tridiagonal_selected_inverse
from attend.perception.block_tridiagonal import solve as _block_tridiagonal_solve
from attend.perception.learning.problem import _observer, _Structure


class _PathPosterior(NamedTuple):
    """q(x) over the sample path x (covered samples), summarised for the learner."""

    mean: np.ndarray  # (R, T, P, n) generalised means X_t = G x_window(t) at every sample
    sigma_mean: np.ndarray  # (R, P n, P n) average over the used samples of Cov(X_t)
    entropy: np.ndarray  # (R,) 1/2 ln|Sigma_path| + 1/2 n T_covered


def _path_layout(T: int, st_used: np.ndarray, P: int):
    """Blocks of P samples: window starts s_t = t - P // 2 of the used samples, their block k and
    offset o, the count w[k, o] (1 if a used window starts there) and the covered samples."""
    before = P // 2
    starts = np.flatnonzero(st_used) - before
    n_blocks = -(-T // P) + 1
    w = np.zeros((n_blocks, P))
    w[starts // P, starts % P] = 1.0
    covered = np.zeros(n_blocks * P, dtype=bool)
    for i in range(P):
        covered[starts + i] = True
    return starts, w, covered



def _path_posterior(theta, lam, Ytil, Util, st: "_Structure", want_mean: bool = True) -> _PathPosterior:
    """Posterior of the whole state path x (samples) with X_t = G x_window(t), G = kron(E, I_n):

        Pi_path = sum_t G' Pi_X G (windows of the used samples),  b = sum_t G' (C~' Vy y~_t + (D - A~)' W B~ u~_t),
        x = inv(Pi_path) b,  F's state entropy 1/2 ln|inv(Pi_path)| + n T_covered / 2.

    Pi_path is block tridiagonal in blocks of P samples (a window spans at most two blocks):
    batched block Cholesky and selected inversion, O(T) in time and memory."""
    Pi_X, _, CtVy, MtWB = _observer(theta, lam, st, want_inverse=False)
    R = Pi_X.shape[0]
    n, P = st.n, st.orders
    T = st.used.shape[0]
    starts, w, covered = _path_layout(T, st.used, P)
    K = w.shape[0]
    b = P * n
    G = np.kron(st.E, np.eye(n))  # (P n, P n): window (sample-major) -> X (order-major)
    Lam = np.swapaxes(G, 0, 1)[None] @ Pi_X @ G[None]  # (R, P n, P n) per window
    two = np.zeros((R, P, 2 * b, 2 * b))  # a window starting at offset o of a block, over two blocks
    for o in range(P):
        two[:, o, o * n:o * n + b, o * n:o * n + b] = Lam
    Dg = np.einsum("ko,roab->rkab", w, two[:, :, :b, :b])
    Dg[:, 1:] += np.einsum("ko,roab->rkab", w[:-1], two[:, :, b:, b:])
    Off = np.einsum("ko,roab->rkab", w[:-1], two[:, :, b:, :b])
    with np.errstate(all="ignore"):
        uncovered = ~covered.reshape(K, P)
        pad = np.repeat(uncovered, n, axis=1).astype(float)  # identity on samples no window touches
        Dg = Dg + pad[None, :, :, None] * np.eye(b)[None, None]
        ok = np.all(np.isfinite(Dg), axis=(1, 2, 3)) & np.all(np.isfinite(Off), axis=(1, 2, 3))
        sigma_mean = np.full((R, b, b), np.nan)
        entropy = np.full(R, -np.inf)
        mean = np.full((R, T, P, n), np.nan)
        if not ok.any():
            return _PathPosterior(mean, sigma_mean, entropy)
        idx = np.flatnonzero(ok)
        try:
            Lk, Bk, Linv = _block_tridiagonal_cholesky(Dg[idx], Off[idx])
        except np.linalg.LinAlgError:  # some run's Pi_path is not positive definite: find which
            positive = []
            for k in idx:
                try:
                    _block_tridiagonal_cholesky(Dg[k:k + 1], Off[k:k + 1])
                    positive.append(k)
                except np.linalg.LinAlgError:
                    pass
            if not positive:
                return _PathPosterior(mean, sigma_mean, entropy)
            idx = np.array(positive)
            Lk, Bk, Linv = _block_tridiagonal_cholesky(Dg[idx], Off[idx])
        logdet = 2 * np.log(np.diagonal(Lk, axis1=2, axis2=3)).sum(axis=(1, 2))
        entropy[idx] = -0.5 * logdet + 0.5 * n * covered.sum()
        Sd, Su = _block_tridiagonal_selected_inverse(Linv, Bk)
        # sum over the used windows of the window covariance, then Cov(X_t) = G Sigma_win G'
        total = np.zeros((len(idx), b, b))
        for o in range(P):
            wk = w[:, o]
            two = np.zeros((len(idx), 2 * b, 2 * b))
            two[:, :b, :b] = np.einsum("k,rkab->rab", wk, Sd)
            two[:, b:, b:] = np.einsum("k,rkab->rab", wk[:-1], Sd[:, 1:])
            up = np.einsum("k,rkab->rab", wk[:-1], Su)
            two[:, :b, b:] = up
            two[:, b:, :b] = np.swapaxes(up, 1, 2)
            total += two[:, o * n:o * n + b, o * n:o * n + b]
        sigma_mean[idx] = G[None] @ (total / len(starts)) @ G.T[None]
        if want_mean:
            h = (Ytil[idx].reshape(len(idx), T, -1) @ np.swapaxes(CtVy[idx], 1, 2)
                 + Util[idx].reshape(len(idx), T, -1) @ np.swapaxes(MtWB[idx], 1, 2))  # (R', T, P n)
            Gh = (h[:, st.used] @ G).reshape(len(idx), len(starts), P, n)
            rhs = np.zeros((len(idx), K * P, n))
            for i in range(P):
                rhs[:, starts + i] += Gh[:, :, i]
            x = _block_tridiagonal_solve(Linv, Bk, rhs.reshape(len(idx), K, b))
            x = x.reshape(len(idx), K * P, n)
            s_all = np.clip(np.arange(T) - P // 2, 0, T - P)
            windows = np.stack([x[:, s_all + i] for i in range(P)], axis=2)  # (R', T, P, n) samples
            mean[idx] = np.einsum("ji,rtia->rtja", st.E, windows)
    return _PathPosterior(mean, sigma_mean, entropy)
