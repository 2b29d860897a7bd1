"""One search-and-rescue mission with outputs: the function behind ``attend search``."""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path
from typing import Sequence

import numpy as np

from attend.action.camera import Camera, Detector
from attend.action.episode import EpisodeLog, fly
from attend.action.errors import ActionInputError
from attend.action.field import DEFAULT_START_POSE_M, make_field
from attend.action.flight import FlightModel
from attend.action.planners import ALTITUDE_LAYERS_M, PLANNERS, PlanningSetup, make_planner


def run_search(
    planner: str = "efe",
    seed: int = 0,
    obstacles: str = "none",
    people_region: str = "all",
    budget_s: float = 150.0,
    out_dir: str | Path = "search_out",
    n_people: int = 7,
    start_pose_m: Sequence[float] = DEFAULT_START_POSE_M,
    altitude_limits_m: Sequence[float] = (2.0, 26.0),
    altitude_layers_m: Sequence[float] = ALTITUDE_LAYERS_M,
    fov_deg: Sequence[float] = (45.0, 60.0),
    speed_m_s: float = 5.0,
    acceleration_m_s2: float = 3.0,
    image_rate_hz: float = 0.15,
    clutter_rate_per_image: float = 0.0,
    diagonal: bool = False,
    charge_planning_time: bool = False,
    lookahead_waypoints: int = 3,
    cma_evaluations: int = 24,
    snapshot_times_s: Sequence[float] | None = None,
    gif: bool = True,
    progress: bool = False,
) -> dict[str, Path]:
    """Fly one mission and write its metrics, figures and animation to ``out_dir``.

    planner: "precision_gain", "adaptive", "efe", "efe_confirm" (EFE search at 14 m, then
    confirmation of detections at 8 m), "cover_confirm" (two coverage passes at 13 m, then
    confirmation of every detection), "lawnmower" or "random";
    seed: seeds the people placement, the detector and the planner;
    obstacles: "none" or "buildings" (a 4 x 4 x 26 m tower at the centre, a 4 x 4 x 13 m block);
    people_region: "all" or "lower_half" (people only at y < 0);
    budget_s: flight budget in s (> 0); out_dir: output directory (created);
    n_people: number of people; start_pose_m: take-off (x, y, z) in m, field-centred frame
    (field spans [-15, 15] m); altitude_limits_m: (min, max) flight altitude in m;
    altitude_layers_m: planner altitude layers in m; fov_deg: camera field of view (x, y) in
    degrees, each in (0, 180); speed_m_s, acceleration_m_s2: flight limits; image_rate_hz: camera
    rate in Hz; clutter_rate_per_image: mean false blobs per image; diagonal: per-cell (diagonal)
    Kalman filter instead of the full covariance; charge_planning_time: planning wall time counts
    against the budget; lookahead_waypoints: planner look-ahead (3-5); cma_evaluations: CMA-ES
    evaluations per replan; snapshot_times_s: times (s) of the map figures (default 4 evenly
    spaced over the budget); gif: write the animated GIF; progress: a tqdm bar on stderr over
    the flight budget, then one over the figures.

    Returns the written paths: "metrics" (JSON), "maps", "path_3d", "metrics_plot" (PNG) and "gif".
    Raises ActionInputError (a ValueError) for bad input, naming the argument.
    """
    if planner not in PLANNERS:
        raise ActionInputError(f"planner: expected one of {sorted(PLANNERS)}, got {planner!r}")
    if not (isinstance(budget_s, (int, float)) and np.isfinite(budget_s) and budget_s > 0):
        raise ActionInputError(f"budget_s: expected a flight budget > 0 s, got {budget_s!r}")
    camera = Camera(*_field_of_view(fov_deg))
    field = make_field(seed, n_people=n_people, obstacles=obstacles, people_region=people_region,
                       start_pose_m=start_pose_m, altitude_limits_m=altitude_limits_m)
    setup = PlanningSetup(
        field, camera, Detector(clutter_rate_per_image=clutter_rate_per_image),
        FlightModel(speed_m_s, acceleration_m_s2, image_rate_hz), tuple(altitude_layers_m),
        lookahead_waypoints=lookahead_waypoints, cma_evaluations=cma_evaluations,
    )
    with _flight_progress(planner, budget_s, progress) as flown:
        log = fly(field, make_planner(planner, setup, seed), budget_s, seed, diagonal=diagonal,
                  charge_planning_time=charge_planning_time, on_image=flown)
    settings = {
        "planner": planner, "seed": seed, "obstacles": obstacles, "people_region": people_region,
        "budget_s": budget_s, "diagonal": diagonal, "altitude_layers_m": list(altitude_layers_m),
        "speed_m_s": speed_m_s, "image_rate_hz": image_rate_hz,
    }
    times = snapshot_times_s if snapshot_times_s is not None else np.linspace(0, budget_s, 4)
    return write_mission(field, log, Path(out_dir), settings, times, gif, progress)


def _field_of_view(fov_deg: Sequence[float]) -> tuple[float, float]:
    """(fov_x, fov_y) in degrees, each in (0, 180), or ActionInputError naming ``fov_deg``."""
    try:
        fov_x, fov_y = (float(v) for v in fov_deg)
    except (TypeError, ValueError):
        raise ActionInputError(f"fov_deg: expected (fov_x, fov_y) in degrees, got {fov_deg!r}") from None
    if not all(np.isfinite(v) and 0 < v < 180 for v in (fov_x, fov_y)):
        raise ActionInputError(f"fov_deg: expected each field of view in (0, 180) degrees, got ({fov_x:g}, {fov_y:g})")
    return fov_x, fov_y


@contextmanager
def _flight_progress(planner: str, budget_s: float, progress: bool):
    """A tqdm bar over the flight budget (hidden unless ``progress``); yields the per-image callback."""
    from tqdm import tqdm

    with tqdm(total=round(float(budget_s), 1), desc=f"{planner} mission", unit="s flown", leave=False,
              disable=not progress, bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s flown [{elapsed}<{remaining}]") as bar:
        def flown(time_s: float) -> None:
            bar.update(round(min(time_s, budget_s) - bar.n, 1))

        yield flown


def write_mission(field, log: EpisodeLog, out: Path, settings: dict, snapshot_times_s: Sequence[float],
                  gif: bool = True, progress: bool = False) -> dict[str, Path]:
    """Write a mission's metrics JSON, map snapshots, 3-D path, metric curves and (with ``gif``)
    animation into ``out`` (created).

    field: the search field; log: the mission's log (with maps); out: output directory;
    settings: the mission's settings (stored in the JSON); snapshot_times_s: times [s] of the map
    snapshots; gif: write the animated GIF; progress: a tqdm bar over the files. Returns the
    written paths by kind ("metrics", "maps", "path_3d", "metrics_plot", "gif")."""
    from tqdm import tqdm

    from attend.action import plots

    out.mkdir(parents=True, exist_ok=True)
    writers = {
        "metrics": lambda: write_metrics_json(log, field, out / "search_metrics.json", settings=settings),
        "maps": lambda: plots.plot_maps(field, log, snapshot_times_s, out / "search_maps.png"),
        "path_3d": lambda: plots.plot_path_3d(field, log, out / "search_path_3d.png"),
        "metrics_plot": lambda: plots.plot_metrics(log, out / "search_metrics.png"),
    }
    if gif:
        writers["gif"] = lambda: plots.write_gif(field, log, out / "search_mission.gif")
    return {name: writers[name]() for name in tqdm(writers, desc="figures", unit="file", leave=False,
                                                    disable=not progress)}


def episode_summary(log: EpisodeLog) -> dict[str, float]:
    """Final values of one mission; log: the mission's log."""
    find_all = log.time_to_find_all_s()
    return {
        "final_rse": float(log.series("rse")[-1]),
        "final_trace": float(log.series("trace")[-1]),
        "people_found": float(log.series("people_found")[-1]),
        "people_total": float(log.people_total),
        "time_to_find_all_s": find_all if np.isfinite(find_all) else None,
        "false_alarm_cells": float(log.series("false_alarm_cells")[-1]),
        "false_alarm_objects": float(log.series("false_alarm_objects")[-1]),
        "images": float(len(log.times_s)),
        "median_planner_time_s": float(np.median(log.planner_times_s)) if log.planner_times_s else 0.0,
    }


def write_metrics_json(log: EpisodeLog, field, path: Path, settings: dict) -> Path:
    """Per-image metrics, the summary and the settings of one mission as JSON.

    log: the mission's log; field: its search field; path: the JSON file written; settings: the
    mission's settings. Returns ``path``."""
    data = {
        "settings": settings,
        "summary": episode_summary(log),
        "per_image": {
            "time_s": log.metric_times_s.tolist(),
            **{key: [float(v) for v in values] for key, values in log.metrics.items()},
            "pose_m": [[0.0, 0.0, 0.0]] + [np.asarray(p).tolist() for p in log.poses_m],
        },
        "planner_times_s": [float(t) for t in log.planner_times_s],
        "waypoints_m": [np.asarray(w).tolist() for w in log.waypoints_m],
        "people_xy_m": [[p.x_m, p.y_m, p.heading_rad] for p in field.people],
    }
    data["per_image"]["pose_m"][0] = list(field.start_pose_m)
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path
