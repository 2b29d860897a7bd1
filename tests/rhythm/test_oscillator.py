"""Precision oscillator: closed-form values, period, troughs, threshold, bad input."""

import math

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.rhythm import PrecisionOscillator


def test_multiplier_closed_form_and_period():
    osc = PrecisionOscillator(frequency=5.0, depth=0.8, baseline_multiplier=2.0, phase=0.3)
    t = np.linspace(0.0, 1.0, 101)
    expected = 2.0 * np.exp(0.8 * np.sin(2 * np.pi * 5.0 * t + 0.3))
    np.testing.assert_allclose(osc.multiplier(t), expected, rtol=1e-14)
    np.testing.assert_allclose(osc.multiplier(t + osc.period), osc.multiplier(t), rtol=1e-12)
    np.testing.assert_allclose(osc.log_multiplier(t), np.log(expected), rtol=1e-12)
    assert osc.period == pytest.approx(0.2)


def test_peaks_troughs_and_extremes():
    osc = PrecisionOscillator(frequency=4.0, depth=1.0, baseline_multiplier=1.5, phase=0.7)
    troughs = osc.trough_times(0.0, 2.0)
    peaks = osc.peak_times(0.0, 2.0)
    assert len(troughs) == 8 and len(peaks) == 8
    np.testing.assert_allclose(np.diff(troughs), osc.period)
    np.testing.assert_allclose(osc.multiplier(troughs), 1.5 * math.exp(-1.0))
    np.testing.assert_allclose(osc.multiplier(peaks), 1.5 * math.exp(1.0))
    assert np.all((troughs >= 0) & (troughs < 2.0))
    fine = np.linspace(0, osc.period, 100001)
    assert osc.multiplier(fine).min() == pytest.approx(1.5 * math.exp(-1.0), rel=1e-8)


@pytest.mark.parametrize("fraction", [0.1, 0.25, 0.5, 0.8])
def test_threshold_leaves_the_requested_fraction_in_the_trough(fraction):
    osc = PrecisionOscillator(frequency=3.0, depth=1.3)
    t = (np.arange(200000) + 0.5) / 200000 * osc.period
    below = np.mean(osc.multiplier(t) < osc.threshold(fraction))
    assert below == pytest.approx(fraction, abs=1e-4)


def test_mean_multiplier_is_bessel():
    osc = PrecisionOscillator(frequency=6.0, depth=1.7, baseline_multiplier=0.5)
    t = (np.arange(100000) + 0.5) / 100000 * osc.period
    assert osc.mean_multiplier() == pytest.approx(osc.multiplier(t).mean(), rel=1e-9)


def test_no_depth_no_rhythm():
    osc = PrecisionOscillator(frequency=4.0, depth=0.0, baseline_multiplier=3.0)
    np.testing.assert_allclose(osc.multiplier(np.linspace(0, 1, 17)), 3.0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(frequency=0.0), "frequency"),
    (dict(frequency=-4.0), "frequency"),
    (dict(frequency=float("nan")), "frequency"),
    (dict(depth=-0.1), "depth"),
    (dict(depth="deep"), "depth"),
    (dict(baseline_multiplier=0.0), "baseline_multiplier"),
    (dict(phase=float("inf")), "phase"),
])
def test_bad_input_names_the_field(kwargs, field):
    with pytest.raises(AttendInputError, match=field):
        PrecisionOscillator(**kwargs)
    assert issubclass(AttendInputError, ValueError)


@pytest.mark.parametrize("fraction", [0.0, 1.0, -0.2, 1.5])
def test_bad_action_fraction(fraction):
    with pytest.raises(AttendInputError, match="action_fraction"):
        PrecisionOscillator().threshold(fraction)
