"""The coloured-noise Kalman smoother/filter against the exact Gaussian posterior (the oracle)."""

import numpy as np
import pytest

import attend
from attend import AttendInputError, ModelWarning
from attend.perception.kalman import KalmanEstimator
from attend.perception.references import exact_posterior


def random_system(rng, n, m, r):
    """A stable, observable random system (eigenvalues' real parts in -0.8 .. -0.05 1/s)."""
    while True:
        A = rng.normal(size=(n, n)) / np.sqrt(n)
        A -= (np.linalg.eigvals(A).real.max() + rng.uniform(0.05, 0.8)) * np.eye(n)
        B, C = rng.normal(size=(n, r)), rng.normal(size=(m, n))
        O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(n)])
        if np.linalg.matrix_rank(O) == n:
            return attend.LinearSystem(A, B, C)


def random_log(rng_seed, sizes, dt, N, **noise):
    """random_system(rng, *sizes) (n, m, r) with rng = default_rng(rng_seed), standard normal inputs
    (N, r) from the same rng, and attend.simulate's log of it (noise: its keyword arguments)."""
    rng = np.random.default_rng(rng_seed)
    system = random_system(rng, *sizes)
    u = rng.normal(size=(N, sizes[2]))
    return system, u, attend.simulate(system, u, dt, **noise)


def gp_inputs(rng, N, r, dt, width, mean, std):
    t = np.arange(N) * dt
    K = np.exp(-((t[:, None] - t[None, :]) ** 2) / (4 * width**2))
    return mean + std * np.linalg.cholesky(K + 1e-9 * np.eye(N)) @ rng.standard_normal((N, r))


CASES = [  # (seed, process width / dt, sensor width / dt)
    (0, 2.0, 2.0),
    (1, 0.5, 5.0),
    (2, 5.0, 0.0),
    (3, 0.0, 3.0),
]


@pytest.mark.parametrize("seed, process_ratio, sensor_ratio", CASES)
def test_known_inputs_reach_the_exact_posterior(seed, process_ratio, sensor_ratio):
    rng = np.random.default_rng(seed)
    system = random_system(rng, 3, 2, 1)
    dt, N = 0.1, 300
    sw, sz = 0.05, 0.03
    t = np.arange(N) * dt
    u = np.sin(2 * np.pi * t / 4)[:, None]
    log = attend.simulate(system, u, dt, process_kernel_width=process_ratio * dt, sensor_kernel_width=sensor_ratio * dt,
                          process_std=sw, measurement_std=sz, seed=seed)
    widths = dict(process_kernel_width=process_ratio * dt, sensor_kernel_width=sensor_ratio * dt)
    exact = exact_posterior(system, dt, log.outputs, u, process_std=sw, measurement_std=sz, causal=True, **widths)
    estimator = KalmanEstimator(system, dt, sensor_precision=sz**-2, process_precision=sw**-2,
                                initial_state=np.zeros(3), **widths)
    smooth, causal = estimator.estimate(log.outputs, u), estimator.filter(log.outputs, u)
    inner = slice(1, None)
    np.testing.assert_allclose(smooth.states, exact.states, atol=0.05 * np.abs(exact.states).max())
    np.testing.assert_allclose(smooth.state_std[inner], exact.state_std[inner], rtol=0.02)
    sse = lambda estimate: np.sum((estimate - log.states) ** 2)
    assert sse(smooth.states) == pytest.approx(sse(exact.states), rel=0.03)
    assert sse(causal.states) == pytest.approx(sse(exact.causal_states), rel=0.03)


def test_white_noise_smoother_equals_the_rts_smoother():
    """With both widths 0 the model is the white-noise one: the classic RTS smoother."""
    dt, N = 0.05, 200
    system, u, log = random_log(5, (3, 1, 2), dt, N, kernel_width=0.0, process_std=0.1, measurement_std=0.05, seed=1)
    estimator = KalmanEstimator(system, dt, sensor_precision=0.05**-2, process_precision=0.1**-2, kernel_width=0.0,
                                initial_state=np.zeros(3), initial_state_std=0.5)
    ours = estimator.estimate(log.outputs, u)
    Q, R = attend.perception.references.simulation_covariances(system, dt, 0.1, 0.05)
    reference = attend.perception.references.rts_smoother(system, dt, log.outputs, u, process_covariance=Q,
                                                         measurement_covariance=R, initial_covariance=0.25 * np.eye(3))
    # to rounding where the gains are time-varying; the steady-gain shortcut (gain within 1e-6 of
    # its limit) moves the estimates by ~1e-5 of their scale and the std by ~1e-3 (relative)
    np.testing.assert_allclose(ours.states, reference.states, atol=1e-5 * np.abs(reference.states).max())
    np.testing.assert_allclose(ours.state_std, reference.state_std, rtol=2e-3)


def test_unknown_inputs_reach_the_exact_posterior_and_are_calibrated():
    rng = np.random.default_rng(11)
    system = random_system(rng, 3, 2, 1)
    dt, N, width = 0.1, 400, 0.3
    u = gp_inputs(rng, N, 1, dt, 0.5, 0.5, 1.0)
    log = attend.simulate(system, u, dt, process_kernel_width=width, sensor_kernel_width=0.2,
                          process_std=0.05, measurement_std=0.03, initial_state=rng.normal(size=3), seed=3)
    eta = np.full((N, 1), 0.5)
    exact = exact_posterior(system, dt, log.outputs, None, input_prior_mean=eta, input_prior_std=1.0,
                            input_kernel_width=0.5, process_kernel_width=width, sensor_kernel_width=0.2,
                            process_std=0.05, measurement_std=0.03, initial_std=2.0)
    estimator = KalmanEstimator(system, dt, sensor_precision=0.03**-2, process_precision=0.05**-2,
                                process_kernel_width=width, sensor_kernel_width=0.2, known_inputs=False,
                                input_prior_precision=1.0, input_kernel_width=0.5,
                                initial_state=np.zeros(3), initial_state_std=2.0)
    ours = estimator.estimate(log.outputs, eta)
    sse = lambda a, b: np.sum((a - b) ** 2)
    assert sse(ours.inputs, u) == pytest.approx(sse(exact.inputs, u), rel=0.03)
    assert sse(ours.states, log.states) == pytest.approx(sse(exact.states, log.states), rel=0.03)
    np.testing.assert_allclose(ours.input_std[20:-20], exact.input_std[20:-20], rtol=0.02)


def test_reported_std_is_calibrated_over_many_runs():
    """|error| < 2 std for about 95 % of samples (states), smoother and filter, pooled over 30
    independent random systems with random (separate, sometimes white) noise widths."""
    counts = {"smoother": [0, 0], "filter": [0, 0]}
    for seed in range(30):
        rng = np.random.default_rng(300 + seed)
        system = random_system(rng, int(rng.integers(2, 5)), int(rng.integers(1, 3)), 1)
        dt, N = 0.1, 300
        sw, sz = np.exp(rng.uniform(-4, -1)), np.exp(rng.uniform(-4, -1))
        widths = dict(process_kernel_width=rng.choice([0, 0.05, 0.1, 0.3]),
                      sensor_kernel_width=rng.choice([0, 0.05, 0.1, 0.3]))
        u = np.sin(np.arange(N) * dt * rng.uniform(0.5, 2))[:, None]
        log = attend.simulate(system, u, dt, process_std=sw, measurement_std=sz, seed=seed, **widths)
        estimator = KalmanEstimator(system, dt, sensor_precision=sz**-2, process_precision=sw**-2,
                                    initial_state=np.zeros(system.n_states), **widths)
        for name, estimate in (("smoother", estimator.estimate(log.outputs, u)),
                               ("filter", estimator.filter(log.outputs, u))):
            error = np.abs(estimate.states - log.states)[30:-30]
            counts[name][0] += np.sum(error < 2 * estimate.state_std[30:-30])
            counts[name][1] += error.size
    for name, (inside, total) in counts.items():
        assert 0.93 <= inside / total <= 0.97, (name, inside / total)


def test_online_filter_equals_batch_filter():
    dt, N = 0.1, 150
    system, u, log = random_log(2, (2, 1, 1), dt, N, kernel_width=0.2, process_std=0.1, measurement_std=0.05, seed=0)
    estimator = KalmanEstimator(system, dt, sensor_precision=400, process_precision=100, kernel_width=0.2)
    batch = estimator.filter(log.outputs, u)
    online = estimator.online()
    steps = [online.step(log.outputs[k], u[k]) for k in range(N)]
    np.testing.assert_allclose(np.array([s[0] for s in steps]), batch.states, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(np.array([s[2] for s in steps]), batch.state_std, rtol=1e-6)


def test_steady_gains_do_not_change_the_result(monkeypatch):
    """The steady-state shortcut equals the fully time-varying recursion."""
    import attend.perception.kalman_recursions as recursions

    dt, N = 0.1, 600
    system, u, log = random_log(4, (2, 1, 1), dt, N, kernel_width=0.3, process_std=0.1, measurement_std=0.05, seed=0)
    estimator = KalmanEstimator(system, dt, sensor_precision=400, process_precision=100, kernel_width=0.3)
    shortcut = estimator.estimate(log.outputs, u), estimator.filter(log.outputs, u)
    model = estimator._model
    schedule = recursions._gain_schedule(model["T"], model["Q"], model["H"], estimator.initial_prior(log.outputs)[1], N,
                                         model["steady_predicted"])
    assert schedule.steady < N // 2  # the shortcut is really taken
    monkeypatch.setattr(recursions, "STEADY_TOLERANCE", -1.0)  # never steady: every step time-varying
    exact = estimator.estimate(log.outputs, u), estimator.filter(log.outputs, u)
    scale = np.abs(exact[0].states).max()
    for fast, slow in zip(shortcut, exact):
        np.testing.assert_allclose(fast.states, slow.states, atol=1e-5 * scale)
        np.testing.assert_allclose(fast.state_std, slow.state_std, rtol=2e-3)


def test_unobservable_state_with_unknown_start_is_an_error():
    system = attend.LinearSystem([[-1.0, 0.0], [0.0, -2.0]], [[1.0], [1.0]], [[1.0, 0.0]], state_names=("a", "b"))
    with pytest.raises(AttendInputError, match="b: not observable"):
        KalmanEstimator(system, 0.1, sensor_precision=100, process_precision=100, kernel_width=0.2)
    with pytest.warns(ModelWarning, match="b: not observable"):
        KalmanEstimator(system, 0.1, sensor_precision=100, process_precision=100, kernel_width=0.2,
                        initial_state=[0, 0], initial_state_std=1.0)


def test_zero_sensor_precision_is_an_error():
    system = attend.LinearSystem([[-1.0]], [[1.0]], [[1.0]])
    with pytest.raises(AttendInputError, match="sensor_precision"):
        KalmanEstimator(system, 0.1, sensor_precision=0.0, process_precision=1.0, kernel_width=0.1)


@pytest.mark.parametrize("field, value", [("kernel_width", -1.0), ("kernel_width", float("nan")),
                                          ("process_kernel_width", "wide")])
def test_bad_widths_name_the_field(field, value):
    system = attend.LinearSystem([[-1.0]], [[1.0]], [[1.0]])
    kwargs = dict(kernel_width=0.1)
    kwargs[field] = value
    with pytest.raises(AttendInputError, match=field):
        KalmanEstimator(system, 0.1, sensor_precision=1.0, process_precision=1.0, **kwargs)


def test_missing_width_and_missing_inputs_are_errors():
    system = attend.LinearSystem([[-1.0]], [[1.0]], [[1.0]])
    with pytest.raises(AttendInputError, match="process_kernel_width: required"):
        KalmanEstimator(system, 0.1, sensor_precision=1.0, process_precision=1.0)
    estimator = KalmanEstimator(system, 0.1, sensor_precision=1.0, process_precision=1.0, kernel_width=0.1)
    with pytest.raises(AttendInputError, match="inputs"):
        estimator.estimate(np.zeros((10, 1)))
    with pytest.raises(AttendInputError, match="input_prior_precision"):
        KalmanEstimator(system, 0.1, sensor_precision=1.0, process_precision=1.0, kernel_width=0.1, known_inputs=False)
