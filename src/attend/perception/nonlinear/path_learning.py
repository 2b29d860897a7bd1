"""Learning theta in path mode: the parameters with the trajectory (unknown inputs included), with error bars.

Path mode (:mod:`attend.perception.nonlinear.path`) ties the generalised states to one sampled
trajectory z (states, and unknown inputs under their prior). Here the parameters theta of
f(x, v, theta), g(x, v, theta) join z; the noise precisions are given (known)::

    -F(z, theta) = 1/(p+1) * 1/2 sum_c e_c(z, theta)' Pi~ e_c(z, theta)
                   + 1/2 (theta - eta_theta)' P_theta (theta - eta_theta)

Each datum enters p + 1 windows, so the window sum is weighted by 1/(p + 1) (as in the linear
learner's path mode): the prior on theta then weighs against the data once. The maximiser is
found by Levenberg-Marquardt on (z, theta) from path mode's trajectory at the starting theta
(linearised motion, itself started from the D-step's and the unscented smoother's estimates: on
three sinusoidal-sensor systems of the random nonlinear bank theta ends 1.6, 0.3 and 6.6 std
from the truth, against 4.9, 15.7 and 26.6 from the D-step's start alone):
J_z as in path mode, J_theta by central differences over theta, and the joint curvature
[[H_zz, H_zt], [H_tz, H_tt]] solved through the Schur complement of the block-tridiagonal H_zz
(O(N k^2)).

Error bars (``parameter_std``): the estimator's spread under the generative model, linearised at
the estimate (the sandwich of path mode's states, over (z, theta) jointly): [z; theta]_hat -
[z; theta] = -inv(H) (1/(p+1) sum_c J_c' Pi~ eps_c + P_theta (theta - eta_theta)), eps_c the
embedded coloured noises drawn ``uncertainty_draws`` times, theta drawn from its prior.
Calibration is measured in benchmarks/bench_nonlinear.py part 6 and docs/nonlinear.md (mean
z^2 of (theta_hat - theta) / std over seeds; 1 when calibrated). Data from a simulator that
holds the noise over each sample (attend's ``simulate``, ``simulate_nonlinear``) carry more
high-order motion energy than S expects, which biases theta by up to ~0.5 std.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from attend._threads import single_blas_thread
from attend._validation import AttendInputError, positive_scalar
from attend.models.linear import ModelWarning
from attend.perception.nonlinear.dem import NonlinearDEM
from attend.perception.nonlinear.path import (NOISE_BUDGET, _accumulate, _draw_noises, _embedded_noises, _errors,
                                              _fill_unused, _noise_sources, _Problem, _solve, estimate_path)


class PathLearningResult(NamedTuple):
    """What :func:`learn_path` found.

    parameters: theta (k,); parameter_std (k,) and parameter_covariance (k, k): the spread of
    theta_hat - theta (module docstring; 0 for fixed entries); states (N, n), state_std (N, n),
    inputs (N, r) and input_std (N, r) (the given inputs and 0 when known); cost: -F after each
    accepted step (row 0 = the start); converged; iterations; message: how it ended.
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
    shifted: dict  # {(j, +-1): the NonlinearDEM at theta +- h_j e_j}, h_j in steps
    steps: dict  # {j: h_j} of the active entries


class _Setup(NamedTuple):
    model: object
    build: object  # theta -> NonlinearDEM
    y: np.ndarray
    u: np.ndarray
    eta: np.ndarray
    P: np.ndarray
    active: np.ndarray
    weight: float  # 1 / (p + 1)


def _shifted_models(setup: _Setup, theta) -> tuple[dict, dict]:
    """({j: h_j}, {(j, +-1): NonlinearDEM at theta +- h_j e_j}) for central differences over the
    active entries, h_j = 1e-4 max(1, |theta_j|)."""
    steps = {j: 1e-4 * max(1.0, abs(theta[j])) for j in np.flatnonzero(setup.active)}
    shifted = {}
    for j, h in steps.items():
        for sign in (1, -1):
            moved = theta.copy()
            moved[j] += sign * h
            shifted[j, sign] = setup.build(moved)
    return steps, shifted


def _theta_jacobian(problem: _Problem, steps: dict, shifted: dict, z, part) -> np.ndarray:
    """de_c/dtheta (C, n_e, k) of the windows in ``part`` by central differences (the models of
    :func:`_shifted_models`); z: the trajectory."""
    layout = problem.layout
    data = (problem.y_tilde[part], problem.u_tilde[part], layout.starts[part])
    columns = [(_errors(shifted[j, 1], layout, z, *data, jacobians=False)[0]
                - _errors(shifted[j, -1], layout, z, *data, jacobians=False)[0]) / (2 * h) for j, h in steps.items()]
    return np.stack(columns, axis=2) if columns else np.zeros((len(data[2]), layout.precision.shape[0], 0))


def _joint(setup: _Setup, z: np.ndarray, theta: np.ndarray) -> _Joint:
    """-F, gradients and Gauss-Newton curvature of (z, theta) (module docstring)."""
    problem = _Problem(setup.build(theta), setup.y, setup.u)
    layout = problem.layout
    steps, shifted = _shifted_models(setup, theta)
    k, b, K = len(steps), layout.W * layout.q, layout.n_blocks
    Dg, Off, rhs = np.zeros((K, b, b)), np.zeros((K - 1, b, b)), np.zeros((K, b, 1 + k))
    H_theta, gradient_theta, total = np.zeros((k, k)), np.zeros(k), 0.0
    w = setup.weight
    for part in problem.chunks():
        starts = layout.starts[part]
        e, J = _errors(problem.dem, layout, z, problem.y_tilde[part], problem.u_tilde[part], starts, jacobians=True)
        J_theta = _theta_jacobian(problem, steps, shifted, z, part)
        weighted = layout.precision @ J  # Pi~ J_c
        weighted_theta = layout.precision @ J_theta
        total += 0.5 * w * np.einsum("ci,ij,cj->", e, layout.precision, e)
        vectors = np.concatenate([np.einsum("cia,ci->ca", weighted, e)[:, :, None],
                                  np.swapaxes(J, 1, 2) @ weighted_theta], axis=2)
        _accumulate(layout, starts, w * (np.swapaxes(J, 1, 2) @ weighted), w * vectors, Dg, Off, rhs)
        H_theta += w * np.einsum("cia,cib->ab", J_theta, weighted_theta)
        gradient_theta += w * np.einsum("cia,ci->a", weighted_theta, e)
    total += problem.add_priors(z, Dg, rhs[:, :, 0])
    _fill_unused(Dg)
    act = setup.active
    e_theta = theta[act] - setup.eta[act]
    total += 0.5 * float(np.sum(setup.P[act] * e_theta**2))
    return _Joint(problem, theta, total, Dg, Off, rhs[:, :, 0], np.moveaxis(rhs[:, :, 1:], 2, 0),
                  H_theta + np.diag(setup.P[act]), gradient_theta + setup.P[act] * e_theta, shifted, steps)


def _joint_solve(joint: _Joint, rhs_z: np.ndarray, rhs_theta: np.ndarray, damping: float):
    """Solve the (damped) joint system [[H_zz, H_zt], [H_tz, H_tt]] [dz; dt] = [rhs_z; rhs_theta]
    by the Schur complement; rhs_z (R, K, b), rhs_theta (R, k). None if not positive definite."""
    k = joint.H_theta.shape[0]
    solved = _solve(joint.Dg, joint.Off, np.concatenate([rhs_z, joint.coupling]), damping)
    if solved is None:
        return None
    R = rhs_z.shape[0]
    inv_rhs, inv_coupling = solved[:R], solved[R:]  # H_zz^{-1} rhs_z, H_zz^{-1} H_zt
    if k == 0:
        return inv_rhs, np.zeros((R, 0))
    schur = joint.H_theta * (1.0 + damping * np.eye(k)) - np.einsum("ikb,jkb->ij", joint.coupling, inv_coupling)
    try:
        d_theta = np.linalg.solve(schur, (rhs_theta - np.einsum("ikb,rkb->ri", joint.coupling, inv_rhs)).T).T
    except np.linalg.LinAlgError:
        return None
    d_z = inv_rhs - np.einsum("ikb,ri->rkb", inv_coupling, d_theta)
    return d_z, d_theta


def _optimise(setup: _Setup, z, theta, max_iterations: int, tolerance: float):
    """Levenberg-Marquardt on -F(z, theta) jointly (module docstring); returns (joint at the end,
    z, -F history, converged, iterations)."""
    joint = _joint(setup, z, theta)
    history, damping = [joint.cost], 1e-3
    act = setup.active
    q = joint.problem.layout.q
    for iteration in range(1, max_iterations + 1):
        while True:
            step = _joint_solve(joint, -joint.gradient_z[None], -joint.gradient_theta[None], damping)
            trial = None
            if step is not None:
                z_c = z + step[0][0].reshape(-1, q)[: len(z)]
                theta_c = joint.theta.copy()
                theta_c[act] += step[1][0]
                try:
                    trial = _joint(setup, z_c, theta_c)
                except AttendInputError:
                    trial = None
            if (trial is not None and trial.cost <= joint.cost) or damping > 1e10:
                break
            damping = max(10.0 * damping, 1e-9)
        if trial is None or not trial.cost <= joint.cost:  # no step lowers -F: the maximiser
            return joint, z, history, True, iteration
        decrease = joint.cost - trial.cost
        joint, z = trial, z_c
        history.append(joint.cost)
        damping = damping / 10.0 if damping > 1e-12 else 0.0
        if decrease <= tolerance * max(1.0, joint.cost):
            return joint, z, history, True, iteration
    return joint, z, history, False, max_iterations


def _spread(setup: _Setup, joint: _Joint, z, draws: int, seed):
    """(parameter covariance (k, k), z std (N, q)) of the estimation error (module docstring)."""
    problem, layout = joint.problem, joint.problem.layout
    rng = np.random.default_rng(seed)
    act = setup.active
    k, b, K = int(act.sum()), layout.W * layout.q, layout.n_blocks
    theta_errors, z_square = [], np.zeros((K, b))
    channels = sum(len(source[0]) for source in _noise_sources(problem.dem, layout))
    batch = max(1, min(draws, int(NOISE_BUDGET // max(1, problem.n_samples * channels))))
    done = 0
    while done < draws:
        count = min(batch, draws - done)
        noises = _draw_noises(problem.dem, layout, problem.n_samples, count, rng)
        rhs_z, rhs_theta = np.zeros((K, b, count)), np.zeros((count, k))
        for part in problem.chunks():
            starts = layout.starts[part]
            eps = _embedded_noises(problem.dem, layout, noises, starts)
            _, J = _errors(problem.dem, layout, z, problem.y_tilde[part], problem.u_tilde[part], starts, True)
            _accumulate(layout, starts, None, setup.weight * np.einsum("cia,rci->car", layout.precision @ J, eps),
                        None, None, rhs_z)
            J_theta = _theta_jacobian(problem, joint.steps, joint.shifted, z, part)
            rhs_theta += setup.weight * np.einsum("cia,rci->ra", layout.precision @ J_theta, eps)
        for places, values in problem.prior_draws(count, rng):
            rhs_z.reshape(-1, count)[places] += values
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


def _start(dem, signals: np.ndarray):
    """The trajectory the joint optimisation starts from: path mode's at the starting theta (from the
    D-step's and the unscented smoother's estimates, the larger F kept; std not computed), or the
    D-step's where path mode stops with an error. dem: the NonlinearDEM at the starting theta (with
    the linearised motion); signals: (N, m + r) outputs then inputs."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ModelWarning)  # a misfit at the starting theta is expected
            return estimate_path(dem, signals, uncertainty_draws=0)
    except AttendInputError:
        return dem.dstep_estimate(signals, False, None, check=False)


def learn_path(model, outputs, inputs, dt: float, *, kernel_width: float, sensor_precision, process_precision,
               prior_mean, prior_precision, initial=None, input_prior_precision=None, embedding_order: int = 6,
               input_order: int = 2, input_kernel_width: float | None = None, max_iterations: int = 50,
               tolerance: float = 1e-10, uncertainty_draws: int = 200, seed: int = 0,
               motion: str = "path") -> PathLearningResult:
    """theta, the trajectory and their error bars by path mode (module docstring).

    model: a :class:`~attend.perception.nonlinear.ParametrisedSystem`; outputs (N, m) sampled at
    dt [s]; inputs (N, r): the measured inputs, or with ``input_prior_precision`` the prior mean
    of unknown inputs (None: zeros; r = 0: None); kernel_width: s [s]; sensor_precision Pi_z and
    process_precision Pi_w (known: scalar, per-row or matrix, as for NonlinearDEM);
    prior_mean eta_theta and prior_precision P_theta (k,) (inf holds an entry, 0 is flat);
    initial: the starting theta (default eta_theta); input_prior_precision: P_v of unknown
    inputs (None: the inputs are measured); embedding_order: p; input_order: d;
    input_kernel_width: s_v [s] (default s); max_iterations: Levenberg-Marquardt steps at most;
    tolerance: stop when -F falls by less than this fraction;
    uncertainty_draws: noise draws of the error bars; seed: of those draws; motion:
    :class:`NonlinearDEM`'s ``motion``, default "path" (f~ along the Taylor path, keeping the
    curvature terms): with "linearized" (SPM's) Lorenz rho came out biased (27.1-27.5 for 28,
    about -2 std, 4 seeds), with "path" not (z^2 1.00 over 12 seeds), at ~3x the time.
    Raises AttendInputError on bad input, and when theta is not identifiable at the estimate.
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

    def build(values, motion=motion):
        return NonlinearDEM(model.at(values), dt, kernel_width=kernel_width, sensor_precision=sensor_precision,
                            process_precision=process_precision,
                            input_prior_precision=input_prior_precision if unknown else None,
                            embedding_order=embedding_order, input_order=input_order, known_inputs=not unknown,
                            input_kernel_width=input_kernel_width if unknown else None, motion=motion)

    dem = build(theta)
    signals = dem.checked_signals(outputs, inputs)
    m = model.n_outputs
    setup = _Setup(model, build, signals[:, :m], signals[:, m:], eta, P, active, 1.0 / (embedding_order + 1))
    with single_blas_thread():
        start = _start(build(theta, "linearized"), signals)  # the linearised motion: ~3x faster, a start
        layout = _Problem(dem, setup.y, setup.u).layout
        z = np.zeros((layout.n_blocks * layout.W, layout.q))
        z[: len(signals), : layout.n] = start.states
        if unknown:
            z[: len(signals), layout.n:] = start.inputs
        joint, z, history, converged, iterations = _optimise(setup, z, theta, max_iterations, tolerance)
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
