"""One shape for the estimators: noise=NoiseModel gives the very numbers of the separate keywords,
every estimator's .estimate() returns the one Estimate type (the estimator's own result, with the
same arrays, in details), and .online() runs the batch filter sample by sample."""

from __future__ import annotations

import numpy as np
import pytest

import attend
from attend import AttendInputError
from attend.models import NoiseModel, NonlinearSystem, simulate, simulate_nonlinear
from attend.models.problems import mass_spring_damper
from attend.perception import Estimate, as_estimate
from attend.perception.dem import DEMObserver
from attend.perception.kalman import KalmanEstimator
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear_smoothers import (
    ExtendedSmoother,
    ParticleSmoother,
    UnscentedSmoother,
    coloured_unscented_smoother,
    extended_kalman,
    particle_smoother,
    unscented_kalman,
    white_noise_options,
)
from attend.perception.references import exact_posterior

DT = 0.1
LINEAR = mass_spring_damper()
FORCED_PENDULUM = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0]) + v[0]]), lambda x, v: x[:1], 2, 1, 1)
STD = dict(process_std=0.2, sensor_std=0.1)
NOISE = NoiseModel.from_std(**STD, kernel_width=0.3)
PRECISIONS = dict(sensor_precision=NOISE.sensor_precision, process_precision=NOISE.process_precision)


@pytest.fixture(scope="module")
def linear_log():
    u = np.sin(np.arange(200) * DT)[:, None]
    return simulate(LINEAR, u, DT, noise=NOISE, seed=1)


@pytest.fixture(scope="module")
def nonlinear_log():
    u = 0.3 * np.sin(np.arange(60) * 0.2)[:, None]
    return simulate_nonlinear(FORCED_PENDULUM, u, DT, noise=NOISE, initial_state=[1.0, 0.0], seed=2)


def same(a, b) -> bool:
    """Two results equal field by field, exactly (None, arrays and numbers alike); an Estimate is
    compared by its details (the estimator's own result, with every field)."""
    a, b = (x.details if isinstance(x, Estimate) else x for x in (a, b))
    return all((x is None and y is None) or np.array_equal(x, y) for x, y in zip(a, b))


# --- noise=NoiseModel gives the numbers of the separate keywords -----------------------------------

def test_kalman_estimator(linear_log):
    y, u = linear_log.outputs, linear_log.inputs
    old = KalmanEstimator(LINEAR, DT, **PRECISIONS, kernel_width=0.3)
    new = KalmanEstimator(LINEAR, DT, noise=NOISE)
    assert same(old.estimate(y, u), new.estimate(y, u)) and same(old.filter(y, u), new.filter(y, u))
    assert (new.kernel_width, new.process_kernel_width, new.sensor_kernel_width) == (0.3, 0.3, 0.3)
    apart = NoiseModel(**PRECISIONS, process_kernel_width=0.0, sensor_kernel_width=0.2)
    old = KalmanEstimator(LINEAR, DT, **PRECISIONS, process_kernel_width=0.0, sensor_kernel_width=0.2)
    assert same(old.estimate(linear_log.outputs, linear_log.inputs),
                KalmanEstimator(LINEAR, DT, noise=apart).estimate(linear_log.outputs, linear_log.inputs))
    assert KalmanEstimator(LINEAR, DT, noise=apart).noise_model == old.noise_model


def test_dem_observer(linear_log):
    old = DEMObserver(LINEAR, DT, **PRECISIONS, kernel_width=0.3, known_inputs=True)
    new = DEMObserver(LINEAR, DT, noise=NOISE, known_inputs=True)
    assert same(old.estimate(linear_log.outputs, linear_log.inputs),
                new.estimate(linear_log.outputs, linear_log.inputs))
    assert new.kernel_width == 0.3
    unknown = dict(known_inputs=False, input_prior_precision=1.0)
    assert same(DEMObserver(LINEAR, DT, **PRECISIONS, kernel_width=0.3, **unknown).estimate(linear_log.outputs),
                DEMObserver(LINEAR, DT, noise=NOISE, **unknown).estimate(linear_log.outputs))
    # a noise model read back from an estimator builds the same estimator
    assert same(DEMObserver(LINEAR, DT, noise=old.noise_model, known_inputs=True).estimate(linear_log.outputs,
                                                                                          linear_log.inputs),
                new.estimate(linear_log.outputs, linear_log.inputs))


def test_nonlinear_dem(nonlinear_log):
    settings = dict(embedding_order=4, known_inputs=True)
    old = NonlinearDEM(FORCED_PENDULUM, DT, **PRECISIONS, kernel_width=0.3, **settings)
    new = NonlinearDEM(FORCED_PENDULUM, DT, noise=NOISE, **settings)
    assert same(old.estimate(nonlinear_log.outputs, nonlinear_log.inputs),
                new.estimate(nonlinear_log.outputs, nonlinear_log.inputs))
    assert new.noise_model.kernel_width == 0.3


def test_exact_posterior(linear_log):
    old = exact_posterior(LINEAR, DT, linear_log.outputs[:80], linear_log.inputs[:80], kernel_width=0.3,
                          process_std=0.2, measurement_std=0.1)
    new = exact_posterior(LINEAR, DT, linear_log.outputs[:80], linear_log.inputs[:80], noise=NOISE)
    assert same(old[:7], new[:7])


@pytest.mark.parametrize("smoother", [unscented_kalman, extended_kalman])
def test_white_noise_smoothers(nonlinear_log, smoother):
    process, sensor = NOISE.precision_matrices(2, 1)
    covariances = white_noise_options(DT, process_precision=process, sensor_precision=sensor)
    old = smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs, **covariances)
    new = smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs, noise=NOISE)
    assert same(old, new)
    np.testing.assert_allclose(covariances["process_covariance"], DT**2 * 0.2**2 * np.eye(2), rtol=1e-15)


def test_coloured_smoothers(nonlinear_log):
    settings = dict(initial_mean=[1.0, 0.0], initial_std=0.1)
    old = coloured_unscented_smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs,
                                      kernel_width=0.3, process_std=0.2, measurement_std=0.1, **settings)
    new = coloured_unscented_smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs, noise=NOISE,
                                      **settings)
    assert same(old, new)
    settings.update(n_particles=100, lag=5, seed=3)
    old = particle_smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs, kernel_width=0.3,
                            process_std=0.2, measurement_std=0.1, **settings)
    new = particle_smoother(FORCED_PENDULUM, DT, nonlinear_log.outputs, nonlinear_log.inputs, noise=NOISE, **settings)
    assert same(old, new)
    assert same(ParticleSmoother(FORCED_PENDULUM, DT, noise=NOISE, **settings).estimate(nonlinear_log.outputs,
                                                                                       nonlinear_log.inputs), new)


def test_smoother_classes_call_the_functions(nonlinear_log):
    y, u = nonlinear_log.outputs, nonlinear_log.inputs
    assert same(UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE, alpha=0.5).estimate(y, u),
                unscented_kalman(FORCED_PENDULUM, DT, y, u, noise=NOISE, alpha=0.5))
    assert same(ExtendedSmoother(FORCED_PENDULUM, DT, noise=NOISE, smooth=False).estimate(y, u),
                extended_kalman(FORCED_PENDULUM, DT, y, u, noise=NOISE, smooth=False))
    unknown = dict(input_variance=[0.01], initial_covariance=0.1)
    assert same(UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE, **unknown).estimate(y),
                unscented_kalman(FORCED_PENDULUM, DT, y, noise=NOISE, **unknown))


# --- giving both forms, or neither -----------------------------------------------------------------

@pytest.mark.parametrize("build, names", [
    (lambda: KalmanEstimator(LINEAR, DT, noise=NOISE, sensor_precision=1.0), "sensor_precision"),
    (lambda: KalmanEstimator(LINEAR, DT, noise=NOISE, kernel_width=0.3), "kernel_width"),
    (lambda: DEMObserver(LINEAR, DT, noise=NOISE, process_precision=1.0, sensor_kernel_width=0.1),
     "process_precision, sensor_kernel_width"),
    (lambda: NonlinearDEM(FORCED_PENDULUM, DT, noise=NOISE, kernel_width=0.3), "kernel_width"),
    (lambda: exact_posterior(LINEAR, DT, np.zeros((5, 1)), np.zeros((5, 1)), noise=NOISE, measurement_std=0.1),
     "measurement_std"),
    (lambda: unscented_kalman(FORCED_PENDULUM, DT, np.zeros((5, 1)), noise=NOISE, process_covariance=1.0),
     "process_covariance"),
    (lambda: ExtendedSmoother(FORCED_PENDULUM, DT, noise=NOISE, measurement_covariance=1.0), "measurement_covariance"),
    (lambda: particle_smoother(FORCED_PENDULUM, DT, np.zeros((5, 1)), noise=NOISE, process_std=0.1), "process_std"),
    (lambda: ParticleSmoother(FORCED_PENDULUM, DT, noise=NOISE, kernel_width=0.3), "kernel_width"),
])
def test_both_forms_are_an_error_naming_both(build, names):
    with pytest.raises(AttendInputError, match=f"^noise and {names}: .* not both"):
        build()


@pytest.mark.parametrize("build, message", [
    (lambda: KalmanEstimator(LINEAR, DT, kernel_width=0.3, sensor_precision=1.0), "process_precision: required"),
    (lambda: DEMObserver(LINEAR, DT, kernel_width=0.3, process_precision=1.0), "sensor_precision: required"),
    (lambda: DEMObserver(LINEAR, DT, sensor_precision=1.0, process_precision=1.0), "kernel_width: required"),
    (lambda: NonlinearDEM(FORCED_PENDULUM, DT, sensor_precision=1.0, process_precision=1.0), "kernel_width: required"),
    (lambda: exact_posterior(LINEAR, DT, np.zeros((5, 1)), kernel_width=0.3, process_std=0.1),
     "measurement_std: required"),
    (lambda: UnscentedSmoother(FORCED_PENDULUM, DT, process_covariance=1.0), "measurement_covariance: required"),
    (lambda: ParticleSmoother(FORCED_PENDULUM, DT, process_std=0.1, measurement_std=0.1), "kernel_width: required"),
    (lambda: KalmanEstimator(LINEAR, DT, noise=STD), "noise: expected an attend.models.NoiseModel"),
    (lambda: DEMObserver(LINEAR, DT, noise=NoiseModel(**PRECISIONS, kernel_width=0.0)), "kernel_width: 0 means white"),
    (lambda: NonlinearDEM(FORCED_PENDULUM, DT, noise=NoiseModel(**PRECISIONS, process_kernel_width=0.3,
                                                               sensor_kernel_width=0.2)),
     "noise: NonlinearDEM uses one kernel width"),
    (lambda: ParticleSmoother(FORCED_PENDULUM, DT, noise=NoiseModel(**PRECISIONS, process_kernel_width=0.3,
                                                                   sensor_kernel_width=0.2)),
     "noise: ParticleSmoother uses one kernel width"),
    (lambda: KalmanEstimator(LINEAR, DT, noise=NoiseModel(process_precision=[1.0, 2.0, 3.0], sensor_precision=1.0,
                                                          kernel_width=0.3)),
     "process_precision: expected 2 diagonal entries"),
])
def test_missing_or_unusable_noise(build, message):
    with pytest.raises(AttendInputError, match=message):
        build()


# --- one result type ---------------------------------------------------------------------------------

def check_estimate(estimate, result, method):
    """estimate: the Estimate of ``result`` (its details), the very arrays, bit for bit."""
    assert isinstance(estimate, Estimate) and estimate.details is result and estimate.method == method
    for name in ("time", "states", "inputs", "state_std", "input_std"):
        assert getattr(estimate, name) is getattr(result, name)
    assert as_estimate(estimate) is estimate


def test_every_estimator_returns_an_estimate(linear_log, nonlinear_log):
    """.estimate() of every estimator is an Estimate whose arrays are those of the estimator's own
    result (details), and those equal, bit for bit, what the functions behind the estimators return."""
    y, u = linear_log.outputs, linear_log.inputs
    kalman = KalmanEstimator(LINEAR, DT, noise=NOISE)
    estimate = kalman.estimate(y, u)
    check_estimate(estimate, estimate.details, "kalman smoother")
    assert type(estimate.details).__name__ == "StateEstimate" and not np.any(estimate.input_std)
    unknown = dict(known_inputs=False, input_prior_precision=1.0)
    estimate = KalmanEstimator(LINEAR, DT, noise=NOISE, **unknown).estimate(y)
    check_estimate(estimate, estimate.details, "kalman smoother")
    assert np.all(estimate.input_std > 0)
    estimate = DEMObserver(LINEAR, DT, noise=NOISE, **unknown).estimate(y, keep_generalized=True)
    check_estimate(estimate, estimate.details, "dem")
    assert type(estimate.details).__name__ == "DEMEstimate" and estimate.generalized.shape[0] == len(y)
    gappy = y.copy()
    gappy[50] = np.nan
    estimate = DEMObserver(LINEAR, DT, noise=NOISE, **unknown).estimate(gappy)  # through dem_gaps
    check_estimate(estimate, estimate.details, "dem")
    y, u = nonlinear_log.outputs, nonlinear_log.inputs
    estimate = NonlinearDEM(FORCED_PENDULUM, DT, noise=NOISE, embedding_order=4, known_inputs=True).estimate(y, u)
    check_estimate(estimate, estimate.details, "nonlinear dem")
    assert estimate.generalized is None
    smoothers = [(UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE), "unscented kalman smoother",
                  unscented_kalman(FORCED_PENDULUM, DT, y, u, noise=NOISE)),
                 (ExtendedSmoother(FORCED_PENDULUM, DT, noise=NOISE, smooth=False), "extended kalman filter",
                  extended_kalman(FORCED_PENDULUM, DT, y, u, noise=NOISE, smooth=False)),
                 (ParticleSmoother(FORCED_PENDULUM, DT, noise=NOISE, n_particles=50, lag=3), "particle smoother",
                  particle_smoother(FORCED_PENDULUM, DT, y, u, noise=NOISE, n_particles=50, lag=3))]
    for smoother, method, function_result in smoothers:
        estimate = smoother.estimate(y, u)
        check_estimate(estimate, estimate.details, method)
        assert type(estimate.details) is type(function_result) and same(estimate.details, function_result)
    assert estimate.effective_sample_size is estimate.details.effective_sample_size


FORCED_PENDULUM_PY = """
import numpy as np


def f(x, v):
    return np.array([x[1], -np.sin(x[0]) + v[0]])


def g(x, v):
    return x[:1]
"""

FORCED_PENDULUM_TOML = """
[model]
python = "model.py"
n_states = 2
n_inputs = 1
n_outputs = 1

[outputs]
columns = ["angle"]

[[inputs]]
name = "push"
column = "push"

[observer]
kernel_width = 0.3
sensor_precision = 100.0
process_precision = 25.0
initial_state = [1.0, 0.0]
"""


@pytest.mark.parametrize("method, name", [("ukf", "unscented kalman smoother"), ("dem", "nonlinear dem")])
def test_the_file_estimator_returns_an_estimate(nonlinear_log, tmp_path, method, name):
    from attend.io.model_file import read_model
    from attend.perception.file_estimators import file_estimator

    (tmp_path / "model.py").write_text(FORCED_PENDULUM_PY)
    (tmp_path / "model.toml").write_text(FORCED_PENDULUM_TOML + f'method = "{method}"\n')
    model = read_model(tmp_path / "model.toml")
    y, u = nonlinear_log.outputs, nonlinear_log.inputs
    estimate = file_estimator(model, DT).estimate(y, u)
    check_estimate(estimate, estimate.details, name)


def test_function_results_convert_to_an_estimate(linear_log, nonlinear_log):
    y, u = linear_log.outputs, linear_log.inputs
    filtered = KalmanEstimator(LINEAR, DT, noise=NOISE).filter(y, u)  # .filter() is an Estimate too
    result = filtered.details
    check_estimate(filtered, result, "kalman filter")
    check_estimate(as_estimate(result), result, "kalman filter")
    check_estimate(result.as_estimate(), result, "kalman filter")
    result = exact_posterior(LINEAR, DT, y[:60], u[:60], noise=NOISE)
    check_estimate(result.as_estimate(), result, "exact posterior")
    assert result.as_estimate().log_likelihood == result.log_likelihood
    y, u = nonlinear_log.outputs, nonlinear_log.inputs
    result = unscented_kalman(FORCED_PENDULUM, DT, y, u, noise=NOISE)
    check_estimate(as_estimate(result, "unscented kalman smoother"), result, "unscented kalman smoother")
    result = particle_smoother(FORCED_PENDULUM, DT, y, u, noise=NOISE, n_particles=50, lag=3)
    check_estimate(result.as_estimate(), result, "particle smoother")
    assert as_estimate(result, "reference").method == "reference"
    assert attend.Estimate is Estimate
    with pytest.raises(AttendInputError, match="result: expected an estimator's result"):
        as_estimate(np.zeros(3))


def test_the_details_extra_fields_read_on_the_estimate(nonlinear_log):
    """Estimate.__getattr__: the details' own fields read on the Estimate; names neither has are
    AttributeErrors naming both; the extras are not the Estimate's fields (no _replace, 7 fields)."""
    y, u = nonlinear_log.outputs, nonlinear_log.inputs
    estimate = UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE).estimate(y, u)
    assert estimate.log_likelihood == estimate.details.log_likelihood
    assert estimate.state_covariance is estimate.details.state_covariance
    assert len(estimate) == 7 and estimate._fields[-2:] == ("method", "details")
    with pytest.raises(AttributeError, match="'generalized': neither an Estimate field nor one of its details "
                                             r"\(KalmanEstimate\)"):
        estimate.generalized
    assert not hasattr(estimate, "_private") and not hasattr(estimate, "__missing_dunder__")
    with pytest.raises(ValueError):
        estimate._replace(log_likelihood=0.0)


# --- .online() ----------------------------------------------------------------------------------------

def test_kalman_online_ends_at_the_batch_filter(linear_log):
    estimator = KalmanEstimator(LINEAR, DT, noise=NOISE)
    batch = estimator.filter(linear_log.outputs, linear_log.inputs)
    online = estimator.online()
    for y, u in zip(linear_log.outputs, linear_log.inputs):
        last = online.step(y, u)
    # the online filter computes its gains one step at a time until they settle and then takes the
    # steady gain as products; the batch filter settles on its own schedule and runs the rest by
    # linear_recurrence: the same model, the gains equal to STEADY_TOLERANCE, the means in another
    # order. Measured: 1.4e-8 posterior std at the last sample (6e-8 at most over the log); allowed: 1e-5 std
    # (an estimate no one could tell from the batch one) and the std itself to 1e-6 (test_kalman)
    assert np.all(np.abs(last[0] - batch.states[-1]) <= 1e-5 * batch.state_std[-1])
    np.testing.assert_allclose(last[2], batch.state_std[-1], rtol=1e-6)


def test_dem_online_ends_at_the_batch_estimate(linear_log):
    observer = DEMObserver(LINEAR, DT, noise=NOISE, known_inputs=True)
    batch = observer.estimate(linear_log.outputs, linear_log.inputs)
    online = observer.online()
    results = [online.step(y, u) for y, u in zip(linear_log.outputs, linear_log.inputs)]
    results = [r for r in results if r is not None] + online.finish()
    # the same transition, applied step by step online and by linear_recurrence in batch (as test_dem)
    np.testing.assert_allclose(results[-1][0], batch.states[-1], atol=1e-10)


def test_nonlinear_dem_online_ends_at_the_batch_estimate(nonlinear_log):
    estimator = NonlinearDEM(FORCED_PENDULUM, DT, noise=NOISE, embedding_order=4, known_inputs=True)
    batch = estimator.estimate(nonlinear_log.outputs, nonlinear_log.inputs)
    online = estimator.online()
    results = [online.step(y, u) for y, u in zip(nonlinear_log.outputs, nonlinear_log.inputs)]
    results = [r for r in results if r is not None] + online.finish()
    # the batch D-step runs this very online object (dstep_estimate): the same numbers
    assert np.array_equal(results[-1][0], batch.states[-1])


@pytest.mark.parametrize("smoother", [UnscentedSmoother, ExtendedSmoother])
@pytest.mark.parametrize("inputs", ["measured", "unknown"])
def test_white_noise_online_filters_equal_the_batch_filter(nonlinear_log, smoother, inputs):
    settings = dict(initial_covariance=0.5) if inputs == "measured" else dict(initial_covariance=0.5,
                                                                              input_variance=0.01)
    estimator = smoother(FORCED_PENDULUM, DT, noise=NOISE, smooth=False, **settings)
    given = nonlinear_log.inputs if inputs == "measured" else None
    batch = estimator.estimate(nonlinear_log.outputs, given)
    online = estimator.online()
    rows = [online.step(y, None if given is None else u) for y, u in zip(nonlinear_log.outputs, nonlinear_log.inputs)]
    # the same prediction and update functions on the same numbers: equal to the last bit
    for column, name in enumerate(("states", "inputs", "state_std", "input_std")):
        assert np.array_equal(np.array([row[column] for row in rows]), getattr(batch, name)), name


def test_online_unscented_with_some_inputs_measured(nonlinear_log):
    estimator = UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE, smooth=False, input_variance=[0.01],
                                  known_inputs=[True])
    batch = estimator.estimate(nonlinear_log.outputs, nonlinear_log.inputs)
    online = estimator.online()
    rows = [online.step(y, u) for y, u in zip(nonlinear_log.outputs, nonlinear_log.inputs)]
    assert np.array_equal(rows[-1][0], batch.states[-1]) and np.array_equal(rows[-1][1], batch.inputs[-1])


@pytest.mark.parametrize("settings", [dict(lag=4), dict(lag=0, input_prior_std=0.5)], ids=["measured", "unknown"])
def test_online_particle_smoother_equals_the_batch_one(nonlinear_log, settings):
    smoother = ParticleSmoother(FORCED_PENDULUM, DT, noise=NOISE, n_particles=200, initial_mean=[1.0, 0.0],
                                initial_std=0.2, **settings)
    signal = nonlinear_log.inputs if "input_prior_std" not in settings else np.full_like(nonlinear_log.inputs, 0.1)
    batch = smoother.estimate(nonlinear_log.outputs, signal)
    assert batch.effective_sample_size.min() < 100  # resampled somewhere: the draws are followed through it
    online = smoother.online()
    rows = [online.step(y, u) for y, u in zip(nonlinear_log.outputs, signal)]
    assert all(row is None for row in rows[: settings["lag"]])
    rows = [row for row in rows if row is not None] + online.finish()
    # one ParticleRun under both, the same draws in the same order: equal to the last bit
    for column, name in enumerate(("states", "inputs", "state_std", "input_std")):
        assert np.array_equal(np.array([row[column] for row in rows]), getattr(batch, name)), name


def test_online_filter_step_checks_its_sample():
    online = UnscentedSmoother(FORCED_PENDULUM, DT, noise=NOISE).online()
    with pytest.raises(AttendInputError, match="step: expected 1 outputs and 1 inputs"):
        online.step([0.0, 1.0])
    with pytest.raises(AttendInputError, match="step output: expected finite"):
        online.step([np.nan])
    online = ParticleSmoother(FORCED_PENDULUM, DT, noise=NOISE, n_particles=10).online()
    with pytest.raises(AttendInputError, match="step: expected 1 outputs and 1 inputs"):
        online.step([0.0], [1.0, 2.0])
