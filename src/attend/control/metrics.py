"""Closed-loop performance figures: ITAE, overshoot, settling time and control effort.

    ITAE = int_0^T t |r(t) - y(t)| dt        effort = int_0^T |a(t)|^2 dt

evaluated on the true controlled variable (not the noisy measurement), by the rectangle rule
on the samples.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError


class StepMetrics(NamedTuple):
    """itae [unit * s^2]; overshoot [% of the step]; settling_time [s] (first time after which |r - y|
    stays within ``band`` of the step; inf if it never does); effort int |a|^2 dt [action unit^2 s]."""

    itae: float
    overshoot: float
    settling_time: float
    effort: float


def _arrays(time, output, reference, action):
    t = np.asarray(time, dtype=float).reshape(-1)
    y = np.asarray(output, dtype=float).reshape(-1)
    r = np.broadcast_to(np.asarray(reference, dtype=float), t.shape) if np.ndim(reference) == 0 else \
        np.asarray(reference, dtype=float).reshape(-1)
    a = np.asarray(action, dtype=float)
    a = a.reshape(t.shape[0], -1) if a.size else np.zeros((t.shape[0], 1))
    if not (y.shape == t.shape == r.shape) or a.shape[0] != t.shape[0]:
        raise AttendInputError(f"step_metrics: time, output, reference and action need one row per sample; got "
                               f"{t.shape}, {y.shape}, {r.shape}, {a.shape}")
    if t.shape[0] < 2:
        raise AttendInputError("time: expected at least 2 samples")
    return t, y, r, a


def itae(time, output, reference) -> float:
    """int t |r - y| dt over the samples (time [s], output y and reference r: (N,) or r a number)."""
    t, y, r, _ = _arrays(time, output, reference, np.zeros(np.size(time)))
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2]))
    return float(np.sum(t * np.abs(r - y) * dt))


def step_metrics(time, output, reference, action, *, start: float = 0.0, band: float = 0.02) -> StepMetrics:
    """Figures of a step response: the step in the reference happens at ``start`` [s] from output[start];
    ``band``: settling band as a fraction of the step size; time from ``start`` in ITAE.

    time (N,) [s]; output: true controlled variable (N,); reference (N,) or a number; action (N, k)."""
    t, y, r, a = _arrays(time, output, reference, action)
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2]))
    after = t >= start
    tau = t - start
    error = r - y
    itae_value = float(np.sum((tau * np.abs(error) * dt)[after]))
    effort = float(np.sum((a**2).sum(axis=1) * dt))
    initial = y[after][0]
    final = r[-1]
    size = final - initial
    if size == 0:
        return StepMetrics(itae_value, float("nan"), float("nan"), effort)
    overshoot = max(0.0, float(np.max((y[after] - final) * np.sign(size))) / abs(size) * 100.0)
    outside = np.flatnonzero(after & (np.abs(error) > band * abs(size)))
    if outside.size == 0:
        settling = 0.0
    elif outside[-1] == t.shape[0] - 1:
        settling = float("inf")
    else:
        settling = float(t[outside[-1] + 1] - start)
    return StepMetrics(itae_value, overshoot, settling, effort)
