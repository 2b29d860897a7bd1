"""Identification on the 10 real quadrotor flights (roll axis), both state models.

    python benchmarks/bench_identify_flights.py [--samples 1200] [--states sample path]

Per flight and state model: iterations, converged, F, the learned free entries with posterior std
(README's [learning] example: free A[2,1], A[2,2], B[2,1], P_theta = 1 / 3.3e6, lambda prior N(0, 1),
50 iterations, tolerance 1e-3), and the one-step prediction error of the learned model on the OTHER
flights against the prior model: mean over the other flights of the mean squared residual of the
measured roll rate, x[k+1] - Ad x[k] - Bd u[k] (zero-order hold, measured [phi, phi_dot]). Learning
must not make it worse (ratio learned / prior <= 1). Needs /work/shared/data/quadrotor-wind
(or ATTEND_QUADROTOR_DATA).
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
LEARNING = dict(free=FREE, free_prior_precision=1.0, known_prior_precision=3.3e6, noise_prior_mean=(0.0, 0.0),
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


def one_step_error(system: LinearSystem, states, inputs) -> float:
    Ad, Bd = system.discretize(DT)
    residual = states[1:] - states[:-1] @ Ad.T - inputs[:-1] @ Bd.T
    return float(np.mean(residual[:, 1] ** 2))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=1200, help="samples per flight from sample 400 (0: all)")
    parser.add_argument("--states", nargs="+", default=["sample", "path"])
    args = parser.parse_args(argv)
    flights = sorted(DATA.glob("exp_*.csv"))
    if not flights:
        print(f"no flights in {DATA}")
        return 1
    samples = args.samples or None
    logs = {f.stem: load(f, 399, samples) for f in flights}
    names = list(logs)
    summary = {}
    print(f"{len(names)} flights, {samples or 'all'} samples each from sample 400, roll model, README [learning]")
    header = (f"{'flight':16s} {'states':6s} {'iter':>4s} {'conv':>4s} {'F':>12s}  "
              + "  ".join(f"{n:>18s}" for n in FREE) + f"  {'lam_z':>6s} {'lam_w':>6s} {'err learned/prior':>17s} {'s':>5s}")
    print(header)
    for states in args.states:
        converged, ratios = 0, []
        for name in names:
            y, u, _ = logs[name]
            started = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = identify(PRIOR, y, u, DT, kernel_width=0.006, embedding_order=6, input_order=2,
                                  precision_convention="max", states=states, **LEARNING)
            elapsed = time.perf_counter() - started
            learned = result.system()
            finite = all(np.all(np.isfinite(M)) for M in (learned.A, learned.B))
            err_learned = np.mean([one_step_error(learned, logs[o][2], logs[o][1]) for o in names if o != name]) \
                if finite else np.inf
            err_prior = np.mean([one_step_error(PRIOR, logs[o][2], logs[o][1]) for o in names if o != name])
            ratio = err_learned / err_prior
            ratios.append(ratio)
            converged += bool(result.converged)
            idx = [result.parameter_names.index(n) for n in FREE]
            std = result.parameter_std
            cells = "  ".join(f"{result.parameters[i]:9.4g}+-{std[i]:<7.2g}" for i in idx)
            print(f"{name:16s} {states:6s} {result.iterations:4d} {'yes' if result.converged else 'no':>4s} "
                  f"{result.free_energy[-1]:12.6g}  {cells}  {result.log_precision[0]:6.2f} {result.log_precision[1]:6.2f} "
                  f"{err_learned:8.4g}/{err_prior:<8.4g} {elapsed:5.1f}", flush=True)
            if not result.converged:
                print(f"    {result.message}")
        summary[states] = (converged, np.array(ratios))
    print()
    for states, (count, ratios) in summary.items():
        print(f"{states:6s}: {count}/{len(names)} flights converge; one-step error learned/prior on the other flights: "
              f"median {np.median(ratios):.3f}, worst {np.max(ratios):.3f} ({int(np.sum(ratios <= 1))}/{len(ratios)} not worse)")
    print(f"target: {len(names)}/{len(names)} flights converge, both state models; ratio <= 1")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
