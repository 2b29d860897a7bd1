"""Tests of attend.rhythm.replanning (schedules as replanning policies) and the rhythm-ipp
experiment's contract."""

import json
import math

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.action import Camera, Detector, FlightModel, Grid, OccupancyMap, PlanningSetup, make_field, make_planner
from attend.action.belief import kalman_update
from attend.action import fly
from attend.action.episode import PlanContext
from attend.rhythm.oscillator import PrecisionOscillator
from attend.rhythm.replanning import (
    FixedReplanning,
    PrecisionDrivenReplanning,
    RhythmicReplanning,
    SegmentReplanning,
    coarse_trace_reduction,
    expected_trace_reduction,
    fly_scheduled_mission,
    make_replan_policy,
    replan_policy,
)
from attend.rhythm.schedule import FixedSchedule, PrecisionDrivenSchedule, RhythmicSchedule
from attend.rhythm.schedule import switch_decision as replan_decision


def precision_policy(oscillator, prior_weight=0.5, tolerance=1.0, switch_cost_s=0.0):
    return replan_policy(PrecisionDrivenSchedule(oscillator, prior_weight, tolerance), switch_cost_s)


def _setup(seed=0, cma=0, cells_per_side=40, cell_size_m=0.75, lookahead=5):
    field = make_field(seed, grid=Grid(cells_per_side, cell_size_m))
    setup = PlanningSetup(field, Camera(), Detector(), FlightModel(), lookahead_waypoints=lookahead,
                          cma_evaluations=cma)
    return field, make_planner("precision_gain", setup, seed)


def test_replan_decision_closed_form():
    assert replan_decision(0.9, 1.0) and not replan_decision(1.1, 1.0)
    assert not replan_decision(0.9, 1.0, tolerance=0.8)  # 0.9 >= 0.8
    # at a trough (sin = -1) the bar is e^kappa higher, at a peak e^kappa lower
    assert replan_decision(1.5, 1.0, phase_angle=-math.pi / 2, prior_weight=0.5)  # 1.5 < e^0.5 = 1.65
    assert not replan_decision(1.7, 1.0, phase_angle=-math.pi / 2, prior_weight=0.5)
    assert not replan_decision(0.7, 1.0, phase_angle=math.pi / 2, prior_weight=0.5)  # 0.7 >= e^-0.5 = 0.61
    assert replan_decision(0.6, 1.0, phase_angle=math.pi / 2, prior_weight=0.5)


def test_expected_trace_reduction_closed_forms():
    grid = Grid(5, 6.0)
    full = OccupancyMap.prior(grid)
    d = np.zeros(grid.n_cells)
    d[[0, 1, 7, 12]] = [1.0, 2.0, 0.5, 3.0]
    posterior = np.linalg.inv(np.linalg.inv(full.covariance) + np.diag(d))
    expected = np.trace(full.covariance) - np.trace(posterior)
    assert expected_trace_reduction(full, d) == pytest.approx(expected, rel=1e-9)
    # the same as a Kalman update with noise variance 1 / d on the observed cells
    cells = np.flatnonzero(d)
    _, cov = kalman_update(full.mean, full.covariance, cells, np.zeros(len(cells)), 1.0 / d[cells])
    assert expected_trace_reduction(full, d) == pytest.approx(np.trace(full.covariance) - np.trace(cov), rel=1e-9)
    diagonal = OccupancyMap.prior(grid, diagonal=True)
    v = diagonal.covariance
    assert expected_trace_reduction(diagonal, d) == pytest.approx(np.sum(v - 1 / (1 / v + d)), rel=1e-12)
    assert expected_trace_reduction(diagonal, np.zeros(grid.n_cells)) == 0.0


def test_precision_rule_on_a_toy_belief():
    """One hover image over a uniform per-cell belief: stay rate = |A| (v - v r / (v + r)) / t."""
    field, planner = _setup(cells_per_side=8, cell_size_m=3.75)
    belief = OccupancyMap.prior(field.grid, diagonal=True)
    v = 0.5
    belief.covariance = np.full(field.grid.n_cells, v)
    pose = np.array([0.0, 0.0, 10.0])
    seen = Camera().visible_cells(pose[None], field.grid)[0].sum()
    r = 1 - math.exp(-0.05 * 10.0)
    wait = 2.0  # hover at the waypoint until the image 2 s later
    stay = seen * (v - v * r / (v + r)) / wait
    oscillator = PrecisionOscillator(frequency=0.05)
    for fresh, phase_time, weight, expected in [
        (stay * 1.01, 0.0, 0.0, True), (stay * 0.99, 0.0, 0.0, False),  # kappa = 0: plain comparison
        (stay / 1.3, 15.0, 0.5, True),   # trough (t = 15 s): replan although staying pays 30 % more
        (stay * 1.3, 5.0, 0.5, False),   # peak (t = 5 s): keep flying although a plan pays 30 % more
    ]:
        schedule = precision_policy(oscillator, prior_weight=weight)
        assert isinstance(schedule, PrecisionDrivenReplanning)
        schedule.plan_rate, schedule.plan_trace = fresh, belief.trace()
        context = PlanContext(planner, belief, pose, pose[None], phase_time, wait, 100.0)
        assert schedule.after_image(context) is expected
        t, s, f, decided = schedule.decisions[-1]
        assert s == pytest.approx(stay, rel=1e-12) and f == pytest.approx(fresh) and decided is expected
    # a used-up plan is always replanned
    assert schedule.after_image(PlanContext(planner, belief, pose, np.zeros((0, 3)), 5.0, wait, 100.0))


def test_segment_schedule_reproduces_the_action_episode_runner():
    field, planner = _setup(seed=1)
    ours = fly_scheduled_mission(field, planner, SegmentReplanning(), budget_s=40.0, seed=1, diagonal=True)
    field, planner = _setup(seed=1)
    reference = fly(field, planner, 40.0, 1, diagonal=True, keep_maps=False)
    np.testing.assert_allclose(ours.series("rse"), reference.series("rse"), rtol=1e-12)
    np.testing.assert_allclose(ours.times_s, reference.times_s)
    assert ours.n_replans == len(reference.planner_times_s)


@pytest.mark.parametrize("policy", ["fixed_10s", "oscillator", "precision"])
def test_short_episode_runs_and_logs_replans(policy):
    field, planner = _setup(seed=2)
    schedule = make_replan_policy(policy)
    log = fly_scheduled_mission(field, planner, schedule, budget_s=45.0, seed=2, diagonal=True)
    replans = np.array(log.replan_times_s)
    assert log.n_replans >= 2 and replans[0] == 0.0 and np.all(np.diff(replans) > 0)
    assert len(log.planner_times_s) == log.n_replans == len(log.decision_times_s)
    assert max(log.times_s) <= 45.0 + 1e-9 and len(log.times_s) == len(log.series("rse")) - 1
    if policy == "fixed_10s":
        assert np.all(np.diff(replans) <= 10.0 + 1e-9)
    if policy == "oscillator":  # troughs at 15, 35 s (f = 0.05 Hz, phase 0), or a used-up plan
        assert any(abs(t - 15.0) < 1e-6 for t in replans)
    if policy == "precision":
        assert len(log.decisions) == len(log.times_s) - 1  # none for the image at take-off
        replanned_after = [t for t, _, _, decided in log.decisions if decided]
        assert set(np.round(replanned_after, 6)) <= set(np.round(replans, 6))


def test_json_contract(tmp_path):
    from attend.experiments import rhythm_ipp

    result = rhythm_ipp.run(quick=True, progress=False, trials=1,
                            policies=["segment", "fixed_20s", "precision"])
    result.figures = rhythm_ipp.plot(result, tmp_path)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "rhythm-ipp"
    names = {m["name"] for m in data["metrics"]}
    for policy in ("segment", "fixed_20s", "precision"):
        assert {f"{policy}_final_RSE_mean", f"{policy}_replans_mean", f"{policy}_compute_time_mean"} <= names
    assert "precision_minus_best_fixed_final_RSE_mean" in names
    for metric in data["metrics"]:
        assert set(metric) == {"name", "value", "published", "unit"}
    assert set(rhythm_ipp.SETTINGS) <= set(data["settings"])
    assert data["settings"]["trials"] == 1 and data["settings"]["diagonal"] is True
    assert all((tmp_path / name).is_file() for name in ("rhythm-ipp_curves.png", "rhythm-ipp_cost.png"))
    assert result.metric("segment_replans_mean").value > result.metric("fixed_20s_replans_mean").value


def test_bad_input_names_the_field():
    oscillator = PrecisionOscillator(frequency=0.05)
    with pytest.raises(AttendInputError, match="policy"):
        make_replan_policy("sometimes")
    with pytest.raises(AttendInputError, match="perceive_s"):
        replan_policy(FixedSchedule(-1.0))
    with pytest.raises(AttendInputError, match="prior_weight"):
        precision_policy(oscillator, prior_weight=-1.0)
    with pytest.raises(AttendInputError, match="tolerance"):
        precision_policy(oscillator, tolerance=0.0)
    with pytest.raises(AttendInputError, match="oscillator"):
        RhythmicSchedule("4 Hz")
    with pytest.raises(AttendInputError, match="schedule"):
        RhythmicReplanning(FixedSchedule(10.0))
    with pytest.raises(AttendInputError, match="schedule"):
        replan_policy("fixed_20s")
    field, planner = _setup()
    with pytest.raises(AttendInputError, match="budget_s"):
        fly_scheduled_mission(field, planner, SegmentReplanning(), budget_s=0.0)
    with pytest.raises(AttendInputError, match="policy"):
        fly_scheduled_mission(field, planner, "segment")
    with pytest.raises(AttendInputError, match="cell_precision"):
        expected_trace_reduction(OccupancyMap.prior(field.grid, diagonal=True), np.ones(3))
    from attend.experiments import rhythm_ipp

    with pytest.raises(AttendInputError, match="trials"):
        rhythm_ipp.run(trials=0, progress=False)
    with pytest.raises(AttendInputError, match="policy"):
        rhythm_ipp.run(trials=1, policies=["segment", "never"], progress=False)


def test_coarse_trace_reduction():
    grid = Grid(8, 3.75)
    belief = OccupancyMap.prior(grid)
    d = np.zeros(grid.n_cells)
    d[[0, 1, 8, 9, 20, 30]] = 2.0
    exact = expected_trace_reduction(belief, d)
    assert coarse_trace_reduction(belief, d, 1) == exact
    assert coarse_trace_reduction(belief, d, 2) == pytest.approx(exact, rel=0.5)  # an approximation, same scale
    with pytest.raises(AttendInputError, match="block_cells"):
        coarse_trace_reduction(belief, d, 3)


def test_precision_rule_discounts_a_fresh_plan_by_the_switch_cost():
    oscillator = PrecisionOscillator(frequency=0.05)
    free, costly = precision_policy(oscillator, 0.0), precision_policy(oscillator, 0.0, switch_cost_s=5.0)
    belief = OccupancyMap.prior(Grid(10, 3.0), diagonal=True)
    for schedule in (free, costly):
        schedule.plan_rate, schedule.plan_trace, schedule.plan_duration = 2.0, 2 * belief.trace(), 15.0
    assert free.fresh_rate(belief) == pytest.approx(1.0)  # the last rate, scaled by the uncertainty left
    assert costly.fresh_rate(belief) == pytest.approx(15.0 / 20.0)  # D / (D + c)
    with pytest.raises(AttendInputError, match="switch_cost_s"):
        precision_policy(oscillator, switch_cost_s=-1.0)
    assert make_replan_policy("continuous").waypoints_per_plan(None) is None


def test_each_schedule_kind_becomes_its_replanning_policy():
    oscillator = PrecisionOscillator(frequency=0.05)
    fixed = replan_policy(FixedSchedule(20.0))
    assert isinstance(fixed, FixedReplanning) and fixed.name == "fixed_20s"
    assert fixed.deadline(3.0, 5.0) == 23.0
    rhythmic = replan_policy(RhythmicSchedule(oscillator))
    assert isinstance(rhythmic, RhythmicReplanning)
    assert rhythmic.deadline(0.0, 2.0) == pytest.approx(15.0)  # the first trough: theta = 3 pi / 2 at 15 s
    assert make_replan_policy("precision_no_prior").schedule.prior_weight == 0.0
