"""Lorenz reproduction: the JSON contract, the figure, and what the quick run must show."""

import json

from attend.experiments import available, lorenz


def test_lorenz_quick_contract(tmp_path):
    result = lorenz.run(quick=True, out_dir=tmp_path, progress=False, seeds=2)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "lorenz"
    names = {m["name"] for m in data["metrics"]}
    assert {"DEM state SSE (median)", "UKF state SSE (median)", "particle state SSE (median)",
            "DEM / particle state SSE (median ratio)", "DEM speed"} <= names
    assert (tmp_path / "lorenz.png").stat().st_size > 20_000
    value = lambda name: result.metric(name).value  # noqa: E731
    # DEM beats the white-noise UKF filter and stays near the particle reference
    assert value("DEM / UKF filter state SSE (median ratio)") < 1.0
    assert value("DEM / particle state SSE (median ratio)") < 1.5
    assert 0.9 < value("DEM |error| < 2 std (fraction of samples)") < 0.99
    assert "lorenz" in available()
