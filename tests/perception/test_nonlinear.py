"""Nonlinear DEM and its baselines: Jacobians against analytic ones, the linear observer as an
oracle, EKF/UKF against attend's Kalman filter, batch = online, calibration, bad input."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models import NonlinearSystem, finite_difference_jacobian, simulate_nonlinear
from attend.models.linear import simulate
from attend.models.problems import convolution_model, mass_spring_damper
from attend.perception.dem import DEMObserver
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear_smoothers import (
    white_noise_options,
    coloured_unscented_smoother,
    extended_kalman,
    particle_smoother,
    unscented_kalman,
    white_noise_covariances,
)
from attend.perception.references import exact_posterior, kalman_filter, rts_smoother, simulation_covariances


def lorenz(x, v):
    return np.array([10.0 * (x[1] - x[0]), x[0] * (28.0 - x[2]) - x[1], x[0] * x[1] - 8.0 / 3.0 * x[2]])


def lorenz_jacobian(x, v):
    fx = np.array([[-10.0, 10.0, 0.0], [28.0 - x[2], -1.0, -x[0]], [x[1], x[0], -8.0 / 3.0]])
    return fx, np.zeros((3, 0))


def pendulum(x, v, theta=(9.81, 0.3)):
    return np.array([x[1], -theta[0] * np.sin(x[0]) - theta[1] * x[1] + v[0]])


def pendulum_sensor(x, v):
    return np.array([np.sin(x[0]), np.cos(x[0])])


def linear_as_nonlinear(system):
    A, B, C = system.A, system.B, system.C
    return NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, A.shape[0], B.shape[1], C.shape[0])


# --- Jacobians ------------------------------------------------------------------------------

@pytest.mark.parametrize("method", ["central", "complex"])
def test_jacobians_match_analytic(method):
    rng = np.random.default_rng(0)
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, jacobian_method=method)
    for _ in range(5):
        x, v = rng.normal(size=2), rng.normal(size=1)
        fx, fv, gx, gv = system.jacobians(x, v)
        np.testing.assert_allclose(fx, [[0, 1], [-9.81 * np.cos(x[0]), -0.3]], rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(fv, [[0], [1]], atol=1e-8)
        np.testing.assert_allclose(gx, [[np.cos(x[0]), 0], [-np.sin(x[0]), 0]], rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(gv, np.zeros((2, 1)), atol=1e-8)
    lorenz_system = NonlinearSystem(lorenz, lambda x, v: x, 3, 0, 3, jacobian_method=method)
    x = rng.normal(size=3) * 10
    fx, fv, gx, gv = lorenz_system.jacobians(x)
    np.testing.assert_allclose(fx, lorenz_jacobian(x, None)[0], rtol=1e-8, atol=1e-7)
    assert fv.shape == (3, 0) and gv.shape == (3, 0)
    np.testing.assert_allclose(gx, np.eye(3), atol=1e-9)


def test_vectorized_and_user_jacobians_agree():
    x = np.array([1.0, -2.0, 20.0])
    plain = NonlinearSystem(lorenz, lambda x, v: x, 3, 0, 3).jacobians(x)
    vectorized = NonlinearSystem(lorenz, lambda x, v: x, 3, 0, 3, vectorized=True).jacobians(x)
    analytic = NonlinearSystem(lorenz, lambda x, v: x, 3, 0, 3, jacobian_f=lorenz_jacobian,
                               jacobian_g=lambda x, v: (np.eye(3), np.zeros((3, 0)))).jacobians(x)
    for a, b, c in zip(plain, vectorized, analytic):
        np.testing.assert_allclose(a, c, atol=1e-7)
        np.testing.assert_allclose(b, c, atol=1e-7)


def test_parameters_are_passed():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, parameters=(4.0, 0.0))
    np.testing.assert_allclose(system.flow([np.pi / 2, 1.0], [0.5]), [1.0, -4.0 + 0.5])


def test_finite_difference_jacobian_of_a_quadratic():
    J = finite_difference_jacobian(lambda z: np.array([z[0] * z[1], z[1] ** 2]), np.array([3.0, 4.0]))
    np.testing.assert_allclose(J, [[4.0, 3.0], [0.0, 8.0]], rtol=1e-9)


# --- the linear observer as an oracle -------------------------------------------------------

@pytest.mark.parametrize("make", [mass_spring_damper, convolution_model])
@pytest.mark.parametrize("known", [False, True])
def test_linear_model_written_as_f_g_equals_linear_observer(make, known):
    linear = make()
    dt, n_samples = 0.1, 200
    time = np.arange(n_samples) * dt
    u = np.exp(-0.25 * (time - 8.0) ** 2)[:, None]
    log = simulate(linear, u, dt, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=3)
    settings = dict(dt=dt, kernel_width=0.5, sensor_precision=np.exp(8), process_precision=np.exp(8),
                    input_prior_precision=np.exp(-8), embedding_order=6, input_order=2, known_inputs=known)
    observer = DEMObserver(linear, **settings)
    reference = observer.estimate(log.outputs, u if known else None)
    estimate = NonlinearDEM(linear_as_nonlinear(linear), flow_time="seconds", **settings).estimate(
        log.outputs, u if known else None)
    # the two start differently (linear: order-0 MAP of the first sample, higher orders 0; nonlinear:
    # Gauss-Newton fit of the first window); the flows are the same, so the difference decays
    # (slowly: spectral radius 0.99; ~2e-6 of the scale by sample 100)
    scale = np.abs(reference.states).max()
    late = slice(100, None)
    np.testing.assert_allclose(estimate.states[late], reference.states[late], atol=1e-5 * scale)
    np.testing.assert_allclose(estimate.inputs[late], reference.inputs[late],
                               atol=1e-5 * max(1.0, np.abs(reference.inputs).max()))
    # the nonlinear std is the Laplace conditional covariance inv(Pi_X), which the linear observer
    # also computes (its reported std is the DEM filter's steady-state error instead)
    n, r = linear.n_states, linear.n_inputs
    laplace = np.sqrt(np.diag(observer.generalized_matrices()["Sigma_X"]))
    np.testing.assert_allclose(estimate.state_std, np.broadcast_to(laplace[:n], estimate.state_std.shape), rtol=1e-6)
    if not known:
        n_x = n * (settings["embedding_order"] + 1)
        np.testing.assert_allclose(estimate.input_std,
                                   np.broadcast_to(laplace[n_x: n_x + r], estimate.input_std.shape), rtol=1e-6)


def test_flow_in_samples_does_not_depend_on_the_time_unit():
    """Lorenz in seconds and in milliseconds (dt, s, f and Pi_w converted together; the states
    keep their units): the same estimates."""
    seconds = NonlinearSystem(lorenz, lambda x, v: 1.0 * x, 3, 0, 3)
    millis = NonlinearSystem(lambda x, v: lorenz(x, v) / 1000.0, lambda x, v: 1.0 * x, 3, 0, 3)
    log = simulate_nonlinear(seconds, 120, 0.01, kernel_width=0.02, process_std=20.0, measurement_std=1.0,
                             initial_state=[1.0, 1.0, 24.0], seed=0)
    in_s = NonlinearDEM(seconds, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                        embedding_order=4).estimate(log.outputs)
    in_ms = NonlinearDEM(millis, 10.0, kernel_width=20.0, sensor_precision=1.0, process_precision=1e6 / 400,
                         embedding_order=4).estimate(log.outputs)
    np.testing.assert_allclose(in_ms.states, in_s.states, atol=1e-6)
    np.testing.assert_allclose(in_ms.state_std, in_s.state_std, rtol=1e-6)


# --- estimation -----------------------------------------------------------------------------

def _lorenz_log(seed, n_samples=300):
    system = NonlinearSystem(lorenz, lambda x, v: 1.0 * x, 3, 0, 3, state_names=("x", "y", "z"))
    log = simulate_nonlinear(system, n_samples, 0.01, kernel_width=0.02, process_std=20.0, measurement_std=1.0,
                             initial_state=[1.0, 1.0, 24.0], seed=seed)
    return system, log


def test_batch_equals_online_autonomous():
    system, log = _lorenz_log(0, 80)
    dem = NonlinearDEM(system, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                       embedding_order=4)
    batch = dem.estimate(log.outputs)
    online = dem.online()
    rows = [row for row in (online.step(y) for y in log.outputs) if row is not None] + online.finish()
    assert len(rows) == len(log.outputs)
    np.testing.assert_allclose(np.array([r[0] for r in rows]), batch.states, atol=1e-12)
    assert batch.inputs.shape == (80, 0)


def test_batch_equals_online_with_unknown_input():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    u = np.sin(np.arange(60) * 0.05)[:, None]
    log = simulate_nonlinear(system, u, 0.05, kernel_width=0.1, process_std=0.3, measurement_std=0.05,
                             initial_state=[0.3, 0.0], seed=1)
    dem = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=10.0,
                       input_prior_precision=0.1, embedding_order=6, input_order=2)
    batch = dem.estimate(log.outputs)
    online = dem.online()
    rows = [row for row in (online.step(y, 0.0) for y in log.outputs) if row is not None] + online.finish()
    np.testing.assert_allclose(np.array([r[1] for r in rows]), batch.inputs, atol=1e-12)
    assert dem.delay == 3


def test_lorenz_estimates_beat_the_raw_data_and_std_is_calibrated():
    inside, errors, raw = [], [], []
    for seed in range(3):
        system, log = _lorenz_log(seed, 400)
        estimate = NonlinearDEM(system, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                                embedding_order=6).estimate(log.outputs)
        trim = slice(7, -7)
        error = (estimate.states - log.states)[trim]
        inside.append(np.abs(error) < 2 * estimate.state_std[trim])
        errors.append(np.sum(error**2))
        raw.append(np.sum((log.outputs - log.states)[trim] ** 2))
    assert np.sum(errors) < 0.7 * np.sum(raw)
    coverage = np.mean(np.concatenate(inside))
    assert 0.93 <= coverage <= 0.97, coverage


def test_pendulum_input_is_estimated_and_calibrated():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    time = np.arange(400) * 0.05
    u = (4 * np.exp(-0.5 * ((time - 5) / 0.7) ** 2) - 3 * np.exp(-0.5 * ((time - 12) / 1.0) ** 2))[:, None]
    log = simulate_nonlinear(system, u, 0.05, kernel_width=0.1, process_std=[0.05, 0.5], measurement_std=0.05,
                             initial_state=[0.5, 0.0], seed=0)
    estimate = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=[400.0, 4.0],
                            input_prior_precision=np.exp(-2), embedding_order=6, input_order=2).estimate(log.outputs)
    trim = slice(7, -7)
    # the input prior (smoothness of the 0.1 s noise kernel) leaves a rough input estimate: a
    # weak bound; the bumps themselves are found
    assert np.sum((estimate.inputs - u)[trim] ** 2) < 0.7 * np.sum(u[trim] ** 2)
    peak = slice(90, 111)
    assert np.mean(estimate.inputs[peak]) > 2.0
    inside = np.abs(estimate.states - log.states)[trim] < 2 * estimate.state_std[trim]
    assert 0.9 <= inside.mean() <= 0.99


# --- baselines ------------------------------------------------------------------------------

def _linear_log():
    linear = mass_spring_damper()
    dt = 0.1
    time = np.arange(150) * dt
    u = np.exp(-0.25 * (time - 6.0) ** 2)[:, None]
    log = simulate(linear, u, dt, kernel_width=0.05, process_std=0.05, measurement_std=0.05, seed=2)
    Q, R = simulation_covariances(linear, dt, 0.05, 0.05)
    return linear, dt, u, log, Q, R


@pytest.mark.parametrize("estimator", [extended_kalman, unscented_kalman])
def test_ekf_ukf_equal_kalman_on_a_linear_model(estimator):
    linear, dt, u, log, Q, R = _linear_log()
    model = linear_as_nonlinear(linear)
    for smooth, reference in ((False, kalman_filter), (True, rts_smoother)):
        kf = reference(linear, dt, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                       initial_covariance=1e-2)
        ours = estimator(model, dt, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                         initial_covariance=1e-2, smooth=smooth)
        np.testing.assert_allclose(ours.states, kf.states, atol=1e-8)
        np.testing.assert_allclose(ours.state_std, kf.state_std, rtol=1e-6, atol=1e-10)


def test_ekf_and_ukf_agree_on_a_mildly_nonlinear_pendulum():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    u = 0.2 * np.sin(np.arange(200) * 0.05)[:, None]
    log = simulate_nonlinear(system, u, 0.05, kernel_width=0.05, process_std=0.05, measurement_std=0.05,
                             initial_state=[0.2, 0.0], seed=4)
    Q, R = white_noise_covariances(system, 0.05, kernel_width=0.05, process_std=0.05, measurement_std=0.05)
    ekf = extended_kalman(system, 0.05, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                          initial_mean=[0.2, 0.0], initial_covariance=1e-2)
    ukf = unscented_kalman(system, 0.05, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                           initial_mean=[0.2, 0.0], initial_covariance=1e-2)
    assert np.max(np.abs(ekf.states - ukf.states)) < 0.02
    assert np.sqrt(np.mean((ukf.states - log.states) ** 2)) < 0.1


def test_augmented_ukf_estimates_an_unknown_input():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    time = np.arange(200) * 0.05
    u = (3 * np.exp(-0.5 * ((time - 5) / 0.7) ** 2))[:, None]
    log = simulate_nonlinear(system, u, 0.05, kernel_width=0.05, process_std=0.1, measurement_std=0.05,
                             initial_state=[0.2, 0.0], seed=5)
    Q, R = white_noise_covariances(system, 0.05, kernel_width=0.05, process_std=0.1, measurement_std=0.05)
    ukf = unscented_kalman(system, 0.05, log.outputs, process_covariance=Q, measurement_covariance=R,
                           input_variance=0.5, initial_mean=[0.2, 0.0], initial_covariance=1e-2)
    assert np.sum((ukf.inputs - u) ** 2) < 0.3 * np.sum(u**2)


def test_vectorized_systems_give_the_pointwise_kalman_estimates():
    # vectorized=True moves all sigma points (and the EKF's shifted points) in one call of f per RK4 stage
    pointwise = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    columns = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, vectorized=True)
    time = np.arange(120) * 0.05
    u = (3 * np.exp(-0.5 * ((time - 3) / 0.7) ** 2))[:, None]
    log = simulate_nonlinear(pointwise, u, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.05,
                             initial_state=[0.2, 0.0], seed=7)
    Q, R = white_noise_covariances(pointwise, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.05)
    kalman = dict(process_covariance=Q, measurement_covariance=R, initial_mean=[0.2, 0.0], initial_covariance=1e-2)
    runs = [(unscented_kalman, (log.outputs, u), kalman), (extended_kalman, (log.outputs, u), kalman),
            (unscented_kalman, (log.outputs,), dict(kalman, input_variance=0.5)),
            (unscented_kalman, (log.outputs, u), dict(kalman, input_variance=0.5, known_inputs=[True])),
            (coloured_unscented_smoother, (log.outputs, u), dict(kernel_width=0.1, process_std=0.1,
                                                                  measurement_std=0.05, initial_mean=[0.2, 0.0])),
            (coloured_unscented_smoother, (log.outputs,), dict(kernel_width=0.1, process_std=0.1, measurement_std=0.05,
                                                              input_prior_std=2.0, initial_mean=[0.2, 0.0]))]
    for function, data, options in runs:
        a = function(pointwise, 0.05, *data, **options)
        b = function(columns, 0.05, *data, **options)
        np.testing.assert_allclose(b.states, a.states, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b.inputs, a.inputs, rtol=0, atol=1e-10)
        np.testing.assert_allclose(b.state_std, a.state_std, rtol=1e-8, atol=1e-9)  # sqrt of a ~0 variance at x[0]


def test_a_vectorized_f_that_ignores_its_columns_is_named():
    system = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0])]).sum(axis=-1) * np.ones(2),
                             pendulum_sensor, 2, 1, 2, vectorized=True)
    y = np.zeros((10, 2))
    with pytest.raises(AttendInputError, match=r"f: with vectorized=True expected \(2, 5\) values"):
        unscented_kalman(system, 0.05, y, np.zeros((10, 1)), process_covariance=1e-2, measurement_covariance=1e-2)


def test_white_noise_options_of_dem_precisions():
    Pi_w, Pi_z = np.array([[4.0, 1.0], [1.0, 2.0]]), np.diag([100.0, 400.0])
    options = white_noise_options(0.05, process_precision=Pi_w, sensor_precision=Pi_z, input_prior_precision=[0.5, 2.0],
                                  input_kernel_width=0.1, known_inputs=[True, False], input_mean=[1.0, 0.0])
    np.testing.assert_allclose(options["process_covariance"], 0.05**2 * np.linalg.inv(Pi_w), rtol=1e-14)
    np.testing.assert_allclose(options["measurement_covariance"], np.diag([0.01, 0.0025]), rtol=1e-14)
    # one-sample steps of a Gaussian-kernel process of variance 1/P_v: 2 (1 - exp(-dt^2 / (4 s^2))) / P_v
    np.testing.assert_allclose(np.diag(options["input_variance"]), [0.0, 2 * (1 - np.exp(-0.0625)) / 2.0],
                               rtol=1e-14)
    assert options["known_inputs"].tolist() == [True, False] and options["input_mean"] == [1.0, 0.0]
    assert set(white_noise_options(0.05, process_precision=Pi_w,
                                   sensor_precision=Pi_z)) == {"process_covariance", "measurement_covariance"}
    with pytest.raises(AttendInputError, match="sensor_precision: the white-noise smoother needs a positive definite"):
        white_noise_options(0.05, process_precision=Pi_w, sensor_precision=np.diag([1.0, 0.0]))
    with pytest.raises(AttendInputError, match="input_prior_precision: .* > 0 for every unknown input"):
        white_noise_options(0.05, process_precision=Pi_w, sensor_precision=Pi_z, input_prior_precision=[0.0, 0.0],
                            input_kernel_width=0.1, known_inputs=[True, False])


def test_rk4_substeps_follow_the_fastest_mode():
    from attend.perception.nonlinear_smoothers.kalman import rk4_substeps

    def linear(A):
        return NonlinearSystem(lambda x, v: A @ x, lambda x, v: x[:1], 2, 0, 1)

    points = np.zeros((5, 2))
    # ceil(dt rho / 0.2): rho = 50 1/s at dt = 0.01 s -> 3; a rotation at 3 rad/s -> 1; clipped to 1..limit
    assert rk4_substeps(linear(np.diag([-50.0, -1.0])), 0.01, points, np.zeros((5, 0))) == 3
    assert rk4_substeps(linear(np.array([[0.0, 3.0], [-3.0, 0.0]])), 0.01, points, np.zeros((5, 0))) == 1
    assert rk4_substeps(linear(np.diag([-1e6, -1.0])), 0.01, points, np.zeros((5, 0)), limit=300) == 300
    nan = NonlinearSystem(lambda x, v: np.sqrt(x - 1.0), lambda x, v: x[:1], 2, 0, 1)
    with np.errstate(invalid="ignore"):
        assert rk4_substeps(nan, 0.01, points, np.zeros((5, 0))) == 10
    # a stiff mode (rho dt = 50) diverges with the fixed 10 sub-steps (RK4 is stable to h rho ~ 2.8)
    stiff = linear(np.diag([-5000.0, -1.0]))
    y = np.ones((30, 1))
    options = dict(process_covariance=1e-4, measurement_covariance=1e-2, initial_mean=[1.0, 1.0],
                   initial_covariance=1.0)
    with pytest.raises(AttendInputError, match=r"substeps: 10 RK4 sub-steps per sample are unstable for this model "
                                                r"\(dt rho\(df/dx\) = 50"):
        unscented_kalman(stiff, 0.01, y, **options)  # it returned ~1e29 without an error before
    steps = rk4_substeps(stiff, 0.01, points, np.zeros((30, 0)))
    assert steps == 250
    assert np.all(np.isfinite(unscented_kalman(stiff, 0.01, y, substeps=steps, **options).states))


def test_the_evidence_floor_stops_only_a_run_that_cannot_reach_it():
    """Closed form: each sample adds at most -1/2 (log|R| + m log 2 pi) to the unscented filter's
    log-likelihood (S >= R). A floor the run reaches changes nothing (to the bit); a floor it misses
    stops the filter at the first sample k where the log-likelihood of samples 0..k-1 (the filter on
    that prefix) plus N - k times the bound falls below it; a spread with a negative covariance weight
    ignores the floor (the bound does not hold there)."""
    from attend.perception.nonlinear_smoothers import EvidenceBelowFloor
    from attend.perception.nonlinear_smoothers.kalman import evidence_bound_per_sample

    system = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0]) - 0.2 * x[1]]),
                             lambda x, v: np.array([np.sin(x[0]), x[1]]), 2, 0, 2)
    log = simulate_nonlinear(system, 80, 0.1, kernel_width=0.0, process_std=0.05, measurement_std=0.1,
                             initial_state=[1.0, 0.0], seed=4)
    options = dict(process_covariance=np.diag([1e-4, 1e-4]), measurement_covariance=np.diag([0.01, 0.02]),
                   initial_mean=[0.0, 0.0], initial_covariance=np.eye(2), substeps=2)
    full = unscented_kalman(system, 0.1, log.outputs, **options)
    bound = evidence_bound_per_sample(options["measurement_covariance"])
    assert bound == pytest.approx(-0.5 * (np.log(0.01 * 0.02) + 2 * np.log(2 * np.pi)), rel=1e-14)
    assert full.log_likelihood <= len(log.outputs) * bound
    reached = unscented_kalman(system, 0.1, log.outputs, evidence_floor=full.log_likelihood - 1e-9, **options)
    assert reached.log_likelihood == full.log_likelihood
    np.testing.assert_array_equal(reached.states, full.states)
    np.testing.assert_array_equal(reached.state_std, full.state_std)
    floor = full.log_likelihood + 5.0
    with pytest.raises(EvidenceBelowFloor) as stopped:
        unscented_kalman(system, 0.1, log.outputs, evidence_floor=floor, **options)
    k, N = stopped.value.samples, len(log.outputs)
    assert 1 <= k < N

    def reachable(samples):  # the log-likelihood of the first samples plus the most the others can add
        prefix = unscented_kalman(system, 0.1, log.outputs[:samples], smooth=False, **options)
        return prefix.log_likelihood + (N - samples) * bound

    assert reachable(k) < floor
    assert k == 1 or reachable(k - 1) >= floor
    negative = unscented_kalman(system, 0.1, log.outputs, alpha=0.5, **options)  # weight on the mean -0.25
    assert unscented_kalman(system, 0.1, log.outputs, alpha=0.5, evidence_floor=negative.log_likelihood + 5.0,
                            **options).log_likelihood == negative.log_likelihood


def test_particle_smoother_near_exact_posterior_on_a_linear_model():
    linear = mass_spring_damper()
    dt, s = 0.1, 0.2
    u = np.zeros((120, 1))
    log = simulate(linear, u, dt, kernel_width=s, process_std=0.3, measurement_std=0.05, seed=6,
                   initial_state=[0.5, 0.0])
    # simulate() adds dt w per sample: as simulate_nonlinear's ZOH only for the linear drift
    exact = exact_posterior(linear, dt, log.outputs, u, kernel_width=s, process_std=0.3, measurement_std=0.05,
                            initial_mean=[0.5, 0.0], initial_std=1e-2)
    particles = particle_smoother(linear_as_nonlinear(linear), dt, log.outputs, u, kernel_width=s,
                                  process_std=0.3, measurement_std=0.05, initial_mean=[0.5, 0.0],
                                  initial_std=1e-2, n_particles=1500, ar_order=3, lag=15, seed=0)
    sse_exact = np.sum((exact.states - log.states) ** 2)
    sse_particles = np.sum((particles.states - log.states) ** 2)
    assert sse_particles < 1.5 * sse_exact


# --- bad input ------------------------------------------------------------------------------

def test_bad_models_and_settings_raise():
    with pytest.raises(AttendInputError, match="f:"):
        NonlinearSystem(3, pendulum_sensor, 2, 1, 2)
    with pytest.raises(AttendInputError, match="n_states"):
        NonlinearSystem(pendulum, pendulum_sensor, 0, 1, 2)
    with pytest.raises(AttendInputError, match="jacobian_method"):
        NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, jacobian_method="forward")
    with pytest.raises(AttendInputError, match="state_names"):
        NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, state_names=("a",))
    wrong = NonlinearSystem(lambda x, v: np.zeros(3), pendulum_sensor, 2, 1, 2)
    with pytest.raises(AttendInputError, match="f: expected 2 values"):
        wrong.flow([0.0, 0.0], [0.0])
    broken = NonlinearSystem(lambda x, v: x[5], pendulum_sensor, 2, 1, 2)
    with pytest.raises(AttendInputError, match="f: raised IndexError"):
        broken.flow([0.0, 0.0], [0.0])
    bad_jacobian = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2, jacobian_f=lambda x, v: np.eye(2))
    with pytest.raises(AttendInputError, match="jacobian_f: expected the pair"):
        bad_jacobian.jacobians([0.0, 0.0], [0.0])
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    with pytest.raises(AttendInputError, match="input_prior_precision"):
        NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=1.0, process_precision=1.0)
    with pytest.raises(AttendInputError, match="kernel_width"):
        NonlinearDEM(system, 0.05, kernel_width=-0.1, sensor_precision=1.0, process_precision=1.0,
                     input_prior_precision=1.0)
    with pytest.raises(AttendInputError, match="flow_time"):
        NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=1.0, process_precision=1.0,
                     input_prior_precision=1.0, flow_time="hours")
    with pytest.raises(AttendInputError, match="system"):
        NonlinearDEM(mass_spring_damper(), 0.05, kernel_width=0.1, sensor_precision=1.0, process_precision=1.0,
                     input_prior_precision=1.0)
    dem = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=1.0, process_precision=1.0,
                       input_prior_precision=1.0)
    with pytest.raises(AttendInputError, match="outputs: expected 2 columns"):
        dem.estimate(np.zeros((50, 3)))
    with pytest.raises(AttendInputError, match="outputs: expected finite"):
        dem.estimate(np.full((50, 2), np.nan))
    with pytest.raises(AttendInputError, match="at least 7 samples"):
        dem.estimate(np.zeros((3, 2)))
    with pytest.raises(AttendInputError, match="input_prior"):
        dem.estimate(np.zeros((50, 2)), np.zeros((49, 1)))
    known = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=1.0, process_precision=1.0, known_inputs=True)
    with pytest.raises(AttendInputError, match="inputs"):
        known.estimate(np.zeros((50, 2)))


def test_divergence_stops_with_a_message_naming_the_settings():
    drift = NonlinearSystem(lambda x, v: 0.0 * x, lambda x, v: x, 1, 0, 1)
    dem = NonlinearDEM(drift, 0.1, kernel_width=0.2, sensor_precision=100.0, process_precision=1.0, embedding_order=2,
                       divergence_limit=20.0)
    with pytest.raises(AttendInputError, match="diverged at sample .*process_precision"):
        dem.estimate(np.arange(60.0)[:, None])
    undefined = NonlinearSystem(lambda x, v: 0.0 * x, lambda x, v: np.sqrt(3.0 - x) if x[0] < 3 else np.array([np.nan]),
                                1, 0, 1)
    with pytest.raises(AttendInputError, match="diverged"):
        NonlinearDEM(undefined, 0.1, kernel_width=0.2, sensor_precision=100.0, process_precision=1.0,
                     embedding_order=2).estimate(-np.arange(60.0)[:, None] / 5)


def test_path_motion_equals_linearized_on_a_linear_model():
    linear = convolution_model()
    log = simulate(linear, np.zeros((60, 1)), 0.1, kernel_width=0.5, process_std=0.1, measurement_std=0.1, seed=1)
    settings = dict(dt=0.1, kernel_width=0.5, sensor_precision=100.0, process_precision=100.0,
                    input_prior_precision=1.0, embedding_order=4, input_order=2)
    model = linear_as_nonlinear(linear)
    a = NonlinearDEM(model, **settings).estimate(log.outputs)
    b = NonlinearDEM(model, motion="path", **settings).estimate(log.outputs)
    np.testing.assert_allclose(b.states, a.states, atol=1e-7)


def test_fixed_lag_ukf_equals_kalman_fixed_lag_on_a_linear_model():
    linear, dt, u, log, Q, R = _linear_log()
    kf = kalman_filter(linear, dt, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                       initial_covariance=1e-2, lag=3)
    ours = unscented_kalman(linear_as_nonlinear(linear), dt, log.outputs, u, process_covariance=Q,
                            measurement_covariance=R, initial_covariance=1e-2, smooth=3)
    np.testing.assert_allclose(ours.states, kf.states, atol=1e-8)


def test_input_kernel_width_sets_the_input_smoothness():
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    same = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=4.0,
                        input_prior_precision=0.1, embedding_order=6, input_order=2, input_kernel_width=0.1)
    default = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=4.0,
                           input_prior_precision=0.1, embedding_order=6, input_order=2)
    slow = NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=4.0,
                        input_prior_precision=0.1, embedding_order=6, input_order=2, input_kernel_width=0.7)
    np.testing.assert_allclose(same.generalized_matrices()["Vv"], default.generalized_matrices()["Vv"])
    assert slow.generalized_matrices()["S_d"][2, 2] > 10 * default.generalized_matrices()["S_d"][2, 2]
    with pytest.raises(AttendInputError, match="input_kernel_width"):
        NonlinearDEM(system, 0.05, kernel_width=0.1, sensor_precision=400.0, process_precision=4.0,
                     input_prior_precision=0.1, input_kernel_width=0.0)


def test_coloured_noise_models_refuse_a_nonstationary_ar_fit():
    # s/dt = 14 (the pendulum's input prior): AR(8) fitted to rho is not stationary and blew up silently
    system = NonlinearSystem(pendulum, pendulum_sensor, 2, 1, 2)
    y = np.zeros((30, 2))
    for function, extra in ((coloured_unscented_smoother, {}), (particle_smoother, dict(n_particles=10))):
        with pytest.raises(AttendInputError, match=r"ar_order: an AR\(\d\) model"):
            function(system, 0.05, y, kernel_width=0.7, process_std=[0.05, 0.5], measurement_std=0.05,
                     input_prior_std=1.0, ar_order=8, **extra)
        function(system, 0.05, y, kernel_width=0.7, process_std=[0.05, 0.5], measurement_std=0.05,
                 input_prior_std=1.0, ar_order=3, **extra)  # AR(3) is fine
