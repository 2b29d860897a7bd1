"""Baselines (PID, LQG), the metrics, and the sensory-attenuation experiment (a short run)."""

from __future__ import annotations

import numpy as np
import pytest

from attend import AttendInputError
from attend.control import GenerativeProcess, LQGController, PIDController, run, step_metrics
from attend.control.metrics import itae

A = np.array([[0.0, 1.0], [-0.8 / 1.4, -0.4 / 1.4]])
B = np.array([[0.0], [1.0 / 1.4]])
C = np.array([[1.0, 0.0]])


def test_itae_of_a_constant_error():
    """int_0^T t * 1 dt = T^2 / 2 (rectangle rule on a fine grid)."""
    t = np.linspace(0.0, 2.0, 200001)
    assert itae(t, np.zeros_like(t), 1.0) == pytest.approx(2.0, rel=1e-4)


def test_step_metrics_of_a_first_order_response():
    """y = 1 - exp(-t / tau): no overshoot, 2 % settling at tau ln 50, ITAE = tau^2 (to T = infinity)."""
    tau, dt = 0.5, 1e-4
    t = np.arange(0.0, 20.0, dt)
    y = 1 - np.exp(-t / tau)
    metrics = step_metrics(t, y, 1.0, np.ones((t.size, 1)))
    assert metrics.overshoot == 0.0
    assert metrics.settling_time == pytest.approx(tau * np.log(50), abs=2 * dt)
    assert metrics.itae == pytest.approx(tau**2, rel=1e-3)
    assert metrics.effort == pytest.approx(20.0, rel=1e-6)


def test_step_metrics_overshoot_of_an_underdamped_response():
    """Second-order step response, zeta = 0.2: overshoot exp(-pi zeta / sqrt(1 - zeta^2)) = 52.66 %."""
    zeta, wn = 0.2, 2.0
    t = np.arange(0.0, 30.0, 1e-4)
    wd = wn * np.sqrt(1 - zeta**2)
    y = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
    metrics = step_metrics(t, y, 1.0, np.zeros((t.size, 1)))
    assert metrics.overshoot == pytest.approx(100 * np.exp(-np.pi * zeta / np.sqrt(1 - zeta**2)), rel=1e-4)


def test_step_metrics_never_settled_is_infinite():
    t = np.linspace(0, 1, 11)
    assert step_metrics(t, 0.5 * t, 1.0, np.zeros((11, 1))).settling_time == np.inf


def test_metrics_validate_lengths():
    with pytest.raises(AttendInputError, match="step_metrics: time, output, reference and action"):
        step_metrics(np.arange(5.0), np.arange(4.0), 1.0, np.zeros((5, 1)))


def test_pid_and_lqg_reach_the_set_point():
    world = GenerativeProcess.linear(A, B, C)
    pid = PIDController(8.0, 4.0, 4.0, 0.01, reference=1.0, derivative_filter=0.02)
    lqg = LQGController(A, B, C, 0.01, reference=1.0, state_weight=[100.0, 1.0], integral_weight=100.0)
    for controller in (pid, lqg):
        loop = run(world, controller, 30.0)
        assert loop.outputs[-1, 0] == pytest.approx(1.0, abs=1e-3)
        assert np.isnan(loop.free_energy).all()


def test_lqg_keeps_the_set_point_under_model_error():
    """Integral action: a 30 % heavier mass than the model still ends at the reference."""
    world = GenerativeProcess.linear(A * [[1, 1], [1 / 1.3, 1 / 1.3]], B / 1.3, C)
    lqg = LQGController(A, B, C, 0.01, reference=1.0, state_weight=[100.0, 1.0], integral_weight=100.0)
    assert run(world, lqg, 40.0).outputs[-1, 0] == pytest.approx(1.0, abs=1e-3)


def test_lqg_kalman_gain_is_the_filter_form():
    """The filter gain equals P C' (C P C' + R)^-1 with P the prediction covariance of SciPy's DARE."""
    from scipy.linalg import solve_discrete_are

    from attend.models.linear import zero_order_hold

    Ad, _ = zero_order_hold(A, B, 0.01)
    W, V = np.diag([1e-6, 1e-4]), np.array([[1e-3]])
    lqg = LQGController(A, B, C, 0.01, process_covariance=W, sensor_covariance=V)
    P = solve_discrete_are(Ad.T, C.T, W, V)
    np.testing.assert_allclose(lqg._L, P @ C.T @ np.linalg.inv(C @ P @ C.T + V), rtol=1e-8)


def test_pid_settings_are_validated():
    with pytest.raises(AttendInputError, match="derivative_filter: expected a time constant >= 0"):
        PIDController(1.0, 0.0, 0.0, 0.01, derivative_filter=-1.0)
    with pytest.raises(AttendInputError, match="kp: expected a number"):
        PIDController("1", 0.0, 0.0, 0.01)


def test_attenuation_experiment_runs_replots_and_judges(tmp_path, monkeypatch):
    """Three attenuation values, both reflex variants: metrics, figure from the JSON alone, claims with verdicts."""
    import json

    from attend.control import attenuation
    from attend.experiments._result import VERDICTS, ExperimentResult

    monkeypatch.setitem(attenuation.SETTINGS, "attenuations", [-4, 0, 6])
    monkeypatch.setitem(attenuation.SETTINGS, "duration", 24.0)
    result = attenuation.run(progress=False)
    forces = result.tables["forces"]
    fixed = forces["fixed reflex precision"]["true_over_intended"]
    assert fixed[0] < fixed[1] < fixed[2]  # more attenuation, more movement, with a fixed reflex
    path = result.write(tmp_path)
    again = ExperimentResult.from_json_dict(json.loads(path.read_text()))
    assert attenuation.plot(again, tmp_path) == ["attenuation.png"]
    assert (tmp_path / "attenuation.png").stat().st_size > 10_000
    verdicts = [claim.verdict for claim in attenuation.claims(again)]
    assert len(verdicts) == 2 and set(verdicts) <= set(VERDICTS)
    assert set(attenuation.CAPTIONS) == {"attenuation.png"}
