"""The mission on your own ground (`attend plan`): closed-loop search on random areas against the
lawnmower, and the wall time of one `attend plan` call at 250 000 cells.

Bank: random concave areas with a hole and a no-fly zone (attend.action.mission.examples), sizes
log-uniform in 200 m - 1 km, 1-3 UAVs, 3-6 expected people (that many placed), the mission
issue's detector, 2 m cells, flight time per UAV max(120 s, 1.5 x searchable area / (n v w(30 m))):
one and a half passes at 30 m shared among the UAVs. Each mission is flown with the same people and detector
seed by `efe` and by the lawnmower at each altitude of the detector table (15, 30, 45, 60 m),
replanning every 30 s (`attend plan --simulate`). The lawnmower is scored at its best altitude
two ways: the one altitude with the least median time to 90 % over the bank (tuned), and the
best altitude of each mission in hindsight (an oracle no team has: the strongest baseline).

Targets (the mission issue): every person found in >= 95 % of missions; median time to find
90 %, efe / lawnmower <= 0.8 (a miss counts as twice the flight time); <= 0.5 false targets per
mission; one `attend plan` call <= 2 s wall at 250 000 cells including reading the logs.

    python benchmarks/bench_mission.py            # 48 missions (about 25 min on 2 cores)
    python benchmarks/bench_mission.py --quick    # 4 missions
    python benchmarks/bench_mission.py --passes 3 # twice the flight time

Beside the planners it prints the share of missions an ideal flight would find everyone in:
images spread evenly over the area at the best altitude of the detector table for the whole
flight time, with no transit from home, no turns and no way back (``even_coverage_bound``). No
planner flying from home can expect more. For the time to 90 % it prints each planner's time over
that of an ideal sweep (``mission_ideal_sweep_t90``, ``ideal_sweep.py``: tracks over the whole area at the best altitude and
overlap of each mission in hindsight, no transit or turns): how much faster than the lawnmower a
planner could be here.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from attend.action.mission import Mission
from attend.action.mission.examples import write_example_mission
from attend.action.mission.flight_logs import write_flight_logs
from attend.action.mission.mission import TARGET_THRESHOLD, at_least
from attend.action.planners.salience import ASSOCIATION_SIGMAS, confirmation_probability
from attend.action.mission.simulate import simulate_mission

sys.path.insert(0, str(Path(__file__).resolve().parent))
from calibration_table import print_calibration_bins  # noqa: E402
from ideal_sweep import ideal_sweep_t90  # noqa: E402

#: The simulator's found checks [s] (``simulate_mission``'s default found_check_s).
FOUND_CHECK_S = float(inspect.signature(simulate_mission).parameters["found_check_s"].default)


#: Altitudes [m] the lawnmower is flown at (the detector table's).
SWEEP_ALTITUDES_M = (15.0, 30.0, 45.0, 60.0)


def flight_time_s(mission: Mission, passes: float = 1.5) -> float:
    """max(120 s, passes x searchable area / (n v w(30 m))): ``passes`` passes at 30 m shared among the UAVs."""
    area = float(mission.ground.searchable.sum()) * mission.ground.grid.cell_area_m2
    uavs = mission.config.uavs
    width = float(mission.cameras[0].footprint_m(30.0)[0])
    return max(120.0, passes * area / (len(uavs) * uavs[0].speed_m_s * width))


def even_coverage_bound(mission: Mission, budget_s: float, people: int) -> tuple[float, float]:
    """(P, h): the largest P(every person confirmed) of an ideal flight that spends the whole
    budget taking images spread evenly over the searchable area at one altitude h of the
    detector table (no transit, no turns, no way home), each person confirmed as the planner's
    channel counts it (:func:`attend.action.planners.salience.confirmation_probability`: the
    disc's prior mass m0 lifted to the target threshold by the detections of L looks, L = n T
    rate F(h) / area, spread as floor / ceil). An upper bound for a planner flying from home
    under this detector; not a bound on luck."""
    config = mission.config
    area = float(mission.ground.searchable.sum()) * mission.ground.grid.cell_area_m2
    cell = mission.ground.grid.cell_size_m
    p0 = float(np.mean(1.0 / (1.0 + np.exp(-mission.belief.log_odds[mission.ground.searchable]))))
    k = int(round(mission.belief.default_target_radius_m() / cell))
    m0 = min(1.0, p0 * (2 * k + 1) ** 2)
    uav = config.uavs[0]
    images = len(config.uavs) * budget_s / uav.image_interval_s
    best = (0.0, float("nan"))
    for h in config.detector.altitudes_m:
        h = float(h)
        width, length = mission.cameras[0].footprint_m(h)
        looks = images * width * length / area
        pd = float(config.detector.detection_probability(h))
        association = cell**2 + np.pi * (ASSOCIATION_SIGMAS * float(config.detector.position_error_m(h))) ** 2
        pf = float(config.detector.false_alarm_probability_per_cell(h, mission.cameras[0], association))
        low = int(np.floor(looks))
        share = looks - low
        confirm = [float(confirmation_probability(m0, pd, pf, n, TARGET_THRESHOLD)) if n > 0 else 0.0
                   for n in (low, low + 1)]
        per_person = (1 - share) * confirm[0] + share * confirm[1]
        best = max(best, (per_person**people, h))
    return best


def mission_ideal_sweep_t90(mission: Mission, budget_s: float, people: int,
                            rng: np.random.Generator) -> tuple[float, float, int]:
    """(t90 [s], h [m], j): :func:`ideal_sweep.ideal_sweep_t90` of the mission: its searchable
    area, the disc's prior mass, the detector table's altitudes, its UAVs; found times rounded
    up to the simulator's checks."""
    config = mission.config
    area = float(mission.ground.searchable.sum()) * mission.ground.grid.cell_area_m2
    cell = mission.ground.grid.cell_size_m
    p0 = float(np.mean(1.0 / (1.0 + np.exp(-mission.belief.log_odds[mission.ground.searchable]))))
    k = int(round(mission.belief.default_target_radius_m() / cell))
    channels = []
    for h in config.detector.altitudes_m:
        h = float(h)
        width, length = (float(v) for v in mission.cameras[0].footprint_m(h))
        association = cell**2 + np.pi * (ASSOCIATION_SIGMAS * float(config.detector.position_error_m(h))) ** 2
        pf = float(config.detector.false_alarm_probability_per_cell(h, mission.cameras[0], association))
        channels.append((h, width, length, float(config.detector.detection_probability(h)), pf))
    uav = config.uavs[0]
    return ideal_sweep_t90(area, people, min(1.0, p0 * (2 * k + 1) ** 2), channels, len(config.uavs), uav.speed_m_s,
                           uav.image_interval_s, budget_s, TARGET_THRESHOLD, rng, check_s=FOUND_CHECK_S)


def closed_loop(n_missions: int, seed: int, passes: float = 1.5) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for case in range(n_missions):
            size = float(np.exp(rng.uniform(np.log(200), np.log(1000))))
            uavs = int(rng.integers(1, 4))
            people = int(rng.integers(3, 7))
            path = write_example_mission(Path(folder) / f"m{case}", seed=seed + case, size_m=size, n_uavs=uavs,
                                         people=people, flight_time_s=600.0)
            budget = flight_time_s(Mission.from_file(path), passes)
            path = write_example_mission(Path(folder) / f"m{case}", seed=seed + case, size_m=size, n_uavs=uavs,
                                         people=people, flight_time_s=round(budget, 1))
            bound, bound_altitude = even_coverage_bound(Mission.from_file(path), budget, people)
            sweep_t90, sweep_altitude, sweep_overlap = mission_ideal_sweep_t90(
                Mission.from_file(path), budget, people, np.random.default_rng(seed + case))
            row = {"case": case, "size_m": size, "uavs": uavs, "people": people, "budget_s": budget,
                   "even_coverage_bound": bound, "even_coverage_altitude_m": bound_altitude,
                   "ideal_sweep_t90_s": sweep_t90, "ideal_sweep_altitude_m": sweep_altitude,
                   "ideal_sweep_overlap": sweep_overlap}
            for planner, altitude in [("efe", None)] + [("lawnmower", h) for h in SWEEP_ALTITUDES_M]:
                mission = Mission.from_file(path)
                if altitude is not None:
                    mission.config = dataclasses.replace(mission.config, lawnmower_altitude_m=altitude)
                started = time.perf_counter()
                result = simulate_mission(mission, seed=seed + case, planner=planner)
                t90 = result.time_to_fraction_s(0.9)
                positions, masses, _, _ = mission.targets()
                real = [bool(np.min(np.hypot(*(result.people_m - q).T)) <= result.found_radius_m) for q in positions]
                key = planner if altitude is None else f"lawnmower@{altitude:g}"
                row[key] = {"found_all": bool(np.all(np.isfinite(result.found_times_s))),
                            "found": int(np.isfinite(result.found_times_s).sum()),
                            "t90_s": t90 if math.isfinite(t90) else 2 * budget,
                            "false_targets": result.false_targets, "p_all_found": result.p_all_found,
                            "wall_s": time.perf_counter() - started,
                            "plan_median_s": float(np.median(result.planner_times_s)),
                            "targets": list(zip(masses.tolist(), real))}
            best = min((f"lawnmower@{h:g}" for h in SWEEP_ALTITUDES_M), key=lambda k: row[k]["t90_s"])
            row["lawnmower_oracle"] = row[best]
            rows.append(row)
            e, l = row["efe"], row["lawnmower_oracle"]
            print(f"  {case:2d}: {size:5.0f} m, {uavs} UAV(s), {people} people, {budget:5.0f} s | efe found "
                  f"{e['found']}/{people}, t90 {e['t90_s']:5.0f} s, false {e['false_targets']} | best lawnmower ({best}) found "
                  f"{l['found']}/{people}, t90 {l['t90_s']:5.0f} s, false {l['false_targets']}", flush=True)
    return rows


def call_time(seed: int) -> tuple[float, int, int]:
    """Wall time [s] of `attend plan` with logs, on an area of about 250 000 cells, after half
    of a simulated mission (median of 3 calls)."""
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        path = write_example_mission(folder, seed=seed, size_m=1150.0, n_uavs=2, people=5, flight_time_s=600.0)
        mission = Mission.from_file(path)
        simulate_mission(mission, seed=seed, replan_s=60.0)
        logs = mission.logs
        keep = logs.image_time_s <= 300.0
        part = logs.subset(keep)
        write_flight_logs(part, [u.name for u in mission.config.uavs], folder / "images.csv", folder / "detections.csv")
        walls = []
        for _ in range(3):
            started = time.perf_counter()
            subprocess.run([sys.executable, "-m", "attend", "plan", str(path), "--out", str(folder / "out"), "--images",
                            str(folder / "images.csv"), "--detections", str(folder / "detections.csv")], check=True,
                           capture_output=True)
            walls.append(time.perf_counter() - started)
        return float(np.median(walls)), mission.ground.grid.n_cells, int(keep.sum())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 missions instead of 48")
    parser.add_argument("--missions", type=int, default=None)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--passes", type=float, default=1.5,
                        help="flight time: this many passes at 30 m over the searchable area, shared among the UAVs (default 1.5)")
    parser.add_argument("--json", help="also write every mission's figures to this JSON file")
    args = parser.parse_args()
    n = args.missions or (4 if args.quick else 48)
    wall, cells, images = call_time(args.seed)
    print(f"one `attend plan` call: {wall:.2f} s wall at {cells} cells with {images} images   (target <= 2 s)")
    print(f"closed loop, {n} random missions, flight time {args.passes:g} passes at 30 m:")
    rows = closed_loop(n, args.seed, args.passes)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float))
    tuned = min((f"lawnmower@{h:g}" for h in SWEEP_ALTITUDES_M),
                key=lambda k: np.median([r[k]["t90_s"] for r in rows]))
    for label, key in (("efe", "efe"), (f"lawnmower, tuned ({tuned} m)", tuned),
                       ("lawnmower, best per mission", "lawnmower_oracle")):
        found = np.mean([r[key]["found_all"] for r in rows])
        false = np.mean([r[key]["false_targets"] for r in rows])
        print(f"{label:34s} every person found in {100 * found:5.1f} % of missions (target >= 95 %), "
              f"false targets {false:.2f} per mission (target <= 0.5), median plan call "
              f"{np.median([r[key]['plan_median_s'] for r in rows]):.2f} s")
    bound = np.mean([r["even_coverage_bound"] for r in rows])
    print(f"{'even coverage, no transit (bound)':34s} every person found in {100 * bound:5.1f} % of missions (expected: the "
          f"ideal flight of even_coverage_bound at its best altitude)")
    # P(all found) at the end of every flight (efe and every lawnmower altitude) against whether all were found
    runs = [r[k] for r in rows for k in ["efe"] + [f"lawnmower@{h:g}" for h in SWEEP_ALTITUDES_M]]
    predicted = np.array([run["p_all_found"] for run in runs])
    observed = np.array([run["found_all"] for run in runs], dtype=float)
    print(f"P(all found) at the end, {len(runs)} flights: Brier score {np.mean((predicted - observed) ** 2):.3f} "
          f"(always saying the base rate {observed.mean():.2f}: {np.mean((observed.mean() - observed) ** 2):.3f})")
    print_calibration_bins(predicted, observed, "P(all found)", "flights")
    # the same with the number of people known ([search] people_known = true): P(>= N targets are people)
    known = np.array([at_least(np.array([m for m, _ in r[k]["targets"]]), r["people"]) for r in rows
                      for k in ["efe"] + [f"lawnmower@{h:g}" for h in SWEEP_ALTITUDES_M]])
    print(f"P(all found) with the number of people known: Brier score {np.mean((known - observed) ** 2):.3f}")
    print_calibration_bins(known, observed, "P(all found)", "flights")

    targets = np.array([t for run in runs for t in run["targets"]], dtype=float).reshape(-1, 2)
    if len(targets):
        print(f"targets.csv probability, {len(targets)} targets at the end: mean {targets[:, 0].mean():.3f}, "
              f"a person within the found radius for {targets[:, 1].mean():.3f} of them")
    draws = np.random.default_rng(0).integers(0, len(rows), size=(2000, len(rows)))
    for label, key in ((f"tuned lawnmower ({tuned} m)", tuned), ("best lawnmower per mission", "lawnmower_oracle")):
        ratios = np.array([r["efe"]["t90_s"] / r[key]["t90_s"] for r in rows])
        low, high = np.percentile(np.median(ratios[draws], axis=1), [2.5, 97.5])
        print(f"time to find 90 %, efe / {label} (median over missions): {np.median(ratios):.2f}, bootstrap 95 % "
              f"[{low:.2f}, {high:.2f}]   (target <= 0.8)")
    ideal = np.array([r["ideal_sweep_t90_s"] for r in rows])
    for label, key in (("efe", "efe"), (f"tuned lawnmower ({tuned} m)", tuned)):
        ratios = np.array([r[key]["t90_s"] for r in rows]) / ideal
        low, high = np.percentile(np.median(ratios[draws], axis=1), [2.5, 97.5])
        print(f"time to find 90 %, {label} / ideal sweep (median over missions): {np.median(ratios):.2f}, "
              f"bootstrap 95 % [{low:.2f}, {high:.2f}]   (1 = as fast as a perfect sweep at its best altitude "
              f"and overlap in hindsight, ideal_sweep_t90)")


if __name__ == "__main__":
    main()
