"""The precision oscillator: a rhythm on sensory precision (paper Sec. 2.3, Fig. 1).

    pi(t) = pi_0 * exp(a * sin(2 pi f t + phi))

pi(t)  precision multiplier [dimensionless]: multiplies the sensor's precision (not to be
       confused with the "precision gain" of attend.action, an expected trace reduction)
pi_0   ``baseline_multiplier``: the geometric-mean multiplier over a cycle
a      ``depth``: log-amplitude of the modulation (a = 0: no rhythm)
f      ``frequency`` [Hz] (theta: 3-8 Hz in the brain)
phi    ``phase`` [rad] at t = 0

High precision (near the peaks): perceive, i.e. assimilate data. Low precision (the troughs):
act, i.e. move the sensor (a saccade). A fraction q of each cycle (``action_fraction``) lies in
the trough when the perception threshold is

    pi_threshold = pi_0 * exp(-a cos(pi q)),

because sin(theta) < s* = -cos(pi q) on an arc of length pi + 2 arcsin(s*) = 2 pi q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from attend._validation import AttendInputError, positive_scalar


def _finite(value, field: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected a finite number, got {value!r}") from None
    if not math.isfinite(number):
        raise AttendInputError(f"{field}: expected a finite number, got {value!r}")
    return number


def _fraction(value, field: str) -> float:
    number = _finite(value, field)
    if not 0.0 < number < 1.0:
        raise AttendInputError(f"{field}: expected a fraction strictly between 0 and 1, got {value!r}")
    return number


@dataclass(frozen=True)
class PrecisionOscillator:
    """pi(t) = pi_0 exp(a sin(2 pi f t + phi)): a rhythmic multiplier on sensory precision.

    Parameters: ``frequency`` f [Hz] > 0 (or cycles per iteration when the clock counts
    iterations), ``depth`` a >= 0 [dimensionless], ``baseline_multiplier`` pi_0 > 0
    [dimensionless], ``phase`` phi [rad].
    """

    frequency: float = 4.0
    depth: float = 1.0
    baseline_multiplier: float = 1.0
    phase: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "frequency", positive_scalar(self.frequency, "frequency", "Hz"))
        depth = _finite(self.depth, "depth")
        if depth < 0:
            raise AttendInputError(f"depth: expected a number >= 0 (log-amplitude), got {self.depth!r}")
        object.__setattr__(self, "depth", depth)
        object.__setattr__(self, "baseline_multiplier", positive_scalar(self.baseline_multiplier, "baseline_multiplier"))
        object.__setattr__(self, "phase", _finite(self.phase, "phase"))

    @property
    def period(self) -> float:
        """T = 1 / f [s]."""
        return 1.0 / self.frequency

    def phase_angle(self, time) -> np.ndarray:
        """theta(t) = 2 pi f t + phi [rad], for ``time`` [s] (scalar or array)."""
        return 2.0 * np.pi * self.frequency * np.asarray(time, dtype=float) + self.phase

    def multiplier(self, time) -> np.ndarray:
        """pi(t) = pi_0 exp(a sin theta(t)) [dimensionless] at ``time`` [s] (scalar or array)."""
        return self.baseline_multiplier * np.exp(self.depth * np.sin(self.phase_angle(time)))

    def log_multiplier(self, time) -> np.ndarray:
        """log pi(t) = log pi_0 + a sin theta(t) at ``time`` [s] (scalar or array)."""
        return math.log(self.baseline_multiplier) + self.depth * np.sin(self.phase_angle(time))

    def threshold(self, action_fraction: float) -> float:
        """pi_threshold = pi_0 exp(-a cos(pi q)): below it lies a fraction q = ``action_fraction`` of each cycle."""
        q = _fraction(action_fraction, "action_fraction")
        return self.baseline_multiplier * math.exp(-self.depth * math.cos(math.pi * q))

    def trough_times(self, start: float, stop: float) -> np.ndarray:
        """Times t in [``start``, ``stop``) [s] of the minima of pi: theta(t) = -pi/2 + 2 pi k."""
        return self._times_of_angle(-0.5 * np.pi, start, stop)

    def peak_times(self, start: float, stop: float) -> np.ndarray:
        """Times t in [``start``, ``stop``) [s] of the maxima of pi: theta(t) = pi/2 + 2 pi k."""
        return self._times_of_angle(0.5 * np.pi, start, stop)

    def _times_of_angle(self, angle: float, start: float, stop: float) -> np.ndarray:
        omega = 2.0 * np.pi * self.frequency
        first = math.ceil((omega * start + self.phase - angle) / (2.0 * np.pi) - 1e-12)
        last = math.ceil((omega * stop + self.phase - angle) / (2.0 * np.pi) - 1e-12)
        k = np.arange(first, last)
        return (angle + 2.0 * np.pi * k - self.phase) / omega

    def mean_multiplier(self) -> float:
        """Time average of pi over a cycle: pi_0 I_0(a) (modified Bessel function of order 0)."""
        from scipy.special import i0

        return float(self.baseline_multiplier * i0(self.depth))
