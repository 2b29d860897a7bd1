"""Generalised coordinates: S against the spec's check values and the paper's eq. 7, embedding
weights against central differences, the shift operator."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.generalized import (
    block_precisions,
    embed,
    embed_newest,
    embedding_weights,
    fold_orders,
    shift_operator,
    smoothness_precision,
    temporal_covariance,
)


def test_smoothness_precision_check_values_from_spec():
    np.testing.assert_allclose(temporal_covariance(3, 1.0), [[1, 0, -0.5], [0, 0.5, 0], [-0.5, 0, 0.75]], atol=1e-15)
    np.testing.assert_allclose(smoothness_precision(3, 1.0), [[1.5, 0, 1], [0, 2, 0], [1, 0, 2]], atol=1e-14)
    np.testing.assert_allclose(smoothness_precision(3, 0.5), [[1.5, 0, 0.25], [0, 0.5, 0], [0.25, 0, 0.125]], atol=1e-14)
    np.testing.assert_allclose(
        np.diag(smoothness_precision(7, 0.5)),
        [2.1875, 2.1875, 1.203125, 0.125, 0.02213542, 2.604167e-4, 2.170139e-5],
        rtol=1e-6,
    )


@pytest.mark.parametrize("s", [0.006, 0.1, 0.5, 1.0, 2.3])
def test_smoothness_precision_matches_paper_closed_form(s):
    """Paper eq. 7: the 7x7 S of a Gaussian kernel in closed form."""
    paper = np.array([
        [35 / 16, 0, 35 / 8 * s**2, 0, 7 / 4 * s**4, 0, s**6 / 6],
        [0, 35 / 4 * s**2, 0, 7 * s**4, 0, s**6, 0],
        [35 / 8 * s**2, 0, 77 / 4 * s**4, 0, 19 / 2 * s**6, 0, s**8],
        [0, 7 * s**4, 0, 8 * s**6, 0, 4 / 3 * s**8, 0],
        [7 / 4 * s**4, 0, 19 / 2 * s**6, 0, 17 / 3 * s**8, 0, 2 / 3 * s**10],
        [0, s**6, 0, 4 / 3 * s**8, 0, 4 / 15 * s**10, 0],
        [s**6 / 6, 0, s**8, 0, 2 / 3 * s**10, 0, 4 / 45 * s**12],
    ])
    np.testing.assert_allclose(smoothness_precision(7, s), paper, rtol=1e-12, atol=1e-300)


@pytest.mark.parametrize("n_orders", [1, 4, 9, 13])
def test_smoothness_precision_is_inverse_of_covariance_at_high_order(n_orders):
    """Checked in the scaled (well-posed) coordinates: L^-1 V L^-1 and L S L are exact inverses."""
    s = 0.006
    scale = (2 * s**2) ** (-np.arange(n_orders) / 2)
    core_v = temporal_covariance(n_orders, s) / np.outer(scale, scale)
    core_s = smoothness_precision(n_orders, s) * np.outer(scale, scale)
    # core_v holds integers: the product with the float core_s is the identity to rounding
    np.testing.assert_allclose(core_v @ core_s, np.eye(n_orders), atol=1e-6 * np.abs(core_s).max())
    assert np.all(np.linalg.eigvalsh(core_s) > 0)


def test_precision_conventions_differ_and_truncate():
    S_p, S_d = block_precisions(6, 2, 0.5, "size")
    np.testing.assert_allclose(S_d, smoothness_precision(3, 0.5))
    T_p, T_d = block_precisions(6, 2, 0.5, "max")
    np.testing.assert_allclose(T_p, S_p)
    np.testing.assert_allclose(T_d, smoothness_precision(7, 0.5)[:3, :3])
    assert not np.allclose(T_d, S_d)
    with pytest.raises(AttendInputError, match="precision_convention"):
        block_precisions(6, 2, 0.5, "other")


def test_shift_operator_is_nilpotent_and_shifts():
    D = shift_operator(4, 2)
    x = np.arange(8.0)
    np.testing.assert_array_equal(D @ x, [2, 3, 4, 5, 6, 7, 0, 0])
    assert np.count_nonzero(np.linalg.matrix_power(D, 4)) == 0
    assert np.count_nonzero(np.linalg.matrix_power(D, 3)) > 0


def test_embedding_weights_are_central_differences():
    weights = embedding_weights(7, 0.1)
    np.testing.assert_allclose(weights[1] * 0.1, np.array([-1, 9, -45, 0, 45, -9, 1]) / 60, atol=1e-14)
    np.testing.assert_allclose(weights[0], [0, 0, 0, 1, 0, 0, 0], atol=1e-14)
    # second derivative, 5 points: [-1, 16, -30, 16, -1] / 12
    np.testing.assert_allclose(embedding_weights(5, 1.0)[2], np.array([-1, 16, -30, 16, -1]) / 12, atol=1e-13)


def test_embedding_is_exact_for_polynomials_and_handles_edges():
    dt = 0.05
    t = np.arange(40) * dt
    y = 2 - t + 0.5 * t**2 - 0.3 * t**3
    derivatives = embed(y, 4, dt).reshape(40, 4)
    interior = slice(2, 38)
    np.testing.assert_allclose(derivatives[interior, 0], y[interior], atol=1e-12)
    np.testing.assert_allclose(derivatives[interior, 1], (-1 + t - 0.9 * t**2)[interior], atol=1e-9)
    np.testing.assert_allclose(derivatives[interior, 2], (1 - 1.8 * t)[interior], atol=1e-7)
    np.testing.assert_allclose(derivatives[interior, 3], -1.8, atol=1e-5)
    order0 = embed(y, 4, dt, edges="order0").reshape(40, 4)
    assert np.all(order0[0, 1:] == 0) and order0[0, 0] == y[0]
    np.testing.assert_allclose(order0[interior], derivatives[interior])
    shifted = embed(y, 3, dt, shift=-1).reshape(40, 3)
    np.testing.assert_allclose(shifted[5], embed(y, 3, dt).reshape(40, 3)[4])
    with pytest.raises(AttendInputError, match="edges"):
        embed(y, 3, dt, edges="wrap")


def test_bad_orders_and_widths():
    with pytest.raises(AttendInputError, match="kernel_width"):
        smoothness_precision(3, 0.0)
    with pytest.raises(AttendInputError, match="kernel_width"):
        smoothness_precision(3, float("nan"))
    with pytest.raises(AttendInputError, match="embedding_order"):
        block_precisions(-1, 2, 0.5)


def test_embed_newest_is_the_last_row_of_embed_for_every_prefix():
    """The window at the newest sample, the ends repeated (5 orders: 2 samples before it): for the
    history 0, 1, 2, 3 the window is [1, 2, 3, 3, 3]; for one sample, that sample five times."""
    rng = np.random.default_rng(3)
    history = [rng.normal(size=2) for _ in range(9)]
    for n_orders in (3, 4, 5, 7):
        for length in range(1, len(history) + 1):
            expected = embed(np.array(history[:length]), n_orders, 0.1)[-1].reshape(n_orders, 2)
            np.testing.assert_allclose(embed_newest(history[:length], n_orders, 0.1), expected, rtol=0, atol=1e-12)
    ramp = [np.array([float(i)]) for i in range(4)]
    np.testing.assert_allclose(embed_newest(ramp, 5, 1.0)[:, 0], embedding_weights(5, 1.0) @ [1.0, 2.0, 3.0, 3.0, 3.0])
    np.testing.assert_allclose(embed_newest(ramp[:1], 5, 1.0)[:, 0], [0.0] * 5, atol=0)


def test_fold_orders_has_the_gradient_of_the_prior_at_all_orders():
    """With v~ = [v; 0] (the orders above d not estimated), the gradient on v of
    1/2 (v~ - eta~)' S (v~ - eta~) is S_00 (v - folded), folded the prior mean fold_orders gives."""
    rng = np.random.default_rng(4)
    P, Q, r, s = 6, 2, 3, 0.7
    table = rng.normal(size=(5, P, r))
    folded = fold_orders(table, Q, s)
    assert folded.shape == (5, Q, r)
    S = smoothness_precision(P, s)
    for k in range(5):
        v = rng.normal(size=(Q, r))
        padded = np.vstack([v, np.zeros((P - Q, r))])
        gradient = (S @ (padded - table[k]))[:Q]
        np.testing.assert_allclose(gradient, S[:Q, :Q] @ (v - folded[k]), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n_orders, width", [(3, 1e200), (7, 1e60)])
def test_a_kernel_width_beyond_the_floating_point_range_is_named(n_orders, width):
    """(2 s^2)^k overflows: an error naming kernel_width, not inf (or an OverflowError) in S and V."""
    with pytest.raises(AttendInputError, match="kernel_width: .* outside the floating-point range"):
        smoothness_precision(n_orders, width)
    with pytest.raises(AttendInputError, match="kernel_width"):
        temporal_covariance(n_orders, 1.0 / width)
