"""The unscented smoother's error spread under coloured noise (nonlinear_baselines.error_spread)."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.experiments import pendulum
from attend.experiments._nonlinear import _setup, kalman_options
from attend.noise import coloured_noise
from attend.perception.nonlinear import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear_baselines import extended_kalman, unscented_kalman

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
    from attend.perception.nonlinear_baselines import error_spread

    original = error_spread._regressions

    def growing(record):
        A, H = original(record)
        return A * 1e6, H * 0.0  # no correction from the data, a huge transition
    monkeypatch.setattr(error_spread, "_regressions", growing)
    log = simulate_nonlinear(LINEAR, 200, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.1, seed=0)
    with pytest.raises(AttendInputError, match="noise_kernel_width: the error spread became non-finite at sample"):
        unscented_kalman(LINEAR, 0.05, log.outputs, noise_kernel_width=0.1, **LINEAR_OPTIONS)
