"""Linear time-invariant systems, their zero-order-hold discretisation and simulation.

Continuous-time model (paper eq. 1)::

    dx/dt = A x + B u + w        y = C x + z

x in R^n (states), u in R^r (inputs, "causes" v), y in R^m (outputs); w and z are coloured
noises (see :mod:`attend.models.noise`). Time is in seconds everywhere. The paper's systems (presets)
are in :mod:`attend.models.problems`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError, as_matrix, positive_scalar, unique_names
from attend.models.noise import coloured_noise
from attend.models.noise_model import NoiseModel, resolve_noise


class ModelWarning(UserWarning):
    """The model is valid but something about it deserves attention (unstable, unobservable)."""


@dataclass(frozen=True, eq=False)
class LinearSystem:
    """Continuous-time LTI system (A, B, C).

    A: (n, n) state matrix [1/s]; B: (n, r) input matrix; C: (m, n) output matrix.
    ``state_names``, ``input_names``, ``output_names`` label the columns of logs and results.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()

    def __post_init__(self):
        A = as_matrix(self.A, "A")
        if A.shape[0] != A.shape[1]:
            raise AttendInputError(f"A: expected a square matrix, got shape {A.shape}")
        n = A.shape[0]
        B = as_matrix(self.B, "B", rows=n, cols=1 if np.ndim(self.B) == 1 else None)
        C = as_matrix(self.C, "C", cols=n, rows=1 if np.ndim(self.C) == 1 else None)
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "B", B)
        object.__setattr__(self, "C", C)
        for field, names, size, letter in (
            ("state_names", self.state_names, n, "x"),
            ("input_names", self.input_names, B.shape[1], "u"),
            ("output_names", self.output_names, C.shape[0], "y"),
        ):
            names = unique_names(names, field) or tuple(f"{letter}{i + 1}" for i in range(size))
            if len(names) != size:
                raise AttendInputError(f"{field}: expected {size} names, got {len(names)}")
            object.__setattr__(self, field, names)

    @property
    def n_states(self) -> int:
        """n, the number of states."""
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        """r, the number of inputs."""
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        """m, the number of outputs."""
        return self.C.shape[0]

    def discretize(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact zero-order hold: Ad = expm(A dt), Bd = int_0^dt expm(A t) dt B.

        Both come from one matrix exponential, expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, I]].
        """
        return zero_order_hold(self.A, self.B, positive_scalar(dt, "dt", "s"))

    def is_stable(self) -> bool:
        """All eigenvalues of A in the open left half-plane."""
        return bool(np.max(np.linalg.eigvals(self.A).real) < 0)

    def is_observable(self) -> bool:
        """Rank of the observability matrix [C; CA; ...; CA^(n-1)] equals n."""
        return observability_rank(self.A, self.C) == self.n_states

    def check(self) -> list[str]:
        """Warn (ModelWarning) if A has an eigenvalue with positive real part (unstable) or (A, C)
        is unobservable; return the messages."""
        messages = []
        eigenvalues = np.linalg.eigvals(self.A)
        tolerance = 1e-9 * max(1.0, float(np.abs(eigenvalues).max()))
        if np.max(eigenvalues.real) > tolerance:
            worst = eigenvalues[np.argmax(eigenvalues.real)]
            messages.append(
                f"A is unstable: eigenvalue {worst:.4g} has a positive real part "
                "(states grow exponentially; integrators, with real part 0, are not flagged)"
            )
        rank = observability_rank(self.A, self.C)
        if rank < self.n_states:
            messages.append(
                f"(A, C) is unobservable: observability matrix has rank {rank} < n = {self.n_states} "
                "(some states cannot be recovered from the outputs; their estimates follow the prior)"
            )
        for message in messages:
            warnings.warn(message, ModelWarning, stacklevel=2)
        return messages


def as_linear_system(system, field: str = "system") -> LinearSystem:
    """``system`` as a LinearSystem: a python-control ``StateSpace`` (continuous time, D = 0) is
    converted with :func:`attend.models.from_statespace`; anything else is an error naming
    ``field``, the argument's name in the caller's API."""
    if isinstance(system, LinearSystem):
        return system
    if type(system).__name__ == "StateSpace" and type(system).__module__.split(".")[0] == "control":
        try:
            return from_statespace(system)
        except AttendInputError as error:
            raise AttendInputError(f"{field}: {error}") from None
    raise AttendInputError(
        f"{field}: expected an attend.LinearSystem (or a python-control StateSpace, converted with "
        f"attend.models.from_statespace), got {type(system).__name__}"
    )


def from_statespace(statespace, *, state_names=(), input_names=(), output_names=()) -> LinearSystem:
    """LinearSystem (A, B, C) of a continuous-time python-control ``StateSpace`` with D = 0
    (``pip install control``; D must be zero: the output model is y = C x + z).

    statespace: the python-control system (dt = 0, D = 0); state_names (n,), input_names (r,),
    output_names (m,): labels for the columns of logs and results (default x1.., u1.., y1..)."""
    try:
        import control
    except ImportError:  # pragma: no cover - exercised only without the optional dependency
        raise AttendInputError("python-control is not installed: pip install control") from None
    if not isinstance(statespace, control.StateSpace):
        raise AttendInputError("statespace: expected a control.StateSpace")
    if not statespace.isctime():
        raise AttendInputError(
            f"statespace: expected a continuous-time system (dt = 0), got dt = {statespace.dt}; "
            "attend models are continuous and discretised by zero-order hold"
        )
    D = np.asarray(statespace.D, dtype=float)
    if np.any(D != 0):
        raise AttendInputError("statespace: D must be zero (attend's output model is y = C x + z)")
    return LinearSystem(np.asarray(statespace.A), np.asarray(statespace.B), np.asarray(statespace.C),
                        state_names=tuple(state_names), input_names=tuple(input_names),
                        output_names=tuple(output_names))


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Ad = expm(A dt), Bd = int_0^dt expm(A t) dt B from one block matrix exponential."""
    from scipy.linalg import expm  # here: reading a model or a log does not load scipy.linalg

    n, r = B.shape
    block = np.zeros((n + r, n + r))
    block[:n, :n] = A
    block[:n, n:] = B
    exponential = expm(block * dt)
    return exponential[:n, :n], exponential[:n, n:]


def observability_rank(A: np.ndarray, C: np.ndarray) -> int:
    """Numerical rank of [C; CA; ...; CA^(n-1)] (rows scaled to unit norm first).

    A: state matrix (n, n); C: output matrix (m, n)."""
    n = A.shape[0]
    blocks, block = [], C
    for _ in range(n):
        blocks.append(block)
        block = block @ A
    matrix = np.vstack(blocks)
    norms = np.linalg.norm(matrix, axis=1)
    matrix = matrix[norms > 0] / norms[norms > 0, None]
    if matrix.size == 0:
        return 0
    return int(np.linalg.matrix_rank(matrix, tol=1e-9 * np.sqrt(n)))


# --- simulation ----------------------------------------------------------------------------

class Trajectory(NamedTuple):
    """A simulated log: time [s] (N,), states x (N, n), inputs u (N, r), outputs y (N, m),
    and the noises that produced it, w (N, n) and z (N, m)."""

    time: np.ndarray
    states: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    process_noise: np.ndarray
    measurement_noise: np.ndarray


def simulate(
    system: LinearSystem,
    inputs: np.ndarray,
    dt: float,
    *,
    kernel_width: float | None = None,
    process_std=None,
    measurement_std=None,
    initial_state=None,
    seed: int | np.random.Generator | None = 0,
    process_kernel_width: float | None = None,
    sensor_kernel_width: float | None = None,
    noise: NoiseModel | None = None,
) -> Trajectory:
    """Simulate the generative process with coloured noise.

    x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1],  y[k] = C x[k] + z[k], with Ad, Bd the zero-order
    hold of (A, B) over dt [s] and w, z white noise convolved with a Gaussian kernel of width
    ``kernel_width`` [s] (standard deviations ``process_std``, ``measurement_std`` per sample,
    scalars or per channel). ``process_kernel_width`` / ``sensor_kernel_width`` [s] set the widths
    of w and z separately (0: white noise); each defaults to ``kernel_width``; process_std and
    measurement_std default to 0 (no noise). noise: an :class:`attend.models.NoiseModel` instead of
    those five (standard deviations 1 / sqrt(precision) per channel, its kernel widths: the model
    ``NoiseModel.from_std(process_std=sigma_w, sensor_std=sigma_z, ...)`` draws exactly the noise
    of process_std=sigma_w, measurement_std=sigma_z; correlated channels are an error).
    ``system`` may also be a python-control StateSpace (converted with
    :func:`attend.models.from_statespace`). inputs: (N, r) u at every sample; initial_state: x[0]
    (default 0); seed: an int or a numpy Generator (the noises are reproducible).
    """
    system = as_linear_system(system)
    dt = positive_scalar(dt, "dt", "s")
    given = dict(process_std=process_std, measurement_std=measurement_std, kernel_width=kernel_width,
                 process_kernel_width=process_kernel_width, sensor_kernel_width=sensor_kernel_width)
    if resolve_noise(noise, given, "simulate") is not None:
        process_std, measurement_std = noise.process_std, noise.sensor_std
        process_kernel_width, sensor_kernel_width = noise.process_kernel_width, noise.sensor_kernel_width
    process_std = 0.0 if process_std is None else process_std
    measurement_std = 0.0 if measurement_std is None else measurement_std
    widths = []
    for value, field in ((process_kernel_width, "process_kernel_width"), (sensor_kernel_width, "sensor_kernel_width")):
        value = kernel_width if value is None else value
        if value is None:
            raise AttendInputError(f"{field}: required (or kernel_width for both noises)")
        widths.append(value)
    u = as_matrix(inputs, "inputs", cols=system.n_inputs if np.ndim(inputs) == 2 else 1)
    if u.shape[1] != system.n_inputs:
        raise AttendInputError(f"inputs: expected {system.n_inputs} columns, got {u.shape[1]}")
    n_samples = u.shape[0]
    rng = np.random.default_rng(seed)
    w = coloured_noise(n_samples, system.n_states, dt, widths[0], process_std, rng)
    z = coloured_noise(n_samples, system.n_outputs, dt, widths[1], measurement_std, rng)
    Ad, Bd = system.discretize(dt)
    x = np.zeros((n_samples, system.n_states))
    x[0] = 0.0 if initial_state is None else as_matrix(initial_state, "initial_state", cols=1)[:, 0]
    drive = u @ Bd.T + dt * w
    for k in range(1, n_samples):
        x[k] = Ad @ x[k - 1] + drive[k - 1]
    y = x @ system.C.T + z
    return Trajectory(np.arange(n_samples) * dt, x, u, y, w, z)

