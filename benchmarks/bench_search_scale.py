"""Expected free energy search on the probability map at field scale: each figure beside its target.

    python benchmarks/bench_search_scale.py --quick            # every part, small (a few minutes)
    python benchmarks/bench_search_scale.py --parts 2          # replan time, map update, memory
    python benchmarks/bench_search_scale.py --parts 1 3 --missions 100

Parts:
1. The paper's 30 m field (``world_from_field(make_field(seed))``, ``DetectionModel.paper()``,
   5 m/s, 0.15 Hz, 150 s): share of missions finding all 7 (target >= 95 %), false targets per
   mission (target <= 0.1), beside a truth oracle (knows where the people are, flies to them in
   nearest-neighbour order at the detector's best altitude and hovers over each until the map
   reports a target there; a ceiling, written here, not in the package).
2. Field scale, one UAV on 500 m x 500 m at 1 m (250 000 cells) and on 1 km x 1 km at 1 m
   (10^6 cells): replan time median (target <= 1 s) and worst (<= 3 s), map update per image
   (<= 10 ms), peak memory of the process (<= 2 GB; ru_maxrss of a fresh worker).
3. Against the best lawnmower: worlds of side 200 m .. 1 km (cells of max(1 m, side / 400)),
   1-20 people, 0-6 buildings, uniform or informative prior; budget 1.2 x the time to cover the
   area once at 45 m (at least 600 s); the lawnmower's altitude (45-90 m, above every roof:
   its detours around buildings can fail lower down) and track spacing tuned (``tune_lawnmower``:
   least median time to 90 %, under the evaluation's own budget rule) on seeds 1000+, the
   comparison on seeds 0+. Median over
   the missions of the time-to-90 % ratio EFE / lawnmower (targets <= 0.8 uniform, <= 0.5
   informative; a planner that never reaches 90 % counts as twice the budget) and P(all found
   by the end) of both; with the uniform prior, beside them an ideal sweep's time to 90 %
   (``world_ideal_sweep_t90``: how fast any sweep could be on these worlds); with the informative
   prior, an ideal sweep in order of the prior's density (``world_ordered_sweep_t90``).
4. Several UAVs (EFE; 400 m x 400 m at 1 m, 10 people, 2 buildings, 600 s): median over missions
   of the time to 90 % with 2 and 4 UAVs relative to 1 (targets <= 0.6, <= 0.35), and the images at
   which two UAVs were closer than the separation (10 m).

Missions run in at most 2 worker processes (concurrent.futures), each on one BLAS thread. The
EFE planner's hyperparameters were chosen on seeds 1000+ of part 1; evaluation seeds start at 0.
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"  # one BLAS thread per worker, before numpy loads BLAS

import argparse  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402

import numpy as np  # noqa: E402

from attend.action.detection import DetectionModel  # noqa: E402
from attend.action.field import make_field  # noqa: E402
from attend.action.planners.field_lawnmower import FieldLawnmowerPlanner  # noqa: E402
from attend.action.planners.salience import ExpectedFreeEnergySearchPlanner  # noqa: E402
from attend.action.search_mission import SearchSettings, fly_search  # noqa: E402
from attend.experiments.search_scale import TruthOraclePlanner  # noqa: E402
from attend.action.world import make_world, world_from_field  # noqa: E402
from attend.action.planners.salience import ASSOCIATION_SIGMAS, box_sums  # noqa: E402
from attend.action.log_odds import logistic  # noqa: E402
from attend.action.probability_map import ProbabilityMap  # noqa: E402

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ideal_sweep import detect_and_confirm_t90, ideal_sweep_t90, ordered_sweep_t90  # noqa: E402

TUNING_SEED_OFFSET = 1000
#: Seconds per confirming detour of the detect-and-confirm reference (part 3): free, and about what
#: a turn, a descent, a look and the way back take at 10 m/s.
DETOUR_SECONDS = (0.0, 3.0, 10.0)
WORKERS = 2


def line(name: str, value: str, target: str) -> None:
    print(f"  {name:<58} {value:<26} target: {target}", flush=True)


#: Options of ExpectedFreeEnergySearchPlanner by the name the missions below give them.
EFE_VARIANTS = {"efe": {}, "efe3": {"legs": 3}}


def run_parallel(function, jobs, workers=WORKERS):
    """function(*job) for every job, in at most ``workers`` fresh processes, results in order."""
    with ProcessPoolExecutor(max_workers=workers, max_tasks_per_child=1) as pool:
        return list(pool.map(function, *zip(*jobs))) if jobs else []


# ------------------------------------------------------------------------------------------------
# part 1: the paper's field


def paper_settings() -> SearchSettings:
    return SearchSettings(budget_s=150.0, speed_m_s=5.0, image_rate_hz=0.15, model=DetectionModel.paper())


def paper_mission(seed: int, planner_name: str):
    """(people found, all found, false targets, time to all [s]) of one paper-field mission."""
    settings = paper_settings()
    world = world_from_field(make_field(seed))
    if planner_name == "oracle":
        planner = TruthOraclePlanner(world.people_m, settings.model.best_altitude_m, settings.found_radius_m,
                                     world.buildings, max_altitude_m=world.altitude_limits_m[1])
    else:
        planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings, **EFE_VARIANTS[planner_name])
    log = fly_search(world, planner, settings, seed)
    found = len(log.found_times_s)
    return found, found == world.n_people, log.false_targets, log.time_to_fraction_s(1.0)


def part1(missions: int) -> None:
    print(f"1. paper field (30 m, paper detector, 5 m/s, 0.15 Hz, 150 s), {missions} missions, seeds 0..{missions - 1}")
    for name in ("efe", "oracle"):
        start = time.perf_counter()
        rows = run_parallel(paper_mission, [(seed, name) for seed in range(missions)])
        found, all_found, false, t_all = (np.array(v, dtype=float) for v in zip(*rows))
        label = "EFE" if name == "efe" else "truth oracle"
        line(f"{label}: missions finding all 7 within 150 s", f"{100 * all_found.mean():.0f} %",
             ">= 95 %" if name == "efe" else "(ceiling)")
        line(f"{label}: false targets per mission (end)", f"{false.mean():.2f}", "<= 0.1" if name == "efe" else "-")
        finite = t_all[np.isfinite(t_all)]
        line(f"{label}: people found (mean), time to all (median of finders)",
             f"{found.mean():.2f}, {np.median(finite) if len(finite) else math.inf:.0f} s", "-")
        print(f"     ({time.perf_counter() - start:.0f} s wall)", flush=True)


# ------------------------------------------------------------------------------------------------
# part 2: field scale


def scale_mission(area_m: float, budget_s: float, seed: int):
    """Replan times [s], map update times [ms], peak RSS [MB] of one EFE mission at 1 m cells."""
    settings = SearchSettings(budget_s=budget_s)
    world = make_world(area_m, 1.0, 10, seed, n_buildings=4)
    planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings)
    log = fly_search(world, planner, settings, seed)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return np.array(log.planner_times_s), np.array(log.map_update_ms), peak_mb, len(log.found_times_s)


def part2(budget_s: float) -> None:
    print(f"2. field scale: one UAV, 1 m cells, 10 people, 4 buildings, {budget_s:g} s mission (10 m/s, 1 Hz)")
    for area in (500.0, 1000.0):
        (plans, updates, peak_mb, found), = run_parallel(scale_mission, [(area, budget_s, 0)], workers=1)
        cells = int(round(area)) ** 2
        line(f"{cells:,} cells: replan time median ({len(plans)} replans)", f"{np.median(plans):.3f} s", "<= 1 s")
        line(f"{cells:,} cells: replan time worst", f"{plans.max():.3f} s", "<= 3 s")
        line(f"{cells:,} cells: map update per image median / worst",
             f"{np.median(updates):.2f} / {updates.max():.1f} ms", "<= 10 ms")
        line(f"{cells:,} cells: peak memory (process RSS)", f"{peak_mb:.0f} MB", "<= 2048 MB")


# ------------------------------------------------------------------------------------------------
# part 3: against the best lawnmower

AREAS_M = (200.0, 400.0, 700.0, 1000.0)


def scenario(seed: int, prior: str):
    """The world of one part-3 mission: side, people, buildings drawn from the seed."""
    rng = np.random.default_rng(seed + 7919)
    area = float(AREAS_M[rng.integers(len(AREAS_M))])
    n_people = int(rng.integers(1, 21))
    n_buildings = int(rng.integers(0, 7))
    return make_world(area, max(1.0, area / 400), n_people, seed, n_buildings=n_buildings, prior=prior)


def scenario_budget_s(world) -> float:
    """Flight budget [s] of a part-3 world: 1.2 x the time to cover it once with tracks 37 m
    apart (the footprint width at 45 m) at 10 m/s, at least 600 s."""
    x0, x1, y0, y1 = world.grid.extent_m
    return max(600.0, 1.2 * (x1 - x0) * (y1 - y0) / (37.0 * 10.0))


def comparison_mission(seed: int, prior: str, planner_name: str, altitude_m: float, spacing_factor: float,
                       n_uavs: int = 1):
    """(time to 90 % [s] (inf: not within the budget), all found at the end, budget [s], false
    targets at the end) of one mission."""
    world = scenario(seed, prior)
    settings = SearchSettings(n_uavs=n_uavs, budget_s=scenario_budget_s(world))
    if planner_name == "lawnmower":
        spacing = spacing_factor * float(settings.camera.footprint_m(altitude_m)[0])
        planner = FieldLawnmowerPlanner(altitude_m, spacing, settings.camera, n_uavs, world.buildings)
    else:
        planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings, **EFE_VARIANTS[planner_name])
    log = fly_search(world, planner, settings, seed)
    return log.time_to_fraction_s(0.9), len(log.found_times_s) == world.n_people, settings.budget_s, log.false_targets


def world_channels(seed: int, prior: str):
    """(settings, searchable area [m^2], people, a target disc's prior mass m0 under a uniform
    prior, channels (h, w_x, w_y, pd, pf) at 20-100 m in 5 m steps, association area [m^2] per
    channel) of a part-3 world, for the sweep references of :mod:`ideal_sweep`. Buildings and
    occlusion are ignored: references, not bounds."""
    world = scenario(seed, prior)
    settings = SearchSettings(budget_s=scenario_budget_s(world))
    grid, model, camera = world.grid, settings.model, settings.camera
    cell = grid.cell_size_m
    belief = ProbabilityMap.uniform(grid, world.n_people, world.searchable)
    k = int(round(belief.default_target_radius_m() / cell))
    p0 = world.n_people / float(world.searchable.sum())
    channels, associations = [], []
    for h in np.arange(20.0, 101.0, 5.0):
        width, length = (float(v) for v in camera.footprint_m(h))
        association = cell**2 + np.pi * (ASSOCIATION_SIGMAS * float(model.position_error_m(h))) ** 2
        channels.append((h, width, length, float(model.detection_probability(h, settings.speed_m_s)),
                         float(model.false_alarm_probability_per_cell(h, camera, association))))
        associations.append(association)
    return (settings, float(world.searchable.sum()) * cell**2, world.n_people, min(1.0, p0 * (2 * k + 1) ** 2),
            channels, associations)


def world_ideal_sweep_t90(seed: int, prior: str) -> float:
    """:func:`ideal_sweep.ideal_sweep_t90` [s] of a part-3 world (:func:`world_channels`), one UAV;
    found times exact (the search checks them at every image)."""
    settings, area, people, mass, channels, _ = world_channels(seed, prior)
    t90, _, _ = ideal_sweep_t90(area, people, mass, channels, 1, settings.speed_m_s, 1.0 / settings.image_rate_hz,
                                settings.budget_s, settings.target_threshold, np.random.default_rng(seed))
    return t90


def world_ordered_sweep_t90(seed: int, prior: str) -> float:
    """:func:`ideal_sweep.ordered_sweep_t90` [s] of a part-3 world: its ideal sweep in order of the
    prior map's density (the planner's starting map), each person at their true place, one UAV."""
    settings, area, _, _, channels, _ = world_channels(seed, prior)
    world = scenario(seed, prior)
    if world.prior_map is None:
        belief = ProbabilityMap.uniform(world.grid, world.n_people, world.searchable)
    else:
        belief = ProbabilityMap.from_prior_map(world.grid, world.prior_map, float(world.n_people), world.searchable)
    p = np.where(world.searchable, logistic(np.asarray(belief.log_odds, dtype=float)), 0.0)
    k = int(round(belief.default_target_radius_m() / world.grid.cell_size_m))
    masses = np.minimum(box_sums(p, k), 1.0)
    density = p[world.searchable]
    cols, rows = world.grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])  # (ix, iy): x is the column
    own = p[rows, cols]
    denser = np.array([(density > d).sum() + 0.5 * (density == d).sum() for d in own]) / density.size
    t90, _ = ordered_sweep_t90(area, denser, masses[rows, cols], channels, 1, settings.speed_m_s,
                               1.0 / settings.image_rate_hz, settings.budget_s, settings.target_threshold,
                               np.random.default_rng(seed))
    return t90


def world_detect_and_confirm_t90(seed: int, prior: str, confirm_s: float) -> float:
    """:func:`ideal_sweep.detect_and_confirm_t90` [s] of a part-3 world: its ideal sweep confirming
    every place with enough reports by a detour of ``confirm_s`` seconds (0: free)."""
    settings, area, people, mass, channels, associations = world_channels(seed, prior)
    t90, _, _ = detect_and_confirm_t90(area, people, mass, channels, associations, 1, settings.speed_m_s,
                                       1.0 / settings.image_rate_hz, settings.budget_s, settings.target_threshold,
                                       confirm_s, np.random.default_rng(seed))
    return t90


def tune_lawnmower(prior: str, seeds, altitudes, factors):
    """(altitude [m], spacing factor) of the lawnmower with the least median time to 90 % over the
    part-3 worlds of ``seeds`` (kept apart from the evaluation seeds), each mission flown under the
    evaluation's own budget rule (``scenario_budget_s``) and a miss counted as twice the budget,
    as in the evaluation; ties broken by the larger share of missions finding everybody, then
    the lower altitude."""
    configs = [(h, f) for h in altitudes for f in factors]
    jobs = [(seed, prior, "lawnmower", h, f) for h, f in configs for seed in seeds]
    rows = run_parallel(comparison_mission, jobs)
    scores = []
    for k, (h, f) in enumerate(configs):
        chunk = rows[k * len(seeds):(k + 1) * len(seeds)]
        times = [r[0] if np.isfinite(r[0]) else 2 * r[2] for r in chunk]
        scores.append((float(np.median(times)), -float(np.mean([r[1] for r in chunk])), float(h), float(f)))
    _, _, h, f = min(scores)
    return h, f


def part3(missions: int, tuning_seeds: int, quick: bool, priors=("uniform", "informative"), efe_name: str = "efe",
          first_seed: int = 0) -> None:
    # above the tallest building (40 m): FieldLawnmowerPlanner's detours can fail below roof height
    altitudes = (45.0, 60.0) if quick else (45.0, 52.0, 60.0, 70.0, 80.0, 90.0)
    factors = (1.0,) if quick else (0.8, 1.0, 1.2)
    last = TUNING_SEED_OFFSET + tuning_seeds - 1
    print(f"3. EFE against the best lawnmower (tuned on seeds {TUNING_SEED_OFFSET}..{last} "
          f"over h {altitudes} m, spacing {factors} x w_x), {missions} missions per prior (seeds {first_seed}.."
          f"{first_seed + missions - 1}), planner {efe_name} {EFE_VARIANTS[efe_name]}, 10 m/s, 1 Hz")
    evaluation = range(first_seed, first_seed + missions)
    seeds = list(range(TUNING_SEED_OFFSET, TUNING_SEED_OFFSET + tuning_seeds))
    for prior in priors:
        target = {"uniform": "<= 0.8", "informative": "<= 0.5"}[prior]
        start = time.perf_counter()
        h, factor = tune_lawnmower(prior, seeds, altitudes, factors)
        jobs = [(seed, prior, name, h, factor) for seed in evaluation for name in (efe_name, "lawnmower")]
        rows = run_parallel(comparison_mission, jobs)
        efe, mower = rows[0::2], rows[1::2]
        t_efe = np.array([r[0] if np.isfinite(r[0]) else 2 * r[2] for r in efe])
        t_mow = np.array([r[0] if np.isfinite(r[0]) else 2 * r[2] for r in mower])
        ratio = t_efe / t_mow
        line(f"{prior}: best lawnmower", f"h {h:g} m, spacing {factor:g} w_x", "-")
        draws = np.random.default_rng(0).integers(0, len(ratio), size=(2000, len(ratio)))
        low, high = np.percentile(np.median(ratio[draws], axis=1), [2.5, 97.5])
        line(f"{prior}: median time-to-90% ratio EFE / lawnmower",
             f"{np.median(ratio):.2f} (bootstrap 95 % [{low:.2f}, {high:.2f}])", target)
        line(f"{prior}: EFE faster in", f"{np.mean(ratio < 1) * 100:.0f} % of missions", "-")
        if prior == "uniform":
            ideal = np.array([world_ideal_sweep_t90(seed, prior) for seed in evaluation])
            line(f"{prior}: median time to 90 %, ideal sweep (no transit, turns or buildings)",
                 f"{np.median(ideal):.0f} s; ideal / lawnmower {np.median(ideal / t_mow):.2f}, EFE / ideal "
                 f"{np.median(t_efe / ideal):.2f} (medians over missions)", "-")
            for confirm_s in DETOUR_SECONDS:
                adaptive = np.array([world_detect_and_confirm_t90(seed, prior, confirm_s) for seed in evaluation])
                line(f"{prior}: ideal sweep confirming by detours of {confirm_s:g} s / lawnmower",
                     f"{np.median(adaptive / t_mow):.2f} (median over missions)", "-")
        if prior == "informative":
            ordered = np.array([world_ordered_sweep_t90(seed, prior) for seed in evaluation])
            line(f"{prior}: ideal sweep in order of the prior's density / lawnmower",
                 f"{np.median(ordered / t_mow):.2f}; EFE / that sweep {np.median(t_efe / ordered):.2f} "
                 f"(medians over missions)", "-")
        line(f"{prior}: median time to 90 % EFE / lawnmower",
             f"{np.median(t_efe):.0f} s / {np.median(t_mow):.0f} s", "-")
        line(f"{prior}: P(all found by the end) EFE / lawnmower",
             f"{np.mean([r[1] for r in efe]):.2f} / {np.mean([r[1] for r in mower]):.2f}", "-")
        failed = [[seed for seed, r in zip(evaluation, rows) if not r[1]] for rows in (efe, mower)]
        line(f"{prior}: missions not finding everyone EFE / lawnmower", f"{failed[0]} / {failed[1]}", "-")
        line(f"{prior}: false targets per mission (end) EFE / lawnmower",
             f"{np.mean([r[3] for r in efe]):.2f} / {np.mean([r[3] for r in mower]):.2f}", "-")
        print(f"     ({time.perf_counter() - start:.0f} s wall)", flush=True)


# ------------------------------------------------------------------------------------------------
# part 4: several UAVs


def team_mission(seed: int, n_uavs: int):
    """(time to 90 % [s] (inf: not within the budget), all found, budget [s]) of one part-4 mission."""
    world = make_world(400.0, 1.0, 10, seed, n_buildings=2)
    settings = SearchSettings(n_uavs=n_uavs, budget_s=600.0)
    planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings)
    log = fly_search(world, planner, settings, seed)
    return log.time_to_fraction_s(0.9), len(log.found_times_s) == world.n_people, settings.budget_s, \
        log.separation_violations


def part4(missions: int) -> None:
    print(f"4. several UAVs (EFE, 400 m x 400 m at 1 m, 10 people, 2 buildings, uniform prior, 600 s), "
          f"{missions} missions per team size")
    times = {}
    for n_uavs in (1, 2, 4):
        start = time.perf_counter()
        rows = run_parallel(team_mission, [(seed, n_uavs) for seed in range(missions)])
        times[n_uavs] = np.array([r[0] if np.isfinite(r[0]) else 2 * r[2] for r in rows])
        print(f"     {n_uavs} UAV(s): median time to 90 % {np.median(times[n_uavs]):.0f} s, all found in "
              f"{np.mean([r[1] for r in rows]) * 100:.0f} %, images closer than the separation "
              f"{np.mean([r[3] for r in rows]):.1f} per mission ({time.perf_counter() - start:.0f} s wall)", flush=True)
    for n_uavs, target in ((2, "<= 0.6"), (4, "<= 0.35")):
        line(f"time to 90 % with {n_uavs} UAVs / 1 UAV (median of per-mission ratios)",
             f"{np.median(times[n_uavs] / times[1]):.2f}", target)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs of every part (a few minutes)")
    parser.add_argument("--parts", type=int, nargs="+", default=[1, 2, 3, 4], choices=[1, 2, 3, 4])
    parser.add_argument("--missions", type=int, default=None, help="missions per configuration (parts 1, 3, 4)")
    parser.add_argument("--priors", nargs="+", default=["uniform", "informative"], choices=["uniform", "informative"],
                        help="priors of part 3")
    parser.add_argument("--efe", default="efe", choices=sorted(EFE_VARIANTS),
                        help="the EFE planner part 3 flies: efe (two legs, the default) or efe3 (legs=3)")
    parser.add_argument("--first-seed", type=int, default=0,
                        help="first evaluation seed of part 3 (seeds first .. first + missions - 1; 0 by default)")
    args = parser.parse_args()
    quick = args.quick
    start = time.perf_counter()
    if 1 in args.parts:
        part1(args.missions or (10 if quick else 100))
    if 2 in args.parts:
        part2(60.0 if quick else 300.0)
    if 3 in args.parts:
        part3(args.missions or (3 if quick else 30), 2 if quick else 6, quick, tuple(args.priors), args.efe,
              args.first_seed)
    if 4 in args.parts:
        part4(args.missions or (2 if quick else 20))
    print(f"total {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
