"""Benchmark of the action half (informative path planning): each figure beside its target.

    python benchmarks/bench_ipp.py                 # 25 trials per planner (paper size)
    python benchmarks/bench_ipp.py --trials 5      # shorter
    python benchmarks/bench_ipp.py --skip-trials   # only prior, timing and scaling
    python benchmarks/bench_ipp.py --find-all-only # only the find-all-7 diagnostics (cover_confirm, efe_confirm, truth oracle)

Targets: initial trace(P) ~ 387 and RSE 7.69; precision-gain and EFE planners below lawnmower at
10 m and random in final RSE and trace(P) over 25 trials; the best planner finds all 7 people
within 150 s in >= 90 % of trials (strict criterion: every cell of a person with map mean > 0.5);
false alarms reported; replanning median <= 0.5 s with full covariance (decisions on exact
full-covariance scores); scaling with grid size 20 x 20 ... 80 x 80 reported.

Planners: precision_gain, adaptive, efe (epistemic + a 0.2-nat preference for seeing people),
efe_confirm (the EFE planner in two phases: search at 14 m, then confirmation views at 8 m chosen
by the expected number of cells pushed across the found threshold), cover_confirm (two coverage
passes at 13 m, then the views that most advance the worst cell of each detection; the replan
time is that of a confirmation decision), lawnmower, random. Every planner decides from the
belief; only the metrics and the truth-oracle ceiling of ``--find-all-only`` read the ground
truth. Hyperparameters were tuned on seeds 100-124 (cover_confirm: 100-199), the trials use seeds
0-24.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from attend.action.belief import PAPER_PRIOR, OccupancyMap, prior_covariance
from attend.action.camera import Camera, Detector
from attend.action.field import Grid, make_field
from attend.action.planners import PlanningSetup, make_planner
from attend.experiments.ipp import INFORMATIVE, PLANNER_NAMES, run_trials, summarise


def line(name: str, value: str, target: str) -> None:
    print(f"  {name:<52} {value:<28} target: {target}")


def replan_times(cells_per_side: int, block: int, planner: str = "precision_gain", repeats: int = 5, seed: int = 0,
                 exact_candidates: int = 4):
    """Wall times (s) of ``repeats`` replans on a belief after a few images, of one fusion, and CPU
    times of the replans."""
    grid = Grid(cells_per_side=cells_per_side, cell_size_m=30.0 / cells_per_side)
    field = make_field(seed, grid=grid)
    setup = PlanningSetup(field, planning_block_cells=block, exact_candidates=exact_candidates)
    # cover_confirm: time a confirmation decision, not the pop of a precomputed coverage stop
    chosen = make_planner(planner, setup, seed, **({"cover_passes": 0} if planner == "cover_confirm" else {}))
    belief = OccupancyMap.prior(grid)
    camera, detector = Camera(), Detector()
    rng = np.random.default_rng(seed)
    from attend.action.camera import take_image

    fusion = []
    for pose in ([10.0, 0.0, 10.0], [0.0, 5.0, 14.0], [-8.0, -8.0, 8.0]):
        image = take_image(field, camera, detector, pose, 0.0, rng)
        tic = time.perf_counter()
        belief.fuse(image.cells, image.measurements, image.noise_variance)
        fusion.append(time.perf_counter() - tic)
    times, cpu = [], []
    for _ in range(repeats):
        tic, cpu_tic = time.perf_counter(), time.process_time()
        chosen.plan(belief, np.array([0.0, 0.0, 10.0]), 120.0, 2.0)
        times.append(time.perf_counter() - tic)
        cpu.append(time.process_time() - cpu_tic)
    return np.array(times), float(np.median(fusion)), np.array(cpu)


def coarse_vs_exact(seed: int = 0) -> tuple[float, float, bool]:
    """Spearman rank correlation, median ratio and same-argmax of coarse (2x2) vs exact single-image
    trace reductions over the candidate lattice, on a belief after three images."""
    from attend.action.episode import belief_after_images
    from attend.action.planners.scoring import ScreeningModel

    field = make_field(seed)
    setup = PlanningSetup(field)
    belief = belief_after_images(field, setup, ([10, 0, 10], [0, 5, 14], [-8, -8, 8]), seed=seed)
    lattice = setup.lattice()
    visible = setup.camera.visible_cells(lattice, field.grid)[:, None, :]
    noise = setup.detector.noise_variance(lattice[:, 2])[:, None]
    gains = []
    for block in (1, 2):
        model = ScreeningModel(belief, PlanningSetup(field, planning_block_cells=block), None)
        gains.append(model.gains(model.precision(visible, noise))[0])
    ranks = [np.argsort(np.argsort(g)) for g in gains]
    return float(np.corrcoef(*ranks)[0, 1]), float(np.median(gains[1] / gains[0])), bool(np.argmax(gains[0]) == np.argmax(gains[1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=25)
    parser.add_argument("--skip-trials", action="store_true")
    parser.add_argument("--max-grid", type=int, default=80)
    parser.add_argument("--workers", type=int, default=2, help="processes for the trials")
    parser.add_argument("--find-all-only", action="store_true", help="only the find-all-7 diagnostics (--trials seeds)")
    args = parser.parse_args()
    import os

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (timings are wall clock unless marked CPU)")
    if args.find_all_only:
        find_all_diagnostics(args.trials)
        return

    print("Prior (40 x 40 grid, Matern-3/2 over cell indices, l = 3.67, s2 = 1.82, r0 = 2.01)")
    trace0 = np.trace(prior_covariance(40))
    line("initial trace(P)", f"{trace0:.1f}", "~387")
    cells = [sum(len(c) for c in make_field(s).person_cells) for s in range(25)]
    rse0 = [np.sqrt(0.81 * n + 0.01 * (1600 - n)) for n in cells]
    line("initial RSE (25 seeded fields)", f"{np.mean(rse0):.2f} +- {np.std(rse0):.2f}", "7.69 (54 person cells)")
    line("person cells per field", f"{np.mean(cells):.1f} +- {np.std(cells):.1f}", "~54")

    print("\nReplanning time (greedy + CMA-ES 24 evaluations, 3 waypoints; set OPENBLAS_NUM_THREADS=1 for one core)")
    print("  default: screening on 2x2 blocks of full P, decisions on the exact full P (top 4 candidates per greedy")
    print("  step, greedy path + best 2 CMA-ES paths re-scored exactly)")
    for planner in INFORMATIVE:
        times, fusion, cpu = replan_times(40, 2, planner=planner)
        line(f"40x40 {planner} (default): median replan", f"{np.median(times):.3f} s wall, {np.median(cpu):.3f} s CPU",
             "<= 0.5 s")
    for block, exact, label in ((2, 0, "screening only, no exact re-scoring"), (1, 0, "every candidate exact (slow)")):
        times, fusion, cpu = replan_times(40, block, exact_candidates=exact, repeats=5 if block > 1 else 2)
        line(f"40x40 precision_gain, {label}", f"{np.median(times):.3f} s wall, {np.median(cpu):.3f} s CPU", "reference")
    line("40x40 full-covariance fusion of one image", f"{fusion * 1e3:.1f} ms", "-")
    rank, ratio, same = coarse_vs_exact()
    line("coarse vs exact gains over the lattice: rank corr.", f"{rank:.3f} (ratio {ratio:.2f}, same best: {same})", "close to 1")

    print("\nScaling with grid size (same 30 m field, default planner)")
    for side in (20, 40, 60, 80):
        if side > args.max_grid:
            continue
        tic = time.perf_counter()
        PAPER_PRIOR.build_covariance(side)
        prior_time = time.perf_counter() - tic
        times, fusion, cpu = replan_times(side, 2, repeats=3)
        line(f"{side}x{side}: prior / fusion / median replan (CPU)",
             f"{prior_time:.2f} s / {fusion * 1e3:.0f} ms / {np.median(times):.2f} s ({np.median(cpu):.2f} s)", "reported")

    if args.skip_trials:
        return
    print(f"\nTrials: {args.trials} seeded fields per planner, 150 s budget")
    tic = time.perf_counter()
    logs = run_trials(trials=args.trials, progress=True, workers=args.workers)
    final = {name: summarise(runs) for name, runs in logs.items()}
    print(f"  ({time.perf_counter() - tic:.0f} s)")
    for name in PLANNER_NAMES:
        v = final[name]
        all_found = np.mean(np.isfinite(v["time_to_all"]))
        finite = v["time_to_all"][np.isfinite(v["time_to_all"])]
        print(f"  {name}")
        line("    final RSE (mean +- std)", f"{v['rse'].mean():.2f} +- {v['rse'].std(ddof=1):.2f}", "lower is better")
        line("    final trace(P) (mean +- std)", f"{v['trace'].mean():.1f} +- {v['trace'].std(ddof=1):.1f}", "lower is better")
        line("    people found (of 7)", f"{v['found'].mean():.2f}", "7")
        line("    all 7 found within 150 s", f"{100 * all_found:.0f} %", ">= 90 % (best planner)")
        line("    all 7 found, looser person-mean criterion", f"{100 * np.mean(np.isfinite(v['time_to_all_person_mean'])):.0f} %",
             "diagnostic")
        line("    time to find all (median of successes)", f"{np.median(finite):.0f} s" if len(finite) else "never", "reported")
        line("    false-alarm cells / objects (final)", f"{v['false_cells'].mean():.2f} / {v['false_objects'].mean():.2f}", "reported")
        line("    planner time per replan (median)", f"{v['planner_median']:.3f} s", "<= 0.5 s")
    print("  Paired differences (planner - baseline, same seeds; negative = better)")
    for name in INFORMATIVE:
        for baseline in ("lawnmower", "random"):
            for key, label in (("rse", "RSE"), ("trace", "trace(P)")):
                diff = final[name][key] - final[baseline][key]
                wins = np.mean(diff < 0)
                line(f"    {name} - {baseline} {label}", f"{diff.mean():+.2f} +- {diff.std(ddof=1):.2f} (wins {100 * wins:.0f} %)", "< 0")
    best = max(PLANNER_NAMES, key=lambda n: np.mean(np.isfinite(final[n]["time_to_all"])))
    line("best planner at finding all 7", f"{best}: {100 * np.mean(np.isfinite(final[best]['time_to_all'])):.0f} %", ">= 90 %")
    find_all_diagnostics(args.trials)


class _TruthOracle:
    """Diagnostic only (uses the ground truth): flies to the nearest person not yet found (strict
    criterion on the current map) at ``altitude_m`` and hovers for images: no search needed, an
    upper bound on what the sensor setup allows within the budget."""

    name = "truth_oracle"
    waypoints_per_replan = None

    def __init__(self, field, altitude_m: float, setup) -> None:
        self.field, self.altitude_m, self.setup = field, altitude_m, setup

    def reset(self, seed: int = 0) -> None:
        pass

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0):
        left = [p for p, cells in zip(self.field.people, self.field.person_cells) if not np.all(belief.mean[cells] > 0.5)]
        if not left:
            return np.array([pose])
        nearest = min(left, key=lambda p: np.hypot(p.x_m - pose[0], p.y_m - pose[1]))
        return np.array([[nearest.x_m, nearest.y_m, self.altitude_m]])


def find_all_diagnostics(trials: int) -> None:
    """All-7-found fractions, strict criterion beside the looser person-mean one, for the two
    search-then-confirm planners ("cover_confirm": two coverage passes at 13 m, then confirmation;
    "efe_confirm": EFE search at 14 m, confirmation at 8 m; settings chosen on seeds 100-199 and
    100-124, disjoint from the trial seeds) and for the ground-truth oracle ceiling at 5, 8 and
    11 m."""
    from attend.action.episode import fly

    print(f"\nFinding all 7 (seeds 0-{trials - 1}; strict: every cell of a person > 0.5 | diagnostic: person-mean > 0.5)")
    runs = {}
    for seed in range(trials):
        field = make_field(seed)
        setup = PlanningSetup(field)
        planners = {"cover_confirm (cover 2 x 13 m, confirm)": make_planner("cover_confirm", setup, seed),
                    "efe_confirm (search 14 m, confirm 8 m)": make_planner("efe_confirm", setup, seed)}
        planners.update({f"truth oracle at {h:g} m (ceiling)": _TruthOracle(field, h, setup) for h in (5.0, 8.0, 11.0)})
        for label, planner in planners.items():
            log = fly(field, planner, 150.0, seed, keep_maps=False)
            runs.setdefault(label, []).append(
                (np.isfinite(log.time_to_find_all_s()), np.isfinite(log.time_to_find_all_s("people_found_person_mean")),
                 log.series("people_found")[-1], log.series("rse")[-1], log.series("trace")[-1]))
    for label, values in runs.items():
        v = np.array(values, dtype=float)
        line(f"  {label}", f"{100 * v[:, 0].mean():.0f} % strict | {100 * v[:, 1].mean():.0f} % person-mean",
             ">= 90 % (strict)")
        line("      people found / final RSE / final trace(P)", f"{v[:, 2].mean():.2f} / {v[:, 3].mean():.2f} / {v[:, 4].mean():.1f}",
             "reported")


if __name__ == "__main__":
    main()
