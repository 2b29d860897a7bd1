"""The HTML report and `attend report DIR`: claims table first, captions under the figures, the
metric table folded away, figures rebuilt from the JSON alone, and one-line errors naming the file."""

import json
import shutil
from pathlib import Path

import pytest

from attend.cli import main
from attend.experiments import fig2, quadrotor

DATA = Path(__file__).parent / "experiments" / "data"


@pytest.fixture
def folder(tmp_path):
    """A results folder holding only the JSON of fig2 and quadrotor (no figures yet)."""
    for name in ("fig2", "quadrotor"):
        shutil.copy(DATA / f"{name}.json", tmp_path / f"{name}.json")
    return tmp_path


def test_report_rebuilds_figures_and_opens_with_the_claims(folder, capsys):
    assert main(["report", str(folder)]) == 0
    for name in list(fig2.CAPTIONS) + list(quadrotor.CAPTIONS):
        assert (folder / name).stat().st_size > 1000
    page = (folder / "index.html").read_text()
    claims, first_section = page.index('<table id="claims">'), page.index("<section")
    assert claims < first_section < page.index('<details id="metrics">')
    # one claims row per claim, coloured by verdict
    from attend.experiments._result import ExperimentResult

    result = ExperimentResult.from_json_dict(json.loads((folder / "fig2.json").read_text()))
    claims_html = page[claims: page.index("</table>", claims)]
    for claim in fig2.claims(result):
        assert claim.claim.replace("'", "&#x27;") in claims_html
    assert claims_html.count('class="verdict"') == len(fig2.claims(result)) + len(quadrotor.claims(
        ExperimentResult.from_json_dict(json.loads((folder / "quadrotor.json").read_text()))))
    assert "background: #" in claims_html
    # captions under the figures, not file names
    assert fig2.CAPTIONS["fig2.png"][:60] in page
    assert quadrotor.CAPTIONS["quadrotor_sse_vs_p.png"][:60] in page
    assert page.count("data:image/png;base64,") == 5
    # every metric is in the folded table
    metrics = page[page.index('<details id="metrics">'):]
    assert "<summary>" in metrics and "dem_sse_wind_p3" in metrics and "input SSE ratio" in metrics


def test_old_json_without_tables_still_renders(tmp_path):
    data = json.loads((DATA / "fig2.json").read_text())
    old = {key: data[key] for key in ("experiment", "metrics", "settings", "figures", "notes", "runtime_s", "cache_key")}
    old["metrics"] = old["metrics"][:2]  # too few metrics for the claims
    (tmp_path / "fig2.json").write_text(json.dumps(old))
    assert main(["report", str(tmp_path)]) == 0
    page = (tmp_path / "index.html").read_text()
    assert 'class="verdict"' not in page and "No experiment in this folder states claims" in page
    assert "DEM state SSE, p = 0 (median)" in page and not (tmp_path / "fig2.png").exists()


def test_modules_without_claims_or_captions_fall_back_to_file_names(tmp_path, monkeypatch):
    import types

    from attend import report
    from attend.experiments._result import ExperimentResult
    from attend.plotting import figure

    result = ExperimentResult("old", figures=["old_figure.png"])
    result.add("value", 1.0, "m")
    fig, axis = figure((2, 2))
    axis.plot([0, 1])
    fig.savefig(tmp_path / "old_figure.png")
    monkeypatch.setattr(report, "_module", lambda name: types.SimpleNamespace(run=lambda quick=True: None))
    page = report.write_report(tmp_path, [result], {"old": "an old experiment"}, "attend report", 0.1).read_text()
    assert "<figcaption>old_figure.png</figcaption>" in page and 'class="verdict"' not in page


@pytest.mark.parametrize("content, expected", [("{not json", "not valid JSON"), ('{"metrics": []}', "not an attend result")])
def test_corrupt_json_is_a_one_line_error_naming_the_file(folder, capsys, content, expected):
    (folder / "fig2.json").write_text(content)
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("attend: error: ") and len(err.splitlines()) == 1
    assert str(folder / "fig2.json") in err and expected in err


def test_missing_json_or_folder_is_named(tmp_path, capsys):
    assert main(["report", str(tmp_path), "fig3"]) == 2
    assert str(tmp_path / "fig3.json") in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "holds no result" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "nowhere")]) == 2
    assert "no such folder" in capsys.readouterr().err
