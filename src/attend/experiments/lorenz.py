"""Lorenz attractor observed with coloured noise: nonlinear DEM against EKF/UKF smoothers and a
particle smoother (in the spirit of SPM's DEM Lorenz demo).

dx/dt = [sigma (x2 - x1); x1 (rho - x3) - x2; x1 x2 - beta x3] + w, y = x + z, sigma = 10,
rho = 28, beta = 8/3 (an autonomous system: no inputs). w, z: white noise convolved with a
Gaussian kernel of width s. DEM uses the true precisions (Pi_z = 1/sigma_z^2, Pi_w = 1/sigma_w^2)
and embedding order p = 6; the Kalman baselines (extended and unscented, filter + RTS smoother)
assume white noise of the same per-sample variance; the particle smoother models the coloured
noise by AR processes (a reference for the posterior mean, see
:func:`attend.perception.nonlinear_smoothers.particle_smoother`).
"""

from __future__ import annotations

import sys

import numpy as np

from attend.experiments import _nonlinear
from attend.experiments._result import Claim, ExperimentResult
from attend.models.nonlinear import NonlinearSystem

SETTINGS = dict(
    dt=0.01, duration=4.0, kernel_width=0.02, process_std=20.0, measurement_std=1.0, embedding_order=6,
    input_order=0, input_prior_log_precision=0.0, initial_state=[1.0, 1.0, 24.0], initial_std=1.0,
    sigma=10.0, rho=28.0, beta=8.0 / 3.0, particles=100_000, ar_order=3, particle_lag=20,
)


def lorenz_system(sigma: float = 10.0, rho: float = 28.0, beta: float = 8.0 / 3.0) -> NonlinearSystem:
    """The Lorenz system, all three states measured (y = x), with its analytic Jacobians;
    sigma [1/s], rho [-], beta [1/s]: the Lorenz parameters.

    f and g also accept (3, k) columns (vectorized=True: the particle smoother and the Kalman
    baselines move all particles or sigma points in one call).
    """

    def f(x, v):
        return np.array([sigma * (x[1] - x[0]), x[0] * (rho - x[2]) - x[1], x[0] * x[1] - beta * x[2]])

    def jacobian_f(x, v):
        fx = np.array([[-sigma, sigma, 0.0], [rho - x[2], -1.0, -x[0]], [x[1], x[0], -beta]])
        return fx, np.zeros((3, 0))

    return NonlinearSystem(f, lambda x, v: 1.0 * np.asarray(x), 3, 0, 3, state_names=("x1", "x2", "x3"),
                           output_names=("y1", "y2", "y3"), jacobian_f=jacobian_f,
                           jacobian_g=lambda x, v: (np.eye(3), np.zeros((3, 0))), vectorized=True)


def build_system(cfg: dict) -> NonlinearSystem:
    """The Lorenz system of a settings dict ``cfg`` (keys sigma, rho, beta)."""
    return lorenz_system(cfg["sigma"], cfg["rho"], cfg["beta"])


def build_jax_system(cfg: dict) -> NonlinearSystem:
    """The same system with f and g written in jax.numpy, for NonlinearDEM(backend="jax") (needs
    JAX); cfg: the settings dict (keys sigma, rho, beta)."""
    import jax.numpy as jnp

    sigma, rho, beta = cfg["sigma"], cfg["rho"], cfg["beta"]

    def f(x, v):
        return jnp.stack([sigma * (x[1] - x[0]), x[0] * (rho - x[2]) - x[1], x[0] * x[1] - beta * x[2]])

    return NonlinearSystem(f, lambda x, v: 1.0 * x, 3, 0, 3, state_names=("x1", "x2", "x3"),
                           output_names=("y1", "y2", "y3"))


def true_input(time: np.ndarray) -> np.ndarray:
    """No inputs: an autonomous system ((N, 0) array for the N sample times ``time`` [s])."""
    return np.zeros((len(time), 0))


def run(quick: bool = True, progress: bool = True, seeds: int | None = None) -> ExperimentResult:
    """State SSE of DEM, EKF, UKF and the particle smoother over seeds (quick: 3 seeds, 2 s, 1000
    particles; full: 20 seeds, 4 s, 100000 particles). quick: the short run; progress: a progress
    bar; seeds: the number of seeds."""
    return _nonlinear.run(sys.modules[__name__], quick, progress, seeds, dict(duration=2.0, particles=1000))


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """lorenz.png, written into ``out_dir``, from ``result.tables``: the three states of seed 0 (true, DEM, UKF, coloured UKS,
    particle) and the state SSE per method and seed."""
    return _nonlinear.plot(result, out_dir, ["x1 [dimensionless]", "x2 [dimensionless]", "x3 [dimensionless]"],
                           sse_unit="dimensionless")


#: the issue's targets (DEM vs the particle reference and the UKF smoother, speed) as claims
claims = _nonlinear.claims

CAPTIONS = {
    "lorenz.png": "Lorenz attractor (sigma = 10, rho = 28, beta = 8/3) observed with coloured noise (kernel width "
                  "s = 2 samples). Left three panels: the states of seed 0, truth (black) against nonlinear DEM, "
                  "the white-noise UKF smoother, the coloured-noise UKS and the particle smoother. Right: state "
                  "SSE per seed and method (log scale); DEM meets its targets when its box sits at or below "
                  "1.2x the particle box and below the UKF box.",
}
