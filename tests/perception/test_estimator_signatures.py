"""One shape for the estimators' constructors: the system and dt first, everything else by keyword.

Positionally, DEMObserver(system, dt, kernel_width, sensor_precision, ...) and
KalmanEstimator(system, dt, sensor_precision, process_precision, ...) would silently exchange a
kernel width and a precision; keyword-only arguments make the old positional form a TypeError."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from attend.models import NonlinearSystem
from attend.models.problems import mass_spring_damper
from attend.perception.dem import DEMObserver
from attend.perception.kalman import KalmanEstimator
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear_smoothers import input_random_walk_variance, white_noise_covariances, \
    white_noise_options

LINEAR = mass_spring_damper()
NONLINEAR = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0])]), lambda x, v: x[:1], 2, 0, 1)


@pytest.mark.parametrize("build", [
    lambda: DEMObserver(LINEAR, 0.1, 0.5, 100.0, 10.0),
    lambda: KalmanEstimator(LINEAR, 0.1, 100.0, 10.0, kernel_width=0.5),
    lambda: NonlinearDEM(NONLINEAR, 0.1, 0.5, 100.0, 10.0),
    lambda: white_noise_covariances(NONLINEAR, 0.1, 0.5, 0.1, 0.1),
    lambda: white_noise_options(0.1, np.eye(2), np.eye(1)),
    lambda: input_random_walk_variance(1.0, 0.5, 0.1),
], ids=["DEMObserver", "KalmanEstimator", "NonlinearDEM", "white_noise_covariances", "white_noise_options",
        "input_random_walk_variance"])
def test_the_old_positional_form_is_a_type_error(build):
    with pytest.raises(TypeError, match="positional argument"):
        build()


@pytest.mark.parametrize("estimator", [DEMObserver, KalmanEstimator, NonlinearDEM])
def test_only_the_system_and_dt_are_positional(estimator):
    parameters = inspect.signature(estimator).parameters.values()
    positional = [p.name for p in parameters if p.kind == p.POSITIONAL_OR_KEYWORD]
    assert positional == ["system", "dt"]


def test_the_keyword_form_builds_the_same_estimators():
    dem = DEMObserver(LINEAR, 0.1, kernel_width=0.5, sensor_precision=100.0, process_precision=10.0, known_inputs=True)
    kalman = KalmanEstimator(LINEAR, 0.1, sensor_precision=100.0, process_precision=10.0, kernel_width=0.5)
    assert (dem.kernel_width, kalman.kernel_width) == (0.5, 0.5)
    np.testing.assert_array_equal(dem.sensor_precision, kalman.sensor_precision)
    np.testing.assert_array_equal(dem.process_precision, kalman.process_precision)
