"""The four rhythm experiments re-plot from their JSON alone: each committed quick-run result
(tests/experiments/data/NAME.json, written by ``attend reproduce NAME``) is rebuilt with
ExperimentResult.from_json_dict, its figures are drawn, and its claims are read from it."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from attend.experiments import load
from attend.experiments._result import VERDICTS, Claim, ExperimentResult

DATA = Path(__file__).resolve().parents[1] / "experiments" / "data"
NAMES = ["rhythm-ipp", "rhythm-learning", "rhythm-tradeoff", "vision"]


def _result(name: str) -> ExperimentResult:
    return ExperimentResult.from_json_dict(json.loads((DATA / f"{name}.json").read_text()))


@pytest.mark.parametrize("name", NAMES)
def test_the_figures_are_drawn_from_the_json_alone(name, tmp_path):
    module, result = load(name), _result(name)
    paths = [Path(p) for p in module.plot(result, tmp_path)]
    assert sorted(p.name for p in paths) == sorted(result.figures)  # the files the CLI run drew
    assert set(module.CAPTIONS) == {p.name for p in paths}
    for path in paths:
        assert path.parent == tmp_path and path.stat().st_size > 10_000


@pytest.mark.parametrize("name", NAMES)
def test_the_claims_state_measured_numbers_and_a_verdict(name):
    module, result = load(name), _result(name)
    found = module.claims(result)
    assert found and all(isinstance(claim, Claim) for claim in found)
    for claim in found:
        assert claim.verdict in VERDICTS
        assert re.search(r"\d", claim.measured)


@pytest.mark.parametrize("name", NAMES)
def test_what_the_figures_need_is_small(name):
    assert (DATA / f"{name}.json").stat().st_size < 1_000_000


def test_the_verdicts_follow_the_quick_run_numbers():
    learning = load("rhythm-learning").claims(_result("rhythm-learning"))[0]
    result = _result("rhythm-learning")
    beaten = result.metric("fixed_policies_beaten_on_worst_case_relative_regret").value
    holds = beaten == result.metric("fixed_policies").value
    quick = result.settings["seeds"] < 20  # a quick run cannot reproduce the claim, only fail it
    assert learning.verdict == ("does not hold" if not holds else "differs" if quick else "reproduced")
    ipp = _result("rhythm-ipp")
    for claim in load("rhythm-ipp").claims(ipp):  # not better than the best fixed budget by 2 s.e.m.
        policy = {"the troughs of a rhythm": "oscillator", "(no rhythm)": "precision_no_prior"}
        name = next((v for k, v in policy.items() if k in claim.claim), "precision")
        mean = ipp.metric(f"{name}_minus_best_fixed_final_RSE_mean").value
        sem = ipp.metric(f"{name}_minus_best_fixed_final_RSE_sem").value
        assert (claim.verdict == "reproduced") == (mean + 2 * sem < 0)
