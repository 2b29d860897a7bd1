"""Pendulum reproduction: the JSON contract, the figure, and what the quick run must show."""

import json

import numpy as np

from attend.experiments import available, pendulum


def test_pendulum_quick_contract(tmp_path):
    result = pendulum.run(quick=True, out_dir=tmp_path, progress=False, seeds=2)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "pendulum"
    names = {m["name"] for m in data["metrics"]}
    assert {"DEM input SSE (median)", "augmented UKF input SSE (median)", "particle input SSE (median)",
            "DEM / augmented UKF input SSE (median ratio)"} <= names
    assert (tmp_path / "pendulum.png").stat().st_size > 20_000
    value = lambda name: result.metric(name).value  # noqa: E731
    assert value("DEM / UKF filter state SSE (median ratio)") < 1.0
    energy = np.sum(pendulum.true_input(np.arange(int(15.0 / 0.05)) * 0.05) ** 2)
    assert value("DEM input SSE (median)") < 0.6 * energy
    assert "pendulum" in available()
