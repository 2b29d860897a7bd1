"""learn_nonlinear: the E-step for theta and the M-step for the noise log-precisions of a nonlinear model."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models import simulate_nonlinear
from attend.perception.learning import LearningSettings, learn_batch
from attend.perception.nonlinear import ParametrisedSystem, learn_nonlinear

# --- a linear model written as f, g: theta = [A[2,1], A[2,2], B[2,1]] ------------------------

def _linear_f(x, u, theta):
    return np.array([x[1], theta[0] * x[0] + theta[1] * x[1] + theta[2] * u[0]])


def _linear_g(x, u, theta):
    return np.array([x[0]])


def _linear_jf(x, u, theta):
    return np.array([[0.0, 1.0], [theta[0], theta[1]]]), np.array([[0.0], [theta[2]]])


def _linear_jg(x, u, theta):
    return np.array([[1.0, 0.0]]), np.zeros((1, 1))


LINEAR = ParametrisedSystem(_linear_f, _linear_g, 2, 1, 1, parameter_names=("A21", "A22", "B21"),
                            jacobian_f=_linear_jf, jacobian_g=_linear_jg)


def _linear_data(samples=120):
    dt, s = 0.1, 0.5
    t = np.arange(samples) * dt
    u = (np.sin(0.7 * t) + 0.5 * np.sin(2.1 * t))[:, None]
    log = simulate_nonlinear(LINEAR.at([-2.0, -0.8, 1.0]), u, dt, kernel_width=s, process_std=0.05,
                             measurement_std=0.05, seed=3)
    return log.outputs, u, dt, s


def test_linear_model_agrees_with_the_linear_learner():
    """Same F (sample mode, top order marginalised) on a linear model: the two learners reach the
    same optimum. Tolerance: 0.05 posterior std in theta, 0.01 in lambda, 1 % in the posterior std;
    both stop when an iteration gains < 1e-6 nats on a flat ridge (measured: 0.01-0.02 std apart)."""
    y, u, dt, s = _linear_data()
    eta, P = np.array([-1.5, -0.4, 0.7]), np.ones(3)
    ours = learn_nonlinear(LINEAR, y, u, dt, kernel_width=s, prior_mean=eta, prior_precision=P, embedding_order=4,
                           noise_prior_mean=(6.0, 6.0), tolerance=1e-6, max_iterations=100, state_iterations=1)
    # the linear learner's theta = [vec(A); vec(B); vec(C)], row-major; entries 2, 3, 5 are free
    theta_eta = np.array([0.0, 1.0, -2.0, -0.8, 0.0, 1.0, 1.0, 0.0])
    P_lin = np.full(8, np.inf)
    free = [2, 3, 5]
    theta_eta[free], P_lin[free] = eta, P
    theirs = learn_batch(y[None], u[None], dt, n_states=2, kernel_width=s, prior_mean=theta_eta[None],
                         prior_precision=P_lin[None],
                         settings=LearningSettings(embedding_order=4, noise_prior_mean=(6.0, 6.0), tolerance=1e-6,
                                                   max_iterations=400, top_order="marginal", newton=True))
    assert ours.converged and theirs.converged[0]
    std_ours = 1 / np.sqrt(np.diag(ours.parameter_precision))
    std_theirs = 1 / np.sqrt(np.diag(theirs.parameter_precision[0])[free])
    assert np.all(np.abs(ours.parameters - theirs.parameters[0, free]) < 0.05 * std_theirs)
    assert np.all(np.abs(ours.log_precision - theirs.log_precision[0]) < 0.01)
    np.testing.assert_allclose(std_ours, std_theirs, rtol=0.01)
    # and far from the prior: the data moved theta by many std
    assert np.all(np.abs(ours.parameters - eta) > 10 * std_ours)


# --- Lorenz: rho from simulated data ------------------------------------------------------------

def _lorenz_f(x, u, theta):
    return np.array([theta[0] * (x[1] - x[0]), x[0] * (theta[1] - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]])


def _lorenz_g(x, u, theta):
    return x.copy()


def _lorenz_jf(x, u, theta):
    return (np.array([[-theta[0], theta[0], 0.0], [theta[1] - x[2], -1.0, -x[0]], [x[1], x[0], -8 / 3]]),
            np.zeros((3, 0)))


LORENZ = ParametrisedSystem(_lorenz_f, _lorenz_g, 3, 0, 3, parameter_names=("sigma", "rho"), jacobian_f=_lorenz_jf)


def _lorenz_log(seed=1, samples=150):
    return simulate_nonlinear(LORENZ.at([10.0, 28.0]), samples, 0.01, kernel_width=0.02, process_std=2.0,
                              measurement_std=1.0, initial_state=[1.0, 1.0, 24.0], seed=seed).outputs


def test_lorenz_rho_is_recovered_and_a_fixed_entry_stays():
    """rho from 1.5 s of the Lorenz attractor, starting at 20 (truth 28), the noise precisions
    known: within 3 % (measured on seeds 0-3 with 200 samples: 0.1-1.3 %), F non-decreasing,
    the posterior precision positive, sigma (P = inf) exactly at its prior mean."""
    y = _lorenz_log()
    result = learn_nonlinear(LORENZ, y, None, 0.01, kernel_width=0.02, prior_mean=[10.0, 20.0],
                             prior_precision=[np.inf, 1e-2], embedding_order=4, state_iterations=2,
                             noise_prior_mean=(0.0, np.log(0.25)), noise_prior_precision=(np.inf, np.inf))
    assert result.converged and result.iterations < 50
    assert abs(result.parameters[1] - 28.0) / 28.0 < 0.03
    assert result.parameters[0] == 10.0 and np.isinf(result.parameter_precision[0, 0])
    assert result.parameter_precision[1, 1] > 0 and result.parameter_precision[0, 1] == 0
    assert np.all(np.diff(result.free_energy) >= 0)
    assert result.free_energy[-1] > result.free_energy[0] + 100  # the data moved rho a long way
    np.testing.assert_array_equal(result.log_precision, [0.0, np.log(0.25)])
    assert result.states.shape == (150 - 4, 3)


def test_noise_precisions_rise_the_free_energy_from_a_wrong_start():
    """The M-step alone (theta held: every P = inf, flat lambda prior) moves lambda_z from 3 to the
    truth 0 (measured -0.003) and F never falls. lambda_w (truth ln 0.25) is not checked: with free
    per-sample states F is nearly flat in it here (measured: F differs by 0.3 nats between
    lambda_w = 3 and -1.4), so the Fisher-scaled steps stop early (see docs/nonlinear.md)."""
    y = _lorenz_log(samples=120)
    result = learn_nonlinear(LORENZ, y, None, 0.01, kernel_width=0.02, prior_mean=[10.0, 28.0],
                             prior_precision=[np.inf, np.inf], embedding_order=4, noise_prior_mean=(3.0, 3.0),
                             noise_prior_precision=(0.0, 0.0), max_iterations=15)
    assert np.all(np.diff(result.free_energy) >= 0)
    np.testing.assert_array_equal(result.parameters, [10.0, 28.0])
    assert abs(result.log_precision[0]) < 0.1
    assert result.free_energy[-1] > result.free_energy[0] + 1000


# --- bad input ------------------------------------------------------------------------------------

def test_bad_inputs_give_one_line_errors():
    y, u, dt, s = _linear_data(40)
    kw = dict(kernel_width=s, prior_mean=[-1.0, -1.0, 1.0], prior_precision=[1.0, 1.0, 1.0], embedding_order=2)
    with pytest.raises(AttendInputError, match="inputs: expected shape"):
        learn_nonlinear(LINEAR, y, u[:-1], dt, **kw)
    bad = y.copy()
    bad[7] = np.nan
    with pytest.raises(AttendInputError, match="outputs: non-finite value at sample 7"):
        learn_nonlinear(LINEAR, bad, u, dt, **kw)
    with pytest.raises(AttendInputError, match="prior_precision: expected shape"):
        learn_nonlinear(LINEAR, y, u, dt, **{**kw, "prior_precision": [1.0, 1.0]})
    with pytest.raises(AttendInputError, match="prior_mean: entry 1"):
        learn_nonlinear(LINEAR, y, u, dt, **{**kw, "prior_mean": [1.0, np.inf, 0.0]})
    with pytest.raises(AttendInputError, match="top_order"):
        learn_nonlinear(LINEAR, y, u, dt, top_order="none", **kw)
    with pytest.raises(AttendInputError, match="model: expected"):
        learn_nonlinear(LINEAR.at([0, 0, 0]), y, u, dt, **kw)


def test_f_that_raises_at_a_theta_names_theta_and_the_iteration():
    """f defined only for A22 < -0.9: at the start (A22 = 0), and at the E-step's first trial (the
    data pull A22 from -1 towards the truth -0.8), the error names theta, the step and the iteration."""

    def f(x, u, theta):
        if theta[1] >= -0.9:
            raise ValueError("damping must be negative")
        return _linear_f(x, u, theta)

    model = ParametrisedSystem(f, _linear_g, 2, 1, 1, parameter_names=("A21", "A22", "B21"))
    y, u, dt, s = _linear_data(60)
    with pytest.raises(AttendInputError, match=r"f: raised ValueError: damping must be negative.*"
                                               r"at theta = \[A21=-2, A22=0, B21=1\] \(start, iteration 0\)"):
        learn_nonlinear(model, y, u, dt, kernel_width=s, prior_mean=[-2.0, 0.0, 1.0], prior_precision=1.0,
                        embedding_order=2)
    with pytest.raises(AttendInputError, match=r"f: raised ValueError.*at theta = \[A21=.*\] \(E-step, iteration [12]\)$"):
        learn_nonlinear(model, y, u, dt, kernel_width=s, prior_mean=[-2.0, -1.0, 1.0], prior_precision=1.0,
                        embedding_order=2)
