"""Lorenz reproduction: the JSON contract, the figure, and what the quick run must show; both
nonlinear reproductions re-plot from their committed JSON (tests/experiments/data)."""

import json
from pathlib import Path

import pytest

from attend.experiments import available, lorenz, pendulum
from attend.experiments._result import VERDICTS, Claim, ExperimentResult

DATA = Path(__file__).parent / "data"


def test_lorenz_quick_contract(tmp_path):
    result = lorenz.run(quick=True, progress=False, seeds=2)
    result.figures = lorenz.plot(result, tmp_path)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "lorenz"
    names = {m["name"] for m in data["metrics"]}
    assert {"DEM state SSE (median)", "UKF state SSE (median)", "particle state SSE (median)",
            "DEM / particle state SSE (median ratio)", "DEM speed"} <= names
    assert len(data["state_sse"]["DEM"]) == 2 and len(data["example"]["DEM_states"]) == 200
    assert (tmp_path / "lorenz.png").stat().st_size > 20_000
    value = lambda name: result.metric(name).value  # noqa: E731
    # DEM beats the white-noise UKF filter and stays near the particle reference
    assert value("DEM / UKF filter state SSE (median ratio)") < 1.0
    assert value("DEM / particle state SSE (median ratio)") < 1.5
    assert 0.9 < value("DEM |error| < 2 std (fraction of samples)") < 0.99
    # the UKF smoother's own std is too small under coloured noise; its error spread is not
    assert value("UKF (white-noise std) |error| < 2 std (fraction of samples)") < 0.85
    assert 0.9 < value("UKF (error spread) |error| < 2 std (fraction of samples)") < 0.99
    assert "lorenz" in available()


@pytest.mark.parametrize("module", [lorenz, pendulum], ids=["lorenz", "pendulum"])
def test_nonlinear_figure_replots_from_the_committed_json(module, tmp_path):
    name = module.__name__.rsplit(".", 1)[-1]
    text = (DATA / f"{name}.json").read_text()
    assert len(text) < 1_000_000
    result = ExperimentResult.from_json_dict(json.loads(text))
    assert result.data == {}  # nothing but the JSON
    files = module.plot(result, tmp_path)
    assert files == [f"{name}.png"] and set(module.CAPTIONS) == set(files)
    assert (tmp_path / files[0]).stat().st_size > 20_000
    claims = module.claims(result)
    assert claims and all(isinstance(c, Claim) and c.verdict in VERDICTS for c in claims)
    # the verdicts follow the measured numbers; an unconverged particle reference (the quick run's
    # 1000 particles) is checked against the coloured UKS as well
    ratio = max(result.metric("DEM / particle state SSE (median ratio)").value,
                result.metric("DEM / coloured UKS state SSE (median ratio)").value)
    assert (claims[0].verdict == "reproduced") == (ratio <= 1.2)
    assert f"median ratio {ratio:.2f}" in claims[0].measured
    dem, ukf = result.metric("DEM state SSE (median)").value, result.metric("UKF state SSE (median)").value
    assert (claims[1].verdict == "reproduced") == (dem <= ukf)
