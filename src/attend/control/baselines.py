"""Baseline controllers with the same ``step(y) -> a`` interface: PID and LQG (Kalman filter + LQR).

PID (derivative on the measurement, first-order filtered; integrator clamped at the limits)::

    e = r - w' y,  a = kp e + ki int e dt - kd d(w' y)/dt (filtered with time constant tau_d) + a_ff(t, y)

LQG with integral action (python-control's dlqr and dlqe on the zero-order-hold model)::

    x^[k|k] = x^[k|k-1] + L (y[k] - C x^[k|k-1] - D a[k-1]),    xi[k+1] = xi[k] + dt (r - H x^[k|k])
    a[k] = a_ff(r) - K_x (x^[k|k] - x_ff(r)) - K_i xi[k],           x^[k+1|k] = Ad x^[k|k] + Bd a[k]

(x_ff, a_ff) the model's equilibrium at the reference r (H x_ff = r), or a given reference trajectory
with its feedforward (``reference_state``), K = [K_x, K_i] the LQR gain
of the plant augmented with the integral xi of the tracking error (one per tracked variable, the
rows of H), L the steady Kalman gain.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from attend._validation import AttendInputError, as_matrix, number, positive_scalar
from attend.control._checks import action_limits as checked_action_limits
from attend.control._checks import vector


def _reference(value, size: int = 1) -> Callable:
    if callable(value):
        return value
    if size == 1 and np.ndim(value) == 0:
        number(value, "reference")
        constant = float(value)
        return lambda t: constant
    constant = vector(value, size, "reference")
    return lambda t: constant


class PIDController:
    """Discrete PID on one controlled variable w' y (w = ``output_weights``, default the first output).

    kp, ki, kd: gains [action / unit, action / (unit s), action s / unit]; dt: sample time [s];
    reference: r, a number or a function r(t) [unit]; output_weights: w (m,) combining the outputs
    (e.g. the mean of two sensors); n_outputs: m; derivative_filter: tau_d [s] (>= 0);
    action_limits: optional (low, high) [action unit] (the integrator stops at the limits);
    feedforward: optional a_ff(t, y) -> number added to the action before saturation (e.g. the gravity
    torque at the measured pose), t [s], y the outputs (m,).
    """

    def __init__(self, kp: float, ki: float, kd: float, dt: float, *, reference=0.0, n_outputs: int = 1,
                 output_weights=None, derivative_filter: float = 0.0, action_limits=None, feedforward=None):
        self.kp, self.ki, self.kd = (number(v, name) for v, name in ((kp, "kp"), (ki, "ki"), (kd, "kd")))
        self.dt = positive_scalar(dt, "dt", "s")
        self.reference = _reference(reference)
        weights = np.eye(n_outputs)[0] if output_weights is None else vector(output_weights, n_outputs, "output_weights")
        self.output_weights = weights
        self.derivative_filter = float(number(derivative_filter, "derivative_filter"))
        if self.derivative_filter < 0:
            raise AttendInputError("derivative_filter: expected a time constant >= 0 (s)")
        self.n_actions = 1
        self.action_limits = checked_action_limits(action_limits, 1)
        if feedforward is not None and not callable(feedforward):
            raise AttendInputError("feedforward: expected a function a_ff(t, y) -> number or None")
        self.feedforward = feedforward
        self.reset()

    def reset(self) -> None:
        """Zero integrator and derivative state, t = 0."""
        self._integral = 0.0
        self._derivative = 0.0
        self._previous = None
        self._k = 0

    def step(self, y) -> np.ndarray:
        """Take y[k] (m,), return the action a[k] (1,)."""
        t = self._k * self.dt
        y = np.asarray(y, dtype=float).reshape(-1)
        measured = float(self.output_weights @ y)
        error = self.reference(t) - measured
        if self._previous is not None:
            tau = self.derivative_filter
            self._derivative = (tau * self._derivative - self.kd * (measured - self._previous)) / (tau + self.dt)
        self._previous = measured
        candidate = self._integral + self.ki * error * self.dt
        action = self.kp * error + candidate + self._derivative
        if self.feedforward is not None:
            action += float(self.feedforward(t, y))
        if self.action_limits is not None:
            low, high = self.action_limits[0][0], self.action_limits[1][0]
            clipped = min(max(action, low), high)
            if clipped == action or (action > high and error < 0) or (action < low and error > 0):
                self._integral = candidate
            action = clipped
        else:
            self._integral = candidate
        self._k += 1
        return np.array([action])


class LQGController:
    """LQG with integral action on a linear model dx/dt = A x + B a, y = C x + D a (see the module).

    A (n, n), B (n, k), C (m, n), D (m, k) (default 0): the model (possibly wrong: that is the test);
    dt: sample time [s]; reference: r, a number or function r(t) (p numbers for p tracked variables), for
    the tracked variables H x; tracked: H (p, n) (default the first output row of C, p = 1); state_weight: Q_x (n, n) or a number
    (times I); integral_weight: q_i >= 0 (0: no integral state); action_weight: R (k, k) or a
    number; process_covariance: covariance of the state noise per sample (n, n) or number;
    sensor_covariance: covariance of the sensor noise (m, m) or number; action_limits: optional;
    reference_state: optional function t -> (x_ff (n,), a_ff (k,)), a reference trajectory and its
    feedforward action (default: the model's equilibrium at r(t), no feedforward of r's motion);
    initial_estimate: x^ at t = 0 (n,) (default zeros).
    """

    def __init__(self, A, B, C, dt: float, *, D=None, reference=0.0, tracked=None, state_weight=1.0,
                 integral_weight: float = 1.0, action_weight=1.0, process_covariance=1e-4, sensor_covariance=1e-4,
                 action_limits=None, reference_state=None, initial_estimate=None):
        import control

        A = as_matrix(A, "A")
        n = A.shape[0]
        B = as_matrix(B, "B", rows=n)
        C = as_matrix(C, "C", cols=n)
        k, m = B.shape[1], C.shape[0]
        D = np.zeros((m, k)) if D is None else as_matrix(D, "D", rows=m, cols=k)
        self.dt = positive_scalar(dt, "dt", "s")
        H = C[:1] if tracked is None else as_matrix(tracked, "tracked", cols=n)
        p = H.shape[0]
        self.reference = _reference(reference, p)
        from attend.models.linear import zero_order_hold

        Ad, Bd = zero_order_hold(A, B, self.dt)
        Qx = _square(state_weight, n, "state_weight")
        R = _square(action_weight, k, "action_weight")
        qi = float(number(integral_weight, "integral_weight"))
        if qi < 0:
            raise AttendInputError("integral_weight: expected a number >= 0")
        self._integral_on = qi > 0
        if self._integral_on:
            Aa = np.block([[Ad, np.zeros((n, p))], [-self.dt * H, np.eye(p)]])
            Ba = np.vstack([Bd, np.zeros((p, k))])
            Qa = np.block([[Qx, np.zeros((n, p))], [np.zeros((p, n)), qi * np.eye(p)]])
            K, _, _ = control.dlqr(Aa, Ba, Qa, R)
        else:
            K, _, _ = control.dlqr(Ad, Bd, Qx, R)
        K = np.asarray(K)
        self._Kx, self._Ki = K[:, :n], (K[:, n:] if self._integral_on else np.zeros((k, p)))
        W = _square(process_covariance, n, "process_covariance")
        V = _square(sensor_covariance, m, "sensor_covariance")
        _, P, _ = control.dlqe(Ad, np.eye(n), C, W, V)
        P = np.asarray(P)
        self._L = P @ C.T @ np.linalg.inv(C @ P @ C.T + V)  # filter (current-estimate) gain
        # equilibrium at the reference: A x + B a = 0, H x = r (least squares when not square)
        eq = np.block([[A, B], [H, np.zeros((p, k))]])
        self._ff = np.linalg.pinv(eq) @ np.vstack([np.zeros((n, p)), np.eye(p)])  # (n + k, p): [x_ff; a_ff] = ff r
        self._Ad, self._Bd, self._C, self._D, self._H = Ad, Bd, C, D, H
        self.n_actions = k
        self.action_limits = checked_action_limits(action_limits, k)
        if reference_state is not None and not callable(reference_state):
            raise AttendInputError("reference_state: expected a function t -> (x_ff, a_ff)")
        self.reference_state = reference_state
        self._x0 = np.zeros(n) if initial_estimate is None else vector(initial_estimate, n, "initial_estimate")
        self.reset()

    def reset(self) -> None:
        """Estimate at initial_estimate (default zero), integrators zero, t = 0."""
        k = self._Bd.shape[1]
        self._x = self._x0.copy()
        self._xi = np.zeros(self._H.shape[0])
        self._a = np.zeros(k)
        self._k = 0

    @property
    def estimate(self) -> np.ndarray:
        """x^[k|k-1], the predicted state for the next sample (n,)."""
        return self._x.copy()

    def step(self, y) -> np.ndarray:
        """Take y[k] (m,), return a[k] (k,)."""
        n = self._Ad.shape[0]
        t = self._k * self.dt
        r = np.asarray(self.reference(t), dtype=float).reshape(-1)
        y = np.asarray(y, dtype=float).reshape(-1)
        x = self._x + self._L @ (y - self._C @ self._x - self._D @ self._a)
        if self.reference_state is None:
            x_ff, a_ff = self._ff[:n] @ r, self._ff[n:] @ r
        else:
            x_ff, a_ff = (np.asarray(value, dtype=float).reshape(-1) for value in self.reference_state(t))
        action = a_ff - self._Kx @ (x - x_ff) - self._Ki @ self._xi
        if self.action_limits is not None:
            clipped = np.clip(action, *self.action_limits)
            if np.array_equal(clipped, action):
                self._xi += self.dt * (r - self._H @ x)
            action = clipped
        else:
            self._xi += self.dt * (r - self._H @ x)
        self._x = self._Ad @ x + self._Bd @ action
        self._a = action
        self._k += 1
        return action


def _square(value, size: int, field: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return float(array) * np.eye(size)
    if array.ndim == 1:
        return np.diag(vector(array, size, field))
    return as_matrix(array, field, rows=size, cols=size)
