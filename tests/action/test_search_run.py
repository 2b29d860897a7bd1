"""attend.action.search_run and ``attend search`` on the probability map: the two grounds, the
files a team reads, and one-line errors naming the option."""

import json
import math

import numpy as np
import pytest

from attend.action import ActionInputError
from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.search_run import coverage_budget_s, mission_setup, run_probability_search
from attend.cli import main

SUMMARY_KEYS = {"people_total", "people_found", "time_to_find_all_s", "median_planner_time_s", "max_planner_time_s",
                "false_targets", "found_times_s", "median_map_update_ms"}


def test_the_paper_field_is_the_default_ground():
    world, settings = mission_setup(seed=3)
    assert world.grid.shape == (40, 40) and world.grid.cell_size_m == 0.75 and world.n_people == 7
    assert (settings.budget_s, settings.speed_m_s, settings.image_rate_hz) == (150.0, 5.0, 0.15)
    assert settings.model == DetectionModel.paper()
    world, settings = mission_setup(seed=3, uavs=3)
    assert len(world.start_poses_m) == 3 and settings.n_uavs == 3
    assert np.all(np.abs(world.start_poses_m[:, :2]) <= 15)
    assert len(np.unique(world.start_poses_m[:, 0])) == 3  # not on top of each other


def test_field_scale_budget_is_one_lawnmower_pass_and_a_quarter():
    camera, model = Camera(), DetectionModel()
    across = 2 * model.best_altitude_m * math.tan(math.radians(45.0) / 2)  # the narrower footprint side
    tracks = math.ceil(200.0 / across)
    assert coverage_budget_s(200.0, 1, camera, model, 10.0) == pytest.approx(1.25 * tracks * 200.0 / 10.0)
    assert coverage_budget_s(200.0, 4, camera, model, 10.0) == pytest.approx(1.25 * tracks * 200.0 / 40.0)
    world, settings = mission_setup(seed=1, area_size_m=200.0, people=4, uavs=2)
    assert world.grid.shape == (200, 200) and world.n_people == 4
    assert settings.budget_s == pytest.approx(coverage_budget_s(200.0, 2, camera, model, 10.0))


def test_a_mission_writes_what_a_search_team_reads(tmp_path):
    paths = run_probability_search("lawnmower", seed=0, out_dir=tmp_path, area_size_m=120.0, people=3, budget_s=40.0)
    data = json.loads(paths["metrics"].read_text())
    summary = data["summary"]
    assert SUMMARY_KEYS <= set(summary)
    assert summary["people_found"] == len(summary["found_times_s"]) <= summary["people_total"] == 3
    assert (summary["time_to_find_all_s"] is None) == (summary["people_found"] < 3)
    assert summary["max_planner_time_s"] >= summary["median_planner_time_s"] >= 0
    assert all(0 <= t <= 40.0 for t in summary["found_times_s"])
    assert len(data["per_image"]["time_s"]) == summary["images"] > 0
    assert paths["map"].stat().st_size > 0 and paths["found"].stat().st_size > 0


def test_the_user_prior_map_places_the_people(tmp_path, capsys):
    from PIL import Image

    picture = np.zeros((10, 10), dtype=np.uint8)
    picture[:3, 7:] = 255  # only the north-east corner is possible
    Image.fromarray(picture, mode="L").save(tmp_path / "likely.png")
    out = tmp_path / "run"
    assert main(["search", "--area-size", "100", "--people", "4", "--budget", "20", "--prior-map",
                 str(tmp_path / "likely.png"), "--no-progress", "--out", str(out)]) == 0
    people = np.array(json.loads((out / "search_metrics.json").read_text())["people_xy_m"])
    assert np.all(people[:, 0] >= 20 - 1e-9) and np.all(people[:, 1] >= 20 - 1e-9)  # x >= 20 m, y >= 20 m
    assert "found" in capsys.readouterr().out


@pytest.mark.parametrize("args, option", [
    (["--people", "0"], "--people"),
    (["--uavs", "0"], "--uavs"),
    (["--area-size", "-5"], "--area-size"),
    (["--area-size", "20", "--cell-size", "30"], "--cell-size"),
    (["--area-size", "3", "--cell-size", "1", "--people", "10"], "--people"),
    (["--budget", "0"], "--budget"),
    (["--speed", "nan"], "--speed"),
    (["--image-rate", "-1"], "--image-rate"),
    (["--buildings", "-1"], "--buildings"),
    (["--start", "100", "0", "7"], "--start"),
    (["--area-size", "100", "--start", "0", "0", "500"], "--start"),
    (["--diagonal"], "--diagonal"),
    (["--map", "gp", "--uavs", "2"], "--uavs"),
    (["--planner", "cover_confirm"], "--planner"),
    (["--prior-map", "missing.csv"], "--prior-map"),
    (["--area-size", "50", "--prior-map", "NEG"], "bad.csv"),
])
def test_bad_search_input_is_one_line_naming_the_option(tmp_path, capsys, args, option):
    (tmp_path / "bad.csv").write_text("1,-2\n3,4\n")
    args = [str(tmp_path / "bad.csv") if a == "NEG" else a for a in args]
    assert main(["search", *args, "--no-progress", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("attend: error: ") and option in err[0], err


def test_library_errors_name_the_argument():
    with pytest.raises(ActionInputError, match="uavs"):
        mission_setup(uavs=0)
    with pytest.raises(ActionInputError, match="area_size_m"):
        mission_setup(prior_map=np.ones((3, 3)))
    with pytest.raises(ActionInputError, match="obstacles, people_region"):
        mission_setup(area_size_m=100.0, obstacles="buildings")
