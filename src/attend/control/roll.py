"""The quadrotor roll plant of the wind flights (shared/data/quadrotor-wind), for control benchmarks.

The roll axis of the authors' linearised model (``model.toml``, section ``[roll]``) is a double
integrator driven by the differential motor command::

    dphi/dt = phi_dot,   dphi_dot/dt = b u + d(t),   u = m1 - m2 - m3 + m4   (raw command units)

with b = 0.374838 rad/s^2 per command unit (:data:`ROLL_GAIN`) and d(t) the wind's roll
acceleration. What the logs can tell about d: on the flights (120 Hz, on-board attitude
controller closing the loop) its one-step estimate

    d[k] = (phi_dot[k+1] - phi_dot[k]) / dt - b u[k]

holds the wind plus the differentiated noise of the motion-capture rate. Its autocorrelation is
fitted, on lags from ``min_lag`` samples, by a fraction alpha of smooth noise with a Gaussian
kernel (rho(tau) = alpha exp(-tau^2 / (4 s^2)), attend.models.noise's form) and a white remainder;
the smooth part is the disturbance (std sqrt(alpha) std(d), kernel width s). The command u is
held for several samples in the logs (the autocorrelation of d oscillates with a 5-sample
period), so lags below 5 samples are not fitted.

b itself is not re-identified: a least-squares fit of phi_dot's increments on u over these
closed-loop flights gives 0.004-0.14 with a spurious stiffness and damping (the on-board
controller correlates u with phi and phi_dot), a biased estimate; the benchmark keeps the
authors' physical b and tests +-30 % errors in it instead.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError, positive_scalar

#: rad/s^2 per unit of the differential motor command m1 - m2 - m3 + m4 (model.toml, [roll])
ROLL_GAIN = 0.374838
#: sample time of the flight logs [s] (120 Hz)
LOG_DT = 1.0 / 120.0


class RollDisturbance(NamedTuple):
    """The wind's roll acceleration identified from the flights: std [rad/s^2] and kernel_width s [s] of its
    smooth part, white_std [rad/s^2] of the white remainder (mostly differentiated sensor noise), and
    per_flight: flight name -> (std, kernel_width, white_std)."""

    std: float
    kernel_width: float
    white_std: float
    per_flight: dict


def roll_command(motors) -> np.ndarray:
    """u = m1 - m2 - m3 + m4 (N,) from the motor commands ``motors`` (N, 4) [raw command units]."""
    motors = np.asarray(motors, dtype=float)
    if motors.ndim != 2 or motors.shape[1] != 4:
        raise AttendInputError(f"motors: expected (N, 4) motor commands, got shape {motors.shape}")
    return motors @ np.array([1.0, -1.0, -1.0, 1.0])


def fit_gaussian_autocorrelation(series, dt: float, min_lag: int = 5, max_lag: int = 40) -> tuple[float, float]:
    """(alpha, s): the fraction alpha of the variance of ``series`` (N,) that is smooth with a Gaussian kernel of
    width s [s], from its sample autocorrelation rho at lags min_lag..max_lag samples of spacing dt [s]:
    least squares of log rho = log alpha - tau^2 / (4 s^2) over the lags where rho > 0.05."""
    x = np.asarray(series, dtype=float).reshape(-1)
    dt = positive_scalar(dt, "dt", "s")
    if not (1 <= min_lag < max_lag < x.size // 2):
        raise AttendInputError(f"min_lag, max_lag: expected 1 <= min_lag < max_lag < N/2 = {x.size // 2}, got "
                               f"{min_lag}, {max_lag}")
    x = x - x.mean()
    variance = float(x @ x) / x.size
    lags = np.arange(min_lag, max_lag + 1)
    rho = np.array([float(x[:-lag] @ x[lag:]) / x.size / variance for lag in lags])
    keep = rho > 0.05
    if keep.sum() < 2:
        return 0.0, 0.0
    tau2 = (lags[keep] * dt) ** 2
    design = np.column_stack([np.ones(tau2.size), -tau2])
    (log_alpha, inverse), *_ = np.linalg.lstsq(design, np.log(rho[keep]), rcond=None)
    if inverse <= 0:
        return float(min(1.0, np.exp(log_alpha))), float("inf")
    return float(min(1.0, np.exp(log_alpha))), float(1.0 / np.sqrt(4.0 * inverse))


def disturbance_samples(phi_dot, motors, dt: float = LOG_DT, gain: float = ROLL_GAIN) -> np.ndarray:
    """d[k] = (phi_dot[k+1] - phi_dot[k]) / dt - gain u[k] (N - 1,) [rad/s^2]: the roll acceleration the
    model does not explain; phi_dot (N,) [rad/s], motors (N, 4) commands, dt [s], gain b [rad/s^2 per unit]."""
    phi_dot = np.asarray(phi_dot, dtype=float).reshape(-1)
    u = roll_command(motors)
    if u.shape[0] != phi_dot.shape[0]:
        raise AttendInputError(f"motors: expected {phi_dot.shape[0]} rows (one per phi_dot sample), got {u.shape[0]}")
    return np.diff(phi_dot) / dt - gain * u[:-1]


def identify_roll_disturbance(data_dir=None, flights=None, first: int = 400, last: int = 1599,
                              min_lag: int = 5, max_lag: int = 40) -> RollDisturbance:
    """The wind's roll acceleration from the flight logs in data_dir (default: the shared data): per flight in
    ``flights`` (default: the four wind flights), samples first..last (1-based, inclusive, the published
    window), :func:`disturbance_samples` fitted by :func:`fit_gaussian_autocorrelation` (min_lag, max_lag
    samples). The result averages variances and kernel widths over the flights."""
    from attend.experiments import quadrotor

    path = quadrotor.data_dir_checked(data_dir)
    names = quadrotor.WIND_FLIGHTS if flights is None else tuple(flights)
    per_flight = {}
    for name in names:
        columns = quadrotor.load_flight(path, name).columns
        rows = slice(first - 1, last)
        motors = np.column_stack([columns[f"motor_{i}"][rows] for i in range(1, 5)])
        d = disturbance_samples(columns["state_phi_dot"][rows], motors)
        alpha, width = fit_gaussian_autocorrelation(d, LOG_DT, min_lag, max_lag)
        total = float(np.std(d, ddof=1))
        per_flight[name] = (float(np.sqrt(alpha) * total), width, float(np.sqrt(1 - alpha) * total))
    values = np.array(list(per_flight.values()))
    return RollDisturbance(float(np.sqrt(np.mean(values[:, 0] ** 2))), float(np.mean(values[:, 1])),
                           float(np.sqrt(np.mean(values[:, 2] ** 2))), per_flight)


def roll_matrices(gain: float = ROLL_GAIN, damping: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of dphi/dt = phi_dot, dphi_dot/dt = -damping phi_dot + gain u: gain b [rad/s^2 per command unit],
    damping [1/s] (0 in the authors' model)."""
    return np.array([[0.0, 1.0], [0.0, -float(damping)]]), np.array([[0.0], [float(gain)]])


def roll_plant(*, gain: float = ROLL_GAIN, damping: float = 0.0, disturbance_std: float = 0.0,
               disturbance_kernel_width: float = 0.0, sensor_std: float = 0.0, sensor_kernel_width: float = 0.0,
               n_sensors: int = 2, action_limit: float | None = None, sensor_noise_scale=None):
    """The roll axis as a :class:`attend.control.GenerativeProcess`: states [phi, phi_dot] [rad, rad/s], action u
    (differential motor command), n_sensors roll-angle sensors.

    gain: b [rad/s^2 per unit]; damping [1/s]; disturbance_std, disturbance_kernel_width: the wind's roll
    acceleration [rad/s^2] and its kernel width [s] (:func:`identify_roll_disturbance`); sensor_std [rad],
    sensor_kernel_width [s]: each sensor's noise; action_limit: |u| saturates there (None: no limit);
    sensor_noise_scale: optional sigma_z(t) -> (n_sensors,) multiplying the sensor noise (a degrading sensor)."""
    from attend.control.process import GenerativeProcess

    A, B = roll_matrices(gain, damping)
    C = np.ones((int(n_sensors), 1)) @ np.array([[1.0, 0.0]])
    limits = None if action_limit is None else (-float(action_limit), float(action_limit))
    return GenerativeProcess.linear(A, B, C, process_noise_std=[0.0, disturbance_std],
                                    process_kernel_width=disturbance_kernel_width, sensor_noise_std=sensor_std,
                                    sensor_kernel_width=sensor_kernel_width, action_limits=limits,
                                    sensor_noise_scale=sensor_noise_scale)
