"""f and g at many points of a model that is not vectorized (attend.perception.nonlinear_smoothers.kalman):
all rows of an RK4 stage advanced together, f called row by row, give the same numbers as integrating
each row alone; a function whose values cannot be taken in one go falls back to the checked calls."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models import NonlinearSystem
from attend.perception.nonlinear_smoothers.kalman import evaluate_rows, observe_points, propagate_points

P = (18.0, -4.0, 46.92)


def _lorenz(x, v):
    """SPM's Lorenz system, written for one point (np.array of a matrix with x's entries: not column-safe)."""
    J = np.array([[-P[0], P[0], 0.0], [P[2] - x[2], -1.0, -x[0]], [x[1], x[0], P[1]]])
    return J @ x / 32.0 + v[0]


LORENZ = NonlinearSystem(_lorenz, lambda x, v: np.array([x[0] + x[1] + x[2]]), 3, 1, 1)


def _one_row(system, x, u, dt, substeps, w=None):
    """RK4 of one row, as propagate_points did it before it advanced all rows together."""
    h, extra = dt / substeps, 0.0 if w is None else w
    for _ in range(substeps):
        k1 = system.flow(x, u) + extra
        k2 = system.flow(x + 0.5 * h * k1, u) + extra
        k3 = system.flow(x + 0.5 * h * k2, u) + extra
        k4 = system.flow(x + h * k3, u) + extra
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


@pytest.mark.parametrize("noise", [False, True])
def test_all_rows_at_once_equal_each_row_alone_to_the_last_bit(noise):
    rng = np.random.default_rng(0)
    x = rng.normal(scale=10.0, size=(7, 3))
    u = rng.normal(size=(7, 1))
    w = rng.normal(size=(7, 3)) if noise else None
    together = propagate_points(LORENZ, x, u, 1.0, 17, w)
    alone = np.array([_one_row(LORENZ, x[i], u[i], 1.0, 17, None if w is None else w[i]) for i in range(7)])
    np.testing.assert_array_equal(together, alone)
    np.testing.assert_array_equal(observe_points(LORENZ, x, u), np.array([LORENZ.observe(a, b) for a, b in zip(x, u)]))


def test_a_function_that_returns_one_buffer_gives_each_rows_value():
    buffer = np.zeros(3)

    def filled(x, v):
        buffer[:] = _lorenz(x, v)
        return buffer

    system = NonlinearSystem(filled, LORENZ.g, 3, 1, 1)
    rng = np.random.default_rng(3)
    x, u = rng.normal(size=(5, 3)), rng.normal(size=(5, 1))
    np.testing.assert_array_equal(evaluate_rows(system, "f", x, u), evaluate_rows(LORENZ, "f", x, u))
    np.testing.assert_array_equal(propagate_points(system, x, u, 1.0, 3), propagate_points(LORENZ, x, u, 1.0, 3))


def test_values_of_another_shape_fall_back_to_the_checked_calls():
    """f returning (n, 1) per point (accepted by NonlinearSystem.evaluate) gives the same rows."""
    column = NonlinearSystem(lambda x, v: _lorenz(x, v)[:, None], LORENZ.g, 3, 1, 1)
    rng = np.random.default_rng(1)
    x, u = rng.normal(size=(5, 3)), rng.normal(size=(5, 1))
    np.testing.assert_array_equal(evaluate_rows(column, "f", x, u), evaluate_rows(LORENZ, "f", x, u))
    assert evaluate_rows(LORENZ, "f", x[:0], u[:0]).shape == (0, 3)


def test_a_wrong_shape_or_a_failure_is_named_as_one_call_names_it():
    rng = np.random.default_rng(2)
    x, u = rng.normal(size=(4, 3)), rng.normal(size=(4, 1))
    short = NonlinearSystem(lambda x, v: x[:2], LORENZ.g, 3, 1, 1)
    with pytest.raises(AttendInputError, match=r"f: expected 3 values \(a 1-D array\), got shape \(2,\)"):
        evaluate_rows(short, "f", x, u)

    def fails_at_the_third(x, v):
        if x[0] == x3[0]:
            raise ZeroDivisionError("at the third point")
        return _lorenz(x, v)

    x3 = x[2]
    failing = NonlinearSystem(fails_at_the_third, LORENZ.g, 3, 1, 1)
    with pytest.raises(AttendInputError, match="f: raised ZeroDivisionError: at the third point"):
        evaluate_rows(failing, "f", x, u)
