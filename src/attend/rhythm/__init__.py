"""Rhythm: precision-modulated scheduling of perception and action (seed §2.3, §3, §4.4).

- :class:`PrecisionOscillator`: pi(t) = pi_0 exp(a sin(2 pi f t + phi)).
- schedulers (:mod:`attend.rhythm.scheduler`): :class:`OscillatorScheduler`,
  :class:`PrecisionDrivenScheduler`, :class:`FixedDurationScheduler`, the task protocol
  :class:`ScheduledTask`, :func:`drive`.
- active vision (:mod:`attend.rhythm.vision`): :class:`FoveatedEye`, :class:`Scene`,
  :func:`random_scene`, exact belief updates, epistemic :func:`salience_map`, policies, and
  :func:`run_episode`.
"""

from attend.rhythm.oscillator import PrecisionOscillator
from attend.rhythm.scheduler import (
    ACT,
    PERCEIVE,
    FixedDurationScheduler,
    OscillatorScheduler,
    PrecisionDrivenScheduler,
    ScheduledTask,
    ScheduleStep,
    ScheduleTrace,
    drive,
)
from attend.rhythm.vision import (
    ActiveVisionAgent,
    Episode,
    EpistemicPolicy,
    FoveatedEye,
    RandomPolicy,
    Scene,
    StaticSaliencyPolicy,
    entropy,
    information_gain,
    letter_patterns,
    random_scene,
    run_episode,
    salience_map,
    static_saliency_map,
    update_beliefs,
)

__all__ = [
    "ACT", "PERCEIVE", "ActiveVisionAgent", "Episode", "EpistemicPolicy", "FixedDurationScheduler",
    "FoveatedEye", "OscillatorScheduler", "PrecisionDrivenScheduler", "PrecisionOscillator",
    "RandomPolicy", "ScheduleStep", "ScheduleTrace", "ScheduledTask", "Scene", "StaticSaliencyPolicy",
    "drive", "entropy", "information_gain", "letter_patterns", "random_scene", "run_episode",
    "salience_map", "static_saliency_map", "update_beliefs",
]
