"""The command line: help texts, the demo, and one-line errors instead of tracebacks."""

from pathlib import Path

import numpy as np
import pytest

from attend.cli import main
from conftest import MASS_SPRING_LEARNING_MODEL


def test_help_explains_units(capsys):
    with pytest.raises(SystemExit):
        main(["estimate", "--help"])
    text = capsys.readouterr().out
    assert "[s]" in text and "--demo" in text and "std" in text


def test_demo_estimate_writes_csv_and_plot(tmp_path, capsys):
    out, plot = tmp_path / "roll.csv", tmp_path / "roll.png"
    assert main(["estimate", "--demo", "--out", str(out), "--plot", str(plot)]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert table.shape[1] == 1 + 2 * (2 + 4) and np.all(np.isfinite(table))
    assert plot.stat().st_size > 10_000


def test_errors_are_one_line(tmp_path, capsys):
    assert main(["estimate", str(tmp_path / "missing.toml"), str(tmp_path / "missing.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("attend: error: model file:") and "Traceback" not in err
    assert main(["reproduce", "nonsense"]) == 2
    assert "unknown experiment 'nonsense'" in capsys.readouterr().err


def test_reproduce_writes_json_report_and_uses_the_cache(tmp_path, capsys, monkeypatch):
    from attend.experiments import fig2

    calls = []
    original = fig2.run

    def small_run(quick=True, progress=True):
        calls.append(quick)
        return original(quick=quick, progress=False, seeds=2)

    monkeypatch.setattr(fig2, "run", small_run)
    assert main(["reproduce", "fig2", "--out", str(tmp_path), "--report", "--no-progress"]) == 0
    assert (tmp_path / "fig2.json").is_file() and (tmp_path / "fig2.png").is_file()
    page = (tmp_path / "index.html").read_text()
    assert "fig2" in page and "data:image/png;base64," in page
    assert main(["reproduce", "fig2", "--out", str(tmp_path), "--no-progress"]) == 0
    assert "cached" in capsys.readouterr().out and calls == [True]
    assert main(["reproduce", "fig2", "--out", str(tmp_path), "--force", "--no-progress"]) == 0
    assert calls == [True, True]


def test_identify_learns_and_writes_a_usable_model(tmp_path, capsys):
    from attend import mass_spring_damper, simulate

    system = mass_spring_damper()
    t = np.arange(320) * 0.1
    u = np.exp(-0.25 * (t - 12) ** 2)
    log = simulate(system, u[:, None], 0.1, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=1)
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, log.outputs[:, 0], u]), delimiter=",",
               header="t,y,u", comments="")
    (tmp_path / "model.toml").write_text(MASS_SPRING_LEARNING_MODEL)
    out = tmp_path / "learned.toml"
    assert main(["identify", str(tmp_path / "model.toml"), str(tmp_path / "log.csv"), "--out", str(out),
                 "--no-progress"]) == 0
    report = capsys.readouterr().out
    assert "A[2,1]" in report and "free energy" in report
    from attend import io

    learned = io.read_model(out)
    assert abs(learned.system.A[1, 0] - system.A[1, 0]) < 0.1  # -k/m = -0.571 from a prior of -1
    assert abs(learned.system.B[1, 0] - system.B[1, 0]) < 0.1  # 1/m = 0.714 from a prior of 1
    assert main(["estimate", str(out), str(tmp_path / "log.csv"), "--out", str(tmp_path / "e.csv")]) == 0
    assert main(["identify", str(tmp_path / "missing.toml"), str(tmp_path / "log.csv")]) == 2
    capsys.readouterr()

    # not converged: exit 3, one line naming what to change, nothing written unless --allow-unconverged
    text = (tmp_path / "model.toml").read_text().replace("max_iterations = 50", "max_iterations = 1")
    (tmp_path / "short.toml").write_text(text)
    out1 = tmp_path / "short_learned.toml"
    assert main(["identify", str(tmp_path / "short.toml"), str(tmp_path / "log.csv"), "--out", str(out1),
                 "--no-progress"]) == 3
    err = capsys.readouterr().err
    assert "did not converge" in err and "max_iterations" in err and "Change:" in err
    assert not out1.exists()
    assert main(["identify", str(tmp_path / "short.toml"), str(tmp_path / "log.csv"), "--out", str(out1),
                 "--no-progress", "--allow-unconverged"]) == 3
    assert out1.exists()

    # no [learning] section: exit 2 with an example section
    (tmp_path / "plain.toml").write_text(text.split("[learning]")[0])
    assert main(["identify", str(tmp_path / "plain.toml"), str(tmp_path / "log.csv"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "[learning]" in err and 'free = ["A[2,1]"' in err


def test_identify_help_documents_exit_status_3(capsys):
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    text = capsys.readouterr().out
    assert "3 the learning did not converge" in text and "--allow-unconverged" in text


def test_search_offers_every_planner():
    from attend.action.planners import PLANNERS
    from attend.cli import _build_parser

    parser = _build_parser()
    from attend.action.search_run import SEARCH_PLANNERS

    search = next(a for a in parser._subparsers._group_actions[0].choices["search"]._actions if a.dest == "planner")
    assert set(search.choices) == set(PLANNERS) | set(SEARCH_PLANNERS)


# --- the user's path never fails silently ------------------------------------------------------

#: A small one-output model with an unknown input (the same TOML as tables written inline).
MODEL = """
model = {A = [[-0.25, 1.0], [-0.5, -0.25]], B = [[1.0], [0.0]], C = [[0.125, 0.1633]], states = ["phi", "rate"]}
outputs = {columns = ["y"]}
inputs = [{name = "u", prior_mean = 0.0, prior_precision = 0.01}]
observer = {kernel_width = 0.5, embedding_order = 4, sensor_precision = 2980.0, process_precision = 2980.0}
"""


def _files(folder, model=MODEL, log=None):
    model_path, log_path = folder / "model.toml", folder / "log.csv"
    model_path.write_text(model)
    if log is None:
        t = np.arange(60) * 0.1
        log = "t,y\n" + "\n".join(f"{a:.10g},{b:.10g}" for a, b in zip(t, np.sin(t))) + "\n"
    log_path.write_text(log) if isinstance(log, str) else log_path.write_bytes(log)
    return model_path, log_path


def _one_error_line(capsys, *fragments):
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("attend: warning:")]
    assert len(lines) == 1 and lines[0].startswith("attend: error: "), err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


def test_directories_instead_of_files_are_one_line_errors(tmp_path, capsys):
    model, log = _files(tmp_path)
    assert main(["estimate", str(tmp_path), str(log)]) == 2
    _one_error_line(capsys, str(tmp_path), "is a directory")
    assert main(["estimate", str(model), str(tmp_path)]) == 2
    _one_error_line(capsys, "log", "is a directory")
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path)]) == 2
    _one_error_line(capsys, "--out", "is a directory", "estimates.csv")
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv"), "--plot", str(tmp_path)]) == 2
    _one_error_line(capsys, "--plot", "is a directory")
    assert main(["identify", str(model), str(log), "--out", str(tmp_path)]) == 2
    _one_error_line(capsys, "--out", "is a directory")
    assert main(["estimate", str(model), str(log), "--out", str(log / "deeper" / "e.csv")]) == 2
    _one_error_line(capsys, "--out", f"{log} is a file; expected a folder there")


def test_missing_parent_folders_of_outputs_are_created(tmp_path, capsys):
    model, log = _files(tmp_path)
    out = tmp_path / "new" / "deeper" / "estimates.csv"
    assert main(["estimate", str(model), str(log), "--out", str(out)]) == 0
    assert out.is_file()


@pytest.mark.parametrize("number, meaning", [(30, "read-only file system"), (13, "permission denied"),
                                             (28, "no space left on the device")])
def test_os_errors_on_outputs_are_one_line_errors(tmp_path, capsys, monkeypatch, number, meaning):
    from attend import io

    model, log = _files(tmp_path)
    out = tmp_path / "e.csv"

    def failing_write(path, *args, **kwargs):
        raise OSError(number, "simulated", str(path) if number != 28 else None)

    monkeypatch.setattr(io, "write_estimates", failing_write)
    assert main(["estimate", str(model), str(log), "--out", str(out)]) == 2
    _one_error_line(capsys, meaning)


def test_read_only_locations_for_plot_reproduce_and_search(tmp_path, capsys, monkeypatch):
    import errno

    import attend.plotting
    from attend import cli

    model, log = _files(tmp_path)

    def read_only(path, *args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(path))

    monkeypatch.setattr(attend.plotting, "plot_estimates", read_only)
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv"), "--plot",
                 str(tmp_path / "e.png")]) == 2
    _one_error_line(capsys, "e.png", "read-only")
    monkeypatch.setattr(cli.tempfile, "TemporaryFile", lambda dir: read_only(dir))
    assert main(["reproduce", "all", "--out", str(tmp_path / "results")]) == 2
    _one_error_line(capsys, "results", "read-only")
    assert main(["search", "--out", str(tmp_path / "search")]) == 2
    _one_error_line(capsys, "search", "read-only")
    (tmp_path / "file").write_text("")
    assert main(["search", "--out", str(tmp_path / "file")]) == 2
    _one_error_line(capsys, "--out", "is a file; expected a directory")


def test_debug_is_accepted_before_or_after_the_command(tmp_path):
    from attend._validation import AttendInputError

    for argv in (["--debug", "estimate", "missing.toml", "missing.csv"],
                 ["estimate", "missing.toml", "missing.csv", "--debug"]):
        with pytest.raises(AttendInputError, match="does not exist"):
            main(argv)


def test_internal_errors_are_not_blamed_on_the_user(tmp_path, capsys, monkeypatch):
    from attend import workflows

    model, log = _files(tmp_path)

    def bug(*args, **kwargs):
        raise ValueError("an internal slip")

    monkeypatch.setattr(workflows, "estimate_from_files", bug)
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("attend: internal error: ValueError: an internal slip; please report it")
    assert "--debug" in err and "Traceback" not in err
    with pytest.raises(ValueError, match="internal slip"):
        main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv"), "--debug"])


@pytest.mark.parametrize("gaps", [False, True])
def test_a_failure_inside_the_smoother_names_the_model_and_the_log(tmp_path, capsys, monkeypatch, gaps):
    """The recursion's own errors (a singular innovation covariance, a non-finite estimate: logs of 1e140 found
    them in bench_fuzz.py) are one line naming both files, on complete logs and on logs with gaps."""
    from attend import AttendInputError
    from attend.perception.kalman import KalmanEstimator

    t = np.arange(60) * 0.1
    y = np.sin(t)
    if gaps:
        y[7] = np.nan
    model, log = _files(tmp_path, log="t,y\n" + "\n".join(f"{a:.10g},{b:.10g}" for a, b in zip(t, y)) + "\n")

    def failing(*args, **kwargs):
        raise AttendInputError("outputs: the estimate went non-finite; check the scale of the log and of the precisions")

    monkeypatch.setattr(KalmanEstimator, "estimate", failing)
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv")]) == 2
    _one_error_line(capsys, f"{model}: [observer] outputs: the estimate went non-finite", f"(on the log {log})")


@pytest.mark.parametrize("where", ["one", "every"])
def test_huge_values_in_a_log_are_errors_naming_file_column_and_line(tmp_path, capsys, where):
    t = np.arange(60) * 0.1
    y = np.sin(t)
    if where == "one":
        y[9] = 1e300
    else:
        y[:] = 1e300
    log = "t,y\n" + "\n".join(f"{a:.10g},{b:.10g}" for a, b in zip(t, y)) + "\n"
    model, log_path = _files(tmp_path, log=log)
    assert main(["estimate", str(model), str(log_path), "--out", str(tmp_path / "e.csv")]) == 2
    line = 11 if where == "one" else 2
    _one_error_line(capsys, str(log_path), f"line {line}", "column 'y'", "1e+300")


def test_excel_bom_and_crlf_logs_are_read(tmp_path, capsys):
    t = np.arange(60) * 0.1
    text = "t,y\r\n" + "\r\n".join(f"{a:.10g},{b:.10g}" for a, b in zip(t, np.sin(t))) + "\r\n"
    model, log = _files(tmp_path, log=b"\xef\xbb\xbf" + text.encode())
    assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv")]) == 0
    table = np.loadtxt(tmp_path / "e.csv", delimiter=",", skiprows=1)
    assert table.shape == (60, 7) and np.all(np.isfinite(table))


def test_binary_files_are_named(tmp_path, capsys):
    model, log = _files(tmp_path, log=b"\x89PNG\r\n\x1a\n\xd0\xff")
    assert main(["estimate", str(model), str(log)]) == 2
    _one_error_line(capsys, str(log), "UTF-8", "0x89")
    model.write_bytes(b"\xd0\xcf\x11\xe0")
    assert main(["estimate", str(model), str(log)]) == 2
    _one_error_line(capsys, str(model), "UTF-8")


def test_short_logs_name_the_file(tmp_path, capsys):
    model, log = _files(tmp_path, log="t,y\n0,1\n")
    assert main(["estimate", str(model), str(log)]) == 2
    _one_error_line(capsys, str(log), "at least 2 samples")
    assert main(["identify", str(model), str(log)]) == 2
    _one_error_line(capsys, str(model), "identify needs measured inputs")


def test_reproduce_with_a_relative_out_embeds_every_figure_and_caches(tmp_path, capsys, monkeypatch):
    """Experiments that store figure paths as out_dir / name (relative --out) must not lose their
    figures in the report nor miss the cache."""
    import types

    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from attend import experiments
    from attend.experiments._result import ExperimentResult

    calls = []

    def fake_experiment(name, n_figures):
        def run(quick=True, progress=True):
            calls.append(name)
            result = ExperimentResult(name)
            result.add("value", 1.0, "")
            return result

        def plot(result, out_dir):
            paths = []
            for i in range(n_figures):
                path = Path(out_dir) / f"{name}_{i}.png"  # the pattern of the experiments: out_dir / name
                figure = Figure(figsize=(1, 1))
                figure.add_subplot().plot([0, 1])
                figure.savefig(path)
                paths.append(str(path))
            return paths
        return types.SimpleNamespace(run=run, plot=plot)

    modules = {"first": fake_experiment("first", 2), "second": fake_experiment("second", 3)}
    monkeypatch.setattr(experiments, "available", lambda: {name: f"{name} experiment" for name in modules})
    monkeypatch.setattr(experiments, "load", modules.__getitem__)
    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "all", "--out", "results", "--no-progress"]) == 0
    page = (tmp_path / "results" / "index.html").read_text()
    written = sorted((tmp_path / "results").glob("*.png"))
    assert len(written) == 5 and page.count("data:image/png;base64,") == len(written)
    assert calls == ["first", "second"]
    assert main(["reproduce", "all", "--out", "results", "--no-progress"]) == 0
    assert calls == ["first", "second"]  # both cached
    assert capsys.readouterr().out.count("cached") == 2
    page = (tmp_path / "results" / "index.html").read_text()
    assert page.count("data:image/png;base64,") == 5


def test_search_shows_progress_unless_asked_not_to(tmp_path, capsys):
    for ground in (["--map", "gp", "--no-gif", "--diagonal"], []):
        assert main(["search", "--planner", "lawnmower", "--budget", "12", *ground, "--out", str(tmp_path / "a")]) == 0
        assert "s flown" in capsys.readouterr().err
        assert main(["search", "--planner", "lawnmower", "--budget", "12", *ground,
                     "--out", str(tmp_path / "b"), "--no-progress"]) == 0
        assert "s flown" not in capsys.readouterr().err


def test_reproduce_all_reports_bad_input_and_bugs_of_experiments_apart(tmp_path, capsys, monkeypatch):
    import types

    from attend import experiments
    from attend._validation import AttendInputError

    def failing(error):
        def run(quick=True, progress=True):
            raise error
        return types.SimpleNamespace(run=run, plot=lambda result, out_dir: [])

    modules = {"needs_data": failing(AttendInputError("data_dir: the flight logs are missing")),
               "buggy": failing(RuntimeError("slip"))}
    monkeypatch.setattr(experiments, "available", lambda: {name: name for name in modules})
    monkeypatch.setattr(experiments, "load", modules.__getitem__)
    assert main(["reproduce", "all", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "attend: error: experiment needs_data: data_dir: the flight logs are missing" in err
    assert "attend: internal error: experiment buggy failed: RuntimeError: slip; please report it" in err
    del modules["buggy"]
    assert main(["reproduce", "all", "--out", str(tmp_path)]) == 2


def test_identify_example_of_the_docs_on_the_whole_bundled_flight(tmp_path, capsys):
    """docs/command-line.md 'Identify your model': the bundled roll model + its [learning] section on the whole bundled
    flight (3481 samples) converges (exit 0) and reports the learned A's eigenvalues."""
    import re
    from pathlib import Path

    root = Path(__file__).parents[1]
    page = (root / "docs" / "command-line.md").read_text()
    section = page[page.index("## Identify your model"):]
    learning = re.search(r"```toml\n(\[learning\].*?)```", section, re.S).group(1)
    assert "known_prior_precision = inf" in learning
    data = root / "src" / "attend" / "data"
    (tmp_path / "model.toml").write_text((data / "quadrotor_roll.toml").read_text() + "\n" + learning)
    out = tmp_path / "learned.toml"
    assert main(["identify", str(tmp_path / "model.toml"), str(data / "quadrotor_roll_wind.csv"), "--out", str(out),
                 "--no-progress"]) == 0
    report = capsys.readouterr().out
    assert "converged at iteration" in report and "eigenvalues of the learned A" in report
    assert out.exists()


def test_reproduce_runs_then_plots_and_report_redraws_from_the_json(tmp_path, capsys, monkeypatch):
    """The CLI runs an experiment, then plots it; `attend report` redraws it from its JSON."""
    import types

    from attend import experiments, report
    from attend.experiments._result import ExperimentResult
    from attend.plotting import figure

    def draw(path):
        fig, axis = figure((1, 1))
        axis.plot([0, 1])
        fig.savefig(path)

    plotted = []

    def new_run(quick=True, progress=True):
        result = ExperimentResult("new")
        result.add("value", 2.0, "m")
        result.tables = {"line": [0.0, 1.0]}
        return result

    def new_plot(result, out_dir):
        plotted.append(result.tables["line"])
        draw(Path(out_dir) / "new.png")
        return ["new.png"]

    modules = {"new": types.SimpleNamespace(run=new_run, plot=new_plot, CAPTIONS={"new.png": "a caption"})}
    monkeypatch.setattr(experiments, "available", lambda: {name: name for name in modules})
    monkeypatch.setattr(experiments, "load", modules.__getitem__)
    monkeypatch.setattr(experiments, "EXPERIMENTS", {name: ("", name) for name in modules})
    monkeypatch.setattr(report, "_module", modules.get)
    assert main(["reproduce", "all", "--out", str(tmp_path), "--no-progress"]) == 0
    assert plotted == [[0.0, 1.0]]
    assert json_figures(tmp_path / "new.json") == ["new.png"]
    (tmp_path / "new.png").unlink()
    assert main(["report", str(tmp_path)]) == 0
    assert plotted == [[0.0, 1.0]] * 2 and (tmp_path / "new.png").is_file()
    assert "a caption" in (tmp_path / "index.html").read_text()


def json_figures(path):
    import json

    return json.loads(path.read_text())["figures"]


def test_report_help_teaches(capsys):
    with pytest.raises(SystemExit):
        main(["report", "--help"])
    text = capsys.readouterr().out
    assert "DIR" in text and "JSON" in text and "exit status" in text
    with pytest.raises(SystemExit):
        main(["search", "--help"])
    text = capsys.readouterr().out
    assert "[s]" in text and "[m/s]" in text and "default" in text


def test_estimate_plot_labels_units_and_measured_inputs(tmp_path, monkeypatch):
    """The --plot figure: every axis with a unit, a band narrower than the signal still visible on
    its own axis, and measured inputs drawn as measured (not as an estimate)."""
    import types

    from attend import plotting
    from attend.cli import DEMO_UNITS

    made = []
    original = plotting.figure

    def recording(*args, **kwargs):
        fig, axes = original(*args, **kwargs)
        made.append(axes)
        return fig, axes

    monkeypatch.setattr(plotting, "figure", recording)
    time = np.arange(50) * 0.1
    system = types.SimpleNamespace(state_names=("phi", "phi_dot"), input_names=("motor_1", "motor_2"))
    estimate = types.SimpleNamespace(states=np.column_stack([np.sin(time), np.cos(time)]),
                                     inputs=np.column_stack([np.ones(50), np.zeros(50)]),
                                     state_std=np.full((50, 2), 1e-5), input_std=np.full((50, 2), 0.1))
    plotting.plot_estimates(tmp_path / "e.png", time, system, estimate, measured_inputs=[0], units=DEMO_UNITS)
    axes = made[0]
    assert all("[" in axis.get_ylabel() for axis in axes[:, 0])
    assert [line.get_label() for line in axes[2, 0].get_lines()] == ["measured input"]
    assert [line.get_label() for line in axes[3, 0].get_lines()] == ["estimate"]
    assert np.allclose(axes[0, 1].get_lines()[0].get_ydata(), 2e-5)  # the band's half-width, own scale
    assert axes[0, 0].get_ylabel() == "phi [rad]" and (tmp_path / "e.png").stat().st_size > 10_000


def test_estimate_warns_when_a_state_swings_far_beyond_what_the_data_support(tmp_path, capsys):
    """A log in degrees for a model in radians: attend estimate runs and names the state and settings."""
    import numpy as np

    from attend.models.linear import simulate
    from attend.models.problems import mass_spring_damper

    dt, n_samples = 0.05, 800
    force = np.sin(0.7 * np.arange(n_samples) * dt)[:, None]
    log = simulate(mass_spring_damper(), force, dt, kernel_width=0.1, process_std=[1e-3, 0.3],
                   measurement_std=0.02, seed=0)
    rows = ["t,pos,force"] + [f"{k * dt!r},{float(y) * 180 / np.pi!r},{float(u)!r}"
                              for k, (y, u) in enumerate(zip(log.outputs[:, 0], force[:, 0]))]
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    model = """
[model]
A = [[0, 1], [-0.5714285714285714, -0.2857142857142857]]
B = [[0], [0.7142857142857143]]
C = [[1, 0]]
states = ["position", "velocity"]
[outputs]
columns = ["pos"]
[[inputs]]
name = "force"
column = "force"
[observer]
kernel_width = 0.1
sensor_precision = %r
process_precision = [1e6, 11.11111111111111]
[log]
time_column = "t"
""" % (0.02 * 180 / np.pi) ** -2
    (tmp_path / "model.toml").write_text(model)
    assert main(["estimate", str(tmp_path / "model.toml"), str(tmp_path / "log.csv"),
                 "--out", str(tmp_path / "out.csv")]) == 0
    err = capsys.readouterr().err
    assert "attend: warning:" in err and "velocity: the estimate's RMS" in err, err
    assert "prior spread under the model" in err and "process_precision" in err
    # the same log in the model's unit: silent
    rows = ["t,pos,force"] + [f"{k * dt!r},{float(y)!r},{float(u)!r}" for k, (y, u) in enumerate(zip(log.outputs[:, 0], force[:, 0]))]
    (tmp_path / "log.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "model.toml").write_text(model.replace("%r" % ((0.02 * 180 / np.pi) ** -2), "2500.0"))
    assert main(["estimate", str(tmp_path / "model.toml"), str(tmp_path / "log.csv"),
                 "--out", str(tmp_path / "out.csv")]) == 0
    assert "estimate's RMS" not in capsys.readouterr().err


def test_a_kernel_width_far_beyond_the_log_is_one_clean_line_for_both_commands(tmp_path, capsys):
    """kernel_width = 1e200 s: `attend estimate` names the width in sample times once (the file named
    once), `attend identify` names kernel_width (was an OverflowError in S(s), exit 1)."""
    (tmp_path / "model.toml").write_text(MASS_SPRING_LEARNING_MODEL.replace("kernel_width = 0.5", "kernel_width = 1e200"))
    t = np.arange(60) * 0.1
    np.savetxt(tmp_path / "log.csv", np.column_stack([t, np.sin(t), np.cos(t)]), delimiter=",", header="t,y,u",
               comments="")
    model, log = str(tmp_path / "model.toml"), str(tmp_path / "log.csv")
    assert main(["estimate", model, log, "--out", str(tmp_path / "e.csv"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("model.toml: [observer]") == 1 and "1e+201 sample times" in err and err.count("\n") == 1
    assert main(["identify", model, log, "--out", str(tmp_path / "learned.toml"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "kernel_width: a width of 1e+200" in err and "floating-point range" in err and err.count("\n") == 1
