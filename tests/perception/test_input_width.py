"""The Kalman filter's log-likelihood against the dense Gaussian density of the outputs, and the
unknown inputs' prior width chosen from the log (attend.perception.input_width). Figures on
logs the model fits poorly: benchmarks/bench_unknown_inputs_misfit.py."""

import warnings

import numpy as np
import pytest
from scipy.stats import multivariate_normal

import attend
from attend.models.linear import ModelWarning
from attend.models.noise import autocorrelation
from attend.perception.input_width import (
    FLAT_LOG_LIKELIHOOD,
    WHITE_FLOOR_DECADES,
    choose_input_width,
    choose_white_floor,
    innovation_terms_on,
    input_width_grid,
    profiled_log_likelihood,
)
from attend.perception.kalman import KalmanEstimator
from attend.perception.references.exact import coloured_noise_correlation
from attend.perception.references.exact_oracle import correlation_root

OSCILLATOR = attend.LinearSystem(np.array([[0.0, 1.0], [-2.0, -0.5]]), np.array([[0.0], [1.0]]),
                                 np.array([[1.0, 0.0]]))


def dense_output_density(system, dt, N, *, process_std, sensor_std, process_width, sensor_width, input_mean=None,
                         input_std=None, input_width=None, known_inputs=None, initial_mean, initial_std,
                         noise_correlation=None):
    """(mean, covariance) of the stacked outputs y = [y[0]; ...; y[N-1]] under the model, built
    densely: x = Phi x[0] + L (Bd u + dt w), w coloured with the simulator's kernel correlation,
    unknown inputs a Gaussian process with rho(tau) = exp(-tau^2 / (4 s_u^2)) sampled at the lags,
    y = (I kron C) x + z; noise_correlation: (N, N), the correlation of w and z instead (both coloured)."""
    n, r = system.n_states, system.n_inputs
    Ad, Bd = system.discretize(dt)
    powers = [np.linalg.matrix_power(Ad, k) for k in range(N)]
    Phi = np.vstack(powers)
    L = np.zeros((N * n, N * n))
    for k in range(1, N):
        for j in range(k):
            L[k * n:(k + 1) * n, j * n:(j + 1) * n] = powers[k - 1 - j]
    Bbig = np.kron(np.eye(N), Bd)
    process_correlation, sensor_correlation = (coloured_noise_correlation(N, dt, width) if noise_correlation is None
                                               else noise_correlation for width in (process_width, sensor_width))
    drive_cov = np.kron(process_correlation, np.diag((dt * np.asarray(process_std)) ** 2))
    if known_inputs is not None:
        drive_mean = Bbig @ np.asarray(known_inputs).reshape(-1)
    else:
        lags = dt * (np.arange(N)[:, None] - np.arange(N)[None, :])
        input_cov = np.kron(autocorrelation(lags, input_width), np.diag(np.square(input_std)))
        drive_cov = drive_cov + Bbig @ input_cov @ Bbig.T
        drive_mean = Bbig @ np.tile(input_mean, N)
    x_cov = L @ drive_cov @ L.T + Phi @ np.diag(np.square(initial_std)) @ Phi.T
    x_mean = Phi @ initial_mean + L @ drive_mean
    Cbig = np.kron(np.eye(N), system.C)
    y_cov = Cbig @ x_cov @ Cbig.T + np.kron(sensor_correlation,
                                            np.diag(np.square(sensor_std)))
    return Cbig @ x_mean, 0.5 * (y_cov + y_cov.T)


@pytest.mark.parametrize("widths", [(0.1, 0.1, 0.2), (0.0, 0.05, 0.1), (0.05, 0.0, 0.6), (0.1, 0.1, 0.025)])
def test_log_likelihood_is_the_dense_gaussian_density_of_the_outputs(widths):
    s_w, s_z, s_u = widths
    dt, N = 0.1, 50
    sw, sz, su, eta = np.array([0.1, 0.3]), np.array([0.05]), np.array([2.0]), np.array([0.3])
    m0, s0 = np.array([0.2, -0.1]), np.array([1.0, 0.5])
    rng = np.random.default_rng(1)
    log = attend.simulate(OSCILLATOR, rng.normal(size=(N, 1)), dt, process_kernel_width=s_w, sensor_kernel_width=s_z,
                          process_std=sw, measurement_std=sz, initial_state=[0.5, 0.0], seed=3)
    mean, cov = dense_output_density(OSCILLATOR, dt, N, process_std=sw, sensor_std=sz, process_width=s_w,
                                     sensor_width=s_z, input_mean=eta, input_std=su, input_width=s_u,
                                     initial_mean=m0, initial_std=s0)
    dense = multivariate_normal.logpdf(log.outputs.reshape(-1), mean, cov)
    smoother = KalmanEstimator(OSCILLATOR, dt, sensor_precision=1 / sz**2, process_precision=1 / sw**2,
                               process_kernel_width=s_w, sensor_kernel_width=s_z, input_prior_precision=1 / su**2,
                               input_kernel_width=s_u, known_inputs=False, initial_state=m0, initial_state_std=s0)
    assert smoother.log_likelihood(log.outputs, np.tile(eta, (N, 1))) == pytest.approx(dense, abs=1e-4)
    # missing outputs: the marginal density of the measured ones (the time-varying filter)
    y = log.outputs.copy()
    y[[0, 5, 6, 20, 49]] = np.nan
    kept = np.isfinite(y.reshape(-1))
    marginal = multivariate_normal.logpdf(y.reshape(-1)[kept], mean[kept], cov[np.ix_(kept, kept)])
    assert smoother.log_likelihood(y, np.tile(eta, (N, 1))) == pytest.approx(marginal, abs=1e-4)


def test_log_likelihood_with_measured_inputs_and_a_skipped_time_stamp():
    dt, N = 0.1, 40
    sw, sz = np.array([0.2, 0.2]), np.array([0.1])
    rng = np.random.default_rng(2)
    u = rng.normal(size=(N, 1))
    u[17] = 0.5 * (u[16] + u[18])  # the input the estimator bridges across the skipped sample
    log = attend.simulate(OSCILLATOR, u, dt, kernel_width=0.1, process_std=sw, measurement_std=sz, seed=4)
    m0, s0 = np.zeros(2), np.array([0.7, 0.7])
    mean, cov = dense_output_density(OSCILLATOR, dt, N, process_std=sw, sensor_std=sz, process_width=0.1,
                                     sensor_width=0.1, known_inputs=u, initial_mean=m0, initial_std=s0)
    smoother = KalmanEstimator(OSCILLATOR, dt, sensor_precision=1 / sz**2, process_precision=1 / sw**2,
                               kernel_width=0.1, initial_state=m0, initial_state_std=s0)
    assert smoother.log_likelihood(log.outputs, u) == pytest.approx(multivariate_normal.logpdf(
        log.outputs.reshape(-1), mean, cov), abs=1e-4)
    keep = np.arange(N) != 17  # row 17 dropped from the log: its time stamp is skipped
    marginal = multivariate_normal.logpdf(log.outputs[keep].reshape(-1), mean[keep], cov[np.ix_(keep, keep)])
    value = smoother.log_likelihood(log.outputs[keep], u[keep], time=np.arange(N)[keep] * dt)
    assert value == pytest.approx(marginal, abs=1e-4)


@pytest.mark.parametrize("floor", [1e-4, 1e-2])
def test_a_raised_white_floor_is_white_noise_added_to_the_process_and_sensor_noise(floor):
    """noise_white_floor f: each coloured noise's model has autocorrelation 1 + f at lag 0 (a white part of
    f times its variance) and the kernel's at lags >= 1 to within f (noise_state_space drops singular values
    below 1e-2 f .. f); the filter's log-likelihood is the dense Gaussian density of the outputs under that
    noise model (to the 1e-5 nats it has at the default floor), and it moves with the floor."""
    from scipy.linalg import toeplitz

    from attend.models.noise import kernel_autocorrelation, noise_state_space

    dt, N = 0.1, 50
    sw, sz, su, eta = np.array([0.1, 0.3]), np.array([0.05]), np.array([2.0]), np.array([0.3])
    m0, s0 = np.array([0.2, -0.1]), np.array([1.0, 0.5])
    rng = np.random.default_rng(6)
    log = attend.simulate(OSCILLATOR, rng.normal(size=(N, 1)), dt, kernel_width=0.1, process_std=sw, measurement_std=sz,
                          initial_state=[0.5, 0.0], seed=7)
    outputs = log.outputs + rng.normal(scale=0.01, size=log.outputs.shape)  # fast content the smooth noise lacks
    settings = dict(sensor_precision=1 / sz**2, process_precision=1 / sw**2, kernel_width=0.1,
                    input_prior_precision=1 / su**2, input_kernel_width=0.2, known_inputs=False, initial_state=m0,
                    initial_state_std=s0)
    kernel = kernel_autocorrelation(dt, 0.1)
    densities = {}
    for f in (1e-8, floor):
        noise = noise_state_space(kernel, white_floor=f)
        lagged, vector = [], noise.stationary_covariance @ noise.output
        for _ in range(N):
            lagged.append(noise.output @ vector)
            vector = noise.transition @ vector
        fitted = np.array(lagged)
        assert fitted[0] == pytest.approx(1 + f, rel=1e-9)
        reach = min(N, kernel.size)
        assert np.max(np.abs(fitted[1:reach] - kernel[1:reach])) <= f and np.max(np.abs(fitted[reach:])) <= f
        mean, cov = dense_output_density(OSCILLATOR, dt, N, process_std=sw, sensor_std=sz, process_width=0.1,
                                         sensor_width=0.1, input_mean=eta, input_std=su, input_width=0.2,
                                         initial_mean=m0, initial_std=s0, noise_correlation=toeplitz(fitted))
        densities[f] = multivariate_normal.logpdf(outputs.reshape(-1), mean, cov)
        value = KalmanEstimator(OSCILLATOR, dt, noise_white_floor=f, **settings).log_likelihood(
            outputs, np.tile(eta, (N, 1)))
        assert value == pytest.approx(densities[f], abs=1e-4)
    assert densities[floor] - densities[1e-8] > 10  # the floor matters on this log: the test sees it
    for bad in (0.0, 1.0, -1e-3, float("nan"), True):
        with pytest.raises(attend.AttendInputError, match="noise_white_floor"):
            KalmanEstimator(OSCILLATOR, dt, noise_white_floor=bad, **settings)


def test_white_floor_rises_a_decade_at_a_time_while_each_rise_pays():
    """choose_white_floor on likelihoods given in closed form: it stops at the first decade that gains
    FLAT_LOG_LIKELIHOOD or less over the one below (one evaluation where nothing is raised)."""
    def run(curve):
        calls = []

        def score(floor):
            calls.append(floor)
            return curve(floor)
        return choose_white_floor(score, 1e-8, curve(1e-8)), calls

    peak = {1e-8: 0.0, 1e-7: 50.0, 1e-6: 80.0, 1e-5: 90.0, 1e-4: 91.5, 1e-3: 60.0}
    choice, calls = run(lambda f: peak.get(f, -1e3))
    assert choice.floor == 1e-5 and calls == [1e-7, 1e-6, 1e-5, 1e-4]  # 1e-4 gains 1.5 <= 2: stop
    assert choice.raised and "raised from 1e-08 to 1e-05" in choice.describe() and "+90.0" in choice.describe()
    choice, calls = run(lambda f: 0.0)
    assert choice.floor == 1e-8 and calls == [1e-7] and not choice.raised and choice.describe() == ""
    choice, calls = run(lambda f: 3.0 * np.log10(f))  # 3 nats a decade, all the way up
    assert choice.floor == WHITE_FLOOR_DECADES[-1] and calls == list(WHITE_FLOOR_DECADES)
    choice, _ = run(lambda f: (FLAT_LOG_LIKELIHOOD + 1e-9) * np.log10(f) if f < 1e-6 else -1e3)
    assert choice.floor == 1e-7


def test_profiled_likelihood_is_the_likelihood_at_the_scaled_precisions():
    """Every precision times lambda* (sensor, process, the inputs' prior, the start's): the
    log-likelihood of that model is the closed-form profile, and no other lambda does better."""
    dt, N = 0.1, 60
    rng = np.random.default_rng(7)
    log = attend.simulate(OSCILLATOR, 2.0 * rng.normal(size=(N, 1)), dt, kernel_width=0.1, process_std=[0.3, 0.3],
                          measurement_std=0.2, seed=8)  # noises ~6x and 10x the model's: lambda* << 1
    settings = dict(sensor_precision=1 / 0.02**2, process_precision=1 / 0.05**2, input_prior_precision=0.25,
                    initial_state=np.zeros(2))

    def model(scale):
        scaled = {key: value * scale for key, value in settings.items() if key.endswith("precision")}
        return KalmanEstimator(OSCILLATOR, dt, kernel_width=0.1, input_kernel_width=0.2, known_inputs=False,
                               initial_state=settings["initial_state"], initial_state_std=1 / np.sqrt(scale), **scaled)

    value, scale = profiled_log_likelihood(model(1.0).innovation_terms(log.outputs))
    assert scale < 0.1
    assert model(scale).log_likelihood(log.outputs) == pytest.approx(value, abs=1e-6 * abs(value))
    for factor in (0.5, 2.0):
        assert model(scale * factor).log_likelihood(log.outputs) < value


def _simulated(seed, true_ratio, N=300, dt=0.1):
    """A log of OSCILLATOR drawn from the model itself with the input's prior width true_ratio dt."""
    rng = np.random.default_rng([2903, seed])
    u = 3.0 * correlation_root(N, dt, true_ratio * dt) @ rng.standard_normal((N, 1))
    log = attend.simulate(OSCILLATOR, u, dt, kernel_width=0.05, process_std=[0.05, 0.05], measurement_std=0.02,
                          initial_state=rng.normal(size=2), seed=rng)
    return log.outputs


def _builder(dt=0.1, **settings):
    options = dict(sensor_precision=1 / 0.02**2, process_precision=1 / 0.05**2, kernel_width=0.05,
                   input_prior_precision=1 / 9.0, known_inputs=False)
    options.update(settings)

    def terms(outputs):
        return lambda width: KalmanEstimator(OSCILLATOR, dt, input_kernel_width=width,
                                             **options).innovation_terms(outputs)
    return terms


@pytest.mark.parametrize("input_width", [0.4, 1.6])
def test_width_choice_likelihood_solves_no_riccati_equation_and_is_the_dense_density(input_width):
    """The criterion's filter pass (innovation_terms_on, a complete uniform log) stops its covariance
    recursion where the gain settles instead of solving the Riccati equation; its log-likelihood is
    the dense Gaussian density of the outputs within the settling approximation (0.01 nats) of the
    smoother's own schedule (see the tolerances below)."""
    dt, N = 0.1, 300
    outputs = _simulated(1, 2.0)
    estimator = KalmanEstimator(OSCILLATOR, dt, sensor_precision=1 / 0.02**2, process_precision=1 / 0.05**2,
                                kernel_width=0.05, input_prior_precision=1 / 9.0, known_inputs=False,
                                input_kernel_width=input_width, initial_state=np.zeros(2),
                                initial_state_std=np.array([1.5, 1.5]))
    fast = innovation_terms_on(estimator, outputs, np.zeros((N, 1)))
    assert "steady_predicted" not in estimator.augmented_model  # no Riccati solution was needed
    mean, cov = dense_output_density(OSCILLATOR, dt, N, process_std=[0.05, 0.05], sensor_std=[0.02],
                                     process_width=0.05, sensor_width=0.05, input_mean=[0.0], input_std=[3.0],
                                     input_width=input_width, initial_mean=np.zeros(2),
                                     initial_std=np.array([1.5, 1.5]))
    dense = multivariate_normal.logpdf(outputs.reshape(-1), mean, cov)
    schedule = estimator.innovation_terms(outputs)  # the smoother's schedule, with the Riccati solution
    assert fast.count == schedule.count == N
    # The settled gain's approximation: 0.0024 nats at width 1.6, 1e-5 at 0.4, the same under the
    # default and PRESCOTT one-thread kernels; 0.01 nats is far below the steps between the
    # half-octave widths the search compares (>= 400 nats on this log), so the choice cannot move.
    assert abs(fast.log_likelihood - schedule.log_likelihood) <= 0.01
    # Against the dense density: the filter's and the dense 300-sample density's rounding differ
    # between BLAS kernels by ~0.01 nats on this ill-conditioned log, so the bound is the schedule's
    # own distance plus the approximation's 0.01, not a multiple of one machine's figure.
    assert abs(fast.log_likelihood - dense) <= abs(schedule.log_likelihood - dense) + 0.01
    # a log with a missing value: the estimator's own time-varying pass
    gappy = outputs.copy()
    gappy[40] = np.nan
    assert innovation_terms_on(estimator, gappy, np.zeros((N, 1))) == estimator.innovation_terms(gappy)


def test_chosen_width_recovers_the_true_width_within_the_grid_resolution():
    """On logs drawn from the model, the chosen width is within a factor sqrt(2) (the grid's
    resolution) of the true width in at least 10 of 12 logs at each true width (measured: 12/12 at
    0.5, 2, 3 and 12 sample times, which the grid holds or not; 11/12 at 0.3 and 1.3)."""
    dt = 0.1
    for true_ratio in (0.5, 2.0, 3.0, 12.0):
        hits = 0
        for seed in range(12):
            choice = choose_input_width(_builder()(_simulated(seed, true_ratio)), dt, fallback=0.05)
            assert not choice.flat
            hits += abs(np.log(choice.width / (true_ratio * dt))) <= np.log(np.sqrt(2)) + 1e-9
        assert hits >= 10, (true_ratio, hits)


def test_choice_reports_the_grid_and_its_likelihoods():
    dt = 0.1
    choice = choose_input_width(_builder()(_simulated(0, 2.0)), dt, fallback=0.05)
    assert np.all(np.diff(choice.widths) > 0)
    assert set(np.round(input_width_grid(dt) / dt, 9)) <= set(np.round(choice.widths / dt, 9))
    assert choice.width == choice.best == choice.widths[np.argmax(choice.log_likelihoods)]
    low, high = choice.supported
    assert low <= choice.width <= high
    assert "chosen from the log" in choice.describe() and choice.warning() is None


def test_flat_likelihood_keeps_the_process_width_and_warns():
    """An input that barely reaches the outputs (prior std 1e-4): no width is preferred."""
    dt = 0.1
    outputs = _simulated(1, 2.0) * 0.0 + np.random.default_rng(5).normal(scale=0.02, size=(300, 1))
    choice = choose_input_width(_builder(input_prior_precision=1e8)(outputs), dt, fallback=0.05)
    assert choice.flat
    assert choice.width == 0.05
    assert np.ptp(choice.log_likelihoods) < FLAT_LOG_LIKELIHOOD
    assert "input_kernel_width" in choice.warning() and "does not decide" in choice.warning()


# --- attend estimate: the width of a model file that gives none ----------------------------------

MODEL_FILE = """
model = {{A = [[0.0, 1.0], [-2.0, -0.5]], B = [[0.0], [1.0]], C = [[1.0, 0.0]]}}
outputs = {{columns = ["y"]}}
inputs = [{{name = "u", prior_mean = 0.0, prior_precision = {prior_precision}}}]

[observer]
kernel_width = 0.05
sensor_precision = {sensor_precision}
process_precision = {process_precision}
{extra}
"""


def _estimate(tmp_path, capsys, prior_precision=0.111, extra="", true_ratio=8.0, sensor_precision=2500.0,
              process_precision=400.0):
    from attend.cli import main

    outputs = _simulated(3, true_ratio)
    model, log = tmp_path / "model.toml", tmp_path / "log.csv"
    model.write_text(MODEL_FILE.format(prior_precision=prior_precision, extra=extra, sensor_precision=sensor_precision,
                                       process_precision=process_precision))
    log.write_text("t,y\n" + "\n".join(f"{k * 0.1:.10g},{v:.12g}" for k, v in enumerate(outputs[:, 0])) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        assert main(["estimate", str(model), str(log), "--out", str(tmp_path / "e.csv"), "--no-progress"]) == 0
    return capsys.readouterr()


def test_estimate_chooses_the_input_width_from_the_log_and_says_so(tmp_path, capsys):
    from attend import io, workflows

    captured = _estimate(tmp_path, capsys)
    line = next(line for line in captured.err.splitlines() if "input prior width" in line)
    assert "chosen from the log" in line and "0.8 s" in line  # the true width, 8 samples
    assert "input prior width 0.8 s (chosen from the log)" in captured.out
    model = io.read_model(tmp_path / "model.toml")
    estimator, _ = workflows.estimate_from_files(model, io.read_log(tmp_path / "log.csv"))
    assert estimator.input_kernel_width == pytest.approx(0.8)
    assert estimator.input_width_choice.width == pytest.approx(0.8)
    assert not estimator.input_width_choice.flat
    assert 0.5 < estimator.input_width_choice.noise_scale < 2  # the model is the log's: lambda* ~ 1
    assert not estimator.input_width_choice.white_floor.raised and estimator.noise_white_floor == 1e-8
    assert "attend: warning:" not in captured.err


def test_estimate_raises_the_white_floor_where_the_log_supports_it(tmp_path, capsys):
    """A log from a system 20 % faster than the file's (A and B x 1.2), process noise 4x and sensor noise
    1/4 of the stated ones, the input rougher than the prior (both states measured): the model's smooth
    noise cannot carry the log's fast content; the white part is raised (hundreds of nats a decade on
    these logs), the command line says so, the misfit is still judged on the model as stated."""
    from attend import io, workflows
    from attend.cli import main

    A, B, dt, N = np.array([[0.0, 1.0], [-2.0, -0.5]]), np.array([[0.0], [1.0]]), 0.1, 300
    rng = np.random.default_rng([2904, 0])
    u = 3.0 * correlation_root(N, dt, 0.1) @ rng.standard_normal((N, 1))
    log = attend.simulate(attend.LinearSystem(1.2 * A, 1.2 * B, np.eye(2)), u, dt, kernel_width=0.2,
                          process_std=[0.2, 0.2], measurement_std=0.005, initial_state=rng.normal(size=2), seed=rng)
    model_path, log_path = tmp_path / "model.toml", tmp_path / "log.csv"
    model_path.write_text("""
model = {A = [[0.0, 1.0], [-2.0, -0.5]], B = [[0.0], [1.0]], C = [[1.0, 0.0], [0.0, 1.0]]}
outputs = {columns = ["y1", "y2"]}
inputs = [{name = "u", prior_mean = 0.0, prior_precision = 0.111}]

[observer]
kernel_width = 0.2
sensor_precision = 2500.0
process_precision = 400.0
""")
    log_path.write_text("t,y1,y2\n" + "\n".join(f"{k * dt:.10g},{a:.12g},{b:.12g}"
                                                 for k, (a, b) in enumerate(log.outputs)) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        assert main(["estimate", str(model_path), str(log_path), "--out", str(tmp_path / "e.csv"), "--no-progress"]) == 0
    captured = capsys.readouterr()
    line = next(line for line in captured.err.splitlines() if "input prior width" in line)
    assert "white part of the process and sensor noise raised from 1e-08 to" in line
    assert "white part of w and z 1e-0" in captured.out and "of their variance (chosen from the log)" in captured.out
    estimator, _ = workflows.estimate_from_files(io.read_model(model_path), io.read_log(log_path))
    floors = estimator.input_width_choice.white_floor
    assert floors.raised and estimator.noise_white_floor == floors.floor > 1e-8
    gains = np.diff(floors.log_likelihoods)
    assert np.all(gains[:-1] > FLAT_LOG_LIKELIHOOD) and gains[-1] <= FLAT_LOG_LIKELIHOOD
    assert estimator.input_width_choice.log_likelihoods.max() > floors.log_likelihoods[-2] - 1e-6  # width again
    # jittered time stamps (steps 1 % off dt) keep the numerical floor: their steps use the continuous noise model
    from attend.perception.file_estimators import file_kalman_estimator

    time = np.arange(N) * dt + 0.001 * np.sin(np.arange(N))
    jittered = file_kalman_estimator(io.read_model(model_path), dt, log.outputs, np.zeros((N, 1)), time)
    assert len(jittered.input_width_choice.white_floor.floors) == 1 and jittered.noise_white_floor == 1e-8
    same = file_kalman_estimator(io.read_model(model_path), dt, log.outputs, np.zeros((N, 1)), np.arange(N) * dt)
    assert same.noise_white_floor == floors.floor  # uniform stamps: searched as without them


def test_estimate_warns_when_the_innovations_are_far_from_the_models_prediction(tmp_path, capsys):
    """Every precision 1e4 x too large (stds 100x too small, the input prior's too): lambda* ~ 1e-4,
    one warning naming the precisions; the width is the same as at the right precisions."""
    captured = _estimate(tmp_path, capsys, sensor_precision=2.5e7, process_precision=4e6, prior_precision=1110.0)
    warned = [line for line in captured.err.splitlines() if line.startswith("attend: warning:")
              and "do not fit this log" in line]
    assert len(warned) == 1 and "sensor_precision, process_precision" in warned[0]
    assert "input prior width 0.8 s (chosen from the log)" in captured.out


def test_estimate_keeps_a_given_input_width(tmp_path, capsys):
    captured = _estimate(tmp_path, capsys, extra="input_kernel_width = 0.2")
    assert "chosen from the log" not in captured.err + captured.out
    assert "input prior width 0.2 s ([observer] input_kernel_width)" in captured.out


def test_estimate_warns_when_the_log_does_not_decide_the_input_width(tmp_path, capsys):
    """An input prior so narrow (std 1e-5) that the input cannot move the outputs: the likelihood
    is flat, the process width is kept and one warning names input_kernel_width."""
    captured = _estimate(tmp_path, capsys, prior_precision=1e10)
    warned = [line for line in captured.err.splitlines() if line.startswith("attend: warning:")
              and "input_kernel_width" in line and "does not decide" in line]
    assert len(warned) == 1 and "model.toml" in warned[0]
    assert "input prior width 0.05 s (the process width: the log does not decide it)" in captured.out


def test_unscented_innovation_terms_are_the_filters_log_likelihood():
    """The unscented filter's prediction-error decomposition (the width choice's criterion for nonlinear
    models) sums to the log-likelihood the filter itself accumulates, sample by sample."""
    from attend.models import NonlinearSystem
    from attend.perception.nonlinear_smoothers import unscented_innovation_terms, unscented_kalman

    system = NonlinearSystem(lambda x, v: np.array([x[1], -np.sin(x[0]) - 0.2 * x[1] + v[0]]),
                             lambda x, v: np.array([np.sin(x[0]), x[1]]), n_states=2, n_inputs=1, n_outputs=2)
    rng = np.random.default_rng(4)
    outputs = np.column_stack([np.sin(0.1 * np.arange(80)), 0.1 * np.cos(0.1 * np.arange(80))])
    outputs += 0.05 * rng.standard_normal(outputs.shape)
    options = dict(process_covariance=np.diag([1e-4, 1e-3]), measurement_covariance=np.diag([0.0025, 0.0025]),
                   input_variance=np.array([[0.01]]), input_mean=np.zeros(1), initial_mean=np.zeros(2),
                   initial_covariance=np.eye(2), substeps=4)
    terms = unscented_innovation_terms(system, 0.1, outputs, **options)
    filtered = unscented_kalman(system, 0.1, outputs, smooth=False, spread_draws=None, **options)
    assert terms.count == outputs.size
    assert terms.log_likelihood == pytest.approx(filtered.log_likelihood, rel=1e-12, abs=1e-9)
    assert terms.quadratic > 0


def test_a_likelihood_not_finite_at_any_width_is_an_error_naming_input_kernel_width():
    """(and widths where it is not finite are never chosen)"""
    from attend import AttendInputError
    from attend.perception.kalman_recursions import InnovationTerms

    with pytest.raises(AttendInputError, match=r"input_kernel_width: not given, and the log-likelihood is not finite"):
        choose_input_width(lambda width: InnovationTerms(np.nan, np.nan, 10), 0.1, 0.05)
    choice = choose_input_width(lambda width: InnovationTerms(np.inf if width < 0.05 else width, 5.0, 10), 0.1, 0.05)
    assert choice.width == pytest.approx(0.05) and np.isneginf(choice.log_likelihoods[:2]).all()
