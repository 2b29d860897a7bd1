"""The files ``attend plan`` writes: the plan for the autopilots, the likely people, the map.

    plan.csv        uav,seq,t_s,lon,lat,alt_m   every UAV's next waypoints (t_s: planned arrival [s]
                                                since mission start; alt_m above home)
    plan.plan       QGroundControl mission (plan_<uav>.plan per UAV when there are several)
    plan.waypoints  QGC WPL 110 text (plan_<uav>.waypoints per UAV when there are several)
    plan.geojson    the area, the no-fly zones, the flown and planned paths, the homes, the targets
    targets.csv     lon,lat,probability,detections  one row per likely person, most probable first
    map.png         P(person) over the area with the paths and targets (metres, scale bar)
    map.tif         GeoTIFF of P(person) (needs rasterio: ``pip install "attend[geotiff]"``)
    summary.json    times per UAV, expected people found, P(all found), area covered, planner time

Atomic: everything is written to a new folder beside DIR, then moved into DIR file by file; an
error before that leaves DIR as it was.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
from attend.action.log_odds import logistic

from attend.action.mission.map_painter import MapPainter
from attend.action.mission.plan_files import fence_rings, write_geojson, write_qgc_plan, write_wpl

#: Files of a previous call that a new call replaces or removes.
OUTPUT_GLOBS = ("plan.csv", "plan.plan", "plan_*.plan", "plan.waypoints", "plan_*.waypoints", "plan.geojson",
                "targets.csv", "map.png", "map.tif", "summary.json")


def write_outputs(mission, plans, out_dir, plot: bool = True, extra: dict | None = None, painter=None) -> list[Path]:
    """Write the files of the module docstring for ``mission`` and its ``plans`` into ``out_dir``
    (created if needed); plot: write map.png; extra: more files {name: text} (e.g. logs of a
    simulated mission); painter: a :class:`~attend.action.mission.map_painter.MapPainter` that
    draws map.png in another process while the other files are written (None: drawn here).
    Returns the paths written."""
    out = Path(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        names = _write_all(mission, plans, staging, plot, painter)
        for name, text in (extra or {}).items():
            (staging / name).write_text(text)
            names.append(name)
        out.mkdir(parents=True, exist_ok=True)
        for old in OUTPUT_GLOBS:
            for path in out.glob(old):
                if path.name not in names:
                    path.unlink()
        written = []
        for name in names:
            os.replace(staging / name, out / name)
            written.append(out / name)
        return written
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _write_all(mission, plans, folder: Path, plot: bool, painter) -> list[str]:
    summary = mission.summary(plans)
    # the map files first, so that another process writes them while the rest is written here
    grid = mission.ground.grid
    probability = np.where(mission.ground.searchable, logistic(mission.belief.log_odds), np.nan)
    jobs = [("tif", (probability, grid.origin_m, grid.cell_size_m, mission.ground.frame.crs.to_wkt()),
             folder / "map.tif")]
    if plot:
        from attend.action.mission.map_plot import map_picture

        jobs.append(("png", map_picture(mission, plans, summary), folder / "map.png"))
    painter = painter if painter is not None else MapPainter(enabled=False)
    painter.submit(jobs)
    frame = mission.ground.frame
    config = mission.config
    names = []
    # plan.csv
    with open(folder / "plan.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["uav", "seq", "t_s", "lon", "lat", "alt_m"])
        for plan in plans:
            lon, lat = frame.to_lon_lat(plan.waypoints[:, 0], plan.waypoints[:, 1])
            for seq, (row, a, b) in enumerate(zip(plan.waypoints, lon, lat), start=1):
                writer.writerow([plan.name, seq, f"{row[3]:.3f}", f"{a:.9f}", f"{b:.9f}", f"{row[2]:.3f}"])
    names.append("plan.csv")
    # autopilot files
    inclusion, exclusion = fence_rings(mission.area)
    several = len(plans) > 1
    for k, plan in enumerate(plans):
        uav = config.uavs[k]
        lon, lat = frame.to_lon_lat(plan.waypoints[:, 0], plan.waypoints[:, 1])
        points = np.column_stack([lon, lat, plan.waypoints[:, 2]]).reshape(-1, 3)
        if len(points) == 0:  # nothing left to fly: hold where the UAV is, then return home
            lon, lat = frame.to_lon_lat(plan.start[0], plan.start[1])
            points = np.array([[float(lon), float(lat), plan.start[2]]])
        home = (uav.home[0], uav.home[1], 0.0)
        stem = f"plan_{uav.name}" if several else "plan"
        write_qgc_plan(folder / f"{stem}.plan", home, points, uav.speed_m_s, inclusion, exclusion)
        write_wpl(folder / f"{stem}.waypoints", home, points, uav.speed_m_s)
        names += [f"{stem}.plan", f"{stem}.waypoints"]
    # targets
    positions, masses, counts, _ = mission.targets()
    t_lon, t_lat = frame.to_lon_lat(positions[:, 0], positions[:, 1]) if len(positions) else (np.zeros(0), np.zeros(0))
    with open(folder / "targets.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["lon", "lat", "probability", "detections"])
        for a, b, p, c in zip(t_lon, t_lat, masses, counts):
            writer.writerow([f"{a:.9f}", f"{b:.9f}", f"{p:.4f}", int(c)])
    names.append("targets.csv")
    # geojson
    flown, planned, homes = {}, {}, {}
    for k, (uav, path) in enumerate(zip(config.uavs, mission.flown_paths_m())):
        lon, lat = frame.to_lon_lat(path[:, 0], path[:, 1])
        flown[uav.name] = np.column_stack([lon, lat, path[:, 2]])
        plan = plans[k]
        route = np.vstack([plan.start[None, :3], plan.waypoints[:, :3]])
        lon, lat = frame.to_lon_lat(route[:, 0], route[:, 1])
        planned[uav.name] = np.column_stack([lon, lat, route[:, 2]])
        homes[uav.name] = uav.home
    targets = np.column_stack([t_lon, t_lat, masses, counts]) if len(positions) else None
    write_geojson(folder / "plan.geojson", mission.area, flown, planned, targets, homes)
    names.append("plan.geojson")
    # map.tif, map.png and summary
    for name, error in painter.wait().items():
        if error is None:
            names.append(name)
        elif name == "map.tif" and "rasterio" in error:  # the optional GeoTIFF extra is not installed
            summary["map_tif"] = f"not written: {error.split(': ', 1)[-1]}"
        else:
            raise RuntimeError(f"{name} could not be written: {error}")
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    names.append("summary.json")
    return names
