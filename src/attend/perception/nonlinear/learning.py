"""Learning the parameters theta and the noise log-precisions of a nonlinear model (DEM's E- and M-steps).

Model: dx/dt = f(x, u, theta) + w, y = g(x, u, theta) + z with measured inputs u (or none),
Pi_z = exp(lambda_z) I_m, Pi_w = exp(lambda_w) I_n, priors theta ~ N(eta_theta, inv(P_theta))
(P_theta diagonal, inf = held fixed) and lambda ~ N(eta_lambda, inv(P_lambda)).

The free energy is the linear learner's sample-mode eq. 8 (:mod:`attend.perception.learning`, top
order truncated) with f, g in place of (A, B, C). Every used sample t (windows inside the log)
has its own generalised state X_t with q(X_t) = N(mu_t, Sigma_t); e_t = [e_y; e_x] are
:meth:`NonlinearDEM.errors` (Jacobians of f, g at order 0 of X_t), E_t = de_t/dX_t, and
Pi = blkdiag(exp(lambda_z) kron(S, I_m), exp(lambda_w) kron(S, I_n))::

    F = -1/2 sum_t [e_t' Pi e_t + tr(Sigma_t E_t' Pi E_t)] + N/2 ln|Pi| + 1/2 sum_t ln|Sigma_t|
        + N dim(X)/2 - 1/2 e_theta' P_theta e_theta - 1/2 ln|Pi_theta inv(P_theta)|
        - 1/2 e_lambda' P_lambda e_lambda - 1/2 ln|Pi_lambda inv(P_lambda)|

(N the number of used samples, e_theta = theta - eta_theta, e_lambda = lambda - eta_lambda).
With rho_t = [U e_t; vec(U E_t L_t)] (U'U = Pi, L_t L_t' = Sigma_t) the expected energy is
sum_t |rho_t|^2, a least-squares problem in theta. Steps (each accepted only if F does not
decrease, else halved up to 6 times):

* D-step: per sample, Gauss-Newton mu_t <- mu_t - inv(E' Pi E) E' Pi e (exact in one step for a
  linear model: the linear learner's D-step), Sigma_t = inv(E_t' Pi E_t). The first D-step
  starts from :class:`NonlinearDEM`'s estimates at the starting (theta, lambda).
* E-step (Gauss-Newton / Laplace): J = d rho / d theta by central differences over theta
  (h_j = 1e-4 max(1, |theta_j|)), Pi_theta = sum_t J_t' J_t + P_theta (the posterior precision),
  theta <- theta + inv(Pi_theta) (-sum_t J_t' rho_t - P_theta e_theta).
* M-step: Newton steps on lambda with the expected (Fisher) curvature
  -N/2 diag(m (p+1), n (p+1)) - P_lambda (as the linear learner; Pi_lambda is this curvature),
  clipped to +-2, up to 8 per iteration; the gradient includes -1/2 tr(Sigma_theta dPi_theta/dlambda).

For a linear f, g this is the F of ``learn_batch`` with ``LearningSettings(top_order="truncate")``
and the two agree (tests/perception/test_nonlinear_learning.py). Unknown inputs (an input prior) are not learned here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from attend._validation import AttendInputError, positive_scalar
from attend.models.generalized import block_precisions, embed
from attend.models.nonlinear import NonlinearSystem
from attend.perception.nonlinear.dem import NonlinearDEM


@dataclass(frozen=True, eq=False)
class ParametrisedSystem:
    """A nonlinear model with parameters: dx/dt = f(x, u, theta), y = g(x, u, theta).

    f, g: functions ``f(x, u, theta)`` -> (n_states,), ``g(x, u, theta)`` -> (n_outputs,) of 1-D
    arrays; n_states, n_inputs, n_outputs: the sizes; parameter_names: one label per entry of
    theta (used in messages); jacobian_f, jacobian_g: optional analytic Jacobians called like f, g
    and returning (d/dx, d/du) (see :class:`NonlinearSystem`).
    """

    f: Callable
    g: Callable
    n_states: int
    n_inputs: int
    n_outputs: int
    parameter_names: tuple[str, ...] = ()
    jacobian_f: Callable | None = None
    jacobian_g: Callable | None = None

    def at(self, theta) -> NonlinearSystem:
        """The :class:`NonlinearSystem` with the parameters held at ``theta`` (1-D array)."""
        return NonlinearSystem(self.f, self.g, self.n_states, self.n_inputs, self.n_outputs,
                               parameters=np.asarray(theta, dtype=float).copy(),
                               jacobian_f=self.jacobian_f, jacobian_g=self.jacobian_g)


class NonlinearLearningResult(NamedTuple):
    """What :func:`learn_nonlinear` found.

    parameters: theta (k,); parameter_precision: Pi_theta (k, k) (fixed entries: inf on the
    diagonal, 0 elsewhere), the Laplace curvature of F that the E-step uses. It is NOT a calibrated
    uncertainty: per-sample states count each datum p + 1 times, and on simulated data the spread of
    theta over seeds is 10-40x sqrt(inv(Pi_theta)) (docs/nonlinear.md); log_precision: [lambda_z, lambda_w]; log_precision_precision:
    Pi_lambda (2,); free_energy: F after each iteration (row 0 = the start); converged: the last
    iteration raised F by less than the tolerance; iterations: how many ran; states: the order-0
    state means (N_used, n) of the used samples; message: how it ended.
    """

    parameters: np.ndarray
    parameter_precision: np.ndarray
    log_precision: np.ndarray
    log_precision_precision: np.ndarray
    free_energy: np.ndarray
    converged: bool
    iterations: int
    states: np.ndarray
    message: str


class _Problem(NamedTuple):
    """The fixed ingredients: the model and settings, the embedded data of the used samples and the priors."""

    model: ParametrisedSystem
    dt: float
    s: float
    p: int
    Y: np.ndarray  # (N, (p+1) m) embedded outputs
    U: np.ndarray  # (N, (p+1) r) embedded inputs
    Uy: np.ndarray  # U'U = kron(S, I_m)
    Uw: np.ndarray  # U'U = kron(S, I_n) (truncate) or kron(S_w, I_n) over orders 0..p-1 (marginal)
    log_det_unit: float  # ln|kron(S, I_m)| + ln|kron(S, I_n)|
    eta: np.ndarray
    P: np.ndarray  # (k,) with inf for fixed
    active: np.ndarray
    eta_lam: np.ndarray
    P_lam: np.ndarray
    fisher: np.ndarray  # (2,) N/2 [m (p+1), n (p+1)]
    raw: tuple  # (outputs (T, m), inputs (T, r)) as given
    used: np.ndarray  # (T,) bool: samples whose embedding window lies inside the log
    motion: str  # NonlinearDEM's motion: "linearized" or "path"


class _Point(NamedTuple):
    """Where the learner stands: q(X), theta, lambda and what F needs there."""

    mu: np.ndarray  # (N, dim X)
    L: np.ndarray  # (N, dim X, dim X) Cholesky factors of Sigma_t
    theta: np.ndarray
    lam: np.ndarray
    energy: np.ndarray  # (2,) unit-precision sensory and motion energies [E_z, E_w]
    rho: tuple  # (rho_z (N, a), rho_w (N, b)) at unit precision
    jac: tuple  # (J_z (N, a, k_active), J_w (N, b, k_active))
    F: float


def _where(problem, theta, iteration, step) -> str:
    """'at theta = [name=value, ...] (step, iteration i)' for messages."""
    names = problem.model.parameter_names or tuple(f"theta{j + 1}" for j in range(len(theta)))
    values = ", ".join(f"{name}={value:.6g}" for name, value in zip(names, np.asarray(theta, dtype=float)))
    return f"at theta = [{values}] ({step}, iteration {iteration})"


def _dem(problem: _Problem, theta) -> NonlinearDEM:
    """NonlinearDEM at theta with unit precisions (its errors(); precisions are applied here)."""
    return NonlinearDEM(problem.model.at(theta), problem.dt, kernel_width=problem.s, sensor_precision=1.0,
                        process_precision=1.0, embedding_order=problem.p, input_order=problem.p, known_inputs=True,
                        motion=problem.motion)


def _errors(problem: _Problem, theta, mu, iteration: int, step: str):
    """(e (N, dim e), E (N, dim e, dim X)) at every used sample; an error naming theta if f/g raise."""
    dem = _dem(problem, theta)
    try:
        pairs = [dem.errors(mu[t], problem.Y[t], problem.U[t])[:2] for t in range(mu.shape[0])]
    except AttendInputError as error:
        raise AttendInputError(f"{error} {_where(problem, theta, iteration, step)}") from None
    return np.array([pair[0] for pair in pairs]), np.array([pair[1] for pair in pairs])


def _residuals(problem: _Problem, theta, mu, L, iteration: int, step: str):
    """Unit-precision residuals rho_z = [Uy e_y; vec(Uy E_y L)], rho_w likewise, per sample."""
    e, E = _errors(problem, theta, mu, iteration, step)
    a = problem.Uy.shape[0]
    EL = E @ L
    rho_z = np.concatenate([e[:, :a] @ problem.Uy.T, (problem.Uy @ EL[:, :a]).reshape(len(e), -1)], axis=1)
    b = a + problem.Uw.shape[0]  # the motion rows that carry precision (marginal: not the top order)
    rho_w = np.concatenate([e[:, a:b] @ problem.Uw.T, (problem.Uw @ EL[:, a:b]).reshape(len(e), -1)], axis=1)
    return rho_z, rho_w


def _evaluate(problem: _Problem, mu, L, theta, lam, iteration: int, step: str) -> _Point:
    """The point (mu, L, theta, lambda) with its residuals, their theta-Jacobian (central
    differences over the active entries) and F; F = -inf where anything is not finite."""
    rho = _residuals(problem, theta, mu, L, iteration, step)
    columns_z, columns_w = [], []
    for j in np.flatnonzero(problem.active):
        h = 1e-4 * max(1.0, abs(theta[j]))
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        rz_up, rw_up = _residuals(problem, up, mu, L, iteration, step)
        rz_down, rw_down = _residuals(problem, down, mu, L, iteration, step)
        columns_z.append((rz_up - rz_down) / (2 * h))
        columns_w.append((rw_up - rw_down) / (2 * h))
    jac = tuple(np.stack(c, axis=2) if c else np.zeros(r.shape + (0,)) for c, r in zip((columns_z, columns_w), rho))
    energy = np.array([np.sum(rho[0] ** 2), np.sum(rho[1] ** 2)])
    point = _Point(mu, L, theta, lam, energy, rho, jac, -np.inf)
    return point._replace(F=_free_energy(problem, point, lam))


def _posterior_precision(problem: _Problem, point: _Point, lam) -> np.ndarray:
    """Pi_theta = exp(lambda_z) sum J_z'J_z + exp(lambda_w) sum J_w'J_w + P_theta (active entries)."""
    Jz, Jw = point.jac
    Hz = np.einsum("tai,taj->ij", Jz, Jz)
    Hw = np.einsum("tai,taj->ij", Jw, Jw)
    return np.exp(lam[0]) * Hz + np.exp(lam[1]) * Hw + np.diag(problem.P[problem.active])


def _free_energy(problem: _Problem, point: _Point, lam) -> float:
    """F of the module docstring at the point, with the noise log-precisions ``lam``."""
    N, dim_x = point.mu.shape
    if not (np.all(np.isfinite(point.energy)) and all(np.all(np.isfinite(J)) for J in point.jac)):
        return -np.inf
    fisher_dims = problem.fisher * 2.0 / N  # [m (p+1), n (p+1)]
    F = -0.5 * (np.exp(lam[0]) * point.energy[0] + np.exp(lam[1]) * point.energy[1])
    F += 0.5 * N * (fisher_dims @ lam + problem.log_det_unit)
    F += float(np.sum(np.log(np.abs(np.diagonal(point.L, axis1=1, axis2=2))))) + 0.5 * N * dim_x
    act = problem.active
    e_theta = point.theta[act] - problem.eta[act]
    F -= 0.5 * float(np.sum(problem.P[act] * e_theta**2))
    sign, log_det = np.linalg.slogdet(_posterior_precision(problem, point, lam))
    if sign <= 0:
        return -np.inf
    F -= 0.5 * (log_det - float(np.sum(np.log(problem.P[act][problem.P[act] > 0]))))
    free = np.isfinite(problem.P_lam)
    e_lam = (lam - problem.eta_lam)[free]
    F -= 0.5 * float(np.sum(problem.P_lam[free] * e_lam**2))
    proper = free & (problem.P_lam > 0)
    F -= 0.5 * float(np.sum(np.log((problem.fisher[proper] + problem.P_lam[proper]) / problem.P_lam[proper])))
    return float(F) if np.isfinite(F) else -np.inf


def _gauss_newton_states(problem: _Problem, theta, lam, mu, iterations: int, iteration: int):
    """Per-sample Gauss-Newton on e' Pi e from mu; returns (mu, Cholesky factors of inv(E' Pi E))."""
    a, b = problem.Uy.shape[0], problem.Uw.shape[0]
    Wz, Ww = problem.Uy.T @ problem.Uy, problem.Uw.T @ problem.Uw
    Pi = np.zeros((a + problem.model.n_states * (problem.p + 1),) * 2)
    Pi[:a, :a] = np.exp(lam[0]) * Wz
    Pi[a:a + b, a:a + b] = np.exp(lam[1]) * Ww
    for _ in range(iterations + 1):
        e, E = _errors(problem, theta, mu, iteration, "D-step")
        EtPi = np.swapaxes(E, 1, 2) @ Pi
        curvature = EtPi @ E
        curvature = 0.5 * (curvature + np.swapaxes(curvature, 1, 2))
        if _ == iterations:
            break
        step = np.linalg.solve(curvature, (EtPi @ e[:, :, None]))[:, :, 0]
        mu = mu - step
    try:
        L = np.linalg.cholesky(np.linalg.inv(curvature))
    except np.linalg.LinAlgError:
        raise AttendInputError(f"D-step: the state precision E' Pi E is not positive definite "
                               f"{_where(problem, theta, iteration, 'D-step')}; the states are not observable") from None
    return mu, L


def _d_step(problem, point: _Point, iterations: int, iteration: int) -> _Point:
    """D-step: move q(X) towards the per-sample Gauss-Newton optimum, halved until F does not fall."""
    target, _ = _gauss_newton_states(problem, point.theta, point.lam, point.mu, iterations, iteration)
    alpha = 1.0
    for _ in range(6):
        mu_c = point.mu + alpha * (target - point.mu)
        mu_c, L_c = _gauss_newton_states(problem, point.theta, point.lam, mu_c, 0, iteration)
        candidate = _evaluate(problem, mu_c, L_c, point.theta, point.lam, iteration, "D-step")
        if candidate.F >= point.F:
            return candidate
        alpha *= 0.5
    return point


def _e_step(problem, point: _Point, iteration: int) -> _Point:
    """E-step: the Gauss-Newton step in theta (q(X), lambda fixed), halved until F does not fall;
    an error naming theta if every trial gives a non-finite F."""
    act = problem.active
    if not act.any():
        return point
    lam = point.lam
    Jz, Jw = point.jac
    gradient = -(np.exp(lam[0]) * np.einsum("tai,ta->i", Jz, point.rho[0])
                 + np.exp(lam[1]) * np.einsum("tai,ta->i", Jw, point.rho[1]))
    gradient -= problem.P[act] * (point.theta[act] - problem.eta[act])
    step = np.linalg.solve(_posterior_precision(problem, point, lam), gradient)
    any_finite = False
    for _ in range(7):
        theta_c = point.theta.copy()
        theta_c[act] += step
        candidate = _evaluate(problem, point.mu, point.L, theta_c, lam, iteration, "E-step")
        any_finite |= np.isfinite(candidate.F)
        if candidate.F >= point.F:
            return candidate
        step = step * 0.5
    if not any_finite:
        raise AttendInputError(f"f/g: non-finite values or free energy for every trial step "
                               f"{_where(problem, point.theta, iteration, 'E-step')}")
    return point


def _overrelax(problem, point: _Point, before: _Point, beta: float, state_iterations: int, iteration: int):
    """Over-relaxation: the sweep's move in (theta, lambda) since ``before`` extended beta times (lambda's
    clipped to +-2), with a D-step there; if F does not rise, the same with lambda held (the
    joint extension alone left the Lorenz runs with lambda learned creeping: rho 24 after 50
    iterations instead of 28 after 23; theta alone left the linear oracle creeping in lambda_w).
    Returns the point and the next beta (doubled after a success, up to 64; 1 after a failure)."""
    theta_c = point.theta + beta * (point.theta - before.theta)
    for lam_c in (point.lam + np.clip(beta * (point.lam - before.lam), -2.0, 2.0), point.lam):
        try:
            mu_c, L_c = _gauss_newton_states(problem, theta_c, lam_c, point.mu, state_iterations, iteration)
            candidate = _evaluate(problem, mu_c, L_c, theta_c, lam_c, iteration, "over-relaxation")
        except (AttendInputError, np.linalg.LinAlgError):  # an extrapolated theta outside f's domain: not taken
            return point, 1.0
        if np.isfinite(candidate.F) and candidate.F > point.F and np.all(np.isfinite(mu_c)):
            return candidate, min(2.0 * beta, 64.0)
        if np.array_equal(point.lam, before.lam):
            break
    return point, 1.0


def _m_step(problem, point: _Point, iterations: int) -> _Point:
    """M-step: Newton steps on lambda with the Fisher curvature, clipped to +-2, halved until F does not fall."""
    free = np.isfinite(problem.P_lam)
    curvature = -(problem.fisher + np.where(free, problem.P_lam, 0.0))
    Jz, Jw = point.jac
    Hz = np.einsum("tai,taj->ij", Jz, Jz)
    Hw = np.einsum("tai,taj->ij", Jw, Jw)
    for _ in range(iterations):
        lam = point.lam
        Sigma_theta = np.linalg.inv(_posterior_precision(problem, point, lam))
        gradient = problem.fisher - 0.5 * np.exp(lam) * (point.energy + np.array(
            [np.sum(Sigma_theta * Hz), np.sum(Sigma_theta * Hw)]))
        gradient -= np.where(free, np.where(free, problem.P_lam, 0.0) * (lam - problem.eta_lam), 0.0)
        step = np.where(free, np.clip(-gradient / curvature, -2.0, 2.0), 0.0)
        if np.abs(step).max() < 1e-6:
            break
        moved = False
        for _ in range(6):
            F_c = _free_energy(problem, point, lam + step)
            if F_c >= point.F:
                point = point._replace(lam=lam + step, F=F_c)
                moved = True
                break
            step = step * 0.5
        if not moved:
            break
    return point


def learn_nonlinear(model: ParametrisedSystem, outputs, inputs, dt: float, *, kernel_width: float, prior_mean,
                    prior_precision, initial=None, noise_prior_mean=(0.0, 0.0), noise_prior_precision=(1.0, 1.0),
                    embedding_order: int = 6, max_iterations: int = 50, tolerance: float = 1e-3,
                    state_iterations: int = 3, top_order: str = "marginal",
                    overrelax: bool = True, motion: str = "linearized") -> NonlinearLearningResult:
    """Alternating D-, E- and M-steps on the free energy of the module docstring, until an
    iteration raises F by less than ``tolerance`` [nats] or ``max_iterations`` have run.

    model: the :class:`ParametrisedSystem`; outputs (N, m) and inputs (N, r) (None when r = 0)
    sampled at dt [s]; kernel_width: s of the noise kernel [s]; prior_mean eta_theta and
    prior_precision P_theta (k,) (P_theta = inf holds an entry at its prior mean, 0 is flat);
    initial: the starting theta (default eta_theta); noise_prior_mean eta_lambda and
    noise_prior_precision P_lambda (2,) for [lambda_z, lambda_w] (inf holds lambda fixed; the
    start is eta_lambda); embedding_order: p; state_iterations: Gauss-Newton iterations per
    sample in each D-step; top_order: "marginal" (default, the linear learner's sample mode: the
    top-order motion error is integrated out, W = kron(S_w, I_n) over orders 0..p-1) or
    "truncate" (eq. 8 as published: x^(p+1) = 0 with all p + 1 orders weighted); overrelax: after
    each sweep try its move extended beta times (the linear learner's option 3,
    module docstring); motion: how f~, g~ are formed (:class:`NonlinearDEM`'s ``motion``:
    "linearized", SPM's Jacobians held at order 0, or "path", which keeps the curvature terms). Raises AttendInputError on bad shapes or values, and naming theta and
    the iteration when f or g raise at a theta or give a non-finite free energy there.
    """
    problem, theta0 = _setup(model, outputs, inputs, dt, kernel_width, prior_mean, prior_precision, initial,
                             noise_prior_mean, noise_prior_precision, embedding_order, top_order, motion)
    point = _start(problem, theta0, state_iterations)
    history, beta = [point.F], 1.0
    converged, iteration, message = False, 0, f"stopped after max_iterations = {max_iterations} (not converged)"
    for iteration in range(1, int(max_iterations) + 1):
        before, start_of_sweep = point.F, point
        point = _d_step(problem, point, state_iterations, iteration)
        point = _e_step(problem, point, iteration)
        point = _m_step(problem, point, 8)
        if overrelax:
            point, beta = _overrelax(problem, point, start_of_sweep, beta, state_iterations, iteration)
        history.append(point.F)
        if point.F - before < tolerance:
            converged = True
            message = f"converged at iteration {iteration} (free energy rose by {point.F - before:.3g} < {tolerance:g})"
            break
    return _result(problem, point, history, converged, iteration, message)


def _start(problem: _Problem, theta0: np.ndarray, state_iterations: int) -> _Point:
    """The first D-step: NonlinearDEM's estimates at (theta0, eta_lambda), refined per sample; F there."""
    lam = problem.eta_lam.copy()
    system = problem.model.at(theta0)
    dem = NonlinearDEM(system, problem.dt, kernel_width=problem.s, sensor_precision=np.exp(lam[0]),
                       process_precision=np.exp(lam[1]), embedding_order=problem.p, input_order=problem.p,
                       known_inputs=True, motion=problem.motion)
    try:
        signals = dem.checked_signals(problem.raw[0], problem.raw[1] if problem.model.n_inputs else None)
        estimate = dem.dstep_estimate(signals, True, None, check=False)  # (no misfit check at the start's theta)
    except AttendInputError as error:
        raise AttendInputError(f"{error} {_where(problem, theta0, 0, 'start')}") from None
    mu = estimate.generalized[problem.used]
    mu, L = _gauss_newton_states(problem, theta0, lam, mu, state_iterations, 0)
    point = _evaluate(problem, mu, L, theta0, lam, 0, "start")
    if not np.isfinite(point.F):
        raise AttendInputError(f"learn_nonlinear: the free energy is not finite {_where(problem, theta0, 0, 'start')}")
    return point


def _result(problem: _Problem, point: _Point, history, converged: bool, iteration: int,
            message: str) -> NonlinearLearningResult:
    """Pack the final point (fixed entries of Pi_theta: inf on the diagonal)."""
    k = problem.eta.shape[0]
    Pi = np.zeros((k, k))
    idx = np.flatnonzero(problem.active)
    Pi[idx[:, None], idx[None, :]] = _posterior_precision(problem, point, point.lam)
    for j in np.flatnonzero(~problem.active):
        Pi[j, j] = np.inf
    n = problem.model.n_states
    return NonlinearLearningResult(point.theta.copy(), Pi, point.lam.copy(),
                                   problem.fisher + np.where(np.isfinite(problem.P_lam), problem.P_lam, np.inf),
                                   np.array(history), converged, iteration, point.mu[:, :n].copy(), message)


def _vector(value, size: int, name: str, allow_inf: bool = False) -> np.ndarray:
    """A 1-D float array of ``size`` entries (finite, or +inf where allowed)."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise AttendInputError(f"{name}: expected {size} numbers, got {value!r}") from None
    if array.ndim == 0:
        array = np.full(size, float(array))
    if array.shape != (size,):
        raise AttendInputError(f"{name}: expected shape ({size},), got {array.shape}")
    bad = np.isnan(array) | (np.isinf(array) if not allow_inf else np.isneginf(array))
    if bad.any():
        raise AttendInputError(f"{name}: entry {int(np.flatnonzero(bad)[0])} is {array[bad][0]} (expected finite)")
    if allow_inf and np.any(array < 0):
        raise AttendInputError(f"{name}: precisions must be >= 0, got {array.min()}")
    return array


def _setup(model, outputs, inputs, dt, kernel_width, prior_mean, prior_precision, initial, noise_prior_mean,
           noise_prior_precision, embedding_order, top_order, motion):
    """Validate the arguments of :func:`learn_nonlinear`; the :class:`_Problem` and the starting theta."""
    if top_order not in ("marginal", "truncate"):
        raise AttendInputError(f"top_order: expected 'marginal' or 'truncate', got {top_order!r}")
    if motion not in ("linearized", "path"):
        raise AttendInputError(f"motion: expected 'linearized' or 'path', got {motion!r}")
    if not isinstance(model, ParametrisedSystem):
        raise AttendInputError("model: expected an attend ParametrisedSystem (f(x, u, theta), g(x, u, theta), sizes)")
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    p = embedding_order
    if isinstance(p, bool) or not isinstance(p, (int, np.integer)) or not 0 <= p <= 12:
        raise AttendInputError(f"embedding_order: expected an integer in 0..12, got {p!r}")
    n, r, m = model.n_states, model.n_inputs, model.n_outputs
    y = np.asarray(outputs, dtype=float)
    y = y[:, None] if y.ndim == 1 and m == 1 else y
    if y.ndim != 2 or y.shape[1] != m:
        raise AttendInputError(f"outputs: expected shape (N, {m}), got {y.shape}")
    u = np.zeros((y.shape[0], 0)) if inputs is None and r == 0 else np.asarray(inputs, dtype=float)
    u = u[:, None] if u.ndim == 1 and r == 1 else u
    if u.shape != (y.shape[0], r):
        raise AttendInputError(f"inputs: expected shape ({y.shape[0]}, {r}), got {u.shape}")
    for name, array in (("outputs", y), ("inputs", u)):
        if not np.all(np.isfinite(array)):
            raise AttendInputError(f"{name}: non-finite value at sample {int(np.argwhere(~np.isfinite(array))[0, 0])}")
    reach = (p + 1) // 2
    if y.shape[0] < 2 * reach + 2:
        raise AttendInputError(f"outputs: expected at least {2 * reach + 2} samples for embedding_order {p}, "
                               f"got {y.shape[0]}")
    eta = _vector(prior_mean, len(np.atleast_1d(prior_mean)), "prior_mean")
    k = eta.shape[0]
    if model.parameter_names and len(model.parameter_names) != k:
        raise AttendInputError(f"parameter_names: expected {k} names (one per entry of prior_mean), "
                               f"got {len(model.parameter_names)}")
    P = _vector(prior_precision, k, "prior_precision", allow_inf=True)
    theta0 = eta.copy() if initial is None else _vector(initial, k, "initial")
    active = np.isfinite(P)
    theta0[~active] = eta[~active]
    eta_lam = _vector(noise_prior_mean, 2, "noise_prior_mean")
    P_lam = _vector(noise_prior_precision, 2, "noise_prior_precision", allow_inf=True)
    used = np.zeros(y.shape[0], dtype=bool)
    used[reach: y.shape[0] - reach] = True
    S, _ = block_precisions(p, p, s, "size")
    Vy, W = np.kron(S, np.eye(m)), np.kron(_motion_precision(S, top_order), np.eye(n))
    Y = embed(y, p + 1, dt, edges="clamp")[used]
    U = embed(u, p + 1, dt, edges="clamp")[used] if r else np.zeros((int(used.sum()), 0))
    N = int(used.sum())
    problem = _Problem(model, dt, s, p, Y, U, np.linalg.cholesky(Vy).T, np.linalg.cholesky(W).T,
                       float(np.linalg.slogdet(Vy)[1] + np.linalg.slogdet(W)[1]), eta, P, active, eta_lam, P_lam,
                       0.5 * N * np.array([m * (p + 1), W.shape[0]], dtype=float), (y, u), used, motion)
    return problem, theta0


def _motion_precision(S: np.ndarray, top_order: str) -> np.ndarray:
    """The temporal precision of the motion error: S (truncate), or over orders 0..p-1 the Schur
    complement S_w = S[:p, :p] - S[:p, p] S[p, :p] / S[p, p] (marginal: x^(p+1) integrated out)."""
    if top_order == "truncate" or S.shape[0] == 1:
        return S
    top = S[:-1, -1:]
    return S[:-1, :-1] - top @ top.T / S[-1, -1]
