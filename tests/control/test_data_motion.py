"""data_motion="generalised": within a sample the data y~ and the prior eta~ move with their own generalised motion
(y~(t) = expm(D t) y~[k], spm_DEM's dy~/dt = D y~), instead of being held at the sample's values."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm

from attend import AttendInputError
from attend.control import ActiveInferenceController, GenerativeModel, markov_parameters
from attend.control._core import discrete_transition, moving_data_transition


def _shift(P, m):
    return np.kron(np.eye(P, k=1), np.eye(m))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_moving_data_transition_is_the_integral_of_the_flow_against_the_moving_data(seed):
    """Gamma_y = int_0^dt expm(J (dt - t)) K_y expm(D_y t) dt (and so for eta~), by adaptive quadrature; the state
    transition and int_0^dt expm(J t) dt are discrete_transition's."""
    rng = np.random.default_rng(seed)
    N, P, m, Q, r, dt = 7, 3, 2, 2, 1, 0.05
    J = rng.standard_normal((N, N)) - 2 * np.eye(N)
    K_y, K_eta = rng.standard_normal((N, P * m)), rng.standard_normal((N, Q * r))
    transition, integral, Gamma_y, Gamma_eta = moving_data_transition(J, K_y, K_eta, P, m, Q, r, dt)
    expected_transition, expected_integral = discrete_transition(J, dt)
    np.testing.assert_allclose(transition, expected_transition, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(integral, expected_integral, rtol=1e-12, atol=1e-14)
    for K, D, Gamma in ((K_y, _shift(P, m), Gamma_y), (K_eta, _shift(Q, r), Gamma_eta)):
        expected, _ = quad_vec(lambda t, K=K, D=D: expm(J * (dt - t)) @ K @ expm(D * t), 0.0, dt, epsabs=1e-15,
                               epsrel=1e-12)
        np.testing.assert_allclose(Gamma, expected, rtol=1e-10, atol=1e-14)


def test_without_higher_orders_the_moving_data_are_the_held_data():
    """One order of motion (P = Q = 1): D = 0, so Gamma_y = int_0^dt expm(J t) dt K_y exactly as for held data."""
    rng = np.random.default_rng(3)
    J = rng.standard_normal((5, 5)) - 3 * np.eye(5)
    K_y, K_eta = rng.standard_normal((5, 2)), rng.standard_normal((5, 1))
    _, integral, Gamma_y, Gamma_eta = moving_data_transition(J, K_y, K_eta, 1, 2, 1, 1, 0.01)
    np.testing.assert_allclose(Gamma_y, integral @ K_y, rtol=1e-13, atol=1e-16)
    np.testing.assert_allclose(Gamma_eta, integral @ K_eta, rtol=1e-13, atol=1e-16)


DT, SLOPE = 0.01, 0.7


def _ramp_agent(data_motion):
    """x' = v, y = x, the prior v = SLOPE: the belief x = SLOPE t, x' = v = SLOPE fulfils every prediction on the data
    y = SLOPE t (errors all zero), so the action (moving y') stays at rest."""
    model = GenerativeModel.linear([[0.0]], [[1.0]], [[1.0]], sensor_precision=1e4, process_precision=1e2,
                                   cause_prior_precision=1e2, cause_prior=[SLOPE], kernel_width=0.05,
                                   embedding_order=1, cause_order=1, initial_states=[0.0])
    G = markov_parameters(np.zeros((1, 1)), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)), 2, hold=DT)
    return ActiveInferenceController(model, DT, action_gain=10.0, action_jacobian=G, sensory_orders=1,
                                     data_motion=data_motion)


def test_a_belief_on_a_ramp_stays_on_it_when_the_data_move_and_lags_a_sample_when_they_are_held():
    """The data y[k] = SLOPE t_k, exact (no noise). Each step integrates the beliefs over [t_k, t_k + dt]: with the
    data moving (y(t) = y[k] + y'[k] (t - t_k)) the ramp is a fixed trajectory of the joint flow, and from any start
    the belief converges to it, ending each step at SLOPE t_(k+1) with the action at rest (every error zero). With the
    data held at y[k], the belief at t_k + dt is pulled back to y[k]: it ends each step one sample behind (measured
    0.99 SLOPE dt), and the action keeps integrating the error that this lag leaves."""
    lag, drift = {}, {}
    for motion in ("held", "generalised"):
        agent = _ramp_agent(motion)
        actions = [agent.step([SLOPE * k * DT])[0] for k in range(400)]
        lag[motion] = SLOPE * 400 * DT - agent.states[0]
        drift[motion] = actions[-1] - actions[-101]
    assert abs(lag["generalised"]) < 1e-12 and abs(drift["generalised"]) < 1e-9  # measured 4e-16 and 3e-12
    assert 0.9 * SLOPE * DT < lag["held"] < SLOPE * DT  # measured 0.99 SLOPE dt
    assert abs(drift["held"]) > 1e-3  # measured 0.012 over the last 100 samples


def test_moving_data_costs_nothing_per_sample_on_the_linear_step():
    """The motion is folded into the cached transition: both variants take the same two products per sample, and the
    generalised variant's Gamma_y differs from the held one's."""
    held, moving = _ramp_agent("held"), _ramp_agent("generalised")
    _, Gy_held, _, _ = held.linear_update()
    Phi_m, Gy_moving, _, _ = moving.linear_update()
    assert Gy_held.shape == Gy_moving.shape and not np.allclose(Gy_held, Gy_moving)
    np.testing.assert_array_equal(Phi_m, held.linear_update()[0])


def test_data_motion_is_checked():
    with pytest.raises(AttendInputError, match="data_motion"):
        _ramp_agent("moving")
    model = GenerativeModel(f=lambda x, v: v - x**3, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            embedding_order=1, cause_order=1)
    with pytest.raises(AttendInputError, match="data_motion: 'generalised' needs the exact linear step"):
        ActiveInferenceController(model, DT, action_jacobian=np.array([[0.0], [1.0]]), data_motion="generalised")
