"""The re-linearised (nonlinear) step in preallocated arrays (control._core.JointFlow) and its exponential
(control._exponential: Taylor series with scaling and squaring, last column only) against the computation they replace:
error_jacobian + joint_system + generalised_errors + scipy.linalg.expm of [[J dt, flow dt], [0, 0]].

Both exponentials are backward stable (relative backward error <= u = 2^-53 in |A|_1), so they differ by rounding times
the exponential's condition, which grows with |J dt|_1 (about 200 for the benchmark's 4-state model); the products of
J and the flow differ only in the order of their sums (a few u of the sums of absolute terms)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy.linalg import expm

from attend._validation import AttendInputError
from attend.control import ActiveInferenceController, GenerativeModel, markov_parameters
from attend.control._core import (
    JointFlow,
    error_jacobian,
    generalised_errors,
    joint_system,
    local_linearisation_step,
    sensory_precision,
    shift_matrix,
)
from attend.control._exponential import (
    UNIT_ROUNDOFF,
    AugmentedExponential,
    taylor_backward_error_bound,
    taylor_theta,
)
from attend.models.generalized import smoothness_precision

# --- the exponential ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("degree, published", [(3, 1.39e-5), (5, 2.40e-3), (8, 5.00e-2), (11, 2.14e-1),
                                               (15, 6.41e-1), (19, 1.26), (24, 2.22), (29, 3.31)])
def test_taylor_degrees_agree_with_the_published_backward_error_bounds(degree, published):
    # Al-Mohy & Higham (2011), SIAM J. Sci. Comput. 33(2), Table 3.1 (double): theta_m from the exact series of the
    # backward error; ours bounds |expm(-X)| by e^theta instead, so it is the same or slightly smaller (safe side)
    theta = taylor_theta(degree)
    assert theta <= published * 1.001
    assert theta == pytest.approx(published, rel=0.01)
    assert taylor_backward_error_bound(theta, degree) <= UNIT_ROUNDOFF
    assert taylor_backward_error_bound(theta * (1 + 1e-9), degree) > UNIT_ROUNDOFF  # the largest such theta


def _phi1(values):
    """(e^x - 1) / x, 1 at 0, without cancellation."""
    values = np.asarray(values, dtype=float)
    out = np.ones_like(values)
    nonzero = values != 0
    out[nonzero] = np.expm1(values[nonzero]) / values[nonzero]
    return out


@pytest.mark.parametrize("largest", [0.0, 1e-6, 1e-3, 0.1, 0.6, 1.2, 2.0, 3.0, 10.0, 200.0, 2000.0])
def test_last_column_of_a_symmetric_matrix_equals_its_eigendecomposition(largest):
    # A = [[B, c], [0, 0]], B = Q diag(lambda) Q' symmetric: expm(A)[:-1, -1] = Q phi_1(lambda) Q' c exactly; from
    # |A|_1 = 0 (degree 3, no squaring) through every degree to 14 squarings
    rng = np.random.default_rng(int(largest * 10) + 1)
    size = 23
    Q, _ = np.linalg.qr(rng.normal(size=(size, size)))
    spectrum = -largest * rng.uniform(0.0, 1.0, size)
    spectrum[0] = -largest
    spectrum[1] = min(largest, 1.0) * 0.5  # one growing mode
    B = (Q * spectrum) @ Q.T
    c = rng.normal(size=size) * 50.0  # a column larger than B: scaled by a power of two first
    A = np.zeros((size + 1, size + 1))
    A[:size, :size], A[:size, size] = B, c
    exact = Q @ (_phi1(spectrum) * (Q.T @ c))
    column = AugmentedExponential(size + 1).last_column(A)
    assert column[-1] == 1.0
    # for a normal B the relative condition of phi_1(B) c is about |B|; the oracle's own rounding (Q products) is a
    # few u; measured <= 6.6 u max(1, |B|) relative to the largest entry
    scale = np.abs(exact).max()
    assert np.abs(column[:-1] - exact).max() <= 32 * UNIT_ROUNDOFF * max(1.0, largest) * scale


def test_last_column_equals_scipy_expm_on_random_stable_matrices():
    rng = np.random.default_rng(5)
    exponential = AugmentedExponential(24)
    worst = 0.0
    for _ in range(200):
        B = rng.normal(size=(23, 23)) / math.sqrt(23)
        B -= 1.2 * np.abs(np.linalg.eigvals(B).real).max() * np.eye(23)
        B *= 10 ** rng.uniform(-3, 2.3)  # |B|_1 from 1e-3 to ~500
        A = np.zeros((24, 24))
        A[:23, :23], A[:23, 23] = B, rng.normal(size=23) * 10 ** rng.uniform(-3, 3)
        reference = expm(A)[:23, 23]
        difference = np.abs(exponential.last_column(A)[:23] - reference).max() / np.abs(reference).max()
        worst = max(worst, difference / max(1.0, np.abs(B).sum(axis=0).max()))
    # both backward stable: the difference is rounding times the condition (~|B|_1); measured 1.2e-15 |B|_1 (against
    # a 40-digit mpmath exponential, the larger part of it was scipy's Pade approximant's)
    assert worst <= 1e-14


def test_last_column_of_a_non_finite_matrix_is_none():
    A = np.zeros((4, 4))
    A[0, 1] = np.nan
    assert AugmentedExponential(4).last_column(A) is None
    A[0, 1] = np.inf
    assert AugmentedExponential(4).last_column(A) is None


# --- the joint flow ----------------------------------------------------------------------------------------------

def _random_problem(seed, n, r, m, k, P, Q, action_precision=False):
    rng = np.random.default_rng(seed)
    fx, fv, gx, gv = (rng.normal(size=shape) for shape in ((n, n), (n, r), (m, n), (m, r)))
    G = rng.normal(size=(P * m, k))
    G[rng.random(G.shape) < 0.3] = 0.0
    S_P, S_Q = smoothness_precision(P, 0.3), smoothness_precision(Q, 0.3)

    def spd(size):
        root = rng.normal(size=(size, size))
        return root @ root.T + size * np.eye(size)

    Pi_y, Pi_x, Pi_v = np.kron(S_P, spd(m)), np.kron(S_P, spd(n)), np.kron(S_Q, spd(r))
    Pi_a = np.kron(S_P, spd(m)) if action_precision else None
    nX = P * n + Q * r
    Z = rng.normal(size=nX + k)
    return dict(jacobians=(fx, fv, gx, gv), G=G, Pi=(Pi_y, Pi_x, Pi_v), Pi_a=Pi_a, Z=Z, y=rng.normal(size=P * m),
                eta=rng.normal(size=Q * r), f0=rng.normal(size=n), g0=rng.normal(size=m),
                gain=float(np.exp(rng.uniform(-1, 3))), prior=float(rng.uniform(0, 2)))


@pytest.mark.parametrize("n, r, m, k, P, Q, action_precision", [
    (4, 1, 2, 1, 5, 2, False), (2, 0, 1, 1, 3, 2, False), (3, 2, 2, 2, 2, 4, True), (1, 3, 3, 2, 4, 4, False),
    (2, 1, 2, 1, 1, 1, True), (3, 1, 1, 3, 3, 1, False)])
def test_joint_flow_equals_error_jacobian_joint_system_and_generalised_errors(n, r, m, k, P, Q, action_precision):
    p = _random_problem(n + 10 * P + 100 * Q, n, r, m, k, P, Q, action_precision)
    fx, fv, gx, gv = p["jacobians"]
    Pi_y, Pi_x, Pi_v = p["Pi"]
    Pi_a = Pi_y if p["Pi_a"] is None else p["Pi_a"]
    D = shift_matrix(P, n, Q, r)
    dt = 0.01
    # the previous computation
    E_y, E_x, E_v = error_jacobian(fx, fv, gx, gv, P, Q)
    J_old, _, _, _ = joint_system(D, E_y, E_x, E_v, Pi_y, Pi_x, Pi_v, p["G"], Pi_a, p["gain"], p["prior"])
    nX, Z = P * n + Q * r, p["Z"]
    e_y, e_x, e_v = generalised_errors(Z[: P * n], Z[P * n: nX], p["y"], p["eta"], p["f0"], p["g0"], fx, fv, gx, gv,
                                       P, Q)
    flow_old = np.empty_like(Z)
    flow_old[:nX] = D @ Z[:nX] - (E_y.T @ (Pi_y @ e_y) + E_x.T @ (Pi_x @ e_x) + E_v.T @ (Pi_v @ e_v))
    flow_old[nX:] = -p["gain"] * (p["G"].T @ (Pi_a @ e_y) + p["prior"] * Z[nX:])
    step_old = local_linearisation_step(J_old, flow_old, dt)
    # the joint flow
    joint = JointFlow(n, r, m, k, P, Q, D, Pi_x, Pi_v, p["gain"], p["prior"], dt)
    joint.set_action_jacobian(p["G"])
    joint.set_sensory_precision(Pi_y, p["Pi_a"])
    joint.set_jacobians(fx, fv, gx, gv)
    J = joint.linearise()
    flow = joint.flow(Z, p["y"], p["eta"], p["f0"], p["g0"])
    step = joint.increment(flow)
    # the same sums in another order: a few u of the sums of absolute terms (bounded here by the largest entry times
    # the number of terms); measured <= 0.11 (J), 0.68 (e), 0.16 (flow) of these bounds
    terms = 2 * J.shape[0] + p["G"].shape[0]
    assert np.abs(J - J_old).max() <= 4 * terms * UNIT_ROUNDOFF * np.abs(J_old).max()
    errors = np.concatenate([e_y, e_x, e_v])
    assert np.abs(joint.errors - errors).max() <= 4 * UNIT_ROUNDOFF * (np.abs(errors).max() + np.abs(Z).max())
    assert np.abs(flow - flow_old).max() <= 4 * terms * UNIT_ROUNDOFF * np.abs(flow_old).max()
    # through the exponential: rounding times its condition (~|J dt|_1) on both sides; measured <= 9e-16
    condition = max(1.0, np.abs(J_old * dt).sum(axis=0).max())
    assert np.abs(step - step_old).max() <= 1e-14 * condition * np.abs(step_old).max()


# --- the controller's step against the previous computation ---------------------------------------------------------

def _previous_step(controller, G, y_t, eta, t):
    """The controller's re-linearised step as it was computed before JointFlow (error_jacobian, joint_system,
    generalised_errors, scipy's expm of the augmented joint flow), from its state now; no state changes."""
    c = controller
    n, r, m, P, Q = c._sizes
    model, Z = c.model, c._Z
    nX = P * n + Q * r
    x_t, v_t, a = Z[: P * n], Z[P * n: nX], Z[nX:]
    x0, v0 = x_t[:n], v_t[:r]
    fx, fv, gx, gv = model.jacobians(x0, v0)
    f0 = np.asarray(model.f(x0, v0), dtype=float).reshape(-1)
    g0 = np.asarray(model.g(x0, v0), dtype=float).reshape(-1)
    precision = c._precision(x0, v0, t)
    E_y, E_x, E_v = error_jacobian(fx, fv, gx, gv, P, Q)
    Pi_y = sensory_precision(c._S_by_order, c._orders, precision)
    Pi_a = Pi_y if c.action_precision is None else sensory_precision(c._S_by_order, c._orders, c.action_precision)
    J, _, _, _ = joint_system(c._D, E_y, E_x, E_v, Pi_y, c._Pi_x, c._Pi_v, G, Pi_a, c.action_gain,
                              c.action_prior_precision)
    e_y, e_x, e_v = generalised_errors(x_t, v_t, y_t, eta, f0, g0, fx, fv, gx, gv, P, Q)
    flow = np.empty_like(Z)
    flow[:nX] = c._D @ Z[:nX] - (E_y.T @ (Pi_y @ e_y) + E_x.T @ (c._Pi_x @ e_x) + E_v.T @ (c._Pi_v @ e_v))
    if c.precision_gradient and model.state_dependent_precision:
        flow[:nX] += c._precision_gradient(x0, v0, e_y, t)
    flow[nX:] = -c.action_gain * (G.T @ (Pi_a @ e_y) + c.action_prior_precision * a)
    return Z + local_linearisation_step(J, flow, c.dt), J


def _compare_every_step(controller, samples, change=None):
    """Run ``controller`` on ``samples``, comparing each sample's new state with :func:`_previous_step` from the same
    state; returns the largest difference relative to the step's size, over the exponential's condition."""
    worst = []
    general = controller._general_step

    def checked(G, y_t, eta, t):
        expected, J = _previous_step(controller, G, y_t, eta, t)
        Z = general(G, y_t, eta, t)
        size = np.abs(expected - controller._Z).max() + 1e-300
        condition = max(1.0, np.abs(J * controller.dt).sum(axis=0).max())
        worst.append(np.abs(Z - expected).max() / size / condition)
        return Z

    controller._general_step = checked
    for i, y in enumerate(samples):
        if change is not None and i == len(samples) // 2:
            change(controller)
        controller.step(y)
    return max(worst)


A4 = np.array([[0, 1, 0, 0], [-1.5, -0.3, 0.5, 0], [0, 0, 0, 1], [1.0, 0, -1.0, -0.6]])
B4 = np.array([[0.0], [1.0], [0.0], [0.0]])
C4 = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
BENCH_OPTIONS = dict(sensor_precision=1e4, process_precision=1e2, cause_prior_precision=1e2, cause_prior=np.zeros(1),
                     kernel_width=0.05, embedding_order=4, cause_order=1)


def _samples(count, m, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(count)[:, None] * 0.01
    return 0.3 * np.sin(t * np.linspace(1.0, 0.6, m)) + 1e-3 * rng.standard_normal((count, m))


# one sample's new state against the previous computation's, relative to the step |dZ| and over the exponential's
# condition |J dt|_1: rounding in the flow's sums and the exponentials; measured <= 1.4e-14 (a random model with its own
# action precision), 3.4e-16 on the benchmark's linear model written as nonlinear
STEP_TOLERANCE = 1e-13


def test_linear_model_written_as_nonlinear_steps_as_before():
    written = GenerativeModel(f=lambda x, v: A4 @ x + B4 @ v, g=lambda x, v: C4 @ x, n_states=4, n_causes=1,
                              n_outputs=2, jacobian_f=lambda x, v: (A4, B4),
                              jacobian_g=lambda x, v: (C4, np.zeros((2, 1))), **BENCH_OPTIONS)
    G = markov_parameters(A4, B4, C4, np.zeros((2, 1)), 5)
    controller = ActiveInferenceController(written, 0.01, action_gain=1.0, action_jacobian=G)
    assert _compare_every_step(controller, _samples(400, 2)) <= STEP_TOLERANCE


def _random_nonlinear_model(seed):
    """A stable random model with tanh, sine and cubic terms in f and g; analytic Jacobians or finite differences."""
    rng = np.random.default_rng(seed)
    # r >= 1: GenerativeModel(n_causes=0) fails in attend._validation.symmetric_matrix (max of an empty array)
    n, r, m = int(rng.integers(2, 5)), int(rng.integers(1, 3)), int(rng.integers(1, 4))
    A = rng.normal(size=(n, n)) * 0.5 - 1.5 * np.eye(n)
    B = rng.normal(size=(n, r))
    C = rng.normal(size=(m, n))
    D = rng.normal(size=(m, r)) * 0.3
    w = rng.uniform(0.2, 1.0, n)

    def f(x, v):
        return A @ x + B @ np.sin(v) - w * np.tanh(x) - 0.1 * x**3

    def g(x, v):
        return C @ x + 0.3 * np.sin(C @ x) + D @ v

    def jacobian_f(x, v):
        return A - np.diag(w / np.cosh(x) ** 2 + 0.3 * x**2), B * np.cos(v)

    def jacobian_g(x, v):
        return C + 0.3 * np.cos(C @ x)[:, None] * C, D

    analytic = bool(seed % 2)
    options = dict(sensor_precision=np.exp(rng.uniform(2, 8, m)), process_precision=np.exp(rng.uniform(0, 4)),
                   cause_prior_precision=np.exp(rng.uniform(0, 4)), cause_prior=rng.normal(size=r),
                   kernel_width=rng.uniform(0.02, 0.3), embedding_order=int(rng.integers(1, 5)),
                   cause_order=int(rng.integers(0, 3)), initial_states=rng.normal(size=n) * 0.3,
                   jacobian_f=jacobian_f if analytic else None, jacobian_g=jacobian_g if analytic else None)
    model = GenerativeModel(f=f, g=g, n_states=n, n_causes=r, n_outputs=m, **options)
    k = int(rng.integers(1, 3))
    Ba = rng.normal(size=(n, k))
    G = markov_parameters(A, Ba, C, np.zeros((m, k)), model.embedding_order + 1)
    extra = dict(action_prior_precision=float(rng.uniform(0, 1)))
    if seed % 3 == 0:
        extra["action_precision"] = np.exp(rng.uniform(2, 6, m))
    return model, G, extra


@pytest.mark.parametrize("seed", range(8))
def test_random_nonlinear_models_step_as_before(seed):
    model, G, extra = _random_nonlinear_model(seed)
    controller = ActiveInferenceController(model, 0.01, action_gain=float(np.exp(seed % 4)), action_jacobian=G,
                                           **extra)

    def change(c):  # settings changed between steps are read at the next sample, as before
        c.action_gain *= 3.0
        c.action_prior_precision += 0.5

    assert _compare_every_step(controller, _samples(200, model.n_outputs, seed), change) <= STEP_TOLERANCE


def test_state_dependent_precision_and_its_gradient_step_as_before():
    # the attenuation demo's agent: Pi_z(x, v), the precision gradient in the flow, and a process dy~/da
    from attend.control import attenuation

    world, controller = attenuation.build(2.0, "fixed reflex precision")
    rng = np.random.default_rng(3)
    samples = 0.2 + 0.01 * rng.standard_normal((300, 2))
    G = world.action_jacobian(world.initial_states, np.zeros(1), controller.model.embedding_order)
    worst = []
    general = controller._general_step

    def checked(G_, y_t, eta, t):
        expected, J = _previous_step(controller, G_, y_t, eta, t)
        Z = general(G_, y_t, eta, t)
        size = np.abs(expected - controller._Z).max()
        worst.append(np.abs(Z - expected).max() / size / max(1.0, np.abs(J * controller.dt).sum(axis=0).max()))
        return Z

    controller._general_step = checked
    for y in samples:
        controller.step(y, action_jacobian=G)
    assert max(worst) <= STEP_TOLERANCE


def test_a_non_finite_jacobian_is_named_by_the_step():
    model = GenerativeModel(f=lambda x, v: -x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            jacobian_f=lambda x, v: (np.array([[np.nan]]), np.zeros((1, 1))))
    controller = ActiveInferenceController(model, 0.01, action_jacobian=np.array([[1.0], [0.0], [0.0]]))
    with pytest.raises(AttendInputError, match=r"jacobian_f\(x, v\): d/dx holds non-finite values"):
        controller.step([0.1])


def test_a_copied_controller_steps_exactly_as_the_original():
    # the joint flow's views into its arrays are rebuilt in the copy (a copied view would be detached)
    model, G, extra = _random_nonlinear_model(1)
    controller = ActiveInferenceController(model, 0.01, action_jacobian=G, **extra)
    samples = _samples(60, model.n_outputs)
    for y in samples[:30]:
        controller.step(y)
    twin = copy.deepcopy(controller)
    for y in samples[30:]:
        np.testing.assert_array_equal(twin.step(y), controller.step(y))
    np.testing.assert_array_equal(twin._Z, controller._Z)
