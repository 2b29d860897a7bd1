"""The public entry point: :func:`identify` learns (A, B, C) and the noise precisions from one log,
validating at the boundary and warning where the data cannot determine what was asked."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from attend._validation import AttendInputError, as_matrix, positive_scalar
from attend.constants import KNOWN_PRIOR_PRECISION
from attend.models.linear import LinearSystem, as_linear_system, observability_rank
from attend.models.parameters import (
    parameter_array,
    parameter_slice,
    parameter_names,
    parameter_vector,
    system_from_parameters,
)
from attend.perception.learning.batch import BatchLearningResult, learn_batch
from attend.perception.learning.problem import IdentifiabilityWarning, LearningWarning
from attend.perception.learning.settings import LearningSettings, _resolved

KNOWN_DISPLACED_STD = 5.0  # identify warns when a known entry ends this many prior std from its mean


@dataclass(frozen=True, eq=False)
class IdentificationResult:
    """The outcome of :func:`identify`.

    parameters: posterior means of theta = [vec(A); vec(B); vec(C)] (row-major), named by
    ``parameter_names``; parameter_precision: Pi_theta = -d2F/dtheta2 (n_theta x n_theta; inf on
    the diagonal of entries held fixed); prior_mean eta_theta, prior_precision P_theta, free (bool
    mask); log_precision [lambda_z, lambda_w] with Pi_z = exp(lambda_z) I, Pi_w = exp(lambda_w) I
    and their posterior precision Pi_lambda; free_energy F per iteration (row 0 = start);
    parameter_history, precision_history (diagonal of Pi_theta), log_precision_history per
    iteration; steps_accepted {"D", "E", "M"}; converged, iterations, message; states x(t)
    (N, n) at the final estimate; prior_system: the model the learning started from;
    log_precision_precision: Pi_lambda (2,); settings: the options the learning ran with.
    """

    parameter_names: tuple[str, ...]
    parameters: np.ndarray
    parameter_precision: np.ndarray
    prior_mean: np.ndarray
    prior_precision: np.ndarray
    free: np.ndarray
    log_precision: np.ndarray
    log_precision_precision: np.ndarray
    free_energy: np.ndarray
    parameter_history: np.ndarray
    precision_history: np.ndarray
    log_precision_history: np.ndarray
    steps_accepted: dict
    converged: bool
    iterations: int
    message: str
    states: np.ndarray
    prior_system: LinearSystem
    settings: dict = field(default_factory=dict)

    @property
    def sensor_precision(self) -> float:
        """Pi_z = exp(lambda_z) (per output, times I)."""
        return float(np.exp(self.log_precision[0]))

    @property
    def process_precision(self) -> float:
        """Pi_w = exp(lambda_w) (per state derivative, times I)."""
        return float(np.exp(self.log_precision[1]))

    @property
    def parameter_std(self) -> np.ndarray:
        """Posterior standard deviations sqrt(diag(inv(Pi_theta))) (0 for fixed entries)."""
        std = np.zeros(len(self.parameters))
        act = np.isfinite(np.diag(self.parameter_precision))
        if act.any():
            cov = np.linalg.inv(self.parameter_precision[np.ix_(act, act)])
            std[act] = np.sqrt(np.clip(np.diag(cov), 0, None))
        return std

    def system(self) -> LinearSystem:
        """The learned LinearSystem (posterior means), labelled like the prior system."""
        return system_from_parameters(self.parameters, self.prior_system)

    def table(self) -> str:
        """Plain-text table: name, prior mean, learned mean, posterior std, free."""
        rows = [("parameter", "prior", "learned", "std", "free")]
        for name, a, b, s, f in zip(self.parameter_names, self.prior_mean, self.parameters,
                                    self.parameter_std, self.free):
            rows.append((name, f"{a:.6g}", f"{b:.6g}", f"{s:.3g}", "yes" if f else "no"))
        rows.append(("lambda_z", "", f"{self.log_precision[0]:.4g}", f"{self.log_precision_precision[0] ** -0.5:.3g}", ""))
        rows.append(("lambda_w", "", f"{self.log_precision[1]:.4g}", f"{self.log_precision_precision[1] ** -0.5:.3g}", ""))
        widths = [max(len(r[i]) for r in rows) for i in range(5)]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows)


def identify(
    system_prior: LinearSystem,
    outputs,
    inputs,
    dt: float,
    *,
    kernel_width: float,
    free=None,
    prior_precision=None,
    free_prior_precision: float = 1.0,
    known_prior_precision: float = KNOWN_PRIOR_PRECISION,
    initial=None,
    settings: LearningSettings | None = None,
    progress: bool = False,
) -> IdentificationResult:
    """Learn the free entries of (A, B, C) and the noise precisions from a log.

    system_prior: the model whose entries are the prior means eta_theta (the learning starts
    there unless ``initial`` is given); outputs (N, m) and measured inputs (N, r) sampled at dt [s];
    kernel_width s [s] of the noise's Gaussian kernel. ``free``: the entries to learn (bool vector
    over :func:`parameter_names`, names like "A[2,1]", or a dict of A/B/C masks; default: all of
    A and B). ``prior_precision`` P_theta per entry (same forms; default free_prior_precision on
    free entries and known_prior_precision = exp(15) on the others; inf holds an entry fixed).
    initial: the starting theta (same forms; default eta_theta). ``settings``: a
    :class:`LearningSettings` (embedding orders, noise prior, stopping rule, state model and the
    numerical options); None is ``LearningSettings()``, and its ``newton`` = None means on here.
    progress: show a progress bar over the iterations.

    Raises AttendInputError for malformed input, free entries with infinite prior precision,
    or a log whose outputs never vary; warns (IdentifiabilityWarning) when the inputs are zero
    while B is free, or when the free entries are not locally identifiable from input-output data.
    If a step diverges the learning stops (LearningWarning) and returns the last accepted estimate.
    """
    settings = _resolved(settings, newton=True)
    system_prior = as_linear_system(system_prior, "system_prior")  # a python-control StateSpace converts
    dt, kernel_width = positive_scalar(dt, "dt", "s"), positive_scalar(kernel_width, "kernel_width", "s")
    y, u = _log(system_prior, outputs, inputs, max(settings.embedding_order, settings.input_order) + 1)
    free_mask, prec = _parameter_prior(system_prior, free, prior_precision, free_prior_precision,
                                       known_prior_precision)
    eta, theta0 = _start(system_prior, y, initial)
    _warn_unidentifiable(system_prior, u, free_mask & np.isfinite(prec), theta0)

    batch = learn_batch(y[None], u[None], dt, n_states=system_prior.n_states, kernel_width=kernel_width,
                        prior_mean=eta[None], prior_precision=prec[None], initial=theta0[None], settings=settings,
                        progress=progress)
    record = dict(dt=dt, kernel_width=kernel_width, embedding_order=settings.embedding_order,
                  input_order=settings.input_order, max_iterations=settings.max_iterations,
                  tolerance=settings.tolerance, integration_time=settings.integration_time,
                  trim_edges=settings.trim_edges, state_model=settings.states, top_order=settings.top_order,
                  overrelax=settings.overrelax, newton=settings.newton, scaled=settings.scaled,
                  noise_prior_mean=list(settings.noise_prior_mean),
                  noise_prior_precision=list(settings.noise_prior_precision),
                  free_energy_trace=batch.free_energy_trace[0])
    return _result(batch, system_prior, free_mask, prec, eta, record)


def _result(batch: BatchLearningResult, system: LinearSystem, free_mask: np.ndarray, prec: np.ndarray,
            eta: np.ndarray, settings: dict) -> IdentificationResult:
    """The IdentificationResult of the single run of ``batch`` (after :func:`_check_outcome`)."""
    message = _check_outcome(batch, system, free_mask, prec, eta)
    return IdentificationResult(
        parameter_names=parameter_names(system),
        parameters=batch.parameters[0],
        parameter_precision=batch.parameter_precision[0],
        prior_mean=eta,
        prior_precision=prec,
        free=free_mask,
        log_precision=batch.log_precision[0],
        log_precision_precision=batch.log_precision_precision[0],
        free_energy=batch.free_energy[0],
        parameter_history=batch.parameter_history[0],
        precision_history=batch.precision_history[0],
        log_precision_history=batch.log_precision_history[0],
        steps_accepted=dict(zip(("D", "E", "M", "over-relaxed"), (int(v) for v in batch.steps_accepted[0]))),
        converged=bool(batch.converged[0]),
        iterations=int(batch.iterations[0]),
        message=message,
        states=batch.states[0],
        prior_system=system,
        settings=settings,
    )


def _log(system: LinearSystem, outputs, inputs, window: int) -> tuple[np.ndarray, np.ndarray]:
    """outputs (N, m) and inputs (N, r) as float arrays, N at least 3 embedding windows."""
    r, m = system.n_inputs, system.n_outputs
    y = as_matrix(outputs, "outputs", cols=m if np.ndim(outputs) == 2 else 1)
    if y.shape[1] != m:
        raise AttendInputError(f"outputs: expected {m} columns (one per output of the model), got {y.shape[1]}")
    u = as_matrix(inputs, "inputs", cols=r if np.ndim(inputs) == 2 else 1)
    if u.shape != (y.shape[0], r):
        raise AttendInputError(f"inputs: expected shape ({y.shape[0]}, {r}) (one row per output sample), got {u.shape}")
    if y.shape[0] < 3 * window:
        raise AttendInputError(f"outputs: expected at least {3 * window} samples (3 embedding windows), got {y.shape[0]}")
    return y, u


def _parameter_prior(system: LinearSystem, free, prior_precision, free_prior_precision,
                     known_prior_precision) -> tuple[np.ndarray, np.ndarray]:
    """The mask of free entries (default: all of A and B) and P_theta per entry."""
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    names = parameter_names(system)
    free_mask = parameter_array(free, system, "free", bool,
                           default=np.concatenate([np.ones(n * n + n * r, bool), np.zeros(m * n, bool)]))
    free_mask = np.asarray(free_mask, dtype=bool)
    default_prec = np.where(free_mask, float(free_prior_precision), float(known_prior_precision))
    prec = np.asarray(parameter_array(prior_precision, system, "prior_precision", float, default=default_prec), dtype=float)
    if np.any(np.isnan(prec)) or np.any(prec < 0):
        raise AttendInputError("prior_precision: expected precisions >= 0 (inf holds an entry fixed)")
    infinite_free = free_mask & np.isinf(prec)
    if infinite_free.any():
        listed = ", ".join(n_ for n_, f in zip(names, infinite_free) if f)
        raise AttendInputError(
            f"prior_precision: the free entries {listed} have infinite prior precision, so the data "
            "cannot move them: give them a finite prior precision or do not mark them free"
        )
    if not np.isfinite(prec).any():
        raise AttendInputError("prior_precision: every entry is held fixed (inf): there is nothing to learn")
    if not free_mask.any():
        warnings.warn("free: no entry is marked free; only the noise precisions and entries with "
                      "finite prior precision will move", IdentifiabilityWarning, stacklevel=3)
    return free_mask, prec


def _start(system: LinearSystem, y: np.ndarray, initial) -> tuple[np.ndarray, np.ndarray]:
    """eta_theta and the starting theta, once the log is known to move."""
    spread = np.ptp(y, axis=0)
    if np.all(spread <= 1e-12 * max(1.0, float(np.abs(y).max()))):
        raise AttendInputError(
            "outputs: the log has no excitation (every output is constant), so no parameter can be "
            "identified; record a log in which the system moves"
        )
    eta = parameter_vector(system)
    theta0 = eta.copy() if initial is None else np.asarray(parameter_array(initial, system, "initial", float,
                                                                       default=eta), dtype=float)
    if not np.all(np.isfinite(theta0)):
        raise AttendInputError("initial: expected finite starting values")
    return eta, theta0


def _warn_unidentifiable(system: LinearSystem, u: np.ndarray, learn: np.ndarray, theta0: np.ndarray) -> None:
    """IdentifiabilityWarning when the inputs are zero while B is free, when the Markov parameters
    do not determine the learned entries, or when (A, C) is unobservable at the prior."""
    names = parameter_names(system)
    if learn[parameter_slice(system, "B")].any() and np.all(np.abs(u) == 0):
        warnings.warn("inputs: the inputs are identically zero, so the free entries of B are not "
                      "identifiable from this log; they will stay at their prior", IdentifiabilityWarning,
                      stacklevel=3)
    rank = _markov_rank(theta0, system, learn)
    if learn.any() and rank < learn.sum():
        listed = ", ".join(n_ for n_, f in zip(names, learn) if f)
        warnings.warn(
            f"free: the input-output behaviour (Markov parameters C A^k B) determines only {rank} of the "
            f"{int(learn.sum())} free entries ({listed}) near the starting point, e.g. because a change "
            "of state basis leaves it unchanged; the undetermined directions follow the prior",
            IdentifiabilityWarning, stacklevel=3,
        )
    if observability_rank(system.A, system.C) < system.n_states:
        warnings.warn("system_prior: (A, C) is unobservable at the prior mean; some states are not "
                      "recoverable from the outputs", IdentifiabilityWarning, stacklevel=3)


def _check_outcome(batch: BatchLearningResult, system: LinearSystem, free_mask: np.ndarray, prec: np.ndarray,
                   eta: np.ndarray) -> str:
    """Warn about a stopped run, displaced known entries and uninformative logs; the run's message."""
    names = parameter_names(system)
    message = batch.messages[0]
    if message.startswith("stopped:"):
        warnings.warn(message, LearningWarning, stacklevel=4)
    # "known" entries (not free, finite prior precision) that the data moved many prior std away: on long,
    # precise logs exp(15) does not hold them, and moving them can reach a (C, A) with an unobservable
    # mode, where eq. 8's F grows without bound (the state entropy of that mode; package docstring)
    theta_hat = batch.parameters[0]
    held = ~free_mask & np.isfinite(prec) & (prec > 0)
    shift = np.where(held, np.abs(theta_hat - eta) * np.sqrt(np.where(held, prec, 0.0)), 0.0)
    displaced = held & (shift > KNOWN_DISPLACED_STD)
    if displaced.any():
        worst = np.argsort(-shift)[:3]
        listed = ", ".join(f"{names[j]} {eta[j]:.4g} -> {theta_hat[j]:.4g} ({shift[j]:.0f} prior std)"
                           for j in worst if displaced[j])
        note = (f"known entries moved far from their prior means ({listed}): the log outweighs "
                f"known_prior_precision; hold them fixed (known_prior_precision = inf) unless they are meant "
                f"to be learned")
        if not batch.converged[0]:
            message = f"{message}; {note}"
        warnings.warn(note, IdentifiabilityWarning, stacklevel=4)
    learn = free_mask & np.isfinite(prec)
    H_info = np.diag(batch.parameter_precision[0]) - prec
    weak = learn & np.isfinite(H_info) & (H_info <= 1e-9 * np.maximum(1.0, prec))
    if weak.any():
        listed = ", ".join(n_ for n_, f in zip(names, weak) if f)
        warnings.warn(f"the log carries no information about {listed} (posterior precision equals the "
                      "prior precision); their estimates are the prior", IdentifiabilityWarning, stacklevel=4)
    return message


def _markov_rank(theta: np.ndarray, system: LinearSystem, free: np.ndarray) -> int:
    """Rank of d[C A^k B, k = 0..2n-1]/d theta_free at theta: local structural identifiability."""
    n = system.n_states

    def markov(t):
        s = system_from_parameters(t, system)
        blocks, power = [], s.B
        for _ in range(2 * n):
            blocks.append((s.C @ power).ravel())
            power = s.A @ power
        return np.concatenate(blocks)

    idx = np.flatnonzero(free)
    h = 1e-6 * max(1.0, float(np.abs(theta).max()))
    cols = []
    for j in idx:
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        cols.append((markov(tp) - markov(tm)) / (2 * h))
    if not cols:
        return 0
    jac = np.stack(cols, axis=1)
    scale = np.abs(jac).max()
    if scale == 0:
        return 0
    return int(np.linalg.matrix_rank(jac / scale, tol=1e-7))
