"""The unscented smoother's error spread under coloured noise (nonlinear_smoothers.error_spread)."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.experiments import pendulum
from attend.experiments._nonlinear import _setup, kalman_options
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.models.noise import coloured_noise
from attend.perception.nonlinear_smoothers import extended_kalman, unscented_kalman

A = np.array([[0.0, 1.0], [-4.0, -0.6]])
C = np.array([[1.0, 0.0]])
LINEAR = NonlinearSystem(lambda x, v: A @ x, lambda x, v: C @ x, 2, 0, 1, vectorized=True)
LINEAR_OPTIONS = dict(process_covariance=np.diag([1e-4, 4e-3]), measurement_covariance=[[0.01]],
                      initial_mean=[1.0, 0.0], initial_covariance=0.04)


@pytest.mark.parametrize("smoother", [unscented_kalman, extended_kalman])
@pytest.mark.parametrize("smooth", [True, False])
def test_with_white_noise_the_spread_is_the_linear_smoothers_own_covariance(smooth, smoother):
    """s = 0 (white noise) on a linear model: the error draws' covariance equals the Kalman
    filter's / RTS smoother's exact covariance, within the Monte Carlo error of 4000 draws
    (relative std error of a variance ~ sqrt(2 / 4000) = 2.2 %)."""
    log = simulate_nonlinear(LINEAR, 150, 0.05, kernel_width=0.0, process_std=[0.2, 1.26], measurement_std=0.1,
                             initial_state=[1.0, 0.0], seed=1)
    own = smoother(LINEAR, 0.05, log.outputs, smooth=smooth, **LINEAR_OPTIONS)
    spread = smoother(LINEAR, 0.05, log.outputs, smooth=smooth, noise_kernel_width=0.0, spread_draws=4000,
                      **LINEAR_OPTIONS)
    np.testing.assert_array_equal(spread.states, own.states)  # only the uncertainty changes
    ratio = spread.state_std[1:] ** 2 / own.state_std[1:] ** 2
    assert np.abs(np.median(ratio) - 1) < 0.02 and np.all(np.abs(ratio - 1) < 0.12), (np.median(ratio), ratio.min(),
                                                                                       ratio.max())


def test_under_coloured_noise_the_spread_is_calibrated_where_the_white_models_std_is_not():
    """The pendulum reproduction's settings (s/dt = 2, unknown push), the push drawn from its prior
    (variance exp(2), width 0.7 s) as the spread assumes: |error| < 2 std over 3 seeds is ~0.95
    with the spread (states and push) and far below with the white-noise model's own std."""
    cfg = dict(pendulum.SETTINGS, duration=20.0)
    system, _, _, n = _setup("pendulum", cfg)
    options = kalman_options(system, cfg)
    prior = (np.exp(-cfg["input_prior_log_precision"]), cfg["input_kernel_width"])
    inside, inside_white = [], []
    for seed in range(3):
        u = coloured_noise(n, 1, cfg["dt"], prior[1], np.sqrt(prior[0]), 50 + seed)
        log = simulate_nonlinear(system, u, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=cfg["process_std"],
                                 measurement_std=cfg["measurement_std"], initial_state=cfg["initial_state"], seed=seed)
        white = unscented_kalman(system, cfg["dt"], log.outputs, **options)
        spread = unscented_kalman(system, cfg["dt"], log.outputs, noise_kernel_width=cfg["kernel_width"],
                                  input_prior=prior, seed=seed, **options)
        inner = slice(10, n - 10)
        for estimate, store in ((white, inside_white), (spread, inside)):
            errors = np.column_stack([estimate.states - log.states, estimate.inputs - log.inputs])[inner]
            stds = np.column_stack([estimate.state_std, estimate.input_std])[inner]
            store.append(np.mean(np.abs(errors) < 2 * stds, axis=0))
    assert np.all((np.mean(inside, axis=0) > 0.90) & (np.mean(inside, axis=0) < 0.99)), np.mean(inside, axis=0)
    assert np.all(np.mean(inside_white, axis=0) < 0.8), np.mean(inside_white, axis=0)


@pytest.mark.parametrize("change, message", [
    (dict(noise_kernel_width=-0.1), "noise_kernel_width: expected a kernel width >= 0"),
    (dict(noise_kernel_width=0.1, smooth=5), "not for a fixed lag"),
    (dict(noise_kernel_width=0.1, spread_draws=1), "spread_draws: expected an integer >= 2"),
    (dict(noise_kernel_width=0.1, spread_draws=2.5), "spread_draws: expected an integer >= 2 or None"),
])
def test_bad_spread_settings_name_the_field(change, message):
    log = simulate_nonlinear(LINEAR, 20, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.1, seed=0)
    with pytest.raises(AttendInputError, match=message):
        unscented_kalman(LINEAR, 0.05, log.outputs, **LINEAR_OPTIONS, **change)


def test_unknown_inputs_need_their_prior_for_the_spread():
    cfg = pendulum.SETTINGS
    system = pendulum.build_system(cfg)
    log = simulate_nonlinear(system, np.zeros((20, 1)), cfg["dt"], kernel_width=0.1, process_std=0.1,
                             measurement_std=0.1, seed=0)
    with pytest.raises(AttendInputError, match="input_prior: with unknown inputs"):
        unscented_kalman(system, cfg["dt"], log.outputs, process_covariance=1e-4, measurement_covariance=0.01,
                         input_variance=0.1, noise_kernel_width=0.1)


def test_a_spread_that_overflows_is_an_error_not_a_result(monkeypatch):
    """Error dynamics that grow without bound (forced here through the recorded gains) stop with an
    error naming the field and the sample instead of returning non-finite std."""
    from attend.perception.nonlinear_smoothers import error_spread

    original = error_spread._regressions

    def growing(record):
        A, H = original(record)
        return A * 1e6, H * 0.0  # no correction from the data, a huge transition
    monkeypatch.setattr(error_spread, "_regressions", growing)
    log = simulate_nonlinear(LINEAR, 200, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.1, seed=0)
    for draws in (200, None):
        with pytest.raises(AttendInputError, match="noise_kernel_width: the error spread became non-finite at sample"):
            unscented_kalman(LINEAR, 0.05, log.outputs, noise_kernel_width=0.1, spread_draws=draws, **LINEAR_OPTIONS)


# --- the exact covariance (spread_draws=None): no draws -------------------------------------------

def _pendulum_case(n_samples: int, seed: int = 0):
    """The pendulum reproduction's system, options, input prior and a log of ``n_samples`` whose push
    is drawn from that prior."""
    cfg = pendulum.SETTINGS
    system, _, _, _ = _setup("pendulum", cfg)
    options = kalman_options(system, cfg)
    prior = (np.exp(-cfg["input_prior_log_precision"]), cfg["input_kernel_width"])
    u = coloured_noise(n_samples, 1, cfg["dt"], prior[1], np.sqrt(prior[0]), 50 + seed)
    log = simulate_nonlinear(system, u, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=cfg["process_std"],
                             measurement_std=cfg["measurement_std"], initial_state=cfg["initial_state"], seed=seed)
    return system, cfg, options, prior, log


def _dense_covariance(model, record, kernel_width, input_prior, smooth):
    """The oracle: every noise of the linearised error written out as unit white noise over the whole
    log (a coloured channel over N samples = its Toeplitz covariance of kernel_autocorrelation, by
    Cholesky), pushed through the error recursion as one column each: Cov(e_k) = T_k T_k'."""
    from attend.models.noise import kernel_autocorrelation
    from attend.perception.nonlinear_smoothers import error_spread

    A, H = error_spread._regressions(record)
    N, d = record["K"].shape[0], record["K"].shape[1]
    n, r, dt = model.system.n_states, model.system.n_inputs, model.dt

    def coloured_root(width):  # (N, N): L L' = Cov of one unit coloured channel over the log
        if width == 0:
            return np.eye(N)
        rho = np.zeros(N)
        values = kernel_autocorrelation(dt, width)[:N]
        rho[: len(values)] = values
        toeplitz = rho[np.abs(np.subtract.outer(np.arange(N), np.arange(N)))]
        return np.linalg.cholesky(toeplitz + 1e-13 * np.eye(N))

    def channel_basis(width, covariance):  # (N, k, N k): unit columns of a k-channel coloured noise
        k = covariance.shape[0]
        return np.einsum("ts,ij->tisj", coloured_root(width), error_spread._root(covariance)).reshape(N, k, N * k)

    unknown = np.flatnonzero(~model.known) if model.augmented else np.zeros(0, dtype=int)
    blocks = [("x0", n), ("w", N * n), ("r", N * model.R.shape[0]), ("v", N * unknown.size)]
    total = sum(size for _, size in blocks)
    first, q, noise = np.zeros((d, total)), np.zeros((N, d, total)), np.zeros((N, model.R.shape[0], total))
    at = 0
    for name, size in blocks:
        columns = slice(at, at + size)
        if name == "x0":
            first[:n, columns] = error_spread._root(model.P0[:n, :n])
        elif name == "w":
            q[1:, :n, columns] = dt * channel_basis(kernel_width, model.Q / dt**2)[:-1]
        elif name == "r":
            noise[:, :, columns] = channel_basis(kernel_width, model.R)
        elif size:
            variance, width = input_prior
            deviation = channel_basis(width, np.asarray(variance)[np.ix_(unknown, unknown)])
            q[1:, n + unknown, columns] = np.diff(deviation, axis=0)
            first[n + unknown, columns] = -deviation[0]
        at += size
    errors = error_spread.propagate_errors(record, A, H, first, q, noise, smooth)
    return np.einsum("nic,njc->nij", errors, errors)


@pytest.mark.parametrize("smooth", [True, False])
@pytest.mark.parametrize("unknown_input", [True, False])
def test_the_exact_covariance_equals_the_dense_oracle(smooth, unknown_input):
    """spread_draws=None against every noise written out over the log (_dense_covariance): 40 samples of
    the pendulum (s/dt = 2, the push unknown with its prior of width 0.7 s = 7 samples, or measured).
    Both are sums of the same products in another order; the tolerance is the rounding of those sums
    (the Toeplitz factor's 1e-13 jitter is below it)."""
    from attend.perception.nonlinear_smoothers import error_spread
    from attend.perception.nonlinear_smoothers.kalman import _Model, _unscented

    system, cfg, options, prior, log = _pendulum_case(40)
    if not unknown_input:
        options = {key: value for key, value in options.items() if key not in ("input_variance", "input_mean")}
    model = _Model(system, cfg["dt"], log.outputs, None if unknown_input else log.inputs,
                   options.get("input_variance"), options.get("input_mean"), options["process_covariance"],
                   options["measurement_covariance"], options.get("initial_mean"), options.get("initial_covariance"),
                   10)
    record = {}
    _unscented(model.transition_points, model.observation_points, model.y, model.m0, model.P0, model.Qz, model.R,
               smooth, (1.0, 2.0, 0.0), "test", record)
    settings = (cfg["kernel_width"], ([[prior[0]]], prior[1]) if unknown_input else None)
    exact = error_spread.smoother_error_covariance(model, record, *settings, smooth)
    dense = _dense_covariance(model, record, *settings, smooth)
    scale = np.sqrt(np.einsum("nii,njj->nij", dense, dense))
    assert np.max(np.abs(exact - dense) / scale) < 1e-9


def test_the_exact_covariance_is_the_limit_of_the_draws():
    """The pendulum with its unknown push, 200 samples: 20 000 draws' variances against the exact
    ones; a variance estimated from D draws has relative std sqrt(2 / D) = 1 %, so the median ratio
    is within 0.5 % of 1 and every one within 5 std (5 %)."""
    system, cfg, options, prior, log = _pendulum_case(200)
    common = dict(noise_kernel_width=cfg["kernel_width"], input_prior=prior, **options)
    exact = unscented_kalman(system, cfg["dt"], log.outputs, spread_draws=None, **common)
    drawn = unscented_kalman(system, cfg["dt"], log.outputs, spread_draws=20_000, **common)
    np.testing.assert_array_equal(exact.states, drawn.states)
    std = {name: np.column_stack([e.state_std, e.input_std]) for name, e in (("exact", exact), ("drawn", drawn))}
    ratio = (std["drawn"] / std["exact"]) ** 2
    assert np.all(np.abs(np.median(ratio, axis=0) - 1) < 0.005), np.median(ratio, axis=0)
    assert np.all(np.abs(ratio - 1) < 0.05), (ratio.min(), ratio.max())


@pytest.mark.parametrize("smoother", [unscented_kalman, extended_kalman])
@pytest.mark.parametrize("smooth", [True, False])
def test_with_white_noise_the_exact_spread_is_the_linear_smoothers_own_covariance(smooth, smoother):
    """s = 0 on a linear model: the exact spread is the Kalman filter's / RTS smoother's covariance
    (closed form), to the rounding of the two recursions (condition of Pp ~ 1e3: 1e-8)."""
    log = simulate_nonlinear(LINEAR, 150, 0.05, kernel_width=0.0, process_std=[0.2, 1.26], measurement_std=0.1,
                             initial_state=[1.0, 0.0], seed=1)
    own = smoother(LINEAR, 0.05, log.outputs, smooth=smooth, **LINEAR_OPTIONS)
    exact = smoother(LINEAR, 0.05, log.outputs, smooth=smooth, noise_kernel_width=0.0, spread_draws=None,
                     **LINEAR_OPTIONS)
    np.testing.assert_allclose(exact.state_std, own.state_std, rtol=1e-8)


def test_the_exact_covariance_in_blocks_equals_the_one_pass(monkeypatch):
    """With too little memory for every window X_k, the backward pass recomputes them block by block
    from checkpoints: the same numbers (blocks of 7 samples here)."""
    from attend.perception.nonlinear_smoothers import error_spread

    system, cfg, options, prior, log = _pendulum_case(60)
    common = dict(noise_kernel_width=cfg["kernel_width"], input_prior=prior, spread_draws=None, **options)
    whole = unscented_kalman(system, cfg["dt"], log.outputs, **common)
    # floats of one window X_k: 3 coordinates (angle, rate, push) x (w and z: 4 channels of the noise's
    # taps; the push: 1 channel of its step's taps, one more than its kernel's)
    taps = len(error_spread._taps(cfg["dt"], cfg["kernel_width"])), len(error_spread._taps(cfg["dt"], prior[1])) + 1
    size = 3 * (4 * taps[0] + taps[1])
    monkeypatch.setattr(error_spread, "DRAW_BUDGET", 7 * size)
    blocks = unscented_kalman(system, cfg["dt"], log.outputs, **common)
    np.testing.assert_allclose(blocks.state_std, whole.state_std, rtol=1e-12)
    np.testing.assert_allclose(blocks.input_std, whole.input_std, rtol=1e-12)


def test_near_deterministic_motion_gets_the_spread_of_its_errors_not_of_the_jitter():
    """x[0] known and process noise far below the sigma points' Cholesky jitter (1e-12): on a linear
    model the unscented smoother is a linear smoother whose gains do not depend on the data, so its
    errors over independent logs have exactly the spread's covariance. 200 logs of 60 samples: the
    mean squared error over the mean spread variance is 1 within 4 std of that estimate (one log's
    ratio scatters by 0.75 -- its errors are correlated along the log --, 200 logs' mean by 0.053;
    600 logs give 0.985). The smoother's own covariance is ~5000x too large here (the jitter acts
    as process noise), and regressing on Pf instead of the covariance the sigma points stand for
    blew the spread up by ~1e6."""
    options = dict(process_covariance=np.diag([1e-16, 1e-16]), measurement_covariance=[[0.01]],
                   initial_mean=[1.0, 0.0], initial_covariance=0.0)
    squared, variance = [], []
    for seed in range(200):
        log = simulate_nonlinear(LINEAR, 60, 0.05, kernel_width=0.0, process_std=[2e-7, 2e-7], measurement_std=0.1,
                                 initial_state=[1.0, 0.0], seed=seed)
        estimate = unscented_kalman(LINEAR, 0.05, log.outputs, noise_kernel_width=0.0, spread_draws=None, **options)
        squared.append((estimate.states - log.states)[10:] ** 2)
        variance.append(estimate.state_std[10:] ** 2)
    ratio = np.mean(squared) / np.mean(variance)
    assert abs(ratio - 1) < 0.2, ratio
