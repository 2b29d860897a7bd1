"""When to replan in UAV search: rhythmic / precision-driven vs fixed budgets (attend.experiments.rhythm_ipp).

    python benchmarks/bench_rhythm_ipp.py [--full] [--trials N]

At equal flight time (150 s) prints, per policy, the final RSE (mean +- sem over trials), the
time-averaged RSE, trace(P), people found, replans per mission and compute per mission (planner
wall time + the schedule's own decision time); then the rhythmic policy's paired final-RSE
difference to the best fixed budget (target: <= 0, i.e. no worse) and its replans and compute
relative to that budget. Quick: 8 trials, per-cell covariance, 6 CMA-ES evaluations; --full:
25 trials, full covariance, 24 evaluations (about 20 min on 2 cores).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from attend.experiments import rhythm_ipp as R  # noqa: E402


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--full", action="store_true", help="25 trials, full covariance, 24 CMA-ES evaluations")
    parser.add_argument("--trials", type=int, default=None, help="override the number of trials")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    res = R.run(quick=not args.full, progress=True, trials=args.trials)
    wall = time.perf_counter() - t0
    s, summary = res.settings, res.data["summary"]
    n = s["trials"]
    print(f"rhythm-ipp ({'full' if args.full else 'quick'}: {n} trials, {s['budget_s']:g} s flight, "
          f"{'per-cell' if s['diagonal'] else 'full'} covariance, {s['cma_evaluations']} CMA-ES evaluations, "
          f"{s['planner']} planner, {s['lookahead_waypoints']} waypoints): {wall:.1f} s")
    print(f"  {'policy':<20} {'final RSE':>15} {'RSE avg':>8} {'trace(P)':>9} {'found':>6} {'replans':>8} "
          f"{'compute s':>10} {'(decide s)':>10}")
    sem = (lambda x: x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else 0.0)
    for name, v in summary.items():
        print(f"  {name:<20} {v['rse'].mean():8.3f} +-{sem(v['rse']):5.3f} {v['rse_time_average'].mean():8.3f} "
              f"{v['trace'].mean():9.1f} {v['found'].mean():6.2f} {v['replans'].mean():8.1f} "
              f"{v['compute_s'].mean():10.2f} {v['decision_s'].mean():10.3f}")
    best = res.data["best_fixed"]
    for name in ("precision", "oscillator", "precision_no_prior"):
        if name not in res.data["comparison"]:
            continue
        diff = res.data["comparison"][name]["rse_difference"]
        verdict = "no worse (holds)" if diff.mean() <= 0 else "WORSE (does not hold)"
        print(f"  {name} vs best fixed budget ({best}): final RSE difference {diff.mean():+.3f} +- {sem(diff):.3f} "
              f"(paired, {int(np.sum(diff <= 0))}/{len(diff)} trials no worse) -> {verdict}; "
              f"replans {summary[name]['replans'].mean():.1f} vs {summary[best]['replans'].mean():.1f}, "
              f"compute {summary[name]['compute_s'].mean():.2f} s vs {summary[best]['compute_s'].mean():.2f} s")


if __name__ == "__main__":
    main()
