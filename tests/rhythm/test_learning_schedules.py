"""Tests of attend.rhythm.learning (a schedule as the prior precision per iteration) and the
rhythm-learning experiment."""

import json

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.linear import simulate
from attend.models.parameters import parameter_vector
from attend.models.problems import mass_spring_damper
from attend.perception import learning as L
from attend.rhythm import FixedSchedule, RhythmicSchedule
from attend.rhythm.learning import learn_scheduled, prior_precision_per_entry, prior_precision_sequence
from attend.rhythm.oscillator import PrecisionOscillator

DT = 0.1
FREE = np.array([False, False, True, True, False, True, False, False])


def _logs(seeds=(0, 1), n=150, sigma=np.exp(-3)):
    system = mass_spring_damper()
    u = np.exp(-0.25 * (np.arange(n) * DT - 6) ** 2)[:, None]
    logs = [simulate(system, u, DT, kernel_width=0.5, process_std=np.exp(-4), measurement_std=sigma, seed=s)
            for s in seeds]
    theta = parameter_vector(system)
    eta = np.stack([theta * (1 + 0.3 * FREE * (-1) ** k) for k in range(len(seeds))])
    return np.stack([g.outputs for g in logs]), np.stack([g.inputs for g in logs]), eta


def test_schedule_matches_the_oscillator_closed_form():
    osc = PrecisionOscillator(frequency=0.1, depth=3.0, baseline_multiplier=20.0, phase=0.7)
    k = np.arange(25)
    expected = 20.0 * np.exp(3.0 * np.sin(2 * np.pi * 0.1 * k + 0.7))
    np.testing.assert_allclose(prior_precision_sequence(RhythmicSchedule(osc), 25), expected, rtol=1e-14)
    # geometric mean over whole cycles is pi_0; the extremes are pi_0 exp(+-a)
    sched = prior_precision_sequence(RhythmicSchedule(osc), 20)
    assert np.exp(np.mean(np.log(sched))) == pytest.approx(20.0, rel=1e-12)
    assert sched.max() <= 20.0 * np.exp(3.0) and sched.min() >= 20.0 * np.exp(-3.0)
    np.testing.assert_array_equal(prior_precision_sequence(FixedSchedule(multiplier=5.0), 4), np.full(4, 5.0))


def test_full_schedule_puts_the_rhythm_on_the_free_entries_only():
    sched = np.array([1.0, 10.0, 100.0])
    P = prior_precision_per_entry(sched, FREE, known_prior_precision=7.0, n_runs=2)
    assert P.shape == (2, 3, 8)
    np.testing.assert_array_equal(P[:, :, FREE], np.broadcast_to(sched[None, :, None], (2, 3, 3)))
    np.testing.assert_array_equal(P[:, :, ~FREE], 7.0)


def test_constant_schedule_equals_learn_batch_with_that_fixed_prior_precision():
    Y, U, eta = _logs()
    kw = dict(n_states=2, kernel_width=0.5, prior_mean=eta)
    fixed = L.learn_batch(Y, U, DT, prior_precision=np.where(FREE, 3.0, L.KNOWN_PRIOR_PRECISION)[None],
                          settings=L.LearningSettings(embedding_order=4, max_iterations=12), **kw)
    constant = prior_precision_sequence(FixedSchedule(multiplier=3.0), 12)
    scheduled = learn_scheduled(Y, U, DT, free_schedule=constant, free=FREE,
                                settings=L.LearningSettings(embedding_order=4), **kw)
    for a, b in zip(fixed, scheduled):
        if isinstance(a, tuple):
            for x, y in zip(a, b):
                np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
        else:
            np.testing.assert_array_equal(a, b)


def test_rhythmic_schedule_changes_the_learning_and_each_iteration_uses_its_prior_precision():
    Y, U, eta = _logs()
    osc = PrecisionOscillator(frequency=0.25, depth=5.0, baseline_multiplier=10.0)
    sched = prior_precision_sequence(RhythmicSchedule(osc), 8)
    res = learn_scheduled(Y, U, DT, free_schedule=sched, free=FREE, prior_mean=eta, n_states=2, kernel_width=0.5,
                          settings=L.LearningSettings(embedding_order=4))
    assert res.iterations.tolist() == [8, 8]  # no early stop while the schedule still moves
    # the posterior precision of a free entry is H + P_theta(k): it moves with the schedule
    info = res.precision_history[:, 1:, FREE] - sched[None, :, None]
    assert np.all(info > 0)
    fixed = L.learn_batch(Y, U, DT, n_states=2, kernel_width=0.5, prior_mean=eta,
                          prior_precision=np.where(FREE, 10.0, L.KNOWN_PRIOR_PRECISION)[None],
                          settings=L.LearningSettings(embedding_order=4, max_iterations=8))
    assert not np.allclose(res.parameters, fixed.parameters)


def test_bad_schedules_are_rejected():
    Y, U, eta = _logs()
    with pytest.raises(AttendInputError, match="free_schedule"):
        prior_precision_per_entry([1.0, -1.0], FREE)
    with pytest.raises(AttendInputError, match="one row per iteration"):
        L.learn_batch(Y, U, DT, n_states=2, kernel_width=0.5, prior_mean=eta, settings=L.LearningSettings(max_iterations=5),
                      prior_precision=prior_precision_per_entry(np.ones(4), FREE, n_runs=2))
    with pytest.raises(AttendInputError, match="n_iterations"):
        prior_precision_sequence(RhythmicSchedule(PrecisionOscillator()), 0)
    with pytest.raises(AttendInputError, match="schedule"):
        prior_precision_sequence(PrecisionOscillator(), 5)


def test_experiment_json_contract(tmp_path, monkeypatch):
    from attend.experiments import rhythm_learning as RL

    small = dict(RL.SETTINGS, iterations=6, duration=16.0)
    monkeypatch.setattr(RL, "SETTINGS", small)
    result = RL.run(quick=True, progress=False)
    result.figures = RL.plot(result, tmp_path)
    data = json.loads(result.write(tmp_path).read_text())
    assert data["experiment"] == "rhythm-learning"
    names = {m["name"] for m in data["metrics"]}
    assert {"rhythmic_worst_case_relative_regret", "best_fixed_worst_case_relative_regret",
            "fixed_policies_beaten_on_worst_case_relative_regret", "rhythmic_worst_case_absolute_regret"} <= names
    for metric in data["metrics"]:
        assert set(metric) == {"name", "value", "published", "unit"}
    assert data["settings"]["rhythm_depth"] == RL.SETTINGS["rhythm_depth"]
    assert (tmp_path / "rhythm-learning.png").exists()
    # regrets: every fixed policy is >= 0 and the best fixed per level has regret 0
    rel = result.tables["relative_regret"]
    n_fixed = len(result.tables["fixed_prior_precision"])
    assert np.all(rel[:n_fixed] >= 0) and np.allclose(rel[:n_fixed].min(axis=0), 0)
    assert result.data["sse"].shape == (n_fixed + 1, 6, 6)
