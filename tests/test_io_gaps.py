"""Logs with missing samples and jittered time stamps: read_log(gaps=True) and `attend estimate`."""

import numpy as np
import pytest

from attend import io
from attend._validation import AttendInputError
from attend.cli import main
from attend.models.linear import LinearSystem, simulate
from conftest import model_file_text

SYSTEM = LinearSystem([[-0.25, 1.0], [-0.5, -0.25]], [[1.0], [0.0]], [[0.125, 0.1633], [0.125, -0.1633]])
MODEL = model_file_text(
    ("[model]", {"A": SYSTEM.A.tolist(), "B": SYSTEM.B.tolist(), "C": SYSTEM.C.tolist()}),
    ("[outputs]", {"columns": ["y1", "y2"]}),
    ("[[inputs]]", {"name": "u", "column": "u"}),
    ("[observer]", {"kernel_width": 0.2, "sensor_precision": 1e4, "process_precision": 100.0,
                    "initial_state": [0.0, 0.0]}),
)
DT, N = 0.1, 200


def _rows(jitter=0.05, seed=0):
    """(t, y1, y2, u) of a simulated log, time stamps jittered by +-jitter/2 dt."""
    rng = np.random.default_rng(seed)
    u = np.sin(np.arange(N) * DT)[:, None]
    log = simulate(SYSTEM, u, DT, kernel_width=0.2, process_std=0.1, measurement_std=0.01, seed=seed)
    t = np.arange(N) * DT + rng.uniform(-jitter / 2, jitter / 2, N) * DT
    return [[f"{t[k]:.6f}", f"{log.outputs[k, 0]:.8g}", f"{log.outputs[k, 1]:.8g}", f"{u[k, 0]:.8g}"] for k in range(N)]


def _write(tmp_path, rows, model=MODEL):
    (tmp_path / "model.toml").write_text(model)
    (tmp_path / "log.csv").write_text("t,y1,y2,u\n" + "\n".join(",".join(row) for row in rows) + "\n")
    return tmp_path / "model.toml", tmp_path / "log.csv"


def test_read_log_keeps_missing_values_and_uneven_stamps(tmp_path):
    rows = _rows()
    rows[3][1] = ""
    rows[4][2] = "nan"
    del rows[10:12]
    _, path = _write(tmp_path, rows)
    log = io.read_log(path, gaps=True)
    assert not log.uniform and len(log.time) == N - 2
    assert log.dt == pytest.approx(DT, rel=2e-3)  # the nominal step: gaps counted in whole samples
    outputs = log.matrix(["y1", "y2"], missing=True)
    assert np.isnan(outputs[3, 0]) and np.isnan(outputs[4, 1]) and np.isfinite(outputs).sum() == 2 * (N - 2) - 2
    with pytest.raises(AttendInputError, match=r"log.csv: line 5 \(sample 4\), column 'y1': expected a finite number"):
        log.matrix(["y1"])
    with pytest.raises(AttendInputError, match="line 5, column 'y1': expected a number, got ''"):
        io.read_log(path)  # the default (attend identify) still asks for complete, uniform logs
    rows[3][1] = "0.5"
    _, path = _write(tmp_path, rows)
    with pytest.raises(AttendInputError, match="non-uniform time stamps"):
        io.read_log(path)


@pytest.mark.parametrize("edit, message", [
    (lambda rows: rows[7].__setitem__(0, rows[5][0]), r"column 't': line 9: time stamp before the previous one "
                                                      r"\(line 9: 0\.[0-9]+ s, line 8: 0\.[0-9]+ s\)"),
    (lambda rows: rows[7].__setitem__(0, rows[6][0]), r"column 't': line 9: time stamp equal to the previous one"),
    (lambda rows: rows[7].__setitem__(0, ""), r"line 9 \(sample 8\), column 't': expected a finite number"),
])
def test_time_going_backwards_or_repeated_names_the_lines(tmp_path, edit, message):
    rows = _rows()
    edit(rows)
    _, path = _write(tmp_path, rows)
    with pytest.raises(AttendInputError, match=message):
        io.read_log(path, gaps=True)


def _estimate(tmp_path, rows, capsys, model=MODEL):
    model_path, log_path = _write(tmp_path, rows, model)
    out = tmp_path / "estimates.csv"
    code = main(["estimate", str(model_path), str(log_path), "--out", str(out), "--no-progress"])
    captured = capsys.readouterr()
    return code, captured.out, captured.err, out


def test_estimate_writes_every_row_and_reports_the_gaps(tmp_path, capsys):
    rows = _rows()
    rows[20][1] = rows[20][2] = "nan"  # a row without outputs: still estimated
    rows[30][1] = ""
    rows[40][3] = ""                   # a missing input value: interpolated
    del rows[60:62]                    # two skipped time stamps
    code, out, err, path = _estimate(tmp_path, rows, capsys)
    assert code == 0, err
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert table.shape[0] == N - 2 and np.all(np.isfinite(table))
    np.testing.assert_allclose(table[:, 0], [float(row[0]) for row in rows], atol=1e-9)
    gaps = [line for line in out.splitlines() if "gaps and jitter:" in line]
    assert len(gaps) == 1, out
    assert "4 of 200 samples missing (2 skipped time stamps, 2 rows with missing outputs)" in gaps[0]
    assert "jitter up to" in gaps[0] and "1 missing input value interpolated" in gaps[0]


def test_gappy_log_estimates_match_the_library(tmp_path, capsys):
    """The CLI runs KalmanEstimator.estimate with the log's time stamps and NaN for the gaps."""
    from attend.perception.kalman import KalmanEstimator

    rows = _rows(jitter=0.0)
    rows[20][1] = "nan"
    del rows[60:63]
    code, _, err, path = _estimate(tmp_path, rows, capsys)
    assert code == 0, err
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    values = np.array([[float(cell) if cell else np.nan for cell in row] for row in rows])
    estimator = KalmanEstimator(SYSTEM, DT, sensor_precision=1e4, process_precision=100.0, kernel_width=0.2,
                                initial_state=[0.0, 0.0])
    expected = estimator.estimate(values[:, 1:3], values[:, 3:], time=values[:, 0])
    np.testing.assert_allclose(table[:, 1:3], expected.states, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("edit, method, message", [
    (lambda rows: [row.__setitem__(3, "") for row in rows[40:44]], "kalman",
     r"log.csv: column 'u': 4 consecutive missing samples between line 41 and line 46; expected gaps of at most 3"),
    (lambda rows: [row.__setitem__(1, "") for row in rows[40:44]], "dem",
     r"log.csv: column 'y1': 4 consecutive missing samples between line 41 and line 46; expected gaps of at most 3"),
    (lambda rows: rows[44].__setitem__(0, f"{float(rows[43][0]) + 0.02:.6f}"), "kalman",
     r"log.csv: column 't': line 46: step of 0.02 s \(line 45 to line 46\) is shorter than half the sample time"),
    (lambda rows: rows[0].__setitem__(3, ""), "kalman",
     r"log.csv: column 'u': 1 consecutive missing sample before line 3 \(the start of the log\)"),
])
def test_bad_gaps_are_one_line_errors_naming_the_lines(tmp_path, capsys, edit, method, message):
    rows = _rows(jitter=0.0)
    edit(rows)
    model = MODEL.replace("kernel_width = 0.2", f'kernel_width = 0.2\nmethod = "{method}"')
    code, _, err, _ = _estimate(tmp_path, rows, capsys, model)
    lines = [line for line in err.splitlines() if line.startswith("attend: error")]
    assert code == 2 and len(lines) == 1, err
    assert __import__("re").search(message, lines[0]), lines[0]


def test_model_dt_is_checked_against_the_nominal_step(tmp_path, capsys):
    rows = _rows()
    del rows[50]
    model = MODEL.replace("[model]", "[model]\ndt = 0.2")
    code, _, err, _ = _estimate(tmp_path, rows, capsys, model)
    assert code == 2 and "[model] dt = 0.2 s but the log" in err and "nominal step" in err


PENDULUM_PY = "import numpy as np\n\ndef f(x, v):\n    return np.array([x[1], -np.sin(x[0])])\n\n" \
    "def g(x, v):\n    return np.array([x[0]])\n"
PENDULUM = ('[model]\npython = "model.py"\nn_states = 2\nn_inputs = 0\nn_outputs = 1\n\n[outputs]\n'
            'columns = ["y1"]\n\n[observer]\nkernel_width = 0.1\nsensor_precision = 400.0\n'
            'process_precision = 400.0\ninitial_state = [1.0, 0.0]\n')


def test_nonlinear_models_take_missing_values_and_skipped_stamps(tmp_path, capsys):
    """A nonlinear model file on a log with empty cells and skipped time stamps: an estimate at every
    row of the log, at its stamps, as close to the truth as on the complete log (within the spread
    that 9 of 80 missing outputs allow), and the report's line on the gaps."""
    from attend.models import simulate_nonlinear

    (tmp_path / "model.py").write_text(PENDULUM_PY)
    (tmp_path / "model.toml").write_text(PENDULUM)
    system = io.read_model(tmp_path / "model.toml").system
    log = simulate_nonlinear(system, 80, DT, kernel_width=0.1, process_std=0.05, measurement_std=0.05,
                             initial_state=[1.0, 0.0], seed=3)
    rows = [[f"{k * DT:.6f}", f"{log.outputs[k, 0]:.8g}", "0", "0"] for k in range(80)]
    code, _, err, path = _estimate(tmp_path, rows, capsys, PENDULUM)
    assert code == 0, err
    complete = np.loadtxt(path, delimiter=",", skiprows=1)
    dropped = [5, 6, 30, 61]  # skipped stamps (two in a row)
    for k in (12, 40, 41, 70, 77):
        rows[k][1] = ""  # empty cells
    kept = [k for k in range(80) if k not in dropped]
    code, out, err, path = _estimate(tmp_path, [rows[k] for k in kept], capsys, PENDULUM)
    assert code == 0, err
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert "gaps and jitter: 9 of 80 samples missing (4 skipped time stamps, 5 rows with missing outputs)" in out
    np.testing.assert_allclose(table[:, 0], np.array(kept) * DT, atol=1e-6)  # every row, at its stamp
    truth = log.states[kept]
    error, full_error = np.sum((table[:, 1:3] - truth) ** 2), np.sum((complete[kept, 1:3] - truth) ** 2)
    assert error < 1.5 * full_error
    # the std of the measured angle is wider where its measurement is missing (no update there)
    widened = table[:, 3] / complete[kept, 3]
    assert np.all(widened[np.isin(kept, [40, 41])] > 1.01)


@pytest.mark.parametrize("edit, message", [
    (lambda rows: rows[7].__setitem__(0, f"{7.3 * DT:.6f}"), "line 9: a step of"),  # jitter
    (lambda rows: [rows[k].__setitem__(1, "") for k in (10, 11, 12, 13)], "'y1': 4 consecutive missing samples"),
])
def test_nonlinear_gaps_it_cannot_take_are_one_line_errors(tmp_path, capsys, edit, message):
    """Jitter (nonlinear smoothers step by dt) and, for nonlinear DEM, more than 3 missing outputs in a row."""
    (tmp_path / "model.py").write_text(PENDULUM_PY)
    rows = [[f"{k * DT:.6f}", f"{np.cos(k * DT):.6f}", "0", "0"] for k in range(50)]
    edit(rows)
    code, _, err, _ = _estimate(tmp_path, rows, capsys, PENDULUM.replace("[observer]\n", '[observer]\nmethod = "dem"\n'))
    assert code == 2 and message in err and err.count("\n") == 1


def test_nonlinear_logs_are_split_at_gaps_longer_than_three_samples():
    from attend.workflows.estimate_gaps import _segments

    rows = np.ones((30, 2))
    rows[[0, 1, 2, 3, 4], :] = np.nan  # a run at the start: kept with the first part
    rows[8:11] = np.nan                # 3 samples: bridged by the smoother
    rows[14, 0] = np.nan               # one output missing: not a gap
    rows[15:19] = np.nan               # 4 samples: split
    rows[25:] = np.nan                 # a run at the end: kept with the last part
    assert _segments(rows) == [slice(0, 15), slice(19, 30)]
    assert _segments(np.ones((5, 1))) == [slice(0, 5)]


def test_a_nonlinear_log_with_a_long_gap_is_estimated_in_parts(tmp_path, capsys):
    """20 skipped stamps: the part after the gap starts from its own searched start; estimates at
    every row, within 3 std of the truth after the gap too."""
    from attend.models import simulate_nonlinear

    (tmp_path / "model.py").write_text(PENDULUM_PY)
    (tmp_path / "model.toml").write_text(PENDULUM)
    system = io.read_model(tmp_path / "model.toml").system
    log = simulate_nonlinear(system, 100, DT, kernel_width=0.1, process_std=0.05, measurement_std=0.05,
                             initial_state=[1.0, 0.0], seed=4)
    kept = [k for k in range(100) if not 40 <= k < 60]
    rows = [[f"{k * DT:.6f}", f"{log.outputs[k, 0]:.8g}", "0", "0"] for k in kept]
    code, out, err, path = _estimate(tmp_path, rows, capsys, PENDULUM)
    assert code == 0, err
    assert "split at 1 gap of more than 3 samples without outputs" in out
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert table.shape[0] == 80
    after = np.array(kept) >= 60
    error = np.abs(table[after, 1:3] - log.states[kept][after])
    assert np.mean(error < 3 * table[after, 3:5]) > 0.9


def test_a_jittered_nonlinear_log_is_integrated_step_by_step(tmp_path, capsys):
    """Stamps jittered by up to +-2 % of dt, read from a simulation 100x finer: the unscented smoother
    integrates each step over its own length; its estimates are as close to the truth at the
    stamps as the uniform log's are at k dt (SSE within 1.5x), and the report says how."""
    from attend.models import simulate_nonlinear

    (tmp_path / "model.py").write_text(PENDULUM_PY)
    (tmp_path / "model.toml").write_text(PENDULUM)
    system = io.read_model(tmp_path / "model.toml").system
    fine = simulate_nonlinear(system, 80 * 100, DT / 100, kernel_width=0.1, process_std=0.05, measurement_std=0.05,
                              initial_state=[1.0, 0.0], seed=6)
    uniform = np.arange(80) * 100
    jittered = uniform + np.concatenate([[0], np.random.default_rng(6).integers(-2, 3, 79)])
    tables = []
    for index in (uniform, jittered):
        rows = [[f"{k * DT / 100:.6f}", f"{fine.outputs[k, 0]:.8g}", "0", "0"] for k in index]
        code, out, err, path = _estimate(tmp_path, rows, capsys, PENDULUM)
        assert code == 0, err
        tables.append((np.loadtxt(path, delimiter=",", skiprows=1), out))
    (complete, _), (table, out) = tables
    assert "each step integrated over its own length (RK4), its process noise scaled to it" in out
    np.testing.assert_allclose(table[:, 0], jittered * DT / 100, atol=1e-6)
    error = np.sum((table[:, 1:3] - fine.states[jittered]) ** 2)
    assert error < 1.5 * np.sum((complete[:, 1:3] - fine.states[uniform]) ** 2)
