"""One search mission on the probability map, with its files: what ``attend search`` runs by default.

Two grounds:

- the paper's field (no ``area_size_m``): 30 m x 30 m, 0.75 m cells, 7 people lying on the
  ground, the paper's detector (best at 10 m, useless at 26 m), 5 m/s, an image every 6.7 s
  (0.15 Hz), 150 s of flight;
- a square area of ``area_size_m`` at ``cell_size_m`` (default 1 m): the field-scale detector
  (best at 30 m, useless at 100 m), 10 m/s, 1 image/s, and by default as much flight time as
  one lawnmower pass at 30 m takes, shared among the UAVs, plus a quarter.

Files written: ``search_metrics.json`` (settings, summary, per-image series), ``search_map.png``
(the final map of P(person), the flown paths, the people and the reported targets) and
``search_found.png`` (people found, P(all found) and the expected number of people against
time).
"""

from __future__ import annotations

import json
import math
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import numpy as np

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.field import make_field
from attend.action.planners.field_lawnmower import FieldLawnmowerPlanner
from attend.action.planners.salience import ExpectedFreeEnergySearchPlanner
from attend.action.search_mission import SearchLog, SearchSettings, fly_search
from attend.action.world import SearchWorld, make_world, world_from_field

#: The planners that fly on the probability map: name -> what it does.
SEARCH_PLANNERS = {
    "efe": "expected free energy per second of flight: information gain about the map plus the "
    "preference for confirming people (no coded phases or altitudes)",
    "lawnmower": "baseline: boustrophedon tracks at the detector's best altitude, no gaps between footprints",
}
#: The paper's field: side [m], cell [m], people, budget [s], speed [m/s], image rate [Hz].
PAPER_FIELD = dict(area_size_m=30.0, cell_size_m=0.75, people=7, budget_s=150.0, speed_m_s=5.0, image_rate_hz=0.15)
#: Field scale defaults: cell [m], people, speed [m/s], image rate [Hz].
FIELD_SCALE = dict(cell_size_m=1.0, people=10, speed_m_s=10.0, image_rate_hz=1.0)
#: Spacing [m] of the take-off poses of several UAVs on the paper's field (along x).
PAPER_FIELD_UAV_SPACING_M = 3.0


def coverage_budget_s(area_size_m: float, n_uavs: int, camera: Camera, model: DetectionModel, speed_m_s: float) -> float:
    """1.25 x the time one lawnmower pass at the detector's best altitude takes over a square of
    ``area_size_m``, shared among ``n_uavs``: 1.25 (area / track spacing) area / (speed n) [s],
    the track spacing being the footprint across track."""
    spacing = float(min(camera.footprint_m(model.best_altitude_m)))
    tracks = math.ceil(area_size_m / spacing)
    return 1.25 * tracks * area_size_m / (speed_m_s * n_uavs)


def mission_setup(
    seed: int = 0,
    area_size_m: float | None = None,
    cell_size_m: float | None = None,
    people: int | None = None,
    uavs: int = 1,
    buildings: int = 0,
    obstacles: str = "none",
    people_region: str = "all",
    prior_map: np.ndarray | None = None,
    budget_s: float | None = None,
    speed_m_s: float | None = None,
    image_rate_hz: float | None = None,
    start_pose_m: Sequence[float] | None = None,
) -> tuple[SearchWorld, SearchSettings]:
    """The world and settings of one mission (module docstring: the paper's field when
    ``area_size_m`` is None, else a square area at field scale).

    seed: seeds the people, buildings and detections; area_size_m: side of the area [m];
    cell_size_m: map cell side [m]; people: number of people; uavs: number of UAVs; buildings:
    random buildings (field scale); obstacles: "none" or "buildings" (the paper's field);
    people_region: "all" or "lower_half" (the paper's field); prior_map: relative likelihood
    (ny, nx) on the grid, row 0 south (field scale; people are drawn from it); budget_s: flight
    time of each UAV [s]; speed_m_s: cruise speed [m/s]; image_rate_hz: camera rate [1/s];
    start_pose_m: take-off (x, y, z) [m] of the first UAV (the others beside it; None: the
    ground's default). Raises ActionInputError naming the argument for bad input."""
    _whole(uavs, "uavs", 1)
    _whole(buildings, "buildings", 0)
    if people is not None:
        _whole(people, "people", 1)
    for name, value in (("budget_s", budget_s), ("speed_m_s", speed_m_s), ("image_rate_hz", image_rate_hz),
                        ("area_size_m", area_size_m), ("cell_size_m", cell_size_m)):
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ActionInputError(f"{name}: expected a number > 0, got {value!r}")
    camera = Camera()
    if area_size_m is None:
        if cell_size_m is not None and cell_size_m != PAPER_FIELD["cell_size_m"]:
            raise ActionInputError("cell_size_m: the paper's field has 0.75 m cells; give area_size_m to choose the cell")
        if prior_map is not None or buildings:
            raise ActionInputError("area_size_m: a prior map and random buildings need an area (area_size_m)")
        field = make_field(seed, n_people=people or PAPER_FIELD["people"], obstacles=obstacles, people_region=people_region,
                           **({} if start_pose_m is None else {"start_pose_m": tuple(start_pose_m)}))
        world = world_from_field(field)
        if uavs > 1:
            start = world.start_poses_m[0]
            offsets = (np.arange(uavs) - (uavs - 1) / 2) * PAPER_FIELD_UAV_SPACING_M
            starts = np.column_stack([np.clip(start[0] + offsets, -14.0, 14.0), np.full(uavs, start[1]),
                                      np.full(uavs, start[2])])
            world = replace(world, start_poses_m=starts)
        model = DetectionModel.paper()
        settings = SearchSettings(
            budget_s=budget_s or PAPER_FIELD["budget_s"], speed_m_s=speed_m_s or PAPER_FIELD["speed_m_s"],
            image_rate_hz=image_rate_hz or PAPER_FIELD["image_rate_hz"], n_uavs=uavs, camera=camera, model=model,
            min_separation_m=PAPER_FIELD_UAV_SPACING_M,
        )
        return world, settings
    if obstacles != "none" or people_region != "all":
        raise ActionInputError("obstacles, people_region: these shape the paper's field; without area_size_m only")
    cell = cell_size_m or FIELD_SCALE["cell_size_m"]
    n_people = people or FIELD_SCALE["people"]
    grid_cells = round(area_size_m / cell) if cell <= area_size_m else 0
    if cell > area_size_m:
        raise ActionInputError(f"cell_size_m: expected a cell no larger than the area ({area_size_m:g} m), got {cell:g}")
    if n_people > grid_cells**2:
        raise ActionInputError(f"people: expected at most the {grid_cells ** 2} cells of the area, got {n_people}")
    grid_prior = None
    if prior_map is not None:
        from attend.io.prior_maps import resample_to_grid

        grid_prior = resample_to_grid(np.asarray(prior_map, dtype=float), (grid_cells, grid_cells))
    world = make_world(float(area_size_m), float(cell), n_people, seed, n_buildings=buildings,
                       **({} if grid_prior is None else {"prior_map": grid_prior}))
    model = DetectionModel()
    speed = speed_m_s or FIELD_SCALE["speed_m_s"]
    if uavs > len(world.start_poses_m):
        raise ActionInputError(f"uavs: expected at most {len(world.start_poses_m)} UAVs, got {uavs}")
    if start_pose_m is not None:
        world = replace(world, start_poses_m=_starts_from(start_pose_m, world))
    budget = budget_s or coverage_budget_s(float(area_size_m), uavs, camera, model, speed)
    settings = SearchSettings(budget_s=budget, speed_m_s=speed, image_rate_hz=image_rate_hz or FIELD_SCALE["image_rate_hz"],
                              n_uavs=uavs, camera=camera, model=model)
    return world, settings


def make_search_planner(name: str, world: SearchWorld, settings: SearchSettings, seed: int = 0):
    """The planner ``name`` (one of :data:`SEARCH_PLANNERS`) for ``world`` flown with ``settings``."""
    if name == "efe":
        return ExpectedFreeEnergySearchPlanner.for_world(world, settings, seed=seed)
    if name == "lawnmower":
        low, high = world.altitude_limits_m
        altitude = float(np.clip(settings.model.best_altitude_m, low, high))
        return FieldLawnmowerPlanner(altitude_m=altitude, camera=settings.camera, n_uavs=settings.n_uavs,
                                     buildings=world.buildings, max_altitude_m=high)
    raise ActionInputError(f"planner: expected one of {sorted(SEARCH_PLANNERS)} on the probability map, got {name!r}")


def run_probability_search(
    planner: str = "efe",
    seed: int = 0,
    out_dir: str | Path = "search_out",
    progress: bool = False,
    **setup,
) -> dict[str, Path]:
    """Fly one mission on the probability map and write its files into ``out_dir`` (module
    docstring).

    planner: "efe" or "lawnmower"; seed: seeds the world, the detections and the planner;
    out_dir: output folder (created); progress: a bar over the mission's flight time on
    stderr; ``setup``: the arguments of :func:`mission_setup` (area_size_m, cell_size_m, people,
    uavs, buildings, obstacles, people_region, prior_map, budget_s, speed_m_s, image_rate_hz).
    Returns the written paths: "metrics" (JSON), "map" and "found" (PNG)."""
    if planner not in SEARCH_PLANNERS:
        raise ActionInputError(f"planner: expected one of {sorted(SEARCH_PLANNERS)} on the probability map, got {planner!r}")
    world, settings = mission_setup(seed=seed, **setup)
    search_planner = make_search_planner(planner, world, settings, seed)
    with _mission_progress(planner, settings.budget_s, progress) as on_image:
        log = fly_search(world, search_planner, settings, seed, on_image=on_image)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mission = {
        "map": "probability", "planner": planner, "seed": seed, "area_size_m": world.grid.extent_m[1] - world.grid.extent_m[0],
        "cell_size_m": world.grid.cell_size_m, "cells": world.grid.n_cells, "people": world.n_people,
        "uavs": settings.n_uavs, "buildings": len(world.buildings), "prior_map": world.prior_map is not None,
        "budget_s": settings.budget_s, "speed_m_s": settings.speed_m_s, "image_rate_hz": settings.image_rate_hz,
        "detector_best_altitude_m": settings.model.best_altitude_m,
    }
    from attend.action import search_plots

    return {
        "metrics": write_search_metrics(log, world, out / "search_metrics.json", mission),
        "map": search_plots.plot_search_map(world, log, out / "search_map.png"),
        "found": search_plots.plot_found_over_time(log, out / "search_found.png"),
    }


def search_summary(log: SearchLog) -> dict:
    """What a search team reads first, from one mission's log: people found and when, false
    targets, P(all found), area covered, distance flown, planner and map-update times."""
    all_found = log.people_total > 0 and len(log.found_times_s) >= log.people_total
    return {
        "people_total": int(log.people_total),
        "people_found": int(len(log.found_times_s)),
        "time_to_find_all_s": float(log.found_times_s[-1]) if all_found else None,
        "found_times_s": [float(t) for t in log.found_times_s],
        "time_to_90_percent_s": _finite_or_none(log.time_to_fraction_s(0.9)) if log.people_total else None,
        "false_targets": int(log.false_targets),
        "p_all_found_end": float(log.p_all_found[-1]) if log.p_all_found else None,
        "expected_people_end": float(log.expected_people[-1]) if log.expected_people else None,
        "area_covered_m2": float(log.area_covered_m2),
        "distance_flown_m": [float(d) for d in log.distance_flown_m],
        "images": int(log.images),
        "median_planner_time_s": float(np.median(log.planner_times_s)) if log.planner_times_s else 0.0,
        "max_planner_time_s": float(np.max(log.planner_times_s)) if log.planner_times_s else 0.0,
        "median_map_update_ms": float(np.median(log.map_update_ms)) if log.map_update_ms else 0.0,
    }


def write_search_metrics(log: SearchLog, world: SearchWorld, path: Path, settings: dict) -> Path:
    """One mission's settings, summary and per-image series as JSON at ``path``; returns ``path``."""
    data = {
        "settings": settings,
        "summary": search_summary(log),
        "per_image": {
            "time_s": [float(t) for t in log.times_s],
            "uav": [int(u) for u in log.uavs],
            "people_found": [int(n) for n in log.people_found],
            "expected_people": [float(v) for v in log.expected_people],
            "p_all_found": [float(v) for v in log.p_all_found],
            "false_targets": [int(v) for v in log.false_targets_series],
            "area_covered_m2": [float(v) for v in log.area_covered_series_m2],
        },
        "planner_times_s": [float(t) for t in log.planner_times_s],
        "paths_m": [np.asarray(p).tolist() for p in log.paths_m],
        "people_xy_m": np.asarray(world.people_m).tolist(),
    }
    if log.final_map is not None:
        positions, masses = log.final_map.targets()
        data["targets"] = [{"x_m": float(x), "y_m": float(y), "mass": float(m)} for (x, y), m in zip(positions, masses)]
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


def _starts_from(start_pose_m: Sequence[float], world: SearchWorld) -> np.ndarray:
    """The world's start poses moved so that the first is ``start_pose_m`` (the others keep their
    offsets from it, clipped into the area); checked inside the area, its altitude limits and
    outside the buildings."""
    start = np.asarray(start_pose_m, dtype=float)
    x0, x1, y0, y1 = world.grid.extent_m
    low, high = world.altitude_limits_m
    if start.shape != (3,) or not np.all(np.isfinite(start)):
        raise ActionInputError(f"start_pose_m: expected (x, y, z) in m, got {start_pose_m!r}")
    if not (x0 <= start[0] <= x1 and y0 <= start[1] <= y1 and low <= start[2] <= high):
        raise ActionInputError(f"start_pose_m: expected x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}] and z in "
                               f"[{low:g}, {high:g}] m, got ({start[0]:g}, {start[1]:g}, {start[2]:g})")
    for box in world.buildings:
        bx0, bx1, by0, by1, _, top = box.bounds
        if bx0 <= start[0] <= bx1 and by0 <= start[1] <= by1 and start[2] <= top:
            raise ActionInputError(f"start_pose_m: ({start[0]:g}, {start[1]:g}, {start[2]:g}) m is inside a building")
    starts = world.start_poses_m - world.start_poses_m[0] + start
    starts[:, 0] = np.clip(starts[:, 0], x0, x1)
    starts[:, 1] = np.clip(starts[:, 1], y0, y1)
    return starts


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _whole(value, name: str, least: int) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ActionInputError(f"{name}: expected a whole number >= {least}, got {value!r}")


@contextmanager
def _mission_progress(planner: str, budget_s: float, progress: bool):
    """A tqdm bar over the mission's flight time; yields the ``on_image`` callback of fly_search."""
    from tqdm import tqdm

    with tqdm(total=round(float(budget_s), 1), desc=f"{planner} mission", unit="s", disable=not progress,
              leave=False, bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s flown [{elapsed}<{remaining}]") as bar:

        def on_image(image, belief, log) -> None:
            bar.update(max(0.0, min(float(image.time_s), bar.total) - bar.n))

        yield on_image
