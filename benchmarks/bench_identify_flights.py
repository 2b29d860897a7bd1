"""Identification on the 10 real quadrotor flights (roll axis), both state models, whole flights.

    python benchmarks/bench_identify_flights.py [--start 0] [--samples 0] [--states sample path]
                                                [--known-prior-precision inf]

Per flight and state model: iterations, converged, F, the learned free entries with posterior std
(README's [learning] example: free A[2,1], A[2,2], B[2,1], the other entries held at their prior
(known_prior_precision = inf), P_theta = 1 on the free ones, lambda prior N(0, 1), 50 iterations,
tolerance 1e-3), the eigenvalues of the learned A, and the one-step prediction error of the learned
model on the OTHER flights against the prior model's: mean over the other flights of the mean
squared residual of the measured roll rate, x[k+1] - Ad x[k] - Bd u[k] (zero-order hold, measured
[phi, phi_dot]), with inputs AND states taken relative to each flight's operating point (its mean;
the model is a linearisation there, and a learned A[2,1] != 0 would otherwise turn each flight's
trim angle into a bias). "raw" repeats it with absolute states (the earlier comparison). The ratio
learned / prior should be <= 1. Default: whole flights (--samples 0). exp_26_WW_WM_0 is known to be
corrupted (data README); it is kept in the table but left out of the prediction summary.
Needs ../shared/data/quadrotor-wind beside the repository (or ATTEND_QUADROTOR_DATA).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from attend.perception.learning import LearningSettings, identify
from attend.models import parameter_vector
from attend.models.linear import LinearSystem

DATA = Path(os.environ.get("ATTEND_QUADROTOR_DATA", Path(__file__).resolve().parents[2] / "shared" / "data" / "quadrotor-wind"))
FREE = ["A[2,1]", "A[2,2]", "B[2,1]", "B[2,2]", "B[2,3]", "B[2,4]"]
LEARNING = dict(free=FREE, free_prior_precision=1.0, known_prior_precision=np.inf)  # the parameter prior
#: the README's [learning] settings with the flights' [observer] embedding (p = 6, d = 2, Meera's S)
SETTINGS = LearningSettings(embedding_order=6, input_order=2, precision_convention="max", noise_prior_mean=(0.0, 0.0),
                            noise_prior_precision=1.0, max_iterations=50, tolerance=1e-3)
PRIOR = LinearSystem(A=np.array([[0.0, 1.0], [0.0, 0.0]]),
                     B=np.array([[0.0, 0.0, 0.0, 0.0], [0.374838, -0.374838, -0.374838, 0.374838]]),
                     C=np.array([[1.0, 0.0]]))
DT = 1.0 / 120.0


def load(path: Path, start: int, samples: int | None):
    table = np.genfromtxt(path, delimiter=",", names=True)
    sl = slice(start, None if samples is None else start + samples)
    motors = np.column_stack([table[f"motor_{i}"] for i in range(1, 5)])[sl]
    inputs = motors - motors.mean(axis=0)  # relative to the flight's operating point
    states = np.column_stack([table["state_phi"], table["state_phi_dot"]])[sl]
    return table["meas_phi"][sl][:, None], inputs, states


CORRUPTED = {"exp_26_WW_WM_0"}
HORIZON = 12  # samples (0.1 s) ahead for the second prediction metric


def one_step_error(system: LinearSystem, states, inputs, relative: bool = True) -> float:
    """Mean squared one-step residual of the roll rate; states relative to the flight's mean if relative."""
    if relative:
        states = states - states.mean(axis=0)
    Ad, Bd = system.discretize(DT)
    residual = states[1:] - states[:-1] @ Ad.T - inputs[:-1] @ Bd.T
    return float(np.mean(residual[:, 1] ** 2))


def prediction_ratio(system: LinearSystem, logs, skip, relative: bool = True) -> tuple[float, float, float]:
    """(learned error, prior error, ratio) averaged over the flights other than skip (corrupted left out)."""
    others = [o for o in logs if o != skip and o not in CORRUPTED]
    if not all(np.all(np.isfinite(M)) for M in (system.A, system.B)):
        return np.inf, np.nan, np.inf
    learned = np.mean([one_step_error(system, logs[o][2], logs[o][1], relative) for o in others])
    prior = np.mean([one_step_error(PRIOR, logs[o][2], logs[o][1], relative) for o in others])
    return learned, prior, learned / prior


def horizon_error(system: LinearSystem, states, inputs, steps: int) -> np.ndarray:
    """Mean squared error [phi, phi_dot] of the prediction ``steps`` samples ahead from the measured state
    (operating-point relative) and the measured inputs in between (zero-order hold)."""
    states = states - states.mean(axis=0)
    Ad, Bd = system.discretize(DT)
    count = len(states) - steps
    predicted = states[:count].copy()
    for j in range(steps):
        predicted = predicted @ Ad.T + inputs[j:j + count] @ Bd.T
    return np.mean((states[steps:] - predicted) ** 2, axis=0)


def horizon_ratio(system: LinearSystem, logs, skip, steps: int = HORIZON) -> np.ndarray:
    """Learned / prior ``steps``-ahead error [phi, phi_dot], averaged over the other flights (corrupted left out)."""
    if not all(np.all(np.isfinite(M)) for M in (system.A, system.B)):
        return np.full(2, np.inf)
    others = [o for o in logs if o != skip and o not in CORRUPTED]
    learned = np.mean([horizon_error(system, logs[o][2], logs[o][1], steps) for o in others], axis=0)
    prior = np.mean([horizon_error(PRIOR, logs[o][2], logs[o][1], steps) for o in others], axis=0)
    return learned / prior


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--start", type=int, default=0, help="first sample (0-based) of every flight")
    parser.add_argument("--samples", type=int, default=0, help="samples per flight from --start (0: to the end)")
    parser.add_argument("--states", nargs="+", default=["sample", "path"])
    parser.add_argument("--known-prior-precision", type=float, default=np.inf,
                        help="P_theta of the entries that are not learned (inf: held fixed; 3.3e6: the paper's exp(15))")
    parser.add_argument("--flights", nargs="*", help="only these flights (stems), default all")
    args = parser.parse_args(argv)
    flights = sorted(DATA.glob("exp_*.csv"))
    if args.flights:
        flights = [f for f in flights if f.stem in args.flights]
    if not flights:
        print(f"no flights in {DATA}")
        return 1
    samples = args.samples or None
    logs = {f.stem: load(f, args.start, samples) for f in flights}
    names = list(logs)
    learning = dict(LEARNING, known_prior_precision=args.known_prior_precision)
    summary = {}
    print(f"{len(names)} flights, {samples or 'all'} samples each from sample {args.start}, roll model, README "
          f"[learning] (known_prior_precision = {args.known_prior_precision:g})")
    print("per flight: iterations, converged, F, lambda, eig(A), one-step roll-rate error learned/prior on the other "
          "flights (operating-point relative; 'raw': absolute states), 0.1 s-ahead error ratio [phi, phi_dot]; "
          "then the learned free entries +- posterior std")
    header = (f"{'flight':16s} {'states':6s} {'T':>5s} {'iter':>4s} {'conv':>4s} {'F':>12s} {'lam_z':>6s} {'lam_w':>6s} "
              f"{'eig(A)':>22s} {'1-step':>7s} {'raw':>6s} {'phi@.1s':>8s} {'dphi@.1s':>8s} {'s':>5s}")
    print(header)
    for states in args.states:
        converged, ratios, raws, horizons, unstable = 0, [], [], [], 0
        for name in names:
            y, u, _ = logs[name]
            started = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = identify(PRIOR, y, u, DT, kernel_width=0.006, settings=replace(SETTINGS, states=states),
                                  **learning)
            elapsed = time.perf_counter() - started
            learned = result.system()
            ratio = prediction_ratio(learned, logs, name)[2]
            raw = prediction_ratio(learned, logs, name, relative=False)[2]
            horizon = horizon_ratio(learned, logs, name)
            if name not in CORRUPTED:
                ratios.append(ratio)
                raws.append(raw)
                horizons.append(horizon)
            converged += bool(result.converged)
            eig = np.linalg.eigvals(learned.A) if np.all(np.isfinite(learned.A)) else np.full(2, np.nan)
            unstable += bool(np.max(eig.real) > 0)
            eig_txt = ",".join(f"{e.real:.3g}" + (f"{e.imag:+.3g}j" if e.imag > 0 else "") for e in eig
                               if e.imag >= 0)
            print(f"{name:16s} {states:6s} {len(y):5d} {result.iterations:4d} {'yes' if result.converged else 'no':>4s} "
                  f"{result.free_energy[-1]:12.6g} {result.log_precision[0]:6.2f} {result.log_precision[1]:6.2f} "
                  f"{eig_txt:>22s} {ratio:7.3f} {raw:6.3f} {horizon[0]:8.3f} {horizon[1]:8.3f} {elapsed:5.1f}"
                  + ("  (corrupted flight: not in the summary)" if name in CORRUPTED else ""), flush=True)
            idx = [result.parameter_names.index(n) for n in FREE]
            std = result.parameter_std
            print("    " + "  ".join(f"{n} {result.parameters[i]:.4g} +- {std[i]:.2g}" for n, i in zip(FREE, idx)))
            if not result.converged:
                print(f"    {result.message}")
        summary[states] = (converged, np.array(ratios), np.array(raws), np.array(horizons), unstable)
    print()
    for states, (count, ratios, raws, horizons, unstable) in summary.items():
        print(f"{states:6s}: {count}/{len(names)} flights converge; {unstable}/{len(names)} learned A unstable")
        for label, values in (("one-step roll rate", ratios), ("one-step roll rate, raw states", raws),
                              (f"{HORIZON * DT:.1f} s ahead phi", horizons[:, 0]),
                              (f"{HORIZON * DT:.1f} s ahead phi_dot", horizons[:, 1])):
            print(f"    error learned/prior on the other flights, {label:31s}: median {np.median(values):.3f}, worst "
                  f"{np.max(values):.3f} ({int(np.sum(values <= 1))}/{len(values)} not worse)")
    print(f"target: {len(names)}/{len(names)} flights converge, both state models; ratio <= 1")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
