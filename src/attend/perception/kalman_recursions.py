"""The Kalman filter's and Rauch-Tung-Striebel smoother's recursions on the augmented model of
:mod:`attend.perception.kalman`: the gain schedule until the gain is steady, then the means and
variances of the filter and smoother (time-invariant from the steady sample on); and
:func:`varying_pass`, the same recursions on a time-varying model (missing channels, a
transition per step) for logs with gaps and jitter. The log-likelihood's terms
(:class:`InnovationTerms`) come from the same filters: the smoother's schedule
(:func:`innovation_terms`), a schedule stopped where its gain settles, without the Riccati
equation (:func:`converged_innovation_terms`, for the input width's search), and the
time-varying pass's forward iteration, shared with :func:`varying_pass`
(:func:`varying_innovation_terms`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from attend._validation import AttendInputError
from attend.perception.recurrence import linear_recurrence


# --- the recursions --------------------------------------------------------------------------
#
# Filter (sample k): a_p[k] = T a_f[k-1] + b[k-1], nu[k] = y[k] - H a_p[k], a_f[k] = a_p[k] + K[k] nu[k].
# Smoother in the Bryson-Frazier form (no inverse of the predicted covariance, which the nearly
# deterministic noise states make ill-conditioned):
#     lam[k] = H' inv(S[k]) nu[k] + (I - K[k] H)' T' lam[k+1],      lam[N] = 0
#     a_s[k] = a_p[k] + P_p[k] lam[k]  = a_f[k] + P_f[k] T' lam[k+1]
#     Lam[k] = H' inv(S[k]) H + (I - K[k] H)' T' Lam[k+1] T (I - K[k] H),   P_s[k] = P_p[k] - P_p[k] Lam[k] P_p[k]
#                                                                          = P_f[k] - P_f[k] T' Lam[k+1] T P_f[k]
# Until the gain is steady the smoother reads out the second forms (filtered mean and covariance,
# P_f[k] = (I - K[k] H) P_p[k] (I - K[k] H)'): a broad prior at sample 0 (P_p[0] 1e8 or more times
# the posterior) multiplies the rounding of lam[0] and Lam[0], which nearly cancel its own inverse,
# by P_p[0]; the filtered covariance has already collapsed, and carries no such factor.

STEADY_TOLERANCE = 1e-6
"""Relative change of the gain (and of the smoother's Lam) below which the recursion is steady.

The noise models' white floor (1e-8 of each noise's variance) makes the covariances
ill-conditioned enough that rounding moves the gain by ~1e-7 relative from step to step, so the
test cannot be much tighter; the estimates move by about this relative amount."""


def _congruences(T):
    """(X -> T X T', X -> T' X T) for symmetric X, using the sparsity of T where it is sparse.

    The augmented transition is the plant's block, its coupling to the noise states and one small
    block per noise channel (~5 % non-zero on a 12-state model with 4 unknown inputs: dim 180):
    products with it as a sparse matrix cost ~1/6 of the dense ones there. T X T' = T (T X)' for
    symmetric X (and T' X T = T' (T' X)'), so each is two sparse-times-dense products. Dense
    below 32 rows or above 25 % non-zero."""
    dim = T.shape[0]
    if dim < 32 or np.count_nonzero(T) > 0.25 * dim * dim:
        return (lambda X: T @ X @ T.T), (lambda X: T.T @ X @ T)
    from scipy.sparse import csr_matrix

    forward, backward = csr_matrix(T), csr_matrix(T.T)
    return (lambda X: np.asarray(forward @ (forward @ X).T)), (lambda X: np.asarray(backward @ (backward @ X).T))


class _GainSchedule(NamedTuple):
    """Gains and covariances of samples 0..steady; from ``steady`` on they are constant."""

    gains: np.ndarray          # (steady + 1, dim, m): K[k]
    innovation_weights: np.ndarray  # (steady + 1, dim, m): H' inv(S[k])
    predicted: np.ndarray      # (steady + 1, dim, dim): P_p[k] (P_p[0] = the prior)
    steady: int                # first sample whose gain is the steady gain (or the last sample)


def _steady_predicted_covariance(T, Q, H) -> np.ndarray | None:
    """P_p of the steady filter from the discrete algebraic Riccati equation, or None.

    The measurement noise lives in the state (R = 0); a white measurement variance of 1e-14 of
    the predicted outputs' scale makes the equation regular without changing the result.
    """
    from scipy.linalg import solve_discrete_are

    scale = max(float(np.max(np.abs(np.diag(H @ Q @ H.T)))), float(np.max(np.abs(np.diag(Q)))), 1e-300)
    try:
        with np.errstate(all="ignore"):
            P = solve_discrete_are(T.T, H.T, Q, 1e-14 * scale * np.eye(H.shape[0]))
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(P)):
        return None
    # polish: iterate the filter's own recursion (Joseph form, as _gain_stream) to its fixed point,
    # which the regularised solver misses by up to ~1e-5 when the noise models are ill-conditioned
    best = np.inf
    stalled = 0
    predict = _congruences(T)[0]
    for _ in range(500):
        P = 0.5 * (P + P.T)
        try:
            K = cho_solve(cho_factor(H @ P @ H.T, lower=True), H @ P).T
        except np.linalg.LinAlgError:
            return None
        new = predict(_joseph(P, K, H)) + Q
        change = np.max(np.abs(new - P)) / max(np.max(np.abs(np.diag(new))), 1e-300)
        P = new
        if change < 1e-13:
            break
        stalled = stalled + 1 if change >= 0.5 * best else 0
        best = min(best, change)
        if stalled >= 10:  # at the rounding floor
            break
    return 0.5 * (P + P.T)


class _Plateau:
    """Detects a recursion that has stopped converging: its relative distance to the limit is
    below 1e-4 and has not fallen by 10 % in ``window`` steps (rounding noise: going on would
    not get closer). A slow but steady convergence (halving time < ~1300 steps) is not a plateau."""

    def __init__(self, window: int = 200):
        self.window, self.best, self.since = window, np.inf, 0

    def reached(self, distance: float) -> bool:
        if distance < 0.9 * self.best:
            self.best, self.since = distance, 0
        else:
            self.since += 1
        return self.best < 1e-4 and self.since >= self.window


def _blockwise_distance(K, steady_gain, blocks) -> float:
    """max over row blocks (plant, each noise model) of max|K_b - K_b,steady| / max|K_b,steady|:
    each block on its own scale, so the small plant gains are not judged against the noise gains."""
    floor = 1e-12 * max(np.max(np.abs(steady_gain)), 1e-300)
    worst = 0.0
    for block in blocks:
        reference = steady_gain[block]
        if reference.size:
            worst = max(worst, np.max(np.abs(K[block] - reference)) / max(np.max(np.abs(reference)), floor))
    return worst


def _innovation_weight(H, P) -> np.ndarray:
    """H' inv(H P H'), with a Cholesky factor; rounding can leave S = H P H' a hair short of
    positive definite after a diffuse start collapses (variances falling by 1e10 in one update),
    so a white variance of 1e-12 .. 1e-8 of its mean diagonal is added before giving up."""
    S = H @ P @ H.T
    S = 0.5 * (S + S.T)
    scale = max(float(np.mean(np.abs(np.diag(S)))), 1e-300)
    for jitter in (0.0, 1e-12, 1e-10, 1e-8):
        try:
            return cho_solve(cho_factor(S + jitter * scale * np.eye(len(S)), lower=True), H).T
        except np.linalg.LinAlgError:
            continue
    raise AttendInputError("sensor_precision: the predicted outputs' covariance is singular; check "
                           "sensor_precision and C")


def _gain_stream(T, Q, H, P0, steady_predicted=None, blocks=None, patience: int = 3, converge: bool = False):
    """Yield (K[k], H' inv(S[k]), P_p[k], steady) for k = 0, 1, ...

    The covariance recursion runs until its gain is within STEADY_TOLERANCE of the steady gain
    of the Riccati equation, block by block (``blocks``: row slices; default the whole gain), for
    ``patience`` samples, or until the distance sits at the rounding floor (_Plateau); from then
    on the Riccati solution itself is yielded with steady = True (every later sample uses it).
    converge (without ``steady_predicted``): no Riccati solution; the recursion stops once its own
    gain stops moving (:class:`_Settling`) and that gain is yielded from then on, with steady = True.
    """
    blocks = [slice(None)] if blocks is None else list(blocks)
    tolerance = STEADY_TOLERANCE
    steady = None
    if steady_predicted is not None:
        try:
            factor = cho_factor(H @ steady_predicted @ H.T, lower=True)
            weight = cho_solve(factor, H).T
            steady = (steady_predicted @ weight, weight, steady_predicted, True)
        except np.linalg.LinAlgError:
            steady = None
    settling = _Settling(blocks, patience) if converge and steady is None else None
    P = 0.5 * (P0 + P0.T)
    calm = 0
    plateau = _Plateau()
    predict = _congruences(T)[0]
    K = None
    while True:
        if K is not None:
            P = predict(_joseph(P, K, H)) + Q  # Joseph form of the update, then predict
            P = 0.5 * (P + P.T)
        weight = _innovation_weight(H, P)  # H' inv(S)
        K = P @ weight
        if steady is not None and tolerance >= 0:
            distance = _blockwise_distance(K, steady[0], blocks)
            calm = calm + 1 if distance <= tolerance else 0
            if plateau.reached(distance):
                calm = patience
        if calm >= patience:
            while True:
                yield steady
        if settling is not None and settling.settled(K):
            while True:
                yield K, weight, P, True
        yield K, weight, P, False


SETTLED_TOLERANCE = 1e-7
"""Relative change of the gain (and the distance to its limit extrapolated from it) below which a
recursion without a Riccati solution is taken as steady (:class:`_Settling`): a tenth of
STEADY_TOLERANCE, as the limit is extrapolated, not known. Measured on the oscillator of
tests/perception/test_input_width.py at an input width of 16 samples, the slowest to settle: the
log-likelihood within 0.015 nats of the dense Gaussian density (the Riccati schedule: 0.012; at
STEADY_TOLERANCE itself: 0.07), and on 2600 samples of a 12-state model within 1e-4 nats of the
Riccati schedule."""


class _Settling:
    """Detects a gain recursion that has reached its steady gain without knowing it: the blockwise
    change of the gain from one sample to the next (:func:`_blockwise_distance`), extrapolated as a
    geometric sequence to the distance left to the limit, is within SETTLED_TOLERANCE on
    ``patience`` samples in a row, or the change sits at the rounding floor (:class:`_Plateau`)."""

    def __init__(self, blocks, patience: int):
        self.blocks, self.patience = blocks, patience
        self.previous, self.change, self.calm, self.plateau = None, np.inf, 0, _Plateau()

    def settled(self, K) -> bool:
        if self.previous is None:
            self.previous = K
            return False
        change = _blockwise_distance(self.previous, K, self.blocks)
        rate = min(change / self.change, 0.999999) if self.change > 0 else 0.0
        remaining = change * rate / (1 - rate)
        self.previous, self.change = K, change
        self.calm = self.calm + 1 if max(change, remaining) <= SETTLED_TOLERANCE else 0
        if self.plateau.reached(change):
            self.calm = self.patience
        return self.calm >= self.patience


def _gain_schedule(T, Q, H, P0, n_samples: int, steady_predicted=None, blocks=None,
                   converge: bool = False) -> _GainSchedule:
    """The first samples of :func:`_gain_stream`: up to the first steady one, or the whole log
    (converge: as :func:`_gain_stream`)."""
    gains, weights, predicted = [], [], []
    stream = _gain_stream(T, Q, H, P0, steady_predicted, blocks, converge=converge)
    for k, (K, weight, P, steady) in zip(range(n_samples), stream):
        gains.append(K)
        weights.append(weight)
        predicted.append(P)
        if steady:
            break
    return _GainSchedule(np.array(gains), np.array(weights), np.array(predicted), len(gains) - 1)


def _at(array: np.ndarray, k: int) -> np.ndarray:
    """Entry k of a schedule array, the steady (last) entry beyond it."""
    return array[min(k, len(array) - 1)]


def _predicted_means(schedule: _GainSchedule, T, H, y, drive, mean0) -> tuple[np.ndarray, np.ndarray]:
    """Predicted means a_p[k] and innovations nu[k] for every sample."""
    N, dim = y.shape[0], T.shape[0]
    predicted = np.empty((N, dim))
    mean = mean0
    head = min(schedule.steady + 1, N)
    for k in range(head):
        if k:
            mean = T @ (mean + schedule.gains[k - 1] @ (y[k - 1] - H @ mean)) + drive[k - 1]
        predicted[k] = mean
    if head < N:  # a_p[k] = T (I - K H) a_p[k-1] + T K y[k-1] + b[k-1]
        K = schedule.gains[-1]
        transition = T @ (np.eye(dim) - K @ H)
        forcing = y[head - 1: N - 1] @ (T @ K).T + drive[head - 1: N - 1]
        predicted[head:] = linear_recurrence(transition, forcing, predicted[head - 1])
    return predicted, y - predicted @ H.T


def _filtered_means(schedule: _GainSchedule, predicted, innovations, output_map) -> np.ndarray:
    """output_map @ a_f[k] for every sample."""
    N = predicted.shape[0]
    head = min(schedule.steady, N)
    out = predicted @ output_map.T
    for k in range(head):
        out[k] += output_map @ (schedule.gains[k] @ innovations[k])
    out[head:] += innovations[head:] @ (output_map @ schedule.gains[-1]).T
    return out


def _smoothed_means(schedule: _GainSchedule, T, H, predicted, innovations, output_map) -> np.ndarray:
    """output_map @ a_s[k] for every sample (the smoothed augmented state is never formed)."""
    N, dim = predicted.shape
    s = min(schedule.steady, N - 1)
    lam = np.empty((N, dim))
    scaled = np.empty((N, dim))  # H' inv(S[k]) nu[k]
    scaled[s:] = innovations[s:] @ schedule.innovation_weights[-1].T
    for k in range(s):
        scaled[k] = schedule.innovation_weights[k] @ innovations[k]
    # steady region: lam[k] = M lam[k+1] + scaled[k], M = (I - K H)' T'
    K = schedule.gains[-1]
    M = (np.eye(dim) - K @ H).T @ T.T
    lam[s:] = linear_recurrence(M, scaled[s:][::-1], np.zeros(dim))[::-1]
    for k in range(s - 1, -1, -1):
        lam[k] = scaled[k] + (np.eye(dim) - schedule.gains[k] @ H).T @ (T.T @ lam[k + 1])
    out = np.empty((N, output_map.shape[0]))
    out[s:] = predicted[s:] @ output_map.T + lam[s:] @ (output_map @ schedule.predicted[-1]).T
    for k in range(s):  # a_f[k] + P_f[k] T' lam[k+1] (the module's note: a broad prior at sample 0)
        K = schedule.gains[k]
        filtered = output_map @ (predicted[k] + K @ innovations[k])
        out[k] = filtered + _filtered_readout(output_map, schedule.predicted[k], K, H) @ (T.T @ lam[k + 1])
    return out


def _filtered_readout(output_map, P, K, Ho) -> np.ndarray:
    """O P_f with P_f = (I - K H_o) P (I - K H_o)' (the Joseph form, as the filter propagates it), in
    O(dim^2 (q + m)) without forming P_f."""
    OX = output_map @ P - (output_map @ K) @ (Ho @ P)
    return OX - (OX @ Ho.T) @ K.T


def _filter_variances(schedule: _GainSchedule, H, output_map, N: int) -> np.ndarray:
    out = np.empty((N, output_map.shape[0]))
    identity = np.eye(H.shape[1])
    for k in range(min(N, schedule.steady + 1)):
        A = identity - schedule.gains[k] @ H
        out[k] = np.einsum("ij,jl,il->i", output_map, A @ schedule.predicted[k] @ A.T, output_map)
    out[schedule.steady + 1:] = out[min(N, schedule.steady + 1) - 1]
    return out


def _smoother_variances(schedule: _GainSchedule, T, H, output_map, N: int) -> np.ndarray:
    """diag(O P_s[k] O') with the backward recursion of Lam; constant in the middle of long logs."""
    tolerance = STEADY_TOLERANCE
    s = min(schedule.steady, N - 1)
    back = _congruences(T)[1]

    def carried(k, Lam):  # (I - K[k] H)' T' Lam T (I - K[k] H)
        return _sandwich_transposed(back(Lam), _at(schedule.gains, k), H)

    def variance(k, Lam):  # diag(O (P - P Lam P) O') from O P: O(q dim^2)
        OP = output_map @ _at(schedule.predicted, k)
        return _diag(OP, output_map) - _diag(OP @ Lam, OP)

    out = np.empty((N, output_map.shape[0]))
    Lam = _at(schedule.innovation_weights, N - 1) @ H
    out[N - 1] = variance(N - 1, Lam)
    k = N - 2
    calm = 0
    previous_change = np.inf
    plateau = _Plateau()
    while k >= s:  # steady gains: Lam, and the reported variances, converge geometrically backwards
        Lam = schedule.innovation_weights[-1] @ H + carried(k, Lam)
        Lam = 0.5 * (Lam + Lam.T)
        out[k] = variance(k, Lam)
        scale = np.maximum(np.abs(out[k]), 1e-300)
        change = float(np.max(np.abs(out[k] - out[k + 1]) / scale))  # relative, per reported variance
        rate = min(change / previous_change, 0.999999) if previous_change > 0 else 0.0
        previous_change = change
        remaining = change * rate / (1 - rate)  # distance to the limit of a geometric sequence
        calm = calm + 1 if remaining <= tolerance and change <= tolerance else 0
        if plateau.reached(change):
            calm = 3
        k -= 1
        if calm >= 3:
            out[s: k + 1] = out[k + 1]
            k = s - 1
            break
    for j in range(k, -1, -1):  # diag(O (P_f - P_f T' Lam[j+1] T P_f) O') (the module's note)
        forward = back(Lam)  # T' Lam[j+1] T
        OP = _filtered_readout(output_map, _at(schedule.predicted, j), _at(schedule.gains, j), H)
        out[j] = _diag(OP, output_map) - _diag(OP @ forward, OP)
        Lam = _at(schedule.innovation_weights, j) @ H + _sandwich_transposed(forward, _at(schedule.gains, j), H)
        Lam = 0.5 * (Lam + Lam.T)
    return out


# --- time-varying model: missing channels and per-step discretisation --------------------------
#
# The same recursions with the step into sample k given by (T[k], Q[k]) and the update using only
# the observed rows H_o of H (no update when none is observed). With A = I - K H_o:
#     P_f = A P_p A'  (Joseph form, computed as X = P_p - K (H_o P_p), P_f = X - (X H_o') K')
#     lam[k] = H_o' inv(S) nu + A' T[k+1]' lam[k+1],  Lam[k] = H_o' inv(S) H_o + A' T[k+1]' Lam[k+1] T[k+1] A
# The smoother keeps, per sample, only O P_p[k] (O the output map), K[k] and H_o' inv(S[k]).

class SteadyGain(NamedTuple):
    """The steady Kalman gain of the model with every channel observed: gain K (dim, m), weight
    H' inv(S) (dim, m), predicted covariance P_p (dim, dim)."""

    gain: np.ndarray
    weight: np.ndarray
    predicted: np.ndarray


def steady_gain(H, steady_predicted) -> SteadyGain | None:
    """:class:`SteadyGain` from the Riccati solution (None when there is none)."""
    if steady_predicted is None:
        return None
    try:
        weight = cho_solve(cho_factor(H @ steady_predicted @ H.T, lower=True), H).T
    except np.linalg.LinAlgError:
        return None
    return SteadyGain(steady_predicted @ weight, weight, steady_predicted)


def _joseph(P, K, Ho):
    """(I - K H_o) P (I - K H_o)' in O(dim^2 m)."""
    X = P - K @ (Ho @ P)
    out = X - (X @ Ho.T) @ K.T
    return 0.5 * (out + out.T)


def _sandwich_transposed(M, K, Ho):
    """(I - K H_o)' M (I - K H_o) in O(dim^2 m)."""
    Y = M - Ho.T @ (K.T @ M)
    out = Y - (Y @ K) @ Ho
    return 0.5 * (out + out.T)


def _diag(left, right=None):
    """diag(left @ right') row by row (right defaults to left)."""
    return np.einsum("ij,ij->i", left, left if right is None else right)


class _ForwardSample(NamedTuple):
    """One sample k of the time-varying filter (:func:`_varying_forward`): predicted: a_p[k];
    rows: the observed channels; innovation: nu[k] on them; gain: K[k]; weight: H_o' inv(S[k]);
    factor: the lower Cholesky factor of S[k] = H_o P_p[k] H_o' (None: nothing observed);
    covariance: P_p[k]; filtered: a_f[k]; filtered_covariance: P_f[k] (the two covariances are
    None on the steady gain); steady: the sample used the steady gain."""

    k: int
    predicted: np.ndarray
    rows: np.ndarray
    innovation: np.ndarray
    gain: np.ndarray
    weight: np.ndarray
    factor: np.ndarray | None
    covariance: np.ndarray | None
    filtered: np.ndarray
    filtered_covariance: np.ndarray | None
    steady: bool


def _varying_forward(step_model, H, y, observed, mean0, P0, steady: SteadyGain | None, blocks, patience: int):
    """The forward pass of :func:`varying_pass` and :func:`varying_innovation_terms` (same
    arguments), one :class:`_ForwardSample` per sample."""
    N, dim = y.shape[0], P0.shape[0]
    blocks = [slice(None)] if blocks is None else list(blocks)
    if steady is not None:
        steady_factor = _jittered_cholesky(H @ steady.predicted @ H.T)
    on_steady, calm, plateau = False, 0, _Plateau()
    a_f = P_f = None
    for k in range(N):
        rows = np.flatnonzero(observed[k])
        full = rows.size == H.shape[0]
        if k == 0:
            a, P = mean0, P0
        else:
            T, Q, b = step_model(k)
            a = T @ a_f + b
            if on_steady:
                P = None
            else:
                P = T @ P_f @ T.T + Q
                P = 0.5 * (P + P.T)
        if on_steady and not full:  # leave the steady gain: its predicted covariance is the fixed point
            on_steady, calm, plateau, P = False, 0, _Plateau(), steady.predicted.copy()
        if on_steady:
            nu = y[k] - H @ a
            a_f = a + steady.gain @ nu
            yield _ForwardSample(k, a, rows, nu, steady.gain, steady.weight, steady_factor, None, a_f, None, True)
            continue
        if rows.size:
            Ho = H[rows]
            factor = _jittered_cholesky(Ho @ P @ Ho.T)
            W = cho_solve((factor, True), Ho).T  # H_o' inv(S)
            K = P @ W
            nu = y[k, rows] - Ho @ a
            a_f = a + K @ nu
            P_f = _joseph(P, K, Ho)
        else:
            K = W = np.zeros((dim, 0))
            factor, nu = None, np.zeros(0)
            a_f, P_f = a, P
        yield _ForwardSample(k, a, rows, nu, K, W, factor, P, a_f, P_f, False)
        if steady is not None and full:
            distance = _blockwise_distance(K, steady.gain, blocks)
            calm = calm + 1 if distance <= STEADY_TOLERANCE else 0
            if plateau.reached(distance):
                calm = patience
            on_steady = calm >= patience
        else:
            calm = 0


def varying_pass(step_model, H, y, observed, mean0, P0, output_map, smooth: bool,
                 steady: SteadyGain | None = None, blocks=None, patience: int = 3):
    """Kalman filter (smooth=False) or Bryson-Frazier smoother (True) on a time-varying model.

    step_model(k) -> (T[k], Q[k], b[k - 1]): the step from sample k - 1 to k (k >= 1), a[k] =
    T[k] a[k - 1] + b[k - 1] + noise of covariance Q[k]; H (m, dim); y (N, m) (ignored where not
    observed); observed (N, m) bool: the channels measured at each sample; mean0, P0: prior of the
    augmented state at sample 0;
    output_map O (q, dim). steady: the steady gain of a constant model (step_model the same at
    every k), taken once the gain is within STEADY_TOLERANCE of it (row ``blocks``, as
    :func:`_gain_stream`) on ``patience`` fully observed samples, until the next missing channel.
    Returns (means (N, q), variances (N, q)) of O a: filtered E[. | y[0..k]] or smoothed.
    """
    N, dim = y.shape[0], P0.shape[0]
    O = output_map
    predicted = np.empty((N, dim))
    scaled = np.zeros((N, dim))  # H_o' inv(S) nu
    records: list = [None] * N   # (observed rows, K, H_o' inv(S), O a_f, O P_f) of the time-varying samples
    is_steady = np.zeros(N, dtype=bool)
    means, variances = np.empty((N, O.shape[0])), np.empty((N, O.shape[0]))
    if steady is not None:
        steady_filter_variance = _diag(O @ _joseph(steady.predicted, steady.gain, H), O)
    for sample in _varying_forward(step_model, H, y, observed, mean0, P0, steady, blocks, patience):
        k = sample.k
        predicted[k] = sample.predicted
        scaled[k] = sample.weight @ sample.innovation
        is_steady[k] = sample.steady
        if smooth:
            if not sample.steady:
                records[k] = (sample.rows, sample.gain, sample.weight, O @ sample.filtered,
                              O @ sample.filtered_covariance)
        else:
            means[k] = O @ sample.filtered
            variances[k] = steady_filter_variance if sample.steady else _diag(O @ sample.filtered_covariance, O)
    if not smooth:
        return means, variances
    return _varying_smoother(step_model, H, O, predicted, scaled, records, is_steady, steady, means, variances)


def _varying_smoother(step_model, H, O, predicted, scaled, records, is_steady, steady, means, variances):
    """The backward pass of :func:`varying_pass` (fills and returns means, variances)."""
    N, dim = predicted.shape
    lam = np.zeros(dim)
    Lam = np.zeros((dim, dim))
    settled = False  # Lam has converged inside a run of steady samples: it stays put back to the run's start
    if steady is not None:
        steady_OP = O @ steady.predicted
        steady_prior_variance = _diag(steady_OP, O)
    calm, previous = 0, None
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            T = step_model(k + 1)[0]
            carry = T.T @ lam
            carry_Lam = None if settled and is_steady[k] else T.T @ Lam @ T
        else:
            carry, carry_Lam = np.zeros(dim), np.zeros((dim, dim))
        if not is_steady[k]:  # a_f + P_f T' lam[k+1], P_f - P_f T' Lam[k+1] T P_f (the module's note)
            settled, calm, previous = False, 0, None
            rows, K, W, filtered, OP = records[k]
            Ho = H[rows]
            means[k] = filtered + OP @ carry
            variances[k] = _diag(OP, O) - _diag(OP @ carry_Lam, OP)
            lam = scaled[k] + carry - Ho.T @ (K.T @ carry)
            Lam = W @ Ho + _sandwich_transposed(carry_Lam, K, Ho)
            continue
        K, W, OP = steady.gain, steady.weight, steady_OP
        lam = scaled[k] + carry - H.T @ (K.T @ carry)
        if carry_Lam is not None:
            Lam = W @ H + _sandwich_transposed(carry_Lam, K, H)
        means[k] = O @ predicted[k] + OP @ lam
        if settled:
            variances[k] = variances[k + 1]
            continue
        variances[k] = steady_prior_variance - _diag(OP @ Lam, OP)
        if previous is not None:
            change = np.max(np.abs(variances[k] - previous) / np.maximum(np.abs(variances[k]), 1e-300))
            calm = calm + 1 if change <= STEADY_TOLERANCE else 0
            settled = calm >= 3
        previous = variances[k]
    return means, variances


# --- the log-likelihood of the log: the prediction-error decomposition ----------------------------
#
# log p(y[0..N-1]) = sum_k log N(nu[k]; 0, S[k]), S[k] = H_o P_p[k] H_o' (the observed rows H_o),
# exact for the linear Gaussian model the filter runs on: the innovations are independent.

_LOG_2PI = float(np.log(2 * np.pi))


def _jittered_cholesky(S: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of S, with the white variance of :func:`_innovation_weight` (1e-12 ..
    1e-8 of its mean diagonal) added only when S needs it."""
    S = 0.5 * (S + S.T)
    scale = max(float(np.mean(np.abs(np.diag(S)))), 1e-300)
    for jitter in (0.0, 1e-12, 1e-10, 1e-8):
        try:
            return np.linalg.cholesky(S + jitter * scale * np.eye(len(S)))
        except np.linalg.LinAlgError:
            continue
    raise AttendInputError("sensor_precision: the predicted outputs' covariance is singular; check "
                           "sensor_precision and C")


def _gaussian_terms(S: np.ndarray, innovations: np.ndarray) -> tuple[float, float]:
    """(log det S, sum over the rows nu of ``innovations`` of nu' inv(S) nu)."""
    factor = _jittered_cholesky(S)
    white = solve_triangular(factor, np.atleast_2d(innovations).T, lower=True)
    return 2.0 * float(np.sum(np.log(np.diag(factor)))), float(np.sum(white**2))


class InnovationTerms(NamedTuple):
    """The parts of log p(y) = -0.5 (log_determinant + quadratic + count log(2 pi)): the sums over
    samples of log det S[k] and of nu[k]' inv(S[k]) nu[k], and the number of measured values."""

    log_determinant: float
    quadratic: float
    count: int

    @property
    def log_likelihood(self) -> float:
        """log p(y) [nats]."""
        return -0.5 * (self.log_determinant + self.quadratic + self.count * _LOG_2PI)


def innovation_terms(schedule: _GainSchedule, H, innovations) -> InnovationTerms:
    """:class:`InnovationTerms` of a complete, uniform log from the filter's innovations nu (N, m)
    and the predicted covariances of its gain schedule (the steady one from the schedule's end on)."""
    N, m = innovations.shape
    head = min(len(schedule.predicted), N)
    log_determinant = quadratic = 0.0
    for k in range(head):
        logdet, value = _gaussian_terms(H @ schedule.predicted[k] @ H.T, innovations[k])
        log_determinant, quadratic = log_determinant + logdet, quadratic + value
    if head < N:
        logdet, value = _gaussian_terms(H @ schedule.predicted[-1] @ H.T, innovations[head:])
        log_determinant, quadratic = log_determinant + (N - head) * logdet, quadratic + value
    return InnovationTerms(log_determinant, quadratic, N * m)


def converged_innovation_terms(T, Q, H, y, drive, mean0, P0, blocks=None) -> InnovationTerms:
    """:class:`InnovationTerms` of a complete, uniform log without the Riccati equation.

    The filter of :func:`_gain_schedule` with ``converge=True``: the covariance recursion runs
    until its own gain stops moving (:class:`_Settling`: the change from sample to sample, and
    the distance to the limit it implies, within STEADY_TOLERANCE relative, block by block, on 3
    samples), and that gain serves the rest of the log (:func:`_predicted_means`). For the
    likelihood alone this is as exact as the smoother's schedule (whose steady gain is the
    Riccati solution, reached to the same tolerance) and saves solving the equation, most of the
    cost of a likelihood pass on a large augmented state. T (dim, dim), Q (dim, dim), H (m, dim):
    the augmented model; y (N, m): the outputs, all measured; drive (N, dim): b[k] entering
    a[k + 1]; mean0, P0: the prior at sample 0; blocks: the gain's row blocks (default: all)."""
    schedule = _gain_schedule(T, Q, H, P0, y.shape[0], None, blocks, converge=True)
    _, innovations = _predicted_means(schedule, T, H, y, drive, mean0)
    return innovation_terms(schedule, H, innovations)


def varying_innovation_terms(step_model, H, y, observed, mean0, P0, steady: SteadyGain | None = None,
                             blocks=None, patience: int = 3) -> InnovationTerms:
    """:class:`InnovationTerms` of the measured values of a log with gaps or jitter: the forward
    pass of :func:`varying_pass` (same arguments, the same iteration) over the samples with a
    measured channel."""
    log_determinant = quadratic = 0.0
    count = 0
    for sample in _varying_forward(step_model, H, y, observed, mean0, P0, steady, blocks, patience):
        if sample.factor is None:  # nothing measured at this sample
            continue
        white = solve_triangular(sample.factor, sample.innovation, lower=True)
        log_determinant += 2.0 * float(np.sum(np.log(np.diag(sample.factor))))
        quadratic += float(white @ white)
        count += sample.innovation.size
    return InnovationTerms(log_determinant, quadratic, count)
