"""The quadrotor roll plant (attend.control.roll): the identification of the wind's roll acceleration against
synthetic noise of known std and kernel width (oracle), the plant against its closed forms, and the controllers
on it against the continuous-time closed loop."""

import inspect
import re

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.control import LQGController, run, step_metrics
from attend.control import roll
from attend.models.noise import coloured_noise


def test_roll_command_is_the_model_files_b_row():
    # model.toml [roll]: B = [0.374838, -0.374838, -0.374838, 0.374838] on the four motors
    motors = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0], [2.0, 1.0, 1.0, 2.0]])
    assert np.array_equal(roll.roll_command(motors), [1, -1, -1, 1, 2])
    with pytest.raises(AttendInputError, match="motors"):
        roll.roll_command(np.ones((3, 3)))


@pytest.mark.parametrize("width, fraction", [(0.05, 1.0), (0.1, 0.7), (0.15, 0.5)])
def test_autocorrelation_fit_recovers_known_noise(width, fraction):
    dt, n = 1 / 120, 60000
    smooth = coloured_noise(n, 1, dt, width, np.sqrt(fraction), seed=1)[:, 0]
    white = np.random.default_rng(2).standard_normal(n) * np.sqrt(1 - fraction)
    alpha, s = roll.fit_gaussian_autocorrelation(smooth + white, dt, 5, 40)
    # sampling error of an autocorrelation over N samples with correlation time ~ s: ~ sqrt(s / (N dt)) ~ 0.01-0.02
    assert abs(alpha - fraction) < 0.06
    assert abs(s - width) < 0.1 * width


def test_disturbance_samples_vanish_for_a_noiseless_double_integrator():
    dt, b = roll.LOG_DT, roll.ROLL_GAIN
    rng = np.random.default_rng(0)
    motors = rng.uniform(150, 180, (50, 4))
    u = roll.roll_command(motors)
    phi_dot = np.concatenate([[0.3], 0.3 + np.cumsum(b * u[:-1] * dt)])
    assert np.allclose(roll.disturbance_samples(phi_dot, motors), 0.0, atol=1e-9)


def test_identified_wind_on_the_flights():
    # the logs' smooth roll acceleration in wind, against the same estimate without wind (a smaller one)
    try:
        wind = roll.identify_roll_disturbance()
        calm = roll.identify_roll_disturbance(flights=("exp_21_WW_WM_0", "exp_22_WW_WM_0", "exp_24_WW_WM_0",
                                                       "exp_25_WW_WM_0"))
    except AttendInputError:
        pytest.skip("shared quadrotor flight logs not available")
    assert 4.0 < wind.std < 9.0 and 0.05 < wind.kernel_width < 0.2  # measured 6.21 rad/s^2, 0.108 s
    assert wind.std > 2 * calm.std  # measured 2.06 without wind
    # the white remainder is the differentiated rate noise: alike with and without wind (3.3 and 2.8)
    assert abs(wind.white_std - calm.white_std) < 0.5 * calm.white_std


def test_plant_is_the_double_integrator():
    A, B = roll.roll_matrices()
    assert np.array_equal(A, [[0, 1], [0, 0]]) and np.array_equal(B, [[0], [roll.ROLL_GAIN]])
    plant = roll.roll_plant(n_sensors=2, action_limit=50)
    # a constant command u for T seconds from rest: phi = b u T^2 / 2 (exact under zero-order hold)
    world = plant.start(120, 1 / 120, seed=0)
    for _ in range(120):
        world.advance([10.0])
    assert abs(world.x[0] - roll.ROLL_GAIN * 10.0 / 2) < 1e-12 and abs(world.x[1] - roll.ROLL_GAIN * 10.0) < 1e-12
    world = plant.start(2, 1 / 120, seed=0)
    world.advance([1e3])  # saturates at 50
    assert abs(world.x[1] - roll.ROLL_GAIN * 50 / 120) < 1e-12


def test_lqg_on_the_noiseless_roll_plant_matches_the_designed_closed_loop():
    # with no noise and integral action, a 0.2 rad step ends exactly at the reference (type-1 loop), and the
    # response decays at the rate of the LQR's slowest closed-loop eigenvalue
    plant = roll.roll_plant(n_sensors=2)
    A, B = roll.roll_matrices()
    C = np.array([[1.0, 0.0], [1.0, 0.0]])
    lqg = LQGController(A, B, C, 1 / 120, reference=0.2, state_weight=[1e4, 10.0], integral_weight=1e6,
                        process_covariance=1e-6, sensor_covariance=1e-6)
    loop = run(plant, lqg, 4.0, seed=0)
    metrics = step_metrics(loop.time, loop.states[:, 0], 0.2, loop.actions, band=0.02)
    assert abs(loop.states[-1, 0] - 0.2) < 1e-4
    assert metrics.settling_time < 2.0
    from attend.models.linear import zero_order_hold

    Ad, Bd = zero_order_hold(A, B, 1 / 120)
    Aa = np.block([[Ad, np.zeros((2, 1))], [-np.array([[1.0, 0.0]]) / 120, np.ones((1, 1))]])
    Ba = np.vstack([Bd, [[0.0]]])
    K = np.hstack([lqg._Kx, lqg._Ki])
    slowest = np.max(np.abs(np.linalg.eigvals(Aa - Ba @ K)))
    error = np.abs(loop.states[:, 0] - 0.2)
    # from 1 s to 2 s the error shrinks at least as fast as slowest^120 (times a transient factor of 50)
    k1, k2 = 120, 240
    assert error[k2] <= 50 * slowest ** (k2 - k1) * error[k1] + 1e-9


def test_every_argument_is_documented():
    for name, obj in vars(roll).items():
        if name.startswith("_") or not inspect.isfunction(obj) or obj.__module__ != roll.__name__:
            continue
        doc = obj.__doc__ or ""
        for parameter in inspect.signature(obj).parameters:
            assert re.search(rf"(?<![A-Za-z0-9_]){parameter}(?![A-Za-z0-9_])", doc), f"{name}({parameter})"


def _roll_agent(learning=None):
    """The roll agent of benchmarks/bench_control.py (0.2 rad step) at its first tuned point with dy~/da held over
    one sample (before the reference's acceleration was added as a cause)."""
    from attend.control import ActiveInferenceController, GenerativeModel, markov_parameters

    w, process_precision, kappa, s = 9.4872, 2.306e8, 3.087e4, 0.008
    C = np.array([[1.0, 0.0], [1.0, 0.0]])
    model = GenerativeModel.linear([[0.0, 1.0], [-w**2, -2 * w]], [[0.0, 0.0], [w**2, 2 * w]], C,
                                   sensor_precision=1 / 0.002**2, process_precision=process_precision,
                                   cause_prior_precision=np.exp(8), cause_prior=[0.2, 0.0], kernel_width=s,
                                   embedding_order=2, cause_order=1, initial_causes=[0.2, 0.0])
    A, B = roll.roll_matrices()
    G = markov_parameters(A, B, C, np.zeros((2, 1)), 3, hold=1 / 120)  # dy~/da of the action held over a sample
    return ActiveInferenceController(model, 1 / 120, action_gain=kappa, action_jacobian=G, action_limits=(-100, 100),
                                     precision_learning=learning, sensory_orders=2)


def test_learning_reweights_the_degrading_roll_sensor():
    from attend.control import SensorPrecisionLearning
    from attend.control.metrics import itae

    # sensor 2's noise std x10 from t = 2 s: its true precision falls 100-fold against sensor 1's
    plant = roll.roll_plant(disturbance_std=6.2, disturbance_kernel_width=0.108, sensor_std=0.002,
                            sensor_kernel_width=0.01, action_limit=100.0,
                            sensor_noise_scale=lambda t: np.array([1.0, 10.0 if t >= 2.0 else 1.0]))
    learning = SensorPrecisionLearning(time_constant=0.25, level="relative", orders="all")
    for seed in range(3):
        fixed = run(plant, _roll_agent(), 4.0, seed=seed)
        learned = run(plant, _roll_agent(learning), 4.0, seed=seed)
        before = learned.sensor_precision[int(1.9 * 120)]
        after = learned.sensor_precision[-1]
        assert 0.5 < before[0] / before[1] < 2.0  # equal sensors: equal shares (measured 0.66-1.04)
        assert after[0] / after[1] > 10.0  # measured 75-118; the oracle ratio is 100
        # the relative level keeps the designed total precision
        assert abs(after.sum() - 2 / 0.002**2) < 1e-6 * after.sum()
        # and the reweighting lowers ITAE (measured 0.27 -> 0.033, 0.18 -> 0.043, 0.14 -> 0.043)
        assert itae(learned.time, learned.states[:, 0], 0.2) < 0.8 * itae(fixed.time, fixed.states[:, 0], 0.2)
