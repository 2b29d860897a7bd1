"""The spread check (attend.perception.spread_check): silent on correct models, a warning naming the
state and the setting when an estimate swings far beyond its measured proxy or its prior spread."""

import numpy as np
import pytest

from attend.models.linear import simulate
from attend.models.problems import mass_spring_damper
from attend.perception.kalman import KalmanEstimator
from attend.perception.spread_check import SPREAD_LIMIT, noise_intensity, spread_findings

DT, WIDTH, PROCESS_STD, SENSOR_STD = 0.05, 0.1, 0.3, 0.02


def _log(seed=0, n_samples=800):
    system = mass_spring_damper()
    t = np.arange(n_samples) * DT
    force = np.sin(0.7 * t)[:, None]
    log = simulate(system, force, DT, kernel_width=WIDTH, process_std=[1e-3, PROCESS_STD],
                   measurement_std=SENSOR_STD, seed=seed)
    return system, force, log


def _check(system, outputs, states, inputs, *, unknown=False, drive=None, input_precision=1.0, **options):
    settings = dict(process_precision=np.array([1e-3, PROCESS_STD]) ** -2.0, process_kernel_width=WIDTH,
                    sensor_kernel_width=WIDTH, unknown=np.array([unknown]),
                    drive=inputs if drive is None else drive, input_prior_precision=np.array([input_precision]),
                    input_kernel_width=WIDTH)
    settings.update(options)
    return spread_findings(system, DT, outputs, states, inputs, **settings)


def _smoother(system, outputs, force, sensor_precision=SENSOR_STD**-2):
    estimator = KalmanEstimator(system, DT, sensor_precision=sensor_precision,
                                process_precision=np.array([1e-3, PROCESS_STD]) ** -2.0, kernel_width=WIDTH,
                                known_inputs=True)
    return estimator.estimate(outputs, force)


def test_noise_intensity_closed_forms():
    assert noise_intensity(0.0, 0.1) == 0.1  # white: the sample time
    assert noise_intensity(1.0, 0.01) == pytest.approx(2 * np.sqrt(np.pi), rel=1e-6)  # s >> dt


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_silent_on_a_correct_model(seed):
    system, force, log = _log(seed)
    estimate = _smoother(system, log.outputs, force)
    assert _check(system, log.outputs, estimate.states, force) == []
    ratios = _check(system, log.outputs, estimate.states, force, ratios=True)
    assert np.all(ratios[:2] < 2.0), ratios  # position: proxy y; velocity: proxy dy/dt or the prior


def test_outputs_in_the_wrong_unit_are_named_with_the_setting():
    """The log in degrees, the model in radians: the states swing 57x their prior spread."""
    system, force, log = _log()
    outputs = log.outputs * 180 / np.pi
    estimate = _smoother(system, outputs, force, sensor_precision=(SENSOR_STD * 180 / np.pi) ** -2)
    # the proxy y / c is as wrong as the estimate; the model's prior spread is not
    findings = _check(system, outputs, estimate.states, force)
    names = {f.name: f for f in findings}
    assert "velocity" in names and names["velocity"].ratio > SPREAD_LIMIT
    assert names["velocity"].reference == "prior spread under the model"
    assert "process_precision" in names["velocity"].settings and "units" in names["velocity"].settings


def test_velocity_swinging_beyond_its_measured_proxy_is_named():
    """A velocity estimate with a 12x larger spread than d(position)/dt, as the issue's roll rate."""
    system, force, log = _log()
    estimate = _smoother(system, log.outputs, force)
    wild = estimate.states.copy()
    wild[:, 1] += 12 * np.std(log.states[:, 1]) * np.sign(np.sin(np.arange(len(wild)) * 2.0))
    findings = _check(system, log.outputs, wild, force, process_precision=np.array([1e-3, 1e-12]))
    assert [f.name for f in findings] == ["velocity"]
    assert findings[0].reference.startswith("measured proxy d(") and findings[0].ratio > SPREAD_LIMIT


def test_unknown_input_beyond_its_prior_names_its_prior_precision():
    system, force, log = _log()
    estimate = _smoother(system, log.outputs, force)
    wild_input = 20 * np.sign(np.sin(np.arange(len(force)) * 0.3))[:, None]
    findings = _check(system, log.outputs, estimate.states, wild_input, unknown=True,
                      drive=np.zeros_like(force), input_precision=1.0)
    force_findings = [f for f in findings if f.name == "force"]
    assert force_findings and "prior_precision ([[inputs]] force)" in force_findings[0].settings
    # the states the unknown input reaches name its prior first
    assert all("unknown input force" in f.settings for f in findings if f.name != "force")
