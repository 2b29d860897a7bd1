"""Missing outputs (NaN) in the nonlinear Kalman smoothers: no update for a missing value, the others
update, and the log-likelihood counts the measured values only. On a linear model the unscented and
extended smoothers are the Kalman smoother of the RK4 transition, so a plain Kalman filter written
here (skipping the missing values) is their oracle."""

import numpy as np
import pytest

from attend.models.nonlinear import NonlinearSystem
from attend.perception.nonlinear.start_search import search_start
from attend.perception.nonlinear_smoothers import (EvidenceBelowFloor, extended_kalman, unscented_innovation_terms,
                                                   unscented_kalman)

A = np.array([[0.0, 1.0], [-2.0, -0.3]])
C = np.array([[1.0, 0.0], [0.5, 1.0]])
DT, SUBSTEPS = 0.1, 3
Q, R = np.diag([1e-3, 4e-3]), np.diag([0.04, 0.09])


def _system():
    return NonlinearSystem(lambda x, v: A @ x, lambda x, v: C @ x, 2, 0, 2)


def _log(seed=0, samples=60):
    """Outputs of the linear model with some values missing: single cells, a whole row, and the last
    10 samples of both outputs."""
    rng = np.random.default_rng(seed)
    x, rows = np.array([1.0, 0.0]), []
    transition = _rk4_matrix_over(DT)
    for _ in range(samples):
        rows.append(C @ x + rng.normal(0, np.sqrt(np.diag(R))))
        x = transition @ x + rng.multivariate_normal(np.zeros(2), Q)
    y = np.array(rows)
    y[[3, 17, 18], 0] = np.nan
    y[[9, 33], 1] = np.nan
    y[25] = np.nan
    y[-10:] = np.nan
    return y


def _kalman(y, m0, P0, steps=None):
    """Kalman filter + RTS smoother of x[k] = F_k x[k-1] + q_k, y[k] = C x[k] + r, a missing value
    skipped: F_k the RK4 transition over step k (DT each, or ``steps``), Cov(q_k) = Q (h_k / DT)^2.
    Returns (smoothed means, smoothed covariances, log-likelihood of the measured values)."""
    N = len(y)
    lengths = np.full(N - 1, DT) if steps is None else np.asarray(steps)
    transitions = [None] + [_rk4_matrix_over(h) for h in lengths]
    mf, Pf, mp, Pp = np.zeros((N, 2)), np.zeros((N, 2, 2)), np.zeros((N, 2)), np.zeros((N, 2, 2))
    mean, cov, ll = m0.copy(), P0.copy(), 0.0
    for k in range(N):
        if k:
            F = transitions[k]
            mean, cov = F @ mean, F @ cov @ F.T + Q * (lengths[k - 1] / DT) ** 2
        mp[k], Pp[k] = mean, cov
        seen = np.isfinite(y[k])
        if seen.any():
            H, Rs = C[seen], R[np.ix_(seen, seen)]
            S = H @ cov @ H.T + Rs
            K = cov @ H.T @ np.linalg.inv(S)
            innovation = y[k, seen] - H @ mean
            ll += -0.5 * (innovation @ np.linalg.solve(S, innovation) + np.linalg.slogdet(S)[1]
                          + seen.sum() * np.log(2 * np.pi))
            mean, cov = mean + K @ innovation, cov - K @ S @ K.T
        mf[k], Pf[k] = mean, cov
    ms, Ps = mf.copy(), Pf.copy()
    for k in range(N - 2, -1, -1):
        G = Pf[k] @ transitions[k + 1].T @ np.linalg.inv(Pp[k + 1])
        ms[k] = mf[k] + G @ (ms[k + 1] - mp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
    return ms, Ps, ll


def _rk4_matrix_over(h):
    """The RK4 transition of dx/dt = A x over a step h in ceil(SUBSTEPS h / DT) steps (the sub-steps
    the smoother takes for a step of its own length: SUBSTEPS for h = DT)."""
    count = max(1, int(np.ceil(SUBSTEPS * h / DT - 1e-9)))
    hA = A * h / count
    step = np.eye(2) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
    return np.linalg.matrix_power(step, count)


@pytest.mark.parametrize("smoother, tolerance", [(unscented_kalman, 1e-9), (extended_kalman, 1e-6)])
def test_missing_outputs_give_the_kalman_smoother_that_skips_them(smoother, tolerance):
    """The extended smoother's Jacobians are central differences (exact for a linear map up to their
    rounding, ~1e-8 relative), the unscented one's sigma points are exact for it."""
    y = _log()
    m0, P0 = np.array([0.5, 0.2]), np.diag([1.0, 1.0])
    means, covariances, ll = _kalman(y, m0, P0)
    result = smoother(_system(), DT, y, process_covariance=Q, measurement_covariance=R, initial_mean=m0,
                      initial_covariance=P0, substeps=SUBSTEPS)
    scale = np.max(np.abs(means))
    np.testing.assert_allclose(result.states, means, rtol=0, atol=tolerance * scale)
    np.testing.assert_allclose(result.state_covariance, covariances, rtol=0, atol=tolerance * np.max(covariances))
    assert abs(result.log_likelihood - ll) <= tolerance * abs(ll)
    assert np.all(np.isfinite(result.states)) and result.state_std[-1, 0] > result.state_std[-11, 0]


def test_the_error_spread_over_missing_outputs_is_the_kalman_covariance_under_white_noise():
    """The std `attend estimate` reports (the exact error spread, here under white noise: kernel width
    0) skips the missing values as the filter does: it equals the oracle's smoothed covariance."""
    y = _log()
    m0, P0 = np.array([0.5, 0.2]), np.diag([1.0, 1.0])
    covariances = _kalman(y, m0, P0)[1]
    result = unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=R, initial_mean=m0,
                              initial_covariance=P0, substeps=SUBSTEPS, noise_kernel_width=0.0, spread_draws=None)
    np.testing.assert_allclose(result.state_covariance, covariances, rtol=0, atol=1e-9 * np.max(covariances))


def test_the_likelihood_counts_the_measured_values_and_the_floor_holds_over_missing_ones():
    y = _log()
    m0, P0 = np.array([0.5, 0.2]), np.diag([1.0, 1.0])
    terms = unscented_innovation_terms(_system(), DT, y, process_covariance=Q, measurement_covariance=R,
                                       initial_mean=m0, initial_covariance=P0, substeps=SUBSTEPS)
    assert terms.count == int(np.isfinite(y).sum())
    assert abs(terms.log_likelihood - _kalman(y, m0, P0)[2]) <= 1e-9 * abs(terms.log_likelihood)
    # a large sensor noise makes each sample's bound negative; the last 10 samples, all missing, add 0:
    # a floor just below the run's own log-likelihood must not stop it
    wide = R * 400.0
    run = unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=wide, initial_mean=m0,
                           initial_covariance=P0, substeps=SUBSTEPS)
    floored = unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=wide,
                               initial_mean=m0, initial_covariance=P0, substeps=SUBSTEPS,
                               evidence_floor=run.log_likelihood - 1e-6)
    np.testing.assert_array_equal(floored.states, run.states)
    with pytest.raises(EvidenceBelowFloor):  # a floor above what the run reaches stops it
        unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=wide, initial_mean=m0,
                         initial_covariance=P0, substeps=SUBSTEPS, evidence_floor=run.log_likelihood + 1.0)


def test_every_value_missing_is_refused_and_inf_is_not_missing():
    from attend._validation import AttendInputError

    y = _log()
    with pytest.raises(AttendInputError, match="every value is missing"):
        unscented_kalman(_system(), DT, np.full_like(y, np.nan), process_covariance=Q, measurement_covariance=R)
    y[4, 1] = np.inf
    with pytest.raises(AttendInputError, match="NaN for a missing value"):
        unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=R)


def test_the_start_search_takes_missing_outputs():
    """The search's bank and its runs skip the missing values: the start found is within 3 of its std
    of the true x[0] = (1, 0), and its score is the smoother's evidence from it."""
    y = _log(seed=1)
    search = search_start(_system(), DT, y, process_covariance=Q, measurement_covariance=R, substeps=SUBSTEPS)
    assert not search.ambiguous
    assert np.all(np.abs(search.mean - [1.0, 0.0]) < 3 * search.std)




@pytest.mark.parametrize("smoother, tolerance", [(unscented_kalman, 1e-9), (extended_kalman, 1e-6)])
def test_jittered_steps_give_the_kalman_smoother_of_each_steps_own_transition(smoother, tolerance):
    """Steps of their own length (a jittered log, and one step of 1.4 dt): the transition of step k is
    RK4 over h_k, its process noise Q (h_k / dt)^2 (the white-noise model holds w over the step), and
    missing values are skipped as before; the oracle is the plain Kalman smoother of those."""
    y = _log()
    steps = DT * (1.0 + np.random.default_rng(5).uniform(-0.05, 0.05, len(y) - 1))
    steps[20] = 1.4 * DT
    m0, P0 = np.array([0.5, 0.2]), np.diag([1.0, 1.0])
    ms, _, ll = _kalman(y, m0, P0, steps)
    result = smoother(_system(), DT, y, process_covariance=Q, measurement_covariance=R, initial_mean=m0,
                      initial_covariance=P0, substeps=SUBSTEPS, step_lengths=steps)
    np.testing.assert_allclose(result.states, ms, rtol=0, atol=tolerance * np.max(np.abs(ms)))
    assert abs(result.log_likelihood - ll) <= tolerance * abs(ll)
    np.testing.assert_allclose(result.time[1:], np.cumsum(steps), rtol=1e-14)


def test_steps_of_the_wrong_count_or_not_positive_are_refused():
    from attend._validation import AttendInputError

    y = _log()
    for steps in (np.full(len(y), DT), np.concatenate([[0.0], np.full(len(y) - 2, DT)])):
        with pytest.raises(AttendInputError, match="step_lengths: expected 59 step lengths > 0"):
            unscented_kalman(_system(), DT, y, process_covariance=Q, measurement_covariance=R, step_lengths=steps)
