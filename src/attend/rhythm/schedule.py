"""Schedules: when to stop perceiving and act (paper Sec. 2.3, 4.4).

A schedule alternates perception (assimilate data at high precision) and action (move the
sensor, or replan, with data taken meanwhile suppressed). Three kinds, each defined once here:

- :class:`RhythmicSchedule`: the rhythm decides. Perceive while the precision multiplier
  pi(t) of a :class:`PrecisionOscillator` is above the threshold pi_0 exp(-a cos(pi q)), act in
  its troughs (a fraction q = ``action_fraction`` of each cycle).
- :class:`PrecisionDrivenSchedule`: the precision dynamics decide, the rhythm is a prior on the
  timing. Switch to acting iff

      G_stay < rho * G_move * exp(-kappa sin theta(t))        (:func:`switch_decision`)

  G_stay, G_move: expected gain per unit time of staying and of moving (same unit), theta(t)
  the oscillator phase (its troughs, sin theta = -1, lower the bar by e^kappa),
  kappa = ``prior_weight`` (0: precision dynamics alone), rho = ``tolerance``.
- :class:`FixedSchedule`: a fixed budget: perceive for ``perceive_s``, act for ``act_s``,
  repeat (the arbitrary alternative the seed argues against).

Words: the *precision multiplier* pi(t) multiplies a sensor's precision; the *precision gain*
(as in :mod:`attend.action`) is an expected reduction of trace(P).

Adapters turn a schedule into what each use needs:

- learning, :func:`attend.rhythm.learning.prior_precision_sequence`: the prior parameter
  precision per learning iteration;
- path planning, :func:`attend.rhythm.replanning.replan_policy`: an
  :class:`attend.action.episode.ReplanPolicy` (when the UAV replans);
- active vision, :func:`attend.rhythm.fixations.fixation_policy`: the perceive/act step of
  every time step of the eye (when it saccades).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from attend._validation import AttendInputError, positive_scalar
from attend.rhythm.oscillator import PrecisionOscillator, _finite, _fraction

__all__ = ["ACT", "PERCEIVE", "FixedSchedule", "PrecisionDrivenSchedule", "RhythmicSchedule", "Schedule",
           "switch_decision"]

PERCEIVE = "perceive"
ACT = "act"


def _oscillator(value) -> PrecisionOscillator:
    if not isinstance(value, PrecisionOscillator):
        raise AttendInputError(f"oscillator: expected a PrecisionOscillator, got {type(value).__name__}")
    return value


def _non_negative(value, field: str, unit: str = "") -> float:
    number = _finite(value, field)
    if number < 0:
        raise AttendInputError(f"{field}: expected a number >= 0{unit}, got {value!r}")
    return number


@dataclass(frozen=True)
class RhythmicSchedule:
    """Perceive while pi(t) >= pi_threshold = pi_0 exp(-a cos(pi q)), act in the troughs.

    oscillator: the :class:`PrecisionOscillator` pi(t) (its clock: seconds, or iterations in
    learning); action_fraction: q in (0, 1), the fraction of each cycle spent acting."""

    oscillator: PrecisionOscillator
    action_fraction: float = 0.25

    def __post_init__(self) -> None:
        _oscillator(self.oscillator)
        object.__setattr__(self, "action_fraction", _fraction(self.action_fraction, "action_fraction"))

    @property
    def threshold(self) -> float:
        """pi_threshold = pi_0 exp(-a cos(pi q)) [dimensionless]."""
        return self.oscillator.threshold(self.action_fraction)

    def _cycle(self, samples: int) -> np.ndarray:
        theta = 2.0 * np.pi * (np.arange(samples) + 0.5) / samples
        return self.oscillator.baseline_multiplier * np.exp(self.oscillator.depth * np.sin(theta))

    def mean_perception_multiplier(self, samples: int = 4096) -> float:
        """Mean of pi over the perception part of a cycle (pi >= threshold) [dimensionless], on
        ``samples`` equally spaced phases."""
        multiplier = self._cycle(samples)
        return float(multiplier[multiplier >= self.threshold].mean())

    def mean_action_multiplier(self, samples: int = 4096) -> float:
        """Mean of pi over the action part of a cycle (pi < threshold) [dimensionless], on
        ``samples`` equally spaced phases."""
        multiplier = self._cycle(samples)
        return float(multiplier[multiplier < self.threshold].mean())


@dataclass(frozen=True)
class PrecisionDrivenSchedule:
    """Switch to acting when staying stops paying: G_stay < rho G_move exp(-kappa sin theta(t)).

    oscillator: the rhythm used as a prior on the timing (phase theta(t)); prior_weight:
    kappa >= 0 (0: the precision dynamics alone); tolerance: rho > 0."""

    oscillator: PrecisionOscillator
    prior_weight: float = 0.5
    tolerance: float = 1.0

    def __post_init__(self) -> None:
        _oscillator(self.oscillator)
        object.__setattr__(self, "prior_weight", _non_negative(self.prior_weight, "prior_weight"))
        object.__setattr__(self, "tolerance", positive_scalar(self.tolerance, "tolerance"))

    def should_switch(self, gain_of_staying: float, gain_of_moving: float, time: float) -> bool:
        """:func:`switch_decision` at ``time`` (on the oscillator's clock) for the expected gains
        ``gain_of_staying`` and ``gain_of_moving`` (same unit)."""
        phase = float(self.oscillator.phase_angle(time))
        return switch_decision(gain_of_staying, gain_of_moving, phase, self.prior_weight, self.tolerance)


@dataclass(frozen=True)
class FixedSchedule:
    """A fixed budget: perceive for ``perceive_s`` [s] (a fixation, or the flight time per plan)
    at precision multiplier ``multiplier`` (in learning: the fixed prior precision), then act for
    ``act_s`` [s] (>= 0), and repeat."""

    perceive_s: float = 1.0
    act_s: float = 0.0
    multiplier: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "perceive_s", positive_scalar(self.perceive_s, "perceive_s", "s"))
        object.__setattr__(self, "act_s", _non_negative(self.act_s, "act_s", " s"))
        object.__setattr__(self, "multiplier", positive_scalar(self.multiplier, "multiplier"))


#: any of the three kinds
Schedule = RhythmicSchedule | PrecisionDrivenSchedule | FixedSchedule


def switch_decision(stay_rate: float, move_rate: float, phase_angle: float = 0.0, prior_weight: float = 0.0,
                    tolerance: float = 1.0) -> bool:
    """Act (move, replan) iff  stay_rate < tolerance * move_rate * exp(-prior_weight * sin(phase_angle)).

    stay_rate: expected gain per unit time of staying (the rest of the plan, one more step
    here); move_rate: the gain per unit time moving is expected to offer (same unit);
    phase_angle: oscillator phase theta(t) [rad] (its troughs, sin = -1, favour acting);
    prior_weight: kappa >= 0; tolerance: rho > 0."""
    prior = math.exp(-float(prior_weight) * math.sin(float(phase_angle)))
    return float(stay_rate) < float(tolerance) * float(move_rate) * prior
