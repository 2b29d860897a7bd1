"""Fig. 4 experiment: run computes only; the JSON re-plots; a low P_theta learns, a high one keeps
the prior's error (the paper's claim, on a small sweep)."""

import json

import numpy as np

from attend.experiments import fig4
from attend.experiments._result import ExperimentResult


def test_fig4_contract_and_claim(tmp_path):
    result = fig4.run(progress=False, n_seeds=3, n_prior_precisions=4)
    assert not list(tmp_path.iterdir())
    rebuilt = ExperimentResult.from_json_dict(json.loads(result.write(tmp_path).read_text()))
    sse = np.array(rebuilt.tables["sse"])
    assert sse.shape == (4, 3) and np.array_equal(sse, result.data["sse"])
    extremes = rebuilt.tables["extremes"]
    assert [e["prior_precision"] for e in extremes] == [1e-4, 1e8]
    assert np.array(extremes[0]["parameters"]).shape[1] == 3
    assert fig4.plot(rebuilt, tmp_path) == ["fig4.png"]
    assert (tmp_path / "fig4.png").stat().st_size > 20_000
    assert [claim.verdict for claim in fig4.claims(rebuilt)] == ["reproduced", "reproduced"]
