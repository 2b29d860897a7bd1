"""NoiseModel: the noise of a model as one value; its forms (precision, standard deviation,
covariance) convert into each other, and simulate() takes it in place of its noise keywords."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import attend
from attend import AttendInputError
from attend.models import NoiseModel, NonlinearSystem, simulate, simulate_nonlinear
from attend.models.problems import mass_spring_damper

PENDULUM = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0])]), lambda x, v: x[:1], 2, 0, 1)


def test_exported_from_models_and_attend():
    assert attend.NoiseModel is NoiseModel


@pytest.mark.parametrize("process_std, sensor_std", [(0.3, 0.1), ([0.3, 0.7], [0.1]), (2.0, [0.5, 0.25])])
def test_std_precision_covariance_round_trips(process_std, sensor_std):
    noise = NoiseModel.from_std(process_std=process_std, sensor_std=sensor_std, kernel_width=0.5)
    # from_std: Pi = 1 / sigma^2 (KalmanEstimator's docstring: Pi_w = 1/sigma_w^2 for simulate(process_std=sigma_w))
    np.testing.assert_allclose(noise.process_precision, 1 / np.square(process_std), rtol=1e-15)
    np.testing.assert_allclose(noise.sensor_precision, 1 / np.square(sensor_std), rtol=1e-15)
    # the given standard deviations come back exactly
    assert np.array_equal(noise.process_std, process_std) and np.array_equal(noise.sensor_std, sensor_std)
    np.testing.assert_allclose(noise.process_covariance, np.square(process_std), rtol=1e-15)
    np.testing.assert_allclose(noise.sensor_covariance, np.square(sensor_std), rtol=1e-15)
    # precision -> std and covariance -> precision, computed (a model built from the precisions)
    plain = NoiseModel(process_precision=noise.process_precision, sensor_precision=noise.sensor_precision,
                       kernel_width=0.5)
    np.testing.assert_allclose(plain.process_std, process_std, rtol=1e-15)
    np.testing.assert_allclose(plain.sensor_std, sensor_std, rtol=1e-15)
    again = NoiseModel.from_covariance(process_covariance=plain.process_covariance,
                                       sensor_covariance=plain.sensor_covariance, kernel_width=0.5)
    np.testing.assert_allclose(again.process_precision, plain.process_precision, rtol=1e-15)
    np.testing.assert_allclose(again.sensor_precision, plain.sensor_precision, rtol=1e-15)
    assert np.ndim(noise.process_precision) == np.ndim(process_std)  # a number stays a number


def test_matrix_covariance_round_trip_and_correlated_std():
    covariance = np.array([[2.0, 0.5], [0.5, 1.0]])
    noise = NoiseModel.from_covariance(process_covariance=covariance, sensor_covariance=0.01, kernel_width=0.2)
    np.testing.assert_allclose(noise.process_precision @ covariance, np.eye(2), atol=1e-15)
    assert noise.process_covariance is not None and np.array_equal(noise.process_covariance, covariance)
    assert noise.correlated
    with pytest.raises(AttendInputError, match="process_std.*correlated"):
        noise.process_std
    assert noise.sensor_std == pytest.approx(0.1, rel=1e-15)
    diagonal = NoiseModel(process_precision=np.diag([4.0, 16.0]), sensor_precision=1.0, kernel_width=0.2)
    assert not diagonal.correlated
    np.testing.assert_allclose(diagonal.process_std, [0.5, 0.25], rtol=1e-15)


def test_kernel_widths():
    both = NoiseModel(process_precision=1.0, sensor_precision=1.0, kernel_width=0.4)
    assert (both.process_kernel_width, both.sensor_kernel_width, both.kernel_width) == (0.4, 0.4, 0.4)
    apart = NoiseModel(process_precision=1.0, sensor_precision=1.0, process_kernel_width=0.0, sensor_kernel_width=0.1)
    assert (apart.process_kernel_width, apart.sensor_kernel_width, apart.kernel_width) == (0.0, 0.1, None)
    assert apart.precision_keywords() == dict(sensor_precision=1.0, process_precision=1.0, kernel_width=None,
                                              process_kernel_width=0.0, sensor_kernel_width=0.1)
    one = NoiseModel(process_precision=1.0, sensor_precision=1.0, kernel_width=0.3, sensor_kernel_width=0.2)
    assert (one.process_kernel_width, one.sensor_kernel_width) == (0.3, 0.2)  # the per-channel width wins
    changed = dataclasses.replace(both, sensor_kernel_width=0.1)
    assert (changed.process_kernel_width, changed.sensor_kernel_width) == (0.4, 0.1)


def test_equality_and_immutability():
    a = NoiseModel(process_precision=[1.0, 2.0], sensor_precision=3.0, kernel_width=0.1)
    assert a == NoiseModel(process_precision=[1.0, 2.0], sensor_precision=3.0, kernel_width=0.1)
    assert a != NoiseModel(process_precision=[1.0, 2.5], sensor_precision=3.0, kernel_width=0.1)
    assert a != NoiseModel(process_precision=1.0, sensor_precision=3.0, kernel_width=0.1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.sensor_precision = 1.0
    with pytest.raises(ValueError):
        a.process_precision[0] = 5.0  # read-only copy


def test_precision_matrices():
    noise = NoiseModel(process_precision=[1.0, 2.0], sensor_precision=3.0, kernel_width=0.1)
    process, sensor = noise.precision_matrices(2, 2)
    assert np.array_equal(process, np.diag([1.0, 2.0])) and np.array_equal(sensor, 3.0 * np.eye(2))
    with pytest.raises(AttendInputError, match="noise.process_precision: expected 3 diagonal entries"):
        noise.precision_matrices(3, 1)


@pytest.mark.parametrize("arguments, message", [
    (dict(process_precision=-1.0, sensor_precision=1.0, kernel_width=0.1),
     "process_precision: expected precisions > 0"),
    (dict(process_precision=1.0, sensor_precision=[1.0, 0.0], kernel_width=0.1),
     "sensor_precision: expected precisions > 0"),
    (dict(process_precision=1.0, sensor_precision=[1.0, np.nan], kernel_width=0.1),
     "sensor_precision: expected finite"),
    (dict(process_precision=np.inf, sensor_precision=1.0, kernel_width=0.1), "process_precision: expected finite"),
    (dict(process_precision=[[1.0, 2.0], [0.0, 1.0]], sensor_precision=1.0, kernel_width=0.1),
     "process_precision: expected a symmetric matrix"),
    (dict(process_precision=[[1.0, 2.0], [2.0, 1.0]], sensor_precision=1.0, kernel_width=0.1),
     "process_precision: expected a positive definite matrix"),
    (dict(process_precision=np.ones((2, 3)), sensor_precision=1.0, kernel_width=0.1), "process_precision: .*shape"),
    (dict(process_precision=[], sensor_precision=1.0, kernel_width=0.1), "process_precision: expected at least one"),
    (dict(process_precision="1", sensor_precision=1.0, kernel_width=0.1), "process_precision: expected"),
    (dict(process_precision=1.0, sensor_precision=1.0), "process_kernel_width: required"),
    (dict(process_precision=1.0, sensor_precision=1.0, kernel_width=-0.1),
     "kernel_width: expected a finite number >= 0"),
    (dict(process_precision=1.0, sensor_precision=1.0, kernel_width=0.1, sensor_kernel_width=np.nan),
     "sensor_kernel_width: expected a finite number >= 0"),
])
def test_bad_values_name_the_field(arguments, message):
    with pytest.raises(AttendInputError, match=message):
        NoiseModel(**arguments)


def test_bad_std_and_covariance_name_the_field():
    with pytest.raises(AttendInputError, match="process_std: expected standard deviations > 0"):
        NoiseModel.from_std(process_std=0.0, sensor_std=1.0, kernel_width=0.1)
    with pytest.raises(AttendInputError, match="sensor_std: expected a number or one standard deviation per channel"):
        NoiseModel.from_std(process_std=1.0, sensor_std=np.eye(2), kernel_width=0.1)
    with pytest.raises(AttendInputError, match="sensor_covariance: expected a positive definite"):
        NoiseModel.from_covariance(process_covariance=1.0, sensor_covariance=np.zeros((2, 2)), kernel_width=0.1)


def test_simulate_draws_the_same_noise_from_a_noise_model():
    system = mass_spring_damper()
    u = np.sin(np.arange(150) * 0.1)[:, None]
    noise = NoiseModel.from_std(process_std=[0.2, 0.3], sensor_std=0.1, process_kernel_width=0.3,
                                sensor_kernel_width=0.0)
    old = simulate(system, u, 0.1, process_std=[0.2, 0.3], measurement_std=0.1, process_kernel_width=0.3,
                   sensor_kernel_width=0.0, seed=4)
    new = simulate(system, u, 0.1, noise=noise, seed=4)
    for a, b in zip(old, new):
        assert np.array_equal(a, b)
    # from precisions: the std 1 / sqrt(Pi), the same as passing that std
    plain = NoiseModel(process_precision=25.0, sensor_precision=100.0, kernel_width=0.2)
    assert np.array_equal(simulate(system, u, 0.1, noise=plain).outputs,
                          simulate(system, u, 0.1, kernel_width=0.2, process_std=plain.process_std,
                                   measurement_std=plain.sensor_std).outputs)
    # the defaults are unchanged: no noise
    quiet = simulate(system, u, 0.1, kernel_width=0.2)
    assert not quiet.process_noise.any() and not quiet.measurement_noise.any()


def test_simulate_nonlinear_draws_the_same_noise_from_a_noise_model():
    noise = NoiseModel.from_std(process_std=0.2, sensor_std=0.1, kernel_width=0.3)
    old = simulate_nonlinear(PENDULUM, 60, 0.1, kernel_width=0.3, process_std=0.2, measurement_std=0.1,
                             initial_state=[1.0, 0.0])
    new = simulate_nonlinear(PENDULUM, 60, 0.1, noise=noise, initial_state=[1.0, 0.0])
    for a, b in zip(old, new):
        assert np.array_equal(a, b)


def test_simulators_refuse_both_forms():
    system = mass_spring_damper()
    noise = NoiseModel.from_std(process_std=0.2, sensor_std=0.1, kernel_width=0.3)
    with pytest.raises(AttendInputError, match="noise and process_std: simulate takes"):
        simulate(system, np.zeros((10, 1)), 0.1, noise=noise, process_std=0.2)
    with pytest.raises(AttendInputError, match="noise and kernel_width: simulate_nonlinear takes"):
        simulate_nonlinear(PENDULUM, 10, 0.1, noise=noise, kernel_width=0.3)
    with pytest.raises(AttendInputError, match="noise: expected an attend.models.NoiseModel"):
        simulate(system, np.zeros((10, 1)), 0.1, noise={"process_std": 0.2})
    apart = NoiseModel(process_precision=1.0, sensor_precision=1.0, process_kernel_width=0.1, sensor_kernel_width=0.2)
    with pytest.raises(AttendInputError, match="noise: simulate_nonlinear uses one kernel width"):
        simulate_nonlinear(PENDULUM, 10, 0.1, noise=apart)
    with pytest.raises(AttendInputError, match="kernel_width: required"):
        simulate_nonlinear(PENDULUM, 10, 0.1, process_std=0.1)
    correlated = NoiseModel(process_precision=[[2.0, 1.0], [1.0, 2.0]], sensor_precision=1.0, kernel_width=0.1)
    with pytest.raises(AttendInputError, match="process_std is per channel"):
        simulate(system, np.zeros((10, 1)), 0.1, noise=correlated)
