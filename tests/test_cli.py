"""The command line: help texts, the demo, and one-line errors instead of tracebacks."""

import numpy as np
import pytest

from attend.cli import main


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

    def small_run(quick=True, out_dir=None, progress=True):
        calls.append(quick)
        return original(quick=quick, out_dir=out_dir, progress=False, seeds=2)

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
    (tmp_path / "model.toml").write_text("""
[model]
A = [[0, 1], [-1.0, -1.0]]
B = [[0], [1.0]]
C = [[1, 0]]
[outputs]
columns = ["y"]
[[inputs]]
name = "force"
column = "u"
[observer]
kernel_width = 0.5
sensor_precision = 2980.0
process_precision = 2980.0
[learning]
free = ["A[2,1]", "A[2,2]", "B[2,1]"]
max_iterations = 50
""")
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
    search = next(a for a in parser._subparsers._group_actions[0].choices["search"]._actions if a.dest == "planner")
    assert set(search.choices) == set(PLANNERS)


def test_identify_readme_example_on_the_whole_bundled_flight(tmp_path, capsys):
    """README 'Identify your model': the bundled roll model + its [learning] section on the whole bundled
    flight (3481 samples) converges (exit 0) and reports the learned A's eigenvalues."""
    import re
    from pathlib import Path

    root = Path(__file__).parents[1]
    readme = (root / "README.md").read_text()
    section = readme[readme.index("### Identify your model"):]
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
