"""The two-link arm (attend.control.arm) against its closed forms, the controllers on it, and bad input.

Closed forms: M(q) symmetric positive definite with det M = (m2 lc2^2 + I2)(m1 lc1^2 + I1) + m2 l1^2 I2
+ m2^2 l1^2 lc2^2 sin^2 q2; M' - 2 C skew-symmetric; g(q) = dV/dq; the static torque that holds a pose is
g(q); the unforced frictionless arm conserves energy (to Runge-Kutta 4's order); the analytic linearisation
against central differences; dy~/da of angle sensors is M^-1 at order 2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.control import ActiveInferenceController, LQGController, SensorPrecisionLearning, run
from attend.control import arm

PARAMS = arm.ArmParameters()
RNG = np.random.default_rng(28)
POSES = RNG.uniform(-math.pi, math.pi, (20, 2))
VELOCITIES = RNG.uniform(-3.0, 3.0, (20, 2))
TORQUES = RNG.uniform(-10.0, 10.0, (20, 2))


def test_mass_matrix_is_symmetric_positive_definite_with_its_closed_form_determinant():
    (m1, m2), (l1, _), (c1, c2), (i1, i2) = (PARAMS.link_masses, PARAMS.link_lengths, PARAMS.com_distances,
                                             PARAMS.link_inertias)
    for q in POSES:
        M = arm.mass_matrix(PARAMS, q)
        assert np.array_equal(M, M.T)
        assert np.linalg.eigvalsh(M).min() > 0
        det = (m2 * c2**2 + i2) * (m1 * c1**2 + i1) + m2 * l1**2 * i2 + (m2 * l1 * c2 * math.sin(q[1])) ** 2
        # a 2 x 2 determinant of entries ~1 in float64: rounding ~1e-16 of the largest product
        assert np.linalg.det(M) == pytest.approx(det, rel=1e-12)


def test_mass_matrix_derivative_minus_twice_coriolis_is_skew_symmetric():
    for q, w in zip(POSES, VELOCITIES):
        h = 1e-6  # M' = dM/dq q' by central differences: truncation ~h^2 |M'''| ~ 1e-12
        M_dot = (arm.mass_matrix(PARAMS, q + h * w) - arm.mass_matrix(PARAMS, q - h * w)) / (2 * h)
        N = M_dot - 2 * arm.coriolis_matrix(PARAMS, q, w)
        # rounding of the difference quotient: eps |M| / h ~ 1e-10
        assert np.abs(N + N.T).max() < 1e-8


def test_gravity_torque_is_the_gradient_of_the_potential_energy():
    for q in POSES:
        h = 1e-6
        gradient = [(arm.potential_energy(PARAMS, q + h * e) - arm.potential_energy(PARAMS, q - h * e)) / (2 * h)
                    for e in np.eye(2)]
        # central differences: truncation h^2 |V'''| / 6 ~ 1e-12, rounding eps |V| / h ~ 1e-9 (|V| ~ 10 J)
        assert np.allclose(arm.gravity_torque(PARAMS, q), gradient, atol=1e-8)


def test_inverse_dynamics_inverts_forward_dynamics():
    for q, w, tau in zip(POSES, VELOCITIES, TORQUES):
        acc = arm.forward_dynamics(PARAMS, q, w, tau)
        # one 2 x 2 solve and its product: rounding ~ cond(M) eps |tau| (cond(M) <= ~100 here)
        assert np.allclose(arm.inverse_dynamics(PARAMS, q, w, acc), tau, rtol=0, atol=1e-11)
    assert np.array_equal(arm.inverse_dynamics(PARAMS, POSES[0], [0, 0], [0, 0]), arm.gravity_torque(PARAMS, POSES[0]))


def test_the_static_torque_g_of_q_holds_the_pose():
    for q in POSES[:5]:
        plant = arm.arm_plant(PARAMS, initial_angles=q)
        world = plant.start(100, 0.01, seed=0)
        holding = arm.gravity_torque(PARAMS, q)
        assert np.abs(arm.forward_dynamics(PARAMS, q, [0, 0], holding)).max() < 1e-13  # rounding only
        for _ in range(100):
            world.advance(holding)
        # a residual acceleration a <= 1e-13 rad/s^2 moves the arm by a T^2 / 2 over T = 1 s
        assert np.abs(world.x[:2] - q).max() < 1e-12 and np.abs(world.x[2:]).max() < 1e-12
    # and without it the arm falls (unless it hangs straight down)
    plant = arm.arm_plant(PARAMS, initial_angles=POSES[0])
    world = plant.start(10, 0.01, seed=0)
    for _ in range(10):
        world.advance([0.0, 0.0])
    assert np.abs(world.x[:2] - POSES[0]).max() > 1e-3


def test_hanging_straight_down_needs_no_torque():
    assert np.allclose(arm.gravity_torque(PARAMS, [-math.pi / 2, 0.0]), 0.0, atol=1e-14)


def test_unforced_frictionless_arm_conserves_energy_to_rk4_order():
    frictionless = arm.ArmParameters(joint_friction=(0.0, 0.0))
    q0, w0 = np.array([0.3, -0.5]), np.array([1.0, -2.0])
    energy0 = arm.energy(frictionless, q0, w0)

    def drift(substeps):
        world = arm.arm_plant(frictionless, initial_angles=q0, initial_velocities=w0, substeps=substeps).start(
            200, 0.01, seed=0)
        worst = 0.0
        for _ in range(200):
            world.advance([0.0, 0.0])
            worst = max(worst, abs(arm.energy(frictionless, world.x[:2], world.x[2:]) - energy0))
        return worst

    coarse, fine, finer = drift(4), drift(8), drift(16)  # h = 2.5, 1.25, 0.625 ms over 2 s
    # Runge-Kutta 4 has global error C h^4: halving h divides the drift by 16 (measured 14.4 and 15.2); a
    # factor 2 either way allows for the higher-order terms at the coarser step
    assert 8 < coarse / fine < 32 and 8 < fine / finer < 32
    # and the error is small against the motion's kinetic energy (0.16 J): measured 7.2e-8 J at h = 2.5 ms
    assert coarse < 1e-6 * (energy0 - arm.potential_energy(frictionless, q0))


def test_friction_dissipates_energy():
    q0, w0 = np.array([0.3, -0.5]), np.array([1.0, -2.0])
    world = arm.arm_plant(PARAMS, initial_angles=q0, initial_velocities=w0).start(100, 0.01, seed=0)
    energies = []
    for _ in range(100):
        world.advance([0.0, 0.0])
        energies.append(arm.energy(PARAMS, world.x[:2], world.x[2:]))
    # dE/dt = -q' B q' <= 0 (to the integration error, ~1e-7 J per the test above)
    assert np.all(np.diff(energies) < 1e-7) and energies[-1] < arm.energy(PARAMS, q0, w0) - 0.01


def test_linearisation_matches_central_differences():
    def f(z):
        return np.concatenate([z[2:4], arm.forward_dynamics(PARAMS, z[:2], z[2:4], z[4:])])

    for q, w, tau in zip(POSES, VELOCITIES, TORQUES):
        z = np.concatenate([q, w, tau])
        fx, fa = arm.state_jacobians(PARAMS, z[:4], tau)
        h = 1e-5
        numeric = np.column_stack([(f(z + h * e) - f(z - h * e)) / (2 * h) for e in np.eye(6)])
        # truncation h^2 |f'''| / 6 with |f'''| <= ~1e4 (rad/s^2 per unit^3 near sin q2 ~ 0, velocities 3 rad/s):
        # ~2e-7; rounding eps |f| / h ~ 2e-16 * 300 / 1e-5 ~ 1e-8
        assert np.allclose(np.hstack([fx, fa]), numeric, rtol=0, atol=1e-6 * max(1.0, np.abs(numeric).max()))


def test_linearise_holds_the_pose_and_its_input_matrix_is_the_inverse_mass_matrix():
    q = np.array([-0.6, 0.8])
    A, B, holding = arm.linearise(PARAMS, q)
    assert np.array_equal(holding, arm.gravity_torque(PARAMS, q))
    assert np.allclose(B[2:], np.linalg.inv(arm.mass_matrix(PARAMS, q)), rtol=1e-14, atol=0)
    assert np.array_equal(A[:2], [[0, 0, 1, 0], [0, 0, 0, 1]])
    # hanging straight down, frictionless: small oscillations with M w^2 = dg/dq, the double pendulum's modes
    frictionless = arm.ArmParameters(joint_friction=(0.0, 0.0))
    A, _, _ = arm.linearise(frictionless, [-math.pi / 2, 0.0])
    M = arm.mass_matrix(frictionless, [-math.pi / 2, 0.0])
    g1, g2 = frictionless._constants()[3:5]
    stiffness = np.array([[g1 + g2, g2], [g2, g2]])  # d g / d q at the bottom
    expected = np.sort(np.linalg.eigvals(np.linalg.solve(M, stiffness)).real)
    eigenvalues = np.linalg.eigvals(A)
    assert np.allclose(eigenvalues.real, 0.0, atol=1e-12)
    assert np.allclose(np.sort(np.unique(np.round(eigenvalues.imag**2, 10))), expected, rtol=1e-9)


def test_action_jacobian_of_angle_sensors_is_the_inverse_mass_matrix_at_order_two():
    jacobian = arm.ArmActionJacobian(PARAMS, embedding_order=2, tolerance=0.0)
    x = np.array([-0.6, 0.8, 0.5, -0.3])
    G = jacobian(x, np.zeros(4), np.zeros(2))
    assert G.shape == (12, 2) and np.array_equal(G[:8], np.zeros((8, 2)))
    Minv = np.linalg.inv(arm.mass_matrix(PARAMS, x[:2]))
    assert np.allclose(G[8:], np.vstack([Minv, Minv]), rtol=1e-14, atol=0)
    # with a tolerance the same array comes back while dy~/da moves less than that fraction
    cached = arm.ArmActionJacobian(PARAMS, tolerance=0.05)
    first = cached(x, None, None)
    assert cached(x + [0.0, 1e-3, 0.0, 0.0], None, None) is first
    assert cached(x + [0.0, 0.5, 0.0, 0.0], None, None) is not first and cached.refreshes == 2


def _action_jacobian_by_markov_parameters(params, x, embedding_order, sensors_per_joint, hold):
    """dy~/da as ArmActionJacobian computed it before its closed-form path: state_jacobians at tau = g(q), then
    markov_parameters (the held column by Horner's rule, or one exponential above |f_x tau|_1 = 1)."""
    from attend.control import markov_parameters

    fx, fa = arm.state_jacobians(params, x, arm.gravity_torque(params, x[:2]))
    C = arm.sensor_matrix(sensors_per_joint)
    return markov_parameters(fx, fa, C, np.zeros((C.shape[0], 2)), embedding_order + 1, hold=hold)


@pytest.mark.parametrize("hold", [0.0, 0.01, 0.02, 0.2])
def test_action_jacobian_equals_its_markov_parameters_path(hold):
    """ArmActionJacobian's Jacobians in floats (M^-1 by its adjugate) and its held series by Krylov doubling equal
    markov_parameters of state_jacobians to rounding, over random states (velocities up to 3 rad/s), orders 0..4
    and 1..3 sensors per joint; hold 0.2 s takes the exponential (|f_x tau|_1 > 1) at most states."""
    heavy = PARAMS.scaled(link_masses=1.3, joint_friction=(2.0, 0.5))
    for params in (PARAMS, heavy):
        for i, (q, w) in enumerate(zip(POSES, VELOCITIES)):
            x = np.concatenate([q, w])
            order, sensors = i % 5, 1 + i % 3
            expected = _action_jacobian_by_markov_parameters(params, x, order, sensors, hold)
            G = arm.ArmActionJacobian(params, order, sensors, tolerance=0.0, hold=hold)(x, None, None)
            assert G.shape == expected.shape
            # entries ~1e-4..10 (M^-1 tau^2 / 2 .. M^-1); the two paths round differently (~1e-16 relative)
            np.testing.assert_allclose(G, expected, rtol=1e-13, atol=1e-14 * np.abs(expected).max())


def test_held_integral_by_krylov_doubling_is_the_truncated_series():
    """_held_integral: tau sum_{j <= J} (f_x tau)^j f_a / (j + 1)! (J from the size bound), against the sum written
    out term by term in exact rational arithmetic on the float inputs, for |f_x tau|_1 from 0.01 to 1."""
    from fractions import Fraction

    rng = np.random.default_rng(5)
    tau = 0.01
    for size in (0.01, 0.3, 0.7138, 1.0):
        fx = rng.standard_normal((4, 4))
        fx *= size / (np.abs(fx).sum(axis=0).max() * tau)
        fa = rng.standard_normal((4, 2))
        measured = np.abs(fx * tau).sum(axis=0).max()
        got = arm._held_integral(fx, fa, tau, measured, {})
        terms, bound = 0, 1.0
        while bound > 2.0**-53 and terms < 30:
            terms += 1
            bound *= measured / (terms + 1)
        X = [[Fraction(float(v)) * Fraction(tau) for v in row] for row in fx]
        column = [[Fraction(float(v)) for v in row] for row in fa]
        total = [[Fraction(0)] * 2 for _ in range(4)]
        for j in range(terms + 1):
            weight = Fraction(tau) / math.factorial(j + 1)
            total = [[total[r][c] + weight * column[r][c] for c in range(2)] for r in range(4)]
            column = [[sum(X[r][i] * column[i][c] for i in range(4)) for c in range(2)] for r in range(4)]
        exact = np.array([[float(v) for v in row] for row in total])
        np.testing.assert_allclose(got, exact, rtol=1e-14, atol=1e-15 * np.abs(exact).max())


def test_gravity_feedforward_adds_the_gravity_torque_at_the_believed_angles():
    wrapped = _aif()
    y = arm.sensor_matrix(2) @ np.array([-1.2, 0.4, 0.0, 0.0])
    for _ in range(3):
        torque = wrapped.step(y)
        action = wrapped.controller.action
        np.testing.assert_array_equal(torque, action + arm.gravity_torque(PARAMS, wrapped.controller.states[:2]))


def test_sensor_matrix_orders_outputs_sensor_major():
    assert np.array_equal(arm.sensor_matrix(2) @ [1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 1.0, 2.0])


def test_torque_disturbance_enters_where_the_torque_does():
    # the process's action noise u: the arm driven by a + u equals a noiseless arm driven by a + u
    noisy = arm.arm_plant(PARAMS, initial_angles=[-1.0, 0.5], torque_noise_std=[0.5, 0.2], torque_kernel_width=0.1,
                          torque_limits=[30.0, 10.0])
    clean = arm.arm_plant(PARAMS, initial_angles=[-1.0, 0.5])
    world, copy = noisy.start(50, 0.01, seed=3), clean.start(50, 0.01, seed=3)
    holding = arm.gravity_torque(PARAMS, [-1.0, 0.5])
    for k in range(50):
        u = world._u[k]
        world.advance(holding)
        copy.advance(holding + u)
        assert np.array_equal(world.applied, holding)  # the recorded action is the command, not the disturbance
    assert np.allclose(world.x, copy.x, rtol=0, atol=1e-14)
    assert np.abs(world.x[:2] - [-1.0, 0.5]).max() > 1e-4  # and the disturbance moved the arm


def test_noise_streams_of_worlds_without_action_noise_are_unchanged():
    # the action noise draws from a third child of the seed; sensor and process noise keep the first two
    from attend.control import GenerativeProcess
    from attend.models.noise import coloured_noise

    world = GenerativeProcess.linear([[0.0]], [[1.0]], [[1.0]], process_noise_std=0.3, sensor_noise_std=0.1,
                                     process_kernel_width=0.05, sensor_kernel_width=0.02).start(40, 0.01, seed=9)
    children = np.random.SeedSequence(9).spawn(2)
    assert np.array_equal(world._w, coloured_noise(41, 1, 0.01, 0.05, 0.3, np.random.default_rng(children[0])))
    assert np.array_equal(world._z, coloured_noise(41, 1, 0.01, 0.02, 0.1, np.random.default_rng(children[1])))


# --- controllers on the noiseless arm --------------------------------------------------------------

START, TARGET = np.array([-math.pi / 2, 0.0]), np.array([-0.6, 0.8])


def _aif(target=TARGET, params=PARAMS, learning=None, start=START):
    """The agent with the settings tuned by benchmarks/bench_control.py (--quick) for the arm."""
    prior = np.concatenate([target, np.zeros(10)])
    model = arm.critically_damped_model(14.09, sensor_std=0.002, process_precision=8.48e5, kernel_width=0.0045,
                                        cause_prior=lambda t: prior, initial_angles=start, reference_acceleration=True)
    controller = ActiveInferenceController(model, 0.01, action_gain=7.95e4, n_actions=2,
                                           action_jacobian=arm.ArmActionJacobian(params),
                                           action_limits=([-30.0, -10.0], [30.0, 10.0]), precision_learning=learning)
    return arm.GravityFeedforward(controller, params, "believed")


def _settled(loop, target, band=0.02):
    """The final angles within band x the step of the target, and still there over the last second."""
    step = np.abs(target - START)
    return np.all(np.abs(loop.states[-100:, :2] - target) <= band * step)


@pytest.mark.parametrize("name", ["active inference", "PID", "LQG"])
def test_controllers_bring_the_noiseless_arm_to_the_target(name):
    plant = arm.arm_plant(PARAMS, initial_angles=START, torque_limits=[30.0, 10.0])
    if name == "active inference":
        controller = _aif()
    elif name == "PID":
        inertia = np.diag(arm.mass_matrix(PARAMS, TARGET))
        gains = np.column_stack([inertia * 700.0, inertia * 6214.0, inertia * 38.7, [0.0016, 0.0016]])
        controller = arm.joint_pid(PARAMS, 0.01, gains=gains, reference=TARGET, torque_limits=[30.0, 10.0])
    else:
        controller = arm.ArmLQG(PARAMS, 0.01, operating_angles=TARGET, reference=TARGET, initial_angles=START,
                                state_weight=[3.9e5, 3.9e5, 2.26, 2.26], integral_weight=12.3,
                                # the disturbance enters the accelerations: a filter told that the angles themselves
                                # wander (W = 1e-4 I) estimates the velocity with a 1.4 s time constant
                                process_covariance=np.diag([1e-12, 1e-12, 1e-4, 1e-4]), sensor_covariance=4e-6,
                                torque_limits=[30.0, 10.0])
    loop = run(plant, controller, 3.0, seed=0)
    assert _settled(loop, TARGET)
    # integral action (the reflex, the PID's and LQG's integrators) leaves no steady error without noise
    assert np.abs(loop.states[-1, :2] - TARGET).max() < 1e-3


def test_active_inference_reaches_the_target_with_a_30_percent_heavier_arm():
    heavy = PARAMS.scaled(link_masses=1.3, link_inertias=1.3)
    plant = arm.arm_plant(heavy, initial_angles=START, torque_limits=[30.0, 10.0])
    loop = run(plant, _aif(), 3.0, seed=0)  # the agent's dy~/da and gravity torque stay nominal
    assert _settled(loop, TARGET)


def test_learning_moves_precision_to_the_good_sensor_of_each_joint():
    # sensor 2 of both joints: noise x10 from t = 1 s (its true precision falls 100-fold)
    scale = lambda t: np.array([1.0, 1.0, 10.0, 10.0]) if t >= 1.0 else 1.0  # noqa: E731
    plant = arm.arm_plant(PARAMS, initial_angles=START, torque_limits=[30.0, 10.0], sensor_std=0.002,
                          sensor_kernel_width=0.01, sensor_noise_scale=scale)
    learning = SensorPrecisionLearning(time_constant=0.25, level="relative", orders="all", groups=(0, 1, 0, 1))
    total = 2 / 0.002**2  # each joint's designed total: 2 sensors at 1 / 0.002^2
    for seed in range(3):
        controller = _aif(learning=learning)
        world = plant.start(300, 0.01, seed)
        controller.reset()
        for k in range(300):
            world.advance(controller.step(world.output()))
            if k == 95:  # before the degradation: equal sensors, equal shares (measured 0.89-1.08)
                before = controller.controller.sensor_precision
                assert 0.5 < before[0] / before[2] < 2 and 0.5 < before[1] / before[3] < 2
        after = controller.controller.sensor_precision
        # the oracle ratio is 100; measured 82-151 at the shoulder, but only 1.9-33 at the elbow, whose belief
        # follows its sensors more closely (equal errors on both sensors when the belief is their mean)
        assert after[0] > 10 * after[2] and after[1] > 1.5 * after[3]
        # the relative level keeps each joint's total
        assert abs(after[0] + after[2] - total) < 1e-9 * total and abs(after[1] + after[3] - total) < 1e-9 * total


def test_lqg_tracks_several_variables():
    # two decoupled double integrators, each with its own reference: the equilibrium feed-forward (no integrator)
    # and the integrators both bring each axis to its own reference; exponential convergence over 20 s leaves
    # rounding-level errors
    from attend.control import GenerativeProcess

    A = np.kron(np.eye(2), [[0.0, 1.0], [0.0, 0.0]])
    B = np.kron(np.eye(2), [[0.0], [1.0]])
    C = np.kron(np.eye(2), [[1.0, 0.0]])
    world = GenerativeProcess.linear(A, B, C)
    for integral_weight in (0.0, 100.0):
        lqg = LQGController(A, B, C, 0.01, reference=[1.0, -2.0], tracked=C, state_weight=[100.0, 1.0, 100.0, 1.0],
                            integral_weight=integral_weight, initial_estimate=[0.0, 0.0, 0.0, 0.0])
        loop = run(world, lqg, 20.0)
        assert np.allclose(loop.states[-1], [1.0, 0.0, -2.0, 0.0], rtol=0, atol=1e-8)
    with pytest.raises(AttendInputError, match="reference: expected 2"):
        LQGController(A, B, C, 0.01, reference=[1.0, -2.0, 3.0], tracked=C)


# --- bad input ------------------------------------------------------------------------------------

@pytest.mark.parametrize("options, match", [
    (dict(link_masses=(-1.0, 1.2)), "link_masses: expected 2 masses > 0"),
    (dict(link_masses=(0.0, 1.2)), "link_masses"),
    (dict(link_lengths=(0.5, 0.4, 0.3)), "link_lengths: expected 2"),
    (dict(com_distances=(np.nan, 0.2)), "com_distances: expected finite"),
    (dict(link_inertias=(-0.1, 0.01)), "link_inertias: expected 2 inertias >= 0"),
    (dict(joint_friction=(0.1, -0.05)), "joint_friction"),
    (dict(gravity=-9.81), "gravity: expected a finite number >= 0"),
    (dict(gravity="9.81"), "gravity: expected a number"),
    (dict(com_distances=(0.25, 0.0), link_inertias=(0.04, 0.0)), "link_inertias: link 2 has no inertia"),
    (dict(link_masses="heavy"), "link_masses"),
])
def test_arm_parameters_are_validated(options, match):
    with pytest.raises(AttendInputError, match=match):
        arm.ArmParameters(**options)


def test_scaled_names_an_unknown_field_and_validates_the_result():
    with pytest.raises(AttendInputError, match="link_mass: not a field"):
        PARAMS.scaled(link_mass=1.3)
    with pytest.raises(AttendInputError, match="link_masses: expected 2 masses > 0"):
        PARAMS.scaled(link_masses=-1.0)
    assert PARAMS.scaled(link_masses=(1.0, 2.0)).link_masses == (2.0, 2.4)


@pytest.mark.parametrize("call, match", [
    (lambda: arm.mass_matrix(PARAMS, [0.1, 0.2, 0.3]), "angles: expected 2"),
    (lambda: arm.forward_dynamics(PARAMS, [0.1, 0.2], [0.0, 0.0], [np.inf, 0.0]), "torques: expected finite"),
    (lambda: arm.forward_dynamics(PARAMS, [0.1, 0.2], [0.0], [0.0, 0.0]), "velocities: expected 2"),
    (lambda: arm.inverse_dynamics(PARAMS, [0.1, 0.2], [0.0, 0.0], [0.0, np.nan]), "accelerations: expected finite"),
    (lambda: arm.state_jacobians(PARAMS, [0.0, 0.0, 0.0], [0.0, 0.0]), "states: expected 4"),
    (lambda: arm.arm_plant(PARAMS, torque_limits=[30.0, -1.0]), "torque_limits: expected limits > 0"),
    (lambda: arm.arm_plant(PARAMS, initial_angles=[0.0, np.nan]), "initial_angles: expected finite"),
    (lambda: arm.arm_plant(PARAMS, sensors_per_joint=0), "sensors_per_joint: expected an integer >= 1"),
    (lambda: arm.arm_plant(PARAMS, torque_noise_std=[0.5, 0.2, 0.1]), "action_noise_std: expected 2"),
    (lambda: arm.arm_plant(PARAMS, torque_noise_std=-0.5), "action_noise_std: expected standard deviations >= 0"),
    (lambda: arm.arm_plant(PARAMS, torque_kernel_width=-0.1), "action_kernel_width"),
    (lambda: arm.arm_plant(PARAMS, sensor_std=[0.002] * 3), "sensor_noise_std: expected 4"),
    (lambda: arm.arm_plant({"link_masses": (1, 1)}), "params: expected attend.control.arm.ArmParameters"),
    (lambda: arm.joint_pid(PARAMS, 0.01, gains=np.ones((2, 3)), reference=TARGET), "gains: expected a \\(2, 4\\)"),
    (lambda: arm.joint_pid(PARAMS, 0.01, gains=np.ones((2, 4)), reference=[0.1]), "reference: expected 2"),
    (lambda: arm.GravityFeedforward(_aif().controller, PARAMS, "true"), "angles: expected 'believed' or 'measured'"),
    (lambda: arm.GravityFeedforward(_aif().controller, {"gravity": 9.81}), "params: expected attend.control.arm"),
    (lambda: arm.ArmActionJacobian(PARAMS, tolerance=-0.1), "tolerance: expected a finite number >= 0"),
    (lambda: arm.ArmActionJacobian(PARAMS)([0.0, 0.0, 0.0], None, None), "states: expected 4"),
    (lambda: arm.ArmActionJacobian(PARAMS, embedding_order=-1), "embedding_order"),
    (lambda: arm.ArmLQG(PARAMS, 0.01, operating_angles=[0.1], reference=TARGET), "operating_angles: expected 2"),
    (lambda: arm.ArmLQG(PARAMS, 0.01, operating_angles=TARGET, reference=TARGET, reference_trajectory=1.0),
     "reference_trajectory: expected a function"),
    (lambda: arm.critically_damped_model(-1.0, sensor_std=0.002, process_precision=1.0, kernel_width=0.01,
                                         cause_prior=lambda t: np.zeros(4)), "bandwidth: expected a finite number > 0"),
    (lambda: SensorPrecisionLearning(groups=("a", "b")), "groups: expected one integer label per output"),
    (lambda: _aif(learning=SensorPrecisionLearning(groups=(0, 1))), "precision_learning.groups: expected one label per"),
    (lambda: LQGController(np.eye(2), np.eye(2), np.eye(2), 0.01, tracked=np.eye(2), initial_estimate=[0.0]),
     "initial_estimate: expected 2"),
])
def test_bad_input_names_the_field(call, match):
    with pytest.raises(AttendInputError, match=match):
        call()
