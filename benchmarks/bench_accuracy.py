"""Accuracy benchmark: the ACC 2020 observer setting (spec §7), DEM against the baselines.

Run:  python benchmarks/bench_accuracy.py [--seeds 50] [--process-precision LOG]

Setting: convolution_model, dt = 0.1 s, 320 samples, kernel width s = 0.5 s,
sigma_w = sigma_z = exp(-4), input u(t) = exp(-0.25 (t - 12)^2), DEM p = 6, d = 2, input prior
mean 0.5 with precision exp(-8). SSE = sum over trimmed samples p+2 .. N-p-2 (1-based) and over
states (or inputs) of the squared error. Medians over independent seeds (seed = 0..seeds-1).
Every figure is printed beside its published value or target.
"""

from __future__ import annotations

import os

# small dense algebra: one BLAS thread is much faster than oversubscribed threads on a busy machine
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from attend.perception import references as bl  # noqa: E402
from attend.perception.dem import DEMObserver  # noqa: E402
from attend.perception.kalman import KalmanEstimator  # noqa: E402
from attend.models.problems import convolution_model  # noqa: E402
from attend.models.linear import simulate  # noqa: E402

DT = 0.1
N_SAMPLES = 320
KERNEL_WIDTH = 0.5
SIGMA = np.exp(-4.0)
P, D = 6, 2
PRIOR_MEAN = 0.5
PRIOR_PRECISION = np.exp(-8.0)


def trimmed_sse(estimate: np.ndarray, truth: np.ndarray) -> float:
    """Sum of squared errors over samples p+2 .. N-p-2 (1-based), i.e. [p+1, N-p-2) 0-based."""
    window = slice(P + 1, N_SAMPLES - P - 2)
    return float(np.sum((estimate[window] - truth[window]) ** 2))


def run(seeds: int, log_process_precision: float, lag: int) -> dict[str, np.ndarray]:
    system = convolution_model()
    t = np.arange(N_SAMPLES) * DT
    u = np.exp(-0.25 * (t - 12.0) ** 2)[:, None]
    prior = np.full((N_SAMPLES, 1), PRIOR_MEAN)
    Q, R = bl.simulation_covariances(system, DT, SIGMA, SIGMA)
    common = dict(kernel_width=KERNEL_WIDTH, sensor_precision=np.exp(8.0),
                  process_precision=np.exp(log_process_precision), embedding_order=P, input_order=D)
    dem = DEMObserver(system, DT, input_prior_precision=PRIOR_PRECISION, **common)
    dem_known = DEMObserver(system, DT, known_inputs=True, **common)
    # attend's default estimator: the Kalman smoother under the coloured-noise model (x0 = 0 known,
    # as simulate() starts and exact_posterior assumes)
    noise = dict(kernel_width=KERNEL_WIDTH, sensor_precision=SIGMA**-2, process_precision=SIGMA**-2,
                 initial_state=np.zeros(system.n_states))
    kalman = KalmanEstimator(system, DT, known_inputs=False, input_prior_precision=PRIOR_PRECISION, **noise)
    kalman_known = KalmanEstimator(system, DT, **noise)
    out: dict[str, list[float]] = {k: [] for k in (
        "dem_state", "dem_input", "kf_ignoring", "kf_ignoring_lag", "aug_kf_state", "aug_kf_input",
        "aug_rts_state", "aug_rts_input", "exact_state", "exact_input", "dem_known", "ss_kf_known",
        "kf_known", "rts_known", "exact_known", "kf_ignoring_unscaled", "ss_kf_known_unscaled",
        "exact_state_expected", "exact_known_expected", "kalman_state", "kalman_input", "kalman_known",
        "kalman_filter_known")}
    # Q = sigma_w^2 I: the continuous-time noise variance without simulate()'s dt^2 (what the
    # published KF numbers are consistent with, see the report printed by main)
    Q_unscaled = SIGMA**2 * np.eye(system.n_states)
    for seed in range(seeds):
        trajectory = simulate(system, u, DT, kernel_width=KERNEL_WIDTH, process_std=SIGMA,
                              measurement_std=SIGMA, seed=seed)
        x, y = trajectory.states, trajectory.outputs
        est = dem.estimate(y, prior)
        out["dem_state"].append(trimmed_sse(est.states, x))
        out["dem_input"].append(trimmed_sse(est.inputs, u))
        kfi = bl.kalman_filter_ignoring_input(system, DT, y, process_covariance=Q, measurement_covariance=R)
        out["kf_ignoring"].append(trimmed_sse(kfi.states, x))
        kfl = bl.kalman_filter_ignoring_input(system, DT, y, process_covariance=Q, measurement_covariance=R,
                                              lag=lag)
        out["kf_ignoring_lag"].append(trimmed_sse(kfl.states, x))
        kfu = bl.kalman_filter_ignoring_input(system, DT, y, process_covariance=Q_unscaled, measurement_covariance=R)
        out["kf_ignoring_unscaled"].append(trimmed_sse(kfu.states, x))
        # random-walk input: increment variance from the input's own scale (max slope ~0.43/s)
        aug = dict(process_covariance=Q, measurement_covariance=R, input_variance=(0.05) ** 2,
                   initial_input=0.0, initial_input_std=1.0)
        ak = bl.augmented_kalman_filter(system, DT, y, lag=1, **aug)
        out["aug_kf_state"].append(trimmed_sse(ak.states, x))
        out["aug_kf_input"].append(trimmed_sse(ak.inputs, u))
        ar = bl.augmented_kalman_filter(system, DT, y, smooth=True, **aug)
        out["aug_rts_state"].append(trimmed_sse(ar.states, x))
        out["aug_rts_input"].append(trimmed_sse(ar.inputs, u))
        ex = bl.exact_posterior(system, DT, y, kernel_width=KERNEL_WIDTH, process_std=SIGMA,
                                measurement_std=SIGMA, input_prior_mean=PRIOR_MEAN,
                                input_prior_std=PRIOR_PRECISION ** -0.5)
        out["exact_state"].append(trimmed_sse(ex.states, x))
        out["exact_input"].append(trimmed_sse(ex.inputs, u))
        out["exact_state_expected"].append(trimmed_sse(ex.state_std, np.zeros_like(x)))
        ka = kalman.estimate(y, prior)
        out["kalman_state"].append(trimmed_sse(ka.states, x))
        out["kalman_input"].append(trimmed_sse(ka.inputs, u))
        # known input
        ek = dem_known.estimate(y, u)
        out["dem_known"].append(trimmed_sse(ek.states, x))
        ss = bl.steady_state_kalman_filter(system, DT, y, u, process_covariance=Q, measurement_covariance=R)
        out["ss_kf_known"].append(trimmed_sse(ss.states, x))
        ssu = bl.steady_state_kalman_filter(system, DT, y, u, process_covariance=Q_unscaled, measurement_covariance=R)
        out["ss_kf_known_unscaled"].append(trimmed_sse(ssu.states, x))
        kk = bl.kalman_filter(system, DT, y, u, process_covariance=Q, measurement_covariance=R)
        out["kf_known"].append(trimmed_sse(kk.states, x))
        rk = bl.rts_smoother(system, DT, y, u, process_covariance=Q, measurement_covariance=R)
        out["rts_known"].append(trimmed_sse(rk.states, x))
        xk = bl.exact_posterior(system, DT, y, u, kernel_width=KERNEL_WIDTH, process_std=SIGMA,
                                measurement_std=SIGMA)
        out["exact_known"].append(trimmed_sse(xk.states, x))
        out["exact_known_expected"].append(trimmed_sse(xk.state_std, np.zeros_like(x)))
        out["kalman_known"].append(trimmed_sse(kalman_known.estimate(y, u).states, x))
        out["kalman_filter_known"].append(trimmed_sse(kalman_known.filter(y, u).states, x))
    return {k: np.array(v) for k, v in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--process-precision", type=float, default=8.0,
                        help="log of the DEM process precision Pi_w (default 8 = 1/sigma_w^2)")
    args = parser.parse_args()
    delay = DEMObserver(convolution_model(), DT, kernel_width=KERNEL_WIDTH, sensor_precision=np.exp(8.0),
                        process_precision=np.exp(8.0), input_prior_precision=PRIOR_PRECISION, embedding_order=P,
                        input_order=D).delay
    start = time.perf_counter()
    r = run(args.seeds, args.process_precision, delay)
    elapsed = time.perf_counter() - start
    med = {k: float(np.median(v)) for k, v in r.items()}
    print(f"ACC 2020 setting, {args.seeds} seeds, DEM Pi_w = exp({args.process_precision:g}); "
          f"median SSE over samples {P + 2}..{N_SAMPLES - P - 2} ({elapsed:.1f} s)")
    rows = [
        ("unknown input: state SSE", None, None),
        ("  DEM", med["dem_state"], "published 1.71"),
        ("  KF ignoring input, Q = dt^2 sigma_w^2 I (simulator)", med["kf_ignoring"], "published 3.13"),
        ("  KF ignoring input, Q = sigma_w^2 I (no dt^2)", med["kf_ignoring_unscaled"], "published 3.13"),
        (f"  KF ignoring input, fixed lag {delay} (DEM's delay)", med["kf_ignoring_lag"], ""),
        ("  augmented KF (random-walk input, lag 1)", med["aug_kf_state"], ""),
        ("  augmented RTS smoother (random-walk input)", med["aug_rts_state"], ""),
        ("  kalman smoother (attend estimate's default)", med["kalman_state"], "= exact posterior up to ~1 %"),
        ("  exact posterior (GP input prior)", med["exact_state"], "the limit"),
        ("  exact posterior: expected SSE (sum of variances)", med["exact_state_expected"], ""),
        ("  ratio DEM / KF ignoring input (simulator Q)", med["dem_state"] / med["kf_ignoring"],
         f"target <= 0.6 (published {1.71 / 3.13:.2f})"),
        ("  ratio DEM / KF ignoring input (Q = sigma_w^2 I)", med["dem_state"] / med["kf_ignoring_unscaled"],
         f"target <= 0.6 (published {1.71 / 3.13:.2f})"),
        ("  ratio DEM / exact posterior", med["dem_state"] / med["exact_state"], "target <= 1.3"),
        ("unknown input: input SSE", None, None),
        ("  DEM", med["dem_input"], "published 2.04"),
        ("  augmented KF (lag 1)", med["aug_kf_input"], ""),
        ("  augmented RTS smoother", med["aug_rts_input"], ""),
        ("  kalman smoother (attend estimate's default)", med["kalman_input"], "= exact posterior up to ~1 %"),
        ("  exact posterior (GP input prior)", med["exact_input"], "the limit (of the GP prior, which the bump "
                                                                   "input is not drawn from)"),
        ("known input: state SSE", None, None),
        ("  DEM", med["dem_known"], "published 1.16"),
        ("  steady-state KF, Q = dt^2 sigma_w^2 I (simulator)", med["ss_kf_known"], "published 1.86"),
        ("  steady-state KF, Q = sigma_w^2 I (no dt^2)", med["ss_kf_known_unscaled"], "published 1.86"),
        ("  time-varying KF", med["kf_known"], ""),
        ("  RTS smoother", med["rts_known"], ""),
        ("  kalman filter (causal)", med["kalman_filter_known"], ""),
        ("  kalman smoother (attend estimate's default)", med["kalman_known"], "= exact posterior up to ~1 %"),
        ("  exact posterior", med["exact_known"], "the limit"),
        ("  exact posterior: expected SSE (sum of variances)", med["exact_known_expected"], ""),
        ("  ratio DEM / exact posterior", med["dem_known"] / med["exact_known"], "no target (the issue sets it for the unknown-input case); DEM uses one embedding window, the KF/RTS the whole trajectory"),
    ]
    for label, value, note in rows:
        if value is None:
            print(label)
        else:
            print(f"{label:<52s} {value:8.3f}   {note}")


if __name__ == "__main__":
    main()
