"""`attend plan` from the command line: the files it writes, and one clear line (exit 2, the
output folder untouched) for each kind of bad input."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import shapely

from attend.action.mission import Mission
from attend.action.mission.area_files import read_polygons
from attend.action.mission.examples import write_example_mission
from attend.action.mission.flight_logs import write_flight_logs
from attend.action.mission.simulate import simulate_mission
from attend.cli import main


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """A mission flown for 120 s by the simulator, its logs written as a team would bring them."""
    folder = tmp_path_factory.mktemp("flown")
    path = write_example_mission(folder, seed=21, size_m=250.0, n_uavs=2, flight_time_s=300.0, cell_size_m=2.0)
    mission = Mission.from_file(path)
    simulate_mission(mission, seed=2, replan_s=40.0)
    keep = mission.logs.image_time_s <= 120.0
    write_flight_logs(mission.logs.subset(keep), [u.name for u in mission.config.uavs], folder / "images.csv",
                      folder / "detections.csv")
    return folder


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_plan_writes_every_file_and_the_autopilot_files_hold_the_plan(flown, tmp_path):
    out = tmp_path / "out"
    assert main(["plan", str(flown / "mission.toml"), "--out", str(out), "--images", str(flown / "images.csv"),
                 "--detections", str(flown / "detections.csv")]) == 0
    for name in ("plan.csv", "plan_uav1.plan", "plan_uav2.plan", "plan_uav1.waypoints", "plan_uav2.waypoints",
                 "plan.geojson", "targets.csv", "map.png", "map.tif", "summary.json"):
        assert (out / name).is_file(), name
    rows = _rows(out / "plan.csv")
    assert list(rows[0]) == ["uav", "seq", "t_s", "lon", "lat", "alt_m"]
    assert (out / "targets.csv").read_text().splitlines()[0] == "lon,lat,probability,detections"
    summary = json.loads((out / "summary.json").read_text())
    assert [u["uav"] for u in summary["uavs"]] == ["uav1", "uav2"]
    assert 0 <= summary["p_all_found"] <= 1 and summary["images"] > 0
    # each UAV's waypoints: plan.csv = the WPL file reloaded by pymavlink = the .plan items
    mavwp = pytest.importorskip("pymavlink.mavwp")
    for uav in ("uav1", "uav2"):
        mine = [r for r in rows if r["uav"] == uav]
        expected = np.array([[float(r["lat"]), float(r["lon"]), float(r["alt_m"])] for r in mine])
        loader = mavwp.MAVWPLoader()
        loader.load(str(out / f"plan_{uav}.waypoints"))
        items = [loader.wp(i) for i in range(loader.count())]
        points = np.array([[w.x, w.y, w.z] for w in items if w.command == 16 and w.frame == 3])
        np.testing.assert_allclose(points[:, :2], expected[:, :2], atol=1e-7)
        np.testing.assert_allclose(points[:, 2], expected[:, 2], atol=1e-3)
        plan = json.loads((out / f"plan_{uav}.plan").read_text())
        qgc = np.array([item["params"][4:7] for item in plan["mission"]["items"] if item["command"] == 16])
        np.testing.assert_allclose(qgc[:, :2], expected[:, :2], atol=1e-7)
    # the .plan's geofence is the area: it reads back as the boundary file's polygon
    inclusion, exclusion = read_polygons(out / "plan_uav1.plan")
    boundary, _ = read_polygons(flown / "area.geojson")
    outer = shapely.Polygon(boundary[0].exterior)
    assert inclusion[0].symmetric_difference(outer).area < 1e-9 * outer.area
    assert len(exclusion) == 2  # the area's hole and the no-fly zone


def test_plan_lawnmower_and_a_dry_run(tmp_path):
    path = write_example_mission(tmp_path / "m", seed=3, size_m=200.0, n_uavs=1, people=2, flight_time_s=150.0)
    assert main(["plan", str(path), "--out", str(tmp_path / "lm"), "--planner", "lawnmower", "--no-plot"]) == 0
    assert len(_rows(tmp_path / "lm" / "plan.csv")) > 2
    assert main(["plan", str(path), "--simulate", "--seed", "1", "--out", str(tmp_path / "dry"), "--no-plot"]) == 0
    summary = json.loads((tmp_path / "dry" / "summary.json").read_text())
    assert summary["simulation"]["people"] == 2 and summary["images"] > 0
    assert (tmp_path / "dry" / "images.csv").is_file() and (tmp_path / "dry" / "people.csv").is_file()


def _edit(source, target, old, new):
    text = source.read_text()
    assert old in text, old
    target.write_text(text.replace(old, new, 1))


def _break_images(flown, tmp_path, column: str, value: str):
    rows = list(csv.reader(open(flown / "images.csv")))
    header = rows[0]
    rows[1][header.index(column)] = value
    target = tmp_path / "images.csv"
    with open(target, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    return target


@pytest.mark.parametrize("column, value, fragment", [
    ("t_s", "-1.000", "expected a time >= 0 s"),
    ("uav", "uav9", "unknown UAV 'uav9'"),
    ("alt_m", "120.000", "outside the limits"),
    ("lon", "abc", "expected a number"),
])
def test_bad_image_rows_name_file_row_and_column(flown, tmp_path, capsys, column, value, fragment):
    images = _break_images(flown, tmp_path, column, value)
    out = tmp_path / "out"
    out.mkdir()
    (out / "plan.csv").write_text("old plan\n")
    status = main(["plan", str(flown / "mission.toml"), "--out", str(out), "--images", str(images)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert len(err) == 1 and "images.csv" in err[0] and "row 2" in err[0] and column in err[0] and fragment in err[0]
    assert (out / "plan.csv").read_text() == "old plan\n"  # nothing in DIR changed
    assert sorted(p.name for p in out.iterdir()) == ["plan.csv"]


def test_images_out_of_time_order_and_missing_columns_and_orphan_detections(flown, tmp_path, capsys):
    rows = list(csv.reader(open(flown / "images.csv")))
    uav1 = [i for i, r in enumerate(rows) if i > 0 and r[1] == "uav1"]
    rows[uav1[0]], rows[uav1[1]] = rows[uav1[1]], rows[uav1[0]]
    swapped = tmp_path / "swapped.csv"
    with open(swapped, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    assert main(["plan", str(flown / "mission.toml"), "--out", str(tmp_path / "o"), "--images", str(swapped)]) == 2
    assert "time order" in capsys.readouterr().err
    cut = tmp_path / "cut.csv"
    cut.write_text("t_s,uav,lon,lat,alt_m\n1,uav1,0,0,20\n")
    assert main(["plan", str(flown / "mission.toml"), "--out", str(tmp_path / "o"), "--images", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "cut.csv" in err and "row 1" in err and "yaw_deg" in err
    orphan = tmp_path / "detections.csv"
    orphan.write_text("t_s,uav,lon,lat,score\n9999.5,uav1,0,0,0.9\n")
    assert main(["plan", str(flown / "mission.toml"), "--out", str(tmp_path / "o"), "--images",
                 str(flown / "images.csv"), "--detections", str(orphan)]) == 2
    err = capsys.readouterr().err
    assert "detections.csv" in err and "row 2" in err and "no image" in err
    assert not (tmp_path / "o").exists()


def test_bad_mission_files(flown, tmp_path, capsys):
    mission = flown / "mission.toml"
    cases = []
    unknown = flown / "unknown.toml"
    _edit(mission, unknown, "[search]", "[search]\nbudget = 3")
    cases.append((unknown, "search.budget", "unknown key"))
    far = flown / "far.toml"
    text = mission.read_text()
    start = text.index("home = [") + len("home = [")
    lon = float(text[start:text.index(",", start)])
    far.write_text(text.replace(f"home = [{lon!r}", f"home = [{lon + 0.5!r}", 1))
    cases.append((far, "km from the area", "home"))
    open_ring = tmp_path / "open.geojson"
    area = json.loads((flown / "area.geojson").read_text())
    area["features"][0]["geometry"]["coordinates"][0].pop()
    open_ring.write_text(json.dumps(area))
    not_closed = flown / "not_closed.toml"
    _edit(mission, not_closed, 'boundary = "area.geojson"', f'boundary = "{open_ring}"')
    cases.append((not_closed, "open.geojson", "closed"))
    bowtie = tmp_path / "bowtie.geojson"
    bowtie.write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[4.0, 52.0], [4.01, 52.01], [4.01, 52.0], [4.0, 52.01], [4.0, 52.0]]]}))
    crossing = flown / "crossing.toml"
    _edit(mission, crossing, 'boundary = "area.geojson"', f'boundary = "{bowtie}"')
    cases.append((crossing, "bowtie.geojson", "intersect"))
    metres = tmp_path / "metres.geojson"
    metres.write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[500000.0, 5760000.0], [500300.0, 5760000.0], [500300.0, 5760300.0], [500000.0, 5760000.0]]]}))
    projected = flown / "projected.toml"
    _edit(mission, projected, 'boundary = "area.geojson"', f'boundary = "{metres}"')
    cases.append((projected, "metres.geojson", "lon/lat"))
    no_fence = tmp_path / "nofence.plan"
    no_fence.write_text(json.dumps({"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
                                    "mission": {"items": []}, "geoFence": {"polygons": [], "circles": [], "version": 2},
                                    "rallyPoints": {"points": [], "version": 2}}))
    fenceless = flown / "fenceless.toml"
    _edit(mission, fenceless, 'boundary = "area.geojson"', f'boundary = "{no_fence}"')
    cases.append((fenceless, "nofence.plan", "geofence"))
    for path, fragment, other in cases:
        out = tmp_path / f"out_{path.stem}"
        assert main(["plan", str(path), "--out", str(out)]) == 2, path
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and fragment in err[0] and other in err[0], (path, err)
        assert not out.exists()


def test_an_image_over_nothing_of_the_area_is_refused(flown, tmp_path, capsys):
    """An image 5 km east of the area (a row in another mission's frame, or lon/lat swapped) sees
    nothing of it: one line naming images.csv, the row and the column, exit 2."""
    rows = list(csv.reader(open(flown / "images.csv")))
    header = rows[0]
    rows[3][header.index("lon")] = f"{float(rows[3][header.index('lon')]) + 0.08:.9f}"
    moved = tmp_path / "images.csv"
    with open(moved, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    assert main(["plan", str(flown / "mission.toml"), "--out", str(tmp_path / "o"), "--images", str(moved)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "images.csv" in err[0] and "row 4" in err[0] and "sees nothing of the area" in err[0]
    assert not (tmp_path / "o").exists()
