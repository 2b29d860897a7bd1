"""The attenuation reproduction (attend.control.attenuation): the analytic gradient of its state-dependent sensory
precision against central differences, the controller's precision gradient from it against the finite-difference one,
the folding of SPM's embedded intention into the orders the agent estimates, the prior's own motion within the bin
(``prior_motion`` of step_generalised), and the "SPM conventions" variant leaving the default settings alone."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from attend import AttendInputError
from attend.control import GenerativeModel, attenuation, run
from attend.control._checks import finite_difference
from attend.models.generalized import smoothness_precision


@pytest.mark.parametrize("h", [-4.0, 0.5, 6.0])
def test_precision_gradient_matches_central_differences(h):
    """dpi/d(x, v) of pi = exp(8 - h tanh(v1 + x1)): central differences with step eps^(1/3) max(1, |z|) carry a
    relative error ~eps^(2/3) (4e-11) times the curvature of pi over its slope (measured up to 4e-9 here)."""
    _, controller = attenuation.build(h)
    model = controller.model
    rng = np.random.default_rng(0)
    for _ in range(20):
        x, v = rng.uniform(-2, 2, 2), rng.uniform(-1, 1, 2)
        numeric = finite_difference(lambda q: np.diag(model.sensor_precision_at(q[:2], q[2:])), np.concatenate([x, v]), 2)
        analytic = model.sensor_precision_derivatives(x, v).T
        assert np.abs(numeric - analytic).max() <= 1e-8 * np.abs(analytic).max() + 1e-12


def test_controller_with_the_analytic_gradient_follows_the_finite_difference_one():
    """The closed loop with the model's analytic dpi/d(x, v) and with central differences of Pi_z (the model without
    sensor_precision_gradient): the same run to the finite difference's own error (observed 4e-11 relative on the
    fixed reflex variant)."""
    cfg = dict(attenuation.SETTINGS, duration=24.0)
    runs = []
    for analytic in (True, False):
        world, controller = attenuation.build(2.0, "fixed reflex precision", cfg)
        if not analytic:
            controller.model = dataclasses.replace(controller.model, sensor_precision_gradient=None)
        runs.append(run(world, controller, cfg["duration"], seed=0))
    for field in ("states", "belief_states", "actions"):
        a, b = getattr(runs[0], field), getattr(runs[1], field)
        assert np.abs(a - b).max() <= 1e-8 * np.abs(b).max()


def test_embedded_intention_folds_the_pinned_orders_into_the_estimated_ones():
    """SPM's prior error e = v~ - eta~ at p + 1 orders, with v~ = 0 above order d: its gradient on the orders 0..d,
    -[S (v~ - eta~)]_(0..d), is that of a prior at d + 1 orders with precision S_00 and the folded mean."""
    cfg = dict(attenuation.SETTINGS, **attenuation.SPM_CONVENTIONS, intention_peak_s=15.0)
    P, Q = cfg["embedding_order"] + 1, cfg["cause_order"] + 1
    S = smoothness_precision(P, cfg["kernel_width"])
    from attend.models.generalized import embed

    samples = np.array([attenuation.intention(k * cfg["dt"], cfg) for k in range(32)])
    full = embed(samples[:, None], P, cfg["dt"])
    prior = attenuation.embedded_intention(cfg)
    rng = np.random.default_rng(1)
    for k in (3, 14, 15, 20):
        v = rng.normal(size=Q)
        padded = np.concatenate([v, np.zeros(P - Q)])
        gradient_full = -(S @ (padded - full[k]))[:Q]
        folded = prior(k * cfg["dt"]).reshape(Q, 2)[:, 0]
        np.testing.assert_allclose(-S[:Q, :Q] @ (v - folded), gradient_full, rtol=1e-10, atol=1e-12)
        assert np.all(prior(k * cfg["dt"]).reshape(Q, 2)[:, 1] == 0)  # the external cause's prior stays 0


def test_spm_conventions_leave_the_default_settings_alone():
    _, default = attenuation.build(0.0)
    assert default.integration == "attend" and default.sensory_orders == "relative_degree" and default.dt == 0.125
    _, spm = attenuation.build(0.0, cfg=dict(attenuation.SETTINGS, **attenuation.SPM_CONVENTIONS))
    assert spm.integration == "spm" and spm.sensory_orders == "all" and spm.dt == 1.0
    assert "integration" not in attenuation.SETTINGS and "sensory_orders" not in attenuation.SETTINGS


def test_unfolded_intention_is_the_embedded_orders_up_to_d():
    """embedded_intention(folded=False): the intention's embedded orders 0..d alone, whose motion spm_ALAP moves its
    prior with; the folded prior differs from it only by the part folded in from the orders above d."""
    cfg = dict(attenuation.SETTINGS, **attenuation.SPM_CONVENTIONS, intention_peak_s=15.0)
    P, Q = cfg["embedding_order"] + 1, cfg["cause_order"] + 1
    from attend.models.generalized import embed

    full = embed(np.array([attenuation.intention(k * cfg["dt"], cfg) for k in range(32)])[:, None], P, cfg["dt"])
    own, folded = attenuation.embedded_intention(cfg, folded=False), attenuation.embedded_intention(cfg)
    S = smoothness_precision(P, cfg["kernel_width"])
    for k in (0, 14, 15, 31):
        np.testing.assert_array_equal(own(k * cfg["dt"]).reshape(Q, 2)[:, 0], full[k, :Q])
        np.testing.assert_allclose(folded(k * cfg["dt"]) - own(k * cfg["dt"]),
                                   np.column_stack([np.linalg.solve(S[:Q, :Q], S[:Q, Q:]) @ full[k, Q:], np.zeros(Q)])
                                   .reshape(-1), rtol=1e-12, atol=1e-15)


def test_prior_motion_of_the_prior_itself_changes_nothing():
    """step_generalised(prior_motion=eta~(t)): the prior moves with its own motion, as without prior_motion; and the
    variant's prior_own_motion moves the run."""
    cfg = dict(attenuation.SETTINGS, **attenuation.SPM_CONVENTIONS, intention_peak_s=15.0, world_log_precision=64.0)
    world, controller = attenuation.build(3.0, "fixed reflex precision", cfg)
    p = controller.model.embedding_order
    runs = []
    for given in (False, True):
        controller.reset()
        state, action, beliefs = world.initial_states.copy(), np.zeros(1), []
        for k in range(20):
            motion = world.generalised_motion(state, action, p)
            y_tilde = motion.y_tilde.copy()
            prior = controller.model.prior(k * cfg["dt"]) if given else None
            action = controller.step_generalised(y_tilde, action_jacobian=motion.action_jacobian, world_motion=motion,
                                                 prior_motion=prior)
            state = state + controller.world_increment[:1]
            beliefs.append(controller.generalised_states.copy())
        runs.append(np.array(beliefs))
    np.testing.assert_array_equal(runs[0], runs[1])
    own = attenuation.simulate(3.0, "fixed reflex precision", cfg)
    folded = attenuation.simulate(3.0, "fixed reflex precision", dict(cfg, prior_own_motion=False))
    assert np.abs(own["perceived_self"] - folded["perceived_self"]).max() > 1e-4


def test_prior_motion_is_checked():
    cfg = dict(attenuation.SETTINGS, **attenuation.SPM_CONVENTIONS)
    world, controller = attenuation.build(0.0, "fixed reflex precision", cfg)
    p = controller.model.embedding_order
    y_tilde = world.generalised_output(world.initial_states, np.zeros(1), p)
    G = world.action_jacobian(world.initial_states, np.zeros(1), p)
    with pytest.raises(AttendInputError, match="prior_motion"):
        controller.step_generalised(y_tilde, action_jacobian=G, prior_motion=np.zeros(5))
    _, held = attenuation.build(0.0, "fixed reflex precision", dict(cfg, integration="attend"))
    with pytest.raises(AttendInputError, match="prior_motion: moving the prior within the sample needs"):
        held.step_generalised(y_tilde, action_jacobian=G, prior_motion=np.zeros(6))


def test_spm_conventions_are_spm_alap_s():
    """spm_ALAP's conventions only: no prior on the beliefs (its M.xP and M.vP are empty, so Pu = 0; spm_ADEM's
    exp(-8) is reaching's), and every part of the joint step is on."""
    conventions = attenuation.SPM_CONVENTIONS
    assert "belief_prior_log_precision" not in conventions
    _, controller = attenuation.build(0.0, cfg=dict(attenuation.SETTINGS, **conventions))
    assert controller.belief_prior_precision == 0.0 and controller.top_motion_error is False
    assert all(conventions[key] for key in ("joint_world", "action_motion", "prior_own_motion", "record_before_step"))


def test_sensor_precision_gradient_is_checked():
    base = dict(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1)
    with pytest.raises(AttendInputError, match="sensor_precision_gradient: given for a constant sensor_precision"):
        GenerativeModel(**base, sensor_precision=2.0, sensor_precision_gradient=lambda x, v: (np.ones((1, 1)),) * 2)
    with pytest.raises(AttendInputError, match="sensor_precision_gradient"):
        GenerativeModel(**base, sensor_precision=lambda x, v: np.exp(x),
                        sensor_precision_gradient=lambda x, v: (np.ones((2, 2)), np.ones((1, 1))))
    with pytest.raises(AttendInputError, match="needs sensor_precision\\(x, v\\) to return m precisions"):
        GenerativeModel(**base, sensor_precision=lambda x, v: np.exp(x).reshape(1, 1),
                        sensor_precision_gradient=lambda x, v: (np.ones((1, 1)), np.zeros((1, 1))))
