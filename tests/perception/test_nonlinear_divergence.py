"""Nonlinear filters whose covariances leave the floating-point range: an error naming the
covariances, not f called at NaN, not a finite estimate of 1e150 with exit 0."""

import numpy as np
import pytest

from attend.models.nonlinear import NonlinearSystem
from attend.perception.nonlinear_smoothers import unscented_kalman

DT = 0.1


@pytest.mark.parametrize("process_variance", [1e300, 1e250])
def test_a_covariance_beyond_the_floating_point_range_is_an_error_not_a_call_of_f_at_nan(process_variance):
    """A process noise of ~1e300 (a precision of 1e-300 in a model file): the filter's covariance
    overflows, or its sigma points reach ~1e125, where f and g return finite nonsense. An error
    naming the covariances, never f called at NaN (which would blame the model's code) nor an
    estimate of 1e150 with exit 0."""
    from attend._validation import AttendInputError

    calls = []

    def f(x, v):
        calls.append(np.all(np.isfinite(x)))
        return np.array([x[1], -np.sin(x[0])])

    system = NonlinearSystem(f, lambda x, v: np.array([np.sin(x[0]), x[1]]), 2, 0, 2)
    y = np.column_stack([np.sin(np.arange(40) * 0.1), np.cos(np.arange(40) * 0.1)])
    with pytest.raises(AttendInputError, match="covariances"):
        unscented_kalman(system, DT, y, process_covariance=process_variance * np.eye(2),
                         measurement_covariance=0.01 * np.eye(2), initial_mean=[0.5, 0.0],
                         initial_covariance=np.eye(2), substeps=1)
    assert all(calls)


def test_scaled_solve_refuses_a_system_beyond_the_floating_point_range():
    from attend.perception.nonlinear._linalg import scaled_solve

    np.testing.assert_allclose(scaled_solve(np.diag([4.0, 1e-12]), np.array([2.0, 1e-12])), [0.5, 1.0])
    with pytest.raises(np.linalg.LinAlgError, match="not finite"):
        scaled_solve(np.array([[1e-300, 1.0], [1.0, 1e-300]]), np.array([1.0, 1e300]))
