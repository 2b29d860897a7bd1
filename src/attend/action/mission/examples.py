"""Example missions: a random concave area with a hole and a no-fly zone, written as the files a
team would bring (area GeoJSON, no-fly GeoJSON, mission TOML). Used by ``attend plan --example``,
the tests and the benchmarks.

Area: a polygon of ``vertices`` points at random angles around the centre, radii uniform in
[0.55, 1] x size / 2 (concave in general), with an elliptical hole (a pond: not part of the
area) and an elliptical no-fly polygon, each 6-12 % of the size, placed where they fit. Homes:
inside the area, or (``home_outside``) up to 20 % of the size outside it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import shapely

from attend.action.mission.ground import LocalFrame

#: The detector of the example missions (the mission issue's calibration).
EXAMPLE_DETECTOR = {"altitude_m": [15, 30, 45, 60], "detection_probability": [0.95, 0.9, 0.75, 0.55],
                    "false_detections_per_image": [0.02, 0.03, 0.05, 0.08], "position_std_m": 2.0}


def random_area_m(rng: np.random.Generator, size_m: float, vertices: int = 14):
    """(area, no-fly) shapely polygons [m] around (0, 0) (module docstring); rng: the random
    generator; size_m: the area's size [m]; vertices: corners of its outline."""
    for _ in range(100):
        angles = np.sort(rng.uniform(0, 2 * np.pi, vertices))
        radii = size_m / 2 * rng.uniform(0.55, 1.0, vertices)
        outer = shapely.Polygon(np.column_stack([radii * np.cos(angles), radii * np.sin(angles)]))
        if not outer.is_valid:
            continue
        shapes = []
        for _ in range(2):
            a, b = size_m * rng.uniform(0.06, 0.12), size_m * rng.uniform(0.04, 0.08)
            centre = rng.uniform(-0.25, 0.25, 2) * size_m
            t = np.linspace(0, 2 * np.pi, 13)[:-1]
            shapes.append(shapely.Polygon(np.column_stack([centre[0] + a * np.cos(t), centre[1] + b * np.sin(t)])))
        hole, no_fly = shapes
        if not (outer.buffer(-0.05 * size_m).contains(hole) and outer.buffer(-0.05 * size_m).contains(no_fly)
                and hole.distance(no_fly) > 0.03 * size_m):
            continue
        area = shapely.Polygon(outer.exterior.coords, [hole.exterior.coords])
        return area, no_fly
    raise RuntimeError("no random area found in 100 draws")


def write_example_mission(folder, seed: int = 0, size_m: float = 400.0, n_uavs: int = 1, people: float = 5.0,
                          flight_time_s: float = 600.0, cell_size_m: float = 2.0, home_outside: bool = False,
                          lon_lat=None) -> Path:
    """Write area.geojson, no_fly.geojson and mission.toml of a random example into ``folder``;
    returns the mission file's path. seed: draws the area, the homes and (lon_lat None) the
    place on Earth; size_m: the area's size [m]; n_uavs; people: expected number;
    flight_time_s [s]; cell_size_m [m]; home_outside: homes outside the area."""
    rng = np.random.default_rng(seed)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    area, no_fly = random_area_m(rng, size_m)
    lon0, lat0 = lon_lat if lon_lat is not None else (float(rng.uniform(-170, 170)), float(rng.uniform(-60, 60)))
    frame = LocalFrame(lon0, lat0)
    free = area.difference(no_fly).buffer(-0.03 * size_m)
    homes = []
    while len(homes) < n_uavs:
        point = rng.uniform(-size_m / 2, size_m / 2, 2) * (1.4 if home_outside else 1.0)
        here = shapely.Point(point)
        if home_outside:
            if area.contains(here) or no_fly.contains(here) or area.distance(here) > 0.2 * size_m:
                continue
        elif not free.contains(here):
            continue
        homes.append(point)

    def feature(polygon):
        lon_lat = shapely.transform(polygon, lambda xy: np.column_stack(frame.to_lon_lat(xy[:, 0], xy[:, 1])))
        lon_lat = shapely.geometry.polygon.orient(lon_lat, 1.0)
        return {"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {}, "geometry": shapely.geometry.mapping(lon_lat)}]}

    (folder / "area.geojson").write_text(json.dumps(feature(area)))
    (folder / "no_fly.geojson").write_text(json.dumps(feature(no_fly)))
    lines = ["[area]", 'boundary = "area.geojson"', 'exclude = ["no_fly.geojson"]', f"cell_size_m = {cell_size_m!r}", "",
             "[search]", f"people = {float(people)!r}", f"flight_time_s = {float(flight_time_s)!r}", ""]
    for k, home in enumerate(homes):
        lon, lat = frame.to_lon_lat(home[0], home[1])
        lines += ["[[uav]]", f'name = "uav{k + 1}"', f"home = [{float(lon)!r}, {float(lat)!r}]", "speed_m_s = 8.0",
                  "altitude_m = [15.0, 60.0]", "camera_fov_deg = [60.0, 45.0]", "image_interval_s = 2.0", ""]
    lines += ["[detector]"] + [f"{key} = {json.dumps(value)}" for key, value in EXAMPLE_DETECTOR.items()]
    path = folder / "mission.toml"
    path.write_text("\n".join(lines) + "\n")
    return path
