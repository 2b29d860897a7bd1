"""Writing the plan: WPL read back by pymavlink, .plan matching QGroundControl's documented
structure (tests/action/mission/data/qgc_reference.plan), RFC 7946 GeoJSON, north-up GeoTIFF."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from attend.action.mission.area_files import AreaPolygons, read_area, read_polygons
from attend.action.mission.errors import MissionInputError
from attend.action.mission.plan_files import (
    fence_rings,
    write_geojson,
    write_geotiff,
    write_qgc_plan,
    write_wpl,
)

REFERENCE_PLAN = Path(__file__).parent / "data" / "qgc_reference.plan"

HOME = (4.3702145, 51.9801273, -1.25)  # lon, lat [deg], alt [m above mean sea level]
WAYPOINTS = np.array([
    [4.3711111111, 51.9811111111, 30.0],
    [4.3722222222, 51.9812345678, 30.5],
    [4.3733333333, 51.9823456789, 42.125],
    [4.3704444444, 51.9834567890, 30.0],
])
SPEED_M_S = 5.5

# Area: a concave polygon with a hole and a second square; one no-fly polygon.
EXTERIOR = [[4.3700, 51.9800], [4.3780, 51.9800], [4.3780, 51.9850], [4.3740, 51.9830], [4.3700, 51.9850],
            [4.3700, 51.9800]]
HOLE = [[4.3760, 51.9805], [4.3760, 51.9815], [4.3770, 51.9815], [4.3770, 51.9805], [4.3760, 51.9805]]
SQUARE = [[4.3800, 51.9800], [4.3820, 51.9800], [4.3820, 51.9820], [4.3800, 51.9820], [4.3800, 51.9800]]
NO_FLY = [[4.3710, 51.9805], [4.3720, 51.9805], [4.3720, 51.9812], [4.3710, 51.9805]]


def make_area() -> AreaPolygons:
    # clockwise exterior and counter-clockwise hole on purpose: the writer must re-orient
    boundary = shapely.MultiPolygon([shapely.Polygon(EXTERIOR[::-1], [HOLE[::-1]]), shapely.Polygon(SQUARE)])
    return AreaPolygons(boundary=boundary, exclusions=(shapely.Polygon(NO_FLY),))


# ---------------------------------------------------------------------------------------------
# QGC WPL 110


def test_wpl_reads_back_with_pymavlink(tmp_path):
    from pymavlink import mavutil, mavwp

    path = tmp_path / "uav1.waypoints"
    write_wpl(path, HOME, WAYPOINTS, SPEED_M_S)
    assert path.read_text().splitlines()[0] == "QGC WPL 110"
    loader = mavwp.MAVWPLoader()
    assert loader.load(str(path)) == len(WAYPOINTS) + 3
    items = [loader.wp(index) for index in range(loader.count())]
    assert [item.seq for item in items] == list(range(len(items)))

    home, speed, *waypoints, rtl = items
    assert (home.current, home.frame, home.command) == (1, mavutil.mavlink.MAV_FRAME_GLOBAL, 16)
    assert (home.x, home.y, home.z) == pytest.approx((HOME[1], HOME[0], HOME[2]), abs=1e-7)
    assert speed.command == mavutil.mavlink.MAV_CMD_DO_CHANGE_SPEED == 178
    assert speed.param2 == pytest.approx(SPEED_M_S) and speed.param1 == 1  # ground speed
    for item, (lon, lat, alt) in zip(waypoints, WAYPOINTS):
        assert (item.current, item.command) == (0, mavutil.mavlink.MAV_CMD_NAV_WAYPOINT)
        assert item.frame == mavutil.mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT == 3
        assert item.x == pytest.approx(lat, abs=1e-7) and item.y == pytest.approx(lon, abs=1e-7)
        assert item.z == pytest.approx(alt, abs=1e-3)
        assert item.autocontinue == 1
    assert rtl.command == mavutil.mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH == 20


def test_wpl_rows_are_tab_separated_with_twelve_fields(tmp_path):
    path = tmp_path / "uav1.waypoints"
    write_wpl(path, HOME, WAYPOINTS, SPEED_M_S)
    rows = path.read_text().splitlines()[1:]
    assert all(len(row.split("\t")) == 12 for row in rows)
    write_wpl(tmp_path / "again.waypoints", HOME, WAYPOINTS, SPEED_M_S)
    assert (tmp_path / "again.waypoints").read_bytes() == path.read_bytes()


# ---------------------------------------------------------------------------------------------
# QGroundControl .plan


def json_type(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    if isinstance(value, str):
        return "string"
    return type(value).__name__


def assert_same_structure(ours, reference, where: str = "plan") -> None:
    """Same keys at every level and the same JSON value types as the reference; a list's
    elements are compared with the reference's first element, except mission items (matched by
    command) and params (position by position)."""
    if isinstance(reference, dict):
        assert isinstance(ours, dict), f"{where}: expected an object"
        assert set(ours) == set(reference), f"{where}: keys {sorted(ours)} != reference {sorted(reference)}"
        for key in reference:
            assert_same_structure(ours[key], reference[key], f"{where}.{key}")
    elif isinstance(reference, list):
        assert isinstance(ours, list), f"{where}: expected a list"
        if where.endswith(".items"):
            by_command = {item["command"]: item for item in reference}
            for index, item in enumerate(ours):
                assert item["command"] in by_command, f"{where}[{index}]: command {item['command']} not in reference"
                assert_same_structure(item, by_command[item["command"]], f"{where}[{index}]")
        elif where.endswith(".params") or where.endswith(".plannedHomePosition"):
            assert len(ours) == len(reference), f"{where}: {len(ours)} entries, reference {len(reference)}"
            for index, (mine, theirs) in enumerate(zip(ours, reference)):
                assert_same_structure(mine, theirs, f"{where}[{index}]")
        else:
            assert reference or not ours, f"{where}: reference has no element to compare with"
            for index, mine in enumerate(ours):
                assert_same_structure(mine, reference[0], f"{where}[{index}]")
    else:
        assert json_type(ours) == json_type(reference), f"{where}: {json_type(ours)} != reference {json_type(reference)}"


def write_plan(tmp_path) -> tuple[Path, list[np.ndarray], list[np.ndarray]]:
    inclusion, exclusion = fence_rings(make_area())
    path = tmp_path / "uav1.plan"
    write_qgc_plan(path, HOME, WAYPOINTS, SPEED_M_S, geofence_inclusion=inclusion, geofence_exclusion=exclusion)
    return path, inclusion, exclusion


def test_plan_has_the_structure_of_the_qgroundcontrol_reference(tmp_path):
    reference = json.loads(REFERENCE_PLAN.read_text())
    path, _, _ = write_plan(tmp_path)
    plan = json.loads(path.read_text())
    assert_same_structure(plan, reference)
    assert (plan["fileType"], plan["version"], plan["groundStation"]) == ("Plan", 1, "QGroundControl")
    mission = plan["mission"]
    assert mission["firmwareType"] == 12 and mission["vehicleType"] == 2 and mission["version"] == 2
    assert mission["cruiseSpeed"] == mission["hoverSpeed"] == SPEED_M_S
    assert mission["plannedHomePosition"] == pytest.approx([HOME[1], HOME[0], HOME[2]])
    assert plan["rallyPoints"] == {"points": [], "version": 2}

    items = mission["items"]
    assert [item["doJumpId"] for item in items] == list(range(1, len(items) + 1))
    assert all(len(item["params"]) == 7 for item in items)
    assert [item["command"] for item in items] == [178] + [16] * len(WAYPOINTS) + [20]
    assert items[0]["params"][1] == SPEED_M_S
    for item, (lon, lat, alt) in zip(items[1:-1], WAYPOINTS):
        assert item["frame"] == 3 and item["params"][3] is None
        assert item["params"][4:] == [lat, lon, alt] and item["Altitude"] == alt


def test_plan_geofence_reads_back_as_the_polygons_written(tmp_path):
    path, inclusion, exclusion = write_plan(tmp_path)
    fence = json.loads(path.read_text())["geoFence"]
    assert [entry["inclusion"] for entry in fence["polygons"]] == [True, True, False, False]
    for entry in fence["polygons"]:
        ring = entry["polygon"]
        assert ring[0] != ring[-1]  # open, as QGroundControl writes it
        assert not shapely.LinearRing([(lon, lat) for lat, lon in ring]).is_ccw  # clockwise, as documented
    read_inclusions, read_exclusions = read_polygons(path)
    for written, read in zip(inclusion + exclusion, read_inclusions + read_exclusions):
        assert shapely.equals_exact(shapely.normalize(shapely.Polygon(written)), shapely.normalize(read), tolerance=1e-9)
    assert (len(read_inclusions), len(read_exclusions)) == (2, 2)
    # as the boundary file, the .plan gives back the area (holes as exclusions)
    area = read_area(path)
    flyable = area.boundary.difference(shapely.union_all(area.exclusions))
    expected = make_area()
    assert shapely.symmetric_difference(flyable, expected.boundary.difference(expected.exclusions[0])).area < 1e-14


def test_plan_is_deterministic_and_rejects_bad_waypoints(tmp_path):
    first, _, _ = write_plan(tmp_path)
    text = first.read_text()
    second, _, _ = write_plan(tmp_path)
    assert second.read_text() == text and "NaN" not in text
    with pytest.raises(MissionInputError, match="projected metres"):
        write_qgc_plan(tmp_path / "bad.plan", HOME, np.array([[85000.0, 445000.0, 30.0]]), SPEED_M_S)
    with pytest.raises(MissionInputError, match=r"waypoints.*\(n, 3\)"):
        write_qgc_plan(tmp_path / "bad.plan", HOME, WAYPOINTS[:, :2], SPEED_M_S)
    with pytest.raises(MissionInputError, match="speed_m_s"):
        write_wpl(tmp_path / "bad.waypoints", HOME, WAYPOINTS, 0.0)


# ---------------------------------------------------------------------------------------------
# GeoJSON


def positions_of(geometry) -> list:
    kind, coordinates = geometry["type"], geometry["coordinates"]
    if kind == "Point":
        return [coordinates]
    if kind == "LineString":
        return coordinates
    if kind == "Polygon":
        return [position for ring in coordinates for position in ring]
    assert kind == "MultiPolygon", kind
    return [position for polygon in coordinates for ring in polygon for position in ring]


def polygons_of(geometry) -> list[list]:
    return [geometry["coordinates"]] if geometry["type"] == "Polygon" else geometry["coordinates"]


def write_mission_geojson(tmp_path) -> tuple[Path, dict]:
    flown = {"uav1": np.column_stack([WAYPOINTS[:, 0], WAYPOINTS[:, 1], WAYPOINTS[:, 2] + 0.01234]),
             "uav2": WAYPOINTS[:1, :2]}
    planned = {"uav1": WAYPOINTS[:, :2], "uav2": WAYPOINTS[::-1]}
    homes = {"uav1": HOME[:2], "uav2": (4.3703, 51.9802)}
    targets = np.array([[4.3751, 51.9821, 0.93, 3], [4.3712, 51.9843, 0.41, 1]])
    path = tmp_path / "plan.geojson"
    write_geojson(path, make_area(), flown, planned, targets=targets, homes=homes)
    return path, json.loads(path.read_text())


def test_geojson_is_rfc7946(tmp_path):
    _, collection = write_mission_geojson(tmp_path)
    assert collection["type"] == "FeatureCollection" and isinstance(collection["features"], list)
    assert "crs" not in collection
    for feature in collection["features"]:
        assert set(feature) == {"type", "properties", "geometry"} and feature["type"] == "Feature"
        assert "crs" not in feature and isinstance(feature["properties"], dict)
        geometry = feature["geometry"]
        assert set(geometry) == {"type", "coordinates"}
        for position in positions_of(geometry):
            assert len(position) in (2, 3) and all(isinstance(value, float) for value in position)
            assert abs(position[0]) <= 180 and abs(position[1]) <= 90
            assert position[:2] == [round(value, 9) for value in position[:2]]
        if geometry["type"] in ("Polygon", "MultiPolygon"):
            for rings in polygons_of(geometry):
                for number, ring in enumerate(rings):
                    assert len(ring) >= 4 and ring[0] == ring[-1]
                    assert all(len(position) == 2 for position in ring)
                    # right-hand rule: exterior counter-clockwise, holes clockwise
                    assert shapely.LinearRing(ring).is_ccw == (number == 0)


def test_geojson_features_and_properties(tmp_path):
    _, collection = write_mission_geojson(tmp_path)
    summary = [(feature["properties"]["kind"], feature["properties"].get("uav"), feature["geometry"]["type"])
               for feature in collection["features"]]
    assert summary == [
        ("area", None, "MultiPolygon"), ("no_fly", None, "Polygon"),
        ("flown", "uav1", "LineString"), ("planned", "uav1", "LineString"), ("home", "uav1", "Point"),
        ("flown", "uav2", "Point"), ("planned", "uav2", "LineString"), ("home", "uav2", "Point"),
        ("target", None, "Point"), ("target", None, "Point"),
    ]
    flown = collection["features"][2]["geometry"]["coordinates"]
    assert flown[2] == [4.373333333, 51.982345679, 42.137]  # 1e-9 deg, 1 mm
    first_target = collection["features"][-2]["properties"]
    assert first_target["probability"] == 0.93 and first_target["detections"] == 3


def test_geojson_skips_empty_paths(tmp_path):
    path = tmp_path / "start.geojson"
    write_geojson(path, make_area(), {"uav1": np.empty((0, 3))}, {"uav1": WAYPOINTS}, homes={"uav1": HOME[:2]})
    kinds = [feature["properties"]["kind"] for feature in json.loads(path.read_text())["features"]]
    assert kinds == ["area", "no_fly", "planned", "home"]


def test_geojson_area_reads_back_as_the_same_polygon(tmp_path):
    path, _ = write_mission_geojson(tmp_path)
    area = make_area()
    inclusions, exclusions = read_polygons(path)
    assert shapely.symmetric_difference(shapely.union_all(inclusions), area.boundary).area < 1e-12
    assert len(exclusions) == 1 and shapely.symmetric_difference(exclusions[0], area.exclusions[0]).area < 1e-12
    again = read_area(path)
    assert shapely.symmetric_difference(again.boundary, area.boundary).area < 1e-12


# ---------------------------------------------------------------------------------------------
# GeoTIFF


def rd_new_wkt() -> str:
    from pyproj import CRS

    return CRS.from_epsg(28992).to_wkt()


def test_geotiff_is_north_up_with_the_rows_flipped(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from pyproj import CRS

    probability = np.arange(12, dtype=float).reshape(3, 4) / 20.0  # row 0 is the south
    probability[0, 3] = np.nan  # outside the area
    origin = (84000.0, 445000.0)
    cell = 2.5
    path = tmp_path / "probability.tif"
    wkt = rd_new_wkt()
    write_geotiff(path, probability, origin, cell, wkt)
    with rasterio.open(path) as dataset:
        data = dataset.read(1)
        transform = dataset.transform
        assert dataset.count == 1 and dataset.dtypes[0] == "float32"
        assert dataset.profile["compress"].lower() == "deflate"
        assert math.isnan(dataset.nodata)
        assert dataset.crs == rasterio.crs.CRS.from_wkt(wkt)
        assert CRS.from_wkt(dataset.crs.to_wkt()).equals(CRS.from_wkt(wkt))
        bounds = dataset.bounds
    assert transform.e < 0 and transform.a == cell and transform.e == -cell
    assert (transform.c, transform.f) == (origin[0], origin[1] + 3 * cell)
    assert (bounds.left, bounds.bottom, bounds.right, bounds.top) == (84000.0, 445000.0, 84010.0, 445007.5)
    np.testing.assert_array_equal(data, probability[::-1].astype(np.float32))  # file row 0 = northernmost
    assert math.isnan(data[-1, 3]) and np.isnan(data).sum() == 1


def test_geotiff_without_rasterio_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rasterio", None)
    with pytest.raises(MissionInputError, match=r'pip install "attend\[geotiff\]"'):
        write_geotiff(tmp_path / "p.tif", np.zeros((2, 2)), (0.0, 0.0), 1.0, rd_new_wkt())


def test_geotiff_rejects_values_that_are_not_probabilities(tmp_path):
    pytest.importorskip("rasterio")
    with pytest.raises(MissionInputError, match=r"probability: expected values in \[0, 1\]"):
        write_geotiff(tmp_path / "p.tif", np.full((2, 2), 1.5), (0.0, 0.0), 1.0, rd_new_wkt())
