"""Fig. 2 experiment: the JSON contract and the paper's claim (more orders, lower input SSE)."""

import json

import numpy as np

from attend.experiments import fig2


def test_fig2_contract_and_claim(tmp_path):
    result = fig2.run(quick=True, out_dir=tmp_path, progress=False, seeds=3)
    path = result.write(tmp_path)
    data = json.loads(path.read_text())
    assert data["experiment"] == "fig2"
    assert {"name", "value", "published", "unit"} <= set(data["metrics"][0])
    assert (tmp_path / "fig2.png").stat().st_size > 20_000
    input_sse = result.data["input_sse"]
    assert np.all(input_sse[:, -1] < 0.1 * input_sse[:, 0])  # p = 6 vs p = 0, every seed
    assert np.median(result.data["state_sse"][:, -1]) < 0.1 * np.median(result.data["kf_state_sse"])
