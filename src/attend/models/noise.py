"""Coloured noise: white noise convolved with a Gaussian kernel of width s (seconds).

Kernel h(t) = exp(-t^2 / (2 s^2)), normalised so that sum_k h(k dt)^2 = 1: convolving unit white
noise with it keeps unit variance per sample. The resulting autocorrelation is

    rho(tau) = exp(-tau^2 / (4 s^2)),

the one assumed by the smoothness precision S (see :mod:`attend.models.generalized`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError, positive_scalar


def gaussian_kernel(dt: float, kernel_width: float, support: float = 6.0) -> np.ndarray:
    """Samples of h(t) = exp(-t^2/(2 s^2)) for |t| <= support*s, normalised to unit energy.

    dt: sample spacing [s]; kernel_width: s [s], the width of the Gaussian kernel; support: the
    half-length kept, in kernel widths. Returns (2 ceil(support s / dt) + 1,) samples centred on t = 0.
    """
    dt = positive_scalar(dt, "dt", "s")
    s = positive_scalar(kernel_width, "kernel_width", "s")
    half = int(np.ceil(support * s / dt))
    t = np.arange(-half, half + 1) * dt
    h = np.exp(-(t**2) / (2 * s**2))
    return h / np.sqrt(np.sum(h**2))


def autocorrelation(tau, kernel_width: float):
    """rho(tau) = exp(-tau^2 / (4 s^2)) for lags tau [s] (any shape) and kernel_width s [s]."""
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
    """(n_samples, n_channels) of white noise convolved with the Gaussian kernel (kernel_width 0: white).

    ``std`` is the standard deviation per sample: a scalar or one value per channel; dt [s] the
    sample spacing; seed: an int or a numpy Generator (reproducible draws).
    The white noise is drawn with margins of the kernel's half-length on both sides, so every
    returned sample is a full convolution (no edge transients).
    """
    if n_samples < 1 or n_channels < 0:
        raise AttendInputError(f"n_samples: expected >= 1, got {n_samples}")
    std = np.broadcast_to(np.asarray(std, dtype=float), (n_channels,))
    if not np.all(np.isfinite(std)) or np.any(std < 0):
        raise AttendInputError(f"std: expected finite standard deviations >= 0, got {std}")
    rng = np.random.default_rng(seed)
    if kernel_width == 0:
        return rng.standard_normal((n_samples, n_channels)) * std
    kernel = gaussian_kernel(dt, kernel_width)
    margin = len(kernel) - 1
    white = rng.standard_normal((n_samples + margin, n_channels))
    if n_channels == 0:
        return np.zeros((n_samples, 0))
    from scipy.signal import fftconvolve  # scipy.signal loads scipy.stats (0.5 s): only when noise is drawn

    smooth = fftconvolve(white, kernel[:, None], mode="valid", axes=0)
    return smooth * std


# --- finite state-space models of Gaussian-correlated sequences -----------------------------

class NoiseStateSpace(NamedTuple):
    """A finite linear model of a unit-variance stationary sequence e[k] with a given autocorrelation.

        psi[k] = transition @ psi[k-1] + noise_input * eps[k],   eps[k] ~ N(0, 1) white
        e[k]   = output @ psi[k]

    psi has ``order + 1`` entries: the innovations predictor state xi (``order`` entries) and the
    innovation nu[k] itself, so e[k] = H xi[k] + nu[k] with xi[k+1] = F xi[k] + K nu[k]. The model is
    a minimum-phase spectral factor of the target autocorrelation, found by a covariance
    realisation (Hankel SVD) and the Riccati equation of its Kalman predictor.
    stationary_covariance: Cov(psi[k]) in steady state; autocorrelation_error: the largest
    |r_model[l] - r_target[l]| over the target's lags (r[0] = 1). White noise is order 0.
    """

    transition: np.ndarray
    noise_input: np.ndarray
    output: np.ndarray
    stationary_covariance: np.ndarray
    autocorrelation_error: float

    @property
    def order(self) -> int:
        """Dimension of the predictor state xi (0 for white noise)."""
        return self.transition.shape[0] - 1


def kernel_autocorrelation(dt: float, kernel_width: float) -> np.ndarray:
    """r[l], l = 0, 1, ...: autocorrelation of :func:`coloured_noise` samples (the kernel's self-correlation).

    r[l] = sum_i h[i] h[i + l] with h = gaussian_kernel(dt, s); r[l] ~ rho(l dt) for s >= dt, and
    exactly zero beyond the kernel's length. dt: sample spacing [s]; kernel_width: s [s], the
    width of the noise's Gaussian kernel.
    """
    h = gaussian_kernel(dt, kernel_width)
    return np.correlate(h, h, mode="full")[len(h) - 1:]


def sampled_autocorrelation(dt: float, kernel_width: float) -> np.ndarray:
    """r[l] = rho(l dt) = exp(-(l dt)^2 / (4 s^2)) for the lags where it exceeds 1e-17.

    dt: sample spacing [s]; kernel_width: s [s], the width of the noise's Gaussian kernel."""
    s = positive_scalar(kernel_width, "kernel_width", "s")
    lags = int(np.ceil(2 * s * np.sqrt(17 * np.log(10)) / dt)) + 1
    return autocorrelation(np.arange(lags) * dt, s)


def white_state_space() -> NoiseStateSpace:
    """The order-0 model: e[k] = eps[k]."""
    one = np.ones((1, 1))
    return NoiseStateSpace(np.zeros((1, 1)), np.ones(1), np.ones(1), one, 0.0)


def noise_state_space(autocorrelation_sequence, *, white_floor: float = 1e-8, accuracy: float = 1e-5) -> NoiseStateSpace:
    """Fit a :class:`NoiseStateSpace` to the autocorrelation r[0], r[1], ... (r[0] = 1).

    autocorrelation_sequence: r[l] at lags l = 0, 1, ... samples, (L,) with r[0] > 0 (rescaled to
    r[0] = 1), e.g. from :func:`kernel_autocorrelation` or :func:`sampled_autocorrelation`.

    Steps: (1) Hankel matrix of r[1..] and its SVD give (F, H, G_bar) with r[l] = H F^(l-1) G_bar
    for l >= 1 (Ho-Kalman on covariances), truncated where the singular values fall below a
    tolerance; (2) the stabilising solution P of
        P = F P F' + (G_bar - F P H')(r0 - H P H')^-1 (G_bar - F P H')'
    gives the innovation variance d = r0 - H P H' and the gain K = (G_bar - F P H') / d, with
    r0 = r[0] (1 + white_floor): a white part of relative variance ``white_floor`` keeps the
    spectrum away from zero, as every real sensor does (the Gaussian spectrum falls below 1e-100
    within a few bandwidths, which would make the filter's covariance recursion ill-conditioned).
    Singular values below a tolerance tied to the floor are dropped. The first tolerance whose
    model reproduces r to ``accuracy`` is returned; the error is recorded in the result.
    """
    from scipy.linalg import solve_discrete_are, solve_discrete_lyapunov

    r = np.asarray(autocorrelation_sequence, dtype=float)
    if r.ndim != 1 or r.size < 1 or not np.all(np.isfinite(r)) or r[0] <= 0:
        raise AttendInputError("autocorrelation_sequence: expected finite r[0] > 0, r[1], ...")
    r = r / r[0]
    if r.size == 1 or np.max(np.abs(r[1:])) < 1e-15:
        return white_state_space()
    size = r.size + 1
    padded = np.zeros(2 * size + 1)
    padded[: r.size] = r
    hankel = padded[1 + np.arange(size)[:, None] + np.arange(size)[None, :]]
    U, singular, Vt = np.linalg.svd(hankel)
    best = None
    if not 0 < white_floor < 1:
        raise AttendInputError(f"white_floor: expected a relative variance in (0, 1), got {white_floor!r}")
    for tolerance in (1e-2 * white_floor, 1e-3 * white_floor, 1e-1 * white_floor, white_floor):
        jitter = white_floor
        order = int(np.sum(singular > tolerance * singular[0]))
        if order == 0:
            continue
        observability = U[:, :order] * np.sqrt(singular[:order])
        F = np.linalg.lstsq(observability[:-1], observability[1:], rcond=None)[0]
        H = observability[0]
        G_bar = np.sqrt(singular[:order]) * Vt[:order, 0]
        r0 = 1.0 + jitter
        try:
            with np.errstate(all="ignore"):
                X = solve_discrete_are(F.T, H[:, None], np.zeros((order, order)), np.array([[r0]]), s=G_bar[:, None])
        except (np.linalg.LinAlgError, ValueError):
            continue
        P = -0.5 * (X + X.T)
        innovation = r0 - H @ P @ H
        if not (np.all(np.isfinite(P)) and innovation > 0):
            continue
        gain = (G_bar - F @ P @ H) / innovation
        transition = np.zeros((order + 1, order + 1))
        transition[:order, :order] = F
        transition[:order, order] = gain
        noise_input = np.zeros(order + 1)
        noise_input[order] = np.sqrt(innovation)
        output = np.append(H, 1.0)
        if np.max(np.abs(np.linalg.eigvals(transition))) >= 1:
            continue
        stationary = solve_discrete_lyapunov(transition, np.outer(noise_input, noise_input))
        stationary = 0.5 * (stationary + stationary.T)
        error = _autocorrelation_error(transition, output, stationary, r)
        candidate = NoiseStateSpace(transition, noise_input, output, stationary, error)
        if best is None or error < best.autocorrelation_error:
            best = candidate
        if error <= accuracy:
            return candidate
    if best is None:
        raise AttendInputError("kernel_width: no finite noise model reproduces this autocorrelation")
    return best


def _autocorrelation_error(transition, output, stationary, target) -> float:
    """max_l |output' T^l Sigma output - target[l]| over the target's lags."""
    vector = stationary @ output
    error = 0.0
    for lag in range(target.size):
        error = max(error, abs(output @ vector - target[lag]))
        vector = transition @ vector
    return float(error)


# --- a continuous-time model of the Gaussian-correlated noise (irregular sampling) -----------

GAUSSIAN_SPECTRUM_DENOMINATOR = (
    1.0, 2.0477904695100064, -7.277589896972496, 21.662064838522003, -28.566430834412547, 21.03079616776568,
    -9.15178984087373, 2.4364785657409733, -0.39404519858208226, 0.03623385670831149, -0.0014322000827319229,
    -2.472572316832933e-05, 2.8335857824623895e-06, 7.335932976216472e-08, -4.799798887948756e-09,
    -2.844773055114596e-10, 1.334382246795179e-11,
)
"""a_0..a_16 of the all-pole spectrum S(omega) ~ 1 / P(s^2 omega^2), P(x) = sum_n a_n x^n, which stands
for the Gaussian spectrum exp(-s^2 omega^2) of rho(tau) = exp(-tau^2 / (4 s^2)).

What a Kalman filter needs of a noise model is its spectrum *relative* to itself (the KL divergence
rate between two stationary Gaussian processes is an integral of S_model / S - 1 - log(S_model / S)),
down to the level of the white floor: an autocorrelation fit leaves the tail of S, where a smooth
noise is predictable, off by orders of magnitude, and estimates of smooth noises then drift from
the exact posterior by percents. So P is fitted to e^x in relative terms: weighted least squares
on P(x) e^-x - 1 with weights S / (S + 1e-9) over 0 <= x <= 22.7, then Lawson iterations toward
the minimax error. Result: S_model / S - 1 within +-4.5 % wherever S > 1e-9 S(0) (the
autocorrelation within 1e-2); P has no root on x >= 0, so S > 0: a valid process of order 16
(:func:`continuous_noise_state_space`)."""


class ContinuousNoiseStateSpace(NamedTuple):
    """A continuous-time model of a unit-variance stationary noise e(t) with autocorrelation
    ~ rho(tau) = exp(-tau^2 / (4 s^2)), sampled at arbitrary times t_k:

        d psi / dt = drift psi / s + (white noise),  Cov(psi) = I (stationary),
        e(t_k) = output @ psi(t_k) + nu_k,  nu_k ~ N(0, white_floor) white

    drift (order, order) and output (order,) for kernel width s = 1 (time in units of s);
    autocorrelation_error: max |r_model(tau) - rho(tau)| (r(0) = 1); spectrum_error: max
    |S_model / S - 1| where S > 1e-9 S(0) (see GAUSSIAN_SPECTRUM_DENOMINATOR); modes: the drift's
    eigenvalues, eigenvectors and their inverse (expm(drift tau) = V exp(L tau) inv(V)). Over a
    step of h seconds psi moves by :meth:`step`. Kernel width 0 (white noise) is order 0: e(t_k) = nu_k.
    """

    drift: np.ndarray
    output: np.ndarray
    white_floor: float
    autocorrelation_error: float
    spectrum_error: float
    modes: tuple = ()

    @property
    def order(self) -> int:
        """Dimension of psi (0 for white noise)."""
        return self.drift.shape[0]

    def step(self, interval: float, kernel_width: float) -> tuple[np.ndarray, np.ndarray]:
        """(transition, covariance) of [psi; nu] over a step of ``interval`` = h [s] for width s [s]:
        psi(t + h) = Phi psi(t) + q, Phi = expm(drift h / s), Cov(q) = I - Phi Phi' (stationary, the
        exact discretisation; PSD up to rounding), nu white; both (order + 1, order + 1)."""
        size = self.order + 1
        transition = np.zeros((size, size))
        covariance = np.zeros((size, size))
        covariance[-1, -1] = self.white_floor if self.order else 1.0
        if self.order:
            values, vectors, inverse = self.modes
            phi = ((vectors * np.exp(values * (interval / kernel_width))) @ inverse).real
            step_cov = np.eye(self.order) - phi @ phi.T
            transition[:-1, :-1] = phi
            covariance[:-1, :-1] = 0.5 * (step_cov + step_cov.T)
        return transition, covariance

    @property
    def readout(self) -> np.ndarray:
        """(order + 1,) the map [psi; nu] -> e."""
        return np.append(self.output, 1.0)

    @property
    def stationary_covariance(self) -> np.ndarray:
        """Cov([psi; nu]) in steady state: diag(I, white_floor) (white noise: 1)."""
        return np.diag(np.append(np.ones(self.order), self.white_floor if self.order else 1.0))


def continuous_noise_state_space(kernel_width: float, *, white_floor: float = 1e-8) -> ContinuousNoiseStateSpace:
    """The :class:`ContinuousNoiseStateSpace` of noise with kernel width ``kernel_width`` [s] (0: white).

    The all-pole spectrum of GAUSSIAN_SPECTRUM_DENOMINATOR is factored, S(omega) ~ 1/|D(i omega)|^2
    with D(p) the Hurwitz polynomial whose roots are those of sum_n a_n (-p^2)^n in Re p < 0, and
    1/D is realised as a cascade of first- and second-order low-pass sections (unit DC gain),
    then rotated so that the stationary covariance is the identity. white_floor: the relative
    variance of the white part nu (as :func:`noise_state_space`'s; keeps the filter regular).
    The model depends on s only through the time unit, so it is built once.
    """
    s = float(kernel_width)
    if s == 0:
        return ContinuousNoiseStateSpace(np.zeros((0, 0)), np.zeros(0), 0.0, 0.0, 0.0)
    if not 0 < white_floor < 1:
        raise AttendInputError(f"white_floor: expected a relative variance in (0, 1), got {white_floor!r}")
    drift, output, error, spectrum_error, modes = _unit_gaussian_model()
    return ContinuousNoiseStateSpace(drift, output * np.sqrt(1 - white_floor), white_floor,
                                     error * (1 - white_floor) + white_floor, spectrum_error, modes)


_UNIT_MODEL: tuple | None = None


def _unit_gaussian_model() -> tuple[np.ndarray, np.ndarray, float, float, tuple]:
    """(drift, output, autocorrelation error, spectrum error, modes) of the all-pole model for
    s = 1, Cov(psi) = I, output @ output = 1, both errors measured on the realised model; modes as
    in :class:`ContinuousNoiseStateSpace`; computed once."""
    global _UNIT_MODEL
    if _UNIT_MODEL is not None:
        return _UNIT_MODEL
    from scipy.linalg import expm, solve_continuous_lyapunov

    a = np.asarray(GAUSSIAN_SPECTRUM_DENOMINATOR)
    order = a.size - 1
    in_p = np.zeros(2 * order + 1)  # ascending powers of p: a_n (-p^2)^n
    in_p[::2] = a * (-1.0) ** np.arange(order + 1)
    roots = np.roots(in_p[::-1])
    left = sorted(roots[roots.real < 0], key=lambda p: (abs(p.imag), p.real))
    drift = np.zeros((order, order))
    feed = np.zeros(order)  # input of the cascade
    previous, k, taken = None, 0, np.zeros(len(left), dtype=bool)
    for i, pole in enumerate(left):
        if taken[i] or pole.imag < -1e-9 * abs(pole):
            continue
        taken[i] = True
        if abs(pole.imag) <= 1e-9 * abs(pole):  # y' = -a y + a u
            block, entry, gain, out = np.array([[pole.real]]), k, -pole.real, k
        else:  # y'' + 2 zeta w0 y' + w0^2 y = w0^2 u with states [y, y'/w0]
            w0, zeta = abs(pole), -pole.real / abs(pole)
            block, entry, gain, out = np.array([[0.0, w0], [-w0, -2 * zeta * w0]]), k + 1, w0, k
            taken[int(np.argmin(np.abs(np.array(left) - np.conj(pole)) + taken * 1e300))] = True
        size = block.shape[0]
        drift[k: k + size, k: k + size] = block
        if previous is None:
            feed[entry] = gain
        else:
            drift[entry, previous] += gain
        previous, k = out, k + size
    if k != order:
        raise AssertionError("the spectral factor has the wrong order")
    output = np.zeros(order)
    output[previous] = 1.0
    covariance = solve_continuous_lyapunov(drift, -np.outer(feed, feed))
    root = np.linalg.cholesky(0.5 * (covariance + covariance.T))  # psi = root psi_white
    drift = np.linalg.solve(root, drift @ root)
    # with Cov(psi) = I, drift + drift' = -g g' (g: the white input), rank one; rounding in the
    # Lyapunov solution leaves ~1e-7 elsewhere, which would make I - Phi Phi' indefinite: keep the
    # skew part and the rank-one symmetric part
    values, vectors = np.linalg.eigh(0.5 * (drift + drift.T))
    drift = 0.5 * (drift - drift.T) + values[0] * np.outer(vectors[:, 0], vectors[:, 0])
    output = output @ root
    output /= np.sqrt(output @ output)
    lags = np.linspace(0.0, 20.0, 401)
    step = expm(drift * (lags[1] - lags[0]))
    vector, error = output.copy(), 0.0
    for tau in lags:
        error = max(error, abs(output @ vector - np.exp(-tau**2 / 4)))
        vector = step.T @ vector  # output Phi(tau) -> row vector propagated
    # spectrum of the realised model, 2 pi S(w) = |output (i w - drift)^-1 g|^2 with g g' = -(drift + drift')
    # (Cov(psi) = I), against sqrt(4 pi) exp(-w^2) (the transform of rho for s = 1)
    frequencies = np.linspace(0.0, np.sqrt(-np.log(1e-9)), 400)
    intensity = -(drift + drift.T)
    spectrum = np.array([np.real(row @ intensity @ row.conj()) for row in
                         (np.linalg.solve((1j * w * np.eye(order) - drift).T, output) for w in frequencies)])
    target = np.sqrt(4 * np.pi) * np.exp(-frequencies**2)
    values, vectors = np.linalg.eig(drift)
    _UNIT_MODEL = (drift, output, float(error), float(np.max(np.abs(spectrum / target - 1))),
                   (values, vectors, np.linalg.inv(vectors)))
    return _UNIT_MODEL
