"""The closed loop: a world (:class:`GenerativeProcess`) and a controller, coupled sample by sample.

    y[k] = g(x[k], a[k-1]) + z[k]   ->   a[k] = controller.step(y[k])   ->   x[k+1] = world over [t_k, t_k + dt) with a[k] held

Any controller with ``dt``, ``n_actions`` and ``step(y) -> a`` runs here (the PID and LQG
baselines too). A world or controller that diverges stops the run with
:class:`ClosedLoopDivergence` naming the settings; for a linear world and a linear agent the
loop's spectral radius is checked before the first sample.
"""

from __future__ import annotations

import time as _time
from typing import NamedTuple

import numpy as np

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, positive_scalar
from attend.control._checks import ClosedLoopDivergence
from attend.control.controller import ActiveInferenceController
from attend.control.process import GenerativeProcess


class ClosedLoop(NamedTuple):
    """One closed-loop run, sample k at time[k] (s): states x[k] of the world (N, n_world), outputs y[k]
    (N, m), actions a[k] as delivered (saturated) over [t_k, t_k + dt) (N, k); for an active inference
    controller also its beliefs belief_states (N, n) and belief_causes (N, r), the sensor precision
    diag Pi_z (N, m) and free_energy (N,) (empty columns / NaN otherwise); step_seconds: wall time of
    each controller step [s] (N,)."""

    time: np.ndarray
    states: np.ndarray
    outputs: np.ndarray
    actions: np.ndarray
    belief_states: np.ndarray
    belief_causes: np.ndarray
    sensor_precision: np.ndarray
    free_energy: np.ndarray
    step_seconds: np.ndarray


@with_single_blas_thread
def run(process: GenerativeProcess, controller, duration: float, *, seed: int | None = 0,
        divergence_limit: float = 1e8, check_stability: bool = True, record_beliefs: bool = True) -> ClosedLoop:
    """Simulate ``controller`` acting on ``process`` for ``duration`` [s] at the controller's dt.

    process: the world; controller: an :class:`ActiveInferenceController` (reset first) or any object
    with ``dt``, ``n_actions``, ``step(y) -> a`` (and optionally ``reset()``); seed: the world's noise;
    divergence_limit: |x| of the world beyond which the run stops with :class:`ClosedLoopDivergence`;
    check_stability: for a linear world and a linear agent with constant precision, refuse an
    unstable loop (spectral radius > 1) before running; record_beliefs: keep the active inference
    controller's beliefs, precision and free energy per sample (False: faster, those columns NaN).
    BLAS runs single-threaded inside (small matrices: many threads are 10-300x slower).
    """
    if not isinstance(process, GenerativeProcess):
        raise AttendInputError(f"process: expected an attend.control.GenerativeProcess, got {type(process).__name__}")
    for name in ("dt", "n_actions", "step"):
        if not hasattr(controller, name):
            raise AttendInputError(f"controller: expected an object with dt, n_actions and step(y), it has no {name!r}")
    dt = positive_scalar(controller.dt, "controller.dt", "s")
    duration = positive_scalar(duration, "duration", "s")
    limit = positive_scalar(divergence_limit, "divergence_limit")
    active = isinstance(controller, ActiveInferenceController)
    _check_sizes(process, controller, active)
    if hasattr(controller, "reset"):
        controller.reset()
    if active and check_stability:
        radius = closed_loop_spectral_radius(process, controller)
        if radius is not None and radius > 1 + 1e-9:
            raise ClosedLoopDivergence(
                f"closed loop unstable before running: spectral radius {radius:.6g} > 1 (linear world, linear agent): "
                f"action_gain kappa = {controller.action_gain:g}, dt = {dt:g} s; lower action_gain, or revise the "
                "precisions or dy~/da (action_jacobian)")
    n_samples = int(round(duration / dt))
    world = process.start(n_samples, dt, seed)
    m, k = process.n_outputs, process.n_actions
    n_b = controller.model.n_states if active else 0
    r_b = controller.model.n_causes if active else 0
    out = dict(time=np.arange(n_samples) * dt, states=np.empty((n_samples, process.n_states)),
               outputs=np.empty((n_samples, m)), actions=np.empty((n_samples, k)),
               belief_states=np.full((n_samples, n_b), np.nan), belief_causes=np.full((n_samples, r_b), np.nan),
               sensor_precision=np.full((n_samples, m), np.nan), free_energy=np.full(n_samples, np.nan),
               step_seconds=np.empty(n_samples))
    from_process = active and controller.action_jacobian_source == "process"
    p = controller.model.embedding_order if active else 0
    fixed_G = process.action_jacobian(world.x, np.zeros(k), p) if from_process and process.is_linear else None
    clock = _time.perf_counter
    for i in range(n_samples):
        y = world.output()
        out["states"][i] = world.x
        out["outputs"][i] = y
        started = clock()
        if from_process:
            G = fixed_G if fixed_G is not None else process.action_jacobian(world.x, world.applied, p)
            action = controller.step(y, action_jacobian=G)
        else:
            action = controller.step(y)
        out["step_seconds"][i] = clock() - started
        if active and record_beliefs:
            info = controller.info()
            out["belief_states"][i] = info.states
            out["belief_causes"][i] = info.causes
            out["sensor_precision"][i] = info.sensor_precision
            out["free_energy"][i] = info.free_energy
        action = np.asarray(action, dtype=float).reshape(-1)
        if action.shape[0] != k or not np.isfinite(action).all():
            raise ClosedLoopDivergence(f"controller returned action {action.tolist()} at t = {i * dt:g} s; expected "
                                       f"{k} finite numbers")
        world.advance(action)
        out["actions"][i] = world.applied
        _check_bounded(world.x, limit, (i + 1) * dt, controller)
    return ClosedLoop(**out)


def _check_sizes(process: GenerativeProcess, controller, active: bool) -> None:
    """The controller's actions (and, for an active inference agent, its model's outputs) match the world's."""
    if controller.n_actions != process.n_actions:
        raise AttendInputError(f"controller.n_actions: the controller gives {controller.n_actions} actions, the process "
                               f"takes n_actions = {process.n_actions}")
    if active and controller.model.n_outputs != process.n_outputs:
        raise AttendInputError(f"model.n_outputs: the model predicts {controller.model.n_outputs} outputs, the process "
                               f"gives n_outputs = {process.n_outputs}")


def _check_bounded(x: np.ndarray, limit: float, t: float, controller) -> None:
    """Stop with :class:`ClosedLoopDivergence` when the world's state x is not finite or |x| > limit at time t [s]."""
    if np.isfinite(x).all() and np.abs(x).max() <= limit:
        return
    advice = (f" (action_gain kappa = {controller.action_gain:g}, dt = {controller.dt:g} s): lower action_gain or check "
              "dy~/da" if isinstance(controller, ActiveInferenceController) else ": check its gains")
    raise ClosedLoopDivergence(f"the world diverged at t = {t:g} s (|x| = {np.nanmax(np.abs(x)):.3g} > divergence_limit "
                               f"{limit:.3g}) under {type(controller).__name__}" + advice)


class GeneralisedLoop(NamedTuple):
    """One run of :func:`run_generalised`, N bins at time[k] = k dt [s]: states x[k] of the world at the start of
    bin k (N, n_world); belief_states (N + 1, n), belief_causes (N + 1, r) and actions (N + 1, k) as delivered:
    row 0 at the start, row k + 1 after the step of bin k (so row k is everything at the start of bin k)."""

    time: np.ndarray
    states: np.ndarray
    belief_states: np.ndarray
    belief_causes: np.ndarray
    actions: np.ndarray


@with_single_blas_thread
def run_generalised(process: GenerativeProcess, controller: ActiveInferenceController, duration: float, *,
                    seed: int | None = 0, action_motion: bool = False, joint_world: bool = False,
                    world_states=None, world_outputs=None, adjust_data=None, prior_motion=None, world_causes=None,
                    divergence_limit: float = 1e8) -> GeneralisedLoop:
    """The loop of spm_ADEM: per bin the agent is given the world's generalised response y~ (the sampled output
    at order 0, :meth:`GenerativeProcess.generalised_output`) instead of an embedding of its samples, and steps
    with :meth:`ActiveInferenceController.step_generalised`.

    process, controller: the world and the agent (``integration="spm"`` for joint_world or prior_motion); duration
    [s] at the controller's dt; seed: the world's noise; action_motion: y~ carries the action's motion,
    embedded from the actions delivered so far; joint_world: the world is integrated with the agent over the bin
    (:meth:`GenerativeProcess.generalised_motion`), not stepped apart with the action held; world_states,
    world_outputs: the world's states and outputs that the joint integration moves (None: all); adjust_data:
    None or a function (k, y~ as (p + 1, m)) -> None that overwrites parts of y~ in place (e.g. causes the
    world shows at every order); prior_motion: None or a function t [s] -> eta~_m (``prior_motion`` of
    :meth:`ActiveInferenceController.step_generalised`); world_causes: None or a function (t [s], x) -> None that
    sets the world's exogenous states of the next bin in place (joint_world only); divergence_limit: |x| of
    the world beyond which the run stops with :class:`ClosedLoopDivergence`."""
    from attend.models.generalized import embed_newest

    if not isinstance(process, GenerativeProcess):
        raise AttendInputError(f"process: expected an attend.control.GenerativeProcess, got {type(process).__name__}")
    if not isinstance(controller, ActiveInferenceController):
        raise AttendInputError(f"controller: expected an attend.control.ActiveInferenceController, got "
                               f"{type(controller).__name__}")
    dt = positive_scalar(controller.dt, "controller.dt", "s")
    duration = positive_scalar(duration, "duration", "s")
    limit = positive_scalar(divergence_limit, "divergence_limit")
    _check_sizes(process, controller, True)
    n_samples = int(round(duration / dt))
    p, m = controller.model.embedding_order, process.n_outputs
    moved = np.arange(process.n_states) if world_states is None else np.asarray(world_states)
    run = process.start(n_samples, dt, seed)
    controller.reset()
    states = np.empty((n_samples, process.n_states))
    beliefs = np.empty((n_samples + 1, controller.model.n_states))
    causes = np.empty((n_samples + 1, controller.model.n_causes))
    actions = np.empty((n_samples + 1, process.n_actions))
    beliefs[0], causes[0], actions[0] = controller.states, controller.causes, run.applied
    for k in range(n_samples):
        motion = embed_newest(actions[: k + 1], p + 1, dt)[1:] if action_motion else None  # the actions so far
        if joint_world:  # the world's motion over the bin, its generalised response and dy~/da
            world_motion = process.generalised_motion(run.x, run.applied, p, action_motion=motion, drive=run.drive(),
                                                      states=world_states, outputs=world_outputs)
            y_tilde, G = world_motion.y_tilde, world_motion.action_jacobian
        else:
            world_motion = None
            y_tilde = process.generalised_output(run.x, run.applied, p, action_motion=motion)
            G = process.action_jacobian(run.x, run.applied, p)
        y_tilde[:m] = run.output()
        if adjust_data is not None:
            adjust_data(k, y_tilde.reshape(p + 1, m))
        states[k] = run.x
        action = controller.step_generalised(y_tilde, action_jacobian=G, world_motion=world_motion,
                                             prior_motion=None if prior_motion is None else prior_motion(k * dt))
        if joint_world:  # the world moved with the agent over the bin
            x_next = run.x.copy()
            x_next[moved] += controller.world_increment[: moved.size]
            if world_causes is not None:
                world_causes((k + 1) * dt, x_next)
            run.advance_to(x_next, action)
        else:
            run.advance(action)
        beliefs[k + 1], causes[k + 1], actions[k + 1] = controller.states, controller.causes, run.applied
        _check_bounded(run.x, limit, (k + 1) * dt, controller)
    return GeneralisedLoop(np.arange(n_samples) * dt, states, beliefs, causes, actions)


def closed_loop_spectral_radius(process: GenerativeProcess, controller: ActiveInferenceController) -> float | None:
    """Spectral radius of the sampled closed loop of a linear world (``process``) and a linear agent
    (``controller``) with constant precision (not learned) and constant dy~/da (None otherwise, or with
    action limits: saturation is not linear). < 1: stable.

    Loop state [x[k]; the embedding window; Z[k]]: y[k] = C x[k] + D a[k-1], window shifted in,
    Z[k+1] = Phi Z[k] + Gamma_y y~[k] (+ prior), x[k+1] = Ad x[k] + Bd a[k]."""
    if not (process.is_linear and isinstance(controller, ActiveInferenceController)):
        return None
    if process.action_limits is not None or controller.action_limits is not None:
        return None
    update = controller.linear_update(process)
    if update is None:
        return None
    Phi, Gamma_y, embed, W = update  # y~ = embed @ window (window flattened sample-major)
    from attend.models.linear import zero_order_hold

    A, B, C, Dw = process.matrices
    Ad, Bd = zero_order_hold(A, B, controller.dt)
    m = controller.model.n_outputs
    nw, k = A.shape[0], process.n_actions
    N = Phi.shape[0]
    sizes = (nw, W * m, N)
    total = sum(sizes)
    ix, ib, iz = slice(0, nw), slice(nw, nw + W * m), slice(nw + W * m, total)
    select_a = np.zeros((k, N))
    select_a[:, -k:] = np.eye(k)
    # y[k] = C x + Dw a(Z)
    Y = np.zeros((m, total))
    Y[:, ix] = C
    Y[:, iz] = Dw @ select_a
    shift = np.zeros((W * m, W * m))
    shift[: (W - 1) * m, m:] = np.eye((W - 1) * m)
    Buf = np.zeros((W * m, total))
    Buf[:, ib] = shift
    Buf[(W - 1) * m:, :] += Y
    Znext = np.zeros((N, total))
    Znext[:, iz] = Phi
    Znext += Gamma_y @ embed @ Buf
    Xnext = np.zeros((nw, total))
    Xnext[:, ix] = Ad
    Xnext += Bd @ select_a @ Znext
    M = np.vstack([Xnext, Buf, Znext])
    return float(np.max(np.abs(np.linalg.eigvals(M))))


def linear_controller(controller: ActiveInferenceController, process: GenerativeProcess | None = None):
    """The agent as a linear time-invariant map from its outputs to its action, or None where its step is not
    one constant linear map (see :meth:`ActiveInferenceController.linear_update`)::

        q[k+1] = A q[k] + B y[k],    a[k] = C q[k] + D y[k],    q[k] = [the embedding window before y[k]; Z[k]]

    y[k] (m,) the newest outputs, a[k] (k,) the action the step returns, Z the joint state [x~; v~; a] of beliefs
    and action. With ``action_limits`` the map holds while the action stays within them. The intention
    enters as an input of its own (Gamma_eta eta~(t)), left out here: the map is the agent's feedback, the part a loop analysis needs (loop gain, sensitivity). The
    first sample's clamp (the window filled with y[0]) is an initial state, q[0] = [y[0], ..., y[0]; Z[0]].
    process: the world whose dy~/da is used when the controller takes it from the process."""
    update = controller.linear_update(process)
    if update is None:
        return None
    Phi, Gamma_y, embed, W = update
    m, k = controller.model.n_outputs, controller.n_actions
    N = Phi.shape[0]
    shift = np.zeros((W * m, W * m))
    shift[: (W - 1) * m, m:] = np.eye((W - 1) * m)
    newest = np.zeros((W * m, m))
    newest[(W - 1) * m:] = np.eye(m)
    embedded = Gamma_y @ embed
    A = np.block([[shift, np.zeros((W * m, N))], [embedded @ shift, Phi]])
    B = np.vstack([newest, embedded @ newest])
    C = np.hstack([embedded @ shift, Phi])[-k:]
    D = (embedded @ newest)[-k:]
    return A, B, C, D
