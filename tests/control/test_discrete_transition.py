"""The exact step of a linear flow, (E, F) = (expm(J dt), int_0^dt expm(J t) dt) (control._exponential.
exponential_and_integral, N x N products, E - I squared), against closed forms and against the computation it
replaces: scipy.linalg.expm of the 2N x 2N block [[J, I], [0, 0]] dt (discrete_transition_reference below).

Tolerances. Both are backward stable: each computes the exponential of the block plus dA with |dA|_1 <= u |A|_1
(u = 2^-53, A = J dt, before the rounding of the products), and the block's exponential [[E, F], [0, I]] has norm at
least 1, so each lies within about u |A|_1 (the exponential's relative condition, |A| for a normal A) of it, relative
to max(1, |E|) for E and to |F| for F. Hence |new - scipy| <= 64 u max(1, |A|_1) here (32 u for the local-linearisation
step's exponential, test_relinearised_step.py). Within that bound the two differ where J is stiff (a fast mode forces
s squarings, |A|_1 = 1.3e9 and s = 29 on the two-link arm): scipy squares E = I + (small), whose slow modes carry a
relative error u into each squaring, 2^s u after s (6e-8 at s = 29); squaring E - I keeps a slow mode's accuracy to
a few u whatever s (the block test below; 3e-10 against a 60-digit mpmath exponential of the arm's J, scipy 2e-8,
and a relative change of one ulp in J's entries moves E by 2e-10 to 1e-9 there: the data's own condition)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm, hadamard

from attend.control import ActiveInferenceController, GenerativeModel, arm, markov_parameters, run
from attend.control import controller as controller_module
from attend.control._core import (
    discrete_transition,
    error_jacobian,
    joint_system,
    shift_matrix,
)
from attend.control._exponential import UNIT_ROUNDOFF, exponential_and_integral
from attend.models.generalized import smoothness_precision

def discrete_transition_reference(J: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """discrete_transition as scipy.linalg.expm of the 2N x 2N block [[J, I], [0, 0]] dt (the definition, the
    computation discrete_transition replaced: slower, and less accurate when J dt is stiff)."""
    N = J.shape[0]
    block = np.zeros((2 * N, 2 * N))
    block[:N, :N] = J * dt
    block[:N, N:] = np.eye(N) * dt
    full = expm(block)
    return full[:N, :N], full[:N, N:]


DT = 2.0**-7  # a power of two: J dt is exact

#: lambda dt of a Hadamard-mixed 16 x 16 test matrix: dyadic, from -2^30 to 2^-4 (two growing modes, one at 0), so
#: that Q diag(lambda) Q' (Q = H / 4, orthogonal in floats) is exact and the closed forms are of the matrix given
SPECTRUM = -np.array([2.0**30, 2.0**20, 2.0**12, 2.0**6, 2.0**3, 1.0, 2.0**-2, 2.0**-5, 2.0**-8, 2.0**-11, 2.0**-14,
                      2.0**-17, 2.0**-18, 0.0, -2.0**-4, -2.0**-10])


def _closed_form(Q, spectrum):
    """(Q e^x Q', Q (dt phi_1(x)) Q') for x = lambda dt: E and F of J = Q diag(lambda) Q', phi_1(x) = (e^x - 1) / x."""
    lam = spectrum / DT
    integral = np.full_like(spectrum, DT)
    nonzero = spectrum != 0
    integral[nonzero] = np.expm1(spectrum[nonzero]) / lam[nonzero]
    return (Q * np.exp(spectrum)) @ Q.T, (Q * integral) @ Q.T


def _relative_errors(E, F, E_exact, F_exact):
    """(|dE| / max(1, |E|), |dF| / |F|) in the largest entries."""
    return (np.abs(E - E_exact).max() / max(1.0, np.abs(E_exact).max()),
            np.abs(F - F_exact).max() / np.abs(F_exact).max())


def _norm(J):
    return float(np.abs(J * DT).sum(axis=0).max())


@pytest.mark.parametrize("scale", [2.0**-40, 2.0**-30, 2.0**-28, 2.0**-25, 2.0**-20, 2.0**-10, 1.0])
def test_a_normal_matrix_mixing_all_its_modes_agrees_with_its_closed_form(scale):
    # |A|_1 from 1e-3 (no squaring) to 1.1e9 (29 squarings): every entry mixes every mode, so both methods come near
    # the bound u |A|_1 (measured <= 0.33 u max(1, |A|_1), at |A|_1 <= 1 the oracle's own rounding; scipy's Pade of the
    # 2N block up to 0.38 u |A|_1, and 7 u at |A|_1 = 1)
    Q = hadamard(16) / 4.0
    spectrum = SPECTRUM * scale
    J = (Q * (spectrum / DT)) @ Q.T
    assert np.array_equal(Q.T @ J @ Q, np.diag(spectrum / DT))  # exact: the closed form is of this J
    E, F = exponential_and_integral(J, DT)
    error_E, error_F = _relative_errors(E, F, *_closed_form(Q, spectrum))
    assert max(error_E, error_F) <= 4 * UNIT_ROUNDOFF * max(1.0, _norm(J))


@pytest.mark.parametrize("stiffness", [2.0**-2, 2.0**10, 2.0**20, 2.0**30])
def test_a_stiff_mode_beside_slow_ones_costs_the_slow_ones_no_accuracy(stiffness):
    # J = blkdiag(-stiffness / dt, slow 16 x 16 block): the stiff mode sets s (0, 9, 19, 29 squarings); the slow
    # block stays within a few u of its closed form (measured <= 2.4 u, the oracle's rounding), where scipy's Pade of
    # the 2N block loses 2^s u (measured 5e7 u at s = 29); the stiff mode's own E and F to rounding
    Q = hadamard(16) / 4.0
    slow = np.concatenate([SPECTRUM[5:], -2.0**-3 * np.arange(1, 6)])
    J = np.zeros((17, 17))
    J[0, 0] = -stiffness / DT
    J[1:, 1:] = (Q * (slow / DT)) @ Q.T
    E, F = exponential_and_integral(J, DT)
    error_E, error_F = _relative_errors(E[1:, 1:], F[1:, 1:], *_closed_form(Q, slow))
    assert max(error_E, error_F) <= 8 * UNIT_ROUNDOFF
    assert E[0, 0] == pytest.approx(math.exp(-stiffness), rel=8 * UNIT_ROUNDOFF, abs=0.0)
    assert F[0, 0] == pytest.approx(-math.expm1(-stiffness) * DT / stiffness, rel=8 * UNIT_ROUNDOFF, abs=0.0)
    assert not E[0, 1:].any() and not E[1:, 0].any() and not F[0, 1:].any() and not F[1:, 0].any()


@pytest.mark.parametrize("lam", [-1e11, -1e3, -1.0, -1e-9, 0.0, 1e-9, 3.0, 300.0])
def test_scalar_flow_equals_exp_and_expm1(lam):
    # E = 1 + (E - 1): a mode decayed within dt keeps u of the block's norm (>= 1), not of its own size (e^-10:
    # 6e-17 off, 1.3e-12 of itself); F, a product of the H_i, keeps u of its own size
    E, F = exponential_and_integral(np.array([[lam]]), 0.01)
    x = lam * 0.01
    assert E[0, 0] == pytest.approx(math.exp(x), rel=16 * UNIT_ROUNDOFF, abs=16 * UNIT_ROUNDOFF)
    assert F[0, 0] == pytest.approx(0.01 if x == 0 else math.expm1(x) / lam, rel=16 * UNIT_ROUNDOFF, abs=0.0)


def test_zero_flow_holds_the_state_and_integrates_the_constant():
    E, F = exponential_and_integral(np.zeros((5, 5)), 0.02)
    np.testing.assert_array_equal(E, np.eye(5))
    np.testing.assert_array_equal(F, 0.02 * np.eye(5))


def test_a_non_finite_jacobian_gives_nan():
    J = np.eye(4)
    J[1, 2] = np.nan
    assert all(np.isnan(block).all() for block in exponential_and_integral(J, 0.01))
    J[1, 2] = np.inf
    assert all(np.isnan(block).all() for block in exponential_and_integral(J, 0.01))


def _controller_jacobian(rng):
    """J of :func:`joint_system` for random sizes, Jacobians, dy~/da and precisions (Pi_y up to 1e7 kron S(s), s down
    to 3 ms: stiff as the controllers' J)."""
    n, r, m, k = (int(value) for value in rng.integers(1, 5, 4))
    r -= 1
    P, Q = int(rng.integers(1, 4)), int(rng.integers(1, 3))
    fx, fv, gx, gv = (rng.normal(size=shape) for shape in ((n, n), (n, r), (m, n), (m, r)))
    kernel_width = 10 ** rng.uniform(-2.5, -0.5)
    scale = 10 ** rng.uniform(-2, 7)

    def spd(size, factor):
        root = rng.normal(size=(size, size))
        return (root @ root.T + size * np.eye(size)) * factor

    S_P, S_Q = smoothness_precision(P, kernel_width), smoothness_precision(Q, kernel_width)
    Pi_y, Pi_x, Pi_v = np.kron(S_P, spd(m, scale)), np.kron(S_P, spd(n, scale**0.5)), np.kron(S_Q, spd(r, 1.0))
    E_y, E_x, E_v = error_jacobian(fx, fv, gx, gv, P, Q)
    J, _, _, _ = joint_system(shift_matrix(P, n, Q, r), E_y, E_x, E_v, Pi_y, Pi_x, Pi_v, rng.normal(size=(P * m, k)),
                              Pi_y, float(np.exp(rng.uniform(-1, 6))), 1.0)
    return J


def test_controller_jacobians_agree_with_scipy_expm_of_the_block():
    # 60 joint flows, |J dt|_1 up to 2.5e7 (22 squarings); measured <= 4.7 u max(1, |A|_1) without squarings and
    # <= 19 u |A|_1 with: scipy's part (against a 50-digit mpmath exponential, in the three cases above 5 u |A|_1 ours
    # is within 4 u, scipy's Pade within 31, 39 and 78 u)
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(60):
        J = _controller_jacobian(rng)
        error_E, error_F = _relative_errors(*discrete_transition(J, 0.01), *discrete_transition_reference(J, 0.01))
        worst = max(worst, max(error_E, error_F) / max(1.0, float(np.abs(J * 0.01).sum(axis=0).max())))
    assert worst <= 64 * UNIT_ROUNDOFF


# --- the controller's trajectories against the previous computation (scipy's expm of the 2N block) ----------------

def _chain_controller():
    """The benchmark's 4-state chain (two masses, p = 4), linear with constant precision: one transition."""
    k1, k2, m1, m2, b = 1.0, 0.5, 1.0, 0.5, 0.3
    A = np.array([[0, 1, 0, 0], [-(k1 + k2) / m1, -b / m1, k2 / m1, 0], [0, 0, 0, 1],
                  [k2 / m2, 0, -k2 / m2, -b / m2]])
    B, C = np.array([[0.0], [1.0 / m1], [0.0], [0.0]]), np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    model = GenerativeModel.linear(A, B, C, sensor_precision=1e4, process_precision=1e2, cause_prior_precision=1e2,
                                   cause_prior=np.zeros(1), kernel_width=0.05, embedding_order=4, cause_order=1)
    G = markov_parameters(A, B, C, np.zeros((2, 1)), 5)
    return ActiveInferenceController(model, 0.01, action_gain=1.0, action_jacobian=G)


def test_chain_controller_actions_are_unchanged(monkeypatch):
    # the actions agree to 1e-12 of their largest (measured 1.6e-14)
    samples = 0.3 * np.sin(np.arange(400)[:, None] * 0.01 * np.array([1.0, 0.7]))
    new = np.array([_chain_controller().step(y) for y in samples])
    monkeypatch.setattr(controller_module, "discrete_transition", discrete_transition_reference)
    old = np.array([_chain_controller().step(y) for y in samples])
    assert np.abs(new - old).max() <= 1e-12 * np.abs(old).max()


def _arm_agent():
    """The arm benchmark's timed agent (w 11.5 rad/s, Pi_w 2.1e6, kappa 533, s 12.2 ms, dy~/da of the torque held
    over dt, refreshed when it moves by 2 %): |J dt|_1 = 1.3e9, s = 29."""
    target = np.array([-0.6, 0.8])
    prior = np.concatenate([target, np.zeros(10)])
    model = arm.critically_damped_model(11.5, sensor_std=0.002, process_precision=2.1e6, kernel_width=0.0122,
                                        cause_prior=lambda t: prior, initial_angles=(-math.pi / 2, 0.0),
                                        reference_acceleration=True)
    controller = ActiveInferenceController(
        model, 0.01, action_gain=533.0, n_actions=2, sensory_orders=2,
        action_jacobian=arm.ArmActionJacobian(arm.ArmParameters(), 2, tolerance=0.02, hold=0.01),
        action_limits=([-30.0, -10.0], [30.0, 10.0]))
    return arm.GravityFeedforward(controller, arm.ArmParameters(), "believed")


def test_arm_closed_loop_is_unchanged_to_the_rounding_of_the_stiff_transition(monkeypatch):
    # the transitions differ by scipy's 2^29 u error (2e-8 of E and F); the agent's action a+ = Phi_a Z + Gamma_y y~
    # + ... sums terms many times its size (|Phi_a| |Z| = 20 |a| at rest), fed back through the loop: the torques
    # differ by <= 1e-6 of the largest (measured 1.5e-7), the angles by <= 1e-7 (measured 3.3e-8)
    plant = arm.arm_plant(arm.ArmParameters(), initial_angles=(-math.pi / 2, 0.0), torque_limits=[30.0, 10.0])
    new = run(plant, _arm_agent(), 2.0, seed=0)
    monkeypatch.setattr(controller_module, "discrete_transition", discrete_transition_reference)
    old = run(plant, _arm_agent(), 2.0, seed=0)
    assert np.abs(new.actions - old.actions).max() <= 1e-6 * np.abs(old.actions).max()
    assert np.abs(new.states[:, :2] - old.states[:, :2]).max() <= 1e-7 * np.abs(old.states[:, :2]).max()
