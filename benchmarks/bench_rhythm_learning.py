"""Rhythmic vs fixed prior precision in system identification (attend.experiments.rhythm_learning).

    python benchmarks/bench_rhythm_learning.py [--full] [--tune]

Prints the worst-case (over sensor-noise levels) regret of the rhythmic P_theta schedule beside
that of every fixed P_theta (target: lower than all), per noise level the best fixed P_theta,
and the wall time. ``--tune`` first repeats the choice of the schedule's parameters on the
tuning runs (other seeds, noise levels between the evaluation levels) and prints it; the
evaluation always uses the parameters in rhythm_learning.SETTINGS.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from attend.experiments import rhythm_learning as RL  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--full", action="store_true", help="20 seeds x 11 noise levels x 25 fixed values")
    parser.add_argument("--tune", action="store_true", help="repeat the choice of the schedule on tuning runs")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    s = RL.SETTINGS
    if args.tune:
        t0 = time.perf_counter()
        tuned = RL.tune(progress=True)
        print(f"tuning ({time.perf_counter() - t0:.0f} s) on seeds {tuned['seeds'][0]}..{tuned['seeds'][-1]}, "
              f"sensor log-precisions {np.round(tuned['levels'], 2).tolist()}")
        print(f"  best candidate {tuned['best']}: worst-case relative regret {tuned['worst_case_relative_regret']:.3f} "
              f"(best fixed on the tuning runs {tuned['fixed_worst_case_relative_regret']:.3f})")
        print("  (SETTINGS uses pi_0 = {rhythm_baseline_precision}, a = {rhythm_depth}, "
              "f = {rhythm_cycles_per_iteration}, phi = {rhythm_phase})".format(**s))
    t0 = time.perf_counter()
    res = RL.run(quick=not args.full, progress=True)
    wall = time.perf_counter() - t0
    d = res.data
    fixed, rel, ab = d["fixed_prior_precision"], d["relative_regret"], d["absolute_regret"]
    levels, median = d["sensor_log_precision"], d["median_sse"]
    n_fixed = len(fixed)
    print(f"rhythm-learning ({'full' if args.full else 'quick'}; {res.settings['seeds']} seeds x {len(levels)} "
          f"sensor log-precisions {levels[0]:g}..{levels[-1]:g} x ({n_fixed} fixed + rhythmic), "
          f"{s['iterations']} iterations): {wall:.1f} s")
    print(f"  rhythm: pi_0 = {s['rhythm_baseline_precision']:g}, a = {s['rhythm_depth']:g}, "
          f"f = {s['rhythm_cycles_per_iteration']:g} cycles/iteration, phi = {s['rhythm_phase']:g} rad")
    print(f"  {'policy':<22} {'worst rel. regret':>18} {'worst abs. regret':>18}")
    worst_rel, worst_abs = rel.max(axis=1), ab.max(axis=1)
    for i in range(n_fixed):
        mark = "  <- rhythm lower" if worst_rel[-1] < worst_rel[i] else "  <- fixed lower or equal"
        print(f"  {'fixed P = %.1e' % fixed[i]:<22} {worst_rel[i]:>18.3f} {worst_abs[i]:>18.4g}{mark}")
    print(f"  {'rhythmic':<22} {worst_rel[-1]:>18.3f} {worst_abs[-1]:>18.4g}")
    beaten = int(np.sum(worst_rel[-1] < worst_rel[:n_fixed]))
    beaten_abs = int(np.sum(worst_abs[-1] < worst_abs[:n_fixed]))
    print(f"  rhythmic worst-case relative regret lower than {beaten}/{n_fixed} fixed values "
          f"(absolute: {beaten_abs}/{n_fixed})   target: {n_fixed}/{n_fixed}")
    print("  per noise level: best fixed P, its median SSE, rhythmic median SSE, rhythmic relative regret")
    for j, lv in enumerate(levels):
        b = int(np.argmin(median[:n_fixed, j]))
        print(f"    lambda_z = {lv:5.2f}: best fixed {fixed[b]:8.1e}  SSE {median[b, j]:.3e}  "
              f"rhythmic {median[-1, j]:.3e}  regret {rel[-1, j]:.3f}")


if __name__ == "__main__":
    main()
