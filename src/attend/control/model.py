"""The agent's generative model: what the controller believes about its world and what it intends.

    dx/dt = f(x, v) + w        y = g(x, v) + z        v = eta(t) + e_v

x (n,) hidden states, v (r,) causes (their prior mean eta(t) is the intention or target), y (m,)
outputs. w, z, e_v are Gaussian with precisions Pi_w (``process_precision``), Pi_z
(``sensor_precision``, constant or a function Pi_z(x, v) as spm_ALAP's M.ph) and P_v
(``cause_prior_precision``), each smooth with kernel width s (``kernel_width``): in generalised
coordinates their precisions are kron(S(s), Pi). The model never sees the action a: action enters
only the world (:class:`attend.control.GenerativeProcess`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from attend._validation import AttendInputError, order, positive_scalar
from attend.control._checks import (
    count,
    evaluated,
    finite_difference,
    function,
    jacobian_pair,
    linear_matrices,
    positive_precision,
    precision_value,
    vector,
)


@dataclass(frozen=True, eq=False)
class GenerativeModel:
    """The agent's model dx/dt = f(x, v) + w, y = g(x, v) + z, prior v ~ N(eta(t), P_v^-1).

    f, g: functions ``f(x, v)`` -> (n_states,) [state unit / s] and ``g(x, v)`` -> (n_outputs,)
    of 1-D arrays x (n_states,), v (n_causes,). n_states, n_causes, n_outputs: n, r (may be 0), m.
    sensor_precision: Pi_z, a scalar, vector (diagonal) or (m, m) matrix, or a function
    ``sensor_precision(x, v)`` returning m precisions or an (m, m) matrix (state-dependent
    precision, like M.ph of spm_ALAP but returning precisions, not log-precisions).
    process_precision: Pi_w (scalar, vector or (n, n)); cause_prior_precision: P_v (scalar,
    vector or (r, r)). cause_prior: eta, the intention: r numbers, or a function ``eta(t)`` of the
    time t [s] returning r numbers (higher orders of motion 0) or (cause_order + 1) * r numbers
    (eta~ order-major). kernel_width: s [s] of the smoothness precision S(s).
    embedding_order: p (p + 1 orders of x and y); cause_order: d (d + 1 orders of v).
    jacobian_f, jacobian_g: optional analytic Jacobians returning (d/dx, d/dv); else central
    differences. initial_states: x at t = 0 (default zeros); initial_causes: v at t = 0
    (default eta(0)). matrices: (A, B, C, D) when the model is linear (set by :meth:`linear`).
    sensor_precision_gradient: optional, for a ``sensor_precision(x, v)`` returning m precisions pi
    (diagonal Pi_z): ``(x, v) -> (dpi/dx (m, n), dpi/dv (m, r))``, the analytic derivatives the
    controller's precision gradient uses (else central differences of sensor_precision).
    """

    f: Callable
    g: Callable
    n_states: int
    n_causes: int
    n_outputs: int
    sensor_precision: object = 1.0
    process_precision: object = 1.0
    cause_prior_precision: object = 1.0
    cause_prior: object = None
    kernel_width: float = 0.5
    embedding_order: int = 2
    cause_order: int = 1
    jacobian_f: Callable | None = None
    jacobian_g: Callable | None = None
    initial_states: object = None
    initial_causes: object = None
    matrices: tuple | None = field(default=None, repr=False)
    sensor_precision_gradient: Callable | None = None

    def __post_init__(self) -> None:
        function(self.f, "f", "f(x, v) -> dx/dt")
        function(self.g, "g", "g(x, v) -> y")
        n = count(self.n_states, "n_states", 1)
        r = count(self.n_causes, "n_causes", 0)
        m = count(self.n_outputs, "n_outputs", 1)
        for name, value in (("n_states", n), ("n_causes", r), ("n_outputs", m)):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "kernel_width", positive_scalar(self.kernel_width, "kernel_width", "s"))
        object.__setattr__(self, "embedding_order", order(self.embedding_order, "embedding_order", 12))
        object.__setattr__(self, "cause_order", order(self.cause_order, "cause_order", 12))
        if not callable(self.sensor_precision):
            object.__setattr__(self, "sensor_precision", positive_precision(self.sensor_precision, m, "sensor_precision"))
        object.__setattr__(self, "process_precision", positive_precision(self.process_precision, n, "process_precision"))
        object.__setattr__(self, "cause_prior_precision",
                           positive_precision(self.cause_prior_precision, r, "cause_prior_precision"))
        if self.cause_prior is None:
            object.__setattr__(self, "cause_prior", np.zeros(r))
        elif not callable(self.cause_prior):
            object.__setattr__(self, "cause_prior", vector(self.cause_prior, r, "cause_prior"))
        for which in ("jacobian_f", "jacobian_g"):
            if getattr(self, which) is not None:
                function(getattr(self, which), which, "(x, v) -> (d/dx, d/dv)")
        x0 = np.zeros(n) if self.initial_states is None else vector(self.initial_states, n, "initial_states")
        object.__setattr__(self, "initial_states", x0)
        if self.initial_causes is not None:
            object.__setattr__(self, "initial_causes", vector(self.initial_causes, r, "initial_causes"))
        # evaluate once at the start, so that a wrong f or g fails here with its name
        v0 = self.prior(0.0)[:r]
        evaluated(self.f(x0, v0), n, "f(x, v)")
        evaluated(self.g(x0, v0), m, "g(x, v)")
        if callable(self.sensor_precision):
            precision_value(self.sensor_precision(x0, v0), m, "sensor_precision(x, v)")
        if self.sensor_precision_gradient is not None:
            function(self.sensor_precision_gradient, "sensor_precision_gradient", "(x, v) -> (dpi/dx, dpi/dv)")
            if not callable(self.sensor_precision):
                raise AttendInputError("sensor_precision_gradient: given for a constant sensor_precision; it needs a "
                                       "function sensor_precision(x, v)")
            if np.ndim(self.sensor_precision(x0, v0)) > 1:
                raise AttendInputError("sensor_precision_gradient: needs sensor_precision(x, v) to return m precisions "
                                       "(a diagonal Pi_z), got a matrix")
            self.sensor_precision_derivatives(x0, v0)

    # --- construction ---------------------------------------------------------------------

    @classmethod
    def linear(cls, A, B, C, D=None, **options) -> "GenerativeModel":
        """dx/dt = A x + B v + w, y = C x + D v + z: A (n, n), B (n, r), C (m, n), D (m, r) (default 0).

        options: the other fields of :class:`GenerativeModel` (precisions, cause_prior, orders...)."""
        A, B, C, D = linear_matrices(A, B, C, D, inputs_optional=True)
        n, r, m = A.shape[0], B.shape[1], C.shape[0]
        return cls(f=lambda x, v: A @ x + B @ v, g=lambda x, v: C @ x + D @ v, n_states=n, n_causes=r,
                   n_outputs=m, jacobian_f=lambda x, v: (A, B), jacobian_g=lambda x, v: (C, D),
                   matrices=(A, B, C, D), **options)

    # --- evaluation -----------------------------------------------------------------------

    @property
    def is_linear(self) -> bool:
        """True when built by :meth:`linear` (f, g affine with constant Jacobians)."""
        return self.matrices is not None

    @property
    def state_dependent_precision(self) -> bool:
        """True when Pi_z is a function of (x, v)."""
        return callable(self.sensor_precision)

    def prior(self, time: float) -> np.ndarray:
        """eta~(t): the prior mean of the causes in generalised coordinates ((d + 1) r,), order-major, at
        ``time`` t [s]."""
        r, orders = self.n_causes, self.cause_order + 1
        if not callable(self.cause_prior):
            out = np.zeros(orders * r)
            out[:r] = self.cause_prior
            return out
        value = np.asarray(self.cause_prior(float(time)), dtype=float).reshape(-1)
        if value.shape[0] == r:
            out = np.zeros(orders * r)
            out[:r] = value
        elif value.shape[0] == orders * r:
            out = value.copy()
        else:
            raise AttendInputError(f"cause_prior(t): expected {r} or {orders * r} values, got {value.shape[0]}")
        if not np.isfinite(out).all():
            raise AttendInputError(f"cause_prior(t): returned non-finite values at t = {time} s")
        return out

    def jacobians(self, x: np.ndarray, v: np.ndarray,
                  check_finite: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(fx, fv, gx, gv) = (df/dx, df/dv, dg/dx, dg/dv) at the states x and causes v; check_finite
        False checks shapes only (the controller's step finds a non-finite Jacobian in its
        exponential and then calls this again with the check to name it)."""
        n, r, m = self.n_states, self.n_causes, self.n_outputs
        if self.matrices is not None:
            A, B, C, D = self.matrices
            return A, B, C, D
        if self.jacobian_f is not None:
            fx, fv = jacobian_pair(self.jacobian_f(x, v), n, (n, r), "jacobian_f(x, v)", check_finite)
        else:
            z = np.concatenate([x, v])
            J = finite_difference(lambda q: self.f(q[:n], q[n:]), z, n)
            fx, fv = J[:, :n], J[:, n:]
        if self.jacobian_g is not None:
            gx, gv = jacobian_pair(self.jacobian_g(x, v), m, (n, r), "jacobian_g(x, v)", check_finite)
        else:
            z = np.concatenate([x, v])
            J = finite_difference(lambda q: self.g(q[:n], q[n:]), z, m)
            gx, gv = J[:, :n], J[:, n:]
        return fx, fv, gx, gv

    def sensor_precision_at(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Pi_z(x, v) as an (m, m) matrix (the constant matrix when it does not depend on the state)."""
        if callable(self.sensor_precision):
            return precision_value(self.sensor_precision(x, v), self.n_outputs, "sensor_precision(x, v)")
        return self.sensor_precision

    def sensor_precision_derivatives(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """d pi / d(x, v) as ((n + r), m) rows (row j: the derivative of the m precisions pi = diag(Pi_z) in the
        j-th of (x, v)) from ``sensor_precision_gradient``, checked for shape and finite values."""
        n, r, m = self.n_states, self.n_causes, self.n_outputs
        dx, dv = jacobian_pair(self.sensor_precision_gradient(x, v), m, (n, r), "sensor_precision_gradient(x, v)", True)
        out = np.empty((n + r, m))
        out[:n] = dx.T
        out[n:] = dv.T
        return out
