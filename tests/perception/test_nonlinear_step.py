"""The lean D-step (StepWorkspace) and its linear algebra against the reference formulas."""

import numpy as np
import pytest
from scipy.linalg import expm

from attend.experiments import lorenz, pendulum
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear._linalg import expm_last_column, inverse_diagonals
from attend.perception.nonlinear._workspace import StepWorkspace


def _pendulum(**settings):
    return NonlinearDEM(pendulum.pendulum_system(), 0.05, kernel_width=0.1, sensor_precision=1 / 0.05**2,
                        process_precision=1 / np.array([0.05, 0.5])**2, embedding_order=6, input_order=2, **settings)


CASES = {
    "lorenz": lambda **kw: NonlinearDEM(lorenz.lorenz_system(), 0.01, kernel_width=0.02, sensor_precision=1.0,
                                        process_precision=1 / 400, **kw),
    "pendulum unknown input": lambda **kw: _pendulum(input_prior_precision=0.1, input_kernel_width=0.7, **kw),
    "pendulum known input": lambda **kw: _pendulum(known_inputs=True, **kw),
    "lorenz p = 0": lambda **kw: NonlinearDEM(lorenz.lorenz_system(), 0.01, kernel_width=0.02, sensor_precision=1.0,
                                              process_precision=1 / 400, embedding_order=0, **kw),
    "pendulum p = 1 < d": lambda **kw: NonlinearDEM(pendulum.pendulum_system(), 0.05, kernel_width=0.1,
                                                    sensor_precision=400.0, process_precision=4.0,
                                                    input_prior_precision=0.1, embedding_order=1, input_order=3, **kw),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("flow_time", ["samples", "seconds"])
@pytest.mark.parametrize("substeps", [1, 2])
def test_lean_step_equals_the_reference_step(case, flow_time, substeps):
    dem = CASES[case](flow_time=flow_time, substeps=substeps)
    rng = np.random.default_rng(3)
    size = dem.n_state_coordinates + dem.n_input_coordinates
    m, r = dem.system.n_outputs, dem.system.n_inputs
    workspace = StepWorkspace(dem)
    scale = dem.generalized_matrices()["order_scale"] if flow_time == "samples" else np.ones(size)
    for _ in range(3):  # the workspace's arrays are reused: several different states in a row
        X = rng.standard_normal(size) / scale ** 0.5  # higher orders larger, as in real runs
        X[: dem.system.n_states] = rng.uniform(-2, 2, dem.system.n_states)
        y_tilde = rng.standard_normal(m * (dem.embedding_order + 1))
        u_tilde = rng.standard_normal(r * (dem.input_order + 1))
        X_ref, curvature_ref = dem.dstep(X, y_tilde, u_tilde)
        # rounding differs (sums in another order) and the stiff flow (|J| ~ 1e5) amplifies it
        X_new, curvature = workspace.step(X, y_tilde, u_tilde, substeps)
        np.testing.assert_allclose(X_new, X_ref, rtol=1e-9, atol=1e-12 * np.abs(X_ref).max())
        # the lean step's curvature is in the flow's units: inv(S) E' Pi E inv(S)
        np.testing.assert_allclose(curvature * np.outer(scale, scale), curvature_ref, rtol=1e-11,
                                   atol=1e-12 * np.abs(curvature_ref).max())
        gradient, curvature, energy = workspace.gradient_curvature(X, y_tilde, u_tilde)
        gradient_ref, curvature_ref, energy_ref = dem._gradient_curvature(X, y_tilde, u_tilde)
        np.testing.assert_allclose(gradient, gradient_ref, rtol=1e-11, atol=1e-12 * np.abs(gradient_ref).max())
        np.testing.assert_allclose(curvature, curvature_ref, rtol=1e-11, atol=1e-12 * np.abs(curvature_ref).max())
        assert energy == pytest.approx(energy_ref, rel=1e-12)


def test_inverse_diagonals_equal_the_inverse_and_survive_a_singular_matrix():
    rng = np.random.default_rng(0)
    units = 10.0 ** rng.uniform(-6, 6, 9)  # coordinates in very different units
    factors = rng.standard_normal((5, 9, 14)) * units[None, :, None]
    matrices = factors @ factors.transpose(0, 2, 1)
    wanted = np.array([0, 1, 4])
    reference = np.array([np.diag(np.linalg.inv(matrix))[wanted] for matrix in matrices])
    np.testing.assert_allclose(inverse_diagonals(matrices, wanted), reference, rtol=1e-9)
    singular = matrices.copy()
    singular[2, :, 3] = singular[2, 3, :] = 0.0  # a coordinate without information: pseudo-inverse
    out = inverse_diagonals(singular, wanted)
    np.testing.assert_allclose(out[[0, 1, 3, 4]], reference[[0, 1, 3, 4]], rtol=1e-9)
    assert np.all(np.isfinite(out[2]))


def test_expm_last_column_reuses_its_work_array_and_equals_scipy():
    rng = np.random.default_rng(1)
    work = np.empty((5, 8, 8))
    for norm in (0.1, 10.0, 1e5):  # no squaring, some, many (stiff)
        block = np.zeros((8, 8))
        block[:7] = rng.standard_normal((7, 8))
        block[:7, :7] -= np.diag(rng.uniform(0, norm, 7))
        kept = block.copy()
        column = expm_last_column(block, work)
        np.testing.assert_array_equal(block, kept)
        np.testing.assert_allclose(column, expm(block)[:-1, -1], rtol=1e-12, atol=1e-14)


def test_expm_last_column_checks_its_route_once_and_falls_back(monkeypatch):
    from attend.perception.nonlinear import _linalg

    rng = np.random.default_rng(2)
    block = np.zeros((6, 6))
    block[:5] = rng.standard_normal((5, 6)) * 50.0  # norm ~ 100: squarings
    reference = expm(block)[:-1, -1]
    # a dgemm that rounds differently from NumPy's products: the check keeps NumPy's squaring
    monkeypatch.setattr(_linalg, "_fast_path", dict(checked=False, usable=True, squaring="dgemm"))
    monkeypatch.setattr(_linalg, "dgemm", lambda alpha, a, b: (a @ b) * (1 + 1e-15))
    np.testing.assert_array_equal(expm_last_column(block), reference)
    assert _linalg._fast_path == dict(checked=True, usable=True, squaring="matmul")
    np.testing.assert_array_equal(expm_last_column(block), reference)
    # neither route equals scipy.linalg.expm: scipy.linalg.expm from then on
    monkeypatch.setattr(_linalg, "_fast_path", dict(checked=False, usable=True, squaring="dgemm"))
    monkeypatch.setattr(_linalg, "expm", lambda matrix: expm(matrix) * (1 + 1e-12))
    np.testing.assert_array_equal(expm_last_column(block), reference * (1 + 1e-12))
    assert _linalg._fast_path["usable"] is False
    np.testing.assert_array_equal(expm_last_column(block), reference * (1 + 1e-12))


def test_the_start_of_the_flow_is_searched_once_per_first_sample(monkeypatch):
    """NonlinearDEM.initial_state keeps what Gauss-Newton found for a first sample: the D-step on the
    whole log and on its first samples (as attend estimate runs them) search once, and give the
    estimates of a fresh estimator to the bit."""
    import attend.perception.nonlinear.dem as dem_module
    from attend.models import simulate_nonlinear

    dem = CASES["lorenz"]()
    log = simulate_nonlinear(dem.system, 60, dem.dt, kernel_width=0.02, process_std=20.0, measurement_std=1.0,
                             initial_state=[1.0, 1.0, 20.0], seed=2)
    searches = []
    search = dem_module.gauss_newton_start

    def counted(*args, **kwargs):
        searches.append(1)
        return search(*args, **kwargs)

    monkeypatch.setattr(dem_module, "gauss_newton_start", counted)
    whole = dem.estimate(log.outputs)
    first = dem.estimate(log.outputs[:20])
    again = dem.estimate(log.outputs)
    assert len(searches) == 1
    np.testing.assert_array_equal(again.states, whole.states)
    for outputs, estimate in ((log.outputs, whole), (log.outputs[:20], first)):
        np.testing.assert_array_equal(CASES["lorenz"]().estimate(outputs).states, estimate.states)
    assert len(searches) == 3
    dem.estimate(log.outputs, initial_state=[1.0, 1.0, 20.0])  # another guess: another search
    assert len(searches) == 4
