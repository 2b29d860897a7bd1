"""FieldLawnmowerPlanner: the pattern's geometry, coverage, finding everyone on an easy world, tuning."""

import numpy as np
import pytest

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.planners.field_lawnmower import FieldLawnmowerPlanner, best_lawnmower
from attend.action.probability_map import MapGrid
from attend.action.search_mission import SearchSettings, fly_search
from attend.action.world import make_world

EASY = DetectionModel(max_detection_probability=0.95, false_detections_at_best=0.0, false_detections_at_useless=0.0)


@pytest.mark.parametrize("n_uavs", [1, 2, 3])
def test_strips_are_covered_by_footprint_wide_tracks(n_uavs):
    grid = MapGrid.square(200.0, 1.0)
    camera = Camera()
    planner = FieldLawnmowerPlanner(30.0, camera=camera, n_uavs=n_uavs)
    width = float(camera.footprint_m(30.0)[0])
    x0, x1, y0, y1 = grid.extent_m
    for strip in range(n_uavs):
        pattern = planner.strip_pattern(grid, strip)
        assert np.all(pattern[:, 2] == 30.0)
        xs = np.unique(pattern[:, 0])
        low, high = x0 + strip * (x1 - x0) / n_uavs, x0 + (strip + 1) * (x1 - x0) / n_uavs
        assert len(xs) == int(np.ceil((high - low) / width))
        # swaths of half a footprint either side of each track cover the strip without gaps
        edges = np.sort(np.r_[xs - width / 2, xs + width / 2])
        assert xs[0] - width / 2 == pytest.approx(low) and xs[-1] + width / 2 == pytest.approx(high)
        assert np.all(np.diff(xs) <= width + 1e-9)
        assert np.ptp(np.diff(xs)) < 1e-9 if len(xs) > 2 else True
        assert set(np.unique(pattern[:, 1])) == {y0, y1}
        assert edges[0] >= low - 1e-9


def test_plan_walks_the_pattern_and_flies_it_back_when_done():
    grid = MapGrid.square(100.0, 1.0)

    class Belief:
        pass

    belief = Belief()
    belief.grid = grid
    planner = FieldLawnmowerPlanner(30.0, waypoints_per_plan=3)
    pattern = planner.strip_pattern(grid, 0)
    flown = [planner.plan(belief, 0, np.array([-50.0, -50.0, 30.0]), 100.0) for _ in range(7)]
    flown = np.vstack(flown)
    m = len(pattern)
    np.testing.assert_allclose(flown[:m], pattern)  # starts at the corner nearest the UAV
    np.testing.assert_allclose(flown[m : 2 * m - 1], pattern[::-1][1:])
    planner.reset(1)
    np.testing.assert_allclose(planner.plan(belief, 0, np.array([-50.0, -50.0, 30.0]), 100.0), pattern[:3])


def test_lawnmower_covers_the_area_and_finds_everyone_on_an_easy_world():
    """200 m square at 30 m: 9 tracks, about 2000 m, 200 s at 10 m/s; the budget 260 s. Each
    person lies under 3 or more images of a track (34.6 m along-track footprint, an image every
    10 m), each reporting them with pd = 0.95 and no clutter, and one report makes a target
    (p ~ 1 without clutter): P(someone missed) <= 15 x 0.05^3 = 0.2 % over 3 seeds x 5 people."""
    settings = SearchSettings(budget_s=260.0, model=EASY)
    for seed in range(3):
        world = make_world(200.0, 1.0, 5, seed=seed)
        planner = FieldLawnmowerPlanner(30.0, camera=settings.camera)
        log = fly_search(world, planner, settings, seed=seed)
        assert log.area_covered_m2 == pytest.approx(200.0 * 200.0, rel=1e-9)
        assert len(log.found_times_s) == 5
        assert log.false_targets == 0


def test_two_uavs_with_buildings_cover_the_area_about_twice_as_fast():
    world = make_world(200.0, 1.0, 5, seed=5, n_buildings=3)
    settings = SearchSettings(budget_s=130.0, n_uavs=2, model=EASY, min_separation_m=5.0)
    planner = FieldLawnmowerPlanner(30.0, camera=settings.camera, n_uavs=2, buildings=world.buildings)
    log = fly_search(world, planner, settings, seed=0)
    searchable_area = world.searchable.sum() * world.grid.cell_area_m2
    # ground hidden behind buildings from every image stays unseen: a few percent at most
    assert log.area_covered_m2 >= 0.97 * searchable_area
    assert log.separation_violations == 0


def test_best_lawnmower_prefers_an_altitude_that_detects():
    settings = SearchSettings(budget_s=120.0, model=EASY)
    tuning = best_lawnmower(lambda seed: make_world(100.0, 1.0, 3, seed=seed), seeds=[0, 1], altitudes=[100.0, 30.0],
                            spacing_factors=[1.0, 2.0], settings=settings)
    assert tuning.altitude_m == 30.0
    assert all(t == np.inf for t in tuning.times_s[(100.0, 1.0)])  # pd(100 m) = 0
    assert tuning.median_time_s == np.median(tuning.times_s[(tuning.altitude_m, tuning.spacing_factor)])
    assert isinstance(tuning.planner(settings.camera, 1), FieldLawnmowerPlanner)


def test_bad_arguments_are_named():
    for kwargs, name in [({"altitude_m": 0.0}, "altitude_m"), ({"track_spacing_m": -1.0}, "track_spacing_m"),
                         ({"n_uavs": 0}, "n_uavs"), ({"waypoints_per_plan": 0}, "waypoints_per_plan")]:
        with pytest.raises(ActionInputError, match=name):
            FieldLawnmowerPlanner(**kwargs)
