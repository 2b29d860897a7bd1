"""Linear time-invariant systems, their zero-order-hold discretisation, presets and simulation.

Continuous-time model (paper eq. 1)::

    dx/dt = A x + B u + w        y = C x + z

x in R^n (states), u in R^r (inputs, "causes" v), y in R^m (outputs); w and z are coloured
noises (see :mod:`attend.noise`). Time is in seconds everywhere.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.linalg import expm

from attend._validation import AttendInputError, as_matrix, positive_scalar
from attend.noise import coloured_noise


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
            names = tuple(names) or tuple(f"{letter}{i + 1}" for i in range(size))
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


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Ad = expm(A dt), Bd = int_0^dt expm(A t) dt B from one block matrix exponential."""
    n, r = B.shape
    block = np.zeros((n + r, n + r))
    block[:n, :n] = A
    block[:n, n:] = B
    exponential = expm(block * dt)
    return exponential[:n, :n], exponential[:n, n:]


def observability_rank(A: np.ndarray, C: np.ndarray) -> int:
    """Numerical rank of [C; CA; ...; CA^(n-1)] (rows scaled to unit norm first)."""
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


# --- presets -------------------------------------------------------------------------------

def mass_spring_damper(mass: float = 1.4, stiffness: float = 0.8, damping: float = 0.4) -> LinearSystem:
    """The paper's mass-spring-damper (eq. 2): m [kg], k [N/m], b [N s/m]; states x [m], dx/dt [m/s].

    A = [[0, 1], [-k/m, -b/m]], B = [0; 1/m], C = [1, 0].
    """
    m = positive_scalar(mass, "mass", "kg")
    return LinearSystem(
        A=[[0.0, 1.0], [-stiffness / m, -damping / m]],
        B=[[0.0], [1.0 / m]],
        C=[[1.0, 0.0]],
        state_names=("position", "velocity"),
        input_names=("force",),
        output_names=("position",),
    )


def convolution_model() -> LinearSystem:
    """The ACC 2020 observer benchmark: 2 states, 1 input, 4 outputs (spec §7)."""
    return LinearSystem(
        A=[[-0.25, 1.0], [-0.5, -0.25]],
        B=[[1.0], [0.0]],
        C=[[0.125, 0.1633], [0.125, 0.0676], [0.125, -0.0676], [0.125, -0.1633]],
    )


def identification_system() -> LinearSystem:
    """The Entropy 2021 identification benchmark: 2 states, 1 input, 4 outputs (spec §7)."""
    return LinearSystem(
        A=[[0.0484, 0.7535], [-0.7617, -0.2187]],
        B=[[0.3604], [0.0776]],
        C=[[0.2265, -0.4786], [0.4066, -0.2641], [0.3871, 0.3817], [-0.1630, -0.9290]],
    )


def quadrotor_roll() -> LinearSystem:
    """Roll axis of the quadrotor of the real-flight benchmark (Bos et al. 2022).

    States phi [rad], phi_dot [rad/s]; inputs the four motor commands (raw units); output phi.
    """
    gain = 0.374838
    return LinearSystem(
        A=[[0.0, 1.0], [0.0, 0.0]],
        B=[[0.0, 0.0, 0.0, 0.0], [gain, -gain, -gain, gain]],
        C=[[1.0, 0.0]],
        state_names=("phi", "phi_dot"),
        input_names=("motor_1", "motor_2", "motor_3", "motor_4"),
        output_names=("phi",),
    )


PRESETS = {
    "mass-spring-damper": mass_spring_damper,
    "convolution": convolution_model,
    "identification": identification_system,
    "quadrotor-roll": quadrotor_roll,
}


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
    process_std=0.0,
    measurement_std=0.0,
    initial_state=None,
    seed: int | np.random.Generator | None = 0,
    process_kernel_width: float | None = None,
    sensor_kernel_width: float | None = None,
) -> Trajectory:
    """Simulate the generative process with coloured noise (spec §1).

    x[k] = Ad x[k-1] + Bd u[k-1] + dt w[k-1],  y[k] = C x[k] + z[k], with Ad, Bd the zero-order
    hold of (A, B) over dt [s] and w, z white noise convolved with a Gaussian kernel of width
    ``kernel_width`` [s] (standard deviations ``process_std``, ``measurement_std`` per sample,
    scalars or per channel). ``process_kernel_width`` / ``sensor_kernel_width`` [s] set the widths
    of w and z separately (0: white noise); each defaults to ``kernel_width``.
    """
    dt = positive_scalar(dt, "dt", "s")
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
