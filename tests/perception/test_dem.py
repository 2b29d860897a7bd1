"""DEM observer: the flow and precision against the free energy written out independently,
batch = online, invariance to the time unit, accuracy, and bad input."""

import re
import warnings

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.generalized import embed
from attend.models.linear import ModelWarning, simulate
from attend.models.problems import convolution_model, mass_spring_damper
from attend.perception.dem import DEMObserver
from attend.perception.dem_flow import start_state
from attend.perception.recurrence import _sequential, linear_recurrence


def _observer(**overrides):
    settings = dict(system=convolution_model(), dt=0.1, kernel_width=0.5, sensor_precision=np.exp(8),
                    process_precision=np.exp(6), input_prior_precision=np.exp(-2), embedding_order=3,
                    input_order=2)
    settings.update(overrides)
    return DEMObserver(**settings)


def _free_energy(observer, X, y_tilde, eta_tilde):
    """F = -1/2 e' Pi e with the errors of spec §5, written without the observer's matrices."""
    system, p, d = observer.system, observer.embedding_order, observer.input_order
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    x = X[: n * (p + 1)].reshape(p + 1, n)
    v = X[n * (p + 1):].reshape(d + 1, r)
    v_padded = np.zeros((p + 1, r))
    v_padded[: min(p, d) + 1] = v[: min(p, d) + 1]
    e_y = (y_tilde.reshape(p + 1, m) - x @ system.C.T).ravel()
    e_v = (v - eta_tilde.reshape(d + 1, r)).ravel()
    x_next = np.vstack([x[1:], np.zeros((1, n))])
    e_x = (x_next - x @ system.A.T - v_padded @ system.B.T).ravel()
    mats = observer.generalized_matrices()
    return -0.5 * (e_y @ mats["Vy"] @ e_y + e_v @ mats["Vv"] @ e_v + e_x @ mats["W"] @ e_x)


def test_flow_is_shift_plus_free_energy_gradient():
    observer = _observer()
    mats = observer.generalized_matrices()
    rng = np.random.default_rng(0)
    X = rng.standard_normal(mats["A_obs"].shape[0])
    y_tilde = rng.standard_normal(4 * 4)
    eta_tilde = rng.standard_normal(3)
    step = 1e-6
    gradient = np.array([
        (_free_energy(observer, X + step * e, y_tilde, eta_tilde)
         - _free_energy(observer, X - step * e, y_tilde, eta_tilde)) / (2 * step)
        for e in np.eye(len(X))
    ])
    D_X = np.zeros_like(mats["A_obs"])
    D_X[:8, :8] = mats["Dx"]
    D_X[8:, 8:] = mats["Dv"]
    flow = mats["A_obs"] @ X + mats["B_obs"] @ np.concatenate([y_tilde, eta_tilde])
    np.testing.assert_allclose(flow, D_X @ X + gradient, rtol=1e-6, atol=1e-6 * np.abs(gradient).max())


def test_conditional_precision_is_negative_hessian():
    observer = _observer(embedding_order=2, input_order=1)
    mats = observer.generalized_matrices()
    size = mats["Pi_X"].shape[0]
    rng = np.random.default_rng(1)
    y_tilde, eta_tilde = rng.standard_normal(12), rng.standard_normal(2)
    step = 1e-3
    hessian = np.empty((size, size))
    base = np.zeros(size)
    for i, ei in enumerate(np.eye(size)):
        for j, ej in enumerate(np.eye(size)):
            hessian[i, j] = (
                _free_energy(observer, base + step * (ei + ej), y_tilde, eta_tilde)
                - _free_energy(observer, base + step * (ei - ej), y_tilde, eta_tilde)
                - _free_energy(observer, base - step * (ei - ej), y_tilde, eta_tilde)
                + _free_energy(observer, base - step * (ei + ej), y_tilde, eta_tilde)
            ) / (4 * step**2)
    np.testing.assert_allclose(-hessian, mats["Pi_X"], rtol=1e-5, atol=1e-5 * np.abs(hessian).max())


def test_discretisation_is_the_exact_solution_of_the_flow():
    """One step of X[k] = Phi X + Gamma Y equals integrating dX/dt = A_obs X + B_obs Y finely."""
    from scipy.integrate import solve_ivp

    observer = _observer(embedding_order=2, input_order=1, sensor_precision=10.0, process_precision=5.0)
    mats = observer.generalized_matrices()
    rng = np.random.default_rng(2)
    X0, Y = rng.standard_normal(mats["A_obs"].shape[0]), rng.standard_normal(mats["B_obs"].shape[1])
    solution = solve_ivp(lambda t, X: mats["A_obs"] @ X + mats["B_obs"] @ Y, (0, 0.1), X0,
                         method="Radau", rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(mats["transition"] @ X0 + mats["gain"] @ Y, solution.y[:, -1], rtol=1e-7, atol=1e-9)


def test_folded_window_gain_equals_embedding_then_gain():
    observer = _observer()
    mats = observer.generalized_matrices()
    rng = np.random.default_rng(3)
    y, eta = rng.standard_normal((50, 4)), rng.standard_normal((50, 1))
    k = 20
    Y = np.concatenate([embed(y, 4, 0.1)[k], embed(eta, 3, 0.1)[k]])
    window = observer._raw_windows(np.hstack([y, eta]), k, k + 1)[0]
    np.testing.assert_allclose(mats["window_gain"] @ window, mats["gain"] @ Y, rtol=1e-10, atol=1e-10)


def test_blocked_recurrence_equals_sequential():
    rng = np.random.default_rng(4)
    M = rng.standard_normal((9, 9))
    transition = 0.98 * M / np.abs(np.linalg.eigvals(M)).max()
    for n_samples in (1, 63, 64, 65, 1000, 4097):
        drive, start = rng.standard_normal((n_samples, 9)), rng.standard_normal(9)
        np.testing.assert_allclose(linear_recurrence(transition, drive, start),
                                   _sequential(transition, drive, start), atol=1e-11)


@pytest.mark.parametrize("known_inputs", [False, True])
def test_online_equals_batch(known_inputs):
    system = convolution_model()
    t = np.arange(200) * 0.1
    u = np.exp(-0.25 * (t - 12) ** 2)[:, None]
    log = simulate(system, u, 0.1, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=5)
    observer = _observer(embedding_order=6, known_inputs=known_inputs,
                         input_prior_precision=None if known_inputs else np.exp(-8))
    signal = u if known_inputs else np.full_like(u, 0.5)
    batch = observer.estimate(log.outputs, signal, segment=64)
    online = observer.online()
    results = [online.step(y, s) for y, s in zip(log.outputs, signal)]
    assert all(r is None for r in results[: observer.delay])
    results = [r for r in results if r is not None] + online.finish()
    np.testing.assert_allclose(np.array([r[0] for r in results]), batch.states, atol=1e-10)
    np.testing.assert_allclose(np.array([r[1] for r in results]), batch.inputs, atol=1e-10)


def test_overflowing_precisions_give_a_clear_error():
    """A flow so stiff that expm overflows is reported, not returned as NaN estimates."""
    with pytest.raises(AttendInputError, match="could not be discretised"):
        _observer(sensor_precision=1e300, process_precision=1e300)


def test_more_embedding_orders_help_under_coloured_noise():
    """The paper's Fig. 2 claim on its mass-spring-damper: input SSE at p = 3 below p = 0 (5 seeds)."""
    system = mass_spring_damper()
    t = np.arange(320) * 0.1
    u = np.exp(-0.25 * (t - 12) ** 2)[:, None]
    wins = 0
    for seed in range(5):
        log = simulate(system, u, 0.1, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=seed)
        sse = []
        for p in (0, 3):
            est = DEMObserver(system, 0.1, kernel_width=0.5, sensor_precision=np.exp(8), process_precision=np.exp(8),
                              input_prior_precision=np.exp(-8), embedding_order=p, input_order=2).estimate(log.outputs)
            sse.append(np.sum((est.inputs[8:-8] - u[8:-8]) ** 2))
        wins += sse[1] < sse[0]
    assert wins == 5


def test_standard_deviations_shrink_with_sensor_precision():
    loose = _observer(sensor_precision=1e2).estimate(np.zeros((2000, 4)))
    tight = _observer(sensor_precision=1e4).estimate(np.zeros((2000, 4)))
    assert np.all(tight.state_std[0] < loose.state_std[0])


def test_bad_input_names_the_field():
    observer = _observer()
    with pytest.raises(AttendInputError, match="outputs 'y1': every value is missing"):  # NaN: missing (gaps)
        observer.estimate(np.full((30, 4), np.nan))
    with pytest.raises(AttendInputError, match="outputs: expected finite numbers"):
        observer.estimate(np.full((30, 4), np.inf))
    with pytest.raises(AttendInputError, match="outputs: expected 4 columns"):
        observer.estimate(np.zeros((30, 3)))
    with pytest.raises(AttendInputError, match="at least 4 samples"):
        observer.estimate(np.zeros((3, 4)))
    with pytest.raises(AttendInputError, match="input_prior: expected shape"):
        observer.estimate(np.zeros((30, 4)), np.zeros((29, 1)))
    with pytest.raises(AttendInputError, match="kernel_width"):
        _observer(kernel_width=0.0)
    with pytest.raises(AttendInputError, match="sensor_precision: expected non-negative"):
        _observer(sensor_precision=-1.0)
    with pytest.raises(AttendInputError, match="process_precision: expected finite"):
        _observer(process_precision=np.inf)
    with pytest.raises(AttendInputError, match="input_prior_precision: required"):
        _observer(input_prior_precision=None)
    with pytest.raises(AttendInputError, match="embedding_order"):
        _observer(embedding_order=2.5)


# --- stability analysis, automatic order, start, widths, honest std (issue 12) ----------------

def _random_stable_system(seed):
    from attend import LinearSystem

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    m, r = int(rng.integers(1, n + 1)), int(rng.integers(1, 3))
    A = rng.standard_normal((n, n)) / np.sqrt(n)
    A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.1, 1.0)) * np.eye(n)
    return LinearSystem(A, rng.standard_normal((n, r)), rng.standard_normal((m, n))), rng


def test_auto_order_is_stable_on_a_bank_of_random_systems():
    """20 random stable systems (n 2..6, s/dt 0.5..5): 'auto' never gives a divergent observer."""
    from attend.models.linear import simulate as sim

    divergent, refused, orders = 0, 0, []
    for seed in range(20):
        system, rng = _random_stable_system(seed)
        dt = 0.05
        s = rng.uniform(0.5, 5.0) * dt
        observer = DEMObserver(system, dt, kernel_width=s, sensor_precision=1 / 0.05**2, process_precision=1 / 0.1**2,
                               input_prior_precision=1.0)
        analysis = observer.analysis()
        assert analysis.automatic and analysis.embedding_order == observer.embedding_order <= 6
        assert analysis.spectral_radius < 1.0
        orders.append(observer.embedding_order)
        u = np.zeros((2000, system.n_inputs))
        log = sim(system, u, dt, kernel_width=s, process_std=0.1, measurement_std=0.05, seed=seed)
        try:
            estimate = observer.estimate(log.outputs)
        except AttendInputError as error:  # too short for this observer's start: refused, not wrong
            assert "remembers its start" in str(error)
            refused += 1
            continue
        error = np.abs(estimate.states[200:-200] - log.states[200:-200])
        divergent += not (np.all(np.isfinite(error)) and error.max() < 10 * (np.abs(log.states).max() + 1))
    # logs of 100 s: some observers remember their start longer (p < d leaves the input's highest
    # orders free of the motion) and are refused with an error, never run into garbage
    assert divergent == 0 and refused <= 8, (divergent, refused)
    assert max(orders) >= 4  # not trivially p = 0


def _growth_in(warning_or_error) -> float:
    return float(re.search(r"grow ([0-9.]+)x", str(warning_or_error)).group(1))


def test_slightly_unstable_observer_runs_on_a_short_log_and_is_refused_on_a_long_one():
    """Sensor precision 1 at p = 3: the flow's slowest mode grows (rho = 1.0044 per sample, doubling
    in ~158 samples). What is judged is its growth over the log, rho^N: under 2x it runs with a
    warning naming the growth and the setting; 2x or more is refused naming embedding_order."""
    from scipy.linalg import expm

    observer = _observer(sensor_precision=1.0)  # no log yet: nothing refused, nothing to warn about
    A_obs = observer.generalized_matrices()["A_obs"]
    rho = float(np.max(np.abs(np.linalg.eigvals(expm(A_obs * observer.dt)))))  # independently of dem_flow
    assert 1.001 < rho < 1.01
    analysis = observer.analysis()
    assert analysis.spectral_radius == pytest.approx(rho, rel=1e-12)
    assert analysis.doubling_time == pytest.approx(observer.dt * np.log(2) / np.log(rho), rel=1e-9)
    doubling = int(np.log(2) / np.log(rho))  # samples
    assert np.all(np.isfinite(analysis.state_std)) and np.all(analysis.state_std > 0)
    short = doubling // 2
    y = np.random.default_rng(0).standard_normal((short, 4))
    with pytest.warns(ModelWarning, match=r"embedding_order: the DEM observer at p = 3 is not stable .*"
                                          rf"\({short} samples, .*grow .*x \(< 2x: run") as record:
        estimate = observer.estimate(y)
    growth = [_growth_in(w.message) for w in record if "not stable" in str(w.message)]
    assert growth[0] == pytest.approx(rho**short, rel=2e-3)  # the closed form, to the 3 digits printed
    assert np.all(np.isfinite(estimate.states)) and np.all(np.isfinite(estimate.state_std))
    # the homogeneous flow grows as the closed form says: Phi^N on the slowest eigenvector
    values, vectors = np.linalg.eig(observer.generalized_matrices()["transition"])
    slowest = vectors[:, np.argmax(np.abs(values))]
    grown = np.linalg.matrix_power(observer.generalized_matrices()["transition"], short) @ slowest
    assert np.linalg.norm(grown) / np.linalg.norm(slowest) == pytest.approx(rho**short, rel=1e-9)
    long = 3 * doubling
    with pytest.raises(AttendInputError, match=rf"embedding_order: the DEM observer at p = 3 is not stable .*"
                                               rf"\({long} samples, .*grow .*x \(>= 2x.*a log shorter than .* s "
                                               r"runs, else no order 0..6 is stable.*allow_unstable=True") as error:
        observer.estimate(np.zeros((long, 4)))
    assert _growth_in(error.value) == pytest.approx(rho**long, rel=2e-3)
    with pytest.raises(AttendInputError, match="embedding_order: .* a stream has no end"):
        observer.online()
    allowed = _observer(sensor_precision=1.0, allow_unstable=True)  # runs, without a std
    with pytest.warns(ModelWarning, match="running it anyway"):
        estimate = allowed.estimate(np.zeros((long, 4)))
    assert np.all(np.isnan(estimate.state_std))
    with pytest.raises(AttendInputError, match="'auto' found no order 0..6 with a stable DEM observer"):
        _observer(sensor_precision=1.0, embedding_order="auto")


def test_order_that_doubles_within_the_shortest_log_is_refused_at_construction():
    with pytest.raises(AttendInputError, match=r"embedding_order: the DEM observer is unstable at p = 3 for this "
                                               r"model \(spectral radius \d\.\d+ >= 1: its slowest mode grows "
                                               r".*x over the shortest log of 4 samples\).*allow_unstable=True"):
        _observer(sensor_precision=1e-4, dt=3.0)


def test_no_stability_warning_on_a_fine_observer():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        observer = _observer(embedding_order=6, sensor_precision=np.exp(8), process_precision=np.exp(8),
                             input_prior_precision=np.exp(-8))
        observer.estimate(np.zeros((320, 4)), np.full((320, 1), 0.5))


def test_drifting_observer_is_refused_for_a_short_log():
    """The mass-spring-damper at p = 0 (input orders free of the motion) remembers a start error in
    the input's derivative for ~1e4 s: a 32 s log is fine (it grows only late), a 1e4 s log is not."""
    observer = DEMObserver(mass_spring_damper(), 0.1, kernel_width=0.5, sensor_precision=np.exp(8),
                           process_precision=np.exp(8), input_prior_precision=np.exp(-8), embedding_order=0,
                           input_order=2)
    assert observer.analysis().start_time_constant > 1000
    observer.estimate(np.zeros((320, 1)))
    with pytest.raises(AttendInputError, match="embedding_order: .* remembers its start"):
        observer.estimate(np.zeros((100_000, 1)))


def test_start_has_higher_orders_at_their_prior_mean():
    observer = _observer(embedding_order=6, edges="clamp")
    rng = np.random.default_rng(7)
    y = rng.standard_normal((50, 4))
    eta = np.full((50, 1), 0.3)
    X = observer.estimate(y, eta, keep_generalized=True)
    start = start_state(observer, np.hstack([y, eta]), 0, edge=False)
    n, n_x = 2, observer.n_state_coordinates
    assert np.all(start[n:n_x] == 0.0)  # state derivatives at 0
    np.testing.assert_allclose(start[n_x + 1:], 0.0, atol=1e-12)  # eta constant: derivatives 0
    assert np.all(np.isfinite(X.states))
    # the constructor's initial_state sets order 0 of the states
    given = _observer(embedding_order=6, initial_state=[0.25, -0.5])
    np.testing.assert_array_equal(start_state(given, np.hstack([y, eta]), 0, edge=True)[:2], [0.25, -0.5])
    with pytest.raises(AttendInputError, match="initial_state: expected 2 order-0 states"):
        _observer(initial_state=[1.0, 2.0, 3.0])


def test_safe_start_beats_the_static_map_start_on_a_slow_observer():
    """Starting the higher orders from the data puts large values there; the default does not."""
    observer = _observer(embedding_order=6, sensor_precision=np.exp(8), process_precision=np.exp(8),
                         input_prior_precision=np.exp(-8))
    log = simulate(convolution_model(), np.zeros((320, 1)), 0.1, kernel_width=0.5, process_std=np.exp(-4),
                   measurement_std=np.exp(-4), seed=11)
    default = observer.estimate(log.outputs)
    mats = observer.generalized_matrices()
    window = observer._raw_windows(np.hstack([log.outputs, np.zeros((320, 1))]), 0, 1)[0]
    static_map = np.linalg.lstsq(mats["Pi_X"], mats["window_B_obs"] @ window, rcond=None)[0]
    old = observer.estimate(log.outputs, initial_state=static_map)
    sse = lambda e: np.sum((e.states - log.states) ** 2)  # noqa: E731
    assert sse(default) <= sse(old)


def test_separate_widths_equal_to_kernel_width_give_the_same_result():
    rng = np.random.default_rng(8)
    y, eta = rng.standard_normal((100, 4)) * 0.1, np.full((100, 1), 0.5)
    common = _observer(embedding_order=4).estimate(y, eta)
    split = _observer(embedding_order=4, kernel_width=None, process_kernel_width=0.5,
                      sensor_kernel_width=0.5).estimate(y, eta)
    np.testing.assert_array_equal(common.states, split.states)
    np.testing.assert_array_equal(common.state_std, split.state_std)
    other = _observer(embedding_order=4, sensor_kernel_width=0.3)
    mats = other.generalized_matrices()
    from attend.models.generalized import smoothness_precision

    np.testing.assert_allclose(mats["Vy"], np.kron(smoothness_precision(5, 0.3), other.sensor_precision))
    np.testing.assert_allclose(mats["W"], np.kron(smoothness_precision(5, 0.5), other.process_precision))


def test_white_noise_width_is_refused_with_a_pointer_to_kalman():
    for field in ("kernel_width", "process_kernel_width", "sensor_kernel_width"):
        with pytest.raises(AttendInputError, match=f"{field}: 0 means white noise.*method=\"kalman\""):
            _observer(**{field: 0.0})
    with pytest.raises(AttendInputError, match="kernel_width: required unless"):
        _observer(kernel_width=None, process_kernel_width=0.5)


@pytest.mark.parametrize("known_inputs", [False, True])
def test_reported_std_is_calibrated_on_simulated_data(known_inputs):
    """|error| < 2 std for ~95 % of the middle samples, states and unknown inputs, 4 random systems."""
    from attend.models.noise import coloured_noise

    inside, total = 0, 0
    for seed in (0, 1, 5, 7):
        system, rng = _random_stable_system(seed)
        dt = 0.05
        s = rng.uniform(0.5, 5.0) * dt
        observer = DEMObserver(system, dt, kernel_width=s, sensor_precision=1 / 0.05**2, process_precision=1 / 0.1**2,
                               input_prior_precision=None if known_inputs else 1.0, known_inputs=known_inputs)
        u = coloured_noise(4000, system.n_inputs, dt, s, 1.0, seed=100 + seed)
        log = simulate(system, u, dt, kernel_width=s, process_std=0.1, measurement_std=0.05, seed=seed)
        estimate = observer.estimate(log.outputs, u if known_inputs else None)
        middle = slice(300, -300)
        checks = [np.abs(estimate.states[middle] - log.states[middle]) < 2 * estimate.state_std[middle]]
        if not known_inputs:
            checks.append(np.abs(estimate.inputs[middle] - u[middle]) < 2 * estimate.input_std[middle])
        for check in checks:
            fraction = check.mean(axis=0)
            assert np.all((fraction > 0.90) & (fraction < 0.99)), fraction
            inside += check.sum()
            total += check.size
    assert 0.93 < inside / total < 0.97
    if known_inputs:
        assert np.all(estimate.input_std == 0.0)


def test_unobservable_state_gets_nan_std_and_a_warning():
    """The roll model (double integrator) with sensor precision 0: phi drifts; never std 0."""
    from attend.models.problems import quadrotor_roll

    with pytest.raises(AttendInputError, match="unstable"):  # the flow has modes exactly at 1
        DEMObserver(quadrotor_roll(), 1 / 120, kernel_width=0.006, sensor_precision=[0.0],
                    process_precision=[5.5e5, 247.0], known_inputs=True, embedding_order=2)
    with pytest.warns(ModelWarning):
        observer = DEMObserver(quadrotor_roll(), 1 / 120, kernel_width=0.006, sensor_precision=[0.0],
                               process_precision=[5.5e5, 247.0], known_inputs=True, embedding_order=2,
                               allow_unstable=True)
        estimate = observer.estimate(np.zeros((500, 1)), np.zeros((500, 4)))
    assert np.all(np.isnan(estimate.state_std))
    # C = 0 on a stable system: also flagged
    from attend import LinearSystem

    blind = LinearSystem([[-1.0, 0.5], [0.0, -2.0]], [[1.0], [0.0]], [[0.0, 0.0]])
    observer = DEMObserver(blind, 0.1, kernel_width=0.5, sensor_precision=1e4, process_precision=1e4,
                           input_prior_precision=1.0, embedding_order=3)
    assert set(observer.analysis().unobservable) == {"x1", "x2", "u1"}
    assert np.all(np.isnan(observer.analysis().state_std))
    with pytest.warns(ModelWarning, match="x1, x2, u1: not informed by the outputs"):
        observer.estimate(np.zeros((1000, 1)))


def test_a_huge_kernel_width_is_named_in_the_overflow_error():
    with pytest.raises(AttendInputError, match=r"^kernel_width: .*kernel_width = 1000 s"):
        _observer(kernel_width=1000.0, embedding_order=6)


def test_python_control_statespace_is_accepted_and_other_types_name_the_converter():
    control = pytest.importorskip("control")
    system = convolution_model()
    converted = _observer(system=control.ss(system.A, system.B, system.C, 0))
    reference = _observer()
    y = np.sin(np.arange(40)[:, None] * 0.1 * np.arange(1, 5))
    np.testing.assert_allclose(converted.estimate(y).states, reference.estimate(y).states)
    with pytest.raises(AttendInputError, match="attend.models.from_statespace"):
        DEMObserver((system.A, system.B, system.C), 0.1, kernel_width=0.5, sensor_precision=1.0, process_precision=1.0,
                    input_prior_precision=1.0)
    with pytest.raises(AttendInputError, match="system: statespace: D must be zero"):
        DEMObserver(control.ss(system.A, system.B, system.C, np.ones((4, 1))), 0.1, kernel_width=0.5,
                    sensor_precision=1.0, process_precision=1.0, input_prior_precision=1.0)


def test_online_step_rejects_text():
    online = _observer().online()
    with pytest.raises(AttendInputError, match="step: output: expected numbers, got 'abc'"):
        online.step("abc")
    with pytest.raises(AttendInputError, match="step: output: expected numbers, got '1.0'"):
        online.step(["1.0", 0.0, 0.0, 0.0])


def test_a_dem_estimate_worse_than_the_prior_is_named_in_a_warning():
    """When DEM's own error analysis puts a variable's error above its spread without data, the
    estimate is worse than the prior mean: a ModelWarning names it (and points to the Kalman
    smoother); fine settings stay silent (test_no_stability_warning_on_a_fine_observer)."""
    from attend.models.linear import simulate as sim

    found = []
    for seed in range(20):
        system, rng = _random_stable_system(seed)
        dt = 0.05
        s = rng.uniform(0.5, 5.0) * dt
        observer = DEMObserver(system, dt, kernel_width=s, sensor_precision=1 / 0.05**2, process_precision=1 / 0.1**2,
                               input_prior_precision=1.0)
        log = sim(system, np.zeros((2000, system.n_inputs)), dt, kernel_width=s, process_std=0.1,
                  measurement_std=0.05, seed=seed)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                estimate = observer.estimate(log.outputs)
            except AttendInputError:
                continue
        messages = [str(w.message) for w in caught if "worse than the model's prior mean" in str(w.message)]
        if not messages:
            continue
        named = [name for name in system.state_names if f"{name} (error std" in messages[0]]
        spread = np.std(log.states[200:-200], axis=0)
        for name in named:  # the named states really are estimated worse than their spread
            i = system.state_names.index(name)
            error = np.sqrt(np.mean((estimate.states[200:-200, i] - log.states[200:-200, i]) ** 2))
            found.append(error / spread[i])
    assert found, "no case of the bank triggered the warning"
    assert np.median(found) > 0.8


def _hover_quadrotor():
    """A 12-state quadrotor linearised at hover, shaped like the AR.Drone 2 flight of issue 29
    (positions, angles, velocities, rates; 6 outputs; thrust and three torques as unknown inputs)."""
    from attend import LinearSystem

    A = np.zeros((12, 12))
    A[0:3, 6:9] = A[3:6, 9:12] = np.eye(3)
    A[6, 4], A[7, 3] = -9.81, 9.81
    B = np.zeros((12, 4))
    B[8, 0], B[9, 1], B[10, 2], B[11, 3] = 1 / 0.42, 1 / 2.2e-3, 1 / 2.9e-3, 1 / 5.3e-3
    return LinearSystem(A, B, np.eye(6, 12))


def test_authors_quadrotor_settings_run_with_a_note():
    """25 Hz, kernel width 0.04 s, sigma_w 0.08-28, sigma_z down to 7e-4, input prior std e^4, p = 5:
    spectral radius 1.00007 (>= 1), growth 1.2x over 2600 samples: it runs, with a warning naming it."""
    sigma_w = np.array([0.08, 0.08, 0.08, 0.1, 0.1, 0.1, 1.0, 1.0, 1.0, 28, 28, 20.0])
    sigma_z = np.array([0.01, 0.01, 0.01, 7e-4, 7e-4, 2e-3])
    observer = DEMObserver(_hover_quadrotor(), 0.04, kernel_width=0.04, sensor_precision=1 / sigma_z**2,
                           process_precision=1 / sigma_w**2, input_prior_precision=np.exp(-8), embedding_order=5,
                           input_order=2, precision_convention="max")
    rho = observer.analysis().spectral_radius
    assert 1.00005 < rho < 1.0001
    y = 0.01 * np.random.default_rng(1).standard_normal((2600, 6))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        estimate = observer.estimate(y)
    notes = [str(w.message) for w in record if "is not stable" in str(w.message)]
    assert len(notes) == 1 and "(2600 samples, 104 s)" in notes[0] and "< 2x: run" in notes[0], notes
    assert _growth_in(notes[0]) == pytest.approx(rho**2600, rel=2e-3) and 1.1 < _growth_in(notes[0]) < 1.3
    assert np.all(np.isfinite(estimate.states)) and np.all(np.isfinite(estimate.inputs))
