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
Needs /work/shared/data/quadrotor-wind (or ATTEND_QUADROTOR_DATA).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

from attend.perception.learning import identify, parameter_vector
from attend.systems import LinearSystem

DATA = Path(os.environ.get("ATTEND_QUADROTOR_DATA", "/work/shared/data/quadrotor-wind"))
FREE = ["A[2,1]", "A[2,2]", "B[2,1]"]
LEARNING = dict(free=FREE, free_prior_precision=1.0, known_prior_precision=np.inf, noise_prior_mean=(0.0, 0.0),
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
    header = (f"{'flight':16s} {'states':6s} {'T':>5s} {'iter':>4s} {'conv':>4s} {'F':>12s}  "
              + "  ".join(f"{n:>17s}" for n in FREE) + f"  {'lam_z':>6s} {'lam_w':>6s} {'eig(A)':>17s} "
              f"{'pred learned/prior':>18s} {'ratio':>6s} {'raw':>6s} {'s':>5s}")
    print(header)
    for states in args.states:
        converged, ratios, raws, unstable = 0, [], [], 0
        for name in names:
            y, u, _ = logs[name]
            started = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = identify(PRIOR, y, u, DT, kernel_width=0.006, embedding_order=6, input_order=2,
                                  precision_convention="max", states=states, **learning)
            elapsed = time.perf_counter() - started
            learned = result.system()
            err_learned, err_prior, ratio = prediction_ratio(learned, logs, name)
            raw = prediction_ratio(learned, logs, name, relative=False)[2]
            if name not in CORRUPTED:
                ratios.append(ratio)
                raws.append(raw)
            converged += bool(result.converged)
            eig = np.linalg.eigvals(learned.A) if np.all(np.isfinite(learned.A)) else np.full(2, np.nan)
            unstable += bool(np.max(eig.real) > 0)
            idx = [result.parameter_names.index(n) for n in FREE]
            std = result.parameter_std
            cells = "  ".join(f"{result.parameters[i]:8.4g}+-{std[i]:<7.2g}" for i in idx)
            eig_txt = ",".join(f"{e.real:.3g}" + (f"{e.imag:+.2g}j" if abs(e.imag) > 0 else "") for e in eig)
            print(f"{name:16s} {states:6s} {len(y):5d} {result.iterations:4d} {'yes' if result.converged else 'no':>4s} "
                  f"{result.free_energy[-1]:12.6g}  {cells}  {result.log_precision[0]:6.2f} {result.log_precision[1]:6.2f} "
                  f"{eig_txt:>17s} {err_learned:8.4g}/{err_prior:<9.4g} {ratio:6.3f} {raw:6.3f} {elapsed:5.1f}"
                  + ("  (corrupted flight)" if name in CORRUPTED else ""), flush=True)
            if not result.converged:
                print(f"    {result.message}")
        summary[states] = (converged, np.array(ratios), np.array(raws), unstable)
    print()
    for states, (count, ratios, raws, unstable) in summary.items():
        print(f"{states:6s}: {count}/{len(names)} flights converge; {unstable}/{len(names)} learned A unstable; one-step "
              f"roll-rate error learned/prior on the other flights (operating-point relative): median "
              f"{np.median(ratios):.4f}, worst {np.max(ratios):.4f} ({int(np.sum(ratios <= 1))}/{len(ratios)} not worse); "
              f"raw states: median {np.median(raws):.4f}, worst {np.max(raws):.4f} ({int(np.sum(raws <= 1))}/{len(raws)})")
    print(f"target: {len(names)}/{len(names)} flights converge, both state models; ratio <= 1")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
