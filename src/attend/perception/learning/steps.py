"""The learner's steps. Each takes the point the learner stands at (q(X), theta, lambda, F there),
tries its move on the live runs and returns the new point, what it accepted (one (runs, F) pair
per accepting trial, in order) and the runs whose every trial gave a non-finite free energy.
A move is accepted for a run only if F does not decrease (strictly rises for the extra moves).

* :func:`d_step`: the exact maximiser of q(X) for the current (theta, lambda), halved on failure.
* :func:`e_step`: the gradient flow of the expected energy's quadratic in theta over the time L.
* :func:`m_step`: clipped steps on the noise log-precisions lambda = [lambda_z, lambda_w].
* :func:`overrelax_step` and :func:`newton_step`: the extra moves of options (3) and (4) of the
  package docstring.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend.perception.learning.free_energy import (
    _d_step,
    _e_step_target,
    _evaluate,
    _Evaluation,
    _flow_step,
    _m_gradient,
    _mean_moments,
)
from attend.perception.learning.problem import _Priors, _State, _Structure

NEWTON_CREEP = 1e-4  # newton=True: a Newton step once a D-E-M sweep gains < this * |F|


class _Data(NamedTuple):
    """The embedded logs and the structure they share (fixed during learning)."""

    st: _Structure
    Ytil: np.ndarray  # (R, T, P, m)
    Util: np.ndarray  # (R, T, P, r)


class _Point(NamedTuple):
    """Where the learner stands: the variational state, F and the parameter posterior there, and
    the S-weighted moments at the state means."""

    state: _State
    ev: _Evaluation
    K_mean: np.ndarray


class _Outcome(NamedTuple):
    """What a step did: the new point, the accepted trials ((runs (R,) bool, F (R,)), ...) in order,
    and the runs (R,) bool whose every trial step gave a non-finite free energy."""

    point: _Point
    accepted: tuple
    diverged: np.ndarray


def _where(mask: np.ndarray, new, old):
    """Per run (leading axis): the fields of ``new`` where mask holds, else those of ``old``."""
    return type(old)(*(np.where(mask.reshape((-1,) + (1,) * (a.ndim - 1)), a, b) for a, b in zip(new, old)))


def start(theta: np.ndarray, lam: np.ndarray, data: _Data, priors: _Priors) -> _Point:
    """The initial D-step (no check: there is no previous q(X)) and F there."""
    mu = _d_step(theta, lam, data.Ytil, data.Util, data.st)
    state = _State(mu, theta, lam)
    K_mean = _mean_moments(mu, data.Ytil, data.Util, data.st)
    return _Point(state, _evaluate(state, K_mean, priors, data.st), K_mean)


def d_step(point: _Point, live: np.ndarray, data: _Data, priors: _Priors) -> _Outcome:
    """D-step: q(X) moves to its exact maximiser (path mode: over one path), halved up to 5 times
    until F does not decrease."""
    state, ev, K_mean = point
    st, Ytil, Util = data
    R = live.shape[0]
    mu_new = _d_step(state.theta, state.lam, Ytil, Util, st)
    pending = live.copy()
    alpha = 1.0
    seen_finite = np.zeros(R, dtype=bool)
    accepted = []
    for _ in range(6):
        cand = state._replace(mu=state.mu + alpha * (mu_new - state.mu))
        with np.errstate(all="ignore"):
            K_c = _mean_moments(cand.mu, Ytil, Util, st)
        ev_c = _evaluate(cand, K_c, priors, st)
        seen_finite |= np.isfinite(ev_c.F)
        ok = pending & (ev_c.F >= ev.F)
        if ok.any():
            state = _where(ok, cand, state)
            K_mean = np.where(ok[:, None, None, None], K_c, K_mean)
            ev = _where(ok, ev_c, ev)
            accepted.append((ok, ev.F))
            pending &= ~ok
        if not pending.any():
            break
        alpha *= 0.5
    return _Outcome(_Point(state, ev, K_mean), tuple(accepted), pending & ~seen_finite)


def e_step(point: _Point, live: np.ndarray, data: _Data, priors: _Priors, integration_time: np.ndarray) -> _Outcome:
    """E-step: theta <- theta* + expm(L J)(theta - theta*) over the integration time L (R,), halved
    up to 7 times until F does not decrease (q(X) held fixed)."""
    state, ev, K_mean = point
    st = data.st
    R = live.shape[0]
    with np.errstate(all="ignore"):
        target, J = _e_step_target(state, ev.K, priors, st)
    pending = live.copy()
    time = integration_time.copy()
    seen_finite = np.zeros(R, dtype=bool)
    accepted = []
    for _ in range(8):
        theta_c = state.theta.copy()
        with np.errstate(all="ignore"):
            theta_c[:, st.active] = _flow_step(J, state.theta[:, st.active], target, time)
        finite = np.all(np.isfinite(theta_c), axis=1)
        theta_c = np.where(finite[:, None], theta_c, state.theta)
        cand = state._replace(theta=theta_c)
        ev_c = _evaluate(cand, K_mean, priors, st)
        seen_finite |= np.isfinite(ev_c.F) & finite
        ok = pending & finite & (ev_c.F >= ev.F)
        if ok.any():
            state = _where(ok, cand, state)
            ev = _where(ok, ev_c, ev)
            accepted.append((ok, ev.F))
            pending &= ~ok
        if not pending.any():
            break
        time = time * 0.5
    return _Outcome(_Point(state, ev, K_mean), tuple(accepted), pending & ~seen_finite)


def m_step(point: _Point, live: np.ndarray, data: _Data, priors: _Priors, integration_time: float,
           iterations: int) -> _Outcome:
    """M-step: up to ``iterations`` steps (expm(L c) - 1)/c * dF/dlambda with the expected curvature c,
    clipped to +-2 and halved up to 5 times until F does not decrease (q(X) and theta held fixed)."""
    state, ev, K_mean = point
    st = data.st
    R = live.shape[0]
    curvature = -(priors.fisher[None] + np.where(np.isfinite(priors.P_lambda), priors.P_lambda, 0.0))
    m_live = live.copy()
    accepted = []
    diverged = np.zeros(R, dtype=bool)
    for _ in range(iterations):
        grad = _m_gradient(ev, state, priors, st)
        step = (np.exp(integration_time * curvature) - 1.0) / curvature * grad
        step = np.clip(step, -2.0, 2.0)
        pending = m_live & np.all(np.isfinite(step), axis=1) & (np.abs(step).max(axis=1) > 1e-6)
        if not pending.any():
            break
        moved = np.zeros(R, dtype=bool)
        seen_finite = np.zeros(R, dtype=bool)
        for _ in range(6):
            cand = state._replace(lam=state.lam + step)
            ev_c = _evaluate(cand, K_mean, priors, st)
            seen_finite |= np.isfinite(ev_c.F)
            ok = pending & (ev_c.F >= ev.F)
            if ok.any():
                state = _where(ok, cand, state)
                ev = _where(ok, ev_c, ev)
                accepted.append((ok, ev.F))
                moved |= ok
                pending &= ~ok
            if not pending.any():
                break
            step = step * 0.5
        diverged |= pending & ~seen_finite
        m_live &= moved & ~diverged
    return _Outcome(_Point(state, ev, K_mean), tuple(accepted), diverged)


def overrelax_step(point: _Point, live: np.ndarray, data: _Data, priors: _Priors, before: _State,
                   beta: np.ndarray) -> tuple[_Outcome, np.ndarray]:
    """Over-relaxation: the D-E-M sweep creeps along ridges where the states and the parameters trade
    off (each step is exact for the others fixed, so it moves little). Extend the sweep's total move
    (theta, lambda) since ``before`` by beta times, with the exact D-step at the extended point;
    accepted only if F rises. Returns the outcome and the new beta (doubled after a success, up to
    64, reset to 1 after a failure)."""
    state, ev, K_mean = point
    st, Ytil, Util = data
    none = np.zeros(live.shape[0], dtype=bool)
    if not live.any():
        return _Outcome(point, (), none), beta
    d_theta = state.theta - before.theta
    d_lam = state.lam - before.lam
    theta_c = state.theta + beta[:, None] * d_theta
    lam_c = state.lam + np.clip(beta[:, None] * d_lam, -2.0, 2.0)
    theta_c[:, ~st.active] = state.theta[:, ~st.active]
    with np.errstate(all="ignore"):
        mu_c = _d_step(theta_c, lam_c, Ytil, Util, st)
        K_c = _mean_moments(mu_c, Ytil, Util, st)
    cand = _State(mu_c, theta_c, lam_c)
    ev_c = _evaluate(cand, K_c, priors, st)
    ok = live & np.isfinite(ev_c.F) & (ev_c.F > ev.F) & np.all(np.isfinite(mu_c), axis=(1, 2, 3))
    accepted = ()
    if ok.any():
        state = _where(ok, cand, state)
        K_mean = np.where(ok[:, None, None, None], K_c, K_mean)
        ev = _where(ok, ev_c, ev)
        accepted = ((ok, ev.F),)
    return _Outcome(_Point(state, ev, K_mean), accepted, none), np.where(ok, np.minimum(2 * beta, 64.0), 1.0)


def newton_step(point: _Point, live: np.ndarray, data: _Data, priors: _Priors) -> _Outcome:
    """Newton step on the collapsed free energy F*(theta, lambda) = max over q(X) of F: its gradient
    is dF/d(theta, lambda) at the optimal q(X) (envelope theorem), its Hessian is taken by
    differences of that gradient in scaled coordinates (unit = the current posterior std of each
    entry); Levenberg-Marquardt damping, accepted only if F rises. The caller takes it only once
    the sweeps creep (NEWTON_CREEP): far from the optimum, with the noise precisions still off,
    the collapsed curvature is a poor model of F."""
    none = np.zeros(live.shape[0], dtype=bool)
    if not live.any():
        return _Outcome(point, (), none)
    state, ev, K_mean, ok = _newton_step(point.state, point.ev, point.K_mean, live, priors, data.st, data.Ytil,
                                         data.Util, priors.fisher, priors.P_lambda)
    return _Outcome(_Point(state, ev, K_mean), ((ok, ev.F),), none)


def _collapsed(theta, lam, priors, st, Ytil, Util):
    """q(X) optimal for (theta, lambda), F and dF/d[theta_active, lambda] there."""
    with np.errstate(all="ignore"):
        mu = _d_step(theta, lam, Ytil, Util, st)
        K = _mean_moments(mu, Ytil, Util, st)
    state = _State(mu, theta, lam)
    ev = _evaluate(state, K, priors, st)
    with np.errstate(all="ignore"):
        target, J = _e_step_target(state, ev.K, priors, st)
        g_theta = np.einsum("rab,rb->ra", J, theta[:, st.active] - target)
        g_lam = _m_gradient(ev, state, priors, st)
    return state, ev, K, np.concatenate([g_theta, g_lam], axis=1), J


def _newton_step(state, ev, K_mean, live, priors, st, Ytil, Util, fisher, P_lam):
    """One damped Newton step on F*(theta_active, lambda) for the live runs (see learn_batch)."""
    R = state.theta.shape[0]
    act = np.flatnonzero(st.active)
    k = len(act)
    lam_free = np.isfinite(P_lam)  # (R, 2)
    _, ev0, _, g0, J = _collapsed(state.theta, state.lam, priors, st, Ytil, Util)
    scale = np.concatenate([np.sqrt(np.abs(np.diagonal(J, axis1=1, axis2=2))),
                            np.sqrt(fisher[None] + np.where(lam_free, P_lam, 0.0))], axis=1)  # (R, k + 2)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    free = np.concatenate([np.ones((R, k), bool), lam_free], axis=1)
    h = 1e-3
    dim = k + 2
    Hs = np.zeros((R, dim, dim))
    for j in range(dim):
        theta_j, lam_j = state.theta.copy(), state.lam.copy()
        if j < k:
            theta_j[:, act[j]] += h / scale[:, j]
        else:
            lam_j[:, j - k] += h / scale[:, j]
        g_j = _collapsed(theta_j, lam_j, priors, st, Ytil, Util)[3]
        Hs[:, :, j] = (g_j - g0) / h / scale  # d(g / scale) / dz_j
    Hs = 0.5 * (Hs + np.swapaxes(Hs, 1, 2))
    mask = free[:, :, None] & free[:, None, :]
    Hs = np.where(mask, Hs, 0.0) + np.where(free, 0.0, -1.0)[:, :, None] * np.eye(dim)[None]
    gs = np.where(free, g0 / scale, 0.0)
    ok_any = np.zeros(R, bool)
    pending = live & np.all(np.isfinite(Hs), axis=(1, 2)) & np.all(np.isfinite(gs), axis=1)
    with np.errstate(all="ignore"):
        top = np.max(np.abs(np.linalg.eigvalsh(np.where(np.isfinite(Hs), Hs, 0.0))), axis=1)
    damping = np.zeros(R)
    for attempt in range(6):
        if not pending.any():
            break
        M = -Hs + (damping * np.maximum(top, 1.0))[:, None, None] * np.eye(dim)[None]
        with np.errstate(all="ignore"):
            try:
                dz = np.linalg.solve(M, gs[..., None])[..., 0]
            except np.linalg.LinAlgError:
                dz = np.stack([np.linalg.lstsq(Mk, gk, rcond=None)[0] for Mk, gk in zip(M, gs)])
        dx = np.where(free, dz / scale, 0.0)
        theta_c, lam_c = state.theta.copy(), state.lam.copy()
        theta_c[:, act] += dx[:, :k]
        lam_c += np.clip(dx[:, k:], -2.0, 2.0)
        usable = pending & np.all(np.isfinite(theta_c), axis=1) & np.all(np.isfinite(lam_c), axis=1)
        theta_c = np.where(usable[:, None], theta_c, state.theta)
        lam_c = np.where(usable[:, None], lam_c, state.lam)
        cand, ev_c, K_c, _, _ = _collapsed(theta_c, lam_c, priors, st, Ytil, Util)
        ok = usable & np.isfinite(ev_c.F) & (ev_c.F > ev.F) & np.all(np.isfinite(cand.mu), axis=(1, 2, 3))
        if ok.any():
            sel = ok.reshape(-1, 1, 1, 1)
            state = _State(np.where(sel, cand.mu, state.mu), np.where(ok[:, None], cand.theta, state.theta),
                           np.where(ok[:, None], cand.lam, state.lam))
            K_mean = np.where(sel, K_c, K_mean)
            ev = _Evaluation(*(np.where(ok.reshape((-1,) + (1,) * (a.ndim - 1)), a, b) for a, b in zip(ev_c, ev)))
            ok_any |= ok
            pending &= ~ok
        damping = np.where(damping == 0, 1e-3, damping * 10.0)
    return state, ev, K_mean, ok_any
