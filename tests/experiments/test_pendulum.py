"""Pendulum reproduction: the JSON contract, the figure, and what the quick run must show."""

import json

import numpy as np

from attend.experiments import available, pendulum
from attend.experiments._result import ExperimentResult


def test_pendulum_quick_contract(tmp_path):
    run = pendulum.run(quick=True, progress=False, seeds=2)
    run.figures = pendulum.plot(run, tmp_path)
    result = ExperimentResult.from_json_dict(json.loads(run.write(tmp_path).read_text()))
    assert result.experiment == "pendulum" and (tmp_path / "pendulum.png").stat().st_size > 20_000
    for name in ("DEM input SSE (median)", "augmented UKF input SSE (median)", "particle input SSE (median)",
                 "DEM / augmented UKF input SSE (median ratio)"):
        assert np.isfinite(result.metric(name).value)
    assert np.shape(result.tables["example"]["DEM_inputs"]) == (300, 1)
    value = lambda name: result.metric(name).value  # noqa: E731
    assert value("DEM / UKF filter state SSE (median ratio)") < 1.0
    energy = np.sum(pendulum.true_input(np.arange(int(15.0 / 0.05)) * 0.05) ** 2)
    assert value("DEM input SSE (median)") < 0.6 * energy
    input_claim = pendulum.claims(result)[2]
    assert "input SSE" in input_claim.claim and input_claim.verdict == (
        "reproduced" if value("DEM input SSE (median)") <= value("augmented UKF input SSE (median)") else "does not hold")
    assert "pendulum" in available()
