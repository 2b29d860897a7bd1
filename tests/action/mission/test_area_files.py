"""Reading the search area: GeoJSON, KML and QGroundControl .plan give the same lon/lat polygons;
every bad file raises MissionInputError naming the file and the problem."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely
from pyproj import Geod

from attend.action.mission.area_files import AreaPolygons, read_area, read_polygons
from attend.action.mission.errors import MissionInputError

# A concave area (a notch in the north edge) with a square hole, near Delft; [lon, lat], closed.
EXTERIOR = [[4.3700, 51.9800], [4.3780, 51.9800], [4.3780, 51.9850], [4.3740, 51.9830], [4.3700, 51.9850],
            [4.3700, 51.9800]]
HOLE = [[4.3760, 51.9805], [4.3760, 51.9815], [4.3770, 51.9815], [4.3770, 51.9805], [4.3760, 51.9805]]
EXPECTED = shapely.Polygon(EXTERIOR, [HOLE])
# A second, disjoint square to the east.
SQUARE = [[4.3800, 51.9800], [4.3820, 51.9800], [4.3820, 51.9820], [4.3800, 51.9820], [4.3800, 51.9800]]
BOWTIE = [[4.370, 51.980], [4.372, 51.982], [4.372, 51.980], [4.370, 51.982], [4.370, 51.980]]

WGS84 = Geod(ellps="WGS84")


def same_shape(a, b, tolerance_deg2: float = 1e-14) -> bool:
    return shapely.symmetric_difference(a, b).area < tolerance_deg2


def geojson_polygon(*rings) -> dict:
    return {"type": "Polygon", "coordinates": [list(ring) for ring in rings]}


def feature_collection(*geometries, kinds=()) -> dict:
    kinds = list(kinds) + [None] * (len(geometries) - len(kinds))
    return {"type": "FeatureCollection",
            "features": [{"type": "Feature", "properties": {"kind": kind} if kind else {}, "geometry": geometry}
                         for geometry, kind in zip(geometries, kinds)]}


def kml_coordinates(ring) -> str:
    return " ".join(f"{lon},{lat},0" for lon, lat in ring)


def kml_polygon(exterior, *holes) -> str:
    inner = "".join(f"<innerBoundaryIs><LinearRing><coordinates>{kml_coordinates(hole)}</coordinates>"
                    "</LinearRing></innerBoundaryIs>" for hole in holes)
    return (f"<Polygon><outerBoundaryIs><LinearRing><coordinates>\n{kml_coordinates(exterior)}\n</coordinates>"
            f"</LinearRing></outerBoundaryIs>{inner}</Polygon>")


def kml_document(*placemark_bodies) -> str:
    placemarks = "".join(f"<Placemark><name>part {number}</name>{body}</Placemark>"
                         for number, body in enumerate(placemark_bodies, start=1))
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<kml xmlns="http://www.opengis.net/kml/2.2">'
            f"<Document>{placemarks}</Document></kml>\n")


def plan_document(polygons=(), circles=()) -> dict:
    """A QGroundControl plan whose geofence has ``polygons`` ((inclusion, [lon, lat] ring) pairs,
    written [lat, lon] and open as QGroundControl does) and ``circles`` ((inclusion, lon, lat, radius_m))."""
    return {
        "fileType": "Plan",
        "geoFence": {
            "circles": [{"circle": {"center": [lat, lon], "radius": radius}, "inclusion": inclusion, "version": 1}
                        for inclusion, lon, lat, radius in circles],
            "polygons": [{"inclusion": inclusion, "polygon": [[lat, lon] for lon, lat in ring[:-1]], "version": 1}
                         for inclusion, ring in polygons],
            "version": 2,
        },
        "groundStation": "QGroundControl",
        "mission": {"items": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "version": 1,
    }


def write(path, content) -> str:
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return str(path)


def test_geojson_kml_and_plan_read_to_the_same_polygon(tmp_path):
    geojson = write(tmp_path / "area.geojson", feature_collection(geojson_polygon(EXTERIOR, HOLE)))
    kml = write(tmp_path / "area.kml", kml_document(kml_polygon(EXTERIOR, HOLE)))
    plan = write(tmp_path / "area.plan", plan_document([(True, EXTERIOR), (False, HOLE)]))

    for path in (geojson, kml):
        inclusions, exclusions = read_polygons(path)
        assert len(inclusions) == 1 and exclusions == []
        assert len(inclusions[0].interiors) == 1
        assert same_shape(inclusions[0], EXPECTED)
        area = read_area(path)
        assert isinstance(area, AreaPolygons) and same_shape(area.boundary, EXPECTED) and area.exclusions == ()

    area = read_area(plan)
    assert same_shape(area.boundary, shapely.Polygon(EXTERIOR))
    assert len(area.exclusions) == 1 and same_shape(area.exclusions[0], shapely.Polygon(HOLE))
    assert same_shape(area.boundary.difference(area.exclusions[0]), EXPECTED)
    # .plan positions are [lat, lon]: the polygon must come back at lon 4.37, lat 51.98
    minx, miny, maxx, maxy = area.boundary.bounds
    assert (minx, miny, maxx, maxy) == pytest.approx((4.370, 51.980, 4.378, 51.985))


def test_geojson_feature_bare_geometry_and_altitudes(tmp_path):
    with_altitude = [[lon, lat, 12.5] for lon, lat in EXTERIOR]
    feature = {"type": "Feature", "properties": None, "geometry": geojson_polygon(with_altitude, HOLE)}
    for name, content in (("feature.geojson", feature), ("bare.json", geojson_polygon(EXTERIOR, HOLE))):
        (polygon,), _ = read_polygons(write(tmp_path / name, content))
        assert not polygon.has_z and same_shape(polygon, EXPECTED)


def test_multipolygon_unions_to_a_multipolygon_area(tmp_path):
    multi = {"type": "MultiPolygon", "coordinates": [[EXTERIOR, HOLE], [SQUARE]]}
    geojson = write(tmp_path / "multi.geojson", feature_collection(multi))
    kml = write(tmp_path / "multi.kml",
                kml_document(f"<MultiGeometry>{kml_polygon(EXTERIOR, HOLE)}{kml_polygon(SQUARE)}</MultiGeometry>"))
    expected = shapely.MultiPolygon([EXPECTED, shapely.Polygon(SQUARE)])
    for path in (geojson, kml):
        inclusions, _ = read_polygons(path)
        assert len(inclusions) == 2
        area = read_area(path)
        assert area.boundary.geom_type == "MultiPolygon" and len(area.boundary.geoms) == 2
        assert same_shape(area.boundary, expected)


def test_plan_circles_become_64_gons_of_the_radius_in_metres(tmp_path):
    lon, lat = 4.3740, 51.9825
    plan = write(tmp_path / "circles.plan", plan_document(circles=[(True, lon, lat, 200.0), (False, lon, lat, 50.0)]))
    area = read_area(plan)
    inside = np.asarray(area.boundary.exterior.coords)[:-1]
    outside = np.asarray(area.exclusions[0].exterior.coords)[:-1]
    assert len(inside) == len(outside) == 64
    _, _, inside_m = WGS84.inv(np.full(64, lon), np.full(64, lat), inside[:, 0], inside[:, 1])
    _, _, outside_m = WGS84.inv(np.full(64, lon), np.full(64, lat), outside[:, 0], outside[:, 1])
    # inclusion: vertices on the circle (the fence polygon lies inside it)
    np.testing.assert_allclose(inside_m, 200.0, atol=0.05)
    # exclusion: vertices outside, so the polygon covers the whole no-fly circle
    np.testing.assert_allclose(outside_m, 50.0 / math.cos(math.pi / 64), atol=0.02)
    area_m2, _ = WGS84.geometry_area_perimeter(area.boundary)
    assert abs(area_m2) == pytest.approx(32 * 200.0**2 * math.sin(2 * math.pi / 64), rel=1e-3)


def test_exclusions_from_the_boundary_file_and_the_exclude_files(tmp_path):
    boundary = write(tmp_path / "area.geojson",
                     feature_collection(geojson_polygon(EXTERIOR), geojson_polygon(HOLE), kinds=[None, "no_fly"]))
    exclude_kml = write(tmp_path / "nofly.kml", kml_document(kml_polygon(SQUARE)))
    # a .plan given as an exclude file: all its polygons and circles are exclusions
    exclude_plan = write(tmp_path / "nofly.plan",
                         plan_document([(True, SQUARE), (False, HOLE)], circles=[(True, 4.372, 51.981, 20.0)]))
    area = read_area(boundary, [exclude_kml, exclude_plan])
    assert same_shape(area.boundary, shapely.Polygon(EXTERIOR))
    assert len(area.exclusions) == 5
    assert same_shape(area.exclusions[0], shapely.Polygon(HOLE))
    assert same_shape(area.exclusions[1], shapely.Polygon(SQUARE))
    assert read_area(boundary, exclude_kml).exclusions[1:] == (area.exclusions[1],)


def test_plan_without_inclusion_geofence(tmp_path):
    only_exclusion = write(tmp_path / "fence.plan", plan_document([(False, EXTERIOR)]))
    no_fence = write(tmp_path / "nofence.plan", plan_document())
    for path in (only_exclusion, no_fence):
        with pytest.raises(MissionInputError, match="no inclusion geofence") as caught:
            read_area(path)
        assert path in str(caught.value)
    # as an exclude file the exclusion-only plan is fine
    assert len(read_polygons(only_exclusion)[1]) == 1


def open_ring(ring):
    return ring[:-1]


PROJECTED = [[85000.0, 445000.0], [85500.0, 445000.0], [85500.0, 445500.0], [85000.0, 445000.0]]
NAN_RING = [[4.37, 51.98], [float("nan"), 51.98], [4.38, 51.99], [4.37, 51.98]]

BAD_FILES = [
    # (file name, content or None for a missing file, words the message must contain)
    ("missing.geojson", None, ["not found"]),
    ("broken.geojson", '{"type": "FeatureCollection", "features": [', ["not valid JSON"]),
    ("broken.kml", "<kml><Document><Placemark></Document>", ["not valid XML"]),
    ("broken.plan", "fileType: Plan", ["not valid JSON"]),
    ("empty.geojson", feature_collection(), ["no polygon", "empty"]),
    ("empty.kml", '<kml xmlns="http://www.opengis.net/kml/2.2"><Document/></kml>', ["no polygon", "empty"]),
    ("open.geojson", feature_collection(geojson_polygon(open_ring(EXTERIOR))), ["feature 1", "not closed"]),
    ("open_hole.geojson", feature_collection(geojson_polygon(EXTERIOR, open_ring(HOLE))), ["hole 1", "not closed"]),
    ("open.kml", kml_document(kml_polygon(open_ring(EXTERIOR))), ["Placemark 1", "not closed"]),
    ("short.geojson", feature_collection(geojson_polygon([[4.37, 51.98], [4.38, 51.98], [4.37, 51.98]])),
     ["fewer than 4"]),
    ("short.plan", plan_document([(True, [[4.37, 51.98], [4.38, 51.98], [4.37, 51.98]])]),
     ["geofence polygon 1", "at least 3"]),
    ("bowtie.geojson", feature_collection(geojson_polygon(SQUARE), geojson_polygon(BOWTIE)),
     ["feature 2", "self-intersecting", "lon 4.371, lat 51.981"]),
    ("bowtie.kml", kml_document(kml_polygon(BOWTIE)), ["self-intersecting", "lon 4.371, lat 51.981"]),
    ("bowtie.plan", plan_document([(True, BOWTIE)]), ["geofence polygon 1", "self-intersecting"]),
    ("hole_outside.geojson", feature_collection(geojson_polygon(EXTERIOR, SQUARE)), ["invalid polygon", "Hole"]),
    ("projected.geojson", feature_collection(geojson_polygon(PROJECTED)),
     ["looks like projected metres", "expected lon/lat WGS84 degrees"]),
    ("projected.kml", kml_document(kml_polygon(PROJECTED)), ["looks like projected metres"]),
    ("projected.plan", plan_document([(True, PROJECTED)]), ["looks like projected metres", "[lat, lon]"]),
    ("crs.geojson", {**feature_collection(geojson_polygon(EXTERIOR)),
                     "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::28992"}}},
     ["expected lon/lat WGS84 degrees"]),
    ("nan.geojson", json.dumps(feature_collection(geojson_polygon(NAN_RING))), ["position 2", "not a finite number"]),
    ("nan.kml", kml_document(kml_polygon(NAN_RING)), ["position 2", "not a finite number"]),
    ("text.geojson", feature_collection(geojson_polygon([["4.37", "51.98"]] * 4)), ["expected [lon, lat]"]),
    ("line.geojson", feature_collection(geojson_polygon(EXTERIOR), {"type": "LineString", "coordinates": EXTERIOR}),
     ["feature 2", "LineString", "expected a Polygon or MultiPolygon"]),
    ("point.kml", kml_document(kml_polygon(EXTERIOR), "<Point><coordinates>4.37,51.98</coordinates></Point>"),
     ["Placemark 2", "Point", "expected a Polygon"]),
    ("radius.plan", plan_document(circles=[(True, 4.37, 51.98, -5.0)]), ["geofence circle 1", "positive number"]),
    ("mission.plan", {"fileType": "Mission"}, ['"fileType": "Plan"']),
    ("area.shp", "", ["expected .geojson"]),
]


@pytest.mark.parametrize("name, content, words", BAD_FILES, ids=[name for name, _, _ in BAD_FILES])
def test_bad_area_file_is_named_with_the_problem(tmp_path, name, content, words):
    path = tmp_path / name
    if content is not None:
        write(path, content)
    with pytest.raises(MissionInputError) as caught:
        read_area(path)
    message = str(caught.value)
    assert str(path) in message
    for word in words:
        assert word in message


def test_the_feature_number_is_the_row(tmp_path):
    path = write(tmp_path / "line.geojson",
                 feature_collection(geojson_polygon(EXTERIOR), {"type": "Point", "coordinates": [4.37, 51.98]}))
    with pytest.raises(MissionInputError) as caught:
        read_polygons(path)
    assert caught.value.row == 2 and caught.value.file == path
