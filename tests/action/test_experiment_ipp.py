"""The ipp experiment's trial runner on short missions (the full run is in benchmarks/)."""

import numpy as np

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
