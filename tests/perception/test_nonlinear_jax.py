"""backend="jax": the compiled D-step against the NumPy D-step (the oracle: the same equations,
tests/perception/test_nonlinear_step.py checks it against the reference formulas), and its errors."""

import sys
import warnings

import numpy as np
import pytest
from scipy.linalg import expm

from attend._validation import AttendInputError
from attend.experiments import lorenz, pendulum
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear import NonlinearDEM

jax = pytest.importorskip("jax")
jnp = jax.numpy
from attend.perception.nonlinear import jax_backend  # noqa: E402  (after the skip)


def lorenz_jax():
    return lorenz.build_jax_system(lorenz.SETTINGS)


def pendulum_jax():
    return pendulum.build_jax_system(pendulum.SETTINGS)


@pytest.fixture(scope="module")
def lorenz_log():
    cfg = lorenz.SETTINGS
    return simulate_nonlinear(lorenz.lorenz_system(), 150, cfg["dt"], kernel_width=cfg["kernel_width"],
                              process_std=20.0, measurement_std=1.0, initial_state=cfg["initial_state"], seed=4)


@pytest.fixture(scope="module")
def pendulum_log():
    time = np.arange(160) * 0.05
    return simulate_nonlinear(pendulum.pendulum_system(), pendulum.true_input(time), 0.05, kernel_width=0.1,
                              process_std=[0.05, 0.5], measurement_std=0.05, initial_state=[0.5, 0.0], seed=2)


def _relative(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def _agree(numpy_estimate, jax_estimate, tolerance=1e-8):
    assert _relative(jax_estimate.states, numpy_estimate.states) < tolerance
    assert _relative(jax_estimate.state_std, numpy_estimate.state_std) < tolerance
    assert _relative(jax_estimate.generalized, numpy_estimate.generalized) < tolerance
    if numpy_estimate.inputs.size and np.any(numpy_estimate.inputs):
        assert _relative(jax_estimate.inputs, numpy_estimate.inputs) < tolerance
        if np.any(numpy_estimate.input_std):
            assert _relative(jax_estimate.input_std, numpy_estimate.input_std) < tolerance


def test_lorenz_equals_the_numpy_step(lorenz_log):
    numpy_dem = NonlinearDEM(lorenz.lorenz_system(), 0.01, kernel_width=0.02, sensor_precision=1.0,
                             process_precision=1 / 400)
    jax_dem = NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                           backend="jax")
    _agree(numpy_dem.estimate(lorenz_log.outputs, keep_generalized=True),
           jax_dem.estimate(lorenz_log.outputs, keep_generalized=True))
    # a second log of another length reuses the compiled chunk (rows past the log are skipped)
    short = lorenz_log.outputs[:37]
    _agree(numpy_dem.estimate(short, keep_generalized=True), jax_dem.estimate(short, keep_generalized=True))


@pytest.mark.parametrize("settings", [
    dict(input_prior_precision=0.1, input_kernel_width=0.7, edges="clamp", substeps=2),
    dict(known_inputs=True),
], ids=["unknown input, clamp, 2 substeps", "known input"])
def test_pendulum_equals_the_numpy_step(pendulum_log, settings):
    build = dict(dt=0.05, kernel_width=0.1, sensor_precision=1 / 0.05**2,
                 process_precision=1 / np.array([0.05, 0.5])**2, embedding_order=6, input_order=2, **settings)
    inputs = pendulum_log.inputs if settings.get("known_inputs") else None
    numpy_dem = NonlinearDEM(pendulum.pendulum_system(), **build)
    jax_dem = NonlinearDEM(pendulum_jax(), backend="jax", **build)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the same misfit warning (or none) from both
        _agree(numpy_dem.estimate(pendulum_log.outputs, inputs, keep_generalized=True),
               jax_dem.estimate(pendulum_log.outputs, inputs, keep_generalized=True))


def test_linear_model_in_seconds_equals_the_numpy_step():
    """flow_time="seconds" (the linear observer's flow) on a mass-spring-damper with a known push."""
    A, B, C = np.array([[0.0, 1.0], [-2.0, -0.7]]), np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    numpy_system = NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, 2, 1, 1)
    jax_system = NonlinearSystem(lambda x, v: jnp.asarray(A) @ x + jnp.asarray(B) @ v,
                                 lambda x, v: jnp.asarray(C) @ x, 2, 1, 1)
    time = np.arange(120) * 0.05
    push = np.sin(time)[:, None]
    log = simulate_nonlinear(numpy_system, push, 0.05, kernel_width=0.1, process_std=0.1, measurement_std=0.1, seed=1)
    build = dict(dt=0.05, kernel_width=0.1, sensor_precision=100.0, process_precision=100.0, embedding_order=4,
                 input_order=2, known_inputs=True, flow_time="seconds")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _agree(NonlinearDEM(numpy_system, **build).estimate(log.outputs, push, keep_generalized=True),
               NonlinearDEM(jax_system, backend="jax", **build).estimate(log.outputs, push, keep_generalized=True))


def test_expm_last_column_equals_scipy():
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 30.0, 5e4):  # no squaring up to ~14 squarings
        G = rng.standard_normal((12, 8))
        block = np.zeros((9, 9))  # [[D - H, b], [0, 0]]: the D-step's stable flow, H = G'G curvature
        block[:8, :8] = np.eye(8, k=1) - scale * (G.T @ G / 12 + 0.1 * np.eye(8))
        block[:8, 8] = scale * rng.standard_normal(8)
        with jax_backend._double_precision(jax):
            column = np.asarray(jax.jit(lambda b: jax_backend._expm_last_column(jnp, jax.lax, b))(block))
        reference = expm(block)[:-1, -1]
        # rounding grows with the squarings (16 at scale 5e4: SciPy's own error is 2e-12 there, this 7e-12)
        assert np.max(np.abs(column - reference)) <= 1e-10 * np.max(np.abs(reference))


def test_misfit_ratio_equals_the_numpy_check(lorenz_log):
    from attend.perception.nonlinear.misfit import sample_misfit
    dem = NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                       backend="jax")
    with jax_backend._double_precision(jax):
        generalized = dem.estimate(lorenz_log.outputs, keep_generalized=True).generalized
        signals = dem.checked_signals(lorenz_log.outputs, None)
        y_tilde, u_tilde = jax_backend.embedded_rows(dem, signals)
        compiled = jax_backend._misfit(dem, generalized, y_tilde, u_tilde)
        reference = sample_misfit(dem, signals, generalized)
    assert compiled == pytest.approx(reference, rel=1e-10)


def test_the_callers_precision_setting_is_kept(lorenz_log):
    before = jax.config.jax_enable_x64
    NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                 backend="jax").estimate(lorenz_log.outputs[:20])
    assert jax.config.jax_enable_x64 == before


def test_divergence_is_an_error_naming_the_sample(lorenz_log):
    dem = NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                       backend="jax", divergence_limit=30.0)
    with pytest.raises(AttendInputError, match="diverged at sample"):
        dem.estimate(lorenz_log.outputs * 3)


def test_numpy_functions_get_an_error_naming_jax_numpy(lorenz_log):
    dem = NonlinearDEM(lorenz.lorenz_system(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                       backend="jax")
    with pytest.raises(AttendInputError, match="jax.numpy"):
        dem.estimate(lorenz_log.outputs[:20])


def test_a_wrong_shape_names_the_function(lorenz_log):
    system = NonlinearSystem(lambda x, v: x[:2], lambda x, v: 1.0 * x, 3, 0, 3)
    with pytest.raises(AttendInputError, match=r"f: expected 3 values \(a 1-D array\), got shape \(2,\)"):
        NonlinearDEM(system, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                     backend="jax").estimate(lorenz_log.outputs[:20])


@pytest.mark.parametrize("setting", [dict(motion="path"), dict(integration="spm"), dict(states="path")])
def test_settings_the_compiled_step_does_not_run_are_refused(setting):
    with pytest.raises(AttendInputError, match="backend: 'jax' runs the D-step with"):
        NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                     backend="jax", **setting)


def test_unknown_backend_is_refused():
    with pytest.raises(AttendInputError, match="backend: expected 'numpy' or 'jax'"):
        NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                     backend="torch")


def test_missing_jax_says_how_to_install(monkeypatch):
    system = lorenz_jax()
    monkeypatch.setitem(sys.modules, "jax", None)  # import jax now raises ImportError
    with pytest.raises(AttendInputError, match=r"attend\[jax\]"):
        NonlinearDEM(system, 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400, backend="jax")


def test_linear_model_equals_the_linear_observer():
    """A linear model written as f, g in jax.numpy, flow_time="seconds": the linear DEM observer's
    estimates once the two starts have decayed, and its Laplace std (the NumPy step's oracle, in
    tests/perception/test_nonlinear.py)."""
    from attend.models.linear import LinearSystem, simulate
    from attend.perception.dem import DEMObserver

    A, B, C = np.array([[0.0, 1.0], [-2.0, -0.7]]), np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]])
    linear = LinearSystem(A, B, C)
    jax_system = NonlinearSystem(lambda x, v: jnp.asarray(A) @ x + jnp.asarray(B) @ v,
                                 lambda x, v: jnp.asarray(C) @ x, 2, 1, 1)
    dt, time = 0.1, np.arange(200) * 0.1
    u = np.exp(-0.25 * (time - 8.0) ** 2)[:, None]
    log = simulate(linear, u, dt, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=3)
    settings = dict(dt=dt, kernel_width=0.5, sensor_precision=np.exp(8), process_precision=np.exp(8),
                    input_prior_precision=np.exp(-8), embedding_order=6, input_order=2)
    observer = DEMObserver(linear, **settings)
    reference = observer.estimate(log.outputs)
    estimate = NonlinearDEM(jax_system, flow_time="seconds", backend="jax", **settings).estimate(log.outputs)
    scale, late = np.abs(reference.states).max(), slice(100, None)
    np.testing.assert_allclose(estimate.states[late], reference.states[late], atol=1e-5 * scale)
    np.testing.assert_allclose(estimate.inputs[late], reference.inputs[late],
                               atol=1e-5 * max(1.0, np.abs(reference.inputs).max()))
    laplace = np.sqrt(np.diag(observer.generalized_matrices()["Sigma_X"]))
    np.testing.assert_allclose(estimate.state_std, np.broadcast_to(laplace[:2], estimate.state_std.shape), rtol=1e-6)


def test_an_estimate_that_leaves_the_data_is_an_error(lorenz_log, monkeypatch):
    """The compiled check of the predicted outputs (g vmapped) against the log, as the NumPy step's:
    a flow shifted 1e4 away in x2 (below divergence_limit) is an error naming y2."""
    flow = jax_backend._flow

    def shifted(*args):
        rows, curvatures, variances = flow(*args)
        rows[60:, 1] += 1e4
        return rows, curvatures, variances

    monkeypatch.setattr(jax_backend, "_flow", shifted)
    with warnings.catch_warnings(), pytest.raises(AttendInputError, match=r"NonlinearDEM: the estimate left the "
                                                                          r"data: at sample \d+ the predicted y2"):
        warnings.simplefilter("ignore")  # the misfit warning comes first
        NonlinearDEM(lorenz_jax(), 0.01, kernel_width=0.02, sensor_precision=1.0, process_precision=1 / 400,
                     backend="jax").estimate(lorenz_log.outputs)
