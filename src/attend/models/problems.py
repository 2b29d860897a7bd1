"""The paper's reference problems, in one place: the systems (presets) and the mass-spring-damper
identification bank shared by the experiments (fig3, fig4, fig5, rhythm-learning), the benchmarks
and the tests.

Systems: :func:`mass_spring_damper` (paper eq. 2), :func:`convolution_model` (ACC 2020 observer
benchmark), :func:`identification_system` (Entropy 2021 identification benchmark),
:func:`quadrotor_roll` (Bos et al. 2022 real flights); ``PRESETS`` maps their command-line names
to them.

Mass-spring-damper bank (the ACC 2020 identification setting): ``MSD_FREE`` marks the unknown
entries theta3 = -k/m, theta4 = -b/m, theta6 = 1/m of theta = [vec A; vec B; vec C];
``MSD_PUBLISHED_THETA`` their published values; :func:`msd_logs` simulates logs under the input
u(t) = exp(-0.25 (t - 12)^2); :func:`msd_random_priors` draws the prior means of the unknown
entries uniformly in [-2, 2], one draw per seed. The known entries get
:data:`attend.constants.KNOWN_PRIOR_PRECISION`.
"""

from __future__ import annotations

import numpy as np

from attend._validation import positive_scalar
from attend.models.linear import LinearSystem, simulate
from attend.models.parameters import parameter_vector

__all__ = [
    "MSD_FREE",
    "MSD_PUBLISHED_THETA",
    "convolution_model",
    "identification_system",
    "mass_spring_damper",
    "msd_input",
    "msd_logs",
    "msd_random_priors",
    "quadrotor_roll",
]


def mass_spring_damper(mass: float = 1.4, stiffness: float = 0.8, damping: float = 0.4) -> LinearSystem:
    """The paper's mass-spring-damper (eq. 2): mass m [kg], stiffness k [N/m], damping b [N s/m];
    states x [m], dx/dt [m/s].

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
    """The ACC 2020 observer benchmark: 2 states, 1 input, 4 outputs."""
    return LinearSystem(
        A=[[-0.25, 1.0], [-0.5, -0.25]],
        B=[[1.0], [0.0]],
        C=[[0.125, 0.1633], [0.125, 0.0676], [0.125, -0.0676], [0.125, -0.1633]],
    )


def identification_system() -> LinearSystem:
    """The Entropy 2021 identification benchmark: 2 states, 1 input, 4 outputs."""
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


# --- the mass-spring-damper identification bank ---------------------------------------------

#: theta3 = -k/m, theta4 = -b/m, theta6 = 1/m (1-based positions in theta = [vec A; vec B; vec C])
MSD_FREE = np.array([False, False, True, True, False, True, False, False])
#: their published values (m = 1.4 kg, k = 0.8 N/m, b = 0.4 N s/m)
MSD_PUBLISHED_THETA = {"theta3": -0.5714, "theta4": -0.2857, "theta6": 0.7143}


def msd_input(time: np.ndarray) -> np.ndarray:
    """The bank's input force u(t) = exp(-0.25 (t - 12)^2) [N] at the sample times ``time`` (N,) [s],
    as (N, 1)."""
    return np.exp(-0.25 * (time - 12.0) ** 2)[:, None]


def msd_logs(seeds, sensor_std, process_std, dt=0.1, duration=32.0, kernel_width=0.5):
    """Simulated mass-spring-damper logs: outputs (R, T, 1), inputs (R, T, 1), one run per
    (seed, sensor_std) pair of the broadcast arrays; u(t) = :func:`msd_input`.

    seeds: simulation seeds; sensor_std, process_std: per-sample noise standard deviations
    [m], [m/s^2]; dt [s] sampling interval; duration [s]; kernel_width s [s] of both noises.
    """
    system = mass_spring_damper()
    time = np.arange(int(round(duration / dt))) * dt
    u = msd_input(time)
    seeds, sensor_std = np.broadcast_arrays(np.asarray(seeds), np.asarray(sensor_std, dtype=float))
    outputs, inputs = [], []
    for seed, std in zip(seeds.ravel(), sensor_std.ravel()):  # simulation only; learning is batched
        log = simulate(system, u, dt, kernel_width=kernel_width, process_std=process_std,
                       measurement_std=std, seed=int(seed))
        outputs.append(log.outputs)
        inputs.append(log.inputs)
    return np.array(outputs), np.array(inputs)


def msd_random_priors(seeds, rng_offset: int = 1000) -> np.ndarray:
    """Prior means (len(seeds), 8): the true theta with theta3, theta4, theta6 uniform in [-2, 2].

    seeds: one draw per seed, from numpy's default_rng(rng_offset + seed); rng_offset: keeps the
    priors' random streams apart from the simulation's.
    """
    eta = np.tile(parameter_vector(mass_spring_damper()), (len(seeds), 1))
    for k, seed in enumerate(seeds):
        eta[k, MSD_FREE] = np.random.default_rng(rng_offset + int(seed)).uniform(-2.0, 2.0, MSD_FREE.sum())
    return eta
