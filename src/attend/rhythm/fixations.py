"""Fixation policies: a :mod:`schedule <attend.rhythm.schedule>` on the clock of an eye.

A fixation policy turns time into steps of ``time_step`` dt [s]. Each step is PERCEIVE (fixate:
assimilate data with precision multiplier m) or ACT (saccade: data taken while moving are
weighted by the suppressed multiplier s m, s = ``saccadic_suppression`` in [0, 1]). The
multiplier m of a step multiplies the eye's sensory precision for that step.

:func:`drive` runs a policy on a :class:`FixationTask` (the active-vision agent of
:mod:`attend.rhythm.vision`); :func:`fixation_policy` builds the policy of a schedule:

- :class:`RhythmicFixations` (a :class:`RhythmicSchedule`): step i, read at its midpoint
  t_i = (i + 1/2) dt, perceives with m = pi(t_i) if pi(t_i) >= pi_threshold, else acts with
  m = s pi(t_i); the saccade falls in an already running rhythm (it does not reset it).
- :class:`FixedFixations` (a :class:`FixedSchedule`): perceive_s of fixation, act_s of
  saccade, rounded to whole steps.
- :class:`PrecisionDrivenFixations` (a :class:`PrecisionDrivenSchedule`): a marginal-value
  rule (as in optimal foraging), see its docstring.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Protocol, runtime_checkable

import numpy as np

from attend._validation import AttendInputError, positive_scalar
from attend.rhythm.oscillator import _finite
from attend.rhythm.schedule import ACT, PERCEIVE, FixedSchedule, PrecisionDrivenSchedule, RhythmicSchedule

__all__ = ["FixationTask", "FixedFixations", "PrecisionDrivenFixations", "RhythmicFixations", "ScheduleStep",
           "ScheduleTrace", "drive", "fixation_policy"]


@runtime_checkable
class FixationTask(Protocol):
    """What a fixation policy needs from the eye. Gains are in the task's unit (nats of
    information in active vision); ``precision_multiplier`` [dimensionless] multiplies the eye's
    sensory precision and ``duration`` [s] is the length of the step."""

    def expected_gain_of_staying(self, precision_multiplier: float, duration: float) -> float:
        """Expected gain of perceiving for ``duration`` more where the eye looks now, at
        ``precision_multiplier``."""

    def expected_gain_of_moving(self, precision_multiplier: float, duration: float) -> float:
        """Expected gain of perceiving for ``duration`` at the best other place, at
        ``precision_multiplier``."""

    def perceive(self, precision_multiplier: float, duration: float) -> None:
        """Assimilate one step of ``duration`` with precision scaled by ``precision_multiplier``."""

    def act(self, precision_multiplier: float, duration: float, onset: bool) -> None:
        """One step of ``duration`` of moving; ``onset`` on the first step of a move (choose the
        target then). Data taken while moving are weighted by ``precision_multiplier``."""


@dataclass(frozen=True)
class ScheduleStep:
    """One step: ``index``, start ``time`` [s], ``duration`` [s], ``mode`` (PERCEIVE or ACT),
    ``precision_multiplier`` m [dimensionless] and ``onset`` (first step of a new phase)."""

    index: int
    time: float
    duration: float
    mode: str
    precision_multiplier: float
    onset: bool


@dataclass(frozen=True)
class ScheduleTrace:
    """A driven policy as arrays: ``time`` [s], ``precision_multiplier``, ``perceiving`` (bool)
    and ``onset`` (bool) per step."""

    time: np.ndarray
    precision_multiplier: np.ndarray
    perceiving: np.ndarray
    onset: np.ndarray

    @property
    def n_moves(self) -> int:
        """Number of act phases (saccades) started."""
        return int(np.sum(self.onset & ~self.perceiving))


def _positive_int(value, field: str) -> int:
    if isinstance(value, bool) or int(value) != value or int(value) < 1:
        raise AttendInputError(f"{field}: expected an integer >= 1, got {value!r}")
    return int(value)


def _suppression(value) -> float:
    number = _finite(value, "saccadic_suppression")
    if not 0.0 <= number <= 1.0:
        raise AttendInputError(f"saccadic_suppression: expected a factor in [0, 1], got {value!r}")
    return number


def _schedule(value, kind):
    if not isinstance(value, kind):
        raise AttendInputError(f"schedule: expected a {kind.__name__}, got {type(value).__name__}")
    return value


class _FixationPolicy:
    time_step: float

    def steps(self, task: FixationTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        """The first ``n_steps`` steps, consulting ``task`` where the policy needs it."""
        raise NotImplementedError


class RhythmicFixations(_FixationPolicy):
    """Fixate while pi(t) >= pi_threshold, saccade in the troughs (module docstring).

    schedule: a :class:`RhythmicSchedule`; time_step: dt [s] > 0; saccadic_suppression: s in
    [0, 1]."""

    def __init__(self, schedule: RhythmicSchedule, time_step: float = 0.0125,
                 saccadic_suppression: float = 0.1) -> None:
        self.schedule = _schedule(schedule, RhythmicSchedule)
        self.oscillator = schedule.oscillator
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.saccadic_suppression = _suppression(saccadic_suppression)
        self.threshold = schedule.threshold

    def mean_perception_multiplier(self) -> float:
        """Mean of pi(t) over the fixation part of a cycle [dimensionless]."""
        return self.schedule.mean_perception_multiplier()

    def mean_action_multiplier(self) -> float:
        """Mean of the suppressed s pi(t) over the saccade part of a cycle [dimensionless]."""
        return float(self.saccadic_suppression * self.schedule.mean_action_multiplier())

    def steps(self, task: FixationTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        """The first ``n_steps`` steps (``task`` is not consulted; None is allowed)."""
        n_steps = _positive_int(n_steps, "n_steps")
        dt, previous = self.time_step, None
        for i in range(n_steps):
            multiplier = float(self.oscillator.multiplier((i + 0.5) * dt))
            mode = PERCEIVE if multiplier >= self.threshold else ACT
            if mode == ACT:
                multiplier *= self.saccadic_suppression
            yield ScheduleStep(i, i * dt, dt, mode, multiplier, mode != previous)
            previous = mode


class FixedFixations(_FixationPolicy):
    """Fixate for ``schedule.perceive_s`` [s] at multiplier ``schedule.multiplier``, then saccade
    for ``schedule.act_s`` [s] at s times it, and repeat; durations rounded to whole steps of
    ``time_step`` [s] (at least one step each). schedule: a :class:`FixedSchedule`;
    saccadic_suppression: s in [0, 1]."""

    def __init__(self, schedule: FixedSchedule, time_step: float = 0.0125, saccadic_suppression: float = 0.1) -> None:
        self.schedule = _schedule(schedule, FixedSchedule)
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.perception_multiplier = schedule.multiplier
        self.saccadic_suppression = _suppression(saccadic_suppression)
        self.fixation_steps = max(1, int(round(schedule.perceive_s / self.time_step)))
        self.action_steps = max(1, int(round(schedule.act_s / self.time_step)))

    def steps(self, task: FixationTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        """The first ``n_steps`` steps (``task`` is not consulted; None is allowed)."""
        n_steps = _positive_int(n_steps, "n_steps")
        cycle, dt, m = self.fixation_steps + self.action_steps, self.time_step, self.perception_multiplier
        for i in range(n_steps):
            position = i % cycle
            if position < self.fixation_steps:
                yield ScheduleStep(i, i * dt, dt, PERCEIVE, m, position == 0)
            else:
                yield ScheduleStep(i, i * dt, dt, ACT, self.saccadic_suppression * m, position == self.fixation_steps)


class PrecisionDrivenFixations(_FixationPolicy):
    """Saccade when staying stops paying; the rhythm is a prior on when.

    At each fixation step (after ``min_fixation_steps``), with m = ``perception_multiplier`` and
    dt = ``time_step``, the schedule's rule (:func:`attend.rhythm.schedule.switch_decision`)

        move  iff  G_stay < rho * G_move / h * exp(-kappa sin theta(t))
        G_stay = task.expected_gain_of_staying(m, dt)             one more step here
        G_move = task.expected_gain_of_moving(m, (h - c) dt)      a whole fixation elsewhere

    A saccade costs c = ``saccade_s`` / dt steps of (almost) no data, so over the next
    h = ``horizon_steps`` steps (default: one oscillator cycle) moving earns G_move / h per step;
    staying earns G_stay, which falls as the posterior precision saturates. kappa, rho and the
    oscillator come from ``schedule`` (a :class:`PrecisionDrivenSchedule`). Saccade steps have
    multiplier s m (s = ``saccadic_suppression``).

    ``perception_multiplier`` defaults to the oscillator's mean multiplier over the fixation
    windows of :class:`RhythmicSchedule` (oscillator, ``action_fraction``), so the precision
    budget per fixation step matches the rhythmic policy's.

    ``decision_time`` [s] >= 0: the rule reads the precision state, so the saccade starts only
    ``decision_time`` after the decision (whole steps), the eye fixating meanwhile (clock-driven
    policies know their saccade times in advance). 0: the saccade starts at once.
    """

    def __init__(self, schedule: PrecisionDrivenSchedule, time_step: float = 0.0125, saccade_s: float = 0.0625,
                 saccadic_suppression: float = 0.1, perception_multiplier: float | None = None,
                 horizon_steps: int | None = None, min_fixation_steps: int = 1, action_fraction: float = 0.25,
                 decision_time: float = 0.0) -> None:
        self.schedule = _schedule(schedule, PrecisionDrivenSchedule)
        self.oscillator = schedule.oscillator
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.action_steps = max(1, int(round(positive_scalar(saccade_s, "saccade_s", "s") / self.time_step)))
        self.saccadic_suppression = _suppression(saccadic_suppression)
        if perception_multiplier is None:
            perception_multiplier = RhythmicSchedule(self.oscillator, action_fraction).mean_perception_multiplier()
        self.perception_multiplier = positive_scalar(perception_multiplier, "perception_multiplier")
        if horizon_steps is None:
            horizon_steps = max(self.action_steps + 1, int(round(self.oscillator.period / self.time_step)))
        self.horizon_steps = _positive_int(horizon_steps, "horizon_steps")
        if self.horizon_steps <= self.action_steps:
            raise AttendInputError(
                f"horizon_steps: expected more than the {self.action_steps} action steps, got {horizon_steps!r}")
        self.min_fixation_steps = _positive_int(min_fixation_steps, "min_fixation_steps")
        decision = _finite(decision_time, "decision_time")
        if decision < 0:
            raise AttendInputError(f"decision_time: expected a time >= 0 s, got {decision_time!r}")
        self.decision_steps = int(round(decision / self.time_step))

    def should_move(self, gain_of_staying: float, gain_of_moving: float, time: float) -> bool:
        """The rule above at ``time`` [s]: ``gain_of_staying`` (one step) vs ``gain_of_moving``
        (a fixation of h - c steps)."""
        return self.schedule.should_switch(gain_of_staying, gain_of_moving / self.horizon_steps, time)

    def _wants_to_move(self, task: FixationTask, time: float) -> bool:
        m, dt = self.perception_multiplier, self.time_step
        return self.should_move(task.expected_gain_of_staying(m, dt),
                                task.expected_gain_of_moving(m, (self.horizon_steps - self.action_steps) * dt), time)

    def steps(self, task: FixationTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        """The first ``n_steps`` steps, consulting ``task`` (required) at every fixation step."""
        if task is None:
            raise AttendInputError("task: the precision-driven policy needs a FixationTask to consult")
        n_steps = _positive_int(n_steps, "n_steps")
        dt, m = self.time_step, self.perception_multiplier
        fixation_steps, action_left, deciding, i = 0, 0, -1, 0
        while i < n_steps:
            t = i * dt
            if deciding == 0:  # the decision is made: move now
                action_left, fixation_steps, deciding = self.action_steps, 0, -1
            if action_left > 0:
                yield ScheduleStep(i, t, dt, ACT, self.saccadic_suppression * m, action_left == self.action_steps)
                action_left -= 1
                i += 1
                continue
            if deciding > 0:  # fixating while the decision to move is being taken
                deciding -= 1
            elif fixation_steps >= self.min_fixation_steps and self._wants_to_move(task, t + 0.5 * dt):
                if self.decision_steps == 0:
                    action_left, fixation_steps = self.action_steps, 0
                    continue
                deciding = self.decision_steps - 1
            yield ScheduleStep(i, t, dt, PERCEIVE, m, fixation_steps == 0)
            fixation_steps += 1
            i += 1


def fixation_policy(schedule, time_step: float = 0.0125, saccadic_suppression: float = 0.1, **options):
    """The fixation policy of ``schedule`` on steps of ``time_step`` [s], saccades weighted by
    ``saccadic_suppression``: :class:`RhythmicFixations`, :class:`FixedFixations` or
    :class:`PrecisionDrivenFixations` (``options``: its other arguments)."""
    kinds = {RhythmicSchedule: RhythmicFixations, FixedSchedule: FixedFixations,
             PrecisionDrivenSchedule: PrecisionDrivenFixations}
    if type(schedule) not in kinds:
        raise AttendInputError(f"schedule: expected a Rhythmic, Fixed or PrecisionDriven schedule, got {schedule!r}")
    return kinds[type(schedule)](schedule, time_step, saccadic_suppression=saccadic_suppression, **options)


def drive(policy: _FixationPolicy, task: FixationTask, n_steps: int,
          until: Callable[[ScheduleStep], bool] | None = None) -> ScheduleTrace:
    """Run up to ``n_steps`` steps of the fixation ``policy`` on ``task``: ``task.perceive(m,
    dt)`` on PERCEIVE steps, ``task.act(m, dt, onset)`` on ACT steps. Stops before the first step
    for which ``until(step)`` is true. Returns the :class:`ScheduleTrace` of the steps run."""
    time, multipliers, perceiving, onsets = [], [], [], []
    for step in policy.steps(task, n_steps):
        if until is not None and until(step):
            break
        if step.mode == PERCEIVE:
            task.perceive(step.precision_multiplier, step.duration)
        else:
            task.act(step.precision_multiplier, step.duration, step.onset)
        time.append(step.time)
        multipliers.append(step.precision_multiplier)
        perceiving.append(step.mode == PERCEIVE)
        onsets.append(step.onset)
    return ScheduleTrace(np.array(time, dtype=float), np.array(multipliers, dtype=float),
                         np.array(perceiving, dtype=bool), np.array(onsets, dtype=bool))
