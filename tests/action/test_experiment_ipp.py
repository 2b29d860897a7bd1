"""The ipp experiment: its trial runner on short missions (the full run is in benchmarks/), and
its figures and claims rebuilt from a committed result (tests/experiments/data/ipp.json, made by
``attend reproduce ipp``)."""

import json
from pathlib import Path

import numpy as np

from attend.experiments import ipp
from attend.experiments._result import VERDICTS, ExperimentResult
from attend.experiments.ipp import run_trials, summarise


def test_trials_share_fields_across_planners_and_summarise():
    logs = run_trials(planners=("lawnmower", "random"), trials=2, budget_s=14.0)
    assert set(logs) == {"lawnmower", "random"} and all(len(v) == 2 for v in logs.values())
    # same seed -> same field -> same initial RSE for every planner
    np.testing.assert_allclose([r.series("rse")[0] for r in logs["lawnmower"]], [r.series("rse")[0] for r in logs["random"]])
    summary = summarise(logs["lawnmower"])
    assert summary["rse"].shape == (2,)
    assert np.all(summary["trace"] < 386.7)
    assert np.all(summary["found"] <= 7)


FIXTURE = Path(__file__).resolve().parents[1] / "experiments" / "data" / "ipp.json"


def fixture_result() -> ExperimentResult:
    return ExperimentResult.from_json_dict(json.loads(FIXTURE.read_text()))


def test_every_figure_renders_from_the_json_alone(tmp_path):
    result = fixture_result()
    paths = ipp.plot(result, tmp_path)
    assert sorted(Path(p).name for p in paths) == sorted(ipp.CAPTIONS)
    for path in paths:
        assert Path(path).stat().st_size > 20_000  # a drawn figure, not an empty canvas


def test_fixture_is_small_and_holds_the_curves_of_every_planner():
    assert FIXTURE.stat().st_size < 1_000_000
    curves = fixture_result().tables["curves"]
    assert set(curves) == {"time_s", *ipp.PLANNER_NAMES}
    for name in ipp.PLANNER_NAMES:
        assert len(curves[name]["rse"]["mean"]) == len(curves["time_s"])


def test_claims_come_from_the_metrics_with_a_verdict_each():
    result = fixture_result()
    claims = ipp.claims(result)
    assert claims and all(claim.verdict in VERDICTS for claim in claims)
    ordering = claims[2]  # adaptive < lawnmower < random in final RSE
    rse = {name: result.metric(f"{name}_final_RSE_mean").value for name in ("adaptive", "lawnmower", "random")}
    holds = rse["adaptive"] < rse["lawnmower"] < rse["random"]
    assert ordering.verdict == ("reproduced" if holds else "does not hold")
    assert f"{rse['lawnmower']:.2f}" in ordering.measured


def test_false_positive_episode_maps_are_kept_for_the_figure():
    maps = fixture_result().tables["false_positive_maps"]
    assert all(s["time_s"] <= t for s, t in zip(maps["snapshots"], ipp.FALSE_POSITIVE_SNAPSHOTS_S))
    assert len(maps["snapshots"]) == len(ipp.FALSE_POSITIVE_SNAPSHOTS_S)
    assert len(maps["truth"]) == maps["shape"][0] * maps["shape"][1]
