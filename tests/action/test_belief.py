"""Map prior, Kalman fusion and planning gains against closed forms."""

import numpy as np
import pytest

from attend.action.belief import (
    OccupancyMap,
    kalman_update,
    kalman_update_diagonal,
    matern32,
    observation_gains,
    prior_covariance,
)
from attend.action.field import Grid
from attend.action.metrics import root_squared_error


def random_spd(n, seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    return a @ a.T / n + 0.1 * np.eye(n)


def test_matern32_closed_form():
    d = np.array([0.0, 1.0, 3.67])
    expected = 1.82 * (1 + np.sqrt(3) * d / 3.67) * np.exp(-np.sqrt(3) * d / 3.67)
    np.testing.assert_allclose(matern32(d, 3.67, 1.82), expected)
    assert matern32(0.0, 3.67, 1.82) == pytest.approx(1.82)


def test_prior_trace_is_387_on_40x40():
    covariance = prior_covariance(40)
    assert covariance.shape == (1600, 1600)
    assert np.trace(covariance) == pytest.approx(387, abs=0.5)
    np.testing.assert_allclose(covariance, covariance.T)
    assert np.linalg.eigvalsh(covariance).min() > 0


def test_prior_matches_gp_posterior_formula_on_small_grid():
    grid = Grid(cells_per_side=5)
    index = grid.cell_indices().astype(float)
    distance = np.linalg.norm(index[:, None] - index[None], axis=-1)
    k = matern32(distance, 3.67, 1.82)
    expected = k - k @ np.linalg.inv(k + 2.01 * np.eye(25)) @ k
    np.testing.assert_allclose(prior_covariance(5), expected, atol=1e-10)


def test_initial_rse_is_7_69_with_54_person_cells():
    truth = np.zeros(1600)
    truth[:54] = 1
    assert root_squared_error(np.full(1600, 0.1), truth) == pytest.approx(7.69, abs=0.005)


def test_kalman_update_equals_gaussian_conditioning():
    n = 12
    p = random_spd(n, 0)
    mean = np.linspace(0, 1, n)
    cells = np.array([1, 4, 7])
    z = np.array([1.0, 0.05, 1.0])
    r = 0.39
    new_mean, new_p = kalman_update(mean, p, cells, z, r)
    # joint Gaussian of (x, y = Hx + v): condition x on y = z
    h = np.eye(n)[cells]
    s = h @ p @ h.T + r * np.eye(3)
    expected_mean = mean + p @ h.T @ np.linalg.solve(s, z - h @ mean)
    expected_p = p - p @ h.T @ np.linalg.solve(s, h @ p)
    np.testing.assert_allclose(new_mean, expected_mean, atol=1e-12)
    np.testing.assert_allclose(new_p, expected_p, atol=1e-12)
    # information form: P_post^-1 = P^-1 + H' H / r
    np.testing.assert_allclose(np.linalg.inv(new_p), np.linalg.inv(p) + h.T @ h / r, rtol=1e-8)


def test_kalman_update_reduces_trace_and_informs_neighbours():
    belief = OccupancyMap.prior(Grid(cells_per_side=10))
    before_var = belief.variance
    before = belief.trace()
    belief.fuse(np.array([55]), np.array([1.0]), 0.39)
    assert belief.trace() < before
    assert belief.variance[56] < before_var[56]  # correlated neighbour learned too
    assert belief.mean[56] > 0.1


def test_diagonal_update_closed_form():
    mean = np.array([0.1, 0.1])
    var = np.array([0.24, 0.5])
    new_mean, new_var = kalman_update_diagonal(mean, var, np.array([1]), np.array([1.0]), 0.39)
    assert new_var[0] == 0.24 and new_mean[0] == 0.1
    assert new_var[1] == pytest.approx(0.5 * 0.39 / 0.89)
    assert new_mean[1] == pytest.approx(0.1 + 0.5 / 0.89 * 0.9)


def test_observation_gains_match_sequential_updates():
    n = 10
    p = random_spd(n, 1)
    precision = np.zeros((3, n))
    precision[0, [0, 1, 2]] = 1 / 0.39
    precision[1, [2, 3]] = 1 / 0.39 + 1 / 0.6  # cell seen twice
    precision[1, 5] = 1 / 0.6
    precision[2, :] = 0.0  # nothing seen
    weights = np.linspace(0.2, 1.0, n)
    reduction, information = observation_gains(p, precision, cell_weights=weights, want_information=True)
    for k in range(3):
        observed = np.flatnonzero(precision[k])
        if len(observed) == 0:
            assert reduction[k] == pytest.approx(0) and information[k] == pytest.approx(0)
            continue
        post = np.linalg.inv(np.linalg.inv(p) + np.diag(precision[k]))
        assert reduction[k] == pytest.approx(np.sum(weights * np.diag(p - post)), rel=1e-9)
        sub = p[np.ix_(observed, observed)]
        d = precision[k, observed]
        expected_info = 0.5 * np.linalg.slogdet(np.eye(len(observed)) + np.sqrt(d)[:, None] * sub * np.sqrt(d)[None])[1]
        assert information[k] == pytest.approx(expected_info, rel=1e-9)
    # diagonal closed form
    diag_reduction, _ = observation_gains(np.diag(p), precision, diagonal=True)
    expected = (np.diag(p) - 1 / (1 / np.diag(p) + precision)).sum(axis=1)
    np.testing.assert_allclose(diag_reduction, expected)
