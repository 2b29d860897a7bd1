"""Every experiment re-plots from its JSON alone: the committed fixture tests/experiments/data/NAME.json
(written by ``attend reproduce NAME``) is rebuilt with ExperimentResult.from_json_dict, drawn with the
module's plot into a fresh folder, and its claims carry valid verdicts."""

import inspect
import json
from pathlib import Path

import pytest

from attend import experiments
from attend.experiments._result import VERDICTS, Claim, ExperimentResult

DATA = Path(__file__).parent / "data"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _fixture(name: str) -> ExperimentResult:
    path = DATA / f"{name}.json"
    assert path.is_file(), f"missing fixture {path}: run 'attend reproduce {name} --out DIR' and copy DIR/{name}.json"
    return ExperimentResult.from_json_dict(json.loads(path.read_text()))


@pytest.mark.parametrize("name", sorted(experiments.EXPERIMENTS))
def test_figures_are_redrawn_from_the_json_alone(name, tmp_path):
    result = _fixture(name)
    module = experiments.load(name)
    assert "out_dir" not in inspect.signature(module.run).parameters, f"{name}: run() must compute only"
    written = module.plot(result, tmp_path)
    assert written
    for figure in written:
        path = Path(figure) if Path(figure).is_absolute() else tmp_path / figure
        assert path.parent == tmp_path, f"{name}: {figure} is not written into out_dir"
        head = path.read_bytes()[:8]
        assert path.stat().st_size > 1000 and (head == PNG_SIGNATURE or head.startswith(b"GIF8")), figure
    # the figures the JSON lists are file names relative to its folder, and plot redraws them all
    assert all(not Path(f).is_absolute() and len(Path(f).parts) == 1 for f in result.figures), result.figures
    assert {Path(f).name for f in written} >= set(result.figures)


@pytest.mark.parametrize("name", sorted(experiments.EXPERIMENTS))
def test_claims_and_captions(name):
    result = _fixture(name)
    module = experiments.load(name)
    found = module.claims(result)
    assert found and all(isinstance(claim, Claim) and claim.verdict in VERDICTS for claim in found)
    assert all(claim.claim and claim.measured for claim in found)
    assert set(result.figures) <= set(module.CAPTIONS), "every figure has a caption"
