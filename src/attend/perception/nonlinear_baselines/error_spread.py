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
"""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.noise import coloured_noise

#: floats held at once by the error draws (N samples x d coordinates x draws x 3 arrays)
DRAW_BUDGET = 20_000_000


def _regressions(record: dict) -> tuple[np.ndarray, np.ndarray]:
    """(A (N-1, d, d), H (N, m, d)): the filter's statistical linear regressions of the transition
    and of the observation (record: from kalman._unscented), by pseudo-inverses: a measured input
    riding in the state has zero variance."""
    A = (np.linalg.pinv(record["Pf"][:-1], hermitian=True) @ record["cross"]).swapaxes(1, 2)
    H = (np.linalg.pinv(record["Pp"], hermitian=True) @ record["Cy"]).swapaxes(1, 2)
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
    K = record["K"]
    gains = record["gains"]  # the RTS gains (None for the filter)
    N, d = K.shape[0], K.shape[1]
    n, dt = model.system.n_states, model.dt
    unknown = np.flatnonzero(~model.known) if model.augmented else np.zeros(0, dtype=int)
    update = np.eye(d) - K @ H  # M_k
    carry = update[1:] @ A  # M_k A_k-1
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
        # e^f_k = M_k A_k-1 e^f_k-1 + (K_k r_k - M_k q_k), M_k = I - K_k H_k: one product per sample
        drive = np.einsum("nim,nmc->nic", K, r) - np.einsum("nij,njc->nic", update, q)
        filtered = np.empty((N, d, count))
        filtered[0] = update[0] @ first + drive[0]
        for k in range(1, N):
            filtered[k] = carry[k - 1] @ filtered[k - 1] + drive[k]
        if smooth:
            predicted = np.einsum("nij,njc->nic", A, filtered[:-1]) - q[1:]  # e^p_k, k >= 1
            for k in range(N - 2, -1, -1):
                filtered[k] += gains[k] @ (filtered[k + 1] - predicted[k])
        second += np.einsum("nic,njc->nij", filtered, filtered)
        done += count
    if not np.all(np.isfinite(second)):
        first_bad = int(np.argmax(~np.isfinite(second).all(axis=(1, 2))))
        raise AttendInputError(f"noise_kernel_width: the error spread became non-finite at sample {first_bad} (the "
                               "filter's linearised error dynamics grow there); report the white-noise std "
                               "(noise_kernel_width=None) or check the model's stability and noise settings")
    return second / draws
