"""integration="spm" (spm_ADEM / spm_ALAP's D-step in the active-inference controller): the data and the prior move
with their generalised motion within the sample, for any model, and the cause prior is weighed by the top-left block
of S(s) at p + 1 orders. The general step's joint integration of [Z; y~; eta~] is checked against the exact linear
step of the same flow (attend.control._core.moving_data_transition), which tests/control/test_data_motion.py checks
against quadrature."""

from __future__ import annotations

import numpy as np
import pytest

from attend import AttendInputError
from attend.control import ActiveInferenceController, GenerativeModel, GenerativeProcess, markov_parameters
from attend.models.generalized import smoothness_precision

DT = 0.05


def _model(precision, cause_order=1):
    """x' = A x + B v, y = C x with a moving intention: GenerativeModel.linear with a constant sensor precision (the
    exact linear step), or the same f, g given as functions with the precision as a function returning that constant
    (the general step, re-linearised every sample)."""
    A, B, C = np.array([[-0.5, 1.0], [0.0, -1.0]]), np.array([[0.0], [1.0]]), np.eye(2)
    options = dict(process_precision=np.exp(4), cause_prior_precision=np.exp(2), kernel_width=0.5, embedding_order=3,
                   cause_order=cause_order,
                   cause_prior=lambda t: np.array([np.sin(t), np.cos(t), -np.sin(t), -np.cos(t)])[: cause_order + 1])
    if not callable(precision):
        return GenerativeModel.linear(A, B, C, sensor_precision=precision, **options)
    return GenerativeModel(f=lambda x, v: A @ x + B @ v, g=lambda x, v: C @ x, n_states=2, n_causes=1, n_outputs=2,
                           jacobian_f=lambda x, v: (A, B), jacobian_g=lambda x, v: (C, np.zeros((2, 1))),
                           sensor_precision=precision, **options)


def _agent(model, **options):
    G = markov_parameters(np.array([[-0.5, 1.0], [0.0, -1.0]]), np.array([[1.0], [0.5]]), np.eye(2),
                          np.zeros((2, 1)), 4)
    return ActiveInferenceController(model, DT, action_gain=2.0, action_jacobian=G, action_prior_precision=0.1,
                                     sensory_orders="all", **options)


@pytest.mark.parametrize("cause_order", [1, 3])
def test_general_step_with_moving_data_is_the_exact_linear_step(cause_order):
    """The same linear model stepped by the exact linear recurrence (constant precision) and by the general step
    (precision given as a function of the state, so re-linearised every sample; its gradient is zero): with
    integration="spm" both integrate [Z; y~; eta~] jointly over the sample and agree to rounding (observed ~1e-13)."""
    precision = np.array([np.exp(3.0), np.exp(2.0)])
    fast = _agent(_model(precision, cause_order), integration="spm")
    general = _agent(_model(lambda x, v: precision, cause_order), integration="spm")
    assert fast._fast and not general._fast
    rng = np.random.default_rng(0)
    for k in range(200):
        y = np.array([np.sin(0.3 * k * DT), np.cos(0.2 * k * DT)]) + 0.01 * rng.standard_normal(2)
        a_fast, a_general = fast.step(y), general.step(y)
        np.testing.assert_allclose(general.generalised_states, fast.generalised_states, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(a_general, a_fast, rtol=1e-9, atol=1e-11)
    # and the moving data matter: the held data give another trajectory
    held = _agent(_model(lambda x, v: precision, cause_order))
    for k in range(200):
        held.step(np.array([np.sin(0.3 * k * DT), np.cos(0.2 * k * DT)]))
    assert np.abs(held.generalised_states - general.generalised_states).max() > 1e-4


def test_spm_cause_prior_precision_is_the_top_left_block_of_S_at_p_plus_1_orders():
    model = _model(np.array([1.0, 2.0]), cause_order=1)
    P, Q = 4, 2
    spm, own = _agent(model, integration="spm"), _agent(model)
    S_P, S_Q = smoothness_precision(P, 0.5), smoothness_precision(Q, 0.5)
    np.testing.assert_allclose(spm._Pi_v, np.exp(2) * S_P[:Q, :Q], rtol=1e-14)
    np.testing.assert_allclose(own._Pi_v, np.exp(2) * S_Q, rtol=1e-14)
    assert not np.allclose(S_P[:Q, :Q], S_Q)  # the two conventions differ (S_P's block is not S_Q)
    # with d = p both conventions are S(s) at p + 1 orders: then "spm" is data_motion="generalised"
    square = _model(np.array([1.0, 2.0]), cause_order=3)
    Phi_spm, Gy_spm, _, _ = _agent(square, integration="spm").linear_update()
    Phi_gen, Gy_gen, _, _ = _agent(square, data_motion="generalised").linear_update()
    np.testing.assert_array_equal(Phi_spm, Phi_gen)
    np.testing.assert_array_equal(Gy_spm, Gy_gen)


def test_integration_is_checked():
    model = _model(np.array([1.0, 2.0]))
    with pytest.raises(AttendInputError, match="integration: expected 'attend' or 'spm'"):
        _agent(model, integration="octave")


def test_generalised_output_of_a_linear_world_is_its_markov_chain():
    """y~ = [C x + D a; C (A x + B a); C A (A x + B a); ...] with the action held."""
    A, B = np.array([[-0.3, 1.0], [-1.0, -0.2]]), np.array([[0.0], [2.0]])
    C, D = np.array([[1.0, 0.5]]), np.array([[0.1]])
    world = GenerativeProcess.linear(A, B, C, D)
    x, a = np.array([0.4, -1.2]), np.array([0.7])
    motion = A @ x + B @ a
    expected = [C @ x + D @ a]
    for _ in range(3):
        expected.append(C @ motion)
        motion = A @ motion
    np.testing.assert_allclose(world.generalised_output(x, a, 3), np.concatenate(expected), rtol=1e-14)


def _noiseless_loop_pair(gain, growth=-0.5):
    """A noiseless linear world (the model's own with growth = -0.5; > 0 an unstable world) and an agent with
    integration="spm" driving it."""
    A, B, C = np.array([[growth, 1.0], [0.0, -1.0]]), np.array([[1.0], [0.5]]), np.eye(2)
    world = GenerativeProcess.linear(A, B, C)
    agent = ActiveInferenceController(_model(np.array([1.0, 2.0])), DT, action_gain=gain,
                                      action_jacobian=markov_parameters(A, B, C, np.zeros((2, 1)), 4),
                                      action_prior_precision=0.1, sensory_orders="all", integration="spm")
    return world, agent


def test_generalised_loop_records_each_bin_start_and_end():
    """Row 0 of the beliefs and actions is the start, row k + 1 the end of bin k; the world's state of bin k + 1
    follows from bin k's state under the action delivered in bin k (the world stepped apart, action held)."""
    from attend.control import run_generalised
    from attend.models.linear import zero_order_hold

    world, agent = _noiseless_loop_pair(gain=1.0)
    loop = run_generalised(world, agent, 1.0, seed=0)
    n = int(round(1.0 / DT))
    assert loop.states.shape == (n, 2) and loop.belief_states.shape == (n + 1, 2) and loop.actions.shape == (n + 1, 1)
    agent.reset()
    np.testing.assert_array_equal(loop.belief_states[0], agent.states)
    np.testing.assert_array_equal(loop.actions[0], np.zeros(1))
    A, B, _, _ = world.matrices
    Ad, Bd = zero_order_hold(A, B, DT)
    predicted = loop.states[:-1] @ Ad.T + loop.actions[1:-1] @ Bd.T
    np.testing.assert_allclose(loop.states[1:], predicted, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(loop.time, np.arange(n) * DT)


def test_generalised_loop_stops_a_diverging_world_and_names_the_gain():
    from attend.control import ClosedLoopDivergence
    from attend.control import run_generalised

    world, agent = _noiseless_loop_pair(gain=0.01, growth=2.0)
    with pytest.raises(ClosedLoopDivergence, match="the world diverged at t = .*action_gain kappa = 0.01"):
        run_generalised(world, agent, 20.0, seed=0, divergence_limit=1e3)


def test_generalised_loop_needs_an_active_inference_controller():
    from attend.control import PIDController
    from attend.control import run_generalised

    world, _ = _noiseless_loop_pair(gain=1.0)
    with pytest.raises(AttendInputError, match="controller: expected an attend.control.ActiveInferenceController"):
        run_generalised(world, PIDController(1.0, 0.0, 0.0, DT), 1.0)


def test_generalised_loop_refuses_a_world_with_other_outputs():
    from attend.control import run_generalised

    _, agent = _noiseless_loop_pair(gain=1.0)
    world = GenerativeProcess.linear(np.array([[-0.5, 1.0], [0.0, -1.0]]), np.array([[1.0], [0.5]]),
                                     np.array([[1.0, 0.0]]))
    with pytest.raises(AttendInputError, match="model.n_outputs: the model predicts 2 outputs, the process gives "
                                               "n_outputs = 1"):
        run_generalised(world, agent, 1.0)
