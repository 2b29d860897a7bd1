"""How good can any estimator be on the Lorenz reproduction? The MAP under the simulator's own model.

    PYTHONPATH=src python benchmarks/bench_lorenz_floor.py [--seeds 100] [--workers 2]

The issue's target asks DEM (path mode) to be at or below the white-noise UKF smoother's state SSE
on Lorenz. Path mode loses by 1.4 % with SPM's linearised motion and ties with motion="path"
(bench_nonlinear.py part 8). This benchmark asks how far below the smoother any estimator could go,
with a reference that knows everything the simulation did: the maximum a posteriori trajectory
under ``simulate_nonlinear``'s exact generative model,

    x[k] = Phi(x[k-1], w[k-1])    (RK4, 10 sub-steps, w held over the sample: the simulator's map)
    w = sigma_w K e_w,  y = x + z,  z = sigma_z K e_z,  e ~ N(0, I),  x[0] ~ N(m0, s0^2 I)

(K: the valid convolution with the unit-energy Gaussian kernel of width s, exactly as
:func:`attend.models.noise.coloured_noise` draws it). The unknowns are the states x[0..N-1] and the process
innovations e_w; the sensor innovations are integrated out (z ~ N(0, sigma_z^2 K K' + (delta
sigma_z)^2 I), delta = 1e-4: the jitter that makes the near-singular Toeplitz covariance factorable).
The dynamics enter as defects (x[k] - Phi(x[k-1], w[k-1])) / defect_std with defect_std = 1e-3
(multiple shooting: from the UKF smoother's trajectory Levenberg-Marquardt converges in ~15 steps
on every seed, where single shooting through the chaotic flow stalls on most). Under a linear f the
MAP is the exact posterior mean of this model; the first check below confirms that on a damped
linear system (the MAP against dense Gaussian conditioning with the same defect and jitter). For
Lorenz the MAP is not the posterior mean, but with y = x and sigma_z = 1 the posterior is close to
Gaussian around it.

Prints: the linear check; the MAP's sensitivity to delta and defect_std on 3 seeds; then, on
``--seeds`` seeds of the reproduction's settings (4 s at dt = 0.01 s, s/dt = 2), the median state
SSE of the MAP, the UKF smoother, and path mode with both motions, and each one's per-seed ratio to
the UKF smoother (median, bootstrap 95 % interval, seeds below 1, paired Wilcoxon p).
~17 s per seed on one core (the MAP's dense normal equations, 2418 unknowns). Not part of the test run.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")  # one core per worker, before numpy loads BLAS

import argparse  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402
from multiprocessing import Pool  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.linalg import cholesky, solve_triangular  # noqa: E402

from attend.experiments import _nonlinear, lorenz  # noqa: E402
from attend.models.noise import gaussian_kernel  # noqa: E402
from attend.perception.nonlinear_smoothers import unscented_kalman  # noqa: E402
from attend.perception.nonlinear_smoothers.kalman import _rk4  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_nonlinear import _paired_log  # noqa: E402

SENSOR_JITTER = 1e-4  # delta: white share of the sensor std in the MAP's model
DEFECT_STD = 1e-3  # state units: the slack of the dynamics per sample
SUBSTEPS = 10  # RK4 sub-steps per sample, as simulate_nonlinear


def convolution_matrix(kernel: np.ndarray, n_samples: int) -> np.ndarray:
    """K (N, N + L - 1) with K e = the valid convolution of white e with ``kernel`` (length L),
    as coloured_noise draws w from e."""
    length = len(kernel)
    K = np.zeros((n_samples, n_samples + length - 1))
    for k in range(n_samples):
        K[k, k:k + length] = kernel[::-1]
    return K


def one_sample(flow, x: np.ndarray, w: np.ndarray, dt: float, substeps: int = SUBSTEPS) -> np.ndarray:
    """Phi(x, w): RK4 over one sample dt [s] of dx/dt = flow(x) + w with w held; x, w (n, batch)
    (the Kalman baselines' integrator, as simulate_nonlinear steps)."""
    return _rk4(None, x, None, dt, substeps, w=w, call=flow)


class SimulatorModel:
    """The residuals r(x, e_w) whose squared norm is -2 log p(x, e_w | y) + const (module docstring).
    flow: f(x) for x (n, batch); y: (N, n) outputs (y = x + z); dt [s]; s: kernel width [s];
    sigma_w, sigma_z: the noises' stds per sample; m0, s0: the prior on x[0]."""

    def __init__(self, flow, y, dt, s, sigma_w, sigma_z, m0, s0, jitter=SENSOR_JITTER, defect_std=DEFECT_STD):
        self.flow, self.y, self.dt = flow, y, dt
        self.sigma_w, self.m0, self.s0, self.defect_std = sigma_w, np.asarray(m0, float), s0, defect_std
        n_samples = len(y)
        self.K = convolution_matrix(gaussian_kernel(dt, s), n_samples)
        covariance = sigma_z**2 * (self.K @ self.K.T) + (jitter * sigma_z) ** 2 * np.eye(n_samples)
        self.whiten = solve_triangular(cholesky(covariance, lower=True), np.eye(n_samples), lower=True)

    def residuals(self, x, e):
        """(r, w): r = [whitened y - x per channel; defects / defect_std; e_w; (x[0] - m0) / s0]."""
        w = self.sigma_w * (self.K @ e)
        predicted = one_sample(self.flow, x[:-1].T, w[:-1].T, self.dt).T
        r = np.concatenate([(self.whiten @ (self.y - x)).T.ravel(), ((x[1:] - predicted) / self.defect_std).ravel(),
                            e.ravel(), (x[0] - self.m0) / self.s0])
        return r, w

    def sensitivities(self, x, w, step=1e-6):
        """(Phi_x, Phi_w), each (N - 1, n, n): d Phi / dx and d Phi / dw at every sample (central
        differences, all samples and directions in one batch)."""
        n = x.shape[1]
        states = np.repeat(x[:-1].T[:, :, None], 2 * n, axis=2)
        noises = np.repeat(w[:-1].T[:, :, None], 2 * n, axis=2)
        shift = np.concatenate([np.eye(n), -np.eye(n)], axis=1)[:, None, :] * step
        out = []
        for moved_states, moved_noises in ((states + shift, noises), (states, noises + shift)):
            ends = one_sample(self.flow, moved_states.reshape(n, -1), moved_noises.reshape(n, -1), self.dt)
            ends = ends.reshape(n, len(x) - 1, 2 * n)
            out.append(np.transpose((ends[:, :, :n] - ends[:, :, n:]) / (2 * step), (1, 0, 2)))
        return out

    def jacobian(self, x, w):
        """dr/d(x, e_w): dense (rows of r, N n + P n), x ordered (sample, state), e_w (lag, state)."""
        n_samples, n = x.shape
        lags = self.K.shape[1]
        n_x = n_samples * n
        phi_x, phi_w = self.sensitivities(x, w)
        J = np.zeros((n_samples * n + (n_samples - 1) * n + lags * n + n, n_x + lags * n))
        for a in range(n):
            J[a * n_samples:(a + 1) * n_samples, np.arange(n_samples) * n + a] = -self.whiten
        scale = 1.0 / self.defect_std
        for k in range(1, n_samples):
            rows = n_samples * n + (k - 1) * n + np.arange(n)
            J[rows, k * n:(k + 1) * n] = scale * np.eye(n)
            J[rows, (k - 1) * n:k * n] = -scale * phi_x[k - 1]
            J[rows, n_x:] = -(scale * self.sigma_w) * np.einsum("ac,p->apc", phi_w[k - 1], self.K[k - 1]).reshape(n, -1)
        first = n_samples * n + (n_samples - 1) * n
        J[first:first + lags * n, n_x:] = np.eye(lags * n)
        J[first + lags * n:, :n] = np.eye(n) / self.s0
        return J


def simulator_map(model: SimulatorModel, start: np.ndarray, max_iterations: int = 60):
    """(x (N, n), -2 log posterior + const, iterations): Levenberg-Marquardt on model's residuals
    from the trajectory ``start`` (N, n), innovations 0."""
    x, e = start.astype(float).copy(), np.zeros((model.K.shape[1], start.shape[1]))
    r, w = model.residuals(x, e)
    cost = float(r @ r)
    n_x = x.size
    for iteration in range(1, max_iterations + 1):
        J = model.jacobian(x, w)
        H, gradient = J.T @ J, J.T @ r
        damping = 1e-8
        while damping < 1e4:
            step = -np.linalg.solve(H + damping * np.diag(np.diag(H)), gradient)
            x_new, e_new = x + step[:n_x].reshape(x.shape), e + step[n_x:].reshape(e.shape)
            r_new, w_new = model.residuals(x_new, e_new)
            cost_new = float(r_new @ r_new)
            if np.isfinite(cost_new) and cost_new <= cost:
                break
            damping *= 10
        if not (np.isfinite(cost_new) and cost_new <= cost):
            return x, cost, iteration
        decrease = cost - cost_new
        x, e, r, w, cost = x_new, e_new, r_new, w_new, cost_new
        if decrease < 1e-10 * cost:
            return x, cost, iteration
    return x, cost, max_iterations


def linear_check(seed: int = 0) -> float:
    """Max |MAP - exact posterior mean| / posterior std on a damped linear system with the Lorenz
    settings' noise, y = x: the posterior by dense Gaussian conditioning on the same affine map."""
    cfg = lorenz.SETTINGS
    dt, s, sigma_w, sigma_z = cfg["dt"], cfg["kernel_width"], cfg["process_std"], cfg["measurement_std"]
    A = np.array([[-0.5, 3.0, 0.0], [-3.0, -0.5, 0.0], [0.0, 0.0, -1.0]])
    n, n_samples, m0, s0 = 3, 150, np.array([1.0, 1.0, 2.0]), 1.0

    def flow(x):
        return A @ x

    rng = np.random.default_rng(seed)
    kernel = gaussian_kernel(dt, s)
    K = convolution_matrix(kernel, n_samples)
    M = one_sample(flow, np.eye(n), np.zeros((n, n)), dt)  # x[k] = M x[k-1] + G w[k-1] (+ defect)
    G = one_sample(flow, np.zeros((n, n)), np.eye(n), dt)
    x = np.zeros((n_samples, n))
    x[0] = m0 + s0 * rng.standard_normal(n)
    w = sigma_w * (K @ rng.standard_normal((K.shape[1], n)))
    for k in range(1, n_samples):
        x[k] = M @ x[k - 1] + G @ w[k - 1]
    y = x + sigma_z * (K @ rng.standard_normal((K.shape[1], n)))
    model = SimulatorModel(flow, y, dt, s, sigma_w, sigma_z, m0, s0)
    estimate, _, _ = simulator_map(model, y)
    # dense conditioning: x = T_0 x0 + T_w w + T_d d, d ~ N(0, defect_std^2), all stacked (sample, state)
    T0 = np.zeros((n_samples * n, n))
    Tw = np.zeros((n_samples * n, n_samples * n))
    T0[:n] = np.eye(n)
    for k in range(1, n_samples):
        T0[k * n:(k + 1) * n] = M @ T0[(k - 1) * n:k * n]
        Tw[k * n:(k + 1) * n] = M @ Tw[(k - 1) * n:k * n]
        Tw[k * n:(k + 1) * n, (k - 1) * n:k * n] += G
    time_cov = K @ K.T
    cov_w = sigma_w**2 * np.kron(time_cov, np.eye(n))
    Td = Tw @ np.kron(np.eye(n_samples), np.linalg.inv(G))  # a defect d enters as w = G^-1 d
    cov_x = s0**2 * T0 @ T0.T + Tw @ cov_w @ Tw.T + DEFECT_STD**2 * Td @ Td.T
    mean_x = (T0 @ m0)
    cov_z = np.kron(sigma_z**2 * time_cov + (SENSOR_JITTER * sigma_z) ** 2 * np.eye(n_samples), np.eye(n))
    gain = cov_x @ np.linalg.inv(cov_x + cov_z)
    posterior = mean_x + gain @ (y.ravel() - mean_x)
    std = np.sqrt(np.clip(np.diag(cov_x - gain @ cov_x), 1e-300, None))
    return float(np.max(np.abs(estimate.ravel() - posterior) / std))


def one_seed(seed: int, sensitivity: bool = False) -> dict:
    """State SSE (interior samples) of the MAP, the UKF smoother and path mode (both motions) on
    the reproduction's log of ``seed``; with ``sensitivity`` also the MAP's with delta 1e-2 and
    defect_std 1e-4."""
    cfg = dict(lorenz.SETTINGS)
    p = cfg["embedding_order"]
    system, states, _, outputs = _paired_log(lorenz, cfg, seed, 1)
    trim = slice(p + 1, len(states) - p - 1)
    smoother = unscented_kalman(system, cfg["dt"], outputs, **_nonlinear.kalman_options(system, cfg))

    def flow(x):
        return system.f(x, np.zeros((0, x.shape[1])))

    def reference(**settings):
        model = SimulatorModel(flow, outputs, cfg["dt"], cfg["kernel_width"], cfg["process_std"],
                               cfg["measurement_std"], cfg["initial_state"], cfg["initial_std"], **settings)
        return simulator_map(model, smoother.states)[0]

    estimates = {"MAP": reference(), "UKF": smoother.states}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for motion in ("linearized", "path"):
            estimates[f"path ({motion})"] = _nonlinear._dem(system, cfg, states="path", motion=motion).estimate(
                outputs).states
    if sensitivity:
        estimates["MAP, delta 1e-2"] = reference(jitter=1e-2)
        estimates["MAP, defect 1e-4"] = reference(defect_std=1e-4)
    return {key: float(np.sum((value - states)[trim] ** 2)) for key, value in estimates.items()}


def summarise(rows: list[dict]) -> None:
    """Medians and per-seed ratios to the UKF smoother."""
    from scipy.stats import wilcoxon

    rng = np.random.default_rng(0)
    ukf = np.array([row["UKF"] for row in rows])
    print(f"  UKF smoother: state SSE median {np.median(ukf):.1f}")
    for key in ("MAP", "path (linearized)", "path (path)"):
        mine = np.array([row[key] for row in rows])
        ratio = mine / ukf
        draws = [np.median(ratio[rng.integers(0, len(ratio), len(ratio))]) for _ in range(2000)]
        low, high = np.percentile(draws, [2.5, 97.5])
        print(f"  {key:18s}: SSE median {np.median(mine):7.1f}; per-seed ratio to the UKF smoother "
              f"{np.median(ratio):.4f} [{low:.4f}, {high:.4f}], below 1 on {np.sum(ratio < 1)}/{len(ratio)}, "
              f"Wilcoxon p {wilcoxon(mine, ukf).pvalue:.2g}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100, help="Lorenz seeds (the reproduction's settings)")
    parser.add_argument("--workers", type=int, default=2, help="processes (one core each)")
    args = parser.parse_args()
    print("== the MAP under the simulator's model (Lorenz reproduction, 4 s at dt = 0.01 s, s/dt = 2)")
    print(f"  linear check: max |MAP - exact posterior mean| / posterior std = {linear_check():.2e}", flush=True)
    for seed, row in enumerate(map(lambda seed: one_seed(seed, sensitivity=True), range(3))):
        print(f"  seed {seed}: MAP SSE {row['MAP']:.2f}; with delta 1e-2 {row['MAP, delta 1e-2']:.2f}, with defect_std "
              f"1e-4 {row['MAP, defect 1e-4']:.2f}; UKF smoother {row['UKF']:.2f}", flush=True)
    with Pool(args.workers) as pool:
        rows = []
        for index, row in enumerate(pool.imap(one_seed, range(args.seeds)), 1):
            rows.append(row)
            if index % 10 == 0 or index == args.seeds:
                print(f"  {index} seeds done", flush=True)
    summarise(rows)


if __name__ == "__main__":
    main()
