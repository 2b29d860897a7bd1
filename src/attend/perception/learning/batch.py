"""The batched learner: alternating D, E and M steps (and the optional extra moves) over R runs
that share one model structure, as in the paper's algorithm (see the package docstring)."""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError
from attend.perception.learning.free_energy import _evaluate, curvature_default
from attend.perception.learning.problem import _prepare, _Priors
from attend.perception.learning.steps import (
    NEWTON_CREEP,
    _Data,
    _Outcome,
    _Point,
    d_step,
    e_step,
    m_step,
    newton_step,
    overrelax_step,
    start,
)
from attend.perception.learning.problem import LearningWarning
from attend.perception.learning.settings import LearningSettings, _resolved


class BatchLearningResult(NamedTuple):
    """Results of R runs (leading axis R); histories have n_iterations + 1 rows (row 0 = start).

    parameters (R, n_theta): posterior means theta; parameter_precision (R, n_theta, n_theta):
    Pi_theta = H + P_theta (rows/columns of fixed entries hold inf on the diagonal, 0 elsewhere);
    log_precision (R, 2): [lambda_z, lambda_w]; log_precision_precision (R, 2): Pi_lambda;
    free_energy (R, I+1); parameter_history (R, I+1, n_theta); precision_history (R, I+1, n_theta)
    (diagonal of Pi_theta); log_precision_history (R, I+1, 2); steps_accepted (R, 4): accepted
    D, E, M steps and over-relaxed moves; iterations (R,); converged (R,); messages: one string per run;
    states (R, T, n): x^(0) at every sample; free_energy_trace: per run, every accepted value.
    """

    parameters: np.ndarray
    parameter_precision: np.ndarray
    log_precision: np.ndarray
    log_precision_precision: np.ndarray
    free_energy: np.ndarray
    parameter_history: np.ndarray
    precision_history: np.ndarray
    log_precision_history: np.ndarray
    steps_accepted: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    messages: tuple[str, ...]
    states: np.ndarray
    free_energy_trace: tuple[np.ndarray, ...]


def learn_batch(
    outputs: np.ndarray,
    inputs: np.ndarray,
    dt: float,
    *,
    n_states: int,
    kernel_width: float,
    prior_mean: np.ndarray,
    prior_precision: np.ndarray,
    initial: np.ndarray | None = None,
    settings: LearningSettings | None = None,
    progress: bool = False,
) -> BatchLearningResult:
    """Alternating D/E/M learning of R independent runs at once (see the package docstring of attend.perception.learning).

    outputs (R, T, m) and inputs (R, T, r) sampled at dt [s]; n_states n; kernel_width s [s] of
    the noise's Gaussian kernel; prior_mean eta_theta and prior_precision P_theta (R, n_theta) in
    the order of :func:`parameter_names` (P_theta = inf holds an entry fixed; all runs must fix
    the same entries); prior_precision may also be a schedule (R, max_iterations, n_theta): row i
    is the P_theta of iteration i + 1 (its E-step and the free energy it maximises; the learning
    schedules of attend.rhythm.learning), and a run then converges only once its schedule stays
    constant; initial theta (R, n_theta) (default eta_theta). ``settings``: a
    :class:`LearningSettings` (embedding, noise prior, stopping rule, options; every run shares
    it); None is ``LearningSettings()``, and its ``newton`` = None means off here. progress: show
    a progress bar over the iterations.
    No Python loop over runs: every step is batched linear algebra over the leading axis.
    The arrays are not validated here (see :func:`identify`).
    """
    settings = _resolved(settings, newton=False)
    data, priors, theta0, P_schedule, constant_from = _setup(
        outputs, inputs, dt, n_states, kernel_width, prior_mean, prior_precision, initial, settings)
    max_iterations = settings.max_iterations
    R, st = theta0.shape[0], data.st
    L = np.full(R, settings.integration_time)
    beta = np.ones(R)
    point = start(theta0, priors.eta_lambda.copy(), data, priors)
    log = _Log(point, st.active, max_iterations)
    for it in _iterations(max_iterations, progress, R):
        live = ~(log.converged | log.stopped)
        if not live.any():
            break
        P_now = P_schedule[:, it - 1]
        if not np.array_equal(P_now, priors.P_theta):  # the schedule moved: F is re-evaluated
            priors = replace(priors, P_theta=P_now.copy())
            point = point._replace(ev=_evaluate(point.state, point.K_mean, priors, st))
        before = point
        point = log.take(d_step(point, live, data, priors), "D", it)
        point = log.take(e_step(point, live & ~log.stopped, data, priors, L), "E", it)
        point = log.take(m_step(point, live & ~log.stopped, data, priors, settings.noise_integration_time,
                                settings.noise_iterations), "M", it)
        if settings.overrelax:
            outcome, beta = overrelax_step(point, live & ~log.stopped, data, priors, before.state, beta)
            point = log.take(outcome, "over-relaxed", it)
        if settings.newton:  # only once the sweeps creep (a sweep gained < NEWTON_CREEP |F|)
            creeping = (point.ev.F - before.ev.F) < NEWTON_CREEP * np.abs(point.ev.F)
            point = log.take(newton_step(point, live & ~log.stopped & creeping, data, priors), "over-relaxed", it)
        log.end_iteration(it, live, point, before.ev.F, settings.tolerance, constant_from[:, it - 1])
    return log.result(point, -curvature_default(priors.fisher, priors.P_lambda), max_iterations)


def _iterations(max_iterations: int, progress: bool, R: int):
    """Iterations 1 .. max_iterations, with a progress bar when asked."""
    iterator = range(1, max_iterations + 1)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"learning ({R} runs)", leave=False)
    return iterator


def _setup(outputs, inputs, dt, n_states, kernel_width, prior_mean, prior_precision, initial,
           settings: LearningSettings):
    """The embedded logs and their structure, the priors of the first iteration, the starting theta,
    P_theta per iteration and when each run's P_theta stops changing (see :func:`_prior_schedule`);
    ``settings`` resolved (:func:`_resolved`)."""
    p = settings.embedding_order
    if settings.states == "path" and p > 6:
        warnings.warn(f"states='path' with embedding_order = {p}: the path precision is "
                      "ill-conditioned above p = 6 (condition number ~dt^-2p); estimates lose accuracy",
                      LearningWarning, stacklevel=3)
    outputs = np.asarray(outputs, dtype=float)
    inputs = np.asarray(inputs, dtype=float)
    R = outputs.shape[0]
    eta, P_schedule, constant_from = _prior_schedule(prior_mean, prior_precision, R, settings.max_iterations)
    active = np.isfinite(P_schedule[0, 0])
    data = _Data(*_prepare(outputs, inputs, dt, kernel_width, p, settings.input_order, active, n_states,
                           settings.trim_edges, settings.precision_convention, settings.states, settings.top_order,
                           settings.scaled))
    st = data.st
    theta0 = eta.copy() if initial is None else np.broadcast_to(np.asarray(initial, dtype=float), eta.shape).copy()
    theta0[:, ~active] = eta[:, ~active]
    lam_eta = np.broadcast_to(np.asarray(settings.noise_prior_mean, dtype=float), (R, 2)).copy()
    P_lam = np.broadcast_to(np.asarray(settings.noise_prior_precision, dtype=float), (R, 2)).copy()
    fisher = 0.5 * st.count * st.n_used * np.array([st.m * st.orders, st.n * st.w_orders], dtype=float)
    priors = _Priors(eta, P_schedule[:, 0].copy(), lam_eta, P_lam, fisher)
    return data, priors, theta0, P_schedule, constant_from


def _prior_schedule(prior_mean, prior_precision, R: int, max_iterations: int):
    """eta_theta (R, n_theta), P_theta per iteration (R, max(max_iterations, 1), n_theta) and
    constant_from (R, max_iterations): P_theta of run r no longer changes from iteration i + 1 on."""
    eta = np.broadcast_to(np.asarray(prior_mean, dtype=float), (R, prior_mean.shape[-1])).copy()
    P_given = np.asarray(prior_precision, dtype=float)
    if P_given.ndim == 3:  # a schedule: one P_theta per iteration
        if P_given.shape[1] != max_iterations:
            raise AttendInputError(f"prior_precision: a schedule needs one row per iteration, expected "
                                   f"(R, {max_iterations}, {eta.shape[1]}), got {P_given.shape}")
        P_schedule = np.broadcast_to(P_given, (R, max_iterations, eta.shape[1])).copy()
    else:
        P_schedule = np.broadcast_to(P_given, eta.shape)[:, None, :].repeat(max(max_iterations, 1), axis=1)
    active_runs = np.isfinite(P_schedule)
    if not np.all(active_runs == active_runs[0, 0][None, None]):
        raise AttendInputError("prior_precision: every run must hold the same entries fixed (inf)")
    same_as_next = np.all(P_schedule[:, 1:] == P_schedule[:, :-1], axis=2)
    constant_from = np.flip(np.cumprod(np.flip(np.concatenate(
        [same_as_next, np.ones((R, 1), dtype=bool)], axis=1), axis=1), axis=1), axis=1).astype(bool)
    return eta, P_schedule, constant_from


class _Log:
    """What learn_batch reports besides the final point: the histories (row 0 = start), the accepted
    steps, every accepted F, and per run whether (and why) it stopped or converged."""

    COLUMNS = {"D": 0, "E": 1, "M": 2, "over-relaxed": 3}

    def __init__(self, point: _Point, active: np.ndarray, max_iterations: int):
        R, n_theta = point.state.theta.shape
        self.active = active
        self.F = np.full((R, max_iterations + 1), np.nan)
        self.theta = np.full((R, max_iterations + 1, n_theta), np.nan)
        self.precision = np.full((R, max_iterations + 1, n_theta), np.nan)
        self.lam = np.full((R, max_iterations + 1, 2), np.nan)
        self.accepted = np.zeros((R, 4), dtype=int)  # D, E, M steps and over-relaxed moves
        self.iterations = np.zeros(R, dtype=int)
        self.converged = np.zeros(R, dtype=bool)
        self.stopped = ~np.isfinite(point.ev.F)
        self.messages = ["stopped: the free energy is not finite at the initial estimate (D-step, iteration 0)"
                         if bad else "" for bad in self.stopped]
        self.trace: list[list[float]] = [[float(f)] for f in point.ev.F]
        self.record(0, point, np.arange(R))

    def record(self, i: int, point: _Point, rows: np.ndarray) -> None:
        R, n_theta = point.state.theta.shape
        self.F[rows, i] = point.ev.F[rows]
        self.theta[rows, i] = point.state.theta[rows]
        diag = np.full((R, n_theta), np.inf)
        diag[:, self.active] = np.diagonal(point.ev.Pi_theta, axis1=1, axis2=2)
        self.precision[rows, i] = diag[rows]
        self.lam[rows, i] = point.state.lam[rows]

    def take(self, outcome: _Outcome, step: str, it: int) -> _Point:
        """Count and trace what a step accepted, stop the runs it diverged on; its new point."""
        for ok, F in outcome.accepted:
            self.accepted[ok, self.COLUMNS[step]] += 1
            for k in np.flatnonzero(ok):
                self.trace[k].append(float(F[k]))
        for k in np.flatnonzero(outcome.diverged & ~self.stopped):
            self.messages[k] = (f"stopped: the {step}-step diverged at iteration {it} (every trial step gave a "
                                "non-finite free energy); returning the last accepted estimate")
        self.stopped[outcome.diverged] = True
        return outcome.point

    def end_iteration(self, it: int, live: np.ndarray, point: _Point, F_start: np.ndarray, tolerance: float,
                      prior_constant: np.ndarray) -> None:
        """Record iteration ``it`` of the live runs; a run converges when the iteration raised F by less
        than ``tolerance`` and its prior precision no longer changes."""
        self.iterations[live] = it
        self.record(it, point, np.flatnonzero(live))
        gain = point.ev.F - F_start
        newly = live & ~self.stopped & (gain < tolerance) & prior_constant
        self.converged |= newly
        for k in np.flatnonzero(newly):
            self.messages[k] = f"converged at iteration {it} (free energy rose by {gain[k]:.3g} < tolerance {tolerance:g})"

    def result(self, point: _Point, lambda_precision: np.ndarray, max_iterations: int) -> BatchLearningResult:
        R, n_theta = point.state.theta.shape
        messages = [m or f"stopped after max_iterations = {max_iterations} (not converged)" for m in self.messages]
        Pi_full = np.zeros((R, n_theta, n_theta))
        idx = np.flatnonzero(self.active)
        Pi_full[:, idx[:, None], idx[None, :]] = point.ev.Pi_theta
        for j in np.flatnonzero(~self.active):
            Pi_full[:, j, j] = np.inf
        n_hist = int(self.iterations.max()) + 1
        for k in range(R):  # runs that stopped earlier keep their last values (no NaN rows in a batch)
            last = int(self.iterations[k])
            for hist in (self.F, self.theta, self.precision, self.lam):
                hist[k, last + 1:n_hist] = hist[k, last]
        return BatchLearningResult(
            parameters=point.state.theta,
            parameter_precision=Pi_full,
            log_precision=point.state.lam,
            log_precision_precision=np.broadcast_to(lambda_precision, (R, 2)).copy(),
            free_energy=self.F[:, :n_hist],
            parameter_history=self.theta[:, :n_hist],
            precision_history=self.precision[:, :n_hist],
            log_precision_history=self.lam[:, :n_hist],
            steps_accepted=self.accepted,
            iterations=self.iterations,
            converged=self.converged,
            messages=tuple(messages),
            states=point.state.mu[:, :, 0, :],
            free_energy_trace=tuple(np.array(t) for t in self.trace),
        )
