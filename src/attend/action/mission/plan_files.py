"""Writing a search plan for the autopilot (QGroundControl .plan, QGC WPL 110) and for GIS
(GeoJSON, GeoTIFF).

Positions are passed in lon/lat (WGS84 degrees); waypoint altitudes in metres above home. The
autopilot files write [lat, lon] (their order); GeoJSON writes [lon, lat]. Every writer is
deterministic: the same input gives the same bytes.

MAVLink numbers used: MAV_CMD_NAV_WAYPOINT 16, MAV_CMD_NAV_RETURN_TO_LAUNCH 20,
MAV_CMD_DO_CHANGE_SPEED 178; MAV_FRAME_GLOBAL 0 (altitude above mean sea level),
MAV_FRAME_MISSION 2 (no position), MAV_FRAME_GLOBAL_RELATIVE_ALT 3 (altitude above home).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
import shapely
from shapely.geometry.polygon import orient

from attend.action.mission.area_files import NO_FLY_KIND, AreaPolygons
from attend.action.mission.errors import MissionInputError

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3

#: MAV_AUTOPILOT_PX4: the .plan is written for PX4 (yaw NaN = keep the heading mode).
FIRMWARE_TYPE_PX4 = 12
#: MAV_TYPE_QUADROTOR.
VEHICLE_TYPE_QUADROTOR = 2
#: QGroundControl AltitudeMode / globalPlanAltitudeMode "relative to home" (MAV_FRAME_GLOBAL_RELATIVE_ALT).
QGC_ALTITUDE_MODE_RELATIVE = 1
#: DO_CHANGE_SPEED param1: 1 = ground speed.
SPEED_TYPE_GROUND = 1

#: Decimal places of a GeoJSON longitude or latitude (1e-9 deg, 0.1 mm) and of an altitude (1 mm).
GEOJSON_DEGREE_DECIMALS = 9
GEOJSON_ALTITUDE_DECIMALS = 3


def write_qgc_plan(path: str | Path, home_lon_lat_alt: tuple[float, float, float], waypoints: np.ndarray,
                   speed_m_s: float, geofence_inclusion: Sequence[np.ndarray] = (),
                   geofence_exclusion: Sequence[np.ndarray] = ()) -> None:
    """Write a QGroundControl plan (JSON, fileType "Plan", version 1) for PX4 (firmwareType 12),
    quadrotor (vehicleType 2) to ``path``.

    home_lon_lat_alt: home lon, lat [deg] and altitude [m above mean sea level], written as
    plannedHomePosition [lat, lon, alt]; waypoints: (w, 3) lon, lat [deg], alt [m above home];
    speed_m_s: ground speed [m/s] (cruiseSpeed, hoverSpeed and a first DO_CHANGE_SPEED item);
    geofence_inclusion, geofence_exclusion: rings as (k, 2) lon/lat [deg] arrays (open or
    closed), written [lat, lon], open, clockwise. Holes of the area must be passed as exclusion
    rings. mission.items: DO_CHANGE_SPEED (178), one NAV_WAYPOINT (16, frame 3, params
    [hold 0, acceptance 0, pass 0, yaw null, lat, lon, alt]) per waypoint, RETURN_TO_LAUNCH (20);
    doJumpId counts from 1."""
    home = _home(home_lon_lat_alt)
    points = _waypoints(waypoints)
    speed = _speed(speed_m_s)
    items = [_qgc_item(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, [SPEED_TYPE_GROUND, speed, -1.0, 0.0, 0.0, 0.0, 0.0])]
    for lon, lat, alt in points:
        item = _qgc_item(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL_RELATIVE_ALT, [0.0, 0.0, 0.0, None, lat, lon, alt])
        item.update({"AMSLAltAboveTerrain": None, "Altitude": alt, "AltitudeMode": QGC_ALTITUDE_MODE_RELATIVE})
        items.append(item)
    items.append(_qgc_item(MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_FRAME_MISSION, [0.0] * 7))
    for jump_id, item in enumerate(items, start=1):
        item["doJumpId"] = jump_id
    fence_polygons = [
        {"inclusion": inclusion, "polygon": _fence_ring(ring, name, index), "version": 1}
        for inclusion, name, rings in ((True, "geofence_inclusion", geofence_inclusion),
                                       (False, "geofence_exclusion", geofence_exclusion))
        for index, ring in enumerate(rings, start=1)
    ]
    plan = {
        "fileType": "Plan",
        "geoFence": {"circles": [], "polygons": fence_polygons, "version": 2},
        "groundStation": "QGroundControl",
        "mission": {
            "cruiseSpeed": speed,
            "firmwareType": FIRMWARE_TYPE_PX4,
            "globalPlanAltitudeMode": QGC_ALTITUDE_MODE_RELATIVE,
            "hoverSpeed": speed,
            "items": items,
            "plannedHomePosition": [home[1], home[0], home[2]],
            "vehicleType": VEHICLE_TYPE_QUADROTOR,
            "version": 2,
        },
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }
    _write_text(path, json.dumps(plan, indent=4, sort_keys=True, allow_nan=False) + "\n")


def fence_rings(area: AreaPolygons) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(inclusion rings, exclusion rings) of ``area`` for :func:`write_qgc_plan`: each (k, 2)
    lon/lat [deg], closed. Inclusions: the exterior ring of every boundary polygon; exclusions:
    the boundary's holes, then the exterior ring of every no-fly polygon."""
    inclusions, exclusions = [], []
    for polygon in _polygons(area.boundary, "area.boundary"):
        inclusions.append(shapely.get_coordinates(polygon.exterior))
        exclusions.extend(shapely.get_coordinates(hole) for hole in polygon.interiors)
    for polygon in area.exclusions:
        exclusions.append(shapely.get_coordinates(polygon.exterior))
    return inclusions, exclusions


def write_wpl(path: str | Path, home_lon_lat_alt: tuple[float, float, float], waypoints: np.ndarray,
              speed_m_s: float) -> None:
    """Write a QGC WPL 110 waypoint file (ArduPilot, Mission Planner, MAVProxy) to ``path``:
    line "QGC WPL 110", then tab-separated rows INDEX CURRENT_WP COORD_FRAME COMMAND PARAM1..4
    LAT LON ALT AUTOCONTINUE. Row 0: home (frame 0, command 16, current 1, altitude [m above
    mean sea level]); row 1: DO_CHANGE_SPEED (178, param1 1 = ground speed, param2 speed
    [m/s]); then a waypoint row (frame 3, command 16, yaw param4 0 = autopilot default) per
    waypoint; last: RETURN_TO_LAUNCH (20).

    home_lon_lat_alt: home lon, lat [deg], altitude [m above mean sea level]; waypoints: (w, 3)
    lon, lat [deg], alt [m above home]; speed_m_s: ground speed [m/s]."""
    home = _home(home_lon_lat_alt)
    points = _waypoints(waypoints)
    speed = _speed(speed_m_s)
    rows = [(1, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, (0.0, 0.0, 0.0, 0.0), home[1], home[0], home[2]),
            (0, MAV_FRAME_MISSION, MAV_CMD_DO_CHANGE_SPEED, (SPEED_TYPE_GROUND, speed, -1.0, 0.0), 0.0, 0.0, 0.0)]
    rows += [(0, MAV_FRAME_GLOBAL_RELATIVE_ALT, MAV_CMD_NAV_WAYPOINT, (0.0, 0.0, 0.0, 0.0), lat, lon, alt)
             for lon, lat, alt in points]
    rows.append((0, MAV_FRAME_MISSION, MAV_CMD_NAV_RETURN_TO_LAUNCH, (0.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0))
    lines = ["QGC WPL 110"]
    for index, (current, frame, command, params, lat, lon, alt) in enumerate(rows):
        fields = [str(index), str(current), str(frame), str(command)]
        fields += [f"{value:.6f}" for value in params]
        fields += [f"{lat:.10f}", f"{lon:.10f}", f"{alt:.6f}", "1"]
        lines.append("\t".join(fields))
    _write_text(path, "\n".join(lines) + "\n")


def write_geojson(path: str | Path, area: AreaPolygons, flown: Mapping[str, np.ndarray],
                  planned: Mapping[str, np.ndarray], targets: np.ndarray | None = None,
                  homes: Mapping[str, tuple[float, float]] = {}) -> None:
    """Write an RFC 7946 FeatureCollection to ``path``, positions [lon, lat] rounded to 1e-9 deg.

    Features in order: the ``area`` boundary (Polygon/MultiPolygon, kind "area"; exterior rings
    counter-clockwise, holes clockwise), each no-fly polygon of ``area`` (kind "no_fly",
    number 1..), then per UAV name (sorted) its ``flown`` and ``planned`` paths ((n, 2) lon, lat
    [deg] or (n, 3) with alt [m above home], rounded to 1 mm; LineString, a one-point path a
    Point; properties uav, kind "flown"/"planned") and its home from ``homes`` (lon, lat [deg];
    kind "home"), then the ``targets`` ((k, 4) lon, lat [deg], probability, detections; Points
    of kind "target", number 1..). No "crs" member."""
    features = [_feature(_polygonal_geometry(area.boundary, "area.boundary"), {"kind": "area"})]
    for number, polygon in enumerate(area.exclusions, start=1):
        features.append(_feature(_polygonal_geometry(polygon, f"area.exclusions[{number - 1}]"),
                                 {"kind": NO_FLY_KIND, "number": number}))
    for uav in sorted(set(flown) | set(planned) | set(homes), key=str):
        for kind, paths in (("flown", flown), ("planned", planned)):
            if uav in paths:
                geometry = _path_geometry(paths[uav], f"{kind}[{uav!r}]")
                if geometry is not None:
                    features.append(_feature(geometry, {"kind": kind, "uav": str(uav)}))
        if uav in homes:
            home = _finite_array(homes[uav], f"homes[{uav!r}]", (2,))
            _check_lon_lat(home[None, :], f"homes[{uav!r}]")
            features.append(_feature({"type": "Point", "coordinates": _position(home)}, {"kind": "home", "uav": str(uav)}))
    if targets is not None:
        table = _finite_array(targets, "targets", (None, 4))
        _check_lon_lat(table[:, :2], "targets")
        for number, (lon, lat, probability, detections) in enumerate(table, start=1):
            properties = {"kind": "target", "number": number, "probability": float(probability),
                          "detections": int(round(detections))}
            features.append(_feature({"type": "Point", "coordinates": _position([lon, lat])}, properties))
    lines = ['{"type": "FeatureCollection", "features": [']
    lines.append(",\n".join(json.dumps(feature, allow_nan=False) for feature in features))
    lines.append("]}")
    _write_text(path, "\n".join(lines) + "\n")


def write_geotiff(path: str | Path, probability: np.ndarray, origin_xy_m: tuple[float, float], cell_size_m: float,
                  crs_wkt: str) -> None:
    """Write P(person) per cell as a north-up float32 single-band GeoTIFF (deflate, nodata NaN)
    to ``path``.

    probability: (ny, nx) map array, row 0 at the south (y grows northwards), NaN outside the
    area; origin_xy_m: (x, y) [m] of its lower-left (south-west) corner in the projected CRS
    ``crs_wkt`` (WKT); cell_size_m: square cell side [m]. Rows are flipped so the file's row 0 is
    the northernmost. Needs rasterio (``pip install "attend[geotiff]"``)."""
    try:
        import rasterio
        from rasterio.crs import CRS
        from rasterio.errors import CRSError
        from rasterio.transform import Affine
    except ImportError:
        raise MissionInputError('writing a GeoTIFF needs rasterio: pip install "attend[geotiff]"', file=path) from None
    grid = np.asarray(probability, dtype=float)
    if grid.ndim != 2 or 0 in grid.shape:
        raise MissionInputError(f"probability: expected a non-empty (ny, nx) array, got shape {grid.shape}", file=path)
    values = grid[np.isfinite(grid)]
    if np.isinf(grid).any() or ((values < 0) | (values > 1)).any():
        raise MissionInputError("probability: expected values in [0, 1], or NaN outside the area", file=path)
    origin = _finite_array(origin_xy_m, "origin_xy_m", (2,))
    cell = float(cell_size_m)
    if not math.isfinite(cell) or cell <= 0:
        raise MissionInputError(f"cell_size_m: expected a positive number of metres, got {cell_size_m!r}", file=path)
    try:
        crs = CRS.from_wkt(crs_wkt)
    except CRSError as error:
        raise MissionInputError(f"crs_wkt: not a coordinate reference system ({error})", file=path) from None
    ny, nx = grid.shape
    north_up = np.ascontiguousarray(grid[::-1], dtype=np.float32)
    transform = Affine(cell, 0.0, origin[0], 0.0, -cell, origin[1] + ny * cell)  # top-left corner, north up
    with rasterio.open(Path(path), "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float32",
                       crs=crs, transform=transform, nodata=float("nan"), compress="deflate") as dataset:
        dataset.write(north_up, 1)
        dataset.set_band_description(1, "P(person)")


# ---------------------------------------------------------------------------------------------
# Helpers


def _write_text(path: str | Path, text: str) -> None:
    Path(path).write_text(text, encoding="utf-8", newline="\n")


def _finite_array(value, name: str, shape: tuple) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None: any length), all finite."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise MissionInputError(f"{name}: expected numbers, got {value!r}") from None
    if array.ndim != len(shape) or any(want is not None and got != want for got, want in zip(array.shape, shape)):
        wanted = "(" + ", ".join("n" if want is None else str(want) for want in shape) + ")"
        raise MissionInputError(f"{name}: expected an array of shape {wanted}, got {array.shape}")
    if not np.isfinite(array).all():
        raise MissionInputError(f"{name}: expected finite numbers, got NaN or infinity")
    return array


def _check_lon_lat(lon_lat: np.ndarray, name: str) -> None:
    outside = np.flatnonzero((np.abs(lon_lat[:, 0]) > 180) | (np.abs(lon_lat[:, 1]) > 90))
    if outside.size:
        lon, lat = lon_lat[outside[0]]
        raise MissionInputError(f"{name}: position {outside[0] + 1} (lon {lon:g}, lat {lat:g}) looks like projected "
                                "metres, expected lon/lat WGS84 degrees")


def _home(home_lon_lat_alt) -> tuple[float, float, float]:
    home = _finite_array(home_lon_lat_alt, "home_lon_lat_alt", (3,))
    _check_lon_lat(home[None, :2], "home_lon_lat_alt")
    return float(home[0]), float(home[1]), float(home[2])


def _waypoints(waypoints) -> list[tuple[float, float, float]]:
    array = _finite_array(waypoints, "waypoints (lon, lat, alt_m)", (None, 3))
    if len(array) == 0:
        raise MissionInputError("waypoints: expected at least one waypoint (lon, lat, alt_m), got none")
    _check_lon_lat(array[:, :2], "waypoints")
    return [(float(lon), float(lat), float(alt)) for lon, lat, alt in array]


def _speed(speed_m_s) -> float:
    speed = float(speed_m_s)
    if not math.isfinite(speed) or speed <= 0:
        raise MissionInputError(f"speed_m_s: expected a positive speed in m/s, got {speed_m_s!r}")
    return speed


def _qgc_item(command: int, frame: int, params: list) -> dict:
    return {"autoContinue": True, "command": command, "doJumpId": 0, "frame": frame,
            "params": [None if value is None else float(value) for value in params], "type": "SimpleItem"}


def _fence_ring(ring, name: str, index: int) -> list[list[float]]:
    """A geofence ring as QGroundControl writes it: [lat, lon] vertices, open, clockwise."""
    lon_lat = _finite_array(ring, f"{name}[{index - 1}]", (None, 2))
    _check_lon_lat(lon_lat, f"{name}[{index - 1}]")
    if len(lon_lat) >= 2 and np.array_equal(lon_lat[0], lon_lat[-1]):
        lon_lat = lon_lat[:-1]
    if len(lon_lat) < 3:
        raise MissionInputError(f"{name}[{index - 1}]: expected a ring of at least 3 vertices, got {len(lon_lat)}")
    if shapely.LinearRing(lon_lat).is_ccw:
        lon_lat = lon_lat[::-1]
    return [[float(lat), float(lon)] for lon, lat in lon_lat]


def _polygons(geometry, name: str) -> list[shapely.Polygon]:
    if isinstance(geometry, shapely.Polygon):
        return [geometry]
    if isinstance(geometry, shapely.MultiPolygon):
        return list(geometry.geoms)
    raise MissionInputError(f"{name}: expected a Polygon or MultiPolygon, got {geometry.geom_type}")


def _position(values) -> list[float]:
    """[lon, lat] rounded to 1e-9 deg, then alt rounded to 1 mm if given."""
    position = [round(float(values[0]), GEOJSON_DEGREE_DECIMALS) + 0.0,
                round(float(values[1]), GEOJSON_DEGREE_DECIMALS) + 0.0]
    if len(values) > 2:
        position.append(round(float(values[2]), GEOJSON_ALTITUDE_DECIMALS) + 0.0)
    return position


def _ring_positions(ring) -> list[list[float]]:
    return [_position(xy) for xy in shapely.get_coordinates(ring)]


def _polygonal_geometry(geometry, name: str) -> dict:
    polygons = [orient(polygon, sign=1.0) for polygon in _polygons(geometry, name)]
    rings = [[_ring_positions(polygon.exterior)] + [_ring_positions(hole) for hole in polygon.interiors]
             for polygon in polygons]
    if isinstance(geometry, shapely.Polygon):
        return {"type": "Polygon", "coordinates": rings[0]}
    return {"type": "MultiPolygon", "coordinates": rings}


def _path_geometry(path_array, name: str) -> dict | None:
    """A LineString, a Point for a one-point path, None for an empty one."""
    if np.size(path_array) == 0:
        return None
    array = _finite_array(path_array, name, (None, None))
    if array.shape[1] not in (2, 3):
        raise MissionInputError(f"{name}: expected an (n, 2) lon, lat or (n, 3) lon, lat, alt array, got {array.shape}")
    _check_lon_lat(array, name)
    if len(array) == 1:
        return {"type": "Point", "coordinates": _position(array[0])}
    return {"type": "LineString", "coordinates": [_position(row) for row in array]}


def _feature(geometry: dict, properties: dict) -> dict:
    return {"type": "Feature", "properties": properties, "geometry": geometry}
