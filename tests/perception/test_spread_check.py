"""The spread check (attend.perception.spread_check): silent on correct models, a warning naming the
state and the setting when an estimate swings far beyond its measured proxy or its prior spread."""

import numpy as np
import pytest

from attend.models.linear import simulate
from attend.models.problems import mass_spring_damper
from attend.perception.kalman import KalmanEstimator
from attend.models.linear import LinearSystem
from attend.perception.spread_check import (INPUT_PRIOR_REFERENCE, SPREAD_LIMIT, describe, effective_samples,
                                            input_prior_limit, noise_intensity, spread_findings)

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



# --- the input-prior check: an unknown input's RMS about its prior mean against its prior std ------

INPUT_WIDTH = 0.5  # s_u [s]


def _prior_draw(rng, n_samples, width=INPUT_WIDTH, std=1.0):
    """(N, 1) a draw of the inputs' prior: rho(tau) = exp(-tau^2 / (4 s_u^2)), std ``std``, mean 0."""
    lags = np.arange(n_samples) * DT
    R = np.exp(-((lags[:, None] - lags[None, :]) ** 2) / (4 * width**2))
    w, V = np.linalg.eigh(R)
    return std * (V * np.sqrt(np.clip(w, 0, None))) @ rng.standard_normal((n_samples, 1))


def _unknown_force_case(seed, b_factor=1.0, n_samples=600):
    """A mass-spring-damper pushed by a force drawn from its prior (std 1); the model's B is the
    truth's times ``b_factor`` (1: the model is right). Returns (model, findings of the smoother)."""
    truth = mass_spring_damper()
    model = LinearSystem(truth.A, truth.B * b_factor, truth.C, state_names=truth.state_names,
                         input_names=truth.input_names)
    force = _prior_draw(np.random.default_rng(seed), n_samples)
    log = simulate(truth, force, DT, kernel_width=WIDTH, process_std=[1e-3, PROCESS_STD], measurement_std=SENSOR_STD,
                   seed=seed)
    estimate = KalmanEstimator(model, DT, sensor_precision=SENSOR_STD**-2,
                               process_precision=np.array([1e-3, PROCESS_STD]) ** -2.0, kernel_width=WIDTH,
                               known_inputs=False, input_prior_precision=[1.0],
                               input_kernel_width=INPUT_WIDTH).estimate(log.outputs, np.zeros_like(force))
    return _check(model, log.outputs, estimate.states, estimate.inputs, unknown=True, drive=np.zeros_like(force),
                  input_kernel_width=INPUT_WIDTH)


def test_effective_samples_closed_forms():
    assert effective_samples(500, 0.1, 0.0) == 500  # white: every sample
    # N dt >> s >> dt: N dt / (s sqrt(2 pi))
    assert effective_samples(20000, 0.01, 1.0) == pytest.approx(200 / np.sqrt(2 * np.pi), rel=0.01)


def test_input_prior_limit_is_the_quantile_of_the_priors_own_rms():
    """The share of the prior's own draws whose RMS passes the limit is the false rate asked for."""
    rng = np.random.default_rng(5)
    n_samples, draws, rate = 120, 20000, 0.02
    lags = np.arange(n_samples) * DT
    w = np.clip(np.linalg.eigvalsh(np.exp(-((lags[:, None] - lags[None, :]) ** 2) / (4 * INPUT_WIDTH**2))), 0, None)
    mean_square = (rng.standard_normal((draws, n_samples)) ** 2) @ w / n_samples
    above = np.mean(mean_square > input_prior_limit(n_samples, DT, INPUT_WIDTH, rate) ** 2)
    assert above == pytest.approx(rate, abs=4 * np.sqrt(rate / draws)), above


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_input_prior_check_is_silent_when_the_input_follows_its_prior(seed):
    assert _unknown_force_case(seed) == []


def test_input_absorbing_a_wrong_b_is_named_with_its_prior_precision():
    """The model's B is 1/4 of the truth's: the estimated force swings ~2x its prior std to make up for it,
    under the spread check's limit of 8 but beyond what a correct model's posterior mean reaches (1.47x)."""
    findings = _unknown_force_case(0, b_factor=0.25)
    assert [f.name for f in findings] == ["force"], findings
    finding = findings[0]
    assert finding.reference == INPUT_PRIOR_REFERENCE and finding.limit < finding.ratio < SPREAD_LIMIT
    assert finding.reference_rms == pytest.approx(1.0)
    text = describe(finding)
    assert "\n" not in text and text.startswith("unknown input 'force': its estimate's RMS about the prior mean")
    assert "prior_precision ([[inputs]] force)" in text and "absorbing" in text


# --- attend estimate: the check's warnings on a model file and a log ------------------------------

ESTIMATE_MODEL = """
model = {{A = {A}, B = {B}, C = {C}, states = ["position", "velocity"]}}
outputs = {{columns = ["y"]}}
inputs = [{{name = "force", prior_mean = 0.0, prior_precision = 1.0}}]

[observer]
kernel_width = {width}
input_kernel_width = 1.0
sensor_precision = {sensor_precision}
process_precision = [1e6, {process_precision}]
"""


def _estimate_warnings(tmp_path, capsys, scale: float) -> list[str]:
    """The spread check's warnings of `attend estimate` on the mass-spring-damper log with an unknown
    force, its outputs times ``scale`` (57.3: logged in degrees, the model in radians) and the sensor
    precision stated for that log (the sensor noise itself fits)."""
    from attend.cli import main

    system, _, log = _log()
    model, path = tmp_path / "model.toml", tmp_path / "log.csv"
    model.write_text(ESTIMATE_MODEL.format(A=system.A.tolist(), B=system.B.tolist(), C=system.C.tolist(), width=WIDTH,
                                           sensor_precision=(scale * SENSOR_STD) ** -2.0,
                                           process_precision=PROCESS_STD**-2.0))
    path.write_text("t,y\n" + "\n".join(f"{k * DT:.10g},{scale * v:.12g}" for k, v in enumerate(log.outputs[:, 0])))
    assert main(["estimate", str(model), str(path), "--out", str(tmp_path / "e.csv"), "--no-progress"]) == 0
    return [line[len("attend: warning: "):] for line in capsys.readouterr().err.splitlines()
            if line.startswith("attend: warning:") and "far beyond what the data support" in line]


def test_estimate_warns_on_a_wild_estimate_naming_it_and_the_setting(tmp_path, capsys):
    """The log in degrees, the model in radians: the unknown force swings far beyond its prior to
    explain it, and the states beyond the spread the model gives them; each is named with what to check."""
    warned = _estimate_warnings(tmp_path, capsys, 180 / np.pi)
    named = {text.split(": ")[1]: text for text in warned}
    assert {"force", "position", "velocity"} <= set(named), warned
    assert "prior_precision ([[inputs]] force)" in named["force"]
    assert "prior spread under the model" in named["velocity"]
    assert "prior_precision of the unknown input force" in named["velocity"]
    assert all("model.toml" in text for text in warned)


def test_estimate_does_not_warn_on_the_log_the_model_describes(tmp_path, capsys):
    assert _estimate_warnings(tmp_path, capsys, 1.0) == []


def test_estimate_warns_on_an_input_absorbing_what_the_model_lacks(tmp_path, capsys):
    """attend estimate on a model file whose B is 1/4 of the truth's: one line naming the force and its
    prior_precision, through the same warnings as the spread check; the estimate is written as without it."""
    from attend.cli import main

    truth = mass_spring_damper()
    force = _prior_draw(np.random.default_rng(1), 600)
    log = simulate(truth, force, DT, kernel_width=WIDTH, process_std=[1e-3, PROCESS_STD], measurement_std=SENSOR_STD,
                   seed=1)
    model, path = tmp_path / "model.toml", tmp_path / "log.csv"
    text = ESTIMATE_MODEL.format(A=truth.A.tolist(), B=(truth.B / 4).tolist(), C=truth.C.tolist(), width=WIDTH,
                                 sensor_precision=SENSOR_STD**-2.0, process_precision=PROCESS_STD**-2.0)
    model.write_text(text.replace("input_kernel_width = 1.0", f"input_kernel_width = {INPUT_WIDTH}"))
    path.write_text("t,y\n" + "\n".join(f"{k * DT:.10g},{v:.12g}" for k, v in enumerate(log.outputs[:, 0])))
    assert main(["estimate", str(model), str(path), "--out", str(tmp_path / "e.csv"), "--no-progress"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "prior std" in line]
    assert len(lines) == 1 and "unknown input 'force'" in lines[0] and "model.toml" in lines[0], lines
    assert "prior_precision ([[inputs]] force)" in lines[0] and "absorbing" in lines[0]
