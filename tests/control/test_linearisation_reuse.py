"""The general (nonlinear) step's speed-ups: error_jacobian built without kron against its kron definition, and
reuse of the last linearisation (jacobian_tolerance) against re-linearising every sample."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.control import ActiveInferenceController, GenerativeModel, markov_parameters
from attend.control._core import error_jacobian, error_jacobian_reference

A = np.array([[0, 1, 0, 0], [-1.5, -0.3, 0.5, 0], [0, 0, 0, 1], [1.0, 0, -1.0, -0.6]])
B = np.array([[0.0], [1.0], [0.0], [0.0]])
C = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
OPTIONS = dict(sensor_precision=1e4, process_precision=1e2, cause_prior_precision=1e2, cause_prior=np.zeros(1),
               kernel_width=0.05, embedding_order=4, cause_order=1)
G = markov_parameters(A, B, C, np.zeros((2, 1)), 5)


@pytest.mark.parametrize("n, r, m, P, Q", [(4, 1, 2, 5, 2), (2, 0, 1, 3, 2), (3, 2, 2, 2, 4), (1, 3, 3, 4, 4)])
def test_error_jacobian_equals_its_kron_definition(n, r, m, P, Q):
    rng = np.random.default_rng(n + 10 * P)
    fx, fv, gx, gv = (rng.normal(size=shape) for shape in ((n, n), (n, r), (m, n), (m, r)))
    for fast, slow in zip(error_jacobian(fx, fv, gx, gv, P, Q), error_jacobian_reference(fx, fv, gx, gv, P, Q)):
        assert np.array_equal(fast, slow)  # the same numbers placed, no arithmetic: exact


def _signals(n=400):
    rng = np.random.default_rng(0)
    t = np.arange(n)[:, None] * 0.01
    return 0.3 * np.sin(t * np.array([1.0, 0.7])) + 1e-3 * rng.standard_normal((n, 2))


def _actions(model, **options):
    controller = ActiveInferenceController(model, 0.01, action_gain=1.0, action_jacobian=G, **options)
    return np.array([controller.step(y) for y in _signals()]), controller


def test_reuse_with_constant_jacobians_changes_nothing_but_the_speed():
    written = GenerativeModel(f=lambda x, v: A @ x + B @ v, g=lambda x, v: C @ x, n_states=4, n_causes=1, n_outputs=2,
                              jacobian_f=lambda x, v: (A, B), jacobian_g=lambda x, v: (C, np.zeros((2, 1))), **OPTIONS)
    exact, _ = _actions(written)
    reused, controller = _actions(written, jacobian_tolerance=0.0)
    assert controller._general_cache["integral"] is not None  # the reuse path was taken
    # expm(J dt) - I) inv(J) f against (int_0^dt expm(J s) ds) f: equal up to the exponentials' rounding
    # (cond ~ |J dt| ~ 1e2 times eps)
    assert np.abs(reused - exact).max() <= 1e-9 * np.abs(exact).max()


def test_a_tolerance_below_the_jacobians_motion_relinearises_every_sample():
    def f(x, v):
        return A @ x + B @ v - np.array([0.0, 4.0 * x[0] ** 3, 0.0, 0.0])

    def jf(x, v):
        fx = A.copy()
        fx[1, 0] -= 12.0 * x[0] ** 2
        return fx, B

    model = GenerativeModel(f=f, g=lambda x, v: C @ x, n_states=4, n_causes=1, n_outputs=2, jacobian_f=jf,
                            jacobian_g=lambda x, v: (C, np.zeros((2, 1))), **OPTIONS)
    exact, _ = _actions(model)
    tight, controller = _actions(model, jacobian_tolerance=1e-14)
    assert np.array_equal(tight, exact)  # the same code path every sample: bit-identical
    assert controller._general_cache["integral"] is None
    loose, _ = _actions(model, jacobian_tolerance=0.05)
    difference = np.abs(loose - exact).max() / np.abs(exact).max()
    assert 0 < difference < 0.1  # reuse approximates: measured 2e-2 of the largest action


@pytest.mark.parametrize("value", [-1.0, float("nan"), "small"])
def test_jacobian_tolerance_is_validated(value):
    model = GenerativeModel.linear(A, B, C, **OPTIONS)
    with pytest.raises(AttendInputError, match="jacobian_tolerance"):
        ActiveInferenceController(model, 0.01, action_jacobian=G, jacobian_tolerance=value)
