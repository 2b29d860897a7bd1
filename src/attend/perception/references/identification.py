"""Identification baselines on the same logs as :func:`attend.perception.learning.identify`, and
errors that compare models in basis-invariant form (transfer function, eigenvalues)."""

from __future__ import annotations

import numpy as np

from attend.models.linear import LinearSystem

#: The identification baselines and error metrics (re-exported by attend.perception.references and
#: attend.perception.learning, in this order).
__all__ = ["n4sid_baseline", "em_baseline", "continuous_from_discrete", "transfer_function_error", "eigenvalue_error"]


def continuous_from_discrete(Ad, Bd, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Inverse zero-order hold: [[A, B], [0, 0]] = logm([[Ad, Bd], [0, I]]) / dt (real part)."""
    from scipy.linalg import logm

    Ad, Bd = np.atleast_2d(Ad), np.atleast_2d(Bd)
    n, r = Bd.shape
    block = np.eye(n + r)
    block[:n, :n], block[:n, n:] = Ad, Bd
    log = logm(block) / dt
    return np.real(log[:n, :n]), np.real(log[:n, n:])


def n4sid_baseline(outputs, inputs, dt: float, n_states: int, block_rows: int = 10) -> LinearSystem:
    """Subspace identification (N4SID, the ``nfoursid`` package) of a continuous-time model.

    The discrete (Ad, Bd, C) of rank ``n_states`` are converted with the inverse zero-order hold;
    the feed-through D is dropped. The state basis is arbitrary: compare with
    :func:`transfer_function_error` or :func:`eigenvalue_error`. outputs (N, m), inputs (N, r)
    sampled at dt [s]; n_states: the model order; block_rows: the block rows of the Hankel matrices.
    """
    try:
        import pandas as pd
        from nfoursid.nfoursid import NFourSID
    except ImportError as error:  # pragma: no cover - optional dependency
        raise ImportError("n4sid_baseline needs the 'nfoursid' package (pip install nfoursid)") from error
    y = np.asarray(outputs, dtype=float).reshape(len(outputs), -1)
    u = np.asarray(inputs, dtype=float).reshape(len(inputs), -1)
    columns_y = [f"y{i}" for i in range(y.shape[1])]
    columns_u = [f"u{i}" for i in range(u.shape[1])]
    frame = pd.DataFrame(np.hstack([y, u]), columns=columns_y + columns_u)
    model = NFourSID(frame, output_columns=columns_y, input_columns=columns_u, num_block_rows=block_rows)
    model.subspace_identification()
    space, _ = model.system_identification(rank=n_states)
    A, B = continuous_from_discrete(space.a, space.b, dt)
    return LinearSystem(A=A, B=B, C=np.asarray(space.c))


def em_baseline(outputs, inputs, dt: float, system_prior: LinearSystem, n_iter: int = 30) -> LinearSystem:
    """EM for a linear-Gaussian state-space model (pykalman) with C known and the measured input
    appended to the state: z = [x; u], z[k+1] = [[Ad, Bd], [0, I]] z[k] + noise, [y; u] = blkdiag(C, I) z.
    EM learns the transition (hence Ad, Bd) and the noise covariances, starting from the prior
    model; the result is converted with the inverse zero-order hold. outputs (N, m), inputs (N, r)
    sampled at dt [s]; system_prior: the starting model (its C is kept); n_iter: EM iterations."""
    from pykalman import KalmanFilter

    n, r = system_prior.n_states, system_prior.n_inputs
    Ad, Bd = system_prior.discretize(dt)
    transition = np.eye(n + r)
    transition[:n, :n], transition[:n, n:] = Ad, Bd
    observation = np.zeros((system_prior.n_outputs + r, n + r))
    observation[: system_prior.n_outputs, :n] = system_prior.C
    observation[system_prior.n_outputs:, n:] = np.eye(r)
    y = np.asarray(outputs, dtype=float).reshape(len(outputs), -1)
    u = np.asarray(inputs, dtype=float).reshape(len(inputs), -1)
    data = np.hstack([y, u])
    scale = max(float(np.var(y)), 1e-12)
    filt = KalmanFilter(
        transition_matrices=transition, observation_matrices=observation,
        transition_covariance=1e-3 * scale * np.eye(n + r),
        observation_covariance=np.diag(np.r_[np.full(y.shape[1], 1e-2 * scale), np.full(r, 1e-6)]),
        initial_state_mean=np.r_[np.zeros(n), u[0]], initial_state_covariance=scale * np.eye(n + r),
        em_vars=["transition_matrices", "transition_covariance", "observation_covariance",
                 "initial_state_mean"],
    )
    filt = filt.em(data, n_iter=n_iter)
    T = np.asarray(filt.transition_matrices)
    A, B = continuous_from_discrete(T[:n, :n], T[:n, n:], dt)
    return LinearSystem(A=A, B=B, C=system_prior.C)


def transfer_function_error(estimate: LinearSystem, truth: LinearSystem, frequencies=None) -> float:
    """||G_est - G_true|| / ||G_true|| over a frequency grid [rad/s], G(jw) = C (jw I - A)^-1 B.

    Invariant to the state basis, so models from different parameterisations compare directly.
    estimate, truth: the models compared; frequencies: the grid (default 60 points, 0.01 to 31.6).
    """
    w = np.logspace(-2, 1.5, 60) if frequencies is None else np.asarray(frequencies, dtype=float)

    def response(s: LinearSystem) -> np.ndarray:
        eye = np.eye(s.n_states)
        return np.stack([s.C @ np.linalg.solve(1j * f * eye - s.A, s.B) for f in w])

    g_est, g_true = response(estimate), response(truth)
    return float(np.linalg.norm(g_est - g_true) / np.linalg.norm(g_true))


def eigenvalue_error(estimate: LinearSystem, truth: LinearSystem) -> float:
    """Largest |lambda_est - lambda_true| over the best matching of the eigenvalues of A [1/s]
    (estimate, truth: the two models; inf when their orders differ)."""
    from itertools import permutations

    a, b = np.linalg.eigvals(estimate.A), np.linalg.eigvals(truth.A)
    if len(a) != len(b):
        return float("inf")
    return float(min(np.max(np.abs(a[list(p)] - b)) for p in permutations(range(len(a)))))
