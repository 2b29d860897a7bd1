"""Schedulers: when to perceive (assimilate data) and when to act (move the sensor).

A scheduler turns time into a sequence of steps of length ``time_step`` [s]. Each step is either
PERCEIVE (assimilate data with precision gain g >= the threshold) or ACT (move; data taken while
moving are weighted by the suppressed gain g = s * pi(t), s = ``saccadic_suppression`` in (0, 1]).
The precision gain g of a step multiplies the task's sensory precision for that step.

The scheduler drives any task that follows :class:`ScheduledTask` (active vision here; a learning
schedule or a path-planning schedule elsewhere)::

    class MyTask:
        def expected_gain_of_staying(self, precision_gain, duration): ...  # next step, here
        def expected_gain_of_moving(self, precision_gain, duration): ...   # next step, at the best other place
        def perceive(self, precision_gain, duration): ...                  # assimilate data
        def act(self, precision_gain, duration, onset): ...                # move (onset: first step of the move)

    trace = drive(OscillatorScheduler(PrecisionOscillator(frequency=4.0)), MyTask(), n_steps=400)

Schedulers that do not consult the task (:class:`OscillatorScheduler`,
:class:`FixedDurationScheduler`) also work without one: ``for step in scheduler.steps(None, n)``
yields the mode and gain of every step, e.g. to set a prior precision in learning.

Three schedulers:

- :class:`OscillatorScheduler`: the rhythm decides. Perceive while pi(t) >= pi_threshold, act in
  the troughs (a fraction q of each cycle); the action starts at the trough onset and falls in an
  already running rhythm (it does not reset it).
- :class:`PrecisionDrivenScheduler`: the precision dynamics decide, the rhythm is a prior on the
  timing. Move when the expected gain of staying drops below the expected gain of moving,
  discounted by the time lost in the move and weighted by the phase prior (see its docstring).
- :class:`FixedDurationScheduler`: a fixed budget (fixed fixation duration), the arbitrary
  alternative the seed argues against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterator, Protocol, runtime_checkable

import numpy as np

from attend._validation import AttendInputError, positive_scalar
from attend.rhythm.oscillator import PrecisionOscillator, _finite, _fraction

PERCEIVE = "perceive"
ACT = "act"


@runtime_checkable
class ScheduledTask(Protocol):
    """What a scheduler needs from a task. Gains are in the task's unit (e.g. nats of information
    or a precision increment); ``precision_gain`` [dimensionless] multiplies the task's sensory
    precision and ``duration`` [s] is the length of the step."""

    def expected_gain_of_staying(self, precision_gain: float, duration: float) -> float:
        """Expected gain of perceiving for ``duration`` more where the sensor is now."""

    def expected_gain_of_moving(self, precision_gain: float, duration: float) -> float:
        """Expected gain of perceiving for ``duration`` at the best place the sensor could move to."""

    def perceive(self, precision_gain: float, duration: float) -> None:
        """Assimilate one step of data with precision scaled by ``precision_gain``."""

    def act(self, precision_gain: float, duration: float, onset: bool) -> None:
        """One step of moving; ``onset`` on the first step of a move (choose the target then).
        Data taken while moving are weighted by ``precision_gain`` (the suppressed gain)."""


@dataclass(frozen=True)
class ScheduleStep:
    """One step: ``index``, start ``time`` [s], ``duration`` [s], ``mode`` (PERCEIVE or ACT),
    ``precision_gain`` g [dimensionless] and ``onset`` (first step of a new perceive/act phase)."""

    index: int
    time: float
    duration: float
    mode: str
    precision_gain: float
    onset: bool


@dataclass(frozen=True)
class ScheduleTrace:
    """A driven schedule as arrays: ``time`` [s], ``precision_gain``, ``perceiving`` (bool) and
    ``onset`` (bool) per step."""

    time: np.ndarray
    precision_gain: np.ndarray
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


class _Scheduler:
    time_step: float

    def steps(self, task: ScheduledTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        raise NotImplementedError

    def _check(self, n_steps) -> int:
        return _positive_int(n_steps, "n_steps")


class OscillatorScheduler(_Scheduler):
    """Perceive at high precision, act in the troughs of pi(t).

    Step i covers [i dt, (i + 1) dt) and is read at its midpoint t_i = (i + 1/2) dt:
    PERCEIVE with g = pi(t_i) if pi(t_i) >= pi_threshold = pi_0 exp(-a cos(pi q)), else ACT with
    g = s pi(t_i) (saccadic suppression s). q = ``action_fraction`` of each cycle is spent acting.
    ``time_step`` dt [s] > 0.
    """

    def __init__(self, oscillator: PrecisionOscillator, time_step: float = 0.0125,
                 action_fraction: float = 0.25, saccadic_suppression: float = 0.1) -> None:
        if not isinstance(oscillator, PrecisionOscillator):
            raise AttendInputError(f"oscillator: expected a PrecisionOscillator, got {type(oscillator).__name__}")
        self.oscillator = oscillator
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.action_fraction = _fraction(action_fraction, "action_fraction")
        self.saccadic_suppression = _suppression(saccadic_suppression)
        self.threshold = oscillator.threshold(self.action_fraction)

    def mean_perception_gain(self, samples: int = 4096) -> float:
        """Mean of pi(t) over the perception part of a cycle (pi >= threshold) [dimensionless]."""
        theta = 2.0 * np.pi * (np.arange(samples) + 0.5) / samples
        gain = self.oscillator.baseline_gain * np.exp(self.oscillator.depth * np.sin(theta))
        return float(gain[gain >= self.threshold].mean())

    def mean_action_gain(self, samples: int = 4096) -> float:
        """Mean of the suppressed gain s pi(t) over the action part of a cycle [dimensionless]."""
        theta = 2.0 * np.pi * (np.arange(samples) + 0.5) / samples
        gain = self.oscillator.baseline_gain * np.exp(self.oscillator.depth * np.sin(theta))
        return float(self.saccadic_suppression * gain[gain < self.threshold].mean())

    def steps(self, task: ScheduledTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        n_steps = self._check(n_steps)
        dt = self.time_step
        previous = None
        for i in range(n_steps):
            gain = float(self.oscillator.gain((i + 0.5) * dt))
            mode = PERCEIVE if gain >= self.threshold else ACT
            if mode == ACT:
                gain *= self.saccadic_suppression
            yield ScheduleStep(i, i * dt, dt, mode, gain, mode != previous)
            previous = mode


class FixedDurationScheduler(_Scheduler):
    """A fixed budget: perceive for ``fixation_duration`` [s] at gain ``perception_gain``, then act
    for ``action_duration`` [s] at gain s * ``perception_gain``, and repeat. Durations are
    rounded to whole steps of ``time_step`` [s] (at least one step each)."""

    def __init__(self, fixation_duration: float, action_duration: float, time_step: float = 0.0125,
                 perception_gain: float = 1.0, saccadic_suppression: float = 0.1) -> None:
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.fixation_duration = positive_scalar(fixation_duration, "fixation_duration", "s")
        self.action_duration = positive_scalar(action_duration, "action_duration", "s")
        self.perception_gain = positive_scalar(perception_gain, "perception_gain")
        self.saccadic_suppression = _suppression(saccadic_suppression)
        self.fixation_steps = max(1, int(round(self.fixation_duration / self.time_step)))
        self.action_steps = max(1, int(round(self.action_duration / self.time_step)))

    def steps(self, task: ScheduledTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        n_steps = self._check(n_steps)
        cycle = self.fixation_steps + self.action_steps
        for i in range(n_steps):
            position = i % cycle
            if position < self.fixation_steps:
                yield ScheduleStep(i, i * self.time_step, self.time_step, PERCEIVE, self.perception_gain,
                                   position == 0)
            else:
                yield ScheduleStep(i, i * self.time_step, self.time_step, ACT,
                                   self.saccadic_suppression * self.perception_gain,
                                   position == self.fixation_steps)


class PrecisionDrivenScheduler(_Scheduler):
    """Move when staying stops paying; the rhythm is a prior on when.

    A marginal-value rule (as in optimal foraging). At each perception step (after
    ``min_fixation_steps``), with g = ``perception_gain`` and dt = ``time_step``:

        G_stay = task.expected_gain_of_staying(g, dt)             one more step here
        G_move = task.expected_gain_of_moving(g, (h - m) dt)      a whole fixation elsewhere
        move  iff  G_stay < G_move / h * exp(-kappa sin theta(t))

    A move costs m action steps of (almost) no data, so over the next h = ``horizon_steps``
    steps (default: one oscillator cycle) moving earns G_move / h per step on average; staying
    earns G_stay now, and G_stay falls as the posterior precision saturates. While the posterior
    precision still rises quickly (G_stay high) the sensor stays. kappa = ``prior_weight`` >= 0:
    the oscillator phase theta(t) tilts the decision towards its troughs (sin theta = -1 lowers
    the bar for moving by e^kappa) and away from its peaks; kappa = 0 is the pure
    precision-dynamics rule. A move lasts m = ``action_duration`` / dt steps at gain s * g.

    ``perception_gain`` defaults to the oscillator's mean gain over its perception windows, so
    the precision budget per perception step matches :class:`OscillatorScheduler`'s.

    ``decision_time`` [s] >= 0: deciding to move takes time. The rule reads the precision state,
    so the move starts only ``decision_time`` after the decision (rounded to whole steps), the
    sensor perceiving where it is meanwhile; clock-driven schedulers know their move times in
    advance and prepare the move during the fixation. 0 (default): the move starts at once.
    """

    def __init__(self, oscillator: PrecisionOscillator, time_step: float = 0.0125,
                 action_duration: float = 0.0625, prior_weight: float = 1.0,
                 saccadic_suppression: float = 0.1, perception_gain: float | None = None,
                 horizon_steps: int | None = None, min_fixation_steps: int = 1,
                 action_fraction: float = 0.25, decision_time: float = 0.0) -> None:
        if not isinstance(oscillator, PrecisionOscillator):
            raise AttendInputError(f"oscillator: expected a PrecisionOscillator, got {type(oscillator).__name__}")
        self.oscillator = oscillator
        self.time_step = positive_scalar(time_step, "time_step", "s")
        self.action_duration = positive_scalar(action_duration, "action_duration", "s")
        self.action_steps = max(1, int(round(self.action_duration / self.time_step)))
        weight = _finite(prior_weight, "prior_weight")
        if weight < 0:
            raise AttendInputError(f"prior_weight: expected a number >= 0, got {prior_weight!r}")
        self.prior_weight = weight
        self.saccadic_suppression = _suppression(saccadic_suppression)
        if perception_gain is None:
            perception_gain = OscillatorScheduler(oscillator, time_step, action_fraction).mean_perception_gain()
        self.perception_gain = positive_scalar(perception_gain, "perception_gain")
        if horizon_steps is None:
            horizon_steps = max(self.action_steps + 1, int(round(oscillator.period / self.time_step)))
        self.horizon_steps = _positive_int(horizon_steps, "horizon_steps")
        if self.horizon_steps <= self.action_steps:
            raise AttendInputError(
                f"horizon_steps: expected more than the {self.action_steps} action steps, got {horizon_steps!r}")
        self.min_fixation_steps = _positive_int(min_fixation_steps, "min_fixation_steps")
        decision = _finite(decision_time, "decision_time")
        if decision < 0:
            raise AttendInputError(f"decision_time: expected a time >= 0 s, got {decision_time!r}")
        self.decision_time = decision
        self.decision_steps = int(round(decision / self.time_step))

    def should_move(self, gain_of_staying: float, gain_of_moving: float, time: float) -> bool:
        """The decision rule above at time ``time`` [s]: G_stay (one step) vs G_move (a fixation of
        h - m steps)."""
        prior = math.exp(-self.prior_weight * math.sin(float(self.oscillator.phase_angle(time))))
        return gain_of_staying < gain_of_moving / self.horizon_steps * prior

    def steps(self, task: ScheduledTask | None, n_steps: int) -> Iterator[ScheduleStep]:
        if task is None:
            raise AttendInputError("task: the precision-driven scheduler needs a ScheduledTask to consult")
        n_steps = self._check(n_steps)
        dt, g = self.time_step, self.perception_gain
        fixation_steps, action_left, deciding, i = 0, 0, -1, 0
        while i < n_steps:
            t = i * dt
            if deciding == 0:  # the decision is made: move now
                action_left, fixation_steps, deciding = self.action_steps, 0, -1
            if action_left > 0:
                onset = action_left == self.action_steps
                yield ScheduleStep(i, t, dt, ACT, self.saccadic_suppression * g, onset)
                action_left -= 1
                i += 1
                continue
            if deciding > 0:  # perceiving while the decision to move is being taken
                deciding -= 1
            elif fixation_steps >= self.min_fixation_steps and self.should_move(
                    task.expected_gain_of_staying(g, dt),
                    task.expected_gain_of_moving(g, (self.horizon_steps - self.action_steps) * dt), t + 0.5 * dt):
                if self.decision_steps == 0:
                    action_left, fixation_steps = self.action_steps, 0
                    continue
                deciding = self.decision_steps - 1
            yield ScheduleStep(i, t, dt, PERCEIVE, g, fixation_steps == 0)
            fixation_steps += 1
            i += 1


def drive(scheduler: _Scheduler, task: ScheduledTask, n_steps: int,
          until: Callable[[ScheduleStep], bool] | None = None) -> ScheduleTrace:
    """Run up to ``n_steps`` steps of ``scheduler`` on ``task``: ``task.perceive(g, dt)`` on
    PERCEIVE steps, ``task.act(g, dt, onset)`` on ACT steps. Stops before the first step for
    which ``until(step)`` is true. Returns the :class:`ScheduleTrace` of the steps run."""
    time, gains, perceiving, onsets = [], [], [], []
    for step in scheduler.steps(task, n_steps):
        if until is not None and until(step):
            break
        if step.mode == PERCEIVE:
            task.perceive(step.precision_gain, step.duration)
        else:
            task.act(step.precision_gain, step.duration, step.onset)
        time.append(step.time)
        gains.append(step.precision_gain)
        perceiving.append(step.mode == PERCEIVE)
        onsets.append(step.onset)
    return ScheduleTrace(np.array(time, dtype=float), np.array(gains, dtype=float),
                         np.array(perceiving, dtype=bool), np.array(onsets, dtype=bool))
