"""Damped nonlinear pendulum pushed by an unknown input, its angle seen through a nonlinear sensor:
nonlinear DEM (states and input) against input-augmented EKF/UKF smoothers and a particle smoother.

d theta/dt = omega, d omega/dt = -(g/L) sin theta - b omega + u + w; y = [sin theta, cos theta] + z
(the angle measured as a unit vector, e.g. an accelerometer pair or a rotary encoder's quadrature
signals). g/L = 9.81 1/s^2, b = 0.3 1/s. The input u(t) [rad/s^2] is two smooth pushes,
4 exp(-(t-5)^2/(2 0.7^2)) - 3 exp(-(t-12)^2/2), unknown to every estimator: DEM gives it a
zero-mean prior of precision exp(input_prior_log_precision) and smoothness input_kernel_width = 0.7 s
(the pushes' own time scale; the noise's s = 0.1 s would be far rougher), the Kalman baselines a
random walk whose one-sample steps have that prior's variance
(:func:`attend.perception.nonlinear_smoothers.input_random_walk_variance`), the coloured UKS and
the particle smoother the DEM prior as a coloured process.
"""

from __future__ import annotations

import sys

import numpy as np

from attend.experiments import _nonlinear
from attend.experiments._result import Claim, ExperimentResult
from attend.models.nonlinear import NonlinearSystem

SETTINGS = dict(
    dt=0.05, duration=20.0, kernel_width=0.1, process_std=[0.05, 0.5], measurement_std=0.05, embedding_order=6,
    input_order=2, input_prior_log_precision=-2.0, input_kernel_width=0.7, initial_state=[0.5, 0.0],
    initial_std=[0.05, 0.2], gravity_over_length=9.81, damping=0.3, particles=100_000, ar_order=3, particle_lag=20,
)


def pendulum_system(gravity_over_length: float = 9.81, damping: float = 0.3) -> NonlinearSystem:
    """The pendulum [theta, omega] with input u (angular acceleration), observed as (sin, cos) theta;
    gravity_over_length: g/L [1/s^2]; damping: b [1/s].

    f and g also accept (2, k) columns (vectorized=True: the particle smoother and the Kalman
    baselines move all particles or sigma points in one call).
    """

    def f(x, v):
        return np.array([x[1], -gravity_over_length * np.sin(x[0]) - damping * x[1] + v[0]])

    def g(x, v):
        return np.array([np.sin(x[0]), np.cos(x[0])])

    def jacobian_f(x, v):
        return np.array([[0.0, 1.0], [-gravity_over_length * np.cos(x[0]), -damping]]), np.array([[0.0], [1.0]])

    def jacobian_g(x, v):
        return np.array([[np.cos(x[0]), 0.0], [-np.sin(x[0]), 0.0]]), np.zeros((2, 1))

    return NonlinearSystem(f, g, 2, 1, 2, state_names=("theta", "omega"), input_names=("u",),
                           output_names=("sin theta", "cos theta"), jacobian_f=jacobian_f, jacobian_g=jacobian_g,
                           vectorized=True)


def true_input(time: np.ndarray) -> np.ndarray:
    """u(t) [rad/s^2] at the sample times ``time`` [s]: two smooth pushes, at 5 s and 12 s."""
    return (4.0 * np.exp(-0.5 * ((time - 5.0) / 0.7) ** 2) - 3.0 * np.exp(-0.5 * ((time - 12.0) / 1.0) ** 2))[:, None]


def build_system(cfg: dict) -> NonlinearSystem:
    """The pendulum of a settings dict ``cfg`` (keys gravity_over_length, damping)."""
    return pendulum_system(cfg["gravity_over_length"], cfg["damping"])


def build_jax_system(cfg: dict) -> NonlinearSystem:
    """The same pendulum with f and g written in jax.numpy, for NonlinearDEM(backend="jax") (needs
    JAX); cfg: the settings dict (keys gravity_over_length, damping)."""
    import jax.numpy as jnp

    gravity_over_length, damping = cfg["gravity_over_length"], cfg["damping"]

    def f(x, v):
        return jnp.stack([x[1], -gravity_over_length * jnp.sin(x[0]) - damping * x[1] + v[0]])

    def g(x, v):
        return jnp.stack([jnp.sin(x[0]), jnp.cos(x[0])])

    return NonlinearSystem(f, g, 2, 1, 2, state_names=("theta", "omega"), input_names=("u",),
                           output_names=("sin theta", "cos theta"))


def run(quick: bool = True, progress: bool = True, seeds: int | None = None) -> ExperimentResult:
    """State and input SSE of DEM, augmented EKF/UKF and the particle smoother (quick: 3 seeds,
    15 s, 1000 particles; full: 20 seeds, 20 s, 100000 particles). quick: the short run;
    progress: a progress bar; seeds: the number of seeds."""
    return _nonlinear.run(sys.modules[__name__], quick, progress, seeds, dict(duration=15.0, particles=1000))


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """pendulum.png, written into ``out_dir``, from ``result.tables``: theta, omega and the input of seed 0 (true and
    estimated) and the state SSE per method and seed."""
    return _nonlinear.plot(result, out_dir, ["theta [rad]", "omega [rad/s]"], "input u [rad/s^2]",
                           sse_unit="rad^2 + (rad/s)^2")


#: the issue's targets (DEM vs the particle reference and the UKF smoother, speed) as claims
claims = _nonlinear.claims

CAPTIONS = {
    "pendulum.png": "Damped pendulum pushed by an unknown input, its angle seen as (sin, cos) with coloured noise "
                    "(s = 2 samples). Panels: theta, omega and the input u of seed 0, truth (black) against "
                    "nonlinear DEM, the input-augmented UKF smoother, the coloured-noise UKS and the particle "
                    "smoother; last panel: state SSE per seed and method (log scale). DEM follows the pushes but "
                    "with a larger error than the smoothers, which see the whole log.",
}
