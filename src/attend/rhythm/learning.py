"""A schedule in learning: the prior parameter precision P_theta per iteration (paper Sec. 4.4).

The paper (§4.4, with Figs. 4-5, use 1) proposes that during system
identification the prior parameter precision P^theta alternate between exploration (low: attend
to the data) and exploitation (high: attend to the prior), so that the learner is neither
over-exposed to noisy data nor biased by its prior, without knowing the noise level. Here the
oscillator of a :class:`attend.rhythm.schedule.RhythmicSchedule` runs over learning iterations
instead of seconds, its precision multiplier being the prior precision::

    P_theta(k) = pi_0 * exp(a * sin(2 pi f k + phi)),   k = 0, 1, ..., n_iterations - 1

k      learning iteration (k = 0 is the first D/E/M iteration of learn_batch)
pi_0   ``baseline_multiplier`` of the oscillator: the geometric-mean prior precision over a cycle
a      ``depth``: log-amplitude (a = 0: the fixed P_theta = pi_0)
f      ``frequency`` in cycles per iteration (the oscillator's "Hz" with one iteration as the
       time unit)
phi    ``phase`` [rad]

P_theta(k) is the prior precision of the free (unknown) entries in iteration k; the known
entries keep their own (high) prior precision throughout. Each iteration's E-step and free
energy use that iteration's P_theta (:func:`attend.perception.learning.learn_batch` takes the
schedule as a prior precision of shape (R, n_iterations, n_theta), batched over runs).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from attend._validation import AttendInputError
from attend.perception.learning import KNOWN_PRIOR_PRECISION, BatchLearningResult, LearningSettings, learn_batch
from attend.rhythm.schedule import FixedSchedule, RhythmicSchedule

__all__ = ["learn_scheduled", "prior_precision_per_entry", "prior_precision_sequence"]


def prior_precision_sequence(schedule, n_iterations: int) -> np.ndarray:
    """P_theta(k) for k = 0 .. n_iterations - 1 (shape (n_iterations,)) of ``schedule``.

    A :class:`RhythmicSchedule`: P_theta(k) = pi_0 exp(a sin(2 pi f k + phi)), the oscillator's
    precision multiplier with one learning iteration as its time unit (``frequency`` in cycles
    per iteration). A :class:`FixedSchedule`: P_theta(k) = ``schedule.multiplier``. (A
    precision-driven schedule has no learning counterpart here.)
    """
    if int(n_iterations) != n_iterations or n_iterations < 1:
        raise AttendInputError(f"n_iterations: expected a positive integer, got {n_iterations!r}")
    if isinstance(schedule, RhythmicSchedule):
        return np.asarray(schedule.oscillator.multiplier(np.arange(int(n_iterations), dtype=float)), dtype=float)
    if isinstance(schedule, FixedSchedule):
        return np.full(int(n_iterations), schedule.multiplier)
    raise AttendInputError(f"schedule: expected a RhythmicSchedule or FixedSchedule, got {type(schedule).__name__}")


def prior_precision_per_entry(free_schedule, free, known_prior_precision: float = KNOWN_PRIOR_PRECISION,
                              n_runs: int | None = None) -> np.ndarray:
    """The full per-iteration P_theta (R, n_iterations, n_theta) for learn_batch.

    free_schedule: P_theta of the free entries per iteration (:func:`prior_precision_sequence`), (n_iterations,) shared by all runs
    or (R, n_iterations) per run; free: bool mask over theta (order of parameter_names); the other
    entries get ``known_prior_precision`` (exp(15) by default; inf holds them fixed); n_runs:
    broadcast to R = n_runs runs (None: as given).
    """
    sched = np.asarray(free_schedule, dtype=float)
    free = np.asarray(free, dtype=bool)
    if sched.ndim == 1:
        sched = sched[None]
    if sched.ndim != 2:
        raise AttendInputError(f"free_schedule: expected (n_iterations,) or (R, n_iterations), got {sched.shape}")
    if np.any(~np.isfinite(sched)) or np.any(sched < 0):
        raise AttendInputError("free_schedule: expected finite prior precisions >= 0")
    if n_runs is not None:
        sched = np.broadcast_to(sched, (int(n_runs), sched.shape[1]))
    return np.where(free[None, None, :], sched[:, :, None], float(known_prior_precision))


def learn_scheduled(outputs, inputs, dt: float, *, free_schedule, free, prior_mean, n_states: int,
                    kernel_width: float, known_prior_precision: float = KNOWN_PRIOR_PRECISION, initial=None,
                    settings: LearningSettings | None = None, progress: bool = False) -> BatchLearningResult:
    """learn_batch of R runs with P_theta of the free entries following ``free_schedule``.

    free_schedule (n_iterations,) or (R, n_iterations), e.g. from :func:`prior_precision_sequence`;
    the number of iterations is its length (it replaces ``settings.max_iterations``); free: bool
    mask of the learned entries. outputs (R, T, m), inputs (R, T, r), sampling interval dt [s],
    prior_mean eta_theta (R, n_theta), n_states, kernel_width, initial, settings and progress as
    in :func:`attend.perception.learning.learn_batch`; known_prior_precision: P_theta of the
    entries that are not free. A constant schedule gives exactly learn_batch with that fixed P_theta.
    """
    outputs = np.asarray(outputs, dtype=float)
    R = outputs.shape[0]
    P = prior_precision_per_entry(free_schedule, free, known_prior_precision, n_runs=R)
    if settings is not None and not isinstance(settings, LearningSettings):
        raise AttendInputError(f"settings: expected a LearningSettings, got {type(settings).__name__}")
    settings = replace(settings or LearningSettings(), max_iterations=P.shape[1])
    return learn_batch(outputs, inputs, dt, n_states=n_states, kernel_width=kernel_width, prior_mean=prior_mean,
                       prior_precision=P, initial=initial, settings=settings, progress=progress)
