"""Missing samples and jittered time stamps in the coloured-noise Kalman smoother and filter.

Oracles: the exact Gaussian posterior with the missing measurements left out
(:func:`attend.perception.references.exact_posterior` with NaN outputs), the exact posterior of the
irregularly sampled continuous-time model (its ``time=``), and a dense conditioning on the
Kalman model's own augmented state, which isolates the recursions from the noise fit.
"""

import numpy as np
import pytest
from scipy.linalg import expm

import attend
from attend import AttendInputError
from attend.models.noise import autocorrelation, continuous_noise_state_space
from attend.perception.kalman import KalmanEstimator
from attend.perception.references import exact_posterior

from test_kalman import random_system

DT, SW, SZ = 0.1, 0.05, 0.03


def _case(seed, process_ratio, sensor_ratio, n_samples=300):
    rng = np.random.default_rng(seed)
    system = random_system(rng, 3, 2, 1)
    widths = dict(process_kernel_width=process_ratio * DT, sensor_kernel_width=sensor_ratio * DT)
    estimator = KalmanEstimator(system, DT, sensor_precision=SZ**-2, process_precision=SW**-2,
                                initial_state=np.zeros(3), **widths)
    return rng, system, widths, estimator


def _scale(reference):
    return np.abs(reference).max()


# --- missing outputs ---------------------------------------------------------------------------

# (seed, s_w / dt, s_z / dt, tolerance on the means as a fraction of their scale). The tolerance is
# the conditioning of the case, the same as the regular smoother meets on the complete log: with
# both noises smooth the posterior hangs on the noise spectra far down their tails, where the
# finite noise models (fit ~1e-7) and the oracle's exact kernel differ: ~1e-3 of the scale.
MISSING_CASES = [(1, 0.5, 5.0, 1e-6), (2, 5.0, 0.0, 1e-6), (3, 0.0, 3.0, 1e-6), (0, 2.0, 2.0, 3e-3)]


@pytest.mark.parametrize("seed, process_ratio, sensor_ratio, tolerance", MISSING_CASES)
def test_missing_outputs_reach_the_exact_posterior_without_them(seed, process_ratio, sensor_ratio, tolerance):
    rng, system, widths, estimator = _case(seed, process_ratio, sensor_ratio)
    N = 300
    u = np.sin(2 * np.pi * np.arange(N) * DT / 4)[:, None]
    log = attend.simulate(system, u, DT, process_std=SW, measurement_std=SZ, seed=seed, **widths)
    y = log.outputs.copy()
    y[rng.random(N) < 0.1] = np.nan            # whole rows
    y[rng.random(N) < 0.1, 0] = np.nan         # single channels
    y[120:135] = np.nan                        # a long gap: the smoother bridges it
    exact = exact_posterior(system, DT, y, u, process_std=SW, measurement_std=SZ, causal=True, **widths)
    smooth, causal = estimator.estimate(y, u), estimator.filter(y, u)
    assert smooth.states.shape == (N, 3) and np.all(np.isfinite(smooth.states))
    scale = _scale(exact.states)
    np.testing.assert_allclose(smooth.states, exact.states, atol=tolerance * scale)
    np.testing.assert_allclose(causal.states, exact.causal_states, atol=3 * tolerance * scale)
    np.testing.assert_allclose(smooth.state_std[1:], exact.state_std[1:], rtol=max(30 * tolerance, 1e-4))
    assert np.all(smooth.state_std[127] > smooth.state_std[100])  # the gap shows in the std


def test_skipped_time_stamps_equal_missing_rows():
    """A time stamp that skips k samples is k - 1 samples without a measurement."""
    rng, system, widths, estimator = _case(4, 2.0, 1.0)
    N = 200
    t = np.arange(N) * DT
    u = (0.3 + 0.05 * t)[:, None]  # linear: interpolating it over the skipped samples is exact
    log = attend.simulate(system, u, DT, process_std=SW, measurement_std=SZ, seed=4, **widths)
    keep = rng.random(N) > 0.1
    keep[[0, 1, -1]] = True
    keep[50:53] = False
    y = np.where(keep[:, None], log.outputs, np.nan)
    for run in (estimator.estimate, estimator.filter):
        with_nan = run(y, u)
        skipped = run(log.outputs[keep], u[keep], time=t[keep])
        np.testing.assert_allclose(skipped.time, t[keep])
        np.testing.assert_allclose(skipped.states, with_nan.states[keep], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(skipped.state_std, with_nan.state_std[keep], rtol=1e-10, atol=1e-14)


def test_complete_logs_with_time_stamps_take_the_regular_path():
    rng, system, widths, estimator = _case(5, 1.0, 1.0)
    u = np.zeros((100, 1))
    log = attend.simulate(system, u, DT, process_std=SW, measurement_std=SZ, seed=5, **widths)
    plain = estimator.estimate(log.outputs, u)
    stamped = estimator.estimate(log.outputs, u, time=10.0 + np.arange(100) * DT)
    np.testing.assert_array_equal(stamped.states, plain.states)
    np.testing.assert_allclose(stamped.time, 10.0 + np.arange(100) * DT)


# --- jittered time stamps ------------------------------------------------------------------------

def _gp(rng, t, width, channels, std):
    """Samples at the times t of a Gaussian process with autocorrelation rho (white for width 0)."""
    if width == 0:
        return rng.standard_normal((len(t), channels)) * std
    values, vectors = np.linalg.eigh(autocorrelation(t[:, None] - t[None, :], width))
    return (vectors * np.sqrt(np.clip(values, 0, None))) @ rng.standard_normal((len(t), channels)) * std


def simulate_irregular(system, u, t, widths, rng):
    """x[k] = Ad(h) x[k-1] + Bd(h) u[k-1] + h w(t[k-1]), y = C x + z(t[k]), h = t[k] - t[k-1]."""
    w = _gp(rng, t, widths["process_kernel_width"], system.n_states, SW)
    z = _gp(rng, t, widths["sensor_kernel_width"], system.n_outputs, SZ)
    x = np.zeros((len(t), system.n_states))
    for k in range(1, len(t)):
        Ad, Bd = system.discretize(t[k] - t[k - 1])
        x[k] = Ad @ x[k - 1] + Bd @ u[k - 1] + (t[k] - t[k - 1]) * w[k - 1]
    return x, x @ system.C.T + z


def _jittered(rng, N, fraction):
    """k dt + e_k, e_k uniform within +-fraction/2 dt: steps within +-fraction of dt."""
    return np.arange(N) * DT + rng.uniform(-fraction / 2, fraction / 2, N) * DT


def test_white_noise_jitter_is_exact():
    """White noises need no noise model: per-step discretisation meets the oracle to rounding."""
    rng, system, widths, estimator = _case(6, 0.0, 0.0)
    N = 200
    t = _jittered(rng, N, 0.3)
    u = np.sin(t)[:, None]
    x, y = simulate_irregular(system, u, t, widths, rng)
    exact = exact_posterior(system, DT, y, u, process_std=SW, measurement_std=SZ, causal=True, time=t, **widths)
    smooth, causal = estimator.estimate(y, u, time=t), estimator.filter(y, u, time=t)
    scale = _scale(exact.states)
    np.testing.assert_allclose(smooth.states, exact.states, atol=1e-7 * scale)
    np.testing.assert_allclose(causal.states, exact.causal_states, atol=1e-7 * scale)
    np.testing.assert_allclose(smooth.state_std[1:], exact.state_std[1:], rtol=1e-5)


JITTER_CASES = [(0, 2.0, 2.0), (1, 0.5, 5.0), (3, 0.0, 3.0), (6, 10.0, 2.0)]


@pytest.mark.parametrize("seed, process_ratio, sensor_ratio", JITTER_CASES)
def test_jitter_reaches_the_exact_posterior_of_the_irregular_model(seed, process_ratio, sensor_ratio):
    """Steps within +-10 % of dt, coloured noises sampled at the true times; the oracle's noises get
    the white floor of the Kalman's noise models. The tolerance is the noise fit's: the order-16
    continuous model has its spectrum within 4.5 % of the Gaussian's, which moves the estimates by
    ~1e-3 of their scale (~1e-3 of their std) and their SSE by < 1 %."""
    rng, system, widths, estimator = _case(seed, process_ratio, sensor_ratio)
    N = 300
    t = _jittered(rng, N, 0.1)
    u = np.sin(2 * np.pi * t / 4)[:, None]
    x, y = simulate_irregular(system, u, t, widths, rng)
    exact = exact_posterior(system, DT, y, u, process_std=SW, measurement_std=SZ, time=t, white_floor=1e-8,
                            **widths)
    smooth = estimator.estimate(y, u, time=t)
    np.testing.assert_allclose(smooth.time, t)
    np.testing.assert_allclose(smooth.states, exact.states, atol=5e-3 * _scale(exact.states))
    assert np.median(np.abs(smooth.state_std[1:] / exact.state_std[1:] - 1)) < 1e-2
    sse = lambda estimate: np.sum((estimate - x) ** 2)  # noqa: E731
    assert sse(smooth.states) == pytest.approx(sse(exact.states), rel=0.02)


def test_jittered_smoother_is_the_posterior_of_its_own_model():
    """Dense conditioning on the augmented model the smoother runs (same noise fit, steps with
    gaps and jitter): the recursions themselves are exact, to rounding."""
    rng, system, widths, estimator = _case(0, 2.0, 2.0)
    N = 60
    t = _jittered(rng, N, 0.4)
    t[30:] += 2 * DT  # two skipped samples
    _, y = simulate_irregular(system, np.zeros((N, 1)), t, widths, rng)
    y[rng.random(N) < 0.15, 1] = np.nan
    grid_time = np.sort(np.concatenate([t, t[29] + (t[30] - t[29]) * np.array([1, 2]) / 3]))
    model = estimator.continuous_model()
    steps = [estimator.continuous_step(h)[:2] for h in np.diff(grid_time)]
    P = model["stationary"].copy()
    P[:3, :3] = 0.0  # initial_state known
    covariances = [P]
    for T, Q in steps:
        covariances.append(T @ covariances[-1] @ T.T + Q)
    M = len(grid_time)
    cross = np.empty((M, M), dtype=object)  # Cov(a_j, a_i) for j >= i
    for i in range(M):
        block = covariances[i]
        for j in range(i, M):
            if j > i:
                block = steps[j - 1][0] @ block
            cross[j, i] = block
    rows = np.searchsorted(grid_time, t)
    H, m = model["H"], 2
    measured = [(rows[k], c) for k in range(N) for c in range(m) if np.isfinite(y[k, c])]
    Kyy = np.array([[H[c] @ (cross[max(a, b), min(a, b)] if a >= b else cross[b, a].T) @ H[d]
                     for (b, d) in measured] for (a, c) in measured])
    Kxy = np.array([[(cross[a, b] if a >= b else cross[b, a].T)[:3] @ H[d] for (b, d) in measured]
                    for a in rows])  # (N, measurements, 3)
    values = np.array([y[np.searchsorted(rows, a), c] for a, c in measured])
    dense = np.einsum("kmi,m->ki", Kxy, np.linalg.solve(Kyy, values))
    smooth = estimator.estimate(y, np.zeros((N, 1)), time=t)
    np.testing.assert_allclose(smooth.states, dense, atol=1e-8 * _scale(dense))


def test_continuous_noise_model_matches_the_gaussian_process():
    model = continuous_noise_state_space(0.3)
    assert model.order == 16 and model.spectrum_error < 0.05 and model.autocorrelation_error < 0.015
    lags = np.linspace(0, 1.5, 31)
    readout, stationary = model.readout, model.stationary_covariance
    modelled = [readout @ (model.step(lag, 0.3)[0] if lag else np.eye(17)) @ stationary @ readout for lag in lags]
    expected = np.exp(-lags**2 / (4 * 0.3**2)) * (1 - model.white_floor) + (lags == 0) * model.white_floor
    np.testing.assert_allclose(modelled, expected, atol=0.015)
    for step in (1e-3, 0.05, 0.3, 3.0):
        T, Q = model.step(step, 0.3)
        np.testing.assert_allclose(T[:-1, :-1], expm(model.drift * step / 0.3), atol=1e-12)
        np.testing.assert_allclose(T @ stationary @ T.T + Q, stationary, atol=1e-12)  # stationary
        assert np.linalg.eigvalsh(Q).min() > -1e-13
    white = continuous_noise_state_space(0.0)
    assert white.order == 0 and np.array_equal(white.step(0.1, 0.0)[1], [[1.0]])


# --- the online filter ---------------------------------------------------------------------------

def _online(estimator, outputs, inputs, times=None, jittered=False):
    online = estimator.online(jittered=jittered)
    rows = [online.step(outputs[k], inputs[k], None if times is None else times[k]) for k in range(len(outputs))]
    return np.array([row[0] for row in rows]), np.array([row[2] for row in rows])


def test_online_filter_with_gaps_and_jitter_equals_the_batch_filter():
    rng, system, widths, estimator = _case(2, 2.0, 1.0)
    N = 300
    t = np.arange(N) * DT
    u = np.full((N, 1), 0.3)  # constant: the online filter holds it over skipped stamps
    log = attend.simulate(system, u, DT, process_std=SW, measurement_std=SZ, seed=2, **widths)
    y = log.outputs.copy()
    y[rng.random(N) < 0.05] = np.nan
    y[rng.random(N) < 0.05, 1] = np.nan
    keep = rng.random(N) > 0.05
    keep[0] = True
    jittered = _jittered(rng, N, 0.1)
    for times, jitter in ((None, False), (t, False), (jittered, True)):
        stamps = None if times is None else times[keep]
        batch = estimator.filter(y[keep], u[keep], time=stamps)
        states, std = _online(estimator, y[keep], u[keep], stamps, jitter)
        scale = _scale(batch.states)
        np.testing.assert_allclose(states, batch.states, atol=1e-7 * scale)
        np.testing.assert_allclose(std, batch.state_std, rtol=1e-6)


# --- bad input -----------------------------------------------------------------------------------

@pytest.mark.parametrize("times, message", [
    ([0.0, 0.1, 0.2, 0.15, 0.4], r"time: row 3: time stamp before the previous one \(row 3: 0.15 s, row 2: 0.2 s\)"),
    ([0.0, 0.1, 0.2, 0.2, 0.4], r"time: row 3: time stamp equal to the previous one"),
    ([0.0, 0.1, 0.13, 0.3, 0.4], r"time: row 2: step of 0.03 s \(row 1 to row 2\) is shorter than half the sample "
                                 r"time dt = 0.1 s"),
    ([0.0, 0.1, np.nan, 0.3, 0.4], r"time: row 2: expected finite time stamps"),
    ([0.0, 0.1, 0.2, 0.3], r"time: expected 5 time stamps \(one per sample\), got 4"),
])
def test_bad_time_stamps_name_the_rows(times, message):
    _, system, widths, estimator = _case(7, 1.0, 1.0)
    with pytest.raises(AttendInputError, match=message):
        estimator.estimate(np.zeros((5, 2)), np.zeros((5, 1)), time=times)


def test_bad_gaps_name_the_field_and_rows():
    _, system, widths, estimator = _case(7, 1.0, 1.0)
    y, u = np.zeros((40, 2)), np.zeros((40, 1))
    u[10:14] = np.nan
    with pytest.raises(AttendInputError, match=r"inputs 'u1': 4 consecutive missing samples between row 9 and row 14; "
                                               r"expected gaps of at most 3"):
        estimator.estimate(y, u)
    u = np.zeros((40, 1))
    u[0] = np.nan
    with pytest.raises(AttendInputError, match=r"inputs 'u1': 1 consecutive missing sample before row 1 \(the start"):
        estimator.estimate(y, u)
    with pytest.raises(AttendInputError, match=r"inputs .u1.: 4 consecutive missing samples between row 1 and row 2"):
        estimator.estimate(y[[0, 1, 2, 3]], np.zeros((4, 1)), time=[0.0, 0.1, 0.6, 0.7])  # 4 skipped samples
    with pytest.raises(AttendInputError, match=r"outputs: expected finite numbers \(NaN for a missing value\), "
                                               r"found inf"):
        estimator.estimate(np.full((40, 2), np.inf), np.zeros((40, 1)))
    with pytest.raises(AttendInputError, match="outputs: every value is missing"):
        estimator.estimate(np.full((40, 2), np.nan), np.zeros((40, 1)))


def test_bad_online_time_stamps_are_errors():
    _, system, widths, estimator = _case(7, 1.0, 1.0)
    online = estimator.online()
    online.step([0.0, 0.0], [0.0], time=1.0)
    with pytest.raises(AttendInputError, match="time: 1 s is not after the previous sample's 1 s"):
        online.step([0.0, 0.0], [0.0], time=1.0)
    with pytest.raises(AttendInputError, match=r"time: step of 0.105 s is not a whole number of sample times dt = "
                                               r"0.1 s; for jittered time stamps build the filter with "
                                               r"estimator.online\(jittered=True\)"):
        online.step([0.0, 0.0], [0.0], time=1.105)
    online.step([0.0, 0.0], [0.0], time=1.1)  # the failed calls changed nothing
    with pytest.raises(AttendInputError, match="step input_value"):
        online.step([0.0, 0.0], [np.nan], time=1.2)
    with pytest.raises(AttendInputError, match=r"time: required at every step of a filter built with "
                                               r"online\(jittered=True\)"):
        estimator.online(jittered=True).step([0.0, 0.0], [0.0])
