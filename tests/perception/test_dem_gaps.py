"""DEM on logs with missing samples and jittered time stamps: short gaps bridged by linear
interpolation onto the uniform grid its embedding needs, long ones refused naming the rows."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.models.linear import simulate
from attend.models.problems import convolution_model
from attend.perception.dem import DEMObserver

DT = 0.1


def _observer():
    return DEMObserver(convolution_model(), DT, kernel_width=0.5, sensor_precision=np.exp(8),
                       process_precision=np.exp(6), known_inputs=True, embedding_order=3, input_order=2)


def _log(n_samples=200):
    t = np.arange(n_samples) * DT
    u = np.exp(-0.25 * (t - 8) ** 2)[:, None]
    log = simulate(convolution_model(), u, DT, kernel_width=0.5, process_std=np.exp(-3), measurement_std=np.exp(-4),
                   seed=3)
    return t, u, log


def test_short_gaps_are_bridged_by_linear_interpolation():
    """A missing value equals the one interpolated from its neighbours, so a log whose values
    there *are* the interpolation gives the same estimates."""
    t, u, log = _log()
    observer = _observer()
    y, filled = log.outputs.copy(), log.outputs.copy()
    for start, length in ((20, 1), (60, 3), (101, 2)):
        before, after = y[start - 1], y[start + length]
        for j in range(length):
            filled[start + j] = before + (after - before) * (j + 1) / (length + 1)
        y[start: start + length] = np.nan
    y[140, 0] = np.nan  # a single channel
    filled[140, 0] = 0.5 * (filled[139, 0] + filled[141, 0])
    gappy, reference = observer.estimate(y, u), observer.estimate(filled, u)
    assert gappy.states.shape == (200, observer.system.n_states)
    np.testing.assert_allclose(gappy.states, reference.states, rtol=1e-12, atol=1e-12)


def test_skipped_and_jittered_time_stamps_are_resampled_to_the_grid():
    t, u, log = _log()
    observer = _observer()
    keep = np.ones(200, dtype=bool)
    keep[[30, 31, 90]] = False
    skipped = observer.estimate(log.outputs[keep], u[keep], time=t[keep])
    assert skipped.states.shape == (keep.sum(), observer.system.n_states)
    np.testing.assert_allclose(skipped.time, t[keep])
    complete = observer.estimate(log.outputs, u)
    # the bridged samples move the estimates near them; long after, they are the complete log's
    np.testing.assert_allclose(skipped.states[-40:], complete.states[keep][-40:], atol=1e-6)
    # jitter: the log resampled onto k dt, the estimates back at the stamps (here: a smooth signal,
    # so the estimates stay within a fraction of their std of the uniform log's)
    jittered = t + np.random.default_rng(0).uniform(-0.02, 0.02, 200) * DT
    resampled = observer.estimate(np.column_stack([np.interp(jittered, t, c) for c in log.outputs.T]),
                                  np.interp(jittered, t, u[:, 0])[:, None], time=jittered)
    np.testing.assert_allclose(resampled.time, jittered)
    assert np.max(np.abs(resampled.states - complete.states)[20:-20] / complete.state_std[20:-20]) < 0.2


def test_long_gaps_are_refused_naming_the_rows():
    t, u, log = _log()
    observer = _observer()
    y = log.outputs.copy()
    y[50:54, 0] = np.nan
    with pytest.raises(AttendInputError, match=r"outputs 'y1': 4 consecutive missing samples between row 49 and "
                                               r"row 54; expected gaps of at most 3"):
        observer.estimate(y, u)
    keep = np.ones(200, dtype=bool)
    keep[100:105] = False
    with pytest.raises(AttendInputError, match=r"outputs 'y1': 5 consecutive missing samples between row 99 "
                                               r"and row 100"):
        observer.estimate(log.outputs[keep], u[keep], time=t[keep])
    with pytest.raises(AttendInputError, match=r"time: row 3: time stamp before the previous one"):
        observer.estimate(log.outputs[:5], u[:5], time=[0.0, 0.1, 0.2, 0.1, 0.4])
