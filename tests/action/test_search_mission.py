"""fly_search: time-ordered fusion of several UAVs, budget, metrics against the map (exact tile sums), planner
errors, map-update timing."""

import gc
import math

import numpy as np
import pytest

from attend.action import search_mission
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.planners.field_lawnmower import FieldLawnmowerPlanner
from attend.action.planners.search_base import SearchPlanner
from attend.action.search_mission import SearchLog, SearchSettings, fly_search
from attend.action.world import make_world


class FixedPlanner(SearchPlanner):
    """Returns the same waypoints every time (records what it was given)."""

    name = "fixed"

    def __init__(self, waypoints):
        self.waypoints = np.asarray(waypoints, float)
        self.calls = []

    def plan(self, belief, uav, pose_m, time_left_s, others=()):
        self.calls.append((uav, np.array(pose_m), time_left_s, [np.array(o) for o in others]))
        return self.waypoints


class HoverPlanner(SearchPlanner):
    name = "hover"

    def plan(self, belief, uav, pose_m, time_left_s, others=()):
        return np.array([pose_m])


def test_two_uavs_fused_in_time_order_within_budget():
    world = make_world(200.0, 1.0, 5, seed=1)
    settings = SearchSettings(budget_s=60.0, n_uavs=2, image_rate_hz=1.0)
    planner = FieldLawnmowerPlanner(30.0, camera=settings.camera, n_uavs=2)
    seen = []
    log = fly_search(world, planner, settings, seed=0, on_image=lambda image, belief, log: seen.append(image))
    assert np.all(np.diff(log.times_s) >= 0)
    assert max(log.times_s) <= 60.0
    assert log.images == len(log.times_s) == len(seen)
    # UAV 0 images at 0, 1, ..., 60; UAV 1 at 0.5, ..., 59.5
    assert log.uavs.count(0) == 61 and log.uavs.count(1) == 60
    np.testing.assert_allclose(sorted(log.times_s), np.sort(np.r_[np.arange(61.0), np.arange(60) + 0.5]))
    assert np.all(log.distance_flown_m <= settings.speed_m_s * 60.0 + 1e-6)
    for path, distance in zip(log.paths_m, log.distance_flown_m):
        assert np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)) == pytest.approx(distance)
    for series in (log.expected_people, log.people_found, log.p_all_found, log.false_targets_series, log.map_update_ms):
        assert len(series) == log.images


def test_metrics_agree_with_the_map_and_found_times_with_the_targets():
    world = make_world(150.0, 1.0, 6, seed=2, n_buildings=2)
    settings = SearchSettings(budget_s=150.0, n_uavs=2, model=DetectionModel(false_detections_at_best=0.5))
    planner = FieldLawnmowerPlanner(30.0, camera=settings.camera, n_uavs=2, buildings=world.buildings)
    found_at = np.full(world.n_people, math.inf)

    def check(image, belief, log):
        positions, _ = belief.targets(settings.target_threshold)
        if len(positions):
            near = np.linalg.norm(positions[:, None] - world.people_m[None], axis=-1) <= settings.found_radius_m
            found_at[near.any(axis=0) & ~np.isfinite(found_at)] = image.time_s
            assert log.false_targets_series[-1] == int((~near.any(axis=1)).sum())
        assert log.people_found[-1] == int(np.isfinite(found_at).sum())
        if log.images % 37 == 0:
            assert log.expected_people[-1] == pytest.approx(belief.expected_people(), rel=1e-9)
            assert log.p_all_found[-1] == pytest.approx(belief.p_all_found(settings.target_threshold), rel=1e-6)

    log = fly_search(world, planner, settings, seed=3, on_image=check)
    np.testing.assert_array_equal(log.person_found_times_s, found_at)
    assert log.found_times_s == sorted(found_at[np.isfinite(found_at)].tolist())
    assert set(log.found_times_s) <= set(log.times_s)
    assert log.expected_people[-1] == pytest.approx(log.final_map.expected_people(), rel=1e-9)
    assert len(log.found_times_s) >= 1


def test_others_hold_the_other_uavs_pose_and_remaining_waypoints():
    world = make_world(100.0, 1.0, 2, seed=0)
    waypoints = [[0.0, 0.0, 30.0], [20.0, 20.0, 30.0], [-20.0, 30.0, 40.0]]
    planner = FixedPlanner(waypoints)
    fly_search(world, planner, SearchSettings(budget_s=5.0, n_uavs=2), seed=0)
    (uav0, pose0, left0, others0), (uav1, pose1, left1, others1) = planner.calls[:2]
    assert (uav0, uav1) == (0, 1) and left0 == left1 == 5.0
    np.testing.assert_allclose(others1[0], np.vstack([world.start_poses_m[0], waypoints]))
    np.testing.assert_allclose(others0[0], world.start_poses_m[1][None])


def test_hovering_planner_does_not_stall_and_images_are_still():
    world = make_world(100.0, 1.0, 2, seed=0)
    speeds = []
    log = fly_search(world, HoverPlanner(), SearchSettings(budget_s=20.0), seed=0,
                     on_image=lambda image, belief, log: speeds.append(image.speed_m_s))
    assert log.images == 21 and set(speeds) == {0.0}
    assert log.distance_flown_m[0] == 0.0


@pytest.mark.parametrize(
    "waypoints",
    [
        [[500.0, 0.0, 30.0]],             # outside the area
        [[0.0, 0.0, 200.0]],              # above the altitude limit
        [[0.0, 0.0, 2.0]],                # below it
        [[0.0, 0.0, np.nan]],
        np.zeros((0, 3)),
        [[0.0, 0.0]],
    ],
)
def test_bad_waypoints_name_the_planner(waypoints):
    world = make_world(100.0, 1.0, 2, seed=0)
    with pytest.raises(ActionInputError, match="fixed"):
        fly_search(world, FixedPlanner(waypoints), SearchSettings(budget_s=10.0), seed=0)


def test_waypoint_in_or_path_through_a_building_names_the_planner():
    world = make_world(200.0, 1.0, 2, seed=0, n_buildings=1)
    box = world.buildings[0]
    assert box.height_m > 6.0
    with pytest.raises(ActionInputError, match="fixed.*inside a building"):
        fly_search(world, FixedPlanner([[box.x_m, box.y_m, 5.0]]), SearchSettings(budget_s=10.0), seed=0)
    x0, x1, _, _ = world.grid.extent_m
    through = [[x0 + 1, box.y_m, 5.0], [x1 - 1, box.y_m, 5.0]]
    with pytest.raises(ActionInputError, match="fixed.*through a building"):
        fly_search(world, FixedPlanner(through), SearchSettings(budget_s=100.0), seed=0)


def test_bad_settings_are_named():
    for kwargs, name in [({"budget_s": 0.0}, "budget_s"), ({"n_uavs": 0}, "n_uavs"), ({"speed_m_s": -1.0}, "speed_m_s"),
                         ({"expected_people": -2.0}, "expected_people"), ({"replan_after_waypoints": 0}, "replan_after_waypoints")]:
        with pytest.raises(ActionInputError, match=name):
            SearchSettings(**kwargs)
    world = make_world(100.0, 1.0, 2, seed=0)
    with pytest.raises(ActionInputError, match="n_uavs"):
        fly_search(world, HoverPlanner(), SearchSettings(n_uavs=9), seed=0)


def test_time_to_fraction():
    log = SearchLog(people_total=10, budget_s=100.0)
    log.found_times_s = [3.0, 5.0, 8.0, 13.0, 21.0, 34.0, 55.0]
    assert log.time_to_fraction_s(0.1) == 3.0
    assert log.time_to_fraction_s(0.7) == 55.0  # ceil(7.000000000000001) would say 8
    assert log.time_to_fraction_s(0.65) == 55.0
    assert log.time_to_fraction_s(0.8) == math.inf
    with pytest.raises(ActionInputError, match="fraction"):
        log.time_to_fraction_s(0.0)


def test_map_sums_are_exact_after_every_image_without_a_whole_map_pass():
    """sum p and P(all found) of the log equal the whole-map sums after every image to rounding,
    on a 150 x 150-cell map (its last tiles partial) over more than 256 images, while the update
    reads no more than the tiles the footprint touches."""
    world = make_world(150.0, 1.0, 4, seed=4, n_buildings=2)
    settings = SearchSettings(budget_s=150.0, n_uavs=2, model=DetectionModel(false_detections_at_best=0.5))
    planner = FieldLawnmowerPlanner(30.0, camera=settings.camera, n_uavs=2, buildings=world.buildings)

    def check(image, belief, log):
        assert log.expected_people[-1] == pytest.approx(belief.expected_people(), rel=1e-12)
        assert log.p_all_found[-1] == pytest.approx(belief.p_all_found(settings.target_threshold), rel=1e-10, abs=1e-300)

    log = fly_search(world, planner, settings, seed=5, on_image=check)
    assert log.images > 256


def test_map_update_is_timed_with_the_garbage_collector_paused(monkeypatch):
    world = make_world(100.0, 1.0, 3, seed=1)
    settings = SearchSettings(budget_s=10.0)
    during = []
    fuse = search_mission._MapTracker.fuse

    def recording(self, image):
        during.append(gc.isenabled())
        fuse(self, image)

    monkeypatch.setattr(search_mission._MapTracker, "fuse", recording)
    assert gc.isenabled()
    log = fly_search(world, HoverPlanner(), settings, seed=0)
    assert during and not any(during) and len(log.map_update_ms) == len(during)
    assert gc.isenabled()
