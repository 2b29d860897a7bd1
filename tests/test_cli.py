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
