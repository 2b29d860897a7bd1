"""The free energy F (eq. 8) and its pieces: the D-step maximiser, the S-weighted moments K, the
expected energy as a quadratic in theta, the E-step target and the M-step gradient."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend.perception.learning.path import _path_posterior
from attend.perception.learning.problem import _bkron, _observer, _Priors, _State, _Structure


def _d_step(theta, lam, Ytil, Util, st: _Structure):
    """Per-sample maximiser of the energy: mu_t = inv(Pi_X)(C~' Vy y~_t + (D - A~)' W B~ u~_t);
    in path mode the maximiser over one state path (:func:`_path_posterior`)."""
    if st.path:
        return _path_posterior(theta, lam, Ytil, Util, st).mean
    R, T = Ytil.shape[:2]
    _, Sigma_X, CtVy, MtWB = _observer(theta, lam, st)
    with np.errstate(all="ignore"):
        gain_y = Sigma_X @ CtVy  # (R, P n, P m)
        gain_u = Sigma_X @ MtWB  # (R, P n, P r)
        mu = Ytil.reshape(R, T, -1) @ np.swapaxes(gain_y, 1, 2) + Util.reshape(R, T, -1) @ np.swapaxes(gain_u, 1, 2)
    return mu.reshape(R, T, st.orders, st.n)


def _mean_moments(mu, Ytil, Util, st: _Structure) -> np.ndarray:
    """sum_t sum_ij S_ij z^(i) z^(j)' at the means, z = [x; u; y; tau] (R, dz, dz)."""
    R = mu.shape[0]
    P = st.orders
    used = st.used
    x = mu[:, used]
    tau = np.concatenate([x[:, :, 1:], np.zeros_like(x[:, :, :1])], axis=2) / st.time_scale
    Z = np.concatenate([x, Util[:, used], Ytil[:, used], tau], axis=3)  # (R, T', P, dz)
    dz = Z.shape[-1]
    Zf = np.ascontiguousarray(Z.reshape(R, -1, P * dz))
    with np.errstate(all="ignore"):
        second = (np.ascontiguousarray(np.swapaxes(Zf, 1, 2)) @ Zf).reshape(R, P, dz, P, dz)
        K = np.einsum("sij,riajb->rsab", np.stack([st.S, st.S_motion]), second)
    return 0.5 * (K + np.swapaxes(K, 2, 3))


def _covariance_moments(Sigma_X, st: _Structure) -> np.ndarray:
    """n_t sum_ij S_ij Cov(z^(i), z^(j)) from Sigma_X (only x and tau = x^(i+1) are uncertain)."""
    R = Sigma_X.shape[0]
    n, r, m, P = st.n, st.r, st.m, st.orders
    dz = 2 * n + r + m
    Sp = np.zeros((R, P + 1, n, P + 1, n))
    Sp[:, :P, :, :P] = Sigma_X.reshape(R, P, n, P, n)
    cov = np.zeros((R, P, dz, P, dz))
    ix, it = slice(0, n), slice(n + r + m, dz)
    c = 1.0 / st.time_scale  # tau = x^(i+1) in scaled coordinates is x'_(i+1) / sigma
    cov[:, :, ix, :, ix] = Sp[:, :P, :, :P]
    cov[:, :, ix, :, it] = Sp[:, :P, :, 1:] * c
    cov[:, :, it, :, ix] = Sp[:, 1:, :, :P] * c
    cov[:, :, it, :, it] = Sp[:, 1:, :, 1:] * (c * c)
    K = st.n_used * np.einsum("sij,riajb->rsab", np.stack([st.S, st.S_motion]), cov)
    return 0.5 * (K + np.swapaxes(K, 2, 3))


class _Quadratic(NamedTuple):
    """Expected energy pieces in the internal order: E_w(theta) and E_z(theta) (unit precision).

    E_w = th_ab' Hw th_ab - 2 gw' th_ab + cw, E_z = th_c' Hz th_c - 2 gz' th_c + cz.
    """

    Hw: np.ndarray  # (R, n(n+r), n(n+r))
    gw: np.ndarray
    cw: np.ndarray
    Hz: np.ndarray  # (R, m n, m n)
    gz: np.ndarray
    cz: np.ndarray


def _quadratic(K: np.ndarray, st: _Structure) -> _Quadratic:
    n, r, m = st.n, st.r, st.m
    R = K.shape[0]
    phi = slice(0, n + r)
    xs = slice(0, n)
    ys = slice(n + r, n + r + m)
    ts = slice(n + r + m, n + r + m + n)
    Ky, Kw = K[:, 0], K[:, 1]  # weighted with S (sensory) and S_w (motion)
    K_pp = Kw[:, phi, phi]
    Hw = _bkron(np.eye(n), K_pp)
    gw = Kw[:, ts, phi].reshape(R, -1)
    cw = np.trace(Kw[:, ts, ts], axis1=1, axis2=2)
    Hz = _bkron(np.eye(m), Ky[:, xs, xs])
    gz = Ky[:, ys, xs].reshape(R, -1)
    cz = np.trace(Ky[:, ys, ys], axis1=1, axis2=2)
    return _Quadratic(Hw, gw, cw, Hz, gz, cz)


def _full_hessian(q: _Quadratic, lam: np.ndarray, st: _Structure):
    """H (internal order) = blkdiag(exp(lambda_w) Hw, exp(lambda_z) Hz) and its parts."""
    R = lam.shape[0]
    nab = st.n_ab
    H_w = np.zeros((R, st.n_theta, st.n_theta))
    H_z = np.zeros_like(H_w)
    pw, pz = st.count * np.exp(lam[:, 1]), st.count * np.exp(lam[:, 0])
    H_w[:, :nab, :nab] = q.Hw * pw[:, None, None]
    H_z[:, nab:, nab:] = q.Hz * pz[:, None, None]
    g = np.concatenate([q.gw * pw[:, None], q.gz * pz[:, None]], axis=1)
    return H_w, H_z, g


def _energies(q: _Quadratic, theta_int: np.ndarray, st: _Structure):
    """E_w, E_z (R,) at theta (internal order), unit precision."""
    nab = st.n_ab
    tw, tz = theta_int[:, :nab], theta_int[:, nab:]
    Ew = np.einsum("ra,rab,rb->r", tw, q.Hw, tw) - 2 * np.einsum("ra,ra->r", q.gw, tw) + q.cw
    Ez = np.einsum("ra,rab,rb->r", tz, q.Hz, tz) - 2 * np.einsum("ra,ra->r", q.gz, tz) + q.cz
    return Ew, Ez


def _scaled_slogdet(M: np.ndarray) -> np.ndarray:
    """ln|M| for SPD M (R, k, k) after Jacobi scaling (entries may span 1e-2 .. 1e14)."""
    if M.shape[-1] == 0:
        return np.zeros(M.shape[0])
    d = np.sqrt(np.abs(np.diagonal(M, axis1=1, axis2=2)))
    d = np.where(d > 0, d, 1.0)
    sign, logdet = np.linalg.slogdet(M / d[:, :, None] / d[:, None, :])
    return np.where(sign > 0, logdet + 2 * np.log(d).sum(axis=1), np.nan)


def _scaled_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.abs(np.diagonal(M, axis1=1, axis2=2)))
    d = np.where(d > 0, d, 1.0)
    x = np.linalg.solve(M / d[:, :, None] / d[:, None, :], (b / d)[..., None])[..., 0]
    return x / d


class _Evaluation(NamedTuple):
    F: np.ndarray  # (R,)
    K: np.ndarray  # (R, dz, dz) moments including the state uncertainty
    Pi_theta: np.ndarray  # (R, k, k) active entries (public order among the active)
    Sigma_theta: np.ndarray
    H_w: np.ndarray  # (R, k, k) active block of the motion part of H
    H_z: np.ndarray
    Ew: np.ndarray
    Ez: np.ndarray


def _evaluate(state: _State, K_mean: np.ndarray, priors: _Priors, st: _Structure,
              Sigma_X: np.ndarray | None = None) -> _Evaluation:
    """The free energy F (R,) and the parameter posterior at the current state.

    With Sigma_X None (the learner), Sigma_X = inv(Pi_X(theta, lambda)) and F is eq. 8; a given
    Sigma_X holds q(X) fixed (the objective of the E- and M-steps, used by the tests).
    """
    n, m, P = st.n, st.m, st.orders
    lam = state.lam
    path_entropy = None
    if Sigma_X is None and st.path:
        posterior = _path_posterior(state.theta, lam, None, None, st, want_mean=False)
        Sigma_X, path_entropy = posterior.sigma_mean, posterior.entropy
    elif Sigma_X is None:
        Sigma_X = _observer(state.theta, lam, st)[1]
    with np.errstate(all="ignore"):
        K = K_mean + _covariance_moments(Sigma_X, st)
    q = _quadratic(K, st)
    theta_int = state.theta[:, st.perm]
    Ew, Ez = _energies(q, theta_int, st)
    H_w, H_z, _ = _full_hessian(q, lam, st)
    # back to public order, active block
    inv = np.argsort(st.perm)
    act = st.active
    H_w = H_w[:, inv][:, :, inv][:, act][:, :, act]
    H_z = H_z[:, inv][:, :, inv][:, act][:, :, act]
    P_act = priors.P_theta[:, act]
    Pi_theta = H_w + H_z + P_act[:, :, None] * np.eye(P_act.shape[1])[None]
    with np.errstate(all="ignore"):
        Sigma_theta = np.linalg.inv(Pi_theta) if Pi_theta.shape[1] else Pi_theta.copy()
        dim_X = n * P
        sign, logdet_sigma = np.linalg.slogdet(Sigma_X)
        logdet_sigma = np.where(sign > 0, logdet_sigma - 2 * n * st.log_jacobian, np.nan)
        energy = -0.5 * st.count * (np.exp(lam[:, 0]) * Ez + np.exp(lam[:, 1]) * Ew)
        entropy_x = 0.5 * st.n_used * (logdet_sigma + dim_X) if path_entropy is None else path_entropy
        log_det_S_w = st.log_det_S if st.log_det_S_w is None else st.log_det_S_w
        noise = 0.5 * st.count * st.n_used * (m * st.log_det_S + n * log_det_S_w + P * m * lam[:, 0]
                                              + st.w_orders * n * lam[:, 1])
        e_theta = state.theta[:, act] - priors.eta_theta[:, act]
        prior_theta = -0.5 * np.sum(P_act * e_theta**2, axis=1)
        finite_l = np.isfinite(priors.P_lambda)
        P_l = np.where(finite_l, priors.P_lambda, 0.0)
        prior_lambda = -0.5 * np.sum(P_l * (lam - priors.eta_lambda) ** 2, axis=1)
        logP = np.where(P_act > 0, np.log(np.where(P_act > 0, P_act, 1.0)), 0.0)
        entropy_theta = 0.5 * (logP.sum(axis=1) - _scaled_slogdet(Pi_theta))
        ratio = np.where(finite_l, P_l / (P_l + priors.fisher[None]), 1.0)
        entropy_lambda = 0.5 * np.sum(np.log(np.where(ratio > 0, ratio, 1.0)), axis=1)
        F = energy + entropy_x + noise + prior_theta + prior_lambda + entropy_theta + entropy_lambda
    F = np.where(np.isfinite(F), F, -np.inf)
    return _Evaluation(F, K, Pi_theta, Sigma_theta, H_w, H_z, Ew, Ez)


def _e_step_target(state: _State, K: np.ndarray, priors: _Priors, st: _Structure):
    """theta* = inv(H + P)(g - H_af theta_f + P eta) over the active entries, and J = -(H + P)."""
    q = _quadratic(K, st)
    H_w, H_z, g = _full_hessian(q, state.lam, st)
    inv = np.argsort(st.perm)
    H = (H_w + H_z)[:, inv][:, :, inv]
    g = g[:, inv]
    act = st.active
    fixed = ~act
    P_act = priors.P_theta[:, act]
    H_aa = H[:, act][:, :, act]
    rhs = g[:, act] + P_act * priors.eta_theta[:, act]
    if fixed.any():
        rhs = rhs - np.einsum("rab,rb->ra", H[:, act][:, :, fixed], state.theta[:, fixed])
    Pi = H_aa + P_act[:, :, None] * np.eye(P_act.shape[1])[None]
    target = _scaled_solve(Pi, rhs)
    return target, -Pi


def _flow_step(J: np.ndarray, start: np.ndarray, target: np.ndarray, time: np.ndarray) -> np.ndarray:
    """theta(L) = target + expm(L J)(start - target): the gradient flow of a concave quadratic."""
    evals, evecs = np.linalg.eigh(0.5 * (J + np.swapaxes(J, 1, 2)))
    decay = np.exp(np.clip(time[:, None] * evals, -700, 0))
    delta = np.einsum("rab,rb->ra", np.swapaxes(evecs, 1, 2), start - target)
    return target + np.einsum("rab,rb->ra", evecs, decay * delta)


def _m_gradient(ev: _Evaluation, state: _State, priors: _Priors, st: _Structure) -> np.ndarray:
    """dF/dlambda (R, 2), exact for fixed q(X) and theta (with the N Sigma_theta N' term)."""
    lam = state.lam
    tr_z = np.einsum("rab,rba->r", ev.Sigma_theta, ev.H_z)
    tr_w = np.einsum("rab,rba->r", ev.Sigma_theta, ev.H_w)
    P = st.orders
    P_l = np.where(np.isfinite(priors.P_lambda), priors.P_lambda, 0.0)
    c = st.count
    gz = -0.5 * (c * np.exp(lam[:, 0]) * ev.Ez + tr_z) + 0.5 * c * st.n_used * st.m * P
    gw = -0.5 * (c * np.exp(lam[:, 1]) * ev.Ew + tr_w) + 0.5 * c * st.n_used * st.n * st.w_orders
    grad = np.stack([gz, gw], axis=1) - P_l * (lam - priors.eta_lambda)
    return np.where(np.isfinite(priors.P_lambda), grad, 0.0)


def curvature_default(fisher, P_lam):
    """Pi_lambda = n_t/2 diag(m(p+1), n(p+1)) + P_lambda (negated, i.e. d2F/dlambda2)."""
    return -(fisher[None] + np.where(np.isfinite(P_lam), P_lam, np.inf))
