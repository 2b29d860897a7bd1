"""Fig. 2 experiment: the JSON contract (tables re-plot), the paper's claim (more orders, lower
input SSE) and the honest comparison with the augmented Kalman smoother."""

import json

import numpy as np

from attend.experiments import fig2
from attend.experiments._result import ExperimentResult


def test_fig2_contract_and_claim(tmp_path):
    result = fig2.run(quick=True, progress=False, seeds=3)
    assert not list(tmp_path.iterdir())  # run draws and writes nothing
    path = result.write(tmp_path)
    data = json.loads(path.read_text())
    assert data["experiment"] == "fig2"
    assert {"name", "value", "published", "unit"} <= set(data["metrics"][0])
    rebuilt = ExperimentResult.from_json_dict(data)
    assert fig2.plot(rebuilt, tmp_path) == ["fig2.png"]
    assert (tmp_path / "fig2.png").stat().st_size > 20_000
    per_seed = rebuilt.tables["per_seed"]
    input_sse = np.array(per_seed["input_sse"])
    assert input_sse.shape == (3, 7)
    assert np.all(input_sse[:, -1] < 0.1 * input_sse[:, 0])  # p = 6 vs p = 0, every seed
    assert np.median(np.array(per_seed["state_sse"])[:, -1]) < 0.1 * np.median(per_seed["kf_state_sse"])
    verdicts = [claim.verdict for claim in fig2.claims(rebuilt)]
    assert verdicts[:2] == ["reproduced", "reproduced"]
