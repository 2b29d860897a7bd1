"""dy~/da of an action held over one sample (markov_parameters(..., hold=tau)) and the reflex built on it."""

from __future__ import annotations

import numpy as np
import pytest

from attend import AttendInputError
from attend.control import ActiveInferenceController, GenerativeModel, GenerativeProcess, markov_parameters, run

A_DI = np.array([[0.0, 1.0], [0.0, 0.0]])  # double integrator phi'' = b a
B_GAIN = 0.375
B_DI = np.array([[0.0], [B_GAIN]])
C_ANGLE = np.array([[1.0, 0.0]])


def test_held_column_of_a_double_integrator_is_b_tau2_over_2_b_tau_b():
    tau = 1 / 120
    G = markov_parameters(A_DI, B_DI, C_ANGLE, np.zeros((1, 1)), 4, hold=tau)
    np.testing.assert_allclose(G[:, 0], [B_GAIN * tau**2 / 2, B_GAIN * tau, B_GAIN, 0.0], rtol=1e-13, atol=1e-18)


def test_hold_zero_is_the_instantaneous_column():
    A = np.array([[0.0, 1.0], [-0.8 / 1.4, -0.4 / 1.4]])
    B = np.array([[0.0], [1 / 1.4]])
    np.testing.assert_array_equal(markov_parameters(A, B, C_ANGLE, np.zeros((1, 1)), 4, hold=0.0),
                                  markov_parameters(A, B, C_ANGLE, np.zeros((1, 1)), 4))


def test_held_column_matches_the_step_response_of_a_damped_plant():
    """y^(i)(tau) of a unit action held from rest: the closed form of a first-order lag in series with an
    integrator, y'' = -c y' + a, y(0) = y'(0) = 0: y' = (1 - e^(-c tau)) / c, y = tau / c - (1 - e^(-c tau)) / c^2,
    y'' = e^(-c tau), y''' = -c e^(-c tau); with a direct term g_a added to order 0 only."""
    c, tau, direct = 3.0, 0.05, 0.2
    A = np.array([[0.0, 1.0], [0.0, -c]])
    B = np.array([[0.0], [1.0]])
    G = markov_parameters(A, B, C_ANGLE, np.array([[direct]]), 4, hold=tau)
    decay = np.exp(-c * tau)
    expected = [tau / c - (1 - decay) / c**2 + direct, (1 - decay) / c, decay, -c * decay]
    np.testing.assert_allclose(G[:, 0], expected, rtol=1e-12)


@pytest.mark.parametrize("hold", [-0.01, np.inf, np.nan])
def test_hold_must_be_a_finite_time(hold):
    with pytest.raises(AttendInputError, match="hold"):
        markov_parameters(A_DI, B_DI, C_ANGLE, np.zeros((1, 1)), 3, hold=hold)


# --- the reflex on a noiseless double integrator (the roll axis without noise, docs/control.md) ------------------

DT = 1 / 120
C_TWO = np.array([[1.0, 0.0], [1.0, 0.0]])  # two angle sensors
TARGET = 0.2


def _roll_like_agent(held: bool) -> ActiveInferenceController:
    """The roll agent of benchmarks/bench_control.py at its first tuned point with the held column (w, Pi_w, kappa, s;
    before the reference's acceleration was added), with dy~/da held over one sample (attending orders 0..2) or
    instantaneous (attending up to the relative degree, order 2)."""
    w, process_precision, kappa, s = 9.4872, 2.306e8, 3.087e4, 0.008
    model = GenerativeModel.linear([[0.0, 1.0], [-w**2, -2 * w]], [[0.0, 0.0], [w**2, 2 * w]], C_TWO,
                                   sensor_precision=1 / 0.002**2, process_precision=process_precision,
                                   cause_prior_precision=np.exp(8), cause_prior=[TARGET, 0.0], kernel_width=s,
                                   embedding_order=2, cause_order=1, initial_causes=[TARGET, 0.0])
    G = markov_parameters(A_DI, B_DI, C_TWO, np.zeros((2, 1)), 3, hold=DT if held else 0.0)
    return ActiveInferenceController(model, DT, action_gain=kappa, action_jacobian=G,
                                     sensory_orders=2 if held else "relative_degree")


def test_held_reflex_cancels_a_constant_disturbance_exactly():
    """phi'' = b a + d with d = -3 rad/s^2 from the start, no noise. At rest every error vanishes, so the angle is
    the target and the action the analytic a* = -d / b (8.0035 command units): the reflex integrates the errors,
    and its action is the agent's estimate of the disturbance."""
    world = GenerativeProcess.linear(A_DI, B_DI, C_TWO, disturbance=lambda t: np.array([0.0, -3.0]))
    agent = _roll_like_agent(held=True)
    loop = run(world, agent, 6.0, record_beliefs=False)
    error = loop.states[:, 0] - TARGET
    assert np.abs(error[int(2 / DT):]).max() < 1e-4  # measured 4.0e-6 from 2 s
    assert loop.actions[-1, 0] == pytest.approx(3.0 / B_GAIN, rel=1e-6)  # measured 8.0034575 against 8.0034575


def test_held_reflex_rejects_a_gust_that_the_instantaneous_reflex_lets_through():
    """The diagnosis of the roll axis. With dy~/da = (0, 0, b), da/dt = -kappa b Pi (s^2 e_0 + 2 s^4 e_2) (S(3)'s
    coupling of orders 0 and 2): the action is the integral of the angle error plus the rate error, with no term
    in the angle error itself. The servo from belief to sensation, eps^(3) + b k_D eps'' + b k_I eps = 0, lacks
    its eps' term and is unstable alone; the loop holds only because the belief yields to the sensations, and so
    to the wind. The held column (b dt^2/2, b dt, b) adds 2 s^2 dt e_1 to da/dt: a term in the angle error. Same
    model, precisions and gain; a -5 rad/s^2 gust from 2 s."""
    world = GenerativeProcess.linear(A_DI, B_DI, C_TWO,
                                     disturbance=lambda t: np.array([0.0, -5.0 if t >= 2.0 else 0.0]))
    peaks = {}
    for held in (True, False):
        loop = run(world, _roll_like_agent(held), 4.0, record_beliefs=False, check_stability=False)
        peaks[held] = np.abs(loop.states[int(2 / DT):, 0] - TARGET).max()
    assert peaks[True] < 0.01  # measured 4.8 mrad
    assert peaks[False] > 5 * peaks[True]  # measured 73 mrad


@pytest.mark.parametrize("s", [0.002, 0.008, 0.05])
def test_reflex_weights_of_each_order_in_closed_form(s):
    """(dy~/da)' S(3) with S(3) = [[3/2, 0, s^2], [0, 2 s^2, 0], [s^2, 0, 2 s^4]] (a Gaussian kernel of width s):
    the weights of the angle, rate and acceleration errors in da/dt. Instantaneous: b (s^2, 0, 2 s^4), no rate
    weight; held over dt: b (3 dt^2 / 4 + s^2, 2 s^2 dt, dt^2 s^2 / 2 + 2 s^4)."""
    from attend.models.generalized import smoothness_precision

    S = smoothness_precision(3, s)
    np.testing.assert_allclose(S, [[1.5, 0, s**2], [0, 2 * s**2, 0], [s**2, 0, 2 * s**4]], rtol=1e-10, atol=1e-300)
    instantaneous = markov_parameters(A_DI, B_DI, C_ANGLE, np.zeros((1, 1)), 3)[:, 0] @ S
    held = markov_parameters(A_DI, B_DI, C_ANGLE, np.zeros((1, 1)), 3, hold=DT)[:, 0] @ S
    np.testing.assert_allclose(instantaneous, B_GAIN * np.array([s**2, 0.0, 2 * s**4]), rtol=1e-10, atol=1e-300)
    expected = B_GAIN * np.array([3 * DT**2 / 4 + s**2, 2 * s**2 * DT, DT**2 * s**2 / 2 + 2 * s**4])
    np.testing.assert_allclose(held, expected, rtol=1e-10)


def test_arm_held_jacobian_is_the_inverse_mass_matrix_times_dt2_over_2_dt_and_1_to_first_order():
    """ArmActionJacobian(hold=dt): the held column of the arm linearised at x. Over a 10 ms hold the arm's own
    dynamics (gravity stiffness, friction, Coriolis terms at 0.5 rad/s) change it from (M^-1 dt^2/2, M^-1 dt, M^-1)
    by 0.5-1.4 % (measured); hold=0 is the instantaneous column."""
    from attend.control import arm

    params, dt = arm.ArmParameters(), 0.01
    x = np.array([-0.6, 0.8, 0.5, -0.3])
    held = arm.ArmActionJacobian(params, tolerance=0.0, hold=dt)(x, None, None)
    inverse = np.linalg.inv(arm.mass_matrix(params, x[:2]))
    both_sensors = np.vstack([inverse, inverse])
    for order, scale in enumerate((dt**2 / 2, dt, 1.0)):
        block = held[4 * order: 4 * order + 4]
        assert np.abs(block - scale * both_sensors).max() < 0.03 * scale * np.abs(both_sensors).max()
    instantaneous = arm.ArmActionJacobian(params, tolerance=0.0)(x, None, None)
    np.testing.assert_array_equal(arm.ArmActionJacobian(params, tolerance=0.0, hold=0.0)(x, None, None), instantaneous)
    with pytest.raises(AttendInputError, match="hold: expected a finite time >= 0"):
        arm.ArmActionJacobian(params, hold=-dt)


@pytest.mark.parametrize("size", [0.05, 0.95, 1.05, 3.0])
def test_held_column_series_and_exponential_agree_with_an_independent_exponential(size):
    """Up to |f_x tau|_1 = 1 the held column is summed as a series, above it comes from one exponential; both
    match the response read from expm([[f_x, f_a, 0], [0, 0, I], [0, 0, 0]] tau)'s blocks (x(tau) and x'(tau) of
    a unit step held from rest) to rounding."""
    from scipy.linalg import expm

    rng = np.random.default_rng(3)
    n, k, m, tau = 4, 2, 3, 0.01
    fx = rng.standard_normal((n, n))
    fx *= size / (np.abs(fx).sum(axis=0).max() * tau)
    fa, gx, ga = rng.standard_normal((n, k)), rng.standard_normal((m, n)), rng.standard_normal((m, k))
    G = markov_parameters(fx, fa, gx, ga, 4, hold=tau)
    augmented = np.zeros((n + k, n + k))
    augmented[:n, :n], augmented[:n, n:] = fx, fa
    exponential = expm(augmented * tau)
    x_tau, rate = exponential[:n, n:], exponential[:n, :n] @ fa
    expected = np.vstack([gx @ x_tau + ga, gx @ rate, gx @ fx @ rate, gx @ fx @ fx @ rate])
    np.testing.assert_allclose(G, expected, rtol=1e-12, atol=1e-14 * np.abs(expected).max())
