"""Calibrates attend.perception.spread_check.SPREAD_LIMIT: how large the ratio of an estimate's RMS to
its reference (measured proxy or prior spread) gets on correct models, and what it is on
mis-specified ones.

Correct models: (1) the random bank of bench_bank.py (dense C: the prior spread is the reference),
estimated by the coloured-noise Kalman smoother with the true model and, where it runs, DEM
(embedding_order "auto"); (2) random mechanical systems [q; dq/dt] with positions measured (the
measured proxy y / c and its derivative are the references), same estimators. False alarms: cases
with any ratio above the limit.

Mis-specified: (a) outputs logged in degrees, model in radians (C 57x too small for the log) on
bank systems; (b) a position sensor whose noise std the model says is 100x smaller than it is, with an
unknown force of a far too wide prior (std 1e3 against a true 0.3): the velocity, weakly pinned by
the data, follows the noise's derivative.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_spread_check.py [--cases 60]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_bank import draw_case  # noqa: E402

from attend import LinearSystem  # noqa: E402
from attend._validation import AttendInputError  # noqa: E402
from attend.perception.dem import DEMObserver  # noqa: E402
from attend.perception.kalman import KalmanEstimator  # noqa: E402
from attend.perception.spread_check import SPREAD_LIMIT, spread_findings  # noqa: E402
from attend.models.linear import ModelWarning, simulate  # noqa: E402


def mechanical_case(index: int):
    """[q; dq/dt] with M q'' = -K q - D q' + F u: positions measured, forces known or unknown."""
    rng = np.random.default_rng([29, index])
    k = int(rng.integers(1, 4))
    n, r = 2 * k, int(rng.integers(1, k + 1))
    Q = np.linalg.qr(rng.standard_normal((k, k)))[0]
    K = Q @ np.diag(10 ** rng.uniform(-1, 1, k)) @ Q.T
    D = Q @ np.diag(10 ** rng.uniform(-1.5, 0, k)) @ Q.T
    A = np.block([[np.zeros((k, k)), np.eye(k)], [-K, -D]])
    B = np.vstack([np.zeros((k, r)), rng.standard_normal((k, r))])
    C = np.hstack([np.eye(k), np.zeros((k, k))])
    dt = float(rng.choice([0.01, 0.02, 0.05]))
    N = int(rng.integers(300, 1200))
    width = float(rng.choice([0.0, 1.0, 2.0, 4.0])) * dt
    unknown = bool(index % 2)
    t = np.arange(N) * dt
    u = np.sin(2 * np.pi * rng.uniform(0.05, 1.0, r) * t[:, None] + rng.uniform(0, 6, r))
    system = LinearSystem(A, B, C)
    process_std = np.concatenate([np.full(k, 1e-3), np.full(k, 10 ** rng.uniform(-2, 0))])
    clean = simulate(system, u, dt, kernel_width=0.0, seed=0)
    sensor_std = max(np.sqrt(np.mean(clean.outputs**2)), 1e-3) * 10 ** rng.uniform(-3, -1)
    log = simulate(system, u, dt, kernel_width=width, process_std=process_std, measurement_std=sensor_std,
                   seed=index)
    return dict(system=system, dt=dt, width=width, outputs=log.outputs, inputs=u, unknown=unknown, states=log.states,
                process_precision=process_std**-2, sensor_precision=sensor_std**-2,
                input_precision=np.ones(r), input_width=max(width, 5 * dt))


def ratios(system, dt, outputs, states, inputs, *, process_precision, width, unknown, drive, input_precision,
           input_width):
    r = system.n_inputs
    return spread_findings(system, dt, outputs, states, inputs, process_precision=process_precision,
                           process_kernel_width=width, sensor_kernel_width=width,
                           unknown=np.full(r, unknown), drive=drive, input_prior_precision=input_precision,
                           input_kernel_width=input_width, ratios=True)


def run_estimators(case, dem: bool = True):
    """{name: (states, inputs)} of the Kalman smoother and DEM (auto) on one case."""
    system, dt, width = case["system"], case["dt"], case["width"]
    r = system.n_inputs
    unknown = case["unknown"]
    signal = case["drive"] if unknown else case["inputs"]
    out = {}
    kalman = KalmanEstimator(system, dt, sensor_precision=case["sensor_precision"],
                             process_precision=case["process_precision"], kernel_width=width, known_inputs=not unknown,
                             input_prior_precision=case["input_precision"] if unknown else None,
                             input_kernel_width=case["input_width"] if unknown else None)
    estimate = kalman.estimate(case["outputs"], signal)
    out["kalman"] = (estimate.states, estimate.inputs if unknown else case["inputs"])
    if dem and width > 0:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)
                observer = DEMObserver(system, dt, kernel_width=width, sensor_precision=case["sensor_precision"],
                                       process_precision=case["process_precision"],
                                       input_prior_precision=case["input_precision"] if unknown else None,
                                       known_inputs=not unknown,
                                       input_kernel_width=case["input_width"] if unknown else None)
                estimate = observer.estimate(case["outputs"], signal)
            out["dem"] = (estimate.states, estimate.inputs)
        except AttendInputError:
            pass
    _ = r
    return out


def bank_case(index: int):
    case = draw_case(index)
    unknown = not case.known
    r = case.system.n_inputs
    return dict(system=case.system, dt=case.dt, width=case.process_width, outputs=case.outputs, states=case.states,
                inputs=case.inputs, unknown=unknown, process_precision=case.process_std**-2,
                sensor_precision=case.sensor_std**-2,
                input_precision=case.input_prior_std**-2 if unknown else np.ones(r),
                input_width=case.input_width if unknown else case.process_width,
                drive=case.input_prior_mean if unknown else case.inputs, sensor_width=case.sensor_width)


def case_ratios(case, estimates):
    drive = case.get("drive")
    if drive is None:
        drive = np.zeros_like(case["inputs"]) if case["unknown"] else case["inputs"]
    found = {}
    for name, (states, inputs) in estimates.items():
        found[name] = ratios(case["system"], case["dt"], case["outputs"], states, inputs,
                             process_precision=case["process_precision"], width=case["width"],
                             unknown=case["unknown"], drive=drive, input_precision=case["input_precision"],
                             input_width=case["input_width"])
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=60)
    args = parser.parse_args(argv)
    worst, alarms, count, true_alarms, missed = [], 0, 0, 0, 0
    for family, make in (("bank", bank_case), ("mechanical", mechanical_case)):
        values = []
        for index in range(args.cases):
            case = make(index)
            if "drive" not in case:
                case["drive"] = np.zeros_like(case["inputs"]) if case["unknown"] else case["inputs"]
            try:
                estimates = run_estimators(case)
            except AttendInputError as error:  # the smoother refuses the case (not the check's business)
                print(f"  {family} #{index}: refused: {error}")
                continue
            truth = np.sqrt(np.mean(case["states"] ** 2, axis=0))
            for name, found in case_ratios(case, estimates).items():
                # wild: some state's estimate swings over 3x as much as the truth does
                wild = np.any(np.sqrt(np.mean(estimates[name][0] ** 2, axis=0)) > 3 * truth)
                top = float(np.nanmax(found, initial=0.0))
                fires = top > SPREAD_LIMIT
                values.append(top)
                alarms += fires and not wild
                true_alarms += fires and wild
                missed += wild and not fires
                count += 1
                worst.append((top, family, index, name, wild))
        values = np.array(values)
        print(f"{family:10s}: {len(values)} estimates, largest ratio per estimate: median {np.median(values):.2f}, "
              f"95 % {np.quantile(values, 0.95):.2f}, max {values.max():.2f}")
    worst.sort(reverse=True)
    calm = [v for v, *_, wild in worst if not wild]
    print(f"correct models, {count} estimates (Kalman smoother and DEM): SPREAD_LIMIT = {SPREAD_LIMIT:g}; "
          f"false alarms (fires, estimate not wild: RMS <= 3x the truth's) {alarms}, largest ratio of those "
          f"{max(calm, default=0):.2f}; true alarms (wild estimates flagged) {true_alarms}; wild, not flagged {missed}")
    print("  largest: " + ", ".join(f"{f} #{i} {n} {v:.2f}{' (wild)' if w else ''}" for v, f, i, n, w in worst[:4]))
    # mis-specified (a): outputs in degrees, model in radians
    fired = []
    for index in range(min(args.cases, 20)):
        case = bank_case(index)
        case["outputs"] = case["outputs"] * 180 / np.pi
        try:
            estimates = run_estimators(case, dem=False)
        except AttendInputError as error:
            print(f"  (a) bank #{index}: refused: {error}")
            continue
        fired.append(float(np.nanmax(case_ratios(case, estimates)["kalman"], initial=0.0)))
    fired = np.array(fired)
    print(f"mis-specified (a), outputs in degrees: fires on {np.sum(fired > SPREAD_LIMIT)} of {len(fired)}; "
          f"largest ratio median {np.median(fired):.1f}, min {fired.min():.1f}")
    # mis-specified (b): sensor std 100x too small, unknown force with a far too wide prior
    fired = []
    for index in range(1, 2 * min(args.cases, 20), 2):
        case = mechanical_case(index)
        case["sensor_precision"] = case["sensor_precision"] * 1e4
        case["input_precision"] = np.full(case["system"].n_inputs, 1e-6)
        case["drive"] = np.zeros_like(case["inputs"])
        try:
            estimates = run_estimators(case, dem=False)
        except AttendInputError:  # the smoother refuses: its predicted outputs' covariance is singular
            continue
        fired.append(float(np.nanmax(case_ratios(case, estimates)["kalman"], initial=0.0)))
    fired = np.array(fired)
    print(f"mis-specified (b), sensor std 100x too small + input prior std 1e3: fires on "
          f"{np.sum(fired > SPREAD_LIMIT)} of {len(fired)}; largest ratio median {np.median(fired):.1f}, "
          f"min {fired.min():.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
