"""The Lorenz floor's reference (benchmarks/bench_lorenz_floor.py): its model is the simulator's own,
and its MAP is the exact posterior mean where the model is linear."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import load_benchmark

from attend.experiments import lorenz
from attend.models import simulate_nonlinear
from attend.models.noise import coloured_noise


@pytest.fixture(scope="module")
def floor():
    return load_benchmark("bench_lorenz_floor")


def test_the_convolution_matrix_draws_what_coloured_noise_draws(floor):
    dt, s, n_samples = 0.01, 0.02, 60
    drawn = coloured_noise(n_samples, 2, dt, s, 1.0, np.random.default_rng(3))
    K = floor.convolution_matrix(floor.gaussian_kernel(dt, s), n_samples)
    white = np.random.default_rng(3).standard_normal((K.shape[1], 2))
    assert np.max(np.abs(K @ white - drawn)) < 1e-12


def test_one_sample_is_the_simulators_map(floor):
    cfg = lorenz.SETTINGS
    system = lorenz.build_system(cfg)
    log = simulate_nonlinear(system, 40, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=cfg["process_std"],
                             initial_state=cfg["initial_state"], seed=1)
    predicted = floor.one_sample(lambda x: system.f(x, np.zeros((0, x.shape[1]))), log.states[:-1].T,
                                 log.process_noise[:-1].T, cfg["dt"]).T
    assert np.max(np.abs(predicted - log.states[1:])) < 1e-10 * np.max(np.abs(log.states))


def test_the_map_is_the_exact_posterior_mean_of_a_linear_model(floor):
    assert floor.linear_check() < 1e-3  # in posterior stds, over every sample and state
