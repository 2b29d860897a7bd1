"""The generative process: the world the agent acts on, with its own f, g and noise.

    dx/dt = f(x, a + u(t)) + w(t) + d(t)        y = g(x, a) + sigma_z(t) * z(t)

x (n,) true states, a (k,) action (held over each sample: zero-order hold), y (m,) sampled
outputs, u an optional disturbance of the action (e.g. a torque on a joint, entering where the
actuator's does), w, z and u coloured noise (white noise convolved with a Gaussian kernel, attend.models.noise), d(t)
an optional deterministic disturbance and sigma_z(t) an optional per-sensor noise scale (a sensor
that degrades). Linear worlds are stepped exactly (zero-order hold of a and w); nonlinear ones
with Runge-Kutta 4 on ``substeps`` sub-intervals.

dy~/da, the generalised response to action, is what the agent's reflex arc needs. As in SPM
(spm_ADEM_diff, spm_ALAP) it is the column of Markov parameters of the process at (x, a)::

    dy~/da = [g_a; g_x f_a; g_x f_x f_a; ...; g_x f_x^(p-1) f_a]        (p + 1 orders)

i.e. how each order of motion of y responds at once to a step in a (:meth:`action_jacobian`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from attend._validation import AttendInputError, kernel_width as _kernel_width, number, order, positive_scalar
from attend.control._checks import action_limits as checked_action_limits
from attend.control._checks import count, evaluated, finite_difference, function, jacobian_pair, linear_matrices, vector


@dataclass(frozen=True, eq=False)
class GenerativeProcess:
    """The world: dx/dt = f(x, a + u) + w + d(t), y = g(x, a) + sigma_z(t) z.

    f, g: functions ``f(x, a)`` -> (n_states,) and ``g(x, a)`` -> (n_outputs,) of 1-D arrays.
    n_states, n_actions, n_outputs: n, k, m. initial_states: x(0) (default zeros).
    process_noise_std: std of w per state (per sample) [state unit / s]; sensor_noise_std: std of z
    per output; process_kernel_width, sensor_kernel_width: their kernel widths s [s] (0: white).
    action_noise_std: std of u per action [action unit] (an input disturbance added to the delivered,
    saturated action; 0: none); action_kernel_width: its kernel width [s].
    disturbance: optional d(t) -> (n,) added to dx/dt (t in s). sensor_noise_scale: optional
    sigma_z(t) -> scalar or (m,) multiplying the sensor noise (1: nominal). action_limits:
    optional (low, high), each a number or k numbers: the actuator saturates there.
    jacobian_f, jacobian_g: optional analytic (d/dx, d/da) functions; else central differences.
    substeps: Runge-Kutta 4 steps per sample (nonlinear worlds). matrices: (A, B, C, D) for
    linear worlds (set by :meth:`linear`).
    """

    f: Callable
    g: Callable
    n_states: int
    n_actions: int
    n_outputs: int
    initial_states: object = None
    process_noise_std: object = 0.0
    sensor_noise_std: object = 0.0
    process_kernel_width: float = 0.0
    sensor_kernel_width: float = 0.0
    disturbance: Callable | None = None
    sensor_noise_scale: Callable | None = None
    action_limits: tuple | None = None
    jacobian_f: Callable | None = None
    jacobian_g: Callable | None = None
    substeps: int = 4
    matrices: tuple | None = field(default=None, repr=False)
    action_noise_std: object = 0.0
    action_kernel_width: float = 0.0

    def __post_init__(self) -> None:
        function(self.f, "f", "f(x, a) -> dx/dt")
        function(self.g, "g", "g(x, a) -> y")
        n = count(self.n_states, "n_states", 1)
        k = count(self.n_actions, "n_actions", 1)
        m = count(self.n_outputs, "n_outputs", 1)
        for name, value in (("n_states", n), ("n_actions", k), ("n_outputs", m)):
            object.__setattr__(self, name, value)
        x0 = np.zeros(n) if self.initial_states is None else vector(self.initial_states, n, "initial_states")
        object.__setattr__(self, "initial_states", x0)
        for name, size in (("process_noise_std", n), ("sensor_noise_std", m), ("action_noise_std", k)):
            value = vector(getattr(self, name), size, name, "standard deviations")
            if np.any(value < 0):
                raise AttendInputError(f"{name}: expected standard deviations >= 0, got {value.tolist()}")
            object.__setattr__(self, name, value)
        object.__setattr__(self, "process_kernel_width", _kernel_width(self.process_kernel_width, "process_kernel_width"))
        object.__setattr__(self, "sensor_kernel_width", _kernel_width(self.sensor_kernel_width, "sensor_kernel_width"))
        object.__setattr__(self, "action_kernel_width", _kernel_width(self.action_kernel_width, "action_kernel_width"))
        for name, form in (("disturbance", "d(t) -> (n,)"), ("sensor_noise_scale", "sigma_z(t) -> (m,)"),
                           ("jacobian_f", "(x, a) -> (d/dx, d/da)"), ("jacobian_g", "(x, a) -> (d/dx, d/da)")):
            if getattr(self, name) is not None:
                function(getattr(self, name), name, form)
        object.__setattr__(self, "action_limits", checked_action_limits(self.action_limits, k))
        object.__setattr__(self, "substeps", count(self.substeps, "substeps", 1))
        a0 = np.zeros(k)
        evaluated(self.f(x0, a0), n, "process f(x, a)")
        evaluated(self.g(x0, a0), m, "process g(x, a)")

    @classmethod
    def linear(cls, A, B, C, D=None, **options) -> "GenerativeProcess":
        """dx/dt = A x + B a + w + d(t), y = C x + D a + z: A (n, n), B (n, k), C (m, n), D (m, k) (default 0).

        options: the other fields of :class:`GenerativeProcess` (noise, limits, initial_states...)."""
        A, B, C, D = linear_matrices(A, B, C, D)
        n, k, m = A.shape[0], B.shape[1], C.shape[0]
        return cls(f=lambda x, a: A @ x + B @ a, g=lambda x, a: C @ x + D @ a, n_states=n, n_actions=k,
                   n_outputs=m, jacobian_f=lambda x, a: (A, B), jacobian_g=lambda x, a: (C, D),
                   matrices=(A, B, C, D), **options)

    @property
    def is_linear(self) -> bool:
        """True when built by :meth:`linear`."""
        return self.matrices is not None

    def jacobians(self, x, a) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(fx, fa, gx, ga) = (df/dx, df/da, dg/dx, dg/da) at (x, a)."""
        if self.matrices is not None:
            return self.matrices
        n, k, m = self.n_states, self.n_actions, self.n_outputs
        x, a = np.asarray(x, dtype=float), np.asarray(a, dtype=float)
        z = np.concatenate([x, a])
        if self.jacobian_f is not None:
            fx, fa = jacobian_pair(self.jacobian_f(x, a), n, (n, k), "process jacobian_f(x, a)")
        else:
            J = finite_difference(lambda q: self.f(q[:n], q[n:]), z, n)
            fx, fa = J[:, :n], J[:, n:]
        if self.jacobian_g is not None:
            gx, ga = jacobian_pair(self.jacobian_g(x, a), m, (n, k), "process jacobian_g(x, a)")
        else:
            J = finite_difference(lambda q: self.g(q[:n], q[n:]), z, m)
            gx, ga = J[:, :n], J[:, n:]
        return fx, fa, gx, ga

    def action_jacobian(self, x, a, embedding_order: int) -> np.ndarray:
        """dy~/da at (x, a): ((p + 1) m, k), rows order-major [g_a; g_x f_a; g_x f_x f_a; ...], p = embedding_order."""
        p = (embedding_order if type(embedding_order) is int and 0 <= embedding_order <= 12
             else order(embedding_order, "embedding_order", 12))
        fx, fa, gx, ga = self.jacobians(x, a)
        return markov_parameters(fx, fa, gx, ga, p + 1)

    def generalised_output(self, x, a, embedding_order: int, action_motion=None) -> np.ndarray:
        """y~ ((p + 1) m,), order-major: the noiseless response of the world at (x, a) and its motion with the action
        held, [g(x, a); g_x f(x, a); g_x f_x f(x, a); ...] (f_x, g_x at (x, a): exact for f and g linear in x, else
        the local linearisation, as spm_ADEM_diff generates the world's generalised response; p = embedding_order).
        What an agent sees in SPM's conventions, where the data are generalised coordinates, not samples.
        action_motion: None (the action held) or its orders 1..p ((p, k)): then y^(i) = g_x x^(i) with x~ from
        :meth:`generalised_states` (the action's motion moves the states' higher orders, as in spm_ADEM_diff)."""
        p = order(embedding_order, "embedding_order", 12)
        x, a = np.asarray(x, dtype=float).reshape(-1), np.asarray(a, dtype=float).reshape(-1)
        fx, _, gx, _ = self.jacobians(x, a)
        m = self.n_outputs
        out = np.empty((p + 1) * m)
        out[:m] = np.asarray(self.g(x, a), dtype=float).reshape(-1)
        if action_motion is not None:
            fa = self.jacobians(x, a)[1]
            out[m:] = (self._states_tilde(x, a, p, action_motion, fx, fa, None)[1:] @ gx.T).reshape(-1)
            return out
        motion = np.asarray(self.f(x, a), dtype=float).reshape(-1)
        for i in range(1, p + 1):
            out[i * m: (i + 1) * m] = gx @ motion
            motion = fx @ motion
        return out

    def generalised_states(self, x, a, embedding_order: int, action_motion=None) -> np.ndarray:
        """x~ ((p + 1) n,), order-major: the world's state and its motion at (x, a), [x; f(x, a); f_x x' + f_a a';
        ...] (f_x, f_a at (x, a); p = embedding_order). action_motion: None (the action held: a' = a'' = ... = 0) or
        the action's orders 1..p ((p, k), e.g. embedded from its history, as spm_ADEM does)."""
        p = order(embedding_order, "embedding_order", 12)
        x, a = np.asarray(x, dtype=float).reshape(-1), np.asarray(a, dtype=float).reshape(-1)
        fx, fa, _, _ = self.jacobians(x, a)
        return self._states_tilde(x, a, p, action_motion, fx, fa, None).reshape(-1)

    def _states_tilde(self, x, a, p: int, action_motion, fx, fa, drive) -> np.ndarray:
        """(p + 1, n): x~ of :meth:`generalised_states` at the Jacobians (fx, fa), with ``drive`` (or None) added to x'
        (and carried into the higher orders)."""
        n = self.n_states
        motion = None if action_motion is None else np.asarray(action_motion, dtype=float).reshape(p, self.n_actions)
        out = np.empty((p + 1, n))
        out[0] = x
        if p:
            out[1] = np.asarray(self.f(x, a), dtype=float).reshape(-1)
            if drive is not None:
                out[1] += np.asarray(drive, dtype=float).reshape(-1)
        for i in range(2, p + 1):
            out[i] = fx @ out[i - 1]
            if motion is not None:
                out[i] += fa @ motion[i - 2]
        return out

    def generalised_motion(self, x, a, embedding_order: int, *, action_motion=None, drive=None, states=None,
                           outputs=None) -> "WorldMotion":
        """The world's generalised motion over one sample, linearised at (x, a), for an agent that integrates it
        jointly with its own beliefs and action (spm_ADEM's convention;
        :meth:`ActiveInferenceController.step_generalised` with ``world_motion``; p = embedding_order). The moving quantities are increments from the start of the
        sample: w = [dx; dx'; ...; dx^(p-1)] of the ``states`` (indices, default all; the top order p does not move)
        and the action's a - a_k::

            dw/dt = c + A w + B (a - a_k),   c = [x'; x''; ...; x^(p)],  A = kron(I_p, f_x),  B = [f_a; 0; ...]
            d(y^(i))/dt = y^(i+1) + g_x dx^(i+1)   (i < p - 1; the top two orders: y^(i+1) only)

        for the ``outputs`` (indices, default all) the world drives; the other outputs move with their own motion
        (dy~/dt = D y~). x~ as :meth:`generalised_states` (action_motion as there) with drive, a known rate added to
        x' (e.g. the noise and disturbance of this sample, :meth:`ProcessRun.drive`). f_x, f_a, g_x at (x, a), taken
        once: the result also holds the world's generalised response y~ = [g; g_x x'; ...] (noiseless; ``y_tilde``)
        and dy~/da (``action_jacobian``, as :meth:`action_jacobian`)."""
        p = embedding_order if type(embedding_order) is int and 0 <= embedding_order <= 12 else order(
            embedding_order, "embedding_order", 12)
        n, m, k = self.n_states, self.n_outputs, self.n_actions
        chosen = np.arange(n) if states is None else np.asarray(states, dtype=int).reshape(-1)
        driven = np.arange(m) if outputs is None else np.asarray(outputs, dtype=int).reshape(-1)
        x, a = np.asarray(x, dtype=float).reshape(-1), np.asarray(a, dtype=float).reshape(-1)
        fx, fa, gx, ga = self.jacobians(x, a)
        x_tilde = self._states_tilde(x, a, p, action_motion, fx, fa, drive)
        y_tilde = np.empty((p + 1, m))
        y_tilde[0] = np.asarray(self.g(x, a), dtype=float).reshape(-1)
        np.dot(x_tilde[1:], gx.T, out=y_tilde[1:])
        q = chosen.size
        fx_q = fx[chosen][:, chosen]
        A = np.zeros((p * q, p * q))
        view = A.reshape(p, q, p, q)
        index = np.arange(p)
        view[index, :, index, :] = fx_q  # kron(I_p, f_x)
        B = np.zeros((p * q, k))
        B[:q] = fa[chosen]
        c = x_tilde[1:, chosen].reshape(-1)
        C = np.zeros(((p + 1) * m, p * q))
        if p > 1:  # y^(i) moves with dx^(i+1), i + 1 <= p - 1
            rows = (np.arange(p - 1)[:, None] * m + driven[None, :]).reshape(-1)
            blocks = C[rows].reshape(p - 1, driven.size, p, q)
            blocks[index[:-1], :, index[1:], :] = gx[driven][:, chosen]
            C[rows] = blocks.reshape(-1, p * q)
        mask = np.zeros((p + 1, m), dtype=bool)
        mask[:, driven] = True
        return WorldMotion(A, B, c, C, mask.reshape(-1), chosen, y_tilde.reshape(-1),
                           markov_parameters(fx, fa, gx, ga, p + 1))

    def saturate(self, action: np.ndarray) -> np.ndarray:
        """The action the actuator delivers: ``action`` clipped to ``action_limits``."""
        if self.action_limits is None:
            return action
        return np.clip(action, self.action_limits[0], self.action_limits[1])

    def start(self, n_samples: int, dt: float, seed: int | None = 0) -> "ProcessRun":
        """A simulation of ``n_samples`` samples of spacing ``dt`` [s] with noise drawn from ``seed``."""
        return ProcessRun(self, count(n_samples, "n_samples", 1), positive_scalar(dt, "dt", "s"), seed)


class WorldMotion(NamedTuple):
    """The world's motion over one sample, linearised (:meth:`GenerativeProcess.generalised_motion`): increments
    w of the chosen states and their orders 0..p-1, dw/dt = c + A w + B (a - a_k); the data rows ``driven`` (bool,
    (p + 1) m) move with C w (plus their own motion y^(i+1)), the others with the shift of y~. ``states``: the
    indices of the world's states in w (order 0 first). y_tilde: the world's noiseless generalised response at the
    start of the sample ((p + 1) m,); action_jacobian: dy~/da there ((p + 1) m, k)."""

    A: np.ndarray
    B: np.ndarray
    c: np.ndarray
    C: np.ndarray
    driven: np.ndarray
    states: np.ndarray
    y_tilde: np.ndarray
    action_jacobian: np.ndarray


def markov_parameters(fx, fa, gx, ga, n_orders: int, hold: float = 0.0) -> np.ndarray:
    """[g_a; g_x f_a; g_x f_x f_a; ...] (n_orders blocks of (m, k)): the instantaneous response of
    y, y', y'', ... to the action a (fx (n, n), fa (n, k), gx (m, n), ga (m, k)).

    hold: tau >= 0 [s]. With tau > 0, the response of y~ at the end of an action held over tau (a zero-order
    hold, from rest): x(tau) = Gamma(tau) f_a with Gamma(tau) = int_0^tau expm(f_x s) ds, so that

        y(tau) = g_x Gamma(tau) f_a + g_a,   y^(i)(tau) = g_x f_x^(i-1) expm(f_x tau) f_a   (i >= 1).

    tau = 0 gives the instantaneous column above. For a double integrator (y'' = b a) the held column is
    (b tau^2 / 2, b tau, b): a sampled agent's action moves its next sample's angle and rate, not only the
    acceleration, and a reflex built on it acts on all three errors (docs/control.md, the roll axis)."""
    hold = number(hold, "hold")
    if not np.isfinite(hold) or hold < 0:
        raise AttendInputError(f"hold: expected a finite time >= 0 (s), got {hold!r}")
    if hold > 0:
        return _held_response(np.asarray(fx, dtype=float), np.asarray(fa, dtype=float),
                              np.asarray(gx, dtype=float), np.asarray(ga, dtype=float), n_orders, hold)
    ga, gx, fx = np.asarray(ga, dtype=float), np.asarray(gx, dtype=float), np.asarray(fx, dtype=float)
    m = ga.shape[0]
    out = np.empty((n_orders * m, ga.shape[1]))
    out[:m] = ga
    column = np.asarray(fa, dtype=float)
    for i in range(1, n_orders):
        np.dot(gx, column, out=out[i * m: (i + 1) * m])
        column = fx @ column
    return out


def _held_response(fx, fa, gx, ga, n_orders: int, hold: float) -> np.ndarray:
    """The held column of :func:`markov_parameters`. While |f_x tau|_1 <= 1, Gamma(tau) f_a is the series
    tau sum_j (f_x tau)^j f_a / (j + 1)!, summed by Horner's rule on the (n, k) columns up to the first j whose
    bound |f_x tau|_1^j / (j + 1)! is below 2^-53, and expm(f_x tau) f_a = f_a + f_x Gamma(tau) f_a; otherwise
    both come from one exponential, expm([[f_x, f_a], [0, 0]] tau)."""
    n, k = fa.shape
    step = fx * hold
    size = np.abs(step).sum(axis=0).max(initial=0.0)
    if size <= 1.0:
        terms, bound = 0, 1.0
        while bound > 2.0**-53 and terms < 30:
            terms += 1
            bound *= size / (terms + 1)
        accumulated = fa
        for j in range(terms, 0, -1):
            accumulated = fa + step @ accumulated / (j + 1)
        integral = hold * accumulated
        derivative = fa + fx @ integral
    else:
        from scipy.linalg import expm

        augmented = np.zeros((n + k, n + k))
        augmented[:n, :n], augmented[:n, n:] = fx, fa
        exponential = expm(augmented * hold)
        integral, derivative = exponential[:n, n:], exponential[:n, :n] @ fa
    column = derivative  # x'(tau) = expm(f_x tau) f_a
    blocks = [gx @ integral + ga]
    for _ in range(1, n_orders):
        blocks.append(gx @ column)
        column = fx @ column
    return np.vstack(blocks)


class ProcessRun:
    """One simulation of the :class:`GenerativeProcess` ``process``: ``output()`` samples y[k], ``advance(a)``
    holds the action over one sample and moves to k + 1; n_samples samples of spacing dt [s]. Noise
    sequences are drawn at the start from ``seed``."""

    def __init__(self, process: GenerativeProcess, n_samples: int, dt: float, seed):
        from attend.models.noise import coloured_noise

        self.process, self.dt, self.n_samples = process, dt, n_samples
        seeds = np.random.SeedSequence(seed).spawn(3)  # the first two streams as before the action noise
        n, m, k = process.n_states, process.n_outputs, process.n_actions
        self._w = (coloured_noise(n_samples + 1, n, dt, process.process_kernel_width, process.process_noise_std,
                                  np.random.default_rng(seeds[0]))
                   if np.any(process.process_noise_std > 0) else np.zeros((n_samples + 1, n)))
        self._z = (coloured_noise(n_samples + 1, m, dt, process.sensor_kernel_width, process.sensor_noise_std,
                                  np.random.default_rng(seeds[1]))
                   if np.any(process.sensor_noise_std > 0) else np.zeros((n_samples + 1, m)))
        self._u = (coloured_noise(n_samples + 1, k, dt, process.action_kernel_width, process.action_noise_std,
                                  np.random.default_rng(seeds[2]))
                   if np.any(process.action_noise_std > 0) else None)
        self.k = 0
        self.x = process.initial_states.copy()
        self.applied = np.zeros(process.n_actions)
        if process.matrices is not None:
            from attend.models.linear import zero_order_hold

            A, B, _, _ = process.matrices
            self._Ad, drive = zero_order_hold(A, np.hstack([B, np.eye(n)]), dt)
            self._Bd, self._Wd = drive[:, : B.shape[1]], drive[:, B.shape[1]:]

    @property
    def time(self) -> float:
        """t = k dt [s] of the current sample."""
        return self.k * self.dt

    def drive(self) -> np.ndarray:
        """The known rate added to dx/dt over the current sample (n,): the process noise w[k] plus the disturbance
        d(t) (zeros for a noiseless world without disturbance)."""
        p = self.process
        drive = self._w[self.k].copy()
        if p.disturbance is not None:
            drive += np.asarray(p.disturbance(self.time), dtype=float)
        return drive

    def advance_to(self, x, action) -> None:
        """Move to the next sample at the state ``x`` (n,), integrated elsewhere (e.g. jointly with the agent, as
        spm_ADEM does: :meth:`GenerativeProcess.generalised_motion`), with ``action`` (saturated) held from now."""
        self.x = vector(x, self.process.n_states, "x")
        self.applied = self.process.saturate(np.asarray(action, dtype=float).reshape(-1))
        self.k += 1

    def output(self) -> np.ndarray:
        """y[k] = g(x[k], a) + sigma_z(t) z[k], a the action held since the last sample."""
        p = self.process
        noise = self._z[self.k]
        if p.sensor_noise_scale is not None:
            noise = noise * np.asarray(p.sensor_noise_scale(self.time), dtype=float)
        return np.asarray(p.g(self.x, self.applied), dtype=float).reshape(-1) + noise

    def advance(self, action) -> None:
        """Hold ``action`` (saturated, plus the action noise u) over [t, t + dt) and move to the next sample."""
        p = self.process
        delivered = p.saturate(np.asarray(action, dtype=float).reshape(-1))
        a = delivered if self._u is None else delivered + self._u[self.k]
        drive = self._w[self.k] + (0.0 if p.disturbance is None else np.asarray(p.disturbance(self.time), dtype=float))
        if p.matrices is not None:
            self.x = self._Ad @ self.x + self._Bd @ a + self._Wd @ drive
        else:
            h = self.dt / p.substeps
            x = self.x
            rate = lambda state: np.asarray(p.f(state, a), dtype=float).reshape(-1) + drive  # noqa: E731
            for _ in range(p.substeps):
                k1 = rate(x)
                k2 = rate(x + 0.5 * h * k1)
                k3 = rate(x + 0.5 * h * k2)
                k4 = rate(x + h * k3)
                x = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            self.x = x
        self.applied = delivered
        self.k += 1
