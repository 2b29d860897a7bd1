"""Coloured noise: white noise convolved with a Gaussian kernel of width s (seconds).

Kernel h(t) = exp(-t^2 / (2 s^2)), normalised so that sum_k h(k dt)^2 = 1: convolving unit white
noise with it keeps unit variance per sample. The resulting autocorrelation is

    rho(tau) = exp(-tau^2 / (4 s^2)),

the one assumed by the smoothness precision S (see :mod:`attend.generalized`).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import fftconvolve

from attend._validation import AttendInputError, positive_scalar


def gaussian_kernel(dt: float, kernel_width: float, support: float = 6.0) -> np.ndarray:
    """Samples of h(t) = exp(-t^2/(2 s^2)) for |t| <= support*s, normalised to unit energy."""
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    half = int(np.ceil(support * s / dt))
    t = np.arange(-half, half + 1) * dt
    h = np.exp(-(t**2) / (2 * s**2))
    return h / np.sqrt(np.sum(h**2))


def autocorrelation(tau, kernel_width: float):
    """rho(tau) = exp(-tau^2 / (4 s^2)) for lags tau [s] and kernel width s [s]."""
    s = positive_scalar(kernel_width, "kernel_width", "s")
    return np.exp(-np.asarray(tau, dtype=float) ** 2 / (4 * s**2))


def coloured_noise(
    n_samples: int,
    n_channels: int,
    dt: float,
    kernel_width: float,
    std=1.0,
    seed: int | np.random.Generator | None = 0,
) -> np.ndarray:
    """(n_samples, n_channels) of white noise convolved with the Gaussian kernel.

    ``std`` is the standard deviation per sample: a scalar or one value per channel.
    The white noise is drawn with margins of the kernel's half-length on both sides, so every
    returned sample is a full convolution (no edge transients).
    """
    if n_samples < 1 or n_channels < 0:
        raise AttendInputError(f"n_samples: expected >= 1, got {n_samples}")
    std = np.broadcast_to(np.asarray(std, dtype=float), (n_channels,))
    if not np.all(np.isfinite(std)) or np.any(std < 0):
        raise AttendInputError(f"std: expected finite standard deviations >= 0, got {std}")
    rng = np.random.default_rng(seed)
    kernel = gaussian_kernel(dt, kernel_width)
    margin = len(kernel) - 1
    white = rng.standard_normal((n_samples + margin, n_channels))
    if n_channels == 0:
        return np.zeros((n_samples, 0))
    smooth = fftconvolve(white, kernel[:, None], mode="valid", axes=0)
    return smooth * std
