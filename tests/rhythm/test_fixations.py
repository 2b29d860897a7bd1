"""Fixation policies of the three schedules: the rhythm's timing, fixed budgets, the
precision-driven rule on a toy task."""

import math

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.rhythm import (
    ACT,
    PERCEIVE,
    FixationTask,
    FixedFixations,
    FixedSchedule,
    PrecisionDrivenFixations,
    PrecisionDrivenSchedule,
    PrecisionOscillator,
    RhythmicFixations,
    RhythmicSchedule,
    drive,
    fixation_policy,
    switch_decision,
)


def rhythmic_fixations(oscillator, time_step=0.0125, action_fraction=0.25, saccadic_suppression=0.1):
    return fixation_policy(RhythmicSchedule(oscillator, action_fraction), time_step, saccadic_suppression)


def fixed_fixations(fixation, action, time_step=0.0125, perception_multiplier=1.0, saccadic_suppression=0.1):
    return fixation_policy(FixedSchedule(fixation, action, perception_multiplier), time_step, saccadic_suppression)


def precision_driven_fixations(oscillator, time_step=0.0125, action_duration=0.0625, prior_weight=1.0,
                             saccadic_suppression=0.1, perception_multiplier=None, **options):
    return fixation_policy(PrecisionDrivenSchedule(oscillator, prior_weight), time_step, saccadic_suppression,
                           saccade_s=action_duration, perception_multiplier=perception_multiplier, **options)


class DecayingTask:
    """Staying yields G0 exp(-n / tau) per step after n steps here (posterior saturates); a
    fixation elsewhere yields ``move_gain``. Counts calls."""

    def __init__(self, g0=1.0, tau=4.0, move_gain=2.0):
        self.g0, self.tau, self.move_gain = g0, tau, move_gain
        self.steps_here, self.perceived, self.acted, self.moves = 0, 0, 0, 0

    def expected_gain_of_staying(self, precision_multiplier, duration):
        return self.g0 * math.exp(-self.steps_here / self.tau)

    def expected_gain_of_moving(self, precision_multiplier, duration):
        return self.move_gain

    def perceive(self, precision_multiplier, duration):
        self.perceived += 1
        self.steps_here += 1

    def act(self, precision_multiplier, duration, onset):
        self.acted += 1
        if onset:
            self.moves += 1
            self.steps_here = 0


def test_oscillator_scheduler_acts_in_the_troughs():
    osc = PrecisionOscillator(frequency=4.0, depth=1.0, phase=0.0)
    scheduler = rhythmic_fixations(osc, time_step=0.001, action_fraction=0.25, saccadic_suppression=0.1)
    steps = list(scheduler.steps(None, 2000))  # 2 s = 8 cycles
    acting = np.array([s.mode == ACT for s in steps])
    assert acting.mean() == pytest.approx(0.25, abs=5e-3)  # 62.5 steps per trough, rounded
    onsets = [s for s in steps if s.onset and s.mode == ACT]
    assert len(onsets) == 8
    times = np.array([s.time for s in steps])
    for trough in osc.trough_times(0.0, 2.0):  # every trough lies inside an action phase
        assert acting[int(trough / 0.001)]
    for s in steps:
        expected = osc.multiplier(s.time + 0.0005) * (0.1 if s.mode == ACT else 1.0)
        assert s.precision_multiplier == pytest.approx(expected)
    assert times[1] - times[0] == pytest.approx(0.001)


def test_rhythmic_mean_perception_and_action_multipliers():
    osc = PrecisionOscillator(frequency=4.0, depth=1.0)
    scheduler = rhythmic_fixations(osc, action_fraction=0.25)
    assert isinstance(scheduler, RhythmicFixations)
    t = (np.arange(400000) + 0.5) / 400000 * osc.period
    g = osc.multiplier(t)
    assert scheduler.mean_perception_multiplier() == pytest.approx(g[g >= scheduler.threshold].mean(), rel=1e-3)
    assert scheduler.mean_action_multiplier() == pytest.approx(0.1 * g[g < scheduler.threshold].mean(), rel=1e-3)


def test_fixed_duration_pattern():
    scheduler = fixed_fixations(0.05, 0.02, time_step=0.01, perception_multiplier=2.0, saccadic_suppression=0.25)
    assert isinstance(scheduler, FixedFixations)
    modes = [s.mode for s in scheduler.steps(None, 14)]
    assert modes == [PERCEIVE] * 5 + [ACT] * 2 + [PERCEIVE] * 5 + [ACT] * 2
    gains = [s.precision_multiplier for s in scheduler.steps(None, 7)]
    assert gains == [2.0] * 5 + [0.5] * 2


def test_precision_driven_moves_when_staying_stops_paying():
    # G_stay(n) = exp(-n / 4) < G_move / h = 2 / 20 = 0.1 first at n = 10 steps here.
    osc = PrecisionOscillator(frequency=4.0)
    scheduler = precision_driven_fixations(osc, time_step=0.0125, action_duration=0.0375, prior_weight=0.0,
                                         perception_multiplier=1.0)
    assert isinstance(scheduler, PrecisionDrivenFixations)
    assert scheduler.horizon_steps == 20 and scheduler.action_steps == 3
    task = DecayingTask()
    trace = drive(scheduler, task, 39)
    expected = [True] * 10 + [False] * 3
    assert list(trace.perceiving) == expected * 3
    assert task.moves == 3 and trace.n_moves == 3
    assert isinstance(task, FixationTask)


def test_precision_driven_prior_pulls_moves_towards_troughs():
    osc = PrecisionOscillator(frequency=4.0, phase=0.0)
    task_times = {}
    for weight in (0.0, 3.0):
        scheduler = precision_driven_fixations(osc, time_step=0.0025, action_duration=0.01, prior_weight=weight,
                                             perception_multiplier=1.0)
        task = DecayingTask(tau=20.0, move_gain=scheduler.horizon_steps * 0.3)
        trace = drive(scheduler, task, 2000)
        onset_times = trace.time[trace.onset & ~trace.perceiving]
        task_times[weight] = np.sin(osc.phase_angle(onset_times))
    # with the prior, moves start at lower phase (closer to the troughs, sin = -1)
    assert task_times[3.0].mean() < task_times[0.0].mean() - 0.3


def test_drive_until_stops_early():
    task = DecayingTask()
    scheduler = fixed_fixations(0.05, 0.02, time_step=0.01)
    trace = drive(scheduler, task, 100, until=lambda step: step.index == 9)
    assert len(trace.time) == 9 and task.perceived + task.acted == 9


@pytest.mark.parametrize("make, field", [
    (lambda: rhythmic_fixations(PrecisionOscillator(), time_step=0.0), "time_step"),
    (lambda: rhythmic_fixations(PrecisionOscillator(), action_fraction=1.0), "action_fraction"),
    (lambda: rhythmic_fixations(PrecisionOscillator(), saccadic_suppression=1.5), "saccadic_suppression"),
    (lambda: rhythmic_fixations("4 Hz"), "oscillator"),
    (lambda: fixed_fixations(0.0, 0.05), "perceive_s"),
    (lambda: fixed_fixations(0.2, -1.0), "act_s"),
    (lambda: precision_driven_fixations(PrecisionOscillator(), prior_weight=-1.0), "prior_weight"),
    (lambda: PrecisionDrivenSchedule(PrecisionOscillator(), tolerance=0.0), "tolerance"),
    (lambda: fixation_policy("rhythm"), "schedule"),
    (lambda: RhythmicFixations(FixedSchedule(0.1)), "schedule"),
    (lambda: precision_driven_fixations(PrecisionOscillator(), horizon_steps=2, action_duration=0.05), "horizon_steps"),
    (lambda: list(precision_driven_fixations(PrecisionOscillator()).steps(None, 3)), "task"),
    (lambda: list(rhythmic_fixations(PrecisionOscillator()).steps(None, 0)), "n_steps"),
])
def test_bad_input_names_the_field(make, field):
    with pytest.raises(AttendInputError, match=field):
        make()


def test_decision_time_delays_the_precision_driven_move():
    class Falling:  # staying pays less every step; moving pays a constant
        def __init__(self):
            self.steps = 0

        def expected_gain_of_staying(self, g, dt):
            return 10.0 - self.steps

        def expected_gain_of_moving(self, g, dt):
            return 50.0

        def perceive(self, g, dt):
            self.steps += 1

        def act(self, g, dt, onset):
            self.steps = 0

    def first_move(decision_time):
        scheduler = precision_driven_fixations(PrecisionOscillator(4.0), 0.0125, 0.05, 0.0, 0.1, 1.0,
                                             horizon_steps=10, decision_time=decision_time)
        task = Falling()
        for step in scheduler.steps(task, 60):
            if step.mode == ACT:
                return step.index
            task.perceive(step.precision_multiplier, step.duration)

    # staying (10 - k) drops below 50 / 10 = 5 at k = 6 perceived steps; then 0, 2, 4 more steps
    assert first_move(0.0) == 6
    assert first_move(0.025) == 8
    assert first_move(0.05) == 10


def test_switch_decision_closed_form():
    # stay < rho * move * exp(-kappa sin theta): at a trough (sin = -1) the bar is e^kappa higher
    assert switch_decision(1.0, 0.9, phase_angle=0.0, prior_weight=0.0, tolerance=1.0) is False
    assert switch_decision(1.0, 0.9, phase_angle=-math.pi / 2, prior_weight=0.2, tolerance=1.0) is True
    assert switch_decision(1.0, 0.9, phase_angle=math.pi / 2, prior_weight=0.2, tolerance=2.0) is True
    schedule = PrecisionDrivenSchedule(PrecisionOscillator(frequency=1.0), prior_weight=0.2, tolerance=1.0)
    assert schedule.should_switch(1.0, 0.9, 0.75) is True  # t = 0.75 s: theta = 3 pi / 2, a trough
    assert schedule.should_switch(1.0, 0.9, 0.25) is False  # a peak


def test_the_rhythmic_schedule_threshold_leaves_the_action_fraction():
    schedule = RhythmicSchedule(PrecisionOscillator(frequency=2.0, depth=1.3), action_fraction=0.3)
    t = (np.arange(100000) + 0.5) / 100000 * 0.5
    below = schedule.oscillator.multiplier(t) < schedule.threshold
    assert below.mean() == pytest.approx(0.3, abs=1e-4)
