"""The nonlinear model dx/dt = f(x, v, theta) + w, y = g(x, v, theta) + z: :class:`NonlinearSystem`,
its Jacobians (analytic or :func:`finite_difference_jacobian`) and :func:`simulate_nonlinear`, the
generative process with coloured noise (see :mod:`attend.perception.nonlinear`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from attend._validation import AttendInputError, as_matrix, positive_scalar, require_finite
from attend.models.linear import Trajectory
from attend.models.noise import coloured_noise
from attend.models.noise_model import resolve_noise

_EPS = np.finfo(float).eps


# --- the model ------------------------------------------------------------------------------

def finite_difference_jacobian(function: Callable, point, *, method: str = "central",
                               vectorized: bool = False) -> np.ndarray:
    """d function / d point at ``point`` (k,), as a (len(function(point)), k) matrix.

    method "central": (f(z + h e_j) - f(z - h e_j)) / 2h with h_j = eps^(1/3) max(1, |z_j|)
    (error O(h^2) + rounding O(eps/h), ~1e-10 relative); "complex": the complex step
    Im f(z + i h e_j) / h, h = 1e-30, exact to rounding but only for functions that are analytic
    and written with complex-safe operations (no abs, max, comparisons): a wrong function gives a
    silently wrong derivative, so it is not the default. ``vectorized``: ``function`` accepts a
    (k, batch) array and returns (out, batch), evaluating columns at once (scipy's convention).
    """
    z = np.asarray(point, dtype=float)
    k = z.shape[0]
    if method == "complex":
        h = 1e-30
        shifted = z[:, None] + 1j * h * np.eye(k)
        if vectorized:
            values = np.asarray(function(shifted))
        else:
            values = np.stack([np.asarray(function(shifted[:, j])) for j in range(k)], axis=1) if k else None
        if k == 0:
            return np.zeros((np.asarray(function(z)).shape[0], 0))
        return np.imag(values) / h
    if method != "central":
        raise AttendInputError(f"jacobian_method: expected 'central' or 'complex', got {method!r}")
    h = _EPS ** (1 / 3) * np.maximum(1.0, np.abs(z))
    if k == 0:
        return np.zeros((np.asarray(function(z)).shape[0], 0))
    steps = np.diag(h)
    if vectorized:
        values = np.asarray(function(np.hstack([z[:, None] + steps, z[:, None] - steps])), dtype=float)
        return (values[:, :k] - values[:, k:]) / (2 * h)
    columns = [(np.asarray(function(z + steps[:, j]), dtype=float) - np.asarray(function(z - steps[:, j]), dtype=float))
               / (2 * h[j]) for j in range(k)]
    return np.stack(columns, axis=1)


@dataclass(frozen=True, eq=False)
class NonlinearSystem:
    """A nonlinear state-space model dx/dt = f(x, v, theta) + w, y = g(x, v, theta) + z.

    f, g: plain NumPy functions of 1-D arrays, ``f(x, v)`` -> (n_states,) [state unit / s] and
    ``g(x, v)`` -> (n_outputs,) [output unit], with x (n_states,) and v (n_inputs,) (an empty
    array when n_inputs = 0: autonomous systems). When ``parameters`` theta is given they are
    called ``f(x, v, parameters)``, ``g(x, v, parameters)``.
    jacobian_f, jacobian_g: optional analytic Jacobians, called like f and g and returning the
    pair (df/dx (n, n), df/dv (n, r)) resp. (dg/dx (m, n), dg/dv (m, r)); without them the
    Jacobians are finite differences (``jacobian_method`` "central" or "complex", see
    :func:`finite_difference_jacobian`; ``vectorized``: f and g accept (k, batch) columns, so that
    a Jacobian is one call, and path mode evaluates all its windows in one call, :func:`evaluate_many`).
    state_names, input_names, output_names: labels (default x1.., u1.., y1..).
    """

    f: Callable
    g: Callable
    n_states: int
    n_inputs: int
    n_outputs: int
    parameters: object = None
    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    jacobian_f: Callable | None = None
    jacobian_g: Callable | None = None
    jacobian_method: str = "central"
    vectorized: bool = False

    def __post_init__(self):
        if not callable(self.f):
            raise AttendInputError("f: expected a function f(x, v) -> dx/dt")
        if not callable(self.g):
            raise AttendInputError("g: expected a function g(x, v) -> y")
        for name, value, low in (("n_states", self.n_states, 1), ("n_inputs", self.n_inputs, 0),
                                 ("n_outputs", self.n_outputs, 1)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise AttendInputError(f"{name}: expected an integer >= {low}, got {value!r}")
            object.__setattr__(self, name, int(value))
        if self.jacobian_method not in ("central", "complex"):
            raise AttendInputError(f"jacobian_method: expected 'central' or 'complex', got {self.jacobian_method!r}")
        for which in ("jacobian_f", "jacobian_g"):
            if getattr(self, which) is not None and not callable(getattr(self, which)):
                raise AttendInputError(f"{which}: expected a function returning (d/dx, d/dv) or None")
        for field_, names, size, letter in (("state_names", self.state_names, self.n_states, "x"),
                                            ("input_names", self.input_names, self.n_inputs, "u"),
                                            ("output_names", self.output_names, self.n_outputs, "y")):
            names = tuple(names) or tuple(f"{letter}{i + 1}" for i in range(size))
            if len(names) != size:
                raise AttendInputError(f"{field_}: expected {size} names, got {len(names)}")
            object.__setattr__(self, field_, names)

    # evaluation ------------------------------------------------------------------------------

    def call_with_parameters(self, function, x, v):
        """``function(x, v)``, or ``function(x, v, parameters)`` when the system has parameters:
        f, g or an analytic Jacobian called as the system calls them, nothing converted or checked
        (for (n, K) columns of a vectorized system, or arrays traced by JAX). function: f, g,
        jacobian_f or jacobian_g; x: the states; v: the inputs."""
        return function(x, v) if self.parameters is None else function(x, v, self.parameters)

    def evaluate(self, which: str, x, v) -> np.ndarray:
        """f(x, v) (``which`` = "f") or g(x, v) ("g") at float arrays x (n,) and v (r,) taken as
        they are: :meth:`flow` and :meth:`observe` without converting their arguments (the inner
        loops of the estimators). The value is a float (n,) or (m,) array; a failure of the user's
        function or a wrong shape is an AttendInputError naming f or g."""
        function, size = (self.f, self.n_states) if which == "f" else (self.g, self.n_outputs)
        try:
            value = np.asarray(self.call_with_parameters(function, x, v), dtype=float)
        except AttendInputError:
            raise
        except Exception as error:  # the user's function failed: say which and where
            raise AttendInputError(f"{which}: raised {type(error).__name__}: {error} at x = {x}, v = {v}") from error
        if value.shape != (size,):
            value = value.reshape(-1) if value.size == size else value
            if value.shape != (size,):
                raise AttendInputError(f"{which}: expected {size} values (a 1-D array), got shape {value.shape}")
        return value

    def flow(self, x, v=None) -> np.ndarray:
        """f(x, v) [state unit / s]."""
        return self.evaluate("f", np.asarray(x, dtype=float), self.input_vector(v))

    def observe(self, x, v=None) -> np.ndarray:
        """g(x, v) [output unit]."""
        return self.evaluate("g", np.asarray(x, dtype=float), self.input_vector(v))

    def input_vector(self, v) -> np.ndarray:
        """The inputs ``v`` as a float (n_inputs,) array; None: zeros (an autonomous system's empty
        array)."""
        return np.zeros(self.n_inputs) if v is None else np.asarray(v, dtype=float).reshape(self.n_inputs)

    def jacobians(self, x, v=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(fx, fv, gx, gv) at (x, v): analytic when given, else finite differences."""
        return self.evaluate_jacobians(np.asarray(x, dtype=float), self.input_vector(v))

    def evaluate_jacobians(self, x, v) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`jacobians` at float arrays x (n,) and v (r,) taken as they are (no conversion:
        the inner loops of the estimators)."""
        n, r, m = self.n_states, self.n_inputs, self.n_outputs
        out = []
        for which, analytic, size in (("f", self.jacobian_f, n), ("g", self.jacobian_g, m)):
            if analytic is not None:
                try:
                    dx, dv = self.call_with_parameters(analytic, x, v)
                    dx, dv = np.asarray(dx, dtype=float), np.asarray(dv, dtype=float)
                    if dx.shape != (size, n) or dv.shape != (size, r):
                        dx, dv = dx.reshape(size, n), dv.reshape(size, r)
                except (TypeError, ValueError) as error:
                    raise AttendInputError(f"jacobian_{which}: expected the pair (d{which}/dx ({size}, {n}), "
                                           f"d{which}/dv ({size}, {r})) ({error})") from None
            else:
                function = self.f if which == "f" else self.g
                if self.vectorized:  # columns, shape-checked; complex steps keep their dtype
                    joint = lambda z, w=which: evaluate_columns(self, w, z, dtype=None)  # noqa: E731
                elif self.jacobian_method == "complex":
                    joint = lambda z, fn=function: np.asarray(self.call_with_parameters(fn, z[:n], z[n:]))  # noqa: E731
                else:
                    joint = lambda z, w=which: self.evaluate(w, z[:n], z[n:])  # noqa: E731
                jac = finite_difference_jacobian(joint, np.concatenate([x, v]), method=self.jacobian_method,
                                                 vectorized=self.vectorized)
                dx, dv = jac[:, :n], jac[:, n:]
            out.extend([dx, dv])
        fx, fv, gx, gv = out
        return fx, fv, gx, gv


def evaluate_columns(system: "NonlinearSystem", which: str, z: np.ndarray, dtype=float) -> np.ndarray:
    """f (``which`` "f") or g ("g") of a vectorized ``system`` at the columns of z ((n + r), K): a
    (size, K) array (of ``dtype``; None keeps the function's, e.g. complex steps)."""
    n = system.n_states
    function, size = (system.f, n) if which == "f" else (system.g, system.n_outputs)
    try:
        values = np.asarray(system.call_with_parameters(function, z[:n], z[n:]), dtype=dtype)
    except AttendInputError:
        raise
    except Exception as error:
        raise AttendInputError(f"{which}: raised {type(error).__name__}: {error} when called with {z.shape[1]} "
                               "columns (vectorized=True: f and g must accept (n, K) columns)") from error
    if values.shape != (size, z.shape[1]):
        raise AttendInputError(f"{which}: with vectorized=True expected ({size}, {z.shape[1]}) values for "
                               f"{z.shape[1]} columns, got shape {values.shape}")
    return values


def evaluate_many(system: "NonlinearSystem", x, v):
    """(f (C, n), g (C, m), fx (C, n, n), fv (C, n, r), gx (C, m, n), gv (C, m, r)) at the C points
    (x_c, v_c) (rows of x (C, n), v (C, r)). For a vectorized system with central finite-difference
    Jacobians, one call of f and one of g on every point and its shifts z +- h_j e_j (h_j as in
    :func:`finite_difference_jacobian`); otherwise point by point (analytic Jacobians, or functions
    of one point). system: the NonlinearSystem."""
    x, v = np.asarray(x, dtype=float), np.asarray(v, dtype=float)
    C, n = x.shape
    if not (system.vectorized and system.jacobian_f is None and system.jacobian_g is None
            and system.jacobian_method == "central"):
        calls = [(system.evaluate("f", xc, vc), system.evaluate("g", xc, vc), *system.evaluate_jacobians(xc, vc))
                 for xc, vc in zip(x, v)]
        return tuple(np.array([call[i] for call in calls]).reshape((C,) + shape)
                     for i, shape in enumerate(_shapes(system)))
    z = np.concatenate([x, v], axis=1)
    k = z.shape[1]
    h = _EPS ** (1 / 3) * np.maximum(1.0, np.abs(z))  # (C, k)
    shifts = h[:, :, None] * np.eye(k)[None]  # (C, j, k): point c shifted along coordinate j
    points = np.concatenate([z, (z[:, None] + shifts).reshape(-1, k), (z[:, None] - shifts).reshape(-1, k)])
    out = []
    for which in ("f", "g"):
        values = evaluate_columns(system, which, points.T).T  # (C (1 + 2k), size)
        centre = values[:C]
        plus, minus = values[C: C * (1 + k)].reshape(C, k, -1), values[C * (1 + k):].reshape(C, k, -1)
        jacobian = np.swapaxes((plus - minus) / (2 * h[:, :, None]), 1, 2)  # (C, size, k)
        out.append((centre, jacobian[:, :, :n], jacobian[:, :, n:]))
    (f, fx, fv), (g, gx, gv) = out
    return f, g, fx, fv, gx, gv


def _shapes(system: "NonlinearSystem") -> list[tuple]:
    n, r, m = system.n_states, system.n_inputs, system.n_outputs
    return [(n,), (m,), (n, n), (n, r), (m, n), (m, r)]


def simulate_nonlinear(system: NonlinearSystem, inputs, dt: float, *, kernel_width: float | None = None,
                       process_std=None, measurement_std=None, initial_state=None, seed=0, substeps: int = 10,
                       noise=None) -> Trajectory:
    """Simulate the generative process with coloured noise.

    system: the NonlinearSystem (f, g); dt: sample time [s]; initial_state: x[0] (default 0);
    seed: seed of the noise draws; substeps: RK4 sub-steps per sample.
    inputs: (N, r) input samples, or the number of samples N for an autonomous system (r = 0).
    x[k] = x[k-1] + integral over one sample of f(x, u[k-1]) + w[k-1] (RK4 with ``substeps``
    sub-steps, u and w held over the sample: the zero-order hold of the linear simulate()),
    y[k] = g(x[k], u[k]) + z[k]; w, z: white noise convolved with the Gaussian kernel of width
    kernel_width [s], standard deviations process_std [state unit / s] and measurement_std per
    sample (both default 0: no noise). noise: an :class:`attend.models.NoiseModel` instead of
    kernel_width, process_std and measurement_std (standard deviations 1 / sqrt(precision) per
    channel, as :func:`attend.models.simulate`; one kernel width for both noises here).
    Returns an :class:`attend.models.linear.Trajectory`.
    """
    if not isinstance(system, NonlinearSystem):
        raise AttendInputError("system: expected an attend NonlinearSystem")
    dt = positive_scalar(dt, "dt", "s")
    given = dict(kernel_width=kernel_width, process_std=process_std, measurement_std=measurement_std)
    if resolve_noise(noise, given, "simulate_nonlinear") is not None:
        if noise.kernel_width is None:
            raise AttendInputError("noise: simulate_nonlinear uses one kernel width for both noises; this model's "
                                   "process_kernel_width and sensor_kernel_width differ")
        kernel_width, process_std, measurement_std = noise.kernel_width, noise.process_std, noise.sensor_std
    if kernel_width is None:
        raise AttendInputError("kernel_width: required (or noise=NoiseModel(...)); 0 means white noise")
    process_std = 0.0 if process_std is None else process_std
    measurement_std = 0.0 if measurement_std is None else measurement_std
    if isinstance(inputs, (int, np.integer)) and not isinstance(inputs, bool):
        u = np.zeros((int(inputs), system.n_inputs))
    else:
        u = np.asarray(inputs, dtype=float)
        if u.ndim == 1 and system.n_inputs == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != system.n_inputs:
            raise AttendInputError(f"inputs: expected shape (N, {system.n_inputs}), got {u.shape}")
        require_finite(u, "inputs")
    n_samples = u.shape[0]
    if n_samples < 1:
        raise AttendInputError("inputs: expected at least one sample")
    rng = np.random.default_rng(seed)
    w = coloured_noise(n_samples, system.n_states, dt, kernel_width, process_std, rng)
    z = coloured_noise(n_samples, system.n_outputs, dt, kernel_width, measurement_std, rng)
    x = np.zeros((n_samples, system.n_states))
    if initial_state is not None:
        x[0] = as_matrix(initial_state, "initial_state", cols=1)[:, 0]
    h = dt / int(substeps)
    for k in range(1, n_samples):
        state, uk, wk = x[k - 1], u[k - 1], w[k - 1]
        for _ in range(int(substeps)):
            k1 = system.flow(state, uk) + wk
            k2 = system.flow(state + 0.5 * h * k1, uk) + wk
            k3 = system.flow(state + 0.5 * h * k2, uk) + wk
            k4 = system.flow(state + h * k3, uk) + wk
            state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(state)):
            raise AttendInputError(f"simulate_nonlinear: the state became non-finite at sample {k}; "
                                   "lower dt or raise substeps")
        x[k] = state
    y = np.stack([system.observe(x[k], u[k]) for k in range(n_samples)]) + z
    return Trajectory(np.arange(n_samples) * dt, x, u, y, w, z)
