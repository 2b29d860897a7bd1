"""Fig. 5 experiment: run computes only; the JSON (SSE and lambda_z grids, crossing) re-plots;
the claims are judged from the metrics."""

import json

import numpy as np

from attend.experiments import fig5
from attend.experiments._result import VERDICTS, ExperimentResult


def test_fig5_contract(tmp_path):
    result = fig5.run(progress=False, n_seeds=2, n_noise_levels=3)
    assert not list(tmp_path.iterdir())
    rebuilt = ExperimentResult.from_json_dict(json.loads(result.write(tmp_path).read_text()))
    assert np.array(rebuilt.tables["sse"]).shape == (2, 3, 2)
    assert np.array_equal(np.array(rebuilt.tables["lambda_z"]), result.data["lambda_z"])
    assert fig5.plot(rebuilt, tmp_path) == ["fig5.png"]
    assert (tmp_path / "fig5.png").stat().st_size > 20_000
    claims = fig5.claims(rebuilt)
    assert len(claims) == 2 and all(claim.verdict in VERDICTS for claim in claims)


def test_fig5_claim_on_the_quick_fixture():
    from pathlib import Path

    data = json.loads((Path(__file__).parent / "data" / "fig5.json").read_text())
    claims = fig5.claims(ExperimentResult.from_json_dict(data))
    assert claims[0].verdict == "reproduced" and "crossing" in claims[0].measured
