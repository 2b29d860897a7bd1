"""Coloured noise: variance and autocorrelation exp(-tau^2 / (4 s^2))."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.noise import autocorrelation, coloured_noise, gaussian_kernel


def test_kernel_has_unit_energy():
    kernel = gaussian_kernel(0.1, 0.5)
    assert abs(np.sum(kernel**2) - 1) < 1e-12
    assert kernel.argmax() == len(kernel) // 2


def test_simulated_autocorrelation_matches_gaussian():
    dt, s = 0.05, 0.4
    noise = coloured_noise(400_000, 2, dt, s, std=[1.0, 3.0], seed=1)
    np.testing.assert_allclose(noise.std(axis=0), [1.0, 3.0], rtol=0.03)
    unit = noise / noise.std(axis=0)
    for lag in range(0, 25, 3):
        empirical = np.mean(unit[: len(unit) - lag] * unit[lag:])
        assert abs(empirical - autocorrelation(lag * dt, s)) < 0.03, lag


def test_seeded_and_independent_channels():
    a = coloured_noise(1000, 3, 0.1, 0.5, seed=7)
    b = coloured_noise(1000, 3, 0.1, 0.5, seed=7)
    np.testing.assert_array_equal(a, b)
    c = coloured_noise(100_000, 2, 0.1, 0.5, seed=3)
    assert abs(np.corrcoef(c.T)[0, 1]) < 0.05


def test_bad_noise_arguments():
    with pytest.raises(AttendInputError, match="kernel_width"):
        coloured_noise(10, 1, 0.1, -1.0)
    with pytest.raises(AttendInputError, match="std"):
        coloured_noise(10, 1, 0.1, 0.5, std=np.nan)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0, 5.0, 10.0])
def test_noise_state_space_reproduces_the_kernel_autocorrelation(ratio):
    """The finite model's autocorrelation H T^l Sigma H' equals the kernel's self-correlation."""
    from attend.models.noise import kernel_autocorrelation, noise_state_space

    target = kernel_autocorrelation(1.0, ratio)
    model = noise_state_space(target)
    assert model.order <= 14
    assert np.max(np.abs(np.linalg.eigvals(model.transition))) < 1
    vector = model.stationary_covariance @ model.output
    for lag in range(len(target)):  # independent evaluation of the model's autocorrelation
        assert abs(model.output @ vector - target[lag]) < 2e-5, lag
        vector = model.transition @ vector
    # and it is a model of a unit-variance sequence driven by unit white noise
    assert abs(model.output @ model.stationary_covariance @ model.output - 1) < 2e-6


def test_white_noise_has_an_order_zero_model_and_simulates_white():
    from attend.models.noise import noise_state_space

    assert noise_state_space([1.0, 0.0, 0.0]).order == 0
    noise = coloured_noise(50_000, 1, 0.1, 0.0, std=2.0, seed=0)
    assert abs(noise.std() - 2.0) < 0.05
    assert abs(np.mean(noise[1:, 0] * noise[:-1, 0])) / 4 < 0.02
