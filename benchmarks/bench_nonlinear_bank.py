"""Nonlinear DEM on unseen nonlinear systems: a random bank against the unscented smoothers.

    PYTHONPATH=src python benchmarks/bench_nonlinear_bank.py [--cases 36] [--first 0] [--fine 1] [--motion path]

Each case (seeded by its index) draws a system nobody tuned for:

    dx/dt = A x + B v + a tanh(W x) + w,        y = C x [+ c sin(H x)] + z

with A stable (eigenvalues 0.2-5 rad/s), the tanh term as large as the linear one (``a`` =
strength x |A| x state scale, strength 0.5-2; W scaled to the states so that it saturates), a
linear or a sinusoidal sensor, n = 2-4 states, m = 1-n outputs, no input, a measured input or an
unknown one (smooth pushes: white noise convolved with a Gaussian of width 0.5-1 s), noise of
kernel width s = 1, 2 or 4 samples, process noise 0.1-3 and sensor noise 3-30 % of the output's
spread, x[0] ~ N(0, 1). 400 samples at dt = 0.05 s (simulate_nonlinear: RK4, inputs and noise held
over each sample).

Every estimator gets the true noise settings and the same prior on x[0]: DEM's D-step, DEM path
mode (``states="path"``, p chosen as attend's "auto": the largest p <= 6 with a conditioned S),
the white-noise UKF smoother (per-sample variances, inputs as random walks with the prior's
one-sample steps), and the coloured UKS (AR(3) noise models). The score is the state SSE over
samples p + 1 .. N - p - 2 (the smoothers see the ends as DEM does not); per case the ratio to
the UKF smoother, then medians, the share of cases where DEM path mode is at or below the UKF
smoother, the worst cases, the calibration of path mode's std (|error| < 2 std), its misfit
warnings and its warnings that F has several maxima; with an unknown input, each method's input
SSE over the same samples and the medians of its ratio to the UKF smoother's. Not part of the test run.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from attend.models.generalized import smoothness_condition
from attend.models.noise import coloured_noise
from attend.perception.dem import AUTO_MAX_CONDITION
from attend.perception.nonlinear import NonlinearDEM
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear_smoothers import (
    coloured_unscented_smoother,
    input_random_walk_variance,
    unscented_kalman,
    white_noise_covariances,
)
from attend.models.linear import Trajectory

DT = 0.05  # s
SAMPLES = 400
#: the simulation runs FINE[0] times finer than the log's dt (inputs and noise held over each fine
#: step, 1: over each sample as robots' logs) and is then sampled every FINE[0] steps
FINE = [1]
METHODS = ("DEM", "DEM path", "UKF", "coloured UKS")
#: path mode's generalised motion (--motion): None = NonlinearDEM's default
MOTION = [None]


def draw_case(index: int) -> dict:
    """The system, log and settings of case ``index`` (module docstring)."""
    rng = np.random.default_rng(10_000 + index)
    n = int(rng.integers(2, 5))
    m = int(rng.integers(1, n + 1))
    input_kind = ("none", "measured", "unknown")[index % 3]
    r = 0 if input_kind == "none" else 1
    rates = np.exp(rng.uniform(np.log(0.2), np.log(5.0), n))
    basis = np.linalg.qr(rng.standard_normal((n, n)))[0]
    A = basis @ (np.diag(-rates) + np.triu(rng.standard_normal((n, n)) * rates.mean(), 1)) @ basis.T
    B = rng.standard_normal((n, r))
    C = rng.standard_normal((m, n))
    s = DT * float(rng.choice([1, 2, 4]))
    sigma_w = float(np.exp(rng.uniform(np.log(0.1), np.log(3.0))))
    width = float(rng.uniform(0.5, 1.0))
    time_axis = np.arange(SAMPLES) * DT
    step, fine_samples = DT / FINE[0], (SAMPLES - 1) * FINE[0] + 1  # simulated FINE times finer, then sampled
    u_fine = coloured_noise(fine_samples, r, step, width, 1.0, rng) if r else np.zeros((fine_samples, 0))
    u = u_fine[:: FINE[0]]
    # the state scale of the linear part (noise and inputs), to size the nonlinear terms
    linear = NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, n, r, m)
    probe = simulate_nonlinear(linear, u, DT, kernel_width=s, process_std=sigma_w, initial_state=np.zeros(n),
                               seed=index)
    scale = max(float(np.std(probe.states)), 1e-3)
    strength = float(rng.uniform(0.5, 2.0))
    W = rng.standard_normal((n, n)) / (scale * np.sqrt(n)) * 1.5
    a = strength * float(np.abs(np.linalg.eigvals(A)).mean()) * scale
    sensor_nonlinear = bool(rng.integers(2))
    H = rng.standard_normal((m, n)) / scale
    c = 0.5 * scale * float(np.abs(C).mean()) if sensor_nonlinear else 0.0

    def f(x, v):
        return A @ x + B @ v + a * np.tanh(W @ x)

    def g(x, v):
        return C @ x + c * np.sin(H @ x)

    system = NonlinearSystem(f, g, n, r, m)
    x0 = rng.standard_normal(n)
    clean = simulate_nonlinear(system, u, DT, kernel_width=s, process_std=sigma_w, initial_state=x0, seed=index)
    sigma_z = float(np.exp(rng.uniform(np.log(0.03), np.log(0.3)))) * max(float(np.std(clean.outputs)), 1e-3)
    fine = simulate_nonlinear(system, u_fine, step, kernel_width=s, process_std=sigma_w, measurement_std=sigma_z,
                              initial_state=x0, seed=index + 1, substeps=max(1, 10 // FINE[0]))
    log = Trajectory(time_axis, fine.states[:: FINE[0]], u, fine.outputs[:: FINE[0]], fine.process_noise[:: FINE[0]],
                     fine.measurement_noise[:: FINE[0]])
    p = next((p for p in range(6, 0, -1) if smoothness_condition(p + 1, s, DT) <= AUTO_MAX_CONDITION), 1)
    return dict(index=index, system=system, log=log, time=time_axis, s=s, sigma_w=sigma_w, sigma_z=sigma_z,
                input_kind=input_kind, input_width=width, p=p, n=n, m=m, strength=strength,
                sensor="sin" if sensor_nonlinear else "linear")


def run_case(case: dict) -> dict:
    """State SSE, seconds and (path mode) coverage and misfit warning of every method on ``case``."""
    system, log, s, p = case["system"], case["log"], case["s"], case["p"]
    n, unknown = case["n"], case["input_kind"] == "unknown"
    inputs = log.inputs if case["input_kind"] == "measured" else None
    prior_precision = 1.0  # the pushes' std is 1
    dem_options = dict(embedding_order=p, input_order=2, known_inputs=case["input_kind"] == "measured")
    path_options = {} if MOTION[0] is None else dict(motion=MOTION[0])
    if unknown:
        dem_options.update(input_prior_precision=prior_precision, input_kernel_width=case["input_width"])
    Pi_z, Pi_w = 1 / case["sigma_z"] ** 2, 1 / case["sigma_w"] ** 2
    Q, R = white_noise_covariances(system, DT, kernel_width=s, process_std=case["sigma_w"],
                                   measurement_std=case["sigma_z"])
    ukf_options = dict(process_covariance=Q, measurement_covariance=R, initial_mean=np.zeros(n), initial_covariance=1.0)
    if unknown:
        ukf_options.update(input_variance=float(input_random_walk_variance(prior_precision,
                                                                           kernel_width=case["input_width"], dt=DT)))
    runs = {
        "DEM": lambda: NonlinearDEM(system, DT, kernel_width=s, sensor_precision=Pi_z, process_precision=Pi_w,
                                    **dem_options).estimate(log.outputs, inputs),
        "DEM path": lambda: NonlinearDEM(system, DT, kernel_width=s, sensor_precision=Pi_z, process_precision=Pi_w,
                                         states="path", **dem_options, **path_options).estimate(
            log.outputs, inputs, initial_state=np.zeros(n), initial_state_std=1.0),
        "UKF": lambda: unscented_kalman(system, DT, log.outputs, inputs, smooth=True, **ukf_options),
        "coloured UKS": lambda: coloured_unscented_smoother(
            system, DT, log.outputs, inputs, kernel_width=s, process_std=case["sigma_w"],
            measurement_std=case["sigma_z"], input_prior_std=1.0 if unknown else None,
            input_kernel_width=case["input_width"] if unknown else None, initial_mean=np.zeros(n), initial_std=1.0),
    }
    trim = slice(p + 1, SAMPLES - p - 1)
    out = dict(sse={}, seconds={}, failed={}, input_sse={})
    for method, run in runs.items():
        start = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                estimate = run()
        except Exception as error:  # noqa: BLE001 - a refusal or a failure is a result of the bank
            out["failed"][method] = f"{type(error).__name__}: {str(error)[:80]}"
            continue
        out["seconds"][method] = time.perf_counter() - start
        error = (estimate.states - log.states)[trim]
        out["sse"][method] = float(np.sum(error ** 2)) if np.all(np.isfinite(error)) else np.inf
        if unknown:  # the unknown push's SSE over the same samples
            miss = (np.asarray(estimate.inputs).reshape(log.inputs.shape) - log.inputs)[trim]
            out["input_sse"][method] = float(np.sum(miss ** 2)) if np.all(np.isfinite(miss)) else np.inf
        if method == "DEM path":
            out["coverage"] = float(np.mean(np.abs(error) < 2 * estimate.state_std[trim]))
            out["warned"] = any("far from DEM's generalised model" in str(w.message) for w in caught)
            out["maxima"] = any("more than one maximum" in str(w.message) for w in caught)
            out["unconverged"] = any("not converged" in str(w.message) for w in caught)
    return out


def describe(case: dict) -> str:
    return (f"case {case['index']:3d} n={case['n']} m={case['m']} input={case['input_kind']:8s} "
            f"sensor={case['sensor']:6s} s/dt={case['s'] / DT:.0f} p={case['p']} tanh x{case['strength']:.1f}")


def summarise(rows: list[tuple[dict, dict]]) -> None:
    """Medians of the ratios to the UKF smoother, overall and by regime; calibration; failures."""
    def ratio(result, method):
        ukf = result["sse"].get("UKF")
        mine = result["sse"].get(method)
        return np.nan if ukf in (None, np.inf) or mine is None else mine / ukf

    groups = [("all", lambda case: True)]
    groups += [(f"s/dt = {k}", lambda case, k=k: round(case["s"] / DT) == k) for k in (1, 2, 4)]
    groups += [(f"input {kind}", lambda case, kind=kind: case["input_kind"] == kind)
               for kind in ("none", "measured", "unknown")]
    groups += [(f"sensor {kind}", lambda case, kind=kind: case["sensor"] == kind) for kind in ("linear", "sin")]
    print("\n  median per-case ratio to the UKF smoother (state SSE); DEM path <= UKF: share of cases")
    for label, chosen in groups:
        part = [result for case, result in rows if chosen(case)]
        if not part:
            continue
        medians = {method: np.nanmedian([ratio(result, method) for result in part]) for method in
                   ("DEM", "DEM path", "coloured UKS")}
        path = np.array([ratio(result, "DEM path") for result in part])
        share = np.mean(path[np.isfinite(path)] <= 1.0) if np.isfinite(path).any() else np.nan
        print(f"  {label:16s} {len(part):3d} cases: D-step {medians['DEM']:6.3f}  path {medians['DEM path']:6.3f} "
              f"(<= UKF in {share:4.0%}, 90th pct {np.nanpercentile(path, 90):7.3f})  coloured UKS "
              f"{medians['coloured UKS']:6.3f}")
    pushed = [result for case, result in rows if result["input_sse"].get("UKF", np.inf) < np.inf]
    if pushed:
        medians = {method: np.nanmedian([result["input_sse"].get(method, np.nan) / result["input_sse"]["UKF"]
                                         for result in pushed]) for method in ("DEM", "DEM path", "coloured UKS")}
        print(f"  input SSE / UKF's, {len(pushed)} cases with an unknown input (median): "
              + "  ".join(f"{method} {value:.3f}" for method, value in medians.items()))
    coverage = [result["coverage"] for _, result in rows if "coverage" in result]
    warned = [result.get("warned", False) for _, result in rows if "coverage" in result]
    calm = [ratio(result, "DEM path") for _, result in rows if "coverage" in result and not result["warned"]]
    print(f"\n  DEM path |error| < 2 std: pooled {np.mean(coverage):.3f} (calibrated: ~0.95), per case "
          f"{np.min(coverage):.3f}-{np.max(coverage):.3f}; misfit warnings in {sum(warned)} of {len(warned)} cases "
          f"(unwarned cases: path / UKF median {np.nanmedian(calm):.3f}, worst {np.nanmax(calm):.3g})")
    several = [result.get("maxima", False) for _, result in rows if "coverage" in result]
    if any(several):
        split = {flag: [c for c, warned_here in zip(coverage, several) if warned_here == flag] for flag in (True, False)}
        print(f"  path mode warned of several maxima of F in {sum(several)} cases: |error| < 2 std pooled "
              f"{np.mean(split[True]):.3f} there ({np.min(split[True]):.3f}-{np.max(split[True]):.3f}), "
              f"{np.mean(split[False]):.3f} in the other {len(split[False])} cases")
    unconverged = [case["index"] for case, result in rows if result.get("unconverged")]
    print(f"  path mode stopped unconverged (max_iterations) in {len(unconverged)} cases {unconverged[:10]}")
    for method in METHODS:
        failed = [case["index"] for case, result in rows if method in result["failed"]]
        speed = [SAMPLES / result["seconds"][method] for _, result in rows if method in result["seconds"]]
        print(f"  {method:12s} failed in {len(failed)} cases {failed[:10]}; median {np.median(speed):6.0f} samples/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=36)
    parser.add_argument("--first", type=int, default=0, help="index of the first case")
    parser.add_argument("--fine", type=int, default=1, help="simulate this many times finer than dt (1: inputs and "
                        "noise held over each sample)")
    parser.add_argument("--motion", choices=("linearized", "path"), default=None,
                        help="path mode's generalised motion (default: NonlinearDEM's)")
    args = parser.parse_args()
    FINE[0], MOTION[0] = args.fine, args.motion
    print(f"== nonlinear DEM on {args.cases} random nonlinear systems ({SAMPLES} samples at dt = {DT} s each, "
          f"simulated {FINE[0]}x finer; ratios to the white-noise UKF smoother)")
    rows = []
    for index in range(args.first, args.first + args.cases):
        case = draw_case(index)
        result = run_case(case)
        rows.append((case, result))
        ukf = result["sse"].get("UKF", np.nan)
        text = "  ".join(f"{method} {result['sse'][method] / ukf:7.3f}" for method in ("DEM", "DEM path", "coloured UKS")
                         if method in result["sse"])
        notes = "".join(f"  [{method} failed: {why}]" for method, why in result["failed"].items())
        flag = " WARNED" if result.get("warned") else ""
        print(f"  {describe(case)}: UKF SSE {ukf:9.3g}; / UKF: {text}; path 2-std {result.get('coverage', np.nan):.2f}"
              f"{flag}{notes}", flush=True)
        if result["input_sse"]:
            pushes = result["input_sse"]
            print("      input SSE: " + "  ".join(f"{method} {value:.4g}" for method, value in pushes.items()), flush=True)
    summarise(rows)


if __name__ == "__main__":
    main()
