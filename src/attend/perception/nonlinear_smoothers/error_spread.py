"""The unscented smoother's error spread under coloured noise: the std it reports when its
white-noise model stands in for noise that is correlated from sample to sample.

The smoother's own covariance assumes independent noise at every sample. Under noise correlated
over ~s/dt samples its errors are larger than that covariance says (Lorenz and pendulum
reproductions, s/dt = 2: |error| < 2 std in 60-73 % of the samples instead of 95 %). Linearised
at the estimate by the filter's own statistical regressions, the error e = estimate - truth is
linear in the noises::

    predicted  e^p_k = A_k e^f_{k-1} - q_k,           A_k = cross_{k-1}' inv(Pf_{k-1})
    filtered   e^f_k = (I - K_k H_k) e^p_k + K_k r_k,  H_k = Cy_k' inv(Pp_k)
    smoothed   e^s_k = e^f_k + G_k (e^s_{k+1} - e^p_{k+1})

with q_k the process noise over sample k (dt w_{k-1}, and for unknown inputs the input's step
v_k - v_{k-1}), r_k the sensor noise, e^p_0 drawn from the prior on x[0] (and minus the input's
first deviation). w, r and v are drawn from the coloured generative model: per-sample covariances
Q / dt^2 and R, Gaussian kernel of width s; unknown inputs v = m0_v + a draw of their prior
(per-sample variance and width s_v). The reported std is sqrt(mean over draws of e^2) (relative
error about 1 / sqrt(2 draws)): the spread of the estimator itself under the coloured noise, as
path mode's (:mod:`attend.perception.nonlinear.path`). For white noise (s = 0) and a linear model
it is the smoother's own std (tests/perception/test_nonlinear_error_spread.py).

:func:`smoother_error_covariance` computes the same covariance exactly, without draws (what the
draws' mean converges to; ``spread_draws=None`` in the smoothers, and ``attend estimate``). Each
coloured channel is a moving average of unit white noise, c_k = sum_i h_i eps_{k-i} over the L
taps of the kernel (:func:`attend.models.noise.gaussian_kernel`, the one the draws use), so
psi_k = [e^f_k; window_k], window_k = (eps_k, ..., eps_{k-L+1}) of every channel, is a linear
Markov chain whose window is white (Cov = I). The forward pass carries P_k = Cov(e^f_k) and
X_k = Cov(e^f_k, window_k) (d x L x channels)::

    P_k = C_k P_k-1 C_k' + C_k X'_k-1 D_k' + D_k X'_k-1' C_k' + D_k D_k'
    X_k = C_k X'_k-1 + D_k                 (X' = X shifted by one lag, C_k = M_k A_k-1)

with D_k the loading of e^f_k on window_k (K_k on the sensor taps, -M_k on the process and input
taps). The smoothed error is e^s_k = U_k psi_k + f_k, f_k independent of psi_k, Cov(f_k) = V_k,
by a backward pass from U_N-1 = [I, 0], V_N-1 = 0::

    Z     = (U^e_k+1 D_k+1 + Qsel) + U^w_k+1     (the loading of e^s_k+1 + q_k+1 on window_k+1)
    U^e_k = I - G_k A_k + G_k U^e_k+1 C_k+1,  U^w_k = G_k Z (one lag older),
    V_k   = G_k (Z_0 Z_0' + V_k+1) G_k'       (Z_0: the taps of the new white noise eps_k+1)
    Cov(e^s_k) = U_k Cov(psi_k) U_k' + V_k.

Cost O(N d^2 channels L) with no random numbers; memory O(N d^2) plus the windows X_k of one
block of samples (recomputed from checkpoints when N d channels L exceeds ``DRAW_BUDGET``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError
from attend.models.noise import coloured_noise, gaussian_kernel

#: floats held at once by the error draws (N samples x d coordinates x draws x 3 arrays), and by
#: the exact covariance's windows X_k (samples x d x channels x taps)
DRAW_BUDGET = 20_000_000


def _regressions(record: dict) -> tuple[np.ndarray, np.ndarray]:
    """(A (N-1, d, d), H (N, m, d)): the filter's statistical linear regressions of the transition
    and of the observation (record: from kalman._unscented or extended_kalman), by pseudo-inverses:
    a measured input riding in the state has zero variance. The unscented filter's cross
    covariances come from sigma points that stand for Pf + jitter (the Cholesky's 1e-12
    max(1, trace)); they are divided by that covariance (``Pf_points``, ``Pp_points``), so that
    a linear map is recovered exactly: dividing by Pf itself blows the directions where Pf is far
    below the jitter up by jitter / eigenvalue (x[0] known, near-deterministic motion: a spread
    20-50x the errors on SPM's Lorenz with W = e^16)."""
    A = (np.linalg.pinv(record.get("Pf_points", record["Pf"][:-1]), hermitian=True) @ record["cross"]).swapaxes(1, 2)
    H = (np.linalg.pinv(record.get("Pp_points", record["Pp"]), hermitian=True) @ record["Cy"]).swapaxes(1, 2)
    return A, H


def _root(covariance: np.ndarray) -> np.ndarray:
    """L with L L' = covariance (k, k) positive semi-definite (zero variances allowed)."""
    try:
        return np.linalg.cholesky(covariance)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(covariance)
        return vectors * np.sqrt(np.clip(values, 0.0, None))


def _draws(rng, count: int, N: int, dt: float, kernel_width: float, covariance: np.ndarray) -> np.ndarray:
    """(N, k, count) coloured noise of per-sample covariance ``covariance`` (k, k), kernel width s [s]."""
    k = covariance.shape[0]
    root = _root(covariance)
    unit = coloured_noise(N, k * count, dt, kernel_width, 1.0, rng).reshape(N, count, k)
    return np.einsum("ij,ncj->nic", root, unit)


def propagate_errors(record: dict, A, H, first, q, r, smooth: bool) -> np.ndarray:
    """(N, d, count) filter (smooth False) or smoother (True) errors for given noises, by the
    linearised recursions of the module docstring. record: the filter's linearisation (K, RTS
    gains); A (N-1, d, d), H (N, m, d): its regressions (:func:`_regressions`); first (d, count):
    e^p_0; q (N, d, count): the step noises (q_0 unused: 0); r (N, m, count): the sensor noises."""
    K, gains = record["K"], record["gains"]
    N, d = K.shape[0], K.shape[1]
    update = np.eye(d) - K @ H  # M_k
    carry = update[1:] @ A  # M_k A_k-1
    # e^f_k = M_k A_k-1 e^f_k-1 + (K_k r_k - M_k q_k), M_k = I - K_k H_k: one product per sample
    drive = np.einsum("nim,nmc->nic", K, r) - np.einsum("nij,njc->nic", update, q)
    filtered = np.empty((N, d, first.shape[1]))
    filtered[0] = update[0] @ first + drive[0]
    for k in range(1, N):
        filtered[k] = carry[k - 1] @ filtered[k - 1] + drive[k]
    if smooth:
        predicted = np.einsum("nij,njc->nic", A, filtered[:-1]) - q[1:]  # e^p_k, k >= 1
        for k in range(N - 2, -1, -1):
            filtered[k] += gains[k] @ (filtered[k + 1] - predicted[k])
    return filtered


@np.errstate(over="ignore", invalid="ignore")  # growing error dynamics are reported at the end, as an error
def smoother_error_spread(model, record: dict, kernel_width: float, input_prior, smooth: bool, draws: int,
                          seed: int) -> np.ndarray:
    """(N, d, d) covariances of the unscented filter's (smooth False) or smoother's (True) errors
    under coloured noise (module docstring).

    model: the Kalman baselines' _Model (dt, Q, R, P0, m0, augmentation); record: the filter's
    linearisation (kalman._unscented); kernel_width: s [s] of the process and sensor noises;
    input_prior: (per-sample covariance (r, r), kernel width s_v [s]) of unknown inputs, or None;
    draws: noise draws; seed: their seed."""
    A, H = _regressions(record)
    N, d = record["K"].shape[0], record["K"].shape[1]
    n, dt = model.system.n_states, model.dt
    unknown = np.flatnonzero(~model.known) if model.augmented else np.zeros(0, dtype=int)
    rng = np.random.default_rng(seed)
    root0 = _root(model.P0[:n, :n])
    batch = max(1, min(draws, DRAW_BUDGET // max(1, 3 * N * d)))
    second = np.zeros((N, d, d))
    done = 0
    while done < draws:
        count = min(batch, draws - done)
        q = np.zeros((N, d, count))
        q[1:, :n] = dt * _draws(rng, count, N, dt, kernel_width, model.Q / dt**2)[:-1]
        r = _draws(rng, count, N, dt, kernel_width, model.R)
        first = np.zeros((d, count))
        first[:n] = root0 @ rng.standard_normal((n, count))
        if unknown.size:
            variance, width = input_prior
            deviation = np.zeros((N, model.system.n_inputs, count))
            deviation[:, unknown] = _draws(rng, count, N, dt, width, np.asarray(variance)[np.ix_(unknown, unknown)])
            q[1:, n:] = np.diff(deviation, axis=0)
            first[n:] = -deviation[0]
        errors = propagate_errors(record, A, H, first, q, r, smooth)
        second += np.einsum("nic,njc->nij", errors, errors)
        done += count
    if not np.all(np.isfinite(second)):
        first_bad = int(np.argmax(~np.isfinite(second).all(axis=(1, 2))))
        raise AttendInputError(f"noise_kernel_width: the error spread became non-finite at sample {first_bad} (the "
                               "filter's linearised error dynamics grow there); report the white-noise std "
                               "(noise_kernel_width=None) or check the model's stability and noise settings")
    return second / draws


def _taps(dt: float, kernel_width: float) -> np.ndarray:
    """The kernel h (L,) of the coloured noise of width s (a single tap 1 for white noise, s = 0):
    the one :func:`attend.models.noise.coloured_noise` convolves unit white noise with."""
    return np.ones(1) if kernel_width == 0 else gaussian_kernel(dt, kernel_width)


class _Group(NamedTuple):
    """Coloured channels sharing one kernel, as moving averages of unit white noise: the loading of
    e^f_k on the channels' noise at sample k is ``load[k]`` (d, c) times the taps ``coef`` (L,) on
    the lags 0..L-1 of the window (``first_coef`` at k = 0); q_k (k >= 1) loads ``q_load`` (d, c)
    times the same taps."""

    load: np.ndarray
    q_load: np.ndarray
    coef: np.ndarray
    first_coef: np.ndarray


def _groups(model, K, update, kernel_width: float, input_prior) -> list[_Group]:
    """The coloured noises of the linearised error (module docstring) in two groups: sensor and
    process noise (kernel width s; no process noise before sample 0, the prior on x[0] stands for
    it) and the unknown inputs' deviations from their prior mean (width s_v; q_k = dev_k - dev_k-1,
    e^p_0 = -dev_0)."""
    d = K.shape[1]
    n, dt = model.system.n_states, model.dt
    h = _taps(dt, kernel_width)
    root_r = _root(model.R)
    process_q = np.zeros((d, n))
    process_q[:n] = dt * _root(model.Q / dt**2)
    process = -update @ process_q
    process[0] = 0.0
    groups = [_Group(np.concatenate([K @ root_r, process], axis=2),
                     np.concatenate([np.zeros((d, root_r.shape[1])), process_q], axis=1), h, h)]
    unknown = np.flatnonzero(~model.known) if model.augmented else np.zeros(0, dtype=int)
    if unknown.size:
        variance, width = input_prior
        input_q = np.zeros((d, unknown.size))
        input_q[n + unknown] = _root(np.asarray(variance)[np.ix_(unknown, unknown)])
        h_v = _taps(dt, width)
        step = np.diff(np.concatenate([[0.0], h_v, [0.0]]))  # dev_k - dev_k-1 = sum_j (h_j - h_j-1) eps_k-j
        groups.append(_Group(-update @ input_q, input_q, step, np.append(h_v, 0.0)))
    return groups


def _forward(groups: list[_Group], x0, carry, k: int, P, X: list) -> tuple[np.ndarray, list]:
    """(P_k, [X_k per group]) from (P_k-1, X_k-1) (module docstring; k = 0: from the prior, with
    x0 the loading of e^f_0 on x[0]'s unit noise; P and X ignored). X_k: (d, L, c), Cov(e^f_k, the
    white noise of lag l of channel c)."""
    if k == 0:
        P = x0 @ x0.T
        for group in groups:
            load, taps = group.load[0], group.first_coef
            P = P + (load * (taps @ taps)) @ load.T
        return 0.5 * (P + P.T), [group.load[0][:, None, :] * group.first_coef[:, None] for group in groups]
    C = carry[k - 1]
    d = C.shape[0]
    P = C @ P @ C.T
    windows = []
    for group, old in zip(groups, X):
        load, taps = group.load[k], group.coef
        new = np.empty_like(old)
        # C_k X'_k-1: lag l of window_k is lag l - 1 of window_k-1 (the new lag 0 is independent)
        new[:, 1:] = (C @ old[:, :-1].reshape(d, -1)).reshape(d, old.shape[1] - 1, old.shape[2])
        mixed = (taps[1:] @ new[:, 1:]) @ load.T
        P = P + mixed + mixed.T + (load * (taps @ taps)) @ load.T
        new[:, 1:] += load[:, None, :] * taps[1:, None]
        new[:, 0] = load * taps[0]
        windows.append(new)
    return 0.5 * (P + P.T), windows


@np.errstate(over="ignore", invalid="ignore")  # growing error dynamics are reported at the end, as an error
def smoother_error_covariance(model, record: dict, kernel_width: float, input_prior, smooth: bool) -> np.ndarray:
    """(N, d, d) covariances of the unscented filter's (smooth False) or smoother's (True) errors
    under coloured noise, exactly: the limit of :func:`smoother_error_spread` as the draws grow,
    by the forward and backward recursions of the module docstring (no random numbers).

    model: the Kalman baselines' _Model (dt, Q, R, P0, augmentation); record: the filter's
    linearisation (kalman._unscented); kernel_width: s [s] of the process and sensor noises;
    input_prior: (per-sample covariance (r, r), kernel width s_v [s]) of unknown inputs, or None."""
    A, H = _regressions(record)
    K = record["K"]
    gains = record["gains"]
    N, d = K.shape[0], K.shape[1]
    update = np.eye(d) - K @ H  # M_k
    carry = update[1:] @ A  # C_k = M_k A_k-1, (N-1, d, d)
    groups = _groups(model, K, update, kernel_width, input_prior)
    n = model.system.n_states
    x0 = update[0][:, :n] @ _root(model.P0[:n, :n])  # e^f_0's loading on x[0]'s unit noise
    size = d * sum(group.load.shape[2] * len(group.coef) for group in groups)  # floats of one window X_k
    block = int(max(1, min(N, DRAW_BUDGET // max(1, size))))
    keep = bool(smooth) and block >= N  # all windows fit: keep them for the backward pass
    P = np.empty((N, d, d))
    checkpoints, windows = {}, []
    X = None
    for k in range(N):
        if k % block == 0:
            checkpoints[k] = X  # X_k-1 (None at k = 0)
        P[k], X = _forward(groups, x0, carry, k, P[k - 1] if k else None, X)
        if keep:
            windows.append(X)
    if smooth:
        forward = lambda k, X: _forward(groups, x0, carry, k, P[k - 1] if k else None, X)[1]  # noqa: E731
        P = _smoothed(groups, forward, carry, A, gains, P, checkpoints, block, windows if keep else None)
    if not np.all(np.isfinite(P)):
        first_bad = int(np.argmax(~np.isfinite(P).all(axis=(1, 2))))
        raise AttendInputError(f"noise_kernel_width: the error spread became non-finite at sample {first_bad} (the "
                               "filter's linearised error dynamics grow there); report the white-noise std "
                               "(noise_kernel_width=None) or check the model's stability and noise settings")
    return P


def _smoothed(groups: list[_Group], forward, carry, A, gains, P, checkpoints: dict, block: int, kept) -> np.ndarray:
    """Cov(e^s_k) (N, d, d) by the backward pass (P: the filtered error covariances), with the
    windows X_k ``kept`` by the forward pass, or (None) recomputed block by block by ``forward(k,
    X_k-1)`` from the ``checkpoints`` X_start-1."""
    N, d = P.shape[0], P.shape[1]
    out = np.empty_like(P)
    eye = np.eye(d)
    Ue, V = eye.copy(), np.zeros((d, d))
    Uw = [np.zeros((d, len(group.coef), group.load.shape[2])) for group in groups]
    for start in range(((N - 1) // block) * block, -1, -block):
        stop = min(start + block, N)
        if kept is not None:
            windows = kept[start:stop]
        else:
            windows, X = [], checkpoints[start]
            for k in range(start, stop):
                X = forward(k, X)
                windows.append(X)
        for k in range(stop - 1, start - 1, -1):
            if k < N - 1:
                G = gains[k]
                new = np.zeros((d, d))
                for index, group in enumerate(groups):
                    # Z: the loading of e^s_k+1 + q_k+1 on window_k+1
                    Z = (Ue @ group.load[k + 1] + group.q_load)[:, None, :] * group.coef[:, None] + Uw[index]
                    new += Z[:, 0] @ Z[:, 0].T
                    older = np.empty_like(Z)  # U^w_k: lag l of window_k is lag l + 1 of window_k+1
                    older[:, :-1] = (G @ Z[:, 1:].reshape(d, -1)).reshape(d, Z.shape[1] - 1, Z.shape[2])
                    older[:, -1] = 0.0
                    Uw[index] = older
                V = G @ (new + V) @ G.T
                Ue = eye - G @ A[k] + G @ Ue @ carry[k]
            cov = Ue @ P[k] @ Ue.T + V
            for X, W in zip(windows[k - start], Uw):
                W = W.reshape(d, -1)
                mixed = (Ue @ X.reshape(d, -1)) @ W.T
                cov += mixed + mixed.T + W @ W.T
            out[k] = 0.5 * (cov + cov.T)
    return out
