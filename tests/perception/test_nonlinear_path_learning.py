"""learn_path: theta with the trajectory in path mode. With every parameter held it is path-mode
DEM (same trajectory, same std to the noise of the draws); Lorenz rho and the pendulum's damping
(with an unknown push) are recovered within their error bars; fixed entries stay; bad input.
Calibration over many seeds is a benchmark (bench_nonlinear.py part 6), not a test."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.experiments import lorenz, pendulum
from attend.models import simulate_nonlinear
from attend.perception.nonlinear import NonlinearDEM, ParametrisedSystem, learn_path


def lorenz_model():
    def f(x, v, theta):
        return np.array([theta[0] * (x[1] - x[0]), x[0] * (theta[1] - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]])

    return ParametrisedSystem(f, lambda x, v, theta: np.asarray(x, float), 3, 0, 3, parameter_names=("sigma", "rho"))


def lorenz_log(seed, samples=200):
    cfg = lorenz.SETTINGS
    system = lorenz_model().at([10.0, 28.0])
    return simulate_nonlinear(system, samples, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=20.0,
                              measurement_std=1.0, initial_state=cfg["initial_state"], seed=seed)


def test_with_every_parameter_held_it_is_path_mode_dem():
    log = lorenz_log(0, 120)
    cfg = lorenz.SETTINGS
    held = learn_path(lorenz_model(), log.outputs, None, cfg["dt"], kernel_width=cfg["kernel_width"],
                      sensor_precision=1.0, process_precision=1 / 400, prior_mean=[10.0, 28.0],
                      prior_precision=[np.inf, np.inf], motion="linearized", uncertainty_draws=400)
    path = NonlinearDEM(lorenz_model().at([10.0, 28.0]), cfg["dt"], kernel_width=cfg["kernel_width"],
                        sensor_precision=1.0, process_precision=1 / 400, embedding_order=6,
                        states="path").estimate(log.outputs)
    np.testing.assert_allclose(held.states, path.states, atol=1e-5 * np.abs(path.states).max())
    np.testing.assert_allclose(np.median(held.state_std / path.state_std), 1.0, atol=0.08)
    np.testing.assert_array_equal(held.parameters, [10.0, 28.0])
    np.testing.assert_array_equal(held.parameter_std, [0.0, 0.0])


@pytest.mark.parametrize("seed", [0, 1])
def test_lorenz_rho_within_its_error_bars(seed):
    """rho from a start of 20 (flat prior): within 3 std of 28, and the std is in a sensible range
    (bench part 6: mean z^2 1.00 over 12 seeds)."""
    log = lorenz_log(seed)
    cfg = lorenz.SETTINGS
    result = learn_path(lorenz_model(), log.outputs, None, cfg["dt"], kernel_width=cfg["kernel_width"],
                        sensor_precision=1.0, process_precision=1 / 400, prior_mean=[10.0, 20.0],
                        prior_precision=[np.inf, 0.0])
    assert result.converged, result.message
    rho, std = result.parameters[1], result.parameter_std[1]
    assert result.parameters[0] == 10.0 and result.parameter_std[0] == 0.0
    assert 0.2 < std < 1.5, std
    assert abs(rho - 28.0) < 3 * std, (rho, std)


def test_pendulum_damping_with_an_unknown_push():
    """The damping is learned while the push is estimated under its prior (unknown inputs while
    learning); the push's SSE is far below the D-step's at the true damping."""
    cfg = pendulum.SETTINGS

    def f(x, v, theta):
        return np.array([x[1], -9.81 * np.sin(x[0]) - theta[0] * x[1] + v[0]])

    model = ParametrisedSystem(f, lambda x, v, theta: np.array([np.sin(x[0]), np.cos(x[0])]), 2, 1, 2)
    n = 300
    time = np.arange(n) * cfg["dt"]
    log = simulate_nonlinear(model.at([0.3]), pendulum.true_input(time), cfg["dt"], kernel_width=cfg["kernel_width"],
                             process_std=cfg["process_std"], measurement_std=cfg["measurement_std"],
                             initial_state=[1.0, 0.0], seed=0)
    sz, sw = cfg["measurement_std"], np.array(cfg["process_std"])
    prior = np.exp(cfg["input_prior_log_precision"])
    result = learn_path(model, log.outputs, None, cfg["dt"], kernel_width=cfg["kernel_width"], sensor_precision=1 / sz**2,
                        process_precision=1 / sw**2, prior_mean=[1.0], prior_precision=[0.0],
                        input_prior_precision=prior, input_kernel_width=cfg["input_kernel_width"],
                        motion="linearized")
    assert abs(result.parameters[0] - 0.3) < 3 * result.parameter_std[0], (result.parameters, result.parameter_std)
    dstep = NonlinearDEM(model.at([0.3]), cfg["dt"], kernel_width=cfg["kernel_width"], sensor_precision=1 / sz**2,
                         process_precision=1 / sw**2, input_prior_precision=prior,
                         input_kernel_width=cfg["input_kernel_width"]).estimate(log.outputs)
    trim = slice(7, n - 7)
    sse = lambda inputs: np.sum((inputs - log.inputs)[trim] ** 2)  # noqa: E731
    assert sse(result.inputs) < 0.5 * sse(dstep.inputs)
    assert np.all(result.input_std[trim] > 0)


def test_bad_input_is_named():
    log = lorenz_log(0, 60)
    common = dict(kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400)
    with pytest.raises(AttendInputError, match="model: expected an attend ParametrisedSystem"):
        learn_path(lorenz_model().at([10.0, 28.0]), log.outputs, None, 0.01, prior_mean=[10.0, 28.0],
                   prior_precision=[np.inf, 0.0], **common)
    with pytest.raises(AttendInputError, match="prior_precision: expected shape"):
        learn_path(lorenz_model(), log.outputs, None, 0.01, prior_mean=[10.0, 28.0], prior_precision=[0.0, 0.0, 0.0],
                   **common)
    with pytest.raises(AttendInputError, match="outputs: expected 3 columns"):
        learn_path(lorenz_model(), log.outputs[:, :2], None, 0.01, prior_mean=[10.0, 28.0],
                   prior_precision=[np.inf, 0.0], **common)
    pendulum_model = ParametrisedSystem(lambda x, v, t: np.array([x[1], -t[0] * x[1] + v[0]]),
                                        lambda x, v, t: x[:1], 2, 1, 1)
    with pytest.raises(AttendInputError, match="inputs: the model has inputs"):
        learn_path(pendulum_model, np.zeros((40, 1)), None, 0.05, prior_mean=[0.3], prior_precision=[0.0], **common)
