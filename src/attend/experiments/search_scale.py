"""Experiment "search-scale": salience that finds everyone, at the size of a real search.

A square area at field scale (1 m cells; 200 m in quick mode, 500 m in full mode), people lying
on the ground, a few buildings that hide the ground and block flight, the field-scale detector
(:class:`attend.action.detection.DetectionModel`: best at 30 m, useless at 100 m), 10 m/s and one
image per second. Every mission flies for the time one lawnmower pass at 30 m takes, plus a
quarter (:func:`attend.action.search_run.coverage_budget_s` for one UAV; each UAV gets that time).

Compared on the same worlds (mission k: seed ``first_seed + k`` for the world, the detections and
the planner):

* ``efe``: the expected-free-energy planner on the probability map
  (:class:`attend.action.planners.salience.ExpectedFreeEnergySearchPlanner`);
* ``lawnmower``: boustrophedon tracks at the detector's best altitude, spaced by the footprint
  (:class:`attend.action.planners.field_lawnmower.FieldLawnmowerPlanner`);
* ``oracle``: a planner that knows where the people are and flies to the nearest one not yet
  found at the best altitude (the truth oracle: how fast finding could be);
* ``efe`` with 2 and 4 UAVs sharing the map.

Per mission: the found times of the people, P(all found) after every image, false targets.
Curves: the mean fraction of people found against time, and P(all found by t) (the fraction of
missions that had found everyone by t) per planner and per number of UAVs.
"""

from __future__ import annotations

import math

import numpy as np

from attend.action.flight import clear_route
from attend.action.planners.search_base import SearchPlanner
from attend.action.search_mission import fly_search
from attend.action.search_run import make_search_planner, mission_setup
from attend.experiments._result import Claim, ExperimentResult
from attend.sweep import run_tasks

SETTINGS = dict(
    quick_area_m=200.0, full_area_m=500.0, cell_size_m=1.0,
    quick_people=5, full_people=10, buildings=3,
    quick_missions=4, full_missions=30, first_seed=1000,
    planners=["efe", "lawnmower", "oracle"], uav_counts=[1, 2, 4],
    time_points=120,
)

#: Fractions of the people whose finding times are compared.
FOUND_FRACTION = 0.9


class TruthOraclePlanner(SearchPlanner):
    """Knows where the people are: flies to the nearest person not yet found, at ``altitude_m``
    (by :func:`attend.action.flight.clear_route`: around the buildings in the way, else over them
    below ``max_altitude_m``), and hovers there for an image; then the next one (the best a
    planner could do with the same camera and detector). A person closer to a building taller
    than ``altitude_m`` than ``building_margin_m`` / 2 is looked at from the nearest point
    ``building_margin_m`` outside its wall."""

    name = "oracle"

    def __init__(self, people_m: np.ndarray, altitude_m: float, found_radius_m: float = 3.0, buildings=(),
                 building_margin_m: float = 1.5, max_altitude_m: float = 120.0) -> None:
        self.people_m = np.asarray(people_m, dtype=float)
        self.buildings = tuple(buildings)
        self.altitude_m = float(altitude_m)
        self.found_radius_m = float(found_radius_m)
        self.building_margin_m = float(building_margin_m)
        self.max_altitude_m = float(max_altitude_m)

    def plan(self, belief, uav, pose_m, time_left_s, others=()):
        pose = np.asarray(pose_m, dtype=float)
        targets, _ = belief.targets()
        unfound = [p for p in self.people_m if not len(targets)
                   or np.min(np.linalg.norm(targets - p, axis=1)) > self.found_radius_m]
        claimed = [np.asarray(o)[-1, :2] for o in others if len(o)]
        if claimed:
            unfound = [p for p in unfound if min(np.linalg.norm(c - p) for c in claimed) > 1.0] or unfound
        if not unfound:
            return np.array([[pose[0], pose[1], self.altitude_m]])
        goal = min(unfound, key=lambda p: np.linalg.norm(p - pose[:2]))
        hover = self._outside_buildings(np.array([goal[0], goal[1], self.altitude_m]))
        return clear_route(pose, hover, self.buildings, self.building_margin_m, self.max_altitude_m, belief.grid.extent_m)

    def _outside_buildings(self, point: np.ndarray) -> np.ndarray:
        """``point`` moved out of every building it lies within half the margin of, to the
        nearest side ``building_margin_m`` outside the wall."""
        m = self.building_margin_m
        for box in self.buildings:
            x0, x1, y0, y1, _, top = box.bounds
            if point[2] <= top + m / 2 and x0 - m / 2 <= point[0] <= x1 + m / 2 and y0 - m / 2 <= point[1] <= y1 + m / 2:
                moves = [(point[0] - (x0 - m), 0, x0 - m), (x1 + m - point[0], 0, x1 + m),
                         (point[1] - (y0 - m), 1, y0 - m), (y1 + m - point[1], 1, y1 + m)]
                _, axis, value = min(moves)
                point = point.copy()
                point[axis] = value
        return point


def mission(task: dict) -> dict:
    """One mission (a sweep task): ``task`` holds planner, uavs, seed, area_m, people, cell_size_m,
    buildings. Returns the people count, budget, found times [s], the image times [s] with
    P(all found) after each, and the false targets at the end."""
    world, settings = mission_setup(seed=int(task["seed"]), area_size_m=task["area_m"], cell_size_m=task["cell_size_m"],
                                    people=int(task["people"]), uavs=int(task["uavs"]), buildings=int(task["buildings"]),
                                    budget_s=task["budget_s"])
    if task["planner"] == "oracle":
        planner = TruthOraclePlanner(world.people_m, settings.model.best_altitude_m, settings.found_radius_m,
                                     world.buildings, max_altitude_m=world.altitude_limits_m[1])
    else:
        planner = make_search_planner(task["planner"], world, settings, int(task["seed"]))
    log = fly_search(world, planner, settings, int(task["seed"]))
    return dict(planner=task["planner"], uavs=int(task["uavs"]), seed=int(task["seed"]), people=world.n_people,
                budget_s=settings.budget_s, found_times_s=list(log.found_times_s), times_s=list(log.times_s),
                p_all_found=list(log.p_all_found), false_targets=int(log.false_targets),
                time_to_90_percent_s=log.time_to_fraction_s(FOUND_FRACTION),
                median_planner_time_s=float(np.median(log.planner_times_s)) if log.planner_times_s else 0.0)


def run(quick: bool = True, progress: bool = True, cluster=None, missions: int | None = None) -> ExperimentResult:
    """Fly every planner and UAV count on the same worlds (module docstring).

    quick: 200 m area, 5 people, 4 missions (else 500 m, 10 people, 30 missions); progress: a
    progress bar; cluster: a Dask scheduler address or client (:func:`attend.sweep.run_tasks`);
    missions: override the number of missions."""
    from attend.action.camera import Camera
    from attend.action.detection import DetectionModel
    from attend.action.search_run import FIELD_SCALE, coverage_budget_s

    mode = "quick" if quick else "full"
    area, people = SETTINGS[f"{mode}_area_m"], SETTINGS[f"{mode}_people"]
    n = int(missions if missions is not None else SETTINGS[f"{mode}_missions"])
    budget = coverage_budget_s(area, 1, Camera(), DetectionModel(), FIELD_SCALE["speed_m_s"])
    base = dict(area_m=area, people=people, cell_size_m=SETTINGS["cell_size_m"], buildings=SETTINGS["buildings"],
                budget_s=budget)
    seeds = [SETTINGS["first_seed"] + k for k in range(n)]
    tasks = [dict(base, planner=p, uavs=1, seed=s) for p in SETTINGS["planners"] for s in seeds]
    tasks += [dict(base, planner="efe", uavs=u, seed=s) for u in SETTINGS["uav_counts"] if u > 1 for s in seeds]
    done = run_tasks(mission, tasks, cluster=cluster, progress=progress, desc="search-scale")
    out = ExperimentResult("search-scale", settings=dict(SETTINGS, mode=mode, missions=n, area_m=area, people=people,
                                                         budget_s=budget))
    grid = np.linspace(0.0, budget, SETTINGS["time_points"])
    groups = {}
    for record in done:
        key = record["planner"] if record["uavs"] == 1 else f"efe_{record['uavs']}_uavs"
        groups.setdefault(key, []).append(record)
    curves, times90 = {}, {}
    for key, records in groups.items():
        fraction = np.mean([[np.sum(np.asarray(r["found_times_s"]) <= t) / r["people"] for t in grid] for r in records], axis=0)
        all_found = np.mean([[len(r["found_times_s"]) == r["people"] and r["found_times_s"][-1] <= t for t in grid]
                             for r in records], axis=0)
        times90[key] = [r["time_to_90_percent_s"] for r in records]
        curves[key] = dict(fraction_found=fraction.tolist(), p_all_found_by_t=all_found.astype(float).tolist())
        out.add(f"{key}_median_time_to_90_percent", np.median(times90[key]), "s")
        out.add(f"{key}_all_found_by_end", np.mean([len(r["found_times_s"]) == r["people"] for r in records]), "")
        out.add(f"{key}_false_targets_per_mission", np.mean([r["false_targets"] for r in records]), "targets")
        out.add(f"{key}_median_planner_time", np.median([r["median_planner_time_s"] for r in records]), "s")
    for numerator, denominator in (("efe", "lawnmower"), ("efe", "oracle"), ("efe_2_uavs", "efe"), ("efe_4_uavs", "efe")):
        if numerator in times90 and denominator in times90:
            out.add(f"{numerator}_over_{denominator}_time_to_90_percent",
                    _paired_median_ratio(times90[numerator], times90[denominator]), "")
    out.tables = dict(grid_t=grid.tolist(), curves=curves, missions=[
        {k: r[k] for k in ("planner", "uavs", "seed", "people", "found_times_s", "false_targets")} for r in done])
    return out


def _paired_median_ratio(numerator: list[float], denominator: list[float]) -> float:
    """Median over missions of t_a / t_b (a mission where a never got there counts as inf, where
    only b never did as 0; neither: skipped)."""
    ratios = []
    for a, b in zip(numerator, denominator):
        if math.isinf(a) and math.isinf(b):
            continue
        ratios.append(math.inf if math.isinf(a) else (0.0 if math.isinf(b) else a / b))
    return float(np.median(ratios)) if ratios else math.nan


CAPTIONS = {
    "search-scale_found.png": "Left: mean fraction of the people found against mission time, per planner (one UAV) and "
    "for 2 and 4 UAVs sharing the map (EFE). Right: P(all found by t), the fraction of missions that had found "
    "everyone by time t. The oracle knows where the people are: the gap to it is what a better planner could still "
    "win; the lawnmower sweeps at the detector's best altitude.",
}


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """search-scale_found.png from ``result.tables`` alone; returns the written paths."""
    from pathlib import Path

    from attend.plotting import figure

    grid = np.asarray(result.tables["grid_t"], dtype=float)
    fig, axes = figure((12, 4.2), 1, 2)
    styles = {"efe": "-", "lawnmower": "--", "oracle": ":", "efe_2_uavs": "-.", "efe_4_uavs": "-."}
    for key, curve in result.tables["curves"].items():
        style = styles.get(key, "-")
        axes[0].plot(grid, curve["fraction_found"], style, label=key.replace("_", " "))
        axes[1].plot(grid, curve["p_all_found_by_t"], style, label=key.replace("_", " "))
    s = result.settings
    title = f"{s.get('area_m', 0):.0f} m area, {s.get('people')} people, {s.get('missions')} missions"
    axes[0].set(xlabel="mission time [s]", ylabel="fraction of people found [1]", title=title, ylim=(0, 1.02))
    axes[1].set(xlabel="mission time [s]", ylabel="P(all found by t) [1]", title="missions that found everyone",
                ylim=(0, 1.02))
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "search-scale_found.png"
    fig.savefig(path, dpi=110)
    return [str(path)]


def claims(result: ExperimentResult) -> list[Claim]:
    """Salience as uncertainty minimisation (the paper's action half) against the strongest
    simple baseline, and several UAVs on one map. result: the ExperimentResult of :func:`run`."""
    found = []
    n = result.settings.get("missions")
    try:
        ratio = result.metric("efe_over_lawnmower_time_to_90_percent").value
        efe_all = result.metric("efe_all_found_by_end").value
        mower_all = result.metric("lawnmower_all_found_by_end").value
    except KeyError:
        ratio = None
    if ratio is not None:
        measured = (f"median over {n} missions of the time to find 90 % of the people, EFE / lawnmower: {ratio:.2f}; "
                    f"all found by the end: EFE {efe_all:.0%}, lawnmower {mower_all:.0%}")
        verdict = "reproduced" if ratio < 1 and efe_all >= mower_all else "does not hold"
        found.append(Claim("Choosing where to look by expected free energy (information gain plus the preference for "
                           "finding people) finds people sooner than a lawnmower at the detector's best altitude",
                           measured, verdict))
    for uavs, target in ((2, 0.6), (4, 0.35)):
        try:
            ratio = result.metric(f"efe_{uavs}_uavs_over_efe_time_to_90_percent").value
        except KeyError:
            continue
        found.append(Claim(f"{uavs} UAVs sharing one probability map find 90 % of the people in at most {target} x "
                           "the time of one", f"median ratio over {n} missions: {ratio:.2f}",
                           "reproduced" if ratio <= target else "does not hold"))
    return found
