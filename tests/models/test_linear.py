"""Linear systems: validation, exact zero-order hold, presets, simulation."""

import numpy as np
import pytest
from scipy.signal import cont2discrete

from attend._validation import AttendInputError
from attend.models.linear import LinearSystem, ModelWarning, simulate
from attend.models.problems import convolution_model, mass_spring_damper, quadrotor_roll


def test_zero_order_hold_matches_scipy():
    system = convolution_model()
    Ad, Bd = system.discretize(0.1)
    reference = cont2discrete((system.A, system.B, system.C, np.zeros((4, 1))), 0.1, method="zoh")
    np.testing.assert_allclose(Ad, reference[0], atol=1e-14)
    np.testing.assert_allclose(Bd, reference[1], atol=1e-14)


def test_double_integrator_hold_closed_form():
    Ad, Bd = LinearSystem([[0, 1], [0, 0]], [[0], [1]], [[1, 0]]).discretize(0.2)
    np.testing.assert_allclose(Ad, [[1, 0.2], [0, 1]], atol=1e-15)
    np.testing.assert_allclose(Bd, [[0.02], [0.2]], atol=1e-15)


def test_mass_spring_damper_parameters():
    system = mass_spring_damper()
    theta = np.concatenate([system.A.ravel(), system.B.ravel(), system.C.ravel()])
    np.testing.assert_allclose(theta, [0, 1, -0.5714, -0.2857, 0, 0.7143, 1, 0], atol=5e-5)


def test_simulation_without_noise_follows_the_recursion():
    system = mass_spring_damper()
    dt = 0.1
    u = np.exp(-0.25 * (np.arange(100) * dt - 5) ** 2)[:, None]
    log = simulate(system, u, dt, kernel_width=0.5, seed=0)
    Ad, Bd = system.discretize(dt)
    np.testing.assert_allclose(log.states[50], Ad @ log.states[49] + Bd @ u[49], atol=1e-14)
    np.testing.assert_allclose(log.outputs[:, 0], log.states[:, 0])


def test_bad_systems_name_the_field():
    with pytest.raises(AttendInputError, match="A: expected a square"):
        LinearSystem(np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((1, 2)))
    with pytest.raises(AttendInputError, match="B: expected 2 rows"):
        LinearSystem(np.eye(2), np.zeros((3, 1)), np.zeros((1, 2)))
    with pytest.raises(AttendInputError, match="C: expected 2 columns"):
        LinearSystem(np.eye(2), np.zeros((2, 1)), np.zeros((1, 3)))
    with pytest.raises(AttendInputError, match="A: expected finite"):
        LinearSystem([[np.nan, 0], [0, 1]], np.zeros((2, 1)), np.zeros((1, 2)))


def test_unstable_and_unobservable_models_warn():
    with pytest.warns(ModelWarning, match="A is unstable"):
        LinearSystem([[0.5, 0], [0, -1]], [[1], [1]], [[1, 1]]).check()
    with pytest.warns(ModelWarning, match="unobservable"):
        LinearSystem([[-1, 0], [0, -2]], [[1], [1]], [[1, 0]]).check()
    assert convolution_model().check() == []
    assert quadrotor_roll().check() == []  # a double integrator is marginally stable: no warning
    assert quadrotor_roll().is_observable()


def test_text_and_repeated_names_are_errors_not_coerced():
    with pytest.raises(AttendInputError, match="A: expected a matrix of numbers, got '0'"):
        LinearSystem([["0", 1], [0, 0]], [[0], [1]], [[1, 0]])
    with pytest.raises(AttendInputError, match="B: expected a matrix of numbers, got True"):
        LinearSystem(np.eye(2), [[True], [1]], [[1, 0]])
    with pytest.raises(AttendInputError, match="state_names: the name 'phi' appears twice"):
        LinearSystem(np.eye(2), np.zeros((2, 1)), [[1, 0]], state_names=("phi", "phi"))


def test_simulate_accepts_a_python_control_statespace():
    control = pytest.importorskip("control")
    system = mass_spring_damper()
    u = np.ones((20, 1))
    direct = simulate(system, u, 0.1, kernel_width=0.2)
    converted = simulate(control.ss(system.A, system.B, system.C, 0), u, 0.1, kernel_width=0.2)
    np.testing.assert_allclose(converted.outputs, direct.outputs)
    with pytest.raises(AttendInputError, match="attend.models.from_statespace"):
        simulate("mass-spring-damper", u, 0.1, kernel_width=0.2)
