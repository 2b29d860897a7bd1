"""Reading the search area of a field mission from GeoJSON, KML or QGroundControl .plan files.

All polygons come back in lon/lat (WGS84 degrees, x = longitude, y = latitude) as shapely
polygons, holes kept. File order of a position differs by format: GeoJSON and KML write
[lon, lat(, alt)], a QGroundControl .plan writes [lat, lon].

Errors are :class:`MissionInputError` naming the file, the feature (row, 1-based) and what was
expected.
"""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from attend.action.mission.errors import MissionInputError

#: File suffix (lower case) -> format read.
AREA_FILE_SUFFIXES = {".geojson": "geojson", ".json": "geojson", ".kml": "kml", ".plan": "plan"}

#: Vertices of the polygon standing in for a .plan geofence circle.
CIRCLE_VERTICES = 64

#: GeoJSON ``properties.kind`` of the features attend itself writes for paths, homes and targets
#: (see ``plan_files.write_geojson``): skipped when reading, so that file reads back as the area.
SKIPPED_KINDS = frozenset({"flown", "planned", "home", "target"})

#: GeoJSON ``properties.kind`` of a no-fly polygon: read as an exclusion.
NO_FLY_KIND = "no_fly"


@dataclass(frozen=True)
class AreaPolygons:
    """The search area in lon/lat (WGS84 degrees).

    boundary: Polygon or MultiPolygon, the union of the area's polygons, holes kept;
    exclusions: no-fly polygons (the UAVs must not enter them)."""

    boundary: BaseGeometry
    exclusions: tuple[shapely.Polygon, ...] = ()


def read_polygons(path: str | Path) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    """(inclusion polygons, exclusion polygons) in lon/lat degrees from the file at ``path``.

    The format follows the suffix: .geojson/.json GeoJSON (features of properties.kind "no_fly"
    are exclusions; kinds flown/planned/home/target, written by attend, are skipped), .kml KML
    (every Placemark must hold Polygons; all inclusions), .plan QGroundControl geofence
    (polygons and circles by their "inclusion" flag; a circle becomes a 64-gon). Each polygon is checked:
    closed rings (GeoJSON, KML) of at least 4 positions, finite lon/lat within +-180/+-90,
    a valid (not self-intersecting) shape."""
    path = Path(path)
    inclusions, exclusions = _read_any(path)
    if not inclusions and not exclusions:
        kind = AREA_FILE_SUFFIXES[path.suffix.lower()]
        expected = {
            "geojson": "a Polygon or MultiPolygon feature",
            "kml": "a Placemark with a Polygon",
            "plan": "a geoFence polygon or circle",
        }[kind]
        raise MissionInputError(f"no polygon found (empty area): expected at least {expected}", file=path)
    return inclusions, exclusions


def read_area(boundary_path: str | Path, exclude_paths: Iterable[str | Path] = ()) -> AreaPolygons:
    """The search area: the union of the inclusion polygons of ``boundary_path`` (for a .plan
    its inclusion geofence polygons and circles) as the boundary; as exclusions the boundary
    file's exclusion polygons (.plan exclusion fences, GeoJSON kind "no_fly") and every polygon
    of each file in ``exclude_paths``. All in lon/lat WGS84 degrees."""
    boundary_path = Path(boundary_path)
    if boundary_path.suffix.lower() == ".plan":
        inclusions, exclusions = _read_any(boundary_path)
        if not inclusions:
            raise MissionInputError('no inclusion geofence: expected at least one geoFence polygon or circle with '
                                    '"inclusion": true to bound the search area', file=boundary_path)
    else:
        inclusions, exclusions = read_polygons(boundary_path)
        if not inclusions:
            raise MissionInputError('no area polygon, only no-fly polygons: expected at least one polygon '
                                    'whose properties.kind is not "no_fly"', file=boundary_path)
    exclusions = list(exclusions)
    for exclude_path in ([exclude_paths] if isinstance(exclude_paths, (str, Path)) else exclude_paths):
        more_inclusions, more_exclusions = read_polygons(exclude_path)
        exclusions.extend(more_inclusions)
        exclusions.extend(more_exclusions)
    boundary = inclusions[0] if len(inclusions) == 1 else shapely.union_all(inclusions)
    return AreaPolygons(boundary=boundary, exclusions=tuple(exclusions))


def metres_per_degree(lat_deg: float) -> tuple[float, float]:
    """(metres per degree of longitude, metres per degree of latitude) at latitude ``lat_deg``
    [deg] on the WGS84 ellipsoid (series expansion, good to ~1 cm per degree)."""
    phi = math.radians(lat_deg)
    per_lat = 111132.92 - 559.82 * math.cos(2 * phi) + 1.175 * math.cos(4 * phi) - 0.0023 * math.cos(6 * phi)
    per_lon = 111412.84 * math.cos(phi) - 93.5 * math.cos(3 * phi) + 0.118 * math.cos(5 * phi)
    return per_lon, per_lat


def circle_polygon(center_lon: float, center_lat: float, radius_m: float, inclusion: bool = True,
                   vertices: int = CIRCLE_VERTICES) -> shapely.Polygon:
    """A ``vertices``-gon in lon/lat standing in for the circle of ``radius_m`` [m] around
    (``center_lon``, ``center_lat``) [deg], radius converted with the local metres per degree.
    On the safe side: for an ``inclusion`` circle the vertices lie on the circle (the polygon is
    inside it), for an exclusion they lie at radius / cos(pi / vertices) (the polygon covers it)."""
    if not inclusion:
        radius_m = radius_m / math.cos(math.pi / vertices)
    per_lon, per_lat = metres_per_degree(center_lat)
    bearings = np.linspace(0.0, 2 * np.pi, vertices, endpoint=False)
    lons = center_lon + radius_m * np.sin(bearings) / per_lon
    lats = center_lat + radius_m * np.cos(bearings) / per_lat
    return shapely.Polygon(np.column_stack([lons, lats]))


# ---------------------------------------------------------------------------------------------
# Reading the files


def _read_any(path: Path) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    """(inclusions, exclusions) of the file at ``path`` by its suffix; empty lists allowed."""
    kind = AREA_FILE_SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise MissionInputError(
            f"unknown area file type {path.suffix or '(no suffix)'!r}: expected .geojson, .json, .kml or .plan",
            file=path)
    if kind == "geojson":
        return _read_geojson(path)
    if kind == "kml":
        return _read_kml(path), []
    return _read_plan(path)


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise MissionInputError("file not found: expected an area file (GeoJSON, KML or .plan)", file=path) from None
    except IsADirectoryError:
        raise MissionInputError("is a directory: expected an area file (GeoJSON, KML or .plan)", file=path) from None
    except OSError as error:
        raise MissionInputError(f"cannot read the file ({error.strerror or error})", file=path) from None


def _read_json(path: Path):
    data = _read_bytes(path)
    try:
        return json.loads(data)
    except UnicodeDecodeError:
        raise MissionInputError("not UTF-8 text: expected a JSON file", file=path) from None
    except json.JSONDecodeError as error:
        raise MissionInputError(
            f"not valid JSON (line {error.lineno}, column {error.colno}: {error.msg})", file=path) from None


def _read_geojson(path: Path) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("type"), str):
        raise MissionInputError(
            'not GeoJSON: expected a JSON object with "type" FeatureCollection, Feature, Polygon or MultiPolygon',
            file=path)
    _check_geojson_crs(data, path)
    kind = data["type"]
    if kind == "FeatureCollection":
        features = data.get("features")
        if not isinstance(features, list):
            raise MissionInputError('FeatureCollection without a "features" list: expected "features": [...]',
                                    file=path)
    elif kind == "Feature":
        features = [data]
    else:
        features = [{"type": "Feature", "geometry": data, "properties": None}]
    inclusions: list[shapely.Polygon] = []
    exclusions: list[shapely.Polygon] = []
    for number, feature in enumerate(features, start=1):
        if not isinstance(feature, dict) or feature.get("type") != "Feature":
            raise MissionInputError(f'feature {number}: expected an object with "type": "Feature"',
                                    file=path, row=number)
        properties = feature.get("properties")
        feature_kind = properties.get("kind") if isinstance(properties, dict) else None
        if feature_kind in SKIPPED_KINDS:
            continue
        polygons = _geojson_geometry_polygons(feature.get("geometry"), path, number)
        (exclusions if feature_kind == NO_FLY_KIND else inclusions).extend(polygons)
    return inclusions, exclusions


def _check_geojson_crs(data: dict, path: Path) -> None:
    """An old-style (2008) "crs" member must name lon/lat WGS84 (RFC 7946 has no other CRS)."""
    crs = data.get("crs")
    if crs is None:
        return
    name = ""
    if isinstance(crs, dict) and isinstance(crs.get("properties"), dict):
        name = str(crs["properties"].get("name", ""))
    if not re.search(r"CRS84|EPSG:+4326$|EPSG::4326", name, flags=re.IGNORECASE):
        raise MissionInputError(
            f"crs {name or crs!r} is not lon/lat: expected lon/lat WGS84 degrees (RFC 7946, no crs member); "
            "reproject the file to EPSG:4326", file=path)


def _geojson_geometry_polygons(geometry, path: Path, number: int) -> list[shapely.Polygon]:
    if not isinstance(geometry, dict):
        raise MissionInputError(f"feature {number} has no geometry: expected a Polygon or MultiPolygon",
                                file=path, row=number)
    kind = geometry.get("type")
    coordinates = geometry.get("coordinates")
    if kind == "Polygon":
        return [_geojson_polygon(coordinates, path, number, f"feature {number} (Polygon)")]
    if kind == "MultiPolygon":
        if not isinstance(coordinates, list) or not coordinates:
            raise MissionInputError(
                f"feature {number} (MultiPolygon): expected coordinates as a non-empty list of polygons",
                file=path, row=number)
        return [_geojson_polygon(part, path, number, f"feature {number} (MultiPolygon part {index})")
                for index, part in enumerate(coordinates, start=1)]
    raise MissionInputError(
        f"feature {number} has geometry type {kind!r}: expected a Polygon or MultiPolygon", file=path, row=number)


def _geojson_polygon(rings, path: Path, number: int, label: str) -> shapely.Polygon:
    if not isinstance(rings, list) or not rings:
        raise MissionInputError(f"{label}: expected coordinates as a non-empty list of rings of [lon, lat] positions",
                                file=path, row=number)
    arrays = []
    for ring_number, ring in enumerate(rings, start=1):
        ring_label = f"{label}, {_ring_name(ring_number)}"
        positions = _numeric_positions(ring, path, number, ring_label, "[lon, lat] or [lon, lat, alt]")
        arrays.append(_checked_ring(positions, path, number, ring_label, closed=True))
    return _valid_polygon(arrays[0], arrays[1:], path, number, label)


def _read_kml(path: Path) -> list[shapely.Polygon]:
    data = _read_bytes(path)
    try:
        root = ElementTree.fromstring(data)
    except ElementTree.ParseError as error:
        line, column = error.position
        raise MissionInputError(f"not valid XML (line {line}, column {column + 1}): expected a KML file",
                                file=path) from None
    polygons = []
    placemarks = [element for element in root.iter() if _local_name(element) == "Placemark"]
    for number, placemark in enumerate(placemarks, start=1):
        name = _child_text(placemark, "name")
        label = f"Placemark {number}" + (f" ({name!r})" if name else "")
        geometries = _kml_geometries(placemark)
        if not geometries:
            raise MissionInputError(f"{label} has no geometry: expected a Polygon", file=path, row=number)
        for geometry in geometries:
            kind = _local_name(geometry)
            if kind != "Polygon":
                raise MissionInputError(f"{label} has a {kind}: expected a Polygon or a MultiGeometry of Polygons",
                                        file=path, row=number)
            polygons.append(_kml_polygon(geometry, path, number, label))
    return polygons


_KML_GEOMETRIES = {"Point", "LineString", "LinearRing", "Polygon", "Model", "Track", "MultiTrack"}


def _kml_geometries(element) -> list:
    """The geometries of a Placemark, MultiGeometry unpacked (in document order)."""
    found = []
    for child in element:
        kind = _local_name(child)
        if kind == "MultiGeometry":
            found.extend(_kml_geometries(child))
        elif kind in _KML_GEOMETRIES:
            found.append(child)
    return found


def _kml_polygon(polygon, path: Path, number: int, label: str) -> shapely.Polygon:
    outer = [child for child in polygon if _local_name(child) == "outerBoundaryIs"]
    inner = [child for child in polygon if _local_name(child) == "innerBoundaryIs"]
    if len(outer) != 1:
        raise MissionInputError(f"{label}: a Polygon has {len(outer)} outerBoundaryIs: expected exactly one",
                                file=path, row=number)
    arrays = []
    for ring_number, boundary in enumerate(outer + inner, start=1):
        ring_label = f"{label}, {_ring_name(ring_number)}"
        rings = [child for child in boundary if _local_name(child) == "LinearRing"]
        coordinates = [child for child in rings[0] if _local_name(child) == "coordinates"] if rings else []
        if not coordinates:
            raise MissionInputError(f"{ring_label}: expected a LinearRing with coordinates \"lon,lat[,alt] ...\"",
                                    file=path, row=number)
        positions = _kml_positions(coordinates[0].text or "", path, number, ring_label)
        arrays.append(_checked_ring(positions, path, number, ring_label, closed=True))
    return _valid_polygon(arrays[0], arrays[1:], path, number, label)


def _kml_positions(text: str, path: Path, number: int, label: str) -> list[list[float]]:
    positions = []
    for index, token in enumerate(text.split(), start=1):
        parts = token.split(",")
        try:
            values = [float(part) for part in parts]
        except ValueError:
            values = []
        if len(values) not in (2, 3):
            raise MissionInputError(
                f"{label}, position {index}: {token!r} is not a coordinate tuple: expected lon,lat or lon,lat,alt "
                "(tuples separated by spaces, no spaces inside a tuple)", file=path, row=number)
        if not all(math.isfinite(value) for value in values):
            raise MissionInputError(f"{label}, position {index}: {token!r} holds a value that is not a finite number: "
                                    "expected lon,lat or lon,lat,alt", file=path, row=number)
        positions.append(values)
    return positions


def _read_plan(path: Path) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    data = _read_json(path)
    if not isinstance(data, dict) or data.get("fileType") != "Plan":
        raise MissionInputError('not a QGroundControl plan: expected a JSON object with "fileType": "Plan"', file=path)
    fence = data.get("geoFence")
    if fence is None:
        return [], []
    if not isinstance(fence, dict):
        raise MissionInputError("geoFence: expected an object with polygons and circles", file=path)
    inclusions: list[shapely.Polygon] = []
    exclusions: list[shapely.Polygon] = []
    if "polygon" in fence:  # geoFence version 1: one inclusion polygon
        entries = [{"inclusion": True, "polygon": fence["polygon"]}]
        inclusions.extend(_plan_polygons(entries, path, "geoFence.polygon")[0])
    included, excluded = _plan_polygons(_plan_list(fence, "polygons", path), path, "geoFence.polygons")
    inclusions += included
    exclusions += excluded
    included, excluded = _plan_circles(_plan_list(fence, "circles", path), path)
    inclusions += included
    exclusions += excluded
    return inclusions, exclusions


def _plan_list(fence: dict, key: str, path: Path) -> list:
    entries = fence.get(key, [])
    if not isinstance(entries, list):
        raise MissionInputError(f"expected a list, got {type(entries).__name__}", file=path, column=f"geoFence.{key}")
    return entries


def _plan_inclusion(entry: dict, path: Path, number: int, column: str, label: str) -> bool:
    inclusion = entry.get("inclusion", True)
    if not isinstance(inclusion, bool):
        raise MissionInputError(f"{label}: \"inclusion\" is {inclusion!r}: expected true or false",
                                file=path, row=number, column=column)
    return inclusion


def _plan_polygons(entries: list, path: Path, column: str) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    inclusions, exclusions = [], []
    for number, entry in enumerate(entries, start=1):
        label = f"geofence polygon {number}"
        if not isinstance(entry, dict) or "polygon" not in entry:
            raise MissionInputError(f'{label}: expected an object with "polygon": [[lat, lon], ...] and "inclusion"',
                                    file=path, row=number, column=column)
        inclusion = _plan_inclusion(entry, path, number, column, label)
        lat_lon = _numeric_positions(entry["polygon"], path, number, label, "[lat, lon]", column=column)
        lon_lat = [[position[1], position[0]] for position in lat_lon]
        if len(lon_lat) >= 2 and lon_lat[0] == lon_lat[-1]:
            lon_lat = lon_lat[:-1]
        if len(lon_lat) < 3:
            raise MissionInputError(f"{label} has {len(lon_lat)} distinct vertices: expected at least 3",
                                    file=path, row=number, column=column)
        lon_lat.append(lon_lat[0])  # QGroundControl writes open rings
        ring = _checked_ring(lon_lat, path, number, label, closed=True, order="[lat, lon]", column=column)
        polygon = _valid_polygon(ring, [], path, number, label, column=column)
        (inclusions if inclusion else exclusions).append(polygon)
    return inclusions, exclusions


def _plan_circles(entries: list, path: Path) -> tuple[list[shapely.Polygon], list[shapely.Polygon]]:
    inclusions, exclusions = [], []
    column = "geoFence.circles"
    for number, entry in enumerate(entries, start=1):
        label = f"geofence circle {number}"
        circle = entry.get("circle") if isinstance(entry, dict) else None
        if not isinstance(circle, dict) or "center" not in circle or "radius" not in circle:
            raise MissionInputError(
                f'{label}: expected an object with "circle": {{"center": [lat, lon], "radius": metres}} and "inclusion"',
                file=path, row=number, column=column)
        inclusion = _plan_inclusion(entry, path, number, column, label)
        center = _numeric_positions([circle["center"]], path, number, f"{label} center", "[lat, lon]",
                                    column=column)[0]
        lat, lon = center[0], center[1]
        _check_lon_lat(np.array([[lon, lat]]), path, number, f"{label} center", "[lat, lon]", column=column)
        radius = circle["radius"]
        if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not math.isfinite(radius) or radius <= 0:
            raise MissionInputError(f"{label}: radius {radius!r}: expected a positive number of metres",
                                    file=path, row=number, column=column)
        polygon = circle_polygon(lon, lat, float(radius), inclusion=inclusion)
        _check_lon_lat(shapely.get_coordinates(polygon), path, number, f"{label} (as a polygon)", "[lat, lon]",
                       column=column)
        (inclusions if inclusion else exclusions).append(polygon)
    return inclusions, exclusions


# ---------------------------------------------------------------------------------------------
# Checking rings and polygons


def _ring_name(ring_number: int) -> str:
    return "exterior ring" if ring_number == 1 else f"hole {ring_number - 1}"


def _numeric_positions(ring, path: Path, number: int, label: str, expected: str,
                       column: str | None = None) -> list[list[float]]:
    """The positions of ``ring`` as lists of floats (2 or 3 numbers each), in file order."""
    if not isinstance(ring, list):
        raise MissionInputError(f"{label}: expected a list of {expected} positions", file=path, row=number, column=column)
    positions = []
    for index, position in enumerate(ring, start=1):
        if (not isinstance(position, list) or len(position) < 2
                or any(isinstance(value, bool) or not isinstance(value, (int, float)) for value in position)):
            raise MissionInputError(f"{label}, position {index}: {position!r}: expected {expected} numbers",
                                    file=path, row=number, column=column)
        try:
            values = [float(value) for value in position]
        except OverflowError:  # an integer beyond float range
            values = [math.inf]
        if not all(math.isfinite(value) for value in values):
            raise MissionInputError(f"{label}, position {index}: {position!r} holds a value that is not a finite number: "
                                    f"expected {expected}",
                                    file=path, row=number, column=column)
        positions.append(values)
    return positions


def _check_lon_lat(lon_lat: np.ndarray, path: Path, number: int, label: str, order: str,
                   column: str | None = None) -> None:
    outside = np.flatnonzero((np.abs(lon_lat[:, 0]) > 180) | (np.abs(lon_lat[:, 1]) > 90))
    if outside.size:
        index = int(outside[0])
        lon, lat = lon_lat[index]
        shown = f"lat {lat:g}, lon {lon:g}" if order.startswith("[lat") else f"lon {lon:g}, lat {lat:g}"
        raise MissionInputError(
            f"{label}, position {index + 1} ({shown}) looks like projected metres, expected lon/lat WGS84 degrees "
            f"(|lon| <= 180, |lat| <= 90, written {order})", file=path, row=number, column=column)


def _checked_ring(positions: Sequence[Sequence[float]], path: Path, number: int, label: str, closed: bool,
                  order: str = "[lon, lat]", column: str | None = None) -> np.ndarray:
    """The ring as a (k, 2) lon/lat array after checking range, closure and length."""
    lon_lat = np.array([position[:2] for position in positions], dtype=float).reshape(-1, 2)
    _check_lon_lat(lon_lat, path, number, label, order, column=column)
    if closed and len(lon_lat) and not np.array_equal(lon_lat[0], lon_lat[-1]):
        raise MissionInputError(
            f"{label} is not closed (first position {lon_lat[0].tolist()} != last {lon_lat[-1].tolist()}): "
            "expected the last position to repeat the first", file=path, row=number, column=column)
    if len(lon_lat) < 4:
        raise MissionInputError(
            f"{label} has {len(lon_lat)} positions, fewer than 4: expected a closed ring of at least 4 positions "
            "(3 corners and the first repeated)", file=path, row=number, column=column)
    return lon_lat


def _valid_polygon(exterior: np.ndarray, holes: list[np.ndarray], path: Path, number: int, label: str,
                   column: str | None = None) -> shapely.Polygon:
    polygon = shapely.Polygon(exterior, holes)
    if shapely.is_valid(polygon):
        return polygon
    reason = shapely.is_valid_reason(polygon)
    match = re.match(r"^(.*?)\s*\[\s*([-+\d.eE]+)\s+([-+\d.eE]+)\s*\]\s*$", reason)
    if match:
        what, x, y = match.group(1), float(match.group(2)), float(match.group(3))
        where = f"{what} at lon {x:.9g}, lat {y:.9g}"
    else:
        where = reason
    kind = "a self-intersecting" if "self-intersection" in reason.lower() else "an invalid"
    raise MissionInputError(
        f"{label} is {kind} polygon ({where}): expected a simple polygon whose edges do not cross and whose "
        "holes lie inside its exterior ring", file=path, row=number, column=column)


def _local_name(element) -> str:
    tag = element.tag
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def _child_text(element, name: str) -> str:
    for child in element:
        if _local_name(child) == name:
            return (child.text or "").strip()
    return ""
