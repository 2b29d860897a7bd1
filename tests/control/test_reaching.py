"""The reaching reproduction (attend.control.reaching): arm kinematics against closed forms, the world's
Jacobians against central differences, the agent's attractor at the target, and the closed loop against its
control condition (no cue: no movement)."""

import inspect
import math
import re

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.control import reaching, run
from attend.control._checks import finite_difference


def test_finger_closed_forms():
    # rest posture (pi/2, pi/2): elbow straight up (0, 1), forearm along +x: finger (1, 1)
    assert np.allclose(reaching.finger([math.pi / 2, math.pi / 2]), [1.0, 1.0], atol=1e-15)
    # straight arm along the x axis: x1 = 0, x2 = pi (forearm folded back would be x2 = 0)
    assert np.allclose(reaching.finger([0.0, math.pi]), [2.0, 0.0], atol=1e-15)
    assert np.allclose(reaching.finger([0.0, 0.0]), [0.0, 0.0], atol=1e-15)
    rng = np.random.default_rng(0)
    for angles in rng.uniform(-3, 3, (20, 2)):
        elbow, forearm = reaching.joints(angles)
        assert abs(np.linalg.norm(elbow) - 1) < 1e-14 and abs(np.linalg.norm(forearm) - 1) < 1e-14


def test_finger_jacobian_matches_central_differences():
    rng = np.random.default_rng(1)
    for angles in rng.uniform(-3, 3, (10, 2)):
        numeric = finite_difference(reaching.finger, angles, 2)
        # central differences with step eps^(1/3): error ~ eps^(2/3) ~ 4e-11 times the curvature (<= 2)
        assert np.allclose(reaching.finger_jacobian(angles), numeric, atol=1e-9)


def test_world_jacobians_match_central_differences():
    cfg = reaching.SETTINGS
    rng = np.random.default_rng(2)
    x, a = rng.normal(size=7), rng.normal(size=2)
    (fx, fa), (gx, ga) = reaching.world_jacobians(x, a, "vision", cfg)
    z = np.concatenate([x, a])
    J = finite_difference(lambda q: reaching.world_flow(q[:7], q[7:], cfg), z, 7)
    assert np.allclose(fx, J[:, :7], atol=1e-9) and np.allclose(fa, J[:, 7:], atol=1e-9)
    world, _ = reaching.build("vision", True, cfg)
    J = finite_difference(lambda q: world.g(q[:7], q[7:]), z, 7)
    assert np.allclose(gx, J[:, :7], atol=1e-9) and np.allclose(ga, J[:, 7:], atol=1e-9)


def test_believed_jacobians_match_central_differences():
    """The agent's analytic df/dx, df/dv and dg/dx, dg/dv (both variants) against central differences (step
    eps^(1/3) max(1, |z|): error ~eps^(2/3) times the curvature, measured <= 1.2e-10 on f)."""
    cfg = reaching.SETTINGS
    rng = np.random.default_rng(4)
    for variant in reaching.VARIANTS:
        _, controller = reaching.build(variant, True, cfg)
        model = controller.model
        for _ in range(10):
            x, v = rng.uniform(-2.5, 2.5, 4), rng.uniform(-1.5, 1.5, 3)
            fx, fv, gx, gv = model.jacobians(x, v)
            z = np.concatenate([x, v])
            F = finite_difference(lambda q: reaching.believed_flow(q[:4], q[4:], cfg), z, 4)
            G = finite_difference(lambda q: model.g(q[:4], q[4:]), z, model.n_outputs)
            assert np.allclose(fx, F[:, :4], rtol=0, atol=1e-9) and np.allclose(fv, F[:, 4:], rtol=0, atol=1e-9)
            assert np.allclose(gx, G[:, :4], rtol=0, atol=1e-9) and np.allclose(gv, G[:, 4:], rtol=0, atol=1e-9)


def test_believed_pull_vanishes_at_the_target_and_elbow_torque_is_the_moment():
    cfg = reaching.SETTINGS
    # angles whose finger is at the target (0.6, 0.6): the elbow on the unit circle at distance 1 from it
    target = np.array(cfg["target"])
    half = np.linalg.norm(target) / 2
    base = math.atan2(target[1], target[0])
    x1 = base + math.acos(half)  # elbow angle so that |elbow| = |elbow - target| = 1
    elbow = np.array([math.cos(x1), math.sin(x1)])
    forearm = target - elbow
    x2 = math.atan2(-forearm[1], -forearm[0]) - x1
    assert np.allclose(reaching.finger([x1, x2]), target, atol=1e-12)
    f = reaching.believed_flow(np.array([x1, x2, 0.0, 0.0]), np.array([*target, 1.0]), cfg)
    assert np.allclose(f, 0.0, atol=1e-12)  # the target is a fixed point of the agent's beliefs
    # elsewhere, the elbow torque is the moment of the force about the elbow: (J' F)[1]
    rng = np.random.default_rng(3)
    angles, v = rng.uniform(-2, 2, 2), np.array([0.3, -0.2, 0.7])
    force = cfg["pull_gain"] * v[2] * (v[:2] - reaching.finger(angles))
    moment = reaching.finger_jacobian(angles).T @ force
    flow = reaching.believed_flow(np.array([*angles, 0.0, 0.0]), v, cfg)
    assert abs(flow[3] * cfg["masses"][1] - moment[1]) < 1e-12


def test_cue_rate_is_the_derivative_of_the_cue():
    for t in (10.0, 30.0, 32.0, 40.0):
        numeric = (reaching.cue(t + 1e-5) - reaching.cue(t - 1e-5)) / 2e-5
        assert abs(reaching.cue_rate(t) - numeric) < 1e-8


@pytest.mark.parametrize("variant", reaching.VARIANTS)
def test_cued_reach_arrives_and_the_uncued_arm_stays(variant):
    cfg = dict(reaching.SETTINGS, duration=56.0)
    cued = reaching.simulate(variant, True, cfg)
    still = reaching.simulate(variant, False, cfg)
    start = np.asarray(cued["finger"][0])
    assert np.allclose(start, [1.0, 1.0], atol=1e-3)
    # cued: the finger comes within the tolerance (0.1 arm length) of the target; measured 0.02
    assert cued["distance"].min() < cfg["reach_tolerance"]
    # uncued: no movement beyond noise (measured < 0.002; the world's noise is exp(-8) ~ 3e-4 per sample)
    assert np.linalg.norm(still["finger"] - start, axis=1).max() < 0.01
    # the agent perceives its own finger: belief and world agree (measured < 1e-3)
    assert np.linalg.norm(cued["finger"] - cued["believed_finger"], axis=1).max() < 0.01


def test_reaching_without_action_does_not_reach():
    # oracle for the action's role: the same agent whose reflex is turned off cannot move the world
    cfg = dict(reaching.SETTINGS, duration=56.0)
    world, controller = reaching.build("vision", True, cfg)
    controller.action_gain = 1e-12
    loop = run(world, controller, cfg["duration"], seed=0)
    distance = np.linalg.norm([reaching.finger(x[:2]) - cfg["target"] for x in loop.states], axis=1)
    assert distance.min() > 0.5


def test_unknown_variant_is_refused():
    with pytest.raises(AttendInputError, match="variant"):
        reaching.build("telepathy")


def test_every_argument_is_documented():
    # tests/test_docstrings.py's rule, applied to this module
    for name, obj in vars(reaching).items():
        if name.startswith("_") or not inspect.isfunction(obj) or obj.__module__ != reaching.__name__:
            continue
        doc = obj.__doc__ or ""
        for parameter in inspect.signature(obj).parameters:
            assert re.search(rf"(?<![A-Za-z0-9_]){parameter}(?![A-Za-z0-9_])", doc), f"{name}({parameter})"


# ---------------------------------------------------------------------------------------------- SPM's conventions
def test_embedded_causes_are_the_centred_window_of_the_samples():
    cfg = dict(reaching.SETTINGS, **reaching.SPM_CONVENTIONS)
    table = reaching.embedded_causes(True, cfg)  # (bins, p + 1, 3)
    bins, P = int(cfg["duration"] / cfg["dt"]), cfg["embedding_order"] + 1
    assert table.shape == (bins, P, 3)
    # the target does not move; the cue's order 0 is its sample (the window's centre), its motion close to the
    # analytic rate (5-point central difference at dt = 1 s of a bump of width 8 s: error ~ dt^4 u^(5) / 30 < 1e-3)
    assert np.allclose(table[:, 0, :2], cfg["target"], atol=1e-15) and np.abs(table[:, 1:, :2]).max() < 1e-14
    times = np.arange(bins) * cfg["dt"]
    assert np.allclose(table[:, 0, 2], [reaching.cue(t, cfg) for t in times], atol=1e-15)
    inner = slice(2, bins - 2)
    assert np.abs(table[inner, 1, 2] - [reaching.cue_rate(t, cfg) for t in times[inner]]).max() < 1e-3
    assert np.all(reaching.embedded_causes(False, cfg)[:, :, 2] == 0.0)


def test_world_motion_holds_the_worlds_generalised_response():
    cfg = dict(reaching.SETTINGS, **reaching.SPM_CONVENTIONS)
    world, _ = reaching.build("vision", True, cfg)
    rng = np.random.default_rng(4)
    x, a, p = rng.normal(size=7), rng.normal(size=2), cfg["embedding_order"]
    motion = rng.normal(size=(p, 2))
    wm = world.generalised_motion(x, a, p, action_motion=motion, states=range(4), outputs=[0, 1, 5, 6])
    assert np.allclose(wm.y_tilde, world.generalised_output(x, a, p, action_motion=motion), atol=1e-14)
    assert np.allclose(wm.action_jacobian, world.action_jacobian(x, a, p), atol=1e-14)
    # x'' = f_x x' + f_a a' (the action's motion moves the velocities' second order); held action: f_x x'
    states = world.generalised_states(x, a, p, motion).reshape(p + 1, 7)
    fx, fa, _, _ = world.jacobians(x, a)
    assert np.allclose(states[2], fx @ states[1] + fa @ motion[0], atol=1e-14)
    assert np.allclose(world.generalised_output(x, a, p), world.generalised_output(x, a, p, np.zeros((p, 2))),
                       atol=1e-14)
    assert np.allclose(wm.c, states[1:, :4].reshape(-1), atol=1e-14)


def _reference_world_increment(joint, flow, y_t, eta_t, world):
    """The definition of the joint step (no reduction): expm of the dense block of [Z; y~; eta~; w; 1], the driven
    rows of y~ moving with C w, the others and eta~ with their shift (scipy's expm)."""
    from scipy.linalg import expm

    from attend.control._core import shift_matrix

    n, r, m, k, P, Q = joint.sizes
    N, ny, nv, nw = flow.shape[0], P * m, Q * r, world.A.shape[0]
    size = N + ny + nv + nw + 1
    y0, v0, w0 = N, N + ny, N + ny + nv
    A = np.zeros((size, size))
    A[:N, :N] = joint.J
    A[:N, y0:v0] = -joint.H[:ny].T
    A[:N, v0:w0] = joint.H[ny + P * n:].T
    shift = shift_matrix(P, m, Q, r)
    A[y0:w0, y0:w0] = shift
    A[y0:v0, y0:v0][world.driven] = 0.0
    A[y0:v0, w0:-1] = world.C
    A[w0:-1, N - k:N] = world.B
    A[w0:-1, w0:-1] = world.A
    A[:N, -1] = flow
    A[y0:w0, -1] = shift @ np.concatenate([y_t, eta_t])
    A[w0:-1, -1] = world.c
    column = expm(A * joint.dt)[:, -1]
    return column[:N], column[w0:-1]


@pytest.mark.parametrize("moving_prior", [False, True])
def test_joint_world_step_matches_its_definition(moving_prior):
    # the step drops the top order of y~ and a still prior, and carries the data's own motion by clock states: the
    # same increments as the dense definition, to rounding
    from attend.control._core import JointFlow, shift_matrix

    cfg = dict(reaching.SETTINGS, **reaching.SPM_CONVENTIONS)
    world, controller = reaching.build("prior", True, cfg)
    n, r, m, P, Q, k = 4, 3, 4, 5, 3, 2
    rng = np.random.default_rng(5)
    joint = JointFlow(n, r, m, k, P, Q, shift_matrix(P, n, Q, r), controller._Pi_x, controller._Pi_v, 1.0,
                      np.exp(-2.0), 1.0)
    x = np.concatenate([[1.2, 1.9, 0.1, -0.2], [0.6, 0.6, 0.5]])
    fx, fv = reaching.believed_jacobians(x[:4], x[4:], cfg)
    gx = np.vstack([np.eye(2, 4), np.hstack([reaching.finger_jacobian(x[:2]), np.zeros((2, 2))])])
    joint.set_jacobians(fx, fv, gx, np.zeros((4, 3)))
    wm = world.generalised_motion(x, np.array([0.3, -0.1]), P - 1, action_motion=rng.normal(size=(P - 1, 2)),
                                  states=range(4))
    joint.set_action_jacobian(wm.action_jacobian)
    joint.set_sensory_precision(np.eye(P * m) * 50.0 + 1.0)
    joint.linearise()
    Z = rng.normal(size=P * n + Q * r + k)
    y_t = wm.y_tilde + 0.01 * rng.normal(size=P * m)
    eta = rng.normal(size=Q * r) if moving_prior else np.concatenate([[0.6, 0.6, 0.5], np.zeros(6)])
    flow = joint.flow(Z, y_t, eta, reaching.believed_flow(Z[:4], Z[20:23], cfg), gx @ Z[:4])
    dZ, dw = joint.moving_data_increment(flow, y_t, eta, wm), joint.world_increment
    ref_Z, ref_w = _reference_world_increment(joint, flow, y_t, eta, wm)
    assert np.allclose(dZ, ref_Z, rtol=1e-9, atol=1e-9 * np.abs(ref_Z).max())
    assert np.allclose(dw, ref_w, rtol=1e-9, atol=1e-9 * np.abs(ref_w).max())


def test_spm_conventions_reach_with_the_demos_noise():
    # SPM_CONVENTIONS over SETTINGS (the world's exp(16) noise, cue at t = 32 s): the claim holds, the arm stays
    cfg = dict(reaching.SETTINGS, **reaching.SPM_CONVENTIONS)
    cued, still = reaching.simulate("vision", True, cfg), reaching.simulate("vision", False, cfg)
    assert cued["distance"].min() < cfg["reach_tolerance"]
    assert np.linalg.norm(still["finger"] - still["finger"][0], axis=1).max() < cfg["stay_tolerance"]
    prior = reaching.simulate("prior", True, cfg)
    assert prior["distance"].min() < cfg["reach_tolerance"]


def test_world_motion_needs_spm_integration():
    world, controller = reaching.build("vision", True, reaching.SETTINGS)
    wm = world.generalised_motion(world.initial_states, np.zeros(2), 4, states=range(4), outputs=[0, 1, 5, 6])
    with pytest.raises(AttendInputError, match="world_motion"):
        controller.step_generalised(wm.y_tilde, action_jacobian=wm.action_jacobian, world_motion=wm)


def test_belief_prior_precision_is_checked_and_off_by_default():
    cfg = dict(reaching.SETTINGS, **reaching.SPM_CONVENTIONS)
    _, controller = reaching.build("vision", True, cfg)
    assert controller.belief_prior_precision == pytest.approx(np.exp(-8.0))
    _, default = reaching.build("vision", True, reaching.SETTINGS)
    assert default.belief_prior_precision == 0.0 and default.top_motion_error
    from attend.control import ActiveInferenceController

    with pytest.raises(AttendInputError, match="belief_prior_precision"):
        ActiveInferenceController(default.model, 1.0, n_actions=2, belief_prior_precision=-1.0)
