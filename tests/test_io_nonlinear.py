"""Nonlinear model files: [model] python = "model.py" with f and g, through `attend estimate`."""

import numpy as np
import pytest

from attend import io, workflows
from attend._validation import AttendInputError
from attend.cli import main

PENDULUM_PY = '''
import numpy as np

parameters = {"gravity_over_length": 9.81, "damping": 0.3}


def f(x, v, parameters):
    return np.array([x[1], -parameters["gravity_over_length"] * np.sin(x[0]) - parameters["damping"] * x[1] + v[0]])


def g(x, v, parameters):
    return np.array([np.sin(x[0]), np.cos(x[0])])
'''

PENDULUM_TOML = '''
[model]
python = "model.py"
n_states = 2
n_inputs = 1
n_outputs = 2
states = ["theta", "omega"]

[outputs]
columns = ["sin", "cos"]

[[inputs]]
name = "push"
prior_mean = 0.0
prior_precision = 0.135

[observer]
kernel_width = 0.1
input_kernel_width = 0.7
sensor_precision = 400.0
process_precision = [400.0, 4.0]
'''

LORENZ_PY = '''
import numpy as np


def f(x, v):
    return np.array([10.0 * (x[1] - x[0]), x[0] * (28.0 - x[2]) - x[1], x[0] * x[1] - 8.0 / 3.0 * x[2]])


def g(x, v):
    return x
'''

LORENZ_TOML = '''
[model]
python = "lorenz.py"
n_states = 3
n_inputs = 0
n_outputs = 3

[outputs]
columns = ["y1", "y2", "y3"]

[observer]
kernel_width = 0.02
sensor_precision = 1.0
process_precision = 0.0025
'''


def _pendulum_files(tmp_path, model=PENDULUM_TOML, code=PENDULUM_PY, samples=200):
    from attend.experiments.pendulum import pendulum_system, true_input
    from attend.models import simulate_nonlinear

    (tmp_path / "model.py").write_text(code)
    (tmp_path / "model.toml").write_text(model)
    t = np.arange(samples) * 0.05
    log = simulate_nonlinear(pendulum_system(), true_input(t + 3.0), 0.05, kernel_width=0.1,
                             process_std=[0.05, 0.5], measurement_std=0.05, initial_state=[0.5, 0.0], seed=3)
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, log.outputs]), delimiter=",", header="t,sin,cos",
               comments="", fmt="%.10g")
    return tmp_path / "model.toml", tmp_path / "log.csv", log


def _lorenz_files(tmp_path, model=LORENZ_TOML, code=LORENZ_PY, samples=120):
    from attend.experiments.lorenz import lorenz_system
    from attend.models import simulate_nonlinear

    (tmp_path / "lorenz.py").write_text(code)
    (tmp_path / "lorenz.toml").write_text(model)
    log = simulate_nonlinear(lorenz_system(), samples, 0.01, kernel_width=0.02, process_std=20.0,
                             measurement_std=1.0, initial_state=[1.0, 1.0, 24.0], seed=0)
    t = np.arange(samples) * 0.01
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, log.outputs]), delimiter=",", header="t,y1,y2,y3",
               comments="", fmt="%.10g")
    return tmp_path / "lorenz.toml", tmp_path / "log.csv", log


@pytest.mark.parametrize("method", ["ukf", "dem"])
def test_pendulum_from_files_estimates_states_and_the_push(tmp_path, method):
    model_path, log_path, truth = _pendulum_files(tmp_path, PENDULUM_TOML.replace(
        "[observer]", f'[observer]\nmethod = "{method}"'))
    model = io.read_model(model_path)
    assert model.nonlinear and model.method == method
    log = io.read_log(log_path)
    estimator, estimate = workflows.estimate_from_files(model, log)
    inner = slice(10, -10)
    theta_error = estimate.states[inner, 0] - truth.states[inner, 0]
    assert np.sqrt(np.mean(theta_error**2)) < 0.05  # rad; the sensor noise is 0.05 per component
    input_error = estimate.inputs[inner, 0] - truth.inputs[inner, 0]
    assert np.sqrt(np.mean(input_error**2)) < 0.6 * np.sqrt(np.mean(truth.inputs[inner, 0] ** 2))
    out = io.write_estimates(tmp_path / "out.csv", log, model.system, estimate)
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["t", "theta", "omega", "push", "theta_std", "omega_std", "push_std"]


def test_the_unknown_push_width_is_chosen_from_the_log_when_the_file_gives_none(tmp_path, capsys):
    """method "ukf" without input_kernel_width: the width of largest (profiled) likelihood of the unscented
    filter, as for linear models; reported, used by the smoother, and on this log closer to the push than
    the kernel width the file would otherwise lend it (input RMS error 0.44 against 0.53)."""
    from dataclasses import replace

    model_path, log_path, truth = _pendulum_files(tmp_path, PENDULUM_TOML.replace("input_kernel_width = 0.7\n", ""))
    model, log = io.read_model(model_path), io.read_log(log_path)
    assert model.input_kernel_width is None
    estimator, estimate = workflows.estimate_from_files(model, log)
    choice = estimator.input_width_choice
    assert choice is not None and not choice.flat and estimator.input_kernel_width == choice.width
    assert choice.width == choice.widths[np.argmax(choice.log_likelihoods)] and choice.width > model.kernel_width
    _, at_kernel_width = workflows.estimate_from_files(replace(model, input_kernel_width=model.kernel_width), log)
    inner = slice(10, -10)

    def input_rms(values):
        return np.sqrt(np.mean((values.inputs[inner, 0] - truth.inputs[inner, 0]) ** 2))

    assert input_rms(estimate) < 0.9 * input_rms(at_kernel_width)
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "e.csv")]) == 0
    captured = capsys.readouterr()
    assert f"input prior width {choice.width:g} s" in captured.err and "chosen from the log" in captured.err
    assert f"(width {choice.width:g} s, chosen from the log)" in captured.out
    given, _ = workflows.estimate_from_files(io.read_model(_pendulum_files(tmp_path)[0]), log)
    assert given.input_width_choice is None and given.input_kernel_width == 0.7  # the file's width is kept


def test_the_default_for_nonlinear_models_is_the_unscented_smoother(tmp_path, capsys):
    model_path, log_path, _ = _lorenz_files(tmp_path)
    out = tmp_path / "est.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "method ukf (unscented Kalman smoother, the default for nonlinear models" in text
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "t,x1,x2,x3,x1_std,x2_std,x3_std"  # no inputs: x1..xn only
    assert table.shape == (120, 7) and np.all(np.isfinite(table))


def test_the_default_smoothers_std_is_calibrated_under_the_files_coloured_noise(tmp_path):
    """method "ukf" reports the smoother's error spread under the file's coloured noise (s/dt = 2):
    |error| < 2 std in ~95 % of the samples of 3 simulated Lorenz logs (the white-noise model's
    own std covered 61-73 %)."""
    from attend.experiments.lorenz import lorenz_system
    from attend.models import simulate_nonlinear

    (tmp_path / "lorenz.py").write_text(LORENZ_PY)
    (tmp_path / "lorenz.toml").write_text(LORENZ_TOML)
    model = io.read_model(tmp_path / "lorenz.toml")
    inside = []
    for seed in range(3):
        truth = simulate_nonlinear(lorenz_system(), 400, 0.01, kernel_width=0.02, process_std=20.0,
                                   measurement_std=1.0, initial_state=[1.0, 1.0, 24.0], seed=seed)
        np.savetxt(tmp_path / "log.csv", np.column_stack([np.arange(400) * 0.01, truth.outputs]), delimiter=",",
                   header="t,y1,y2,y3", comments="", fmt="%.10g")
        _, estimate = workflows.estimate_from_files(model, io.read_log(tmp_path / "log.csv"))
        inner = slice(10, -10)
        inside.append(np.mean(np.abs(estimate.states - truth.states)[inner] < 2 * estimate.state_std[inner], axis=0))
    assert np.all((np.mean(inside, axis=0) > 0.90) & (np.mean(inside, axis=0) < 0.99)), np.mean(inside, axis=0)


def test_lorenz_without_inputs_by_dem_beats_the_raw_data(tmp_path, capsys):
    model_path, log_path, truth = _lorenz_files(tmp_path, LORENZ_TOML + 'method = "dem"\nembedding_order = 6\n')
    out = tmp_path / "est.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0
    assert "method dem (nonlinear DEM" in capsys.readouterr().out
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    inner = slice(10, -10)
    error = np.mean((table[inner, 1:4] - truth.states[inner]) ** 2)
    raw = np.mean((truth.outputs[inner] - truth.states[inner]) ** 2)
    assert error < raw


def test_spm_integration_from_a_nonlinear_model_file(tmp_path):
    """[observer] integration = "spm", edges = "clamp", initial_state reach NonlinearDEM: the
    estimates are those of NonlinearDEM built with the same options (docs/spm.md)."""
    from attend.perception.nonlinear import NonlinearDEM

    extra = 'method = "dem"\nembedding_order = 6\nintegration = "spm"\nedges = "clamp"\ninitial_state = [1.0, 1.0, 24.0]\n'
    model_path, log_path, _ = _lorenz_files(tmp_path, LORENZ_TOML + extra)
    model, log = io.read_model(model_path), io.read_log(log_path)
    estimator, estimate = workflows.estimate_from_files(model, log)
    dem = estimator.dem()
    assert (dem.integration, dem.edges) == ("spm", "clamp")
    direct = NonlinearDEM(dem.system, dem.dt, kernel_width=dem.kernel_width, sensor_precision=dem.sensor_precision,
                          process_precision=dem.process_precision, embedding_order=6, integration="spm", edges="clamp")
    expected = direct.estimate(log.matrix(["y1", "y2", "y3"]), initial_state=[1.0, 1.0, 24.0])
    np.testing.assert_allclose(estimate.states, expected.states, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(estimate.states[0], [1.0, 1.0, 24.0])  # SPM: row 0 is the start


def test_path_mode_from_a_nonlinear_model_file(tmp_path, capsys):
    """[observer] states = "path" (with method = "dem") reaches NonlinearDEM(states="path"): the
    CLI's estimates are those of the estimator built directly, std included."""
    from attend.perception.nonlinear import NonlinearDEM

    extra = 'method = "dem"\nembedding_order = 6\nstates = "path"\n'
    model_path, log_path, truth = _lorenz_files(tmp_path, LORENZ_TOML + extra)
    model, log = io.read_model(model_path), io.read_log(log_path)
    estimator, estimate = workflows.estimate_from_files(model, log)
    dem = estimator.dem()
    assert dem.states == "path"
    direct = NonlinearDEM(dem.system, dem.dt, kernel_width=dem.kernel_width, sensor_precision=dem.sensor_precision,
                          process_precision=dem.process_precision, embedding_order=6,
                          states="path").estimate(log.matrix(["y1", "y2", "y3"]))
    np.testing.assert_allclose(estimate.states, direct.states, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(estimate.state_std, direct.state_std, rtol=1e-12)
    out = tmp_path / "path.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0, capsys.readouterr().err
    assert out.exists()


def test_the_files_motion_reaches_nonlinear_dem(tmp_path):
    """[observer] motion = "path" (with method = "dem") builds NonlinearDEM(motion="path"); without
    it the estimate uses SPM's linearised motion."""
    from attend.perception.nonlinear import NonlinearDEM

    for extra, motion in (('motion = "path"\n', "path"), ("", "linearized")):
        model_path, log_path, _ = _lorenz_files(tmp_path, LORENZ_TOML + 'method = "dem"\nembedding_order = 6\n' + extra)
        model, log = io.read_model(model_path), io.read_log(log_path)
        estimator, estimate = workflows.estimate_from_files(model, log)
        dem = estimator.dem()
        assert dem.motion == motion
        direct = NonlinearDEM(dem.system, dem.dt, kernel_width=dem.kernel_width, sensor_precision=dem.sensor_precision,
                              process_precision=dem.process_precision, embedding_order=6,
                              motion=motion).estimate(log.matrix(["y1", "y2", "y3"]))
        np.testing.assert_allclose(estimate.states, direct.states, rtol=1e-12, atol=1e-12)


def test_path_mode_takes_the_files_initial_state_as_a_prior(tmp_path):
    """[observer] initial_state (std 0: known) reaches path mode as a prior on x[0] with std
    1e-6 (1 + |x0|); initial_state_std, when given, is used as it is."""
    from attend.perception.nonlinear import NonlinearDEM

    for std_line, std in (("", 1e-6 * (1 + np.abs([1.0, 1.0, 24.0]))), ("initial_state_std = 0.5\n", 0.5)):
        extra = f'method = "dem"\nembedding_order = 6\nstates = "path"\ninitial_state = [1.0, 1.0, 24.0]\n{std_line}'
        model_path, log_path, _ = _lorenz_files(tmp_path, LORENZ_TOML + extra, samples=80)
        model, log = io.read_model(model_path), io.read_log(log_path)
        estimator, estimate = workflows.estimate_from_files(model, log)
        dem = estimator.dem()
        direct = NonlinearDEM(dem.system, dem.dt, kernel_width=dem.kernel_width, sensor_precision=dem.sensor_precision,
                              process_precision=dem.process_precision, embedding_order=6, states="path").estimate(
            log.matrix(["y1", "y2", "y3"]), initial_state=[1.0, 1.0, 24.0], initial_state_std=std)
        np.testing.assert_allclose(estimate.states, direct.states, rtol=1e-12, atol=1e-12)


def test_path_mode_is_refused_for_linear_models(tmp_path, capsys):
    (tmp_path / "m.toml").write_text('[model]\nA = [[-1.0]]\nB = [[1.0]]\nC = [[1.0]]\n\n[outputs]\ncolumns = ["y"]\n\n'
                                     '[[inputs]]\nname = "u"\n\n[observer]\nmethod = "dem"\nstates = "path"\n'
                                     'kernel_width = 0.1\nsensor_precision = 1.0\nprocess_precision = 1.0\n')
    with pytest.raises(AttendInputError, match="states: DEM's path mode is for nonlinear models"):
        io.read_model(tmp_path / "m.toml")


def test_parameters_from_the_model_file_override_the_python_file(tmp_path):
    model_path, _, _ = _pendulum_files(tmp_path, PENDULUM_TOML.replace(
        'states = ["theta", "omega"]', 'states = ["theta", "omega"]\nparameters = { damping = 2.0 }'))
    system = io.read_model(model_path).system
    np.testing.assert_allclose(system.flow([0.0, 1.0], [0.0]), [1.0, -2.0])
    code = PENDULUM_PY.replace('parameters = {"gravity_over_length": 9.81, "damping": 0.3}', "")
    model_path, _, _ = _pendulum_files(tmp_path, PENDULUM_TOML.replace(
        'states = ["theta", "omega"]', 'parameters = { gravity_over_length = 1.0, damping = 0.5 }'), code)
    system = io.read_model(model_path).system
    np.testing.assert_allclose(system.flow([np.pi / 2, 1.0], [0.25]), [1.0, -1.0 - 0.5 + 0.25])
    assert system.state_names == ("x1", "x2")


def test_measured_and_unknown_inputs_together(tmp_path):
    code = '''
import numpy as np

def f(x, v):
    return np.array([x[1], -9.81 * np.sin(x[0]) - 0.3 * x[1] + v[0] + v[1]])

def g(x, v):
    return np.array([np.sin(x[0]), np.cos(x[0])])
'''
    model = PENDULUM_TOML.replace("n_inputs = 1", "n_inputs = 2") + (
        '\n[[inputs]]\nname = "motor"\ncolumn = "sin"\noperating_point = 0.5\n').replace("[observer]", "")
    model = model.replace("\nkernel_width = 0.1", "\n[observer]\nkernel_width = 0.1")
    model = model.replace("[observer]\nkernel_width = 0.1\ninput_kernel_width",
                          "kernel_width = 0.1\ninput_kernel_width")
    model_path, log_path, _ = _pendulum_files(tmp_path, model, code, samples=60)
    parsed = io.read_model(model_path)
    log = io.read_log(log_path)
    for method in ("ukf", "dem"):
        parsed = io.ModelFile(**{**parsed.__dict__, "method": method})
        _, estimate = workflows.estimate_from_files(parsed, log)
        if method == "ukf":  # the measured input is the column minus its operating point, std 0
            np.testing.assert_allclose(estimate.inputs[:, 1], log.columns["sin"] - 0.5)
            assert np.all(estimate.input_std[:, 1] == 0)
        assert np.all(np.isfinite(estimate.inputs[:, 0]))


def _error(tmp_path, capsys, model=PENDULUM_TOML, code=PENDULUM_PY):
    model_path, log_path, _ = _pendulum_files(tmp_path, model, code, samples=40)
    status = main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "e.csv")])
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.startswith("attend: error: ") and "internal error" not in err and len(err.strip().splitlines()) == 1
    return err


@pytest.mark.parametrize("edit_model, edit_code, message", [
    (lambda m: m.replace('python = "model.py"', 'python = "missing.py"'), None,
     "[model] python: " ),
    (lambda m: m.replace('python = "model.py"', 'python = "."'), None, "is not a file"),
    (None, lambda c: c.replace("def g(", "def h("), "defines no function g"),
    (None, lambda c: c.replace("def f(", "def ff(").replace("f = 1", ""), "defines no function f"),
    (None, lambda c: c + "\nf = 3\n", "f is a int; expected a function f(x, v)"),
    (None, lambda c: c.replace("return np.array([np.sin(x[0]), np.cos(x[0])])", "return np.sin(x[0])"),
     "g(x, v) returned shape (); expected 2 values (y, one per output: [model] n_outputs = 2)"),
    (None, lambda c: c.replace("+ v[0]])", "+ v[0], 0.0])"),
     "f(x, v) returned shape (3,); expected 2 values (dx/dt, one per state: [model] n_states = 2)"),
    (None, lambda c: c.replace("def f(x, v, parameters):", "def f(x, v, parameters):\n    return None"),
     "f(x, v) returned NoneType"),
    (None, lambda c: c.replace('"damping": 0.3', '"damping": float("nan")'), "f(x, v) returned non-finite values"),
    (None, lambda c: c.replace('parameters["damping"]', 'parameters["dampin"]'),
     "f(x, v) failed (line 8): KeyError: 'dampin'"),
    (None, lambda c: c.replace("np.cos(x[0])])", "1 / float(x[0] - x[0])])"),
     "g(x, v) failed (line 12): ZeroDivisionError"),
    (None, lambda c: c + "\nraise RuntimeError('no licence')\n", "the model's code failed when loaded (line 14): "
     "RuntimeError: no licence"),
    (None, lambda c: c + "\ndef broken(:\n", "not valid Python"),
    (None, lambda c: c.replace("def f(x, v, parameters):", "def f(x):"), "f(x): expected f(x, v) or f(x, v, parameters)"),
    (None, lambda c: c.replace('parameters = {"gravity_over_length": 9.81, "damping": 0.3}', ""),
     "f and g take a third argument (the parameters) but neither the file nor the model file gives them"),
    (None, lambda c: c.replace('parameters = {"gravity_over_length": 9.81, "damping": 0.3}', "parameters = 3"),
     "parameters is a int; expected a dict"),
    (lambda m: m.replace("n_states = 2", "n_states = 2\nA = [[1.0]]"), None, "has both python"),
    (lambda m: m.replace("n_states = 2\n", ""), None, "[model] needs n_states"),
    (lambda m: m.replace("n_inputs = 1", "n_inputs = 1.5"), None, "[model] n_inputs: expected an integer"),
    (lambda m: m.replace("n_inputs = 1", "n_inputs = 2"), None, "n_inputs = 2 but the file has 1 [[inputs]] table"),
    (lambda m: m.replace('columns = ["sin", "cos"]', 'columns = ["sin"]'), None,
     "expected 2 column names (one per output of g: [model] n_outputs)"),
    (lambda m: m.replace("[observer]", '[observer]\nmethod = "kalman"'), None,
     "expected \"ukf\" or \"dem\" for a nonlinear model"),
    (lambda m: m.replace("[observer]", "[observer]\nprocess_kernel_width = 0.1"), None,
     "nonlinear models take one kernel_width"),
    (lambda m: m.replace("kernel_width = 0.1\n", ""), None, "[observer] needs kernel_width"),
    (lambda m: m.replace("input_kernel_width = 0.7", "input_kernel_width = 0"), None,
     "input_kernel_width: expected a number > 0"),
    (lambda m: m.replace("n_states = 2", "n_states = 2\nparameters = 3"), None, "[model] parameters: expected a table"),
    (lambda m: m.replace("[observer]", '[observer]\nstates = "path"'), None,
     "[observer] states: DEM's path mode is for nonlinear models with method = \"dem\""),
    (lambda m: m.replace("[observer]", '[observer]\nmethod = "dem"\nstates = "paths"'), None,
     "[observer] states: expected 'sample' or 'path', got 'paths'"),
    (lambda m: m.replace("process_precision = [400.0, 4.0]", "process_precision = [400.0, 0.0]"), None,
     "method \"ukf\" needs a positive definite precision"),
    (lambda m: m.replace("[observer]", '[observer]\nmotion = "path"'), None,
     "[observer] motion: the generalised motion f~ of nonlinear DEM (method = \"dem\""),
    (lambda m: m.replace("[observer]", '[observer]\nmethod = "dem"\nmotion = "curved"'), None,
     "[observer] motion: expected 'linearized' or 'path', got 'curved'"),
    (lambda m: m.replace("n_states = 2", "n_states = 2\nvectorized = 1"), None,
     "[model] vectorized: expected true or false"),
    (lambda m: m.replace("n_states = 2", "n_states = 2\nvectorized = true"),
     lambda c: c.replace("return np.array([np.sin(x[0]), np.cos(x[0])])",
                         "return np.array([np.sin(x[0]), np.cos(x[0])]).reshape(2, -1).mean(axis=1)"),
     "g(x, v) returned shape (2,) for 3 points given as columns; [model] vectorized = true expects (2, 3)"),
    (lambda m: m.replace("n_states = 2", "n_states = 2\nvectorized = true"),
     lambda c: c.replace("np.cos(x[0])])", "np.cos(x[0]) + 1e-3 * (np.sum(x) - np.sum(x, axis=0))])"),
     "[model] vectorized = true, but g(x, v) at 3 points given as columns differs from 3 calls"),
])
def test_nonlinear_model_errors_name_the_file_and_field(tmp_path, capsys, edit_model, edit_code, message):
    model = edit_model(PENDULUM_TOML) if edit_model else PENDULUM_TOML
    code = edit_code(PENDULUM_PY) if edit_code else PENDULUM_PY
    err = _error(tmp_path, capsys, model, code)
    assert message in err, err


def test_vectorized_model_files_give_the_same_estimates(tmp_path):
    # [model] vectorized = true: the unscented smoother moves its sigma points in one call of f
    estimates = []
    for flag in ("false", "true"):
        folder = tmp_path / flag
        folder.mkdir()
        model_path, log_path, _ = _pendulum_files(folder, PENDULUM_TOML.replace("n_states = 2", f"n_states = 2\n"
                                                                                f"vectorized = {flag}"), samples=80)
        model = io.read_model(model_path)
        assert model.system.vectorized == (flag == "true")
        estimates.append(workflows.estimate_from_files(model, io.read_log(log_path))[1])
    np.testing.assert_allclose(estimates[1].states, estimates[0].states, rtol=0, atol=1e-10)
    np.testing.assert_allclose(estimates[1].inputs, estimates[0].inputs, rtol=0, atol=1e-10)


def test_column_safe_functions_are_recognised_for_the_vectorized_hint(tmp_path):
    from attend.io.python_model import takes_columns

    model_path, _, _ = _pendulum_files(tmp_path, samples=20)
    model = io.read_model(model_path)
    assert takes_columns(model.system, model.initial_state, model.inputs)
    for code in (PENDULUM_PY.replace("np.cos(x[0])])", "np.cos(x[0]) + 1e-3 * (np.sum(x) - np.sum(x, axis=0))])"),
                 PENDULUM_PY.replace("return np.array([x[1],", "assert x.ndim == 1\n    return np.array([x[1],"),
                 PENDULUM_PY.replace("np.sin(x[0]), np.cos(x[0])])", "float(np.sin(x[0])), np.cos(x[0])])")):
        (tmp_path / "model.py").write_text(code)
        model = io.read_model(model_path)
        assert not takes_columns(model.system, model.initial_state, model.inputs)


def test_errors_in_the_users_code_say_so(tmp_path, capsys):
    code = PENDULUM_PY.replace('parameters["damping"]', 'parameters["dampin"]')
    err = _error(tmp_path, capsys, code=code)
    assert str(tmp_path / "model.py") in err and "this is an error in the model's code" in err


def test_identify_learns_a_nonlinear_parameter_with_an_unknown_push(tmp_path, capsys):
    """[learning] free = ["damping"] from a wrong start (0.8 for 0.3), the push unknown: the learned
    damping is within 3 of its std of the truth, written to [model] parameters (which `attend
    estimate` then uses) with its std in [learned]."""
    model = PENDULUM_TOML.replace('states = ["theta", "omega"]',
                                  'states = ["theta", "omega"]\nparameters = { damping = 0.8 }')
    model += '\n[learning]\nfree = ["damping"]\n'
    model_path, log_path, _ = _pendulum_files(tmp_path, model)
    out = tmp_path / "learned.toml"
    status = main(["identify", str(model_path), str(log_path), "--out", str(out)])
    printed = capsys.readouterr()
    assert status == 0, printed.err
    assert "damping" in printed.out and "learned model ->" in printed.out
    learned = io.read_model(out)
    damping = learned.system.f.parameters["damping"]
    import tomllib
    details = tomllib.loads(out.read_text())["learned"]
    assert details["parameter_names"] == ["damping"] and details["parameters"] == [damping]
    assert 0 < details["parameter_std"][0] < 0.5 and abs(damping - 0.3) < 3 * details["parameter_std"][0], details
    assert main(["estimate", str(out), str(log_path), "--out", str(tmp_path / "e.csv")]) == 0


@pytest.mark.parametrize("learning, message", [
    ('free = ["dampin"]', "[learning] free: 'dampin' is not a parameter of the model (its parameters: damping, "
                          "gravity_over_length)"),
    ('free = ["damping"]\nnoise_prior_mean = [0.0, 0.0]', "[learning] noise_prior_mean: not used for nonlinear models"),
    ("free = []", "[learning] free: expected a list of parameter names"),
])
def test_nonlinear_identify_errors_name_the_field(tmp_path, capsys, learning, message):
    model_path, log_path, _ = _pendulum_files(tmp_path, PENDULUM_TOML + "\n[learning]\n" + learning + "\n", samples=60)
    assert main(["identify", str(model_path), str(log_path), "--out", str(tmp_path / "l.toml")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


ONE_OUTPUT_ONE_MEASURED_INPUT = """
[outputs]
columns = ["y"]

[[inputs]]
name = "u"
column = "u"
"""


def test_linear_models_refuse_the_nonlinear_keys(tmp_path):
    linear = """
[model]
A = [[0.0, 1.0], [-1.0, -0.5]]
B = [[0.0], [1.0]]
C = [[1.0, 0.0]]
n_states = 2
""" + ONE_OUTPUT_ONE_MEASURED_INPUT + """
[observer]
kernel_width = 0.1
sensor_precision = 1.0
process_precision = 1.0
"""
    path = tmp_path / "linear.toml"
    path.write_text(linear)
    with pytest.raises(AttendInputError, match="n_states: only for nonlinear models"):
        io.read_model(path)
    path.write_text(linear.replace("n_states = 2\n", "").replace("[observer]", '[observer]\nmethod = "ukf"'))
    with pytest.raises(AttendInputError, match="nonlinear models"):
        io.read_model(path)
    path.write_text(linear.replace("n_states = 2\n", "").replace("A = [[0.0, 1.0], [-1.0, -0.5]]\n", ""))
    with pytest.raises(AttendInputError, match=r"needs A .* or python"):
        io.read_model(path)


LORENZ_JAX_PY = '''
import jax.numpy as jnp


def f(x, v):
    return jnp.stack([10.0 * (x[1] - x[0]), x[0] * (28.0 - x[2]) - x[1], x[0] * x[1] - 8.0 / 3.0 * x[2]])


def g(x, v):
    return 1.0 * x
'''


def test_jax_backend_from_a_nonlinear_model_file(tmp_path, capsys):
    """[observer] backend = "jax" with f, g in jax.numpy gives the NumPy D-step's estimates (1e-8)
    through `attend estimate`."""
    pytest.importorskip("jax")
    model_path, log_path, _ = _lorenz_files(tmp_path, LORENZ_TOML + 'method = "dem"\nbackend = "jax"\n',
                                            code=LORENZ_JAX_PY)
    out = tmp_path / "jax.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0, capsys.readouterr().err
    compiled = np.genfromtxt(out, delimiter=",", names=True)
    numpy_folder = tmp_path / "numpy"
    numpy_folder.mkdir()
    numpy_path, _, _ = _lorenz_files(numpy_folder, LORENZ_TOML + 'method = "dem"\n')
    numpy_out = tmp_path / "numpy.csv"
    assert main(["estimate", str(numpy_path), str(log_path), "--out", str(numpy_out)]) == 0
    reference = np.genfromtxt(numpy_out, delimiter=",", names=True)
    for name in ("x1", "x2", "x3"):
        np.testing.assert_allclose(compiled[name], reference[name], rtol=1e-8, atol=1e-8 * np.abs(reference[name]).max())


def test_jax_backend_with_numpy_functions_says_to_use_jax_numpy(tmp_path, capsys):
    pytest.importorskip("jax")
    model_path, log_path, _ = _lorenz_files(tmp_path, LORENZ_TOML + 'method = "dem"\nbackend = "jax"\n')
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "x.csv")]) == 2
    error = capsys.readouterr().err
    assert "lorenz.py: f(x, v) failed (line 6)" in error and "write them with jax.numpy" in error
    assert "Traceback" not in error


def test_jax_backend_is_refused_for_linear_models_and_other_methods(tmp_path):
    (tmp_path / "m.toml").write_text('[model]\nA = [[-1.0]]\nB = [[1.0]]\nC = [[1.0]]\n\n[outputs]\ncolumns = ["y"]\n\n'
                                     '[[inputs]]\nname = "u"\n\n[observer]\nmethod = "dem"\nbackend = "jax"\n'
                                     'kernel_width = 0.1\nsensor_precision = 1.0\nprocess_precision = 1.0\n')
    with pytest.raises(AttendInputError, match="backend: the JAX D-step is for nonlinear models"):
        io.read_model(tmp_path / "m.toml")
    model_path, _, _ = _lorenz_files(tmp_path, LORENZ_TOML + 'backend = "cuda"\n')
    with pytest.raises(AttendInputError, match="backend: expected 'numpy' or 'jax', got 'cuda'"):
        io.read_model(model_path)


HELD_PY = '''
import numpy as np

A = np.array([[-0.24, 0.02], [-0.02, -0.18]])
B, C = np.array([[-0.22], [-0.53]]), np.array([[-0.81, 0.58]])


def f(x, v):
    return A @ x + B @ v


def g(x, v):
    return C @ x
'''

HELD_TOML = '''
[model]
python = "held.py"
n_states = 2
n_inputs = 1
n_outputs = 1
''' + ONE_OUTPUT_ONE_MEASURED_INPUT + '''
[observer]
kernel_width = 0.25
sensor_precision = 1.479e7
process_precision = 1e10
'''


def test_the_smoothers_start_widens_a_misfit_d_step_instead_of_warning(tmp_path, capsys):
    # inputs held over each sample with almost no process noise: DEM's D-step on the first samples is
    # far from its generalised model (it warns when run itself); the unscented smoother only takes x[0]
    # from it, with the std widened by sqrt(misfit), and its own estimate is fine: no warning
    from attend.models import NonlinearSystem
    from attend.models.linear import LinearSystem, ModelWarning, simulate
    from attend.perception.nonlinear import NonlinearDEM

    (tmp_path / "held.py").write_text(HELD_PY)
    (tmp_path / "held.toml").write_text(HELD_TOML)
    A = np.array([[-0.24, 0.02], [-0.02, -0.18]])
    B, C = np.array([[-0.22], [-0.53]]), np.array([[-0.81, 0.58]])
    dt = 0.05
    u = np.sin(2.0 * np.arange(160) * dt)[:, None]
    log = simulate(LinearSystem(A, B, C), u, dt, kernel_width=0.25, process_std=1e-5, measurement_std=2.6e-4,
                   seed=1, initial_state=[0.3, -0.2])
    t = np.arange(160) * dt
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, log.outputs, u]), delimiter=",", header="t,y,u",
               comments="", fmt="%.17g")
    system = NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, 2, 1, 1)
    with pytest.warns(ModelWarning, match="far from DEM's generalised model"):
        NonlinearDEM(system, dt, kernel_width=0.25, sensor_precision=1.479e7, process_precision=1e10,
                     known_inputs=True).estimate(log.outputs[:28], u[:28])
    status = main(["estimate", str(tmp_path / "held.toml"), str(tmp_path / "log.csv"), "--out",
                   str(tmp_path / "e.csv")])
    err = capsys.readouterr().err
    assert status == 0 and err == "", err
    estimate = np.genfromtxt(tmp_path / "e.csv", delimiter=",", names=True)
    error = np.column_stack([estimate["x1"], estimate["x2"]]) - log.states
    assert np.sqrt(np.mean(error[10:] ** 2)) < 0.05 * np.sqrt(np.mean(log.states ** 2))


# --- no initial_state: the start search (attend.perception.nonlinear.start_search) ----------------

SPM_LORENZ_PY = '''
import numpy as np

P = (18.0, -4.0, 46.92)


def f(x, v):
    J = np.array([[-P[0], P[0], 0.0], [P[2] - x[2], -1.0, -x[0]], [x[1], x[0], P[1]]])
    return J @ x / 32.0


def g(x, v):
    return np.array([x[0] + x[1] + x[2]])
'''

SPM_LORENZ_TOML = '''
[model]
python = "model.py"
n_states = 3
n_inputs = 0
n_outputs = 1

[outputs]
columns = ["y"]

[observer]
kernel_width = 0.125
sensor_precision = 1.0
process_precision = 8886110.520507872
'''

DOUBLE_WELL_PY = '''
import numpy as np


def f(x, v):
    return (16.0 * x / (1.0 + x**2) - x / 2.0 + 2.0 * v) / 8.0


def g(x, v):
    return x**2 / 16.0
'''

DOUBLE_WELL_TOML = '''
[model]
python = "model.py"
n_states = 1
n_inputs = 1
n_outputs = 1

[outputs]
columns = ["y"]

[[inputs]]
name = "u"
{input}

[observer]
kernel_width = 0.5
sensor_precision = 7.38905609893065
process_precision = 8886110.520507872
'''

MEASURED = 'column = "u"'
UNKNOWN = "prior_mean = 0.0\nprior_precision = 0.125"


def _start_files(tmp_path, code, model, x0, samples, kernel_width, measurement_std, amplitude=0.0):
    """model.py, model.toml and log.csv (dt = 1, one SPM bin; process noise exp(-8)); the truth."""
    from attend.models import simulate_nonlinear

    (tmp_path / "model.py").write_text(code)
    (tmp_path / "model.toml").write_text(model)
    system = io.read_model(tmp_path / "model.toml").system
    t = np.arange(samples, dtype=float)
    u = amplitude * np.sin(np.pi * t / 16.0)[:, None]
    truth = simulate_nonlinear(system, u if system.n_inputs else samples, 1.0, kernel_width=kernel_width,
                               process_std=np.exp(-8), measurement_std=measurement_std, initial_state=x0, seed=0)
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, truth.outputs, u]), delimiter=",", header="t,y,u",
               comments="", fmt="%.12g")
    return tmp_path / "model.toml", tmp_path / "log.csv", truth


def test_spms_lorenz_demo_runs_without_initial_state_and_locks_on(tmp_path, capsys):
    """SPM's Lorenz demo (spm_DEM_M('Lorenz'): y = x1 + x2 + x3, sigma_z = 1, s = 1/8 bin, W = exp(16),
    M(1).x = [0.9, 0.8, 30], 128 bins) as a user writes it, without initial_state: it runs, and after
    a start-up of 20 samples the estimate follows the truth with an RMS error per state below
    sigma_z = 1 (the scale the single output resolves). A start in the wrong place or a smoother that
    lost the attractor would give errors of the attractor's own spread, ~7 per state; the search's
    estimate is ~0.1 there (and DEM's start used to be refused)."""
    model_path, log_path, truth = _start_files(tmp_path, SPM_LORENZ_PY, SPM_LORENZ_TOML, [0.9, 0.8, 30.0], 128,
                                               0.125, 1.0)
    out = tmp_path / "est.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "start: the best of a search over x[0]" in captured.out
    error = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:4] - truth.states
    assert np.sqrt(np.mean(error[20:] ** 2)) < 1.0
    assert np.sqrt(np.mean(np.std(truth.states, axis=0) ** 2)) > 5.0  # the attractor's spread: the contrast


@pytest.mark.parametrize("x0", [-5.6, 5.6])
def test_a_double_well_seen_through_x_squared_starts_in_either_well(tmp_path, capsys, x0):
    """SPM's double well (y = x^2 / 16, sigma_z = exp(-1), s = 1/2) driven by a measured input
    u = 4 sin(pi t / 16) that keeps it in its well: the first samples fit both wells; the input's
    response tells them apart (it raises |x| in the right well and lowers it in the left one). Both
    starts end in the right well: RMS error after the start-up below the sensor's resolution of x at
    the well, sigma_x = 8 sigma_z / |x| = 0.53 (the wrong well costs ~11 = 20 sigma_x)."""
    model_path, log_path, truth = _start_files(tmp_path, DOUBLE_WELL_PY, DOUBLE_WELL_TOML.format(input=MEASURED),
                                               [x0], 128, 0.5, np.exp(-1), amplitude=4.0)
    out = tmp_path / "est.csv"
    assert main(["estimate", str(model_path), str(log_path), "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    error = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1] - truth.states[:, 0]
    assert np.sqrt(np.mean(error[20:] ** 2)) < 8 * np.exp(-1) / 5.57


def test_a_start_the_log_cannot_decide_is_one_line_naming_initial_state(tmp_path, capsys):
    """The same double well with the input unknown (prior N(0, 8)): x -> -x, v -> -v leaves f, g and
    the prior unchanged, so the two wells fit the log exactly equally well and their estimates differ
    everywhere. The command says so in one line naming initial_state (exit 2), not a coin toss."""
    model_path, log_path, _ = _start_files(tmp_path, DOUBLE_WELL_PY, DOUBLE_WELL_TOML.format(input=UNKNOWN),
                                           [5.6], 128, 0.5, np.exp(-1), amplitude=8.0)
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "est.csv")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert err.startswith(f"attend: error: {model_path}: [observer] initial_state: not given, and the log fits 2 "
                          "starts about equally well")
    assert "give initial_state" in err
    with_start = DOUBLE_WELL_TOML.format(input=UNKNOWN) + "initial_state = [5.6]\ninitial_state_std = 1.0\n"
    (tmp_path / "model.toml").write_text(with_start)
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "est.csv")]) == 0


def test_an_estimate_that_does_not_follow_the_log_is_a_warning_naming_initial_state(tmp_path, capsys):
    """The unknown-input double well with a gentler push (a = 4): its state comes near 0, where the
    unscented smoother's Gaussian cannot hold the two signs of x^2 and loses the track from every start
    (the truth's own start as well): the smoothed outputs are ~85 sensor noise variances from the
    log. The estimate is written with a one-line warning, not silently."""
    model_path, log_path, _ = _start_files(tmp_path, DOUBLE_WELL_PY, DOUBLE_WELL_TOML.format(input=UNKNOWN),
                                           [5.6], 128, 0.5, np.exp(-1), amplitude=4.0)
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "est.csv")]) == 0
    err = capsys.readouterr().err
    warned = [line for line in err.splitlines() if line.startswith("attend: warning:")]
    assert len(warned) == 1  # (and the line saying how the push's width was chosen from the log)
    assert err.startswith(f"attend: warning: {model_path}: [observer] initial_state: not given, and from the best "
                          "start the search found")
    assert "sensor noise variances from the log" in err


def test_initial_state_std_alone_sets_the_searchs_scale_and_must_be_positive(tmp_path, capsys):
    model_path, log_path, _ = _start_files(tmp_path, DOUBLE_WELL_PY, DOUBLE_WELL_TOML.format(input=MEASURED),
                                           [5.6], 40, 0.5, np.exp(-1), amplitude=4.0)
    (tmp_path / "model.toml").write_text(DOUBLE_WELL_TOML.format(input=MEASURED) + "initial_state_std = 0.0\n")
    assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "est.csv")]) == 2
    assert "initial_state_std: the search's prior needs a finite scale > 0 per state" in capsys.readouterr().err
