"""The learning problem: logs embedded in (scaled) generalised coordinates, the structure every run
of a batch shares, the variational state of the runs, their priors, and the state precision Pi_X."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError
from attend.models.generalized import block_precisions, embed, embedding_weights, shift_operator
from attend.models.parameters import internal_parameter_order


class IdentifiabilityWarning(UserWarning):
    """The log or the model leaves some free parameters undetermined by the data."""


class LearningWarning(UserWarning):
    """Learning stopped early (a step could not increase the free energy without diverging)."""


@dataclass(frozen=True, eq=False)
class _Structure:
    """What all runs of a batch share: dimensions, S, shift operator, used samples."""

    n: int
    r: int
    m: int
    orders: int  # p + 1
    S: np.ndarray  # (P, P)
    log_det_S: float
    Dx: np.ndarray  # (P n, P n)
    n_used: int
    used: np.ndarray  # (T,) bool
    active: np.ndarray  # (n_theta,) bool, public order: entries with finite prior precision
    perm: np.ndarray  # public -> internal index
    path: bool = False  # states: one path (True) or free per sample (False)
    E: np.ndarray | None = None  # (P, P) embedding weights (orders x window samples), path mode
    count: float = 1.0  # weight of each window's energy: 1 per sample, 1 / P for a path (data counted once)
    time_scale: float = 1.0  # sigma [s]: order k is held as sigma^k d^k/dt^k (see _prepare)
    log_jacobian: float = 0.0  # sum_k k ln(sigma): ln|Sigma_X| (true units) = ln|Sigma_X (scaled)| - 2 n this
    S_w: np.ndarray | None = None  # (P, P) temporal precision of the motion error (default S)
    log_det_S_w: float | None = None  # ln|S_w| over its modelled orders (true units)
    motion_orders: int = 0  # orders of the motion error that carry precision (P, or p: top one marginalised)

    @property
    def S_motion(self) -> np.ndarray:
        return self.S if self.S_w is None else self.S_w

    @property
    def w_orders(self) -> int:
        return self.motion_orders or self.orders

    @property
    def n_theta(self) -> int:
        return self.n * self.n + self.n * self.r + self.m * self.n

    @property
    def n_ab(self) -> int:
        return self.n * (self.n + self.r)


def _embed_batch(series: np.ndarray, n_orders: int, dt: float) -> np.ndarray:
    """(R, T, k) samples -> (R, T, n_orders, k) generalised coordinates (clamped edges)."""
    R, T, k = series.shape
    flat = np.moveaxis(series, 0, 1).reshape(T, R * k)
    tilde = embed(flat, n_orders, dt, edges="clamp")  # (T, n_orders * R * k), order-major
    return np.moveaxis(tilde.reshape(T, n_orders, R, k), 2, 0)


def _bkron(S: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Batched kron(S, M_r): S (P, P), M (R, a, b) -> (R, P a, P b)."""
    R, a, b = M.shape
    P = S.shape[0]
    return (S[None, :, None, :, None] * M[:, None, :, None, :]).reshape(R, P * a, P * b)


class _State(NamedTuple):
    """The variational parameters of every run (leading axis R); Sigma_X = inv(Pi_X(theta, lambda))."""

    mu: np.ndarray  # (R, T, P, n) state means in generalised coordinates
    theta: np.ndarray  # (R, n_theta), public order
    lam: np.ndarray  # (R, 2): [lambda_z, lambda_w]


@dataclass(frozen=True, eq=False)
class _Priors:
    eta_theta: np.ndarray  # (R, n_theta) public order
    P_theta: np.ndarray  # (R, n_theta), inf = fixed
    eta_lambda: np.ndarray  # (R, 2)
    P_lambda: np.ndarray  # (R, 2), inf = fixed
    fisher: np.ndarray  # (2,) n_t/2 [m P, n P]


def _split_theta(theta: np.ndarray, st: _Structure):
    n, r, m = st.n, st.r, st.m
    A = theta[:, : n * n].reshape(-1, n, n)
    B = theta[:, n * n: n * n + n * r].reshape(-1, n, r)
    C = theta[:, n * n + n * r:].reshape(-1, m, n)
    return A, B, C


def _observer(theta, lam, st: _Structure, want_inverse: bool = True):
    """Pi_X = C~' Vy C~ + (D - A~)' W (D - A~), Sigma_X = inv(Pi_X) and the gains of the D-step."""
    R = theta.shape[0]
    n, m, P = st.n, st.m, st.orders
    A, B, C = _split_theta(theta, st)
    eye_P = np.eye(P)
    Ct = _bkron(eye_P, C)  # (R, P m, P n)
    motion = st.Dx[None] - _bkron(eye_P, A)  # (R, P n, P n)
    Bt = _bkron(eye_P, B)  # (R, P n, P r)
    pz = st.count * np.exp(lam[:, 0])[:, None, None]
    pw = st.count * np.exp(lam[:, 1])[:, None, None]
    Vy = _bkron(st.S, np.broadcast_to(np.eye(m), (R, m, m))) * pz
    W = _bkron(st.S_motion, np.broadcast_to(np.eye(n), (R, n, n))) * pw
    CtVy = np.swapaxes(Ct, 1, 2) @ Vy
    MtW = np.swapaxes(motion, 1, 2) @ W
    Pi_X = CtVy @ Ct + MtW @ motion
    Pi_X = 0.5 * (Pi_X + np.swapaxes(Pi_X, 1, 2))
    if not want_inverse:
        return Pi_X, None, CtVy, MtW @ Bt
    with np.errstate(all="ignore"):
        ok = np.all(np.isfinite(Pi_X), axis=(1, 2))
        Sigma_X = np.full_like(Pi_X, np.nan)
        if ok.any():
            try:
                Sigma_X[ok] = np.linalg.inv(Pi_X[ok])
            except np.linalg.LinAlgError:
                for k in np.flatnonzero(ok):
                    try:
                        Sigma_X[k] = np.linalg.inv(Pi_X[k])
                    except np.linalg.LinAlgError:
                        pass
        Sigma_X = 0.5 * (Sigma_X + np.swapaxes(Sigma_X, 1, 2))
    return Pi_X, Sigma_X, CtVy, MtW @ Bt


def _prepare(outputs, inputs, dt, kernel_width, embedding_order, input_order, active, n, trim_edges,
             precision_convention, states="sample", top_order="marginal", scaled=True):
    """Embed the logs and build the shared structure.

    Scaled generalised coordinates: order k of every variable is held as sigma^k d^k/dt^k with
    sigma = sqrt(2) s (the kernel's time scale). S = diag(sigma^k) S0 diag(sigma^k) with S0 the
    O(1) integer-derived core (:mod:`attend.models.generalized`), so in these coordinates the temporal
    precision is S0 (cond ~7e4 at p = 6) instead of S (cond ~1.6e29 at s = 0.006 s, p = 6), the
    shift operator is D / sigma, and every quantity the learner forms (Pi_X, the moments K, the
    energies) is a sum of terms of comparable size. F, theta and lambda are unchanged (exact
    reparameterisation; ln|Sigma_X| is reported in true units via ``log_jacobian``).
    """
    R, T, m = outputs.shape
    r = inputs.shape[2]
    P = embedding_order + 1
    Q = input_order + 1
    S, _ = block_precisions(embedding_order, embedding_order, kernel_width, precision_convention)
    sigma = float(np.sqrt(2.0) * kernel_width) if scaled else 1.0  # 1: plain d^k/dt^k (as published)
    scale = sigma ** np.arange(max(P, Q))
    S_scaled = S / scale[:P, None] / scale[None, :P]
    Ytil = _embed_batch(outputs, P, dt) * scale[None, None, :P, None]
    Uq = _embed_batch(inputs, Q, dt) * scale[None, None, :Q, None]
    Util = np.zeros((R, T, P, r))
    k = min(P, Q)
    Util[:, :, :k] = Uq[:, :, :k]
    used = np.ones(T, dtype=bool)
    if trim_edges:
        reach = max(P, Q) // 2  # samples a window reaches on either side (either centring)
        if reach:
            used[:reach] = False
            used[T - reach:] = False
    path = states == "path"
    if path:  # only windows inside the log: X_t = G x_window(t) needs no clamped samples
        reach = max(P, Q) // 2
        used[:reach] = False
        used[T - reach:] = False
    S_w, log_det_S_w, motion_orders = None, None, 0
    if top_order == "marginal" and P > 1:
        # x^(p+1) is not modelled: integrate it out of the top-order motion error. Its Schur
        # complement leaves the precision of orders 0..p-1, inv(V[:p, :p]); the top order gets none.
        top = S_scaled[:-1, -1:]
        S_w = np.zeros((P, P))
        S_w[:-1, :-1] = S_scaled[:-1, :-1] - top @ top.T / S_scaled[-1, -1]
        log_det_S_w = float(np.linalg.slogdet(S_w[:-1, :-1])[1] + 2 * np.sum(np.arange(P - 1) * np.log(sigma)))
        motion_orders = P - 1
    elif top_order != "truncate":
        raise AttendInputError(f"top_order: expected 'marginal' or 'truncate', got {top_order!r}")
    st = _Structure(
        n=n, r=r, m=m, orders=P, S=S_scaled, S_w=S_w, log_det_S_w=log_det_S_w, motion_orders=motion_orders,
        log_det_S=float(np.linalg.slogdet(S_scaled)[1] + 2 * np.sum(np.arange(P) * np.log(sigma))),
        Dx=shift_operator(P, n) / sigma, n_used=int(used.sum()), used=used, active=active,
        perm=internal_parameter_order(n, r, m), path=path,
        E=embedding_weights(P, dt) * scale[:P, None] if path else None,
        count=1.0 / P if path else 1.0, time_scale=sigma,
        log_jacobian=float(np.sum(np.arange(P) * np.log(sigma))),
    )
    return st, Ytil, Util
