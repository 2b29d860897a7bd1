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
