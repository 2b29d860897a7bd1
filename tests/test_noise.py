"""Coloured noise: variance and autocorrelation exp(-tau^2 / (4 s^2))."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.noise import autocorrelation, coloured_noise, gaussian_kernel


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
