"""Rhythm: precision-modulated scheduling of perception and action (paper Sec. 2.3, 3, 4.4).

- :class:`PrecisionOscillator`: the precision multiplier pi(t) = pi_0 exp(a sin(2 pi f t + phi)).
- schedules (:mod:`attend.rhythm.schedule`), when to stop perceiving and act, one kind each:
  :class:`RhythmicSchedule`, :class:`PrecisionDrivenSchedule`, :class:`FixedSchedule`, and the
  rule :func:`switch_decision`. Adapters to the three uses:
  learning (:mod:`attend.rhythm.learning`, :func:`prior_precision_sequence`), replanning in UAV
  search (:mod:`attend.rhythm.replanning`, :func:`replan_policy`) and active vision
  (:mod:`attend.rhythm.fixations`, :func:`fixation_policy`, :func:`drive`).
- active vision (:mod:`attend.rhythm.vision`): :class:`FoveatedEye`, :class:`Scene`,
  :func:`random_scene`, exact belief updates, epistemic :func:`salience_map`, saccade policies,
  :class:`ActiveVisionAgent` and :func:`look` (one scene).
"""

from attend.rhythm.fixations import (
    FixationTask,
    FixedFixations,
    PrecisionDrivenFixations,
    RhythmicFixations,
    ScheduleStep,
    ScheduleTrace,
    drive,
    fixation_policy,
)
from attend.rhythm.learning import prior_precision_sequence
from attend.rhythm.oscillator import PrecisionOscillator
from attend.rhythm.replanning import make_replan_policy, replan_policy
from attend.rhythm.schedule import (
    ACT,
    PERCEIVE,
    FixedSchedule,
    PrecisionDrivenSchedule,
    RhythmicSchedule,
    switch_decision,
)
from attend.rhythm.vision import (
    ActiveVisionAgent,
    EpistemicPolicy,
    FoveatedEye,
    RandomPolicy,
    Scene,
    StaticSaliencyPolicy,
    VisionEpisode,
    look,
    random_scene,
    salience_map,
)

__all__ = [
    "ACT", "PERCEIVE", "ActiveVisionAgent", "EpistemicPolicy", "FixationTask", "FixedFixations", "FixedSchedule",
    "FoveatedEye", "PrecisionDrivenFixations", "PrecisionDrivenSchedule", "PrecisionOscillator", "RandomPolicy",
    "RhythmicFixations", "RhythmicSchedule", "ScheduleStep", "ScheduleTrace", "Scene", "StaticSaliencyPolicy",
    "VisionEpisode", "drive", "fixation_policy", "look", "make_replan_policy", "prior_precision_sequence",
    "random_scene", "replan_policy", "salience_map", "switch_decision",
]
