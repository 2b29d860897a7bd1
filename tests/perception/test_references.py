"""Baselines: Kalman filter/smoother against pykalman, the exact posterior against the RTS smoother
(white-noise limit), an information-form computation and the simulator itself (calibration)."""

import numpy as np
import pytest
from pykalman import KalmanFilter

from attend._validation import AttendInputError
from attend.models.linear import LinearSystem, simulate
from attend.models.noise import autocorrelation, coloured_noise
from attend.models.problems import convolution_model
from attend.perception import references as bl

DT = 0.1
SEEDS = 60


def _stable_system(rng, n, r, m, margin):
    """A random system (A, B, C drawn from rng in that order) whose slowest pole is at -margin 1/s."""
    A = rng.normal(size=(n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + margin) * np.eye(n)
    return LinearSystem(A, rng.normal(size=(n, r)), rng.normal(size=(m, n)))


@pytest.fixture(scope="module")
def problem():
    """A random stable 3-state, 2-input, 2-output system with random data and a full R."""
    rng = np.random.default_rng(1)
    n, r, m, N = 3, 2, 2, 40
    system = _stable_system(rng, n, r, m, 0.5)
    return dict(
        system=system, u=rng.normal(size=(N, r)), y=rng.normal(size=(N, m)),
        Q=np.diag([0.1, 0.2, 0.05]), R=np.array([[0.3, 0.1], [0.1, 0.2]]),
        m0=rng.normal(size=n), P0=0.5 * np.eye(n),
    )


def _pykalman(p):
    Ad, Bd = p["system"].discretize(DT)
    return KalmanFilter(
        transition_matrices=Ad, observation_matrices=p["system"].C,
        transition_covariance=p["Q"], observation_covariance=p["R"],
        transition_offsets=(p["u"] @ Bd.T)[:-1], observation_offsets=np.zeros(p["y"].shape[1]),
        initial_state_mean=p["m0"], initial_state_covariance=p["P0"],
    )


def _kw(p):
    return dict(process_covariance=p["Q"], measurement_covariance=p["R"],
                initial_mean=p["m0"], initial_covariance=p["P0"])


def test_kalman_filter_matches_pykalman(problem):
    reference = _pykalman(problem)
    means, covariances = reference.filter(problem["y"])
    ours = bl.kalman_filter(problem["system"], DT, problem["y"], problem["u"], **_kw(problem))
    np.testing.assert_allclose(ours.states, means, atol=1e-12)
    np.testing.assert_allclose(ours.state_covariance, covariances, atol=1e-12)
    np.testing.assert_allclose(ours.state_std, np.sqrt(np.diagonal(covariances, axis1=1, axis2=2)), atol=1e-12)
    assert ours.log_likelihood == pytest.approx(reference.loglikelihood(problem["y"]), rel=1e-12)
    np.testing.assert_array_equal(ours.inputs, problem["u"])
    np.testing.assert_allclose(ours.time, np.arange(40) * DT)


def test_rts_smoother_matches_pykalman(problem):
    means, covariances = _pykalman(problem).smooth(problem["y"])
    ours = bl.rts_smoother(problem["system"], DT, problem["y"], problem["u"], **_kw(problem))
    np.testing.assert_allclose(ours.states, means, atol=1e-12)
    np.testing.assert_allclose(ours.state_covariance, covariances, atol=1e-12)


def test_fixed_lag_is_the_smoother_on_the_truncated_log(problem):
    lag, k = 4, 10
    lagged = bl.kalman_filter(problem["system"], DT, problem["y"], problem["u"], lag=lag, **_kw(problem))
    truncated = bl.rts_smoother(problem["system"], DT, problem["y"][: k + lag + 1],
                                problem["u"][: k + lag + 1], **_kw(problem))
    np.testing.assert_allclose(lagged.states[k], truncated.states[k], atol=1e-12)
    np.testing.assert_allclose(lagged.state_covariance[k], truncated.state_covariance[k], atol=1e-12)
    full = bl.kalman_filter(problem["system"], DT, problem["y"], problem["u"], lag=1000, **_kw(problem))
    smooth = bl.rts_smoother(problem["system"], DT, problem["y"], problem["u"], **_kw(problem))
    np.testing.assert_allclose(full.states, smooth.states, atol=1e-12)


def test_ignoring_input_is_the_filter_with_zero_input(problem):
    ignoring = bl.kalman_filter_ignoring_input(problem["system"], DT, problem["y"], **_kw(problem))
    zero = bl.kalman_filter(problem["system"], DT, problem["y"], np.zeros_like(problem["u"]), **_kw(problem))
    np.testing.assert_array_equal(ignoring.states, zero.states)
    np.testing.assert_array_equal(ignoring.inputs, 0.0)


def test_steady_state_filter_converges_to_the_time_varying_one(problem):
    p = dict(problem)
    p["y"] = np.random.default_rng(2).normal(size=(300, 2))
    p["u"] = np.random.default_rng(3).normal(size=(300, 2))
    steady = bl.steady_state_kalman_filter(p["system"], DT, p["y"], p["u"], process_covariance=p["Q"],
                                           measurement_covariance=p["R"], initial_mean=p["m0"])
    varying = bl.kalman_filter(p["system"], DT, p["y"], p["u"], **_kw(p))
    np.testing.assert_allclose(steady.states[-50:], varying.states[-50:], atol=1e-9)
    np.testing.assert_allclose(steady.state_covariance[-1], varying.state_covariance[-1], atol=1e-12)


def test_augmented_filter(problem):
    system, y = problem["system"], problem["y"]
    constant = np.array([0.3, -0.7])
    # a frozen random walk with a known start is the filter with that constant input
    frozen = bl.augmented_kalman_filter(system, DT, y, input_variance=0.0, initial_input=constant,
                                        initial_input_std=0.0, **_kw(problem))
    known = bl.kalman_filter(system, DT, y, np.tile(constant, (len(y), 1)), **_kw(problem))
    np.testing.assert_allclose(frozen.states, known.states, atol=1e-12)
    np.testing.assert_allclose(frozen.inputs, np.tile(constant, (len(y), 1)), atol=1e-12)
    # smoothing on the augmented state matches pykalman on the augmented matrices
    Ad, Bd = system.discretize(DT)
    n, r = 3, 2
    variance = np.diag([0.01, 0.02])
    reference = KalmanFilter(
        transition_matrices=np.block([[Ad, Bd], [np.zeros((r, n)), np.eye(r)]]),
        observation_matrices=np.hstack([system.C, np.zeros((2, r))]),
        transition_covariance=np.block([[problem["Q"], np.zeros((n, r))], [np.zeros((r, n)), variance]]),
        observation_covariance=problem["R"],
        initial_state_mean=np.concatenate([problem["m0"], [0.1, 0.2]]),
        initial_state_covariance=np.block([[problem["P0"], np.zeros((n, r))], [np.zeros((r, n)), 4 * np.eye(r)]]),
    )
    means, covariances = reference.smooth(y)
    ours = bl.augmented_kalman_filter(system, DT, y, input_variance=[0.01, 0.02], initial_input=[0.1, 0.2],
                                      initial_input_std=2.0, smooth=True, **_kw(problem))
    np.testing.assert_allclose(ours.states, means[:, :n], atol=1e-12)
    np.testing.assert_allclose(ours.inputs, means[:, n:], atol=1e-12)
    np.testing.assert_allclose(ours.input_std, np.sqrt(np.diagonal(covariances, axis1=1, axis2=2)[:, n:]), atol=1e-12)


def test_augmented_filter_tracks_a_step_input():
    system = convolution_model()
    N = 200
    u = np.where(np.arange(N) >= 50, 1.0, 0.0)[:, None]
    trajectory = simulate(system, u, DT, kernel_width=0.01, process_std=1e-3, measurement_std=1e-3, seed=0)
    Q, R = bl.simulation_covariances(system, DT, 1e-3, 1e-3)
    estimate = bl.augmented_kalman_filter(system, DT, trajectory.outputs, process_covariance=Q,
                                          measurement_covariance=R, input_variance=1e-2, lag=5)
    assert np.mean(np.abs(estimate.inputs[100:] - 1.0)) < 0.03
    assert np.max(np.abs(estimate.inputs[100:] - 1.0)) < 0.15
    assert np.max(np.abs(estimate.states[100:] - trajectory.states[100:])) < 0.01


# --- exact posterior -----------------------------------------------------------------------

def test_coloured_noise_correlation_matches_the_sampler():
    K = bl.coloured_noise_correlation(12, DT, 0.3)
    assert np.allclose(np.diag(K), 1.0)
    np.testing.assert_allclose(K[0], autocorrelation(np.arange(12) * DT, 0.3), atol=1e-12)
    samples = coloured_noise(200_000, 1, DT, 0.3, 1.0, seed=0)[:, 0]
    empirical = [np.mean(samples[: len(samples) - lag] * samples[lag:]) for lag in range(12)]
    np.testing.assert_allclose(empirical, K[0], atol=0.015)


def test_exact_posterior_equals_rts_in_the_white_noise_limit():
    rng = np.random.default_rng(4)
    n, r, m, N = 3, 2, 2, 30
    system = _stable_system(rng, n, r, m, 0.3)
    u = rng.normal(size=(N, r))
    process_std, measurement_std, initial_std = [0.5, 1.0, 2.0], [0.3, 0.1], [0.2, 0.4, 0.1]
    x0 = np.array([0.3, -0.2, 0.1])
    trajectory = simulate(system, u, DT, kernel_width=1e-3, process_std=process_std,
                          measurement_std=measurement_std, initial_state=x0, seed=3)
    exact = bl.exact_posterior(system, DT, trajectory.outputs, u, kernel_width=1e-3, process_std=process_std,
                               measurement_std=measurement_std, initial_mean=[0.2, 0.0, 0.0],
                               initial_std=initial_std)
    Q, R = bl.simulation_covariances(system, DT, process_std, measurement_std)
    smooth = bl.rts_smoother(system, DT, trajectory.outputs, u, process_covariance=Q, measurement_covariance=R,
                             initial_mean=[0.2, 0.0, 0.0], initial_covariance=np.square(initial_std))
    np.testing.assert_allclose(exact.states, smooth.states, atol=1e-9)
    np.testing.assert_allclose(exact.state_std, smooth.state_std, atol=1e-9)
    assert exact.log_likelihood == pytest.approx(smooth.log_likelihood, rel=1e-9)
    np.testing.assert_array_equal(exact.inputs, u)


def _information_form(system, y, s, sw, sz, prior_mean, prior_std):
    """The posterior computed a second way: over the latents v = [u; w] (x[0] = 0) with their
    prior precisions and the measurement precision, then mapped to the states."""
    N, n, r = len(y), system.n_states, system.n_inputs
    Ad, Bd = system.discretize(DT)
    K = bl.coloured_noise_correlation(N, DT, s)
    Ku = autocorrelation(DT * (np.arange(N)[:, None] - np.arange(N)[None, :]), s)
    # states by the recurrence applied to unit latents: x = T v (x[0] = 0)
    size = N * r + N * n
    T = np.zeros((N * n, size))
    for column in range(size):
        v = np.zeros(size)
        v[column] = 1.0
        uu, ww = v[: N * r].reshape(N, r), v[N * r:].reshape(N, n)
        x = np.zeros((N, n))
        for k in range(1, N):
            x[k] = Ad @ x[k - 1] + Bd @ uu[k - 1] + DT * ww[k - 1]
        T[:, column] = x.reshape(-1)
    prior_cov = np.zeros((size, size))
    prior_cov[: N * r, : N * r] = np.kron(Ku, prior_std**2 * np.eye(r))
    prior_cov[N * r:, N * r:] = np.kron(K, sw**2 * np.eye(n))
    prior_precision = np.linalg.inv(prior_cov)
    v_mean = np.concatenate([np.full(N * r, prior_mean), np.zeros(N * n)])
    M = np.kron(np.eye(N), system.C) @ T
    noise_precision = np.linalg.inv(np.kron(K, sz**2 * np.eye(system.n_outputs)))
    precision = prior_precision + M.T @ noise_precision @ M
    covariance = np.linalg.inv(precision)
    mean = covariance @ (prior_precision @ v_mean + M.T @ noise_precision @ y.reshape(-1))
    state_cov = T @ covariance @ T.T
    return (T @ mean).reshape(N, n), mean[: N * r].reshape(N, r), state_cov, covariance[: N * r, : N * r]


def test_exact_posterior_equals_the_information_form():
    system = convolution_model()
    N, s, sw, sz = 25, 0.06, 0.5, 0.05
    u = np.sin(np.arange(N) * DT)[:, None]
    trajectory = simulate(system, u, DT, kernel_width=s, process_std=sw, measurement_std=sz, seed=5)
    exact = bl.exact_posterior(system, DT, trajectory.outputs, kernel_width=s, process_std=sw,
                               measurement_std=sz, input_prior_mean=0.2, input_prior_std=1.5,
                               jitter=0.0, return_covariance=True)
    states, inputs, state_cov, input_cov = _information_form(system, trajectory.outputs, s, sw, sz, 0.2, 1.5)
    np.testing.assert_allclose(exact.states, states, atol=1e-9)
    np.testing.assert_allclose(exact.inputs, inputs, atol=1e-9)
    n = system.n_states
    np.testing.assert_allclose(exact.covariance[: N * n, : N * n], state_cov, atol=1e-10)
    np.testing.assert_allclose(exact.covariance[N * n:, N * n:], input_cov, atol=1e-10)
    # the joint covariance is symmetric positive definite (but for the known x[0] = 0) and its
    # diagonal gives the stds
    np.testing.assert_array_equal(exact.covariance, exact.covariance.T)
    np.testing.assert_allclose(exact.covariance[:n], 0.0, atol=1e-14)
    assert np.linalg.eigvalsh(exact.covariance[n:, n:]).min() > 0
    np.testing.assert_allclose(np.sqrt(np.diag(exact.covariance)),
                               np.concatenate([exact.state_std.ravel(), exact.input_std.ravel()]), rtol=1e-8)


def test_exact_posterior_is_calibrated_on_simulated_data():
    """Under simulate()'s own model (coloured noise, dt-scaled process noise, x[0] = 0), the
    posterior variances predict the squared errors: mean(err^2 / var) ~ 1 over many logs."""
    system = convolution_model()
    N, s, sigma = 40, 0.3, 0.05
    u = np.exp(-0.25 * (np.arange(N) * DT - 2.0) ** 2)[:, None]
    ratios = []
    for seed in range(SEEDS):
        trajectory = simulate(system, u, DT, kernel_width=s, process_std=20 * sigma, measurement_std=sigma, seed=seed)
        exact = bl.exact_posterior(system, DT, trajectory.outputs, u, kernel_width=s, process_std=20 * sigma,
                                   measurement_std=sigma)
        errors = (exact.states - trajectory.states)[1:] / exact.state_std[1:]  # x[0] = 0 is known
        ratios.append(np.mean(errors**2))
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.15)


def test_exact_posterior_beats_the_kalman_smoother_on_coloured_noise():
    system = convolution_model()
    N, s, sigma = 60, 0.4, np.exp(-4)
    u = np.exp(-0.25 * (np.arange(N) * DT - 3.0) ** 2)[:, None]
    Q, R = bl.simulation_covariances(system, DT, 5 * sigma, sigma)
    exact_sse, rts_sse = [], []
    for seed in range(20):
        trajectory = simulate(system, u, DT, kernel_width=s, process_std=5 * sigma, measurement_std=sigma, seed=seed)
        exact = bl.exact_posterior(system, DT, trajectory.outputs, u, kernel_width=s, process_std=5 * sigma,
                                   measurement_std=sigma)
        smooth = bl.rts_smoother(system, DT, trajectory.outputs, u, process_covariance=Q, measurement_covariance=R)
        exact_sse.append(np.sum((exact.states - trajectory.states) ** 2))
        rts_sse.append(np.sum((smooth.states - trajectory.states) ** 2))
    assert np.mean(exact_sse) < np.mean(rts_sse)


# --- bad input -----------------------------------------------------------------------------

@pytest.mark.parametrize("call, field", [
    (lambda s, y: bl.kalman_filter(s, 0.1, y[:, :3], process_covariance=1, measurement_covariance=1), "outputs"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, np.ones((5, 1)), process_covariance=1, measurement_covariance=1),
     "inputs"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, process_covariance=-1, measurement_covariance=1), "process_covariance"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=[[1, 2], [3, 4]]),
     "measurement_covariance"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=0), "measurement_covariance"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=1, lag=-1), "lag"),
    (lambda s, y: bl.kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=1, initial_mean=[1]),
     "initial_mean"),
    (lambda s, y: bl.rts_smoother(s, -0.1, y, process_covariance=1, measurement_covariance=1), "dt"),
    (lambda s, y: bl.rts_smoother("model", 0.1, y, process_covariance=1, measurement_covariance=1), "system"),
    (lambda s, y: bl.steady_state_kalman_filter(s, 0.1, np.where(y > 0, np.nan, y), process_covariance=1,
                                                measurement_covariance=1), "outputs"),
    (lambda s, y: bl.augmented_kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=1,
                                             input_variance=-1), "input_variance"),
    (lambda s, y: bl.augmented_kalman_filter(s, 0.1, y, process_covariance=1, measurement_covariance=1,
                                             input_variance=1, initial_input_std=-1), "initial_input_std"),
    (lambda s, y: bl.exact_posterior(s, 0.1, y, kernel_width=0.5, process_std=1, measurement_std=1),
     "input_prior_mean"),
    (lambda s, y: bl.exact_posterior(s, 0.1, y, kernel_width=0.5, process_std=-1, measurement_std=1,
                                     input_prior_mean=0, input_prior_std=1), "process_std"),
    (lambda s, y: bl.exact_posterior(s, 0.1, y, kernel_width=0, process_std=1, measurement_std=1,
                                     input_prior_mean=0, input_prior_std=1), "kernel_width"),
    (lambda s, y: bl.exact_posterior(s, 0.1, y, kernel_width=0.5, process_std=1, measurement_std=1,
                                     input_prior_mean=np.zeros((3, 1)), input_prior_std=1), "input_prior_mean"),
    (lambda s, y: bl.exact_posterior(s, 0.1, y, kernel_width=0.5, process_std=1, measurement_std=1,
                                     input_prior_mean=0, input_prior_std=1, jitter=-1.0), "jitter"),
])
def test_bad_input_names_the_field(call, field):
    system = convolution_model()
    y = np.random.default_rng(0).normal(size=(10, 4))
    with pytest.raises(AttendInputError, match=field):
        call(system, y)


def test_exact_posterior_reduction_to_range_of_C_keeps_the_likelihood():
    """m = 4 > n = 2: the outputs are reduced to 2 channels; mean, stds and log p(y) stay exact."""
    system = convolution_model()
    u = np.ones((30, 1))
    trajectory = simulate(system, u, DT, kernel_width=1e-3, process_std=0.3,
                          measurement_std=[0.02, 0.03, 0.01, 0.05], seed=2)
    exact = bl.exact_posterior(system, DT, trajectory.outputs, u, kernel_width=1e-3, process_std=0.3,
                               measurement_std=[0.02, 0.03, 0.01, 0.05], initial_std=0.1)
    Q, R = bl.simulation_covariances(system, DT, 0.3, [0.02, 0.03, 0.01, 0.05])
    smooth = bl.rts_smoother(system, DT, trajectory.outputs, u, process_covariance=Q, measurement_covariance=R,
                             initial_covariance=0.01)
    np.testing.assert_allclose(exact.states, smooth.states, atol=1e-9)
    np.testing.assert_allclose(exact.state_std, smooth.state_std, atol=1e-9)
    assert exact.log_likelihood == pytest.approx(smooth.log_likelihood, rel=1e-9)


def test_baselines_accept_a_python_control_statespace(problem):
    control = pytest.importorskip("control")
    system = problem["system"]
    statespace = control.ss(system.A, system.B, system.C, 0)
    ours = bl.kalman_filter(system, DT, problem["y"], problem["u"], **_kw(problem))
    converted = bl.kalman_filter(statespace, DT, problem["y"], problem["u"], **_kw(problem))
    np.testing.assert_allclose(converted.states, ours.states)
    with pytest.raises(AttendInputError, match="attend.models.from_statespace"):
        bl.kalman_filter((system.A, system.B, system.C), DT, problem["y"], problem["u"], **_kw(problem))
