"""Model and log files: the worked example and every validation error."""

import numpy as np
import pytest

from attend import io, workflows
from attend._validation import AttendInputError
from attend.data import demo_paths
from conftest import MASS_SPRING_LEARNING_MODEL, model_file_text

MODEL = model_file_text(
    ("[model]", {"A": [[-0.25, 1.0], [-0.5, -0.25]], "B": [[1.0], [0.0]], "C": [[0.125, 0.1633], [0.125, -0.1633]],
                 "dt": 0.1}),
    ("[outputs]", {"columns": ["y1", "y2"]}),
    ("[[inputs]]", {"name": "u", "prior_mean": 0.0, "prior_precision": 0.01}),
    ("[observer]", {"kernel_width": 0.5, "embedding_order": 4, "input_order": 2, "sensor_precision": 2980.0,
                    "process_precision": 2980.0}),
)


def _write(tmp_path, model=MODEL, rows=None, header="t,y1,y2"):
    model_path = tmp_path / "model.toml"
    model_path.write_text(model)
    log_path = tmp_path / "log.csv"
    if rows is None:
        t = np.arange(50) * 0.1
        rows = np.column_stack([t, np.sin(t), np.cos(t)])
    text = header + "\n" + "\n".join(",".join(f"{v:.10g}" for v in row) for row in rows)
    log_path.write_text(text + "\n")
    return model_path, log_path


def _refused(tmp_path, model_text: str, message: str) -> None:
    """Reading the model text, or estimating with it on the default log, fails with ``message``."""
    model_path, log_path = _write(tmp_path, model_text)
    with pytest.raises(AttendInputError, match=message):
        model = io.read_model(model_path)
        workflows.estimate_from_files(model, io.read_log(log_path))


def test_round_trip_estimate(tmp_path):
    model_path, log_path = _write(tmp_path)
    model = io.read_model(model_path)
    log = io.read_log(log_path)
    observer, estimate = workflows.estimate_from_files(model, log)
    assert estimate.states.shape == (50, 2) and estimate.inputs.shape == (50, 1)
    out = io.write_estimates(tmp_path / "out.csv", log, model.system, estimate)
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["t", "x1", "x2", "u", "x1_std", "x2_std", "u_std"]
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1:3], estimate.states, rtol=1e-9)


def test_the_model_files_noise_is_one_noise_model(tmp_path):
    """ModelFile.noise holds the file's precisions and widths (a separate width where given,
    kernel_width otherwise), and the Kalman smoother built from it estimates what the one built
    from the separate keywords does, to the bit."""
    from attend import NoiseModel
    from attend.perception.kalman import KalmanEstimator

    text = MODEL.replace("kernel_width = 0.5", "kernel_width = 0.5\nsensor_kernel_width = 0.25")
    model_path, log_path = _write(tmp_path, text)
    model = io.read_model(model_path)
    noise = model.noise
    assert isinstance(noise, NoiseModel)
    assert noise == NoiseModel(process_precision=2980.0, sensor_precision=2980.0, process_kernel_width=0.5,
                               sensor_kernel_width=0.25)
    log = io.read_log(log_path)
    observer, from_file = workflows.estimate_from_files(model, log)
    by_keywords = KalmanEstimator(model.system, 0.1, sensor_precision=2980.0, process_precision=2980.0,
                                  kernel_width=0.5, sensor_kernel_width=0.25, input_prior_precision=np.array([0.01]),
                                  known_inputs=[False], input_kernel_width=observer.input_kernel_width)
    outputs = log.matrix(model.output_columns)
    again = by_keywords.estimate(outputs, np.zeros((len(outputs), 1)))
    np.testing.assert_array_equal(again.states, from_file.states)
    np.testing.assert_array_equal(again.state_std, from_file.state_std)


def test_spm_conventions_from_the_model_file(tmp_path):
    """[observer] integration = "spm" and edges = "clamp" reach the DEM observer: the estimates are
    those of DEMObserver built with the same options, and differ from attend's default step."""
    from attend.perception.dem import DEMObserver

    spm = MODEL.replace("kernel_width = 0.5", 'kernel_width = 0.5\nmethod = "dem"\nintegration = "spm"\nedges = "clamp"')
    model_path, log_path = _write(tmp_path, spm)
    model, log = io.read_model(model_path), io.read_log(log_path)
    observer, estimate = workflows.estimate_from_files(model, log)
    assert (observer.integration, observer.edges) == ("spm", "clamp")
    direct = DEMObserver(model.system, 0.1, kernel_width=0.5, sensor_precision=2980.0, process_precision=2980.0,
                         input_prior_precision=[0.01], embedding_order=4, input_order=2, integration="spm",
                         edges="clamp")
    np.testing.assert_allclose(estimate.states, direct.estimate(log.matrix(["y1", "y2"]), np.zeros((50, 1))).states,
                               rtol=1e-12, atol=1e-12)
    _, default = workflows.estimate_from_files(io.read_model(_write(tmp_path, MODEL.replace(
        "kernel_width = 0.5", 'kernel_width = 0.5\nmethod = "dem"'))[0]), log)
    assert np.max(np.abs(default.states - estimate.states)) > 1e-6


def test_demo_matches_shared_flight(quadrotor_data):
    """The bundled demo is the shared flight exp_21_WW_WM_1: same samples, same estimates."""
    model_path, demo_log = demo_paths()
    model = io.read_model(model_path)
    shared = io.read_log(quadrotor_data / "exp_21_WW_WM_1.csv")
    demo = io.read_log(demo_log)
    np.testing.assert_array_equal(demo.columns["meas_phi"], shared.columns["meas_phi"])
    _, from_demo = workflows.estimate_from_files(model, demo)
    _, from_shared = workflows.estimate_from_files(model, shared)
    np.testing.assert_allclose(from_demo.states, from_shared.states)
    # the roll rate is estimated from the angle alone: compare with the measured rate
    error = from_shared.states[10:-10, 1] - shared.columns["state_phi_dot"][10:-10]
    assert np.sqrt(np.mean(error**2)) < 0.1  # rad/s; the rate itself swings by ~1 rad/s


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda m: m + "\n[extra]\nkey = 1\n", "unknown section or key 'extra'"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.5\nkernel = 3"), "unknown key 'kernel'"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = -0.5"), "kernel_width: expected a number >= 0"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.0"), "input_kernel_width: expected a width > 0"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.0\nmethod = \"dem\""),
         "kernel_width: expected a number > 0"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.5\nmethod = \"ekf\""), "method: expected"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.5\ninitial_state = [1]"),
         "initial_state: expected 2 finite numbers"),
        (lambda m: m.replace("A = [[-0.25, 1.0], [-0.5, -0.25]]", "A = [[-0.25, 1.0, 0.0], [-0.5, -0.25, 0.0]]"), "A: expected a square"),
        (lambda m: m.replace("B = [[1.0], [0.0]]", "B = [[1.0], [0.0], [2.0]]"), "B: expected 2 rows"),
        (lambda m: m.replace('columns = ["y1", "y2"]', 'columns = ["y1"]'), "columns: expected 2 column names"),
        (lambda m: m.replace("prior_precision = 0.01", "prior_precision = -1.0"), "prior_precision"),
        (lambda m: m.replace("sensor_precision = 2980.0", "sensor_precision = -5.0"), "sensor_precision: expected non-negative"),
        (lambda m: m.replace("process_precision = 2980.0", "process_precision = nan"), "process_precision: expected finite"),
        (lambda m: m.replace("[model]", "[model\n"), "not valid TOML"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.5\nmethod = \"dem\"\nintegration = \"SPM\""),
         "integration: expected 'attend' or 'spm', got 'SPM'"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 0.5\nedges = \"clamp\""),
         'edges: a setting of DEM; add method = "dem"'),
    ],
)
def test_bad_model_files_name_the_field(tmp_path, edit, message):
    _refused(tmp_path, edit(MODEL), message)


def test_bad_logs_name_the_problem(tmp_path):
    model_path, log_path = _write(tmp_path, header="t,y1,z2")
    with pytest.raises(AttendInputError, match="missing the declared column 'y2'"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    t = np.arange(50) * 0.1
    t[20:] += 0.03
    model_path, log_path = _write(tmp_path, rows=np.column_stack([t, t, t]))
    with pytest.raises(AttendInputError, match="non-uniform time stamps"):
        io.read_log(log_path)
    rows = np.column_stack([np.arange(50) * 0.1, np.ones(50), np.ones(50)])
    rows[7, 1] = np.nan
    model_path, log_path = _write(tmp_path, rows=rows)
    with pytest.raises(AttendInputError, match="line 9 .sample 8., column .y1.: expected a finite number"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    model_path, log_path = _write(tmp_path, rows=np.column_stack([np.arange(1) * 0.1, np.ones(1), np.ones(1)]))
    with pytest.raises(AttendInputError, match="at least 2 samples"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    dem = MODEL.replace("kernel_width = 0.5", "kernel_width = 0.5\nmethod = \"dem\"")
    model_path, log_path = _write(tmp_path, dem, rows=np.column_stack([np.arange(3) * 0.1, np.ones(3), np.ones(3)]))
    with pytest.raises(AttendInputError, match="at least 5 samples"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    model_path, log_path = _write(tmp_path, rows=np.column_stack([np.arange(50) * 0.2, np.ones(50), np.ones(50)]))
    with pytest.raises(AttendInputError, match="dt = 0.1 s but the log"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    log_path.write_text("")
    with pytest.raises(AttendInputError, match="empty"):
        io.read_log(log_path)
    log_path.write_text("t,y1,y2\n")
    with pytest.raises(AttendInputError, match="no samples"):
        io.read_log(log_path)
    log_path.write_text("t,y1,y2\n0,1,abc\n")
    with pytest.raises(AttendInputError, match="column 'y2': expected a number"):
        io.read_log(log_path)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda m: m.replace("A = [[-0.25, 1.0]", 'A = [["-0.25", 1.0]'), r"\[model\] A: expected a matrix of numbers.*'-0.25'"),
        (lambda m: m.replace("sensor_precision = 2980.0", 'sensor_precision = "2980"'), r"\[observer\] sensor_precision: expected .*'2980'"),
        (lambda m: m.replace("kernel_width = 0.5", 'kernel_width = "0.5"'), r"\[observer\] kernel_width: expected a number"),
        (lambda m: m.replace("embedding_order = 4", 'embedding_order = "4"'), r"\[observer\] embedding_order: expected an integer"),
        (lambda m: m.replace("prior_precision = 0.01", 'prior_precision = "0.01"'), r"\[\[inputs\]\] 'u' prior_precision: expected a number"),
        (lambda m: m.replace("prior_mean = 0.0", "prior_mean = 1e200"), r"prior_mean: expected values within"),
        (lambda m: m.replace("A = [[-0.25, 1.0]", "A = [[-1e300, 1.0]"), r"\[model\] A: expected values within \+-1e\+150"),
        (lambda m: m.replace("dt = 0.1", 'dt = "0.1"'), r"\[model\] dt: expected a number"),
        (lambda m: m.replace("[model]", '[model]\nstates = ["phi", "phi"]'), r"\[model\] states: the name 'phi' appears twice"),
        (lambda m: m.replace("[model]", '[model]\nstates = ["phi"]'), r"\[model\] states: expected 2 state names, got 1"),
        (lambda m: m.replace('columns = ["y1", "y2"]', 'columns = ["y1", "y1"]'), r"\[outputs\] columns: the name 'y1' appears twice"),
        (lambda m: m.replace("B = [[1.0], [0.0]]", "B = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]"),
         r"\[model\] B has 3 columns but the file has 1 \[\[inputs\]\] table"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 1000"),
         r"\[observer\] kernel_width: 1000 s is 10000 sample times; expected at most 100"),
        (lambda m: m.replace("kernel_width = 0.5", "kernel_width = 1000\nmethod = \"dem\""),
         r"\[observer\] kernel_width: the observer's flow matrix could not be discretised .* kernel_width = 1000 s"),
        (lambda m: m.replace('precision_convention', 'x') + 'precision_convention = "spm"\n', r"precision_convention: expected"),
        (lambda m: m + "[learning]\nnoise_prior_mean = [0.0]\n", r"\[learning\] noise_prior_mean: expected a number or a pair"),
        (lambda m: m + '[learning]\nmax_iterations = "5"\n', r"\[learning\] max_iterations: expected an integer"),
        (lambda m: m + "[learning]\nstates = 'paths'\n", r"\[learning\] states: expected \"sample\" or \"path\""),
        (lambda m: "", r"the model file is empty"),
        (lambda m: m.replace("prior_mean = 0.0\nprior_precision = 0.01", 'column = "y2"\noperating_point = "172"'),
         r"\[\[inputs\]\] 'u' operating_point: expected a number, got '172'"),
    ],
)
def test_model_files_are_strict_and_speak_in_their_own_keys(tmp_path, edit, message):
    _refused(tmp_path, edit(MODEL), message)


def test_log_errors_name_the_file_line_and_column(tmp_path):
    rows = np.column_stack([np.arange(50) * 0.1, np.ones(50), np.ones(50)])
    rows[4, 2] = 2e150
    model_path, log_path = _write(tmp_path, rows=rows)
    with pytest.raises(AttendInputError, match=rf"{log_path}: line 6 \(sample 5\), column 'y2': expected a value within"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    log_path.write_text("t,y1,y1\n0,1,2\n")
    with pytest.raises(AttendInputError, match=rf"{log_path}: header: the name 'y1' appears twice"):
        io.read_log(log_path)
    log_path.write_bytes(b"\xef\xbb\xbft,y1,y2\r\n0,1,2\r\n0.1,1,2\r\n")
    log = io.read_log(log_path)
    assert list(log.columns) == ["t", "y1", "y2"] and len(log.time) == 2
    log_path.write_bytes(b"t,y1\n\xd0\xcf")
    with pytest.raises(AttendInputError, match=rf"{log_path}: expected a UTF-8 text log, found byte 0xd0"):
        io.read_log(log_path)
    with pytest.raises(AttendInputError, match=rf"log: {tmp_path} is a directory"):
        io.read_log(tmp_path)
    with pytest.raises(AttendInputError, match=rf"model file: {tmp_path} is a directory"):
        io.read_model(tmp_path)
    # unused columns may hold anything numeric, even NaN
    rows = np.column_stack([np.arange(50) * 0.1, np.ones(50), np.ones(50), np.full(50, np.nan)])
    model_path, log_path = _write(tmp_path, rows=rows, header="t,y1,y2,spare")
    workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))


def test_a_three_row_log_names_the_file(tmp_path):
    dem = MODEL.replace("kernel_width = 0.5", "kernel_width = 0.5\nmethod = \"dem\"")
    model_path, log_path = _write(tmp_path, dem, rows=np.column_stack([np.arange(3) * 0.1, np.ones(3), np.ones(3)]))
    with pytest.raises(AttendInputError, match=rf"{log_path}: expected at least 5 samples"):
        workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))


def test_identify_checks_the_learning_section_against_the_files(tmp_path):
    model = MODEL.replace("prior_mean = 0.0\nprior_precision = 0.01", 'column = "u"') + "[learning]\nfree = [\"A[9,9]\"]\n"
    t = np.arange(60) * 0.1
    model_path, log_path = _write(tmp_path, model, rows=np.column_stack([t, np.sin(t), np.cos(t), np.sin(2 * t)]),
                                  header="t,y1,y2,u")
    with pytest.raises(AttendInputError, match=rf"{model_path}: \[learning\] free"):
        workflows.identify_from_files(io.read_model(model_path), io.read_log(log_path))


def test_identify_auto_order_is_not_moved_by_a_few_rough_samples(tmp_path):
    """With a smooth noise model (kernel width 5 samples) "auto" learns at order 2: a ninth of the
    sensor std added to 30 of 600 samples leaves A[2,1], A[2,2], B[2,1] where the clean log puts
    them (order 6 moved A[2,1] from -0.57 to -2.59 on this log); at 0.72 samples (the quadrotor
    flights) "auto" stays at 6."""
    from attend import mass_spring_damper, simulate
    from attend.workflows.identify import auto_identification_order, identify_from_files
    from attend.io.logs import Log

    assert auto_identification_order(0.006, 1 / 120) == 6 and auto_identification_order(0.5, 0.1) == 2
    system = mass_spring_damper()
    t = np.arange(600) * 0.1
    u = sum(a * np.exp(-0.25 * (t - c) ** 2) for c, a in ((8, 1.0), (22, -1.0), (35, 1.5), (48, -0.7)))
    log = simulate(system, u[:, None], 0.1, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4),
                   seed=1)
    (tmp_path / "model.toml").write_text(MASS_SPRING_LEARNING_MODEL)
    model = io.read_model(tmp_path / "model.toml")
    rng = np.random.default_rng(0)
    rough = log.outputs[:, 0].copy()
    rows = rng.choice(600, 30, replace=False)
    rough[rows] += rng.normal(0, 0.002, 30)
    learned = []
    for y in (log.outputs[:, 0], rough):
        result = identify_from_files(model, Log(time=t, columns={"y": y, "u": u}, path="log.csv"))
        assert result.converged and result.settings["embedding_order"] == 2
        s = result.system()
        learned.append(np.array([s.A[1, 0], s.A[1, 1], s.B[1, 0]]))
    truth = np.array([system.A[1, 0], system.A[1, 1], system.B[1, 0]])
    # the clean log's error is the estimate's own (about 0.01 here); the rough samples may add little to it
    assert np.max(np.abs(learned[0] - truth)) < 0.05
    assert np.max(np.abs(learned[1] - learned[0])) < 0.01
