"""attend.control: every bad input fails with an AttendInputError naming the field; divergence is never silent."""

from __future__ import annotations

import numpy as np
import pytest

from attend import AttendInputError
from attend.control import (
    ActiveInferenceController,
    ClosedLoopDivergence,
    GenerativeModel,
    GenerativeProcess,
    SensorPrecisionLearning,
    run,
)


def scalar_model(**options):
    defaults = dict(sensor_precision=4.0, cause_prior=[1.0])
    return GenerativeModel.linear([[-1.0]], [[1.0]], [[1.0]], **(defaults | options))


def scalar_world(**options):
    return GenerativeProcess.linear([[-1.0]], [[1.0]], [[1.0]], **options)


def test_closed_loop_divergence_is_an_attend_input_error():
    assert issubclass(ClosedLoopDivergence, AttendInputError)


@pytest.mark.parametrize("field, options, match", [
    ("C", dict(C=[[1.0, 2.0]]), "C: expected 1 columns"),
    ("B", dict(B=[[1.0], [2.0]]), "B: expected 1 rows"),
])
def test_linear_model_sizes_must_agree(field, options, match):
    arguments = dict(A=[[-1.0]], B=[[1.0]], C=[[1.0]]) | options
    with pytest.raises(AttendInputError, match=match):
        GenerativeModel.linear(**arguments)


def test_model_and_world_output_counts_must_agree():
    model = GenerativeModel.linear([[-1.0]], [[1.0]], [[1.0], [1.0]], cause_prior=[1.0])
    controller = ActiveInferenceController(model, 0.01, n_actions=1)
    with pytest.raises(AttendInputError, match="model.n_outputs"):
        run(scalar_world(), controller, 1.0)


def test_action_counts_must_agree():
    controller = ActiveInferenceController(scalar_model(), 0.01, action_jacobian=np.ones((3, 2)))
    with pytest.raises(AttendInputError, match="controller.n_actions"):
        run(scalar_world(), controller, 1.0)


def test_action_jacobian_shape_is_checked():
    with pytest.raises(AttendInputError, match=r"action_jacobian: expected dy~/da of shape \(\(p \+ 1\) m, k\) = \(3, 1\)"):
        ActiveInferenceController(scalar_model(), 0.01, action_jacobian=np.ones((2, 1)))


def test_output_sample_size_is_checked():
    controller = ActiveInferenceController(scalar_model(), 0.01, action_jacobian=[[0.0], [1.0], [-1.0]])
    with pytest.raises(AttendInputError, match="y: expected 1 outputs"):
        controller.step([1.0, 2.0])
    with pytest.raises(AttendInputError, match="y: expected finite outputs"):
        controller.step([np.nan])


def test_action_with_no_effect_on_any_output_is_refused():
    G = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.0]])
    with pytest.raises(AttendInputError, match=r"column 1 of dy~/da is zero: action a\[1\] has no effect on any output"):
        ActiveInferenceController(scalar_model(), 0.01, action_jacobian=G)


def test_action_from_process_needs_the_jacobian_each_sample():
    controller = ActiveInferenceController(scalar_model(), 0.01, n_actions=1)
    with pytest.raises(AttendInputError, match="action_jacobian: the controller takes dy~/da from the process"):
        controller.step([0.0])


def test_a_world_whose_action_moves_nothing_is_refused_at_the_first_sample():
    world = GenerativeProcess(f=lambda x, a: -x, g=lambda x, a: x, n_states=1, n_actions=1, n_outputs=1)
    controller = ActiveInferenceController(scalar_model(), 0.01, n_actions=1)
    with pytest.raises(AttendInputError, match="has no effect on any output"):
        run(world, controller, 1.0)


@pytest.mark.parametrize("value, match", [
    (lambda x, v: np.array([-1.0]), "sensor_precision\\(x, v\\): returned precisions \\[-1.0\\]; expected values > 0"),
    (lambda x, v: np.array([np.inf]), "sensor_precision\\(x, v\\): returned non-finite precisions"),
    (lambda x, v: np.ones(3), "sensor_precision\\(x, v\\): expected 1 precisions"),
    (lambda x, v: np.array([[1.0, 2.0], [2.0, 1.0]]), "sensor_precision\\(x, v\\): expected a 1x1 matrix"),
])
def test_bad_precision_function_values_are_refused_at_construction(value, match):
    with pytest.raises(AttendInputError, match=match):
        GenerativeModel(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                        sensor_precision=value, cause_prior=[1.0])


def test_precision_function_turning_bad_during_the_run_stops_it():
    """Pi_z(x, v) = 1 - x: fine at x = 0, negative once the belief passes 1."""
    model = GenerativeModel(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            sensor_precision=lambda x, v: 1.0 - x, cause_prior=[3.0])
    controller = ActiveInferenceController(model, 0.05, n_actions=1, action_gain=10.0)
    with pytest.raises(AttendInputError, match="sensor_precision\\(x, v\\): returned precisions"):
        run(scalar_world(), controller, 30.0)


@pytest.mark.parametrize("field, options, match", [
    ("sensor_precision", dict(sensor_precision=-2.0), "sensor_precision: expected"),
    ("process_precision", dict(process_precision=np.nan), "process_precision: expected finite"),
    ("cause_prior_precision", dict(cause_prior_precision=0.0), "cause_prior_precision: expected precisions > 0"),
    ("kernel_width", dict(kernel_width=0.0), "kernel_width: expected a finite number > 0"),
    ("embedding_order", dict(embedding_order=-1), "embedding_order: expected an integer"),
    ("cause_prior", dict(cause_prior=[1.0, 2.0]), "cause_prior: expected 1 numbers"),
])
def test_model_fields_are_validated(field, options, match):
    with pytest.raises(AttendInputError, match=match):
        scalar_model(**options)


@pytest.mark.parametrize("options, match", [
    (dict(action_gain=0.0), "action_gain: expected a finite number > 0"),
    (dict(action_gain=np.inf), "action_gain: expected a finite number > 0"),
    (dict(action_prior_precision=-1.0), "action_prior_precision: expected a finite number >= 0"),
    (dict(action_limits=(1.0, -1.0)), "action_limits: expected low < high"),
    (dict(action_precision=-1.0), "action_precision: expected"),
    (dict(sensory_orders=7), "sensory_orders: expected an order 0..p = 2"),
    (dict(sensory_orders="some"), "sensory_orders: expected 'relative_degree', 'all'"),
    (dict(precision_schedule="theta"), "precision_schedule: expected a PrecisionOscillator"),
    (dict(embedding_window=1), "embedding_window: expected at least 2 samples"),
    (dict(action_jacobian="world"), "action_jacobian: expected a matrix"),
])
def test_controller_settings_are_validated(options, match):
    arguments = dict(action_jacobian=[[0.0], [1.0], [-1.0]]) | options
    with pytest.raises(AttendInputError, match=match):
        ActiveInferenceController(scalar_model(), 0.01, **arguments)


def test_fixed_schedule_with_an_act_phase_is_refused():
    from attend.rhythm import FixedSchedule

    with pytest.raises(AttendInputError, match="precision_schedule: a FixedSchedule with act_s > 0"):
        ActiveInferenceController(scalar_model(), 0.01, n_actions=1, precision_schedule=FixedSchedule(1.0, 0.5))


def test_precision_learning_needs_a_constant_start():
    model = GenerativeModel(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            sensor_precision=lambda x, v: np.ones(1), cause_prior=[1.0])
    with pytest.raises(AttendInputError, match="precision_learning: cannot learn a state-dependent"):
        ActiveInferenceController(model, 0.01, n_actions=1, precision_learning=SensorPrecisionLearning())


def test_precision_learning_settings_are_validated():
    with pytest.raises(AttendInputError, match="time_constant: expected a finite number > 0"):
        SensorPrecisionLearning(time_constant=-1.0)


def test_unstable_linear_loop_is_refused_before_running():
    """dy~/da with the wrong sign: the action pushes away from the intention; the spectral radius says so."""
    controller = ActiveInferenceController(scalar_model(), 0.01, action_gain=5.0,
                                           action_jacobian=[[0.0], [-1.0], [1.0]])
    with pytest.raises(ClosedLoopDivergence, match=r"closed loop unstable before running: spectral radius .* action_gain"):
        run(scalar_world(), controller, 5.0)


def test_diverging_nonlinear_loop_stops_with_the_settings_named():
    """An unstable world (dx/dt = x + a) and a reflex with the wrong sign: the run stops, naming action_gain."""
    world = GenerativeProcess(f=lambda x, a: x + a, g=lambda x, a: x, n_states=1, n_actions=1, n_outputs=1,
                              initial_states=[0.1])
    model = GenerativeModel(f=lambda x, v: v - x, g=lambda x, v: x, n_states=1, n_causes=1, n_outputs=1,
                            sensor_precision=4.0, cause_prior=[0.0])
    controller = ActiveInferenceController(model, 0.05, n_actions=1, action_gain=2.0,
                                           action_jacobian=lambda x, v, a: np.array([[0.0], [-1.0], [1.0]]))
    with pytest.raises(ClosedLoopDivergence, match="action_gain kappa = 2"):
        run(world, controller, 100.0)


@pytest.mark.parametrize("options, match", [
    (dict(sensor_noise_std=[-1.0]), "sensor_noise_std: expected standard deviations >= 0"),
    (dict(process_kernel_width=-0.1), "process_kernel_width: expected a finite number >= 0"),
    (dict(action_limits=(2.0, 1.0)), "action_limits: expected low < high"),
    (dict(initial_states=[1.0, 2.0]), "initial_states: expected 1 numbers"),
])
def test_world_fields_are_validated(options, match):
    with pytest.raises(AttendInputError, match=match):
        scalar_world(**options)


def test_world_functions_are_checked():
    with pytest.raises(AttendInputError, match="process g\\(x, a\\): expected 1 values, got 2"):
        GenerativeProcess(f=lambda x, a: -x, g=lambda x, a: np.ones(2), n_states=1, n_actions=1, n_outputs=1)
    with pytest.raises(AttendInputError, match="f: expected a function"):
        GenerativeProcess(f=3.0, g=lambda x, a: x, n_states=1, n_actions=1, n_outputs=1)


@pytest.mark.parametrize("options, match", [
    (dict(orders="some"), "orders: expected 'value' or 'all'"),
    (dict(level="total"), "level: expected 'absolute' or 'relative'"),
    (dict(rebuild_tolerance=0.0), "rebuild_tolerance: expected a finite number > 0"),
])
def test_precision_learning_options_are_validated(options, match):
    with pytest.raises(AttendInputError, match=match):
        SensorPrecisionLearning(**options)


def test_a_model_without_causes_is_accepted_and_runs():
    """n_causes = 0 (no intention, e.g. a regulator to zero): the model, the controller and a run
    build; the zero-size cause precision is the empty matrix, not an error."""
    model = GenerativeModel(f=lambda x, v: -x, g=lambda x, v: x, n_states=1, n_causes=0, n_outputs=1,
                            sensor_precision=4.0)
    world = GenerativeProcess(f=lambda x, a: -x + a, g=lambda x, a: x, n_states=1, n_actions=1, n_outputs=1,
                              initial_states=[1.0])
    controller = ActiveInferenceController(model, dt=0.05, action_jacobian=[[1.0], [0.0], [0.0]])  # (p + 1) m rows
    result = run(world, controller, duration=1.0, seed=0)
    assert np.all(np.isfinite(result.states))
    assert abs(result.states[-1, 0]) < abs(result.states[0, 0])  # it regulates towards 0
