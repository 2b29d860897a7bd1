"""Fig. 3 experiment: run computes only, the JSON holds seed 0's learning histories, plot draws
four distinct panels from it, and the learning moves every unknown parameter toward the truth."""

import json
from pathlib import Path

import numpy as np

from attend.experiments import fig3
from attend.experiments._result import ExperimentResult


def test_fig3_contract_histories_and_panels(tmp_path):
    result = fig3.run(quick=True, progress=False)
    assert not list(tmp_path.iterdir())
    rebuilt = ExperimentResult.from_json_dict(json.loads(result.write(tmp_path).read_text()))
    seed0 = rebuilt.tables["seed0"]
    history = np.array(seed0["paper"]["parameters"], dtype=float)
    truth = np.array(seed0["theta_true"])
    free = np.array(seed0["free"], dtype=bool)
    # every unknown parameter ends nearer the truth than its random prior mean
    assert np.all(np.abs(history[-1, free] - truth[free]) < np.abs(history[0, free] - truth[free]))
    assert len(seed0["paper"]["free_energy"]) == len(history)
    assert fig3.plot(rebuilt, tmp_path) == ["fig3.png"]
    assert (tmp_path / "fig3.png").stat().st_size > 20_000
    claims = fig3.claims(rebuilt)
    assert len(claims) == 5 and claims[3].verdict == "reproduced"  # the free energy rises


def test_fig3_panel_titles_are_distinct(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    saved = []
    monkeypatch.setattr(Figure, "savefig", lambda self, *args, **kwargs: saved.append(self))
    rebuilt = ExperimentResult.from_json_dict(json.loads((Path(__file__).parent / "data" / "fig3.json").read_text()))
    fig3.plot(rebuilt, tmp_path)
    panels = saved[0].axes
    assert sorted(axis.get_title().split(")")[0] for axis in panels) == ["a", "b", "c", "d"]
    assert all(axis.get_xlabel() and axis.get_ylabel() for axis in panels)
