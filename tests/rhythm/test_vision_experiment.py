"""Vision experiment: the JSON contract and its figure files on a tiny run."""

import json

from attend.experiments import vision


def test_vision_contract(tmp_path):
    result = vision.run(quick=True, progress=False, scenes=2)
    result.figures = vision.plot(result, tmp_path)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "vision"
    assert {"name", "value", "published", "unit"} <= set(data["metrics"][0])
    names = {m["name"] for m in data["metrics"]}
    for policy in ("epistemic", "static_saliency", "random"):
        assert f"{policy}: revisit rate, first 12 saccades" in names
    for suffix in ("vision.png", "vision_scanpath.png", "vision_scanpath.gif"):
        assert (tmp_path / suffix).stat().st_size > 10_000
