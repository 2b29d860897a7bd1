"""Learning theta in path mode: the trajectory and the parameters together, with calibrated error bars.

Path mode (:mod:`attend.perception.nonlinear.path`) ties the generalised states to one sampled
trajectory z (states, and unknown inputs under their prior). Here the parameters theta of
f(x, v, theta), g(x, v, theta) join z, and the noise precisions are given (known)::

    -F(z, theta) = 1/(p+1) * 1/2 sum_c e_c(z, theta)' Pi~ e_c(z, theta)
                   + 1/2 (theta - eta_theta)' P_theta (theta - eta_theta)

Each datum enters p + 1 windows, so the window sum is weighted by 1/(p + 1), as in the linear
learner's path mode; then the prior weighs against the data once. The maximiser is found by
Levenberg-Marquardt on (z, theta): J_z as in path mode, J_theta by central differences over theta,
and the joint curvature [[H_zz, H_ztheta], [H_thetaz, H_thetatheta]] solved through the Schur
complement of the block-tridiagonal H_zz (O(N k^2)).

Error bars: the estimator's spread under the generative model, linearised at the estimate (the
same sandwich as path mode's states): [z, theta]_hat - [z, theta] = -inv(H) (g_noise + g_prior)
with g_noise = 1/(p+1) sum_c J_c' Pi~ eps_c (eps_c the embedded coloured noises, drawn
``uncertainty_draws`` times) and g_prior = P_theta (theta - eta_theta), theta drawn from its prior
(``parameter_covariance`` is that of the estimation error theta_hat - theta).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from attend._threads import single_blas_thread
from attend._validation import AttendInputError, positive_scalar
from attend.perception.nonlinear.dem import NonlinearDEM
from attend.perception import block_tridiagonal
from attend.perception.nonlinear.path import _accumulate, _errors, _noise_draws, _Problem, _solve


class PathLearningResult(NamedTuple):
    """What :func:`learn_path` found.

    parameters: theta (k,); parameter_std (k,) and parameter_covariance (k, k): the spread of
    theta_hat - theta (module docstring; 0 for fixed entries); states (N, n), state_std (N, n),
    inputs (N, r) and input_std (N, r) (the given inputs and 0 when known); cost: -F after each
    iteration (row 0 = the start); converged; iterations; message: how it ended.
    """

    parameters: np.ndarray
    parameter_std: np.ndarray
    parameter_covariance: np.ndarray
    states: np.ndarray
    state_std: np.ndarray
    inputs: np.ndarray
    input_std: np.ndarray
    cost: np.ndarray
    converged: bool
    iterations: int
    message: str


@dataclass
class _Joint:
    """The path problem at one theta with what the joint step needs (module docstring)."""

    problem: _Problem
    theta: np.ndarray
    cost: float
    Dg: np.ndarray
    Off: np.ndarray
    gradient_z: np.ndarray  # (K, b)
    coupling: np.ndarray  # H_z,theta (k, K, b)
    H_theta: np.ndarray  # (k, k)
    gradient_theta: np.ndarray  # (k,)


class _Setup(NamedTuple):
    model: object
    build: object  # theta -> NonlinearDEM
    y: np.ndarray
    u: np.ndarray
    eta: np.ndarray
    P: np.ndarray
    active: np.ndarray
    weight: float  # 1 / (p + 1)


def _theta_steps(theta, active):
    """Central-difference steps h_j = 1e-4 max(1, |theta_j|) of the active entries."""
    return {j: 1e-4 * max(1.0, abs(theta[j])) for j in np.flatnonzero(active)}


def _joint(setup: _Setup, z: np.ndarray, theta: np.ndarray) -> _Joint:
    """-F, gradients and Gauss-Newton curvature of (z, theta) (module docstring)."""
    problem = _Problem(setup.build(theta), setup.y, setup.u)
    layout = problem.layout
    steps = _theta_steps(theta, setup.active)
    shifted = {}
    for j, h in steps.items():
        for sign in (1, -1):
            moved = theta.copy()
            moved[j] += sign * h
            shifted[j, sign] = setup.build(moved)
    k, b, K = len(steps), layout.W * layout.q, layout.n_blocks
    Dg, Off, rhs = np.zeros((K, b, b)), np.zeros((K - 1, b, b)), np.zeros((K, b, 1 + k))
    H_theta, gradient_theta, total = np.zeros((k, k)), np.zeros(k), 0.0
    w = setup.weight
    for part in problem.chunks():
        starts = layout.starts[part]
        data = (problem.y_tilde[part], problem.u_tilde[part], starts)
        e, J = _errors(problem.dem, layout, z, data[0], data[1], starts, jacobians=True)
        J_theta = np.zeros(e.shape + (k,))
        for i, (j, h) in enumerate(steps.items()):
            up = _errors(shifted[j, 1], layout, z, *data, jacobians=False)[0]
            down = _errors(shifted[j, -1], layout, z, *data, jacobians=False)[0]
            J_theta[:, :, i] = (up - down) / (2 * h)
        weighted = layout.precision @ J  # Pi~ J_c
        weighted_theta = layout.precision @ J_theta
        total += 0.5 * w * np.einsum("ci,ij,cj->", e, layout.precision, e)
        vectors = np.concatenate([np.einsum("cia,ci->ca", weighted, e)[:, :, None],
                                  np.swapaxes(J, 1, 2) @ weighted_theta], axis=2)
        _accumulate(layout, starts, w * (np.swapaxes(J, 1, 2) @ weighted), w * vectors, Dg, Off, rhs)
        H_theta += w * np.einsum("cia,cib->ab", J_theta, weighted_theta)
        gradient_theta += w * np.einsum("cia,ci->a", weighted_theta, e)
    uncovered = np.flatnonzero(np.einsum("kii->ki", Dg).ravel() == 0)
    Dg.reshape(K, b * b)[uncovered // b, (uncovered % b) * (b + 1)] = 1.0
    act = setup.active
    e_theta = theta[act] - setup.eta[act]
    total += 0.5 * float(np.sum(setup.P[act] * e_theta**2))
    return _Joint(problem, theta, total, Dg, Off, rhs[:, :, 0], np.moveaxis(rhs[:, :, 1:], 2, 0),
                  H_theta + np.diag(setup.P[act]), gradient_theta + setup.P[act] * e_theta)


def _joint_solve(joint: _Joint, rhs_z: np.ndarray, rhs_theta: np.ndarray, damping: float):
    """Solve the (damped) joint system [[H_zz, H_zt], [H_tz, H_tt]] [dz; dt] = [rhs_z; rhs_theta]
    by the Schur complement; rhs_z (R, K, b), rhs_theta (R, k). None if not positive definite."""
    k = joint.H_theta.shape[0]
    solved = _solve(joint.Dg, joint.Off, np.concatenate([rhs_z, joint.coupling]), damping)
    if solved is None:
        return None
    R = rhs_z.shape[0]
    inv_rhs, inv_coupling = solved[:R], solved[R:]  # H_zz^{-1} rhs_z, H_zz^{-1} H_zt
    schur = joint.H_theta * (1.0 + damping * np.eye(k)) - np.einsum("ikb,jkb->ij", joint.coupling, inv_coupling)
    try:
        d_theta = np.linalg.solve(schur, (rhs_theta - np.einsum("ikb,rkb->ri", joint.coupling, inv_rhs)).T).T
    except np.linalg.LinAlgError:
        return None
    d_z = inv_rhs - np.einsum("ikb,ri->rkb", inv_coupling, d_theta)
    return d_z, d_theta


def _window_covariances(problem: _Problem, Dg, Off, weight: float) -> np.ndarray:
    """Cov of each window's samples (C, Wq, Wq) under q(z) = N(z_hat, inv(weight H_zz)), from the
    selected inverse of the block-tridiagonal H_zz (:func:`block_tridiagonal.selected_inverse`)."""
    layout = problem.layout
    W, q = layout.W, layout.q
    b = W * q
    _, Bk, Linv = block_tridiagonal.cholesky(Dg[None], Off[None])
    Sd, Su = (part[0] / weight for part in block_tridiagonal.selected_inverse(Linv, Bk))
    starts = layout.starts
    block_of, offset_of = starts // W, starts % W
    out = np.empty((len(starts), b, b))
    for offset in range(W):
        chosen = offset_of == offset
        k = block_of[chosen]
        pair = np.zeros((len(k), 2 * b, 2 * b))
        pair[:, :b, :b], pair[:, b:, b:] = Sd[k], Sd[k + 1]
        pair[:, :b, b:] = Su[k]
        pair[:, b:, :b] = np.swapaxes(Su[k], 1, 2)
        rows = slice(offset * q, (offset + W) * q)
        out[chosen] = pair[:, rows, rows]
    return out


def _expected_residuals(setup: _Setup, dem, problem: _Problem, z, roots) -> np.ndarray:
    """rho_c = [U e_c; vec(U J_c L_c)] (C, n_e (1 + Wq)) at the model ``dem``: |rho_c|^2 is
    E_q[e_c' Pi~ e_c] to second order (U'U = Pi~, L_c L_c' = the window's covariance)."""
    layout = problem.layout
    U = np.linalg.cholesky(layout.precision).T
    out = []
    for part in problem.chunks():
        e, J = _errors(dem, layout, z, problem.y_tilde[part], problem.u_tilde[part], layout.starts[part], True)
        out.append(np.concatenate([e @ U.T, (U @ J @ roots[part]).reshape(len(e), -1)], axis=1))
    return np.concatenate(out)


def _expected_energy(setup: _Setup, rho, theta) -> float:
    """w sum_c |rho_c|^2 / 2 + the prior's energy: the theta-dependent part of -F at fixed q(z)."""
    act = setup.active
    return 0.5 * setup.weight * float(np.sum(rho**2)) + 0.5 * float(np.sum(setup.P[act] * (theta - setup.eta)[act] ** 2))


def _e_step(setup: _Setup, problem: _Problem, z, roots, theta):
    """One Gauss-Newton step in theta on the expected energy (q(z) fixed), halved until it falls;
    returns (theta, energy)."""
    act = setup.active
    rho = _expected_residuals(setup, setup.build(theta), problem, z, roots)
    energy = _expected_energy(setup, rho, theta)
    columns = []
    for j, h in _theta_steps(theta, act).items():
        pair = []
        for sign in (1, -1):
            moved = theta.copy()
            moved[j] += sign * h
            pair.append(_expected_residuals(setup, setup.build(moved), problem, z, roots))
        columns.append((pair[0] - pair[1]) / (2 * h))
    R = np.stack(columns, axis=2)  # (C, n_rho, k)
    curvature = setup.weight * np.einsum("cia,cib->ab", R, R) + np.diag(setup.P[act])
    gradient = setup.weight * np.einsum("cia,ci->a", R, rho) + setup.P[act] * (theta - setup.eta)[act]
    step = -np.linalg.solve(curvature, gradient)
    for _ in range(8):
        candidate = theta.copy()
        candidate[act] += step
        try:
            trial = _expected_energy(setup, _expected_residuals(setup, setup.build(candidate), problem, z, roots),
                                     candidate)
        except AttendInputError:
            trial = np.inf
        if trial <= energy:
            return candidate, trial, np.sqrt(np.diag(np.linalg.inv(curvature)))
        step = step / 2
    return theta, energy, np.sqrt(np.diag(np.linalg.inv(curvature)))


def _optimise(setup: _Setup, z, theta, max_iterations: int, tolerance: float):
    """Alternate the path D-step (z at theta, q(z) from its curvature) and the E-step (theta on
    the expected energy) until theta moves by less than ``tolerance`` of its Laplace std.
    Returns (z, theta, energy history, converged, iterations)."""
    from attend.perception.nonlinear.path import _optimise as d_step

    history = []
    for iteration in range(1, max_iterations + 1):
        problem = _Problem(setup.build(theta), setup.y, setup.u)
        z, (Dg, Off), _, _ = d_step(problem, z, 50, 1e-10)
        roots = np.linalg.cholesky(_window_covariances(problem, Dg, Off, setup.weight))
        new_theta, energy, laplace_std = _e_step(setup, problem, z, roots, theta)
        history.append(energy)
        moved = np.abs(new_theta - theta)[setup.active]
        theta = new_theta
        if np.all(moved <= tolerance * laplace_std):
            return z, theta, history, True, iteration
    return z, theta, history, False, max_iterations


def _spread(setup: _Setup, joint: _Joint, z, draws: int, seed):
    """(parameter covariance (k, k), z std (N, q)) of the estimation error (module docstring)."""
    problem, layout = joint.problem, joint.problem.layout
    rng = np.random.default_rng(seed)
    act = setup.active
    k, b, K = int(act.sum()), layout.W * layout.q, layout.n_blocks
    theta_errors, z_square = [], np.zeros((K, b))
    batch = max(1, min(draws, int(2e6 // max(1, problem.n_samples * (layout.q + 4)))))
    done = 0
    while done < draws:
        count = min(batch, draws - done)
        eps = _noise_draws(problem.dem, layout, problem.n_samples, count, rng)
        rhs_z, rhs_theta = np.zeros((K, b, count)), np.zeros((count, k))
        for part in problem.chunks():
            starts = layout.starts[part]
            e, J = _errors(problem.dem, layout, z, problem.y_tilde[part], problem.u_tilde[part], starts, True)
            _accumulate(layout, starts, None, setup.weight * np.einsum("cia,rci->car", layout.precision @ J,
                                                                       eps[:, part]), None, None, rhs_z)
            J_theta = _theta_jacobian(setup, joint, z, part)
            rhs_theta += setup.weight * np.einsum("cia,rci->ra", layout.precision @ J_theta, eps[:, part])
        prior_draw = rng.standard_normal((count, k)) * np.sqrt(np.where(setup.P[act] > 0, setup.P[act], 0.0))
        step = _joint_solve(joint, -np.moveaxis(rhs_z, 2, 0), -(rhs_theta + prior_draw), 0.0)
        if step is None:
            raise AttendInputError("learn_path: the joint curvature is not positive definite at the estimate; "
                                   "theta is not identifiable from this log (fix some entries or add a prior)")
        z_square += np.sum(step[0] ** 2, axis=0)
        theta_errors.append(step[1])
        done += count
    theta_errors = np.concatenate(theta_errors)
    covariance = theta_errors.T @ theta_errors / draws
    return covariance, np.sqrt(z_square / draws).reshape(-1, layout.q)[: problem.n_samples]


def _theta_jacobian(setup: _Setup, joint: _Joint, z, part) -> np.ndarray:
    """de_c/dtheta (C, n_e, k) of the windows in ``part`` by central differences."""
    problem, layout = joint.problem, joint.problem.layout
    starts = layout.starts[part]
    columns = []
    for j, h in _theta_steps(joint.theta, setup.active).items():
        pair = []
        for sign in (1, -1):
            moved = joint.theta.copy()
            moved[j] += sign * h
            pair.append(_errors(setup.build(moved), layout, z, problem.y_tilde[part], problem.u_tilde[part],
                                starts, False)[0])
        columns.append((pair[0] - pair[1]) / (2 * h))
    return np.stack(columns, axis=2) if columns else np.zeros((len(starts), layout.precision.shape[0], 0))


def learn_path(model, outputs, inputs, dt: float, *, kernel_width: float, sensor_precision, process_precision,
               prior_mean, prior_precision, initial=None, input_prior_precision=None, embedding_order: int = 6,
               input_order: int = 2, input_kernel_width: float | None = None, max_iterations: int = 50,
               tolerance: float = 1e-3, uncertainty_draws: int = 200, seed: int = 0,
               motion: str = "path") -> PathLearningResult:
    """theta, the trajectory and their error bars by path mode (module docstring).

    model: a :class:`~attend.perception.nonlinear.ParametrisedSystem`; outputs (N, m) sampled at
    dt [s]; inputs (N, r): the measured inputs, or with ``input_prior_precision`` the prior mean
    of unknown inputs (None: zeros; r = 0: None); kernel_width: s [s]; sensor_precision Pi_z and
    process_precision Pi_w (known: scalar, per-row or matrix, as for NonlinearDEM);
    prior_mean eta_theta and prior_precision P_theta (k,) (inf holds an entry, 0 is flat);
    initial: the starting theta (default eta_theta); input_prior_precision: P_v of unknown
    inputs (None: the inputs are measured); embedding_order: p; input_order: d;
    input_kernel_width: s_v [s] (default s); max_iterations, tolerance: the Levenberg-Marquardt
    stop (-F falls by less than this fraction); uncertainty_draws: noise draws of the error bars;
    seed: of those draws. Raises AttendInputError on bad input, and when theta is not
    identifiable at the estimate.
    """
    from attend.perception.nonlinear.learning import ParametrisedSystem, _vector

    if not isinstance(model, ParametrisedSystem):
        raise AttendInputError("model: expected an attend ParametrisedSystem (f(x, u, theta), g(x, u, theta), sizes)")
    eta = _vector(prior_mean, len(np.atleast_1d(prior_mean)), "prior_mean")
    P = _vector(prior_precision, eta.shape[0], "prior_precision", allow_inf=True)
    theta = eta.copy() if initial is None else _vector(initial, eta.shape[0], "initial")
    active = np.isfinite(P)
    theta[~active] = eta[~active]
    positive_scalar(dt, "dt", "s")
    unknown = input_prior_precision is not None and model.n_inputs > 0
    if model.n_inputs > 0 and not unknown and inputs is None:
        raise AttendInputError("inputs: the model has inputs; pass the measured inputs, or input_prior_precision "
                               "for unknown inputs")

    def build(values):
        return NonlinearDEM(model.at(values), dt, kernel_width, sensor_precision, process_precision,
                            input_prior_precision if unknown else None, embedding_order, input_order,
                            known_inputs=not unknown, input_kernel_width=input_kernel_width if unknown else None,
                            motion=motion)

    dem = build(theta)
    signals = dem._signals(outputs, inputs)
    m = model.n_outputs
    setup = _Setup(model, build, signals[:, :m], signals[:, m:], eta, P, active, 1.0 / (embedding_order + 1))
    with single_blas_thread():
        start = dem._sample_estimate(signals, False, None)
        layout = _Problem(dem, setup.y, setup.u).layout
        z = np.zeros((layout.n_blocks * layout.W, layout.q))
        z[: len(signals), : layout.n] = start.states
        if unknown:
            z[: len(signals), layout.n:] = start.inputs
        z, theta, history, converged, iterations = _optimise(setup, z, theta, max_iterations, tolerance)
        joint = _joint(setup, z, theta)
        covariance_active, z_std = _spread(setup, joint, z, uncertainty_draws, seed)
    k = eta.shape[0]
    covariance = np.zeros((k, k))
    index = np.flatnonzero(active)
    covariance[index[:, None], index[None, :]] = covariance_active
    n, N = model.n_states, len(signals)
    z = z[:N]
    message = (f"converged at iteration {iterations}" if converged else
               f"stopped after max_iterations = {max_iterations} (not converged)")
    inputs_out = z[:, n:] if unknown else signals[:, m:]
    input_std = z_std[:, n:] if unknown else np.zeros((N, model.n_inputs))
    return PathLearningResult(joint.theta.copy(), np.sqrt(np.diag(covariance)), covariance, z[:, :n].copy(),
                              z_std[:, :n].copy(), inputs_out.copy(), input_std.copy(), np.array(history),
                              converged, iterations, message)
