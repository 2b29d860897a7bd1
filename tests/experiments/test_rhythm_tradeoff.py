"""rhythm-tradeoff: tuning and trial seeds are disjoint, every family gets the same tuning budget,
the quick run keeps the JSON contract, and a Dask cluster gives the local numbers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from attend import AttendInputError
from attend.experiments import rhythm_tradeoff as rt
from attend.experiments._result import ExperimentResult

TINY = dict(progress=False, trials=2, tuning_seeds=2, settings_per_family=1, points=[0, 2])


def _cfg(quick):
    mode = "quick" if quick else "full"
    return dict(rt.SETTINGS, quick=quick, trials=rt.SETTINGS[f"{mode}_trials"],
                tuning_seeds=rt.SETTINGS[f"{mode}_tuning_seeds"])


@pytest.mark.parametrize("quick", [True, False])
def test_tuning_and_trial_seeds_are_disjoint(quick):
    cfg = _cfg(quick)
    tune, trial = rt.tuning_seed_list(cfg), rt.trial_seed_list(cfg)
    assert not set(tune) & set(trial)
    assert trial == list(range(len(trial)))  # the seeds of `attend reproduce ipp`
    assert min(tune) == 100
    if not quick:
        assert len(trial) >= 25


def test_overlapping_seeds_are_refused(monkeypatch):
    monkeypatch.setitem(rt.SETTINGS, "tuning_first_seed", 1)
    with pytest.raises(AttendInputError, match="overlap"):
        rt.run(quick=True, progress=False, trials=3, points=[0])


def test_every_family_gets_the_same_tuning_budget():
    for families in (rt.IPP_FAMILIES, rt.VISION_FAMILIES):
        sizes = {name: len(grid) for name, grid in families.items() if name != "continuous"}
        assert set(sizes.values()) == {rt.SETTINGS["full_settings_per_family"]}
        assert all(len({repr(p) for p in grid}) == len(grid) for grid in families.values())  # distinct settings
    assert len(rt.IPP_FAMILIES["continuous"]) == 1  # nothing to tune


def test_oscillator_shorter_than_its_saccade_is_infeasible():
    cfg = dict(_cfg(True), vision_duration_s=0.1)
    out = rt.vision_episode(dict(domain="vision", saccade_cost_s=0.15, family="oscillator",
                                 params=dict(frequency_hz=8.0), seed=100, settings=cfg))
    assert out["objective"] == float("inf") and not out["feasible"]


def test_paired_interval_closed_form():
    mean, low, high = rt.paired_interval(np.array([1.0, 2.0, 3.0]))
    assert mean == 2.0
    assert high - mean == pytest.approx(4.302652729911275 * 1.0 / np.sqrt(3))  # t_{0.975, 2} s / sqrt(n)
    assert mean - low == pytest.approx(high - mean)


def test_quick_run_contract(tmp_path):
    result = rt.run(quick=True, progress=False)
    result.figures = rt.plot(result, tmp_path)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "rhythm-tradeoff"
    assert {"name", "value", "published", "unit"} <= set(data["metrics"][0])
    assert set(rt.SETTINGS) <= set(data["settings"])
    assert (tmp_path / "rhythm-tradeoff.png").stat().st_size > 10_000
    rows = data["map"]
    assert [r["domain"] for r in rows] == ["ipp", "ipp", "vision", "vision"]
    assert rows[0]["blur"] == 0.0 and rows[0]["latency_s"] == 0.0  # the zero-cost limit is on the map
    for row in rows:
        assert row["winner"] in row["mean"]
        assert row["mean"][row["winner"]] == min(row["mean"].values())
        budget = {f: n for f, n in row["evaluated"].items() if f != "continuous"}
        assert set(budget.values()) == {rt.SETTINGS["quick_settings_per_family"]}
        assert row["versus_fixed"]["fixed"] == [0.0, 0.0, 0.0]
        for mean, low, high in row["versus_fixed"].values():
            assert low <= mean <= high
    ipp = rows[0]["summary"]["fixed"]
    assert {"final_rse", "final_trace", "time_to_find_all_median_s", "false_alarm_cells"} <= set(ipp)
    assert result.metric("trial seeds").value == rt.SETTINGS["quick_trials"]
    # the map survives the report cache (JSON -> result -> JSON)
    assert ExperimentResult.from_json_dict(data).to_json_dict()["map"] == rows


# ---- a real Dask cluster ----------------------------------------------------------------------


def test_cluster_run_equals_the_local_run():
    distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed")
    local = rt.run(quick=True, **TINY)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as two_workers:
        remote = rt.run(quick=True, cluster=two_workers.scheduler_address, **TINY)
    assert len(local.tables["map"]) == 2
    for a, b in zip(local.tables["map"], remote.tables["map"]):
        assert a["tuned"] == b["tuned"] and a["winner"] == b["winner"]
        assert a["mean"] == b["mean"]
        assert a["versus_fixed"] == b["versus_fixed"]
    values = lambda r: [m.value for m in r.metrics if m.name != "wall_time"]
    assert values(local) == values(remote)
