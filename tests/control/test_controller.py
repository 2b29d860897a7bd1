"""attend.control: closed forms, oracles and consistency of the active inference controller."""

from __future__ import annotations

import numpy as np
import pytest

from attend.control import (
    ActiveInferenceController,
    GenerativeModel,
    GenerativeProcess,
    SensorPrecisionLearning,
    closed_loop_spectral_radius,
    markov_parameters,
    run,
)
from attend.control._core import error_jacobian, joint_system, local_linearisation_step, shift_matrix
from attend.models.generalized import smoothness_precision

MASS, STIFFNESS, DAMPING = 1.4, 0.8, 0.4
A_MSD = np.array([[0.0, 1.0], [-STIFFNESS / MASS, -DAMPING / MASS]])
B_MSD = np.array([[0.0], [1.0 / MASS]])
C_POS = np.array([[1.0, 0.0]])


def test_markov_parameters_of_the_mass_spring_damper():
    """dy~/da = [D; CB; CAB; CA^2 B] = [0; 0; 1/m; -b/m^2] for a position sensor."""
    G = markov_parameters(A_MSD, B_MSD, C_POS, np.zeros((1, 1)), 4)
    np.testing.assert_allclose(G[:, 0], [0.0, 0.0, 1 / MASS, -DAMPING / MASS**2], atol=1e-15)
    world = GenerativeProcess.linear(A_MSD, B_MSD, C_POS)
    np.testing.assert_allclose(world.action_jacobian(np.zeros(2), np.zeros(1), 3), G)


@pytest.mark.parametrize("plant_gain", [1.0, 2.0, 0.5])
def test_steady_state_action_is_the_analytic_fixed_point(plant_gain):
    """Model dx/dt = A x + B v, prior v = eta; world dx/dt = A_p x + B_p a (here B_p = gain B, A_p stiffer).
    At rest every error vanishes: y = -C A^-1 B eta (what the model predicts under its intention) and the
    action holds the world there, a = (C A_p^-1 B_p)^-1 C A^-1 B eta, whatever the precisions."""
    eta = 0.7
    A_p = A_MSD + np.array([[0.0, 0.0], [-0.3, 0.0]])
    B_p = plant_gain * B_MSD
    world = GenerativeProcess.linear(A_p, B_p, C_POS)
    model = GenerativeModel.linear(A_MSD, B_MSD, C_POS, sensor_precision=np.exp(4), process_precision=np.exp(2),
                                   cause_prior_precision=np.exp(2), cause_prior=[eta], kernel_width=1.0,
                                   embedding_order=2, cause_order=1)
    G = markov_parameters(A_p, B_p, C_POS, np.zeros((1, 1)), 3)
    controller = ActiveInferenceController(model, 0.05, action_gain=5.0, action_jacobian=G)
    loop = run(world, controller, 250.0, record_beliefs=False)
    assert closed_loop_spectral_radius(world, controller) < 0.997  # so 5000 samples leave < 1e-6 of the start
    y_star = -(C_POS @ np.linalg.solve(A_MSD, B_MSD))[0, 0] * eta
    a_star = y_star / -(C_POS @ np.linalg.solve(A_p, B_p))[0, 0]
    assert loop.outputs[-1, 0] == pytest.approx(y_star, abs=1e-6)
    assert loop.actions[-1, 0] == pytest.approx(a_star, abs=1e-6)
    assert controller.causes[0] == pytest.approx(eta, abs=1e-6)


def _static_posterior(A, B, C, eta, pz, pw, pv, y):
    """Dense oracle: the Gaussian posterior of (x, v) given y = C x + z, 0 = A x + B v + w, v = eta + e."""
    n, r = B.shape
    E = np.block([[C, np.zeros((C.shape[0], r))], [A, B], [np.zeros((r, n)), np.eye(r)]])
    b = np.concatenate([y, np.zeros(n), eta])
    Pi = np.diag(np.concatenate([pz, pw, pv]))
    precision = E.T @ Pi @ E
    return np.linalg.solve(precision, E.T @ Pi @ b), precision


def test_d_step_reaches_the_gaussian_posterior_mean():
    """One order of motion (p = d = 0): the D-step is a gradient flow on a quadratic free energy, and its fixed
    point is the exact posterior mean of the linear Gaussian model; the curvature is the posterior precision."""
    A = np.array([[-1.0, 0.3], [0.2, -0.8]])
    B = np.array([[0.5], [1.0]])
    C = np.array([[1.0, 0.0], [0.4, 1.0], [0.0, 2.0]])
    eta, y = np.array([0.3]), np.array([0.9, -0.2, 0.5])
    pz, pw, pv = np.array([4.0, 2.0, 1.0]), np.array([3.0, 5.0]), np.array([0.5])
    mean, precision = _static_posterior(A, B, C, eta, pz, pw, pv, y)
    S = smoothness_precision(1, 0.5)  # [[1]]
    E_y, E_x, E_v = error_jacobian(A, B, C, np.zeros((3, 1)), 1, 1)
    G = np.zeros((3, 0))  # no action: the pure D-step
    J, K_y, K_eta, curvature = joint_system(shift_matrix(1, 2, 1, 1), E_y, E_x, E_v, np.kron(S, np.diag(pz)),
                                            np.kron(S, np.diag(pw)), np.kron(S, np.diag(pv)), G, np.kron(S, np.diag(pz)),
                                            1.0, 0.0)
    np.testing.assert_allclose(curvature, precision, rtol=1e-12)
    X = np.zeros(3)
    for _ in range(200):
        flow = J @ X + K_y @ y + K_eta @ eta
        X = X + local_linearisation_step(J, flow, 0.5)
    np.testing.assert_allclose(X, mean, rtol=1e-10, atol=1e-12)


def test_d_step_in_generalised_coordinates_reaches_its_moving_frame_fixed_point():
    """p = 2 with constant generalised data y~: the controller's beliefs settle where D X + dF/dX = 0, i.e.
    X* = (E' Pi E - D)^-1 E' Pi b (closed form, exact for a linear model); the action is off (dy~/da = 0 rows
    above order 0 are not read because y is attended only at order 0 here)."""
    model = GenerativeModel.linear(A_MSD, B_MSD, C_POS, sensor_precision=9.0, process_precision=4.0,
                                   cause_prior_precision=2.0, cause_prior=[0.4], kernel_width=0.4, embedding_order=2,
                                   cause_order=1)
    G = np.array([[1e-300], [0.0], [0.0]])  # a negligible action: isolates perception
    controller = ActiveInferenceController(model, 0.05, action_gain=1e-300, action_jacobian=G)
    y_t = np.array([0.25, 0.1, -0.05])
    for _ in range(3000):
        controller.step_generalised(y_t)
    P, Q = 3, 2
    S_y = np.zeros((3, 3))
    S_y[:1, :1] = smoothness_precision(1, 0.4)  # order 0 attended: the relative degree of the tiny dy~/da
    E_y, E_x, E_v = error_jacobian(A_MSD, B_MSD, C_POS, np.zeros((1, 1)), P, Q)
    Pi = [S_y * 9.0, np.kron(smoothness_precision(P, 0.4), 4.0 * np.eye(2)), smoothness_precision(Q, 0.4) * 2.0]
    E = np.vstack([E_y, E_x, E_v])
    Pi_all = np.zeros((E.shape[0], E.shape[0]))
    sizes = np.cumsum([0, 3, 6, 2])
    for block, (i, j) in zip(Pi, zip(sizes[:-1], sizes[1:])):
        Pi_all[i:j, i:j] = block
    offset = np.concatenate([y_t, np.zeros(6), [-0.4, 0.0]])  # e = offset + E X
    D = shift_matrix(P, 2, Q, 1)
    expected = np.linalg.solve(E.T @ Pi_all @ E - D, -E.T @ Pi_all @ offset)
    np.testing.assert_allclose(np.concatenate([controller.generalised_states, controller.generalised_causes]), expected,
                               rtol=1e-8, atol=1e-10)


def test_linear_fast_path_equals_the_general_step():
    """The cached linear transition and the local-linearisation step agree sample by sample (the general step is
    forced by a constant precision given as a function)."""
    world = GenerativeProcess.linear(A_MSD, B_MSD, np.vstack([C_POS, C_POS]), sensor_noise_std=[0.01, 0.02],
                                     process_noise_std=[0.0, 0.05], sensor_kernel_width=0.05, process_kernel_width=0.3)
    options = dict(process_precision=np.exp(3), cause_prior_precision=np.exp(6), cause_prior=[1.0], kernel_width=0.1,
                   embedding_order=3, cause_order=1)
    precision = np.array([np.exp(6), np.exp(5)])
    fast = GenerativeModel.linear(A_MSD, B_MSD, np.vstack([C_POS, C_POS]), sensor_precision=precision, **options)
    general = GenerativeModel.linear(A_MSD, B_MSD, np.vstack([C_POS, C_POS]),
                                     sensor_precision=lambda x, v: precision, **options)
    a = ActiveInferenceController(fast, 0.01, action_gain=3.0, n_actions=1)
    b = ActiveInferenceController(general, 0.01, action_gain=3.0, n_actions=1)
    assert a._fast and not b._fast
    one, two = run(world, a, 3.0, seed=4), run(world, b, 3.0, seed=4)
    np.testing.assert_allclose(one.actions, two.actions, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(one.belief_states, two.belief_states, rtol=1e-9, atol=1e-12)


def test_attended_orders_stop_at_the_relative_degree():
    """Position sensors of a force-driven mass (relative degree 2) are attended up to acceleration; an output no
    action moves keeps every order."""
    model = GenerativeModel.linear(A_MSD, B_MSD, np.vstack([C_POS, [[0.0, 1.0]]]), embedding_order=4, cause_order=1)
    G = markov_parameters(A_MSD, B_MSD, np.vstack([C_POS, [[0.0, 1.0]]]), np.zeros((2, 1)), 5)
    controller = ActiveInferenceController(model, 0.01, action_jacobian=G)
    np.testing.assert_array_equal(controller._orders, [2, 1])
    controller = ActiveInferenceController(model, 0.01, action_jacobian=G, sensory_orders="all")
    np.testing.assert_array_equal(controller._orders, [4, 4])


def test_loop_is_stable_for_any_action_gain_on_the_scalar_plant():
    """The action update is integrated with its curvature (local linearisation), so a large gain does not
    destabilise a well-posed loop: spectral radius < 1 from kappa = 0.1 to 1e4."""
    world = GenerativeProcess.linear([[-1.0]], [[1.0]], [[1.0]])
    model = GenerativeModel.linear([[-1.0]], [[1.0]], [[1.0]], sensor_precision=np.exp(2), process_precision=np.exp(2),
                                   cause_prior_precision=np.exp(4), cause_prior=[1.0], embedding_order=3)
    for gain in (0.1, 10.0, 1e4):
        controller = ActiveInferenceController(model, 0.01, action_gain=gain, n_actions=1)
        assert closed_loop_spectral_radius(world, controller) < 1.0


def test_rhythm_modulates_sensory_precision():
    """Pi_z(t) = pi(t) Pi_z with pi(t) the oscillator's multiplier."""
    from attend.rhythm import PrecisionOscillator

    oscillator = PrecisionOscillator(frequency=2.0, depth=1.5)
    world = GenerativeProcess.linear([[-1.0]], [[1.0]], [[1.0]])
    model = GenerativeModel.linear([[-1.0]], [[1.0]], [[1.0]], sensor_precision=5.0, cause_prior=[1.0])
    controller = ActiveInferenceController(model, 0.01, n_actions=1, precision_schedule=oscillator)
    loop = run(world, controller, 1.0)
    np.testing.assert_allclose(loop.sensor_precision[:, 0], 5.0 * oscillator.multiplier(loop.time), rtol=1e-12)


def test_state_dependent_precision_is_evaluated_at_the_beliefs():
    """Pi_z(x, v) is read at the current belief (order 0)."""
    world = GenerativeProcess.linear([[-1.0]], [[1.0]], [[1.0]])
    model = GenerativeModel(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            sensor_precision=lambda x, v: np.exp(3.0 - np.tanh(x + v)), cause_prior=[0.5])
    controller = ActiveInferenceController(model, 0.05, n_actions=1)
    loop = run(world, controller, 2.0)
    expected = np.exp(3.0 - np.tanh(loop.belief_states[:-1, 0] + loop.belief_causes[:-1, 0]))
    np.testing.assert_allclose(loop.sensor_precision[1:, 0], expected, rtol=1e-12)


def test_precision_learning_follows_a_degrading_sensor():
    """Two position sensors (noise std 0.01, smooth as the model assumes); sensor 2's noise grows x10 at t = 10 s.
    Before: both learned precisions near 1/0.01^2 = 1e4. After: sensor 2's falls to near 1/0.1^2 = 100 (>= 30x
    drop) and the agent weights sensor 1 above it (ratio > 3; sensor 1's own precision also drops for a while:
    the belief carries more common error while sensor 2 is still trusted)."""
    C2 = np.vstack([C_POS, C_POS])
    world = GenerativeProcess.linear(A_MSD, B_MSD, C2, sensor_noise_std=[0.01, 0.01], sensor_kernel_width=0.05,
                                     sensor_noise_scale=lambda t: np.array([1.0, 10.0 if t >= 10.0 else 1.0]))
    model = GenerativeModel.linear(A_MSD, B_MSD, C2, sensor_precision=1e4, process_precision=1e3,
                                   cause_prior_precision=1e2, cause_prior=[0.5], kernel_width=0.05)
    learning = SensorPrecisionLearning(time_constant=2.0, level="absolute")
    controller = ActiveInferenceController(model, 0.01, action_gain=1.0, n_actions=1, precision_learning=learning)
    loop = run(world, controller, 20.0, seed=1)
    before = loop.sensor_precision[(loop.time > 7) & (loop.time < 10)].mean(axis=0)
    after = loop.sensor_precision[loop.time > 17].mean(axis=0)
    assert np.all((before > 3e3) & (before < 3e4))
    assert before[1] / after[1] > 30
    assert 30 < after[1] < 300
    assert after[0] / after[1] > 3


def test_relative_precision_learning_keeps_the_total_and_moves_the_shares():
    """level="relative": sum(pi) stays at the model's total while the degrading sensor's share falls."""
    C2 = np.vstack([C_POS, C_POS])
    world = GenerativeProcess.linear(A_MSD, B_MSD, C2, sensor_noise_std=[0.01, 0.01], sensor_kernel_width=0.05,
                                     sensor_noise_scale=lambda t: np.array([1.0, 10.0 if t >= 5.0 else 1.0]))
    model = GenerativeModel.linear(A_MSD, B_MSD, C2, sensor_precision=1e4, process_precision=1e3,
                                   cause_prior_precision=1e2, cause_prior=[0.5], kernel_width=0.05)
    learning = SensorPrecisionLearning(time_constant=1.0, level="relative", orders="all")
    controller = ActiveInferenceController(model, 0.01, action_gain=1.0, n_actions=1, precision_learning=learning)
    loop = run(world, controller, 12.0, seed=3)
    np.testing.assert_allclose(loop.sensor_precision.sum(axis=1), 2e4, rtol=1e-9)
    share = loop.sensor_precision[:, 1] / 2e4
    assert share[loop.time > 10].mean() < 0.1 < 0.4 < share[(loop.time > 3) & (loop.time < 5)].mean()
