"""Expected free energy search planner on the probability map (attend.action.planners.salience):
closed forms, summed-area tables, behaviour that must emerge from the score, several UAVs."""

import time

import numpy as np
import pytest
from scipy.special import logit

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.field import Obstacle
from attend.action.planners.salience import (
    ExpectedFreeEnergySearchPlanner,
    _Lattice,
    _take,
    binary_entropy,
    box_sums,
    mutual_information,
    rectangle_sums,
    summed_area_table,
)
from attend.action.probability_map import ImageObservation, MapGrid, ProbabilityMap
from attend.action.search_mission import SearchSettings, fly_search
from attend.action.world import footprint_window, make_world


def _map(grid: MapGrid, p: np.ndarray) -> ProbabilityMap:
    return ProbabilityMap(grid, logit(np.clip(p, 1e-12, 1 - 1e-12)))


def _footprint_contains(camera, waypoint, point) -> bool:
    width_x, width_y = camera.footprint_m(waypoint[2])
    return abs(point[0] - waypoint[0]) <= width_x / 2 and abs(point[1] - waypoint[1]) <= width_y / 2


def _paper_planner(**options):
    """The paper's detector and camera pace; both legs returned (the path the score chose)."""
    return ExpectedFreeEnergySearchPlanner(DetectionModel.paper(), Camera(), 5.0, 0.15, altitude_limits_m=(2.0, 26.0),
                                           fly_second_leg=True, **options)


# ------------------------------------------------------------------------------------------------
# closed forms


def test_mutual_information_matches_brute_force_joint_entropy():
    rng = np.random.default_rng(0)
    for _ in range(50):
        p, pd, pf = rng.uniform(0, 1, 3)
        joint = np.array([[(1 - p) * (1 - pf), (1 - p) * pf], [p * (1 - pd), p * pd]])  # rows: state, cols: reading

        def entropy(q):
            q = q[q > 0]
            return -np.sum(q * np.log(q))

        brute = entropy(joint.sum(axis=1)) + entropy(joint.sum(axis=0)) - entropy(joint.ravel())
        assert mutual_information(p, pd, pf) == pytest.approx(brute, abs=1e-12)


def test_mutual_information_vanishes_at_certainty_and_peaks_where_derived():
    for pd, pf in ((0.9, 0.01), (0.6, 0.2), (0.95, 0.0)):
        assert mutual_information(np.array([0.0, 1.0]), pd, pf) == pytest.approx([0.0, 0.0], abs=1e-15)
    # symmetric channel: maximum at p = 1/2
    p = np.linspace(0, 1, 200001)
    assert p[np.argmax(mutual_information(p, 0.9, 0.1))] == pytest.approx(0.5, abs=1e-5)
    # Z channel (pf = 0): dI/dp = 0 at p* pd = 1 / (1 + exp(H_b(pd) / pd))
    pd = 0.8
    expected = 1.0 / (1.0 + np.exp(binary_entropy(pd) / pd)) / pd
    assert p[np.argmax(mutual_information(p, pd, 0.0))] == pytest.approx(expected, abs=1e-5)


def test_binary_entropy_values():
    assert binary_entropy(np.array([0.0, 0.5, 1.0])) == pytest.approx([0.0, np.log(2), 0.0])


# ------------------------------------------------------------------------------------------------
# summed-area tables


def test_rectangle_sums_equal_direct_sums():
    rng = np.random.default_rng(1)
    values = rng.random((37, 53))
    table = summed_area_table(values)
    r0 = rng.integers(0, 38, 200)
    r1 = np.maximum(r0, rng.integers(0, 38, 200))
    c0 = rng.integers(0, 54, 200)
    c1 = np.maximum(c0, rng.integers(0, 54, 200))
    direct = [values[a:b, c:d].sum() for a, b, c, d in zip(r0, r1, c0, c1)]
    assert rectangle_sums(table, r0, r1, c0, c1) == pytest.approx(direct, rel=1e-12, abs=1e-12)


def test_footprint_ranges_match_grid_window_and_direct_sum():
    rng = np.random.default_rng(2)
    grid = MapGrid(41, 29, 0.75, origin_m=(-12.0, 3.0))
    lattice = _Lattice(grid)
    values = rng.random(grid.shape)
    table = summed_area_table(values)
    x0, x1, y0, y1 = grid.extent_m
    for _ in range(300):  # rectangles reaching over the edges too
        x, y = rng.uniform(x0 - 5, x1 + 5), rng.uniform(y0 - 5, y1 + 5)
        wx, wy = rng.uniform(0, 20, 2)
        rows, cols = grid.window(x, y, wx, wy)
        r0, r1, c0, c1 = lattice.ranges(np.array(x), np.array(y), wx / 2, wy / 2)
        assert (int(r0), int(r1), int(c0), int(c1)) == (rows.start, rows.stop, cols.start, cols.stop) or (
            rows.start == rows.stop or cols.start == cols.stop) and (r0 == r1 or c0 == c1)
        assert rectangle_sums(table, r0, r1, c0, c1) == pytest.approx(values[rows, cols].sum(), abs=1e-9)


def test_box_sums_clip_at_edges():
    values = np.random.default_rng(3).random((9, 12))
    out = box_sums(values, 2)
    for i in range(9):
        for j in range(12):
            assert out[i, j] == pytest.approx(values[max(i - 2, 0):i + 3, max(j - 2, 0):j + 3].sum())


# ------------------------------------------------------------------------------------------------
# behaviour that emerges from the score


def test_plan_looks_at_an_uncertain_cell_nearby():
    grid = MapGrid.square(300.0, 1.0)
    p = np.full(grid.shape, 1e-5)
    row, col = 180, 170  # centre (20.5, 30.5) m
    p[row, col] = 0.3
    target = (grid.centres_x[col], grid.centres_y[row])
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0)
    waypoints = planner.plan(_map(grid, p), 0, np.array([-20.0, -10.0, 30.0]), 600.0)
    assert any(_footprint_contains(planner.camera, w, target) for w in waypoints)
    # the first leg already ends over it
    leg_end = waypoints[1] if np.allclose(waypoints[0, :2], [-20.0, -10.0]) else waypoints[0]
    assert _footprint_contains(planner.camera, leg_end, target)


def test_plan_leaves_resolved_ground_for_far_unresolved_ground():
    grid = MapGrid.square(1000.0, 2.0)
    p = np.full(grid.shape, 1e-9)  # the vicinity: resolved
    far = grid.centres_x[None, :] > 300.0
    p[np.broadcast_to(far, grid.shape)] = 1e-3
    pose = np.array([-400.0, -400.0, 40.0])
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0)
    waypoints = planner.plan(_map(grid, p), 0, pose, 600.0)
    horizontal = waypoints[-1, 0] - pose[0]
    assert horizontal > 0.8 * np.hypot(*(waypoints[-1, :2] - pose[:2]))  # heading east, to x > 300 m
    assert np.hypot(*(waypoints[-1, :2] - pose[:2])) > planner.horizon_m  # beyond the local lattice


def test_paper_detection_gets_looked_at_again_and_not_from_higher_up():
    """After a detection the next plan images it (an image of its two legs covers it) from no higher
    than the broad-search altitude. (That it descends below the search altitude does not emerge
    with the paper detector: see the xfail below.)"""
    model, camera = DetectionModel.paper(), Camera()
    grid = MapGrid.square(30.0, 0.75)
    planner = _paper_planner()
    belief = ProbabilityMap.uniform(grid, 7.0)
    pose = np.array([-8.0, -8.0, 15.0])
    search = planner.plan(belief, 0, pose, 150.0)
    p = belief.probability.copy()
    row, col = 25, 25
    p[row, col] = 0.3  # an uncertain detection, below the target threshold
    looked = planner.plan(_map(grid, p), 0, pose, 140.0)
    target = (grid.centres_x[col], grid.centres_y[row])
    covering = [w for w in looked if _footprint_contains(camera, w, target)]
    assert covering
    assert min(w[2] for w in covering) <= search[:, 2].max() + 1e-9
    assert model.detection_probability(min(w[2] for w in covering)) > 0.5


@pytest.mark.xfail(reason="with DetectionModel.paper() one look from 15 m (pd 0.86, twice the footprint of 10 m) "
                          "scores above a descent to 10 m (pd 0.95): confirming lower does not emerge", strict=False)
def test_paper_confirming_look_is_lower_than_broad_search():
    model, camera = DetectionModel.paper(), Camera()
    grid = MapGrid.square(30.0, 0.75)
    planner = _paper_planner()
    belief = ProbabilityMap.uniform(grid, 7.0)
    pose = np.array([0.0, 0.0, 15.0])
    search_altitude = planner.plan(belief, 0, pose, 150.0)[:, 2].max()
    window = footprint_window(grid, pose, camera)
    visible = np.ones((window[0].stop - window[0].start, window[1].stop - window[1].start), dtype=bool)
    belief.update(ImageObservation(pose, 0.0, 5.0, window, visible, np.array([[1.5, 2.0]])), model, camera)
    confirm = planner.plan(belief, 0, pose, 140.0)
    covering = [w[2] for w in confirm if _footprint_contains(camera, w, (1.5, 2.0))]
    assert covering and min(covering) < search_altitude


# ------------------------------------------------------------------------------------------------
# several UAVs


def test_two_uavs_at_one_pose_get_different_first_waypoints_kept_apart():
    grid = MapGrid.square(400.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 10.0)
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, min_separation_m=10.0)
    pose = np.array([-150.0, -150.0, 30.0])
    first = planner.plan(belief, 0, pose, 600.0)
    second = planner.plan(belief, 1, pose, 600.0, others=[np.vstack([pose, first])])
    assert np.linalg.norm(first[0] - second[0]) >= 10.0
    for w in second:
        assert np.min(np.linalg.norm(np.vstack([pose, first]) - w, axis=1)) >= 10.0 - 1e-9


def test_booked_images_make_the_other_uav_look_elsewhere():
    grid = MapGrid.square(200.0, 1.0)
    p = np.full(grid.shape, 1e-6)
    p[120:140, 120:140] = 1e-2  # one valuable patch around (30, 30)
    belief = _map(grid, p)
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0)
    pose = np.array([0.0, 0.0, 30.0])
    first = planner.plan(belief, 0, pose, 600.0)
    before = belief.log_odds.copy()
    second = planner.plan(belief, 1, pose + [0.0, -15.0, 0.0], 600.0, others=[np.vstack([pose, first])])
    assert np.array_equal(belief.log_odds, before)  # the shared map is not touched
    assert not np.allclose(first[-1], second[-1])


# ------------------------------------------------------------------------------------------------
# missions, limits, validation


def test_mission_with_buildings_respects_limits():
    world = make_world(150.0, 1.0, 4, seed=3, n_buildings=3)
    settings = SearchSettings(budget_s=60.0, n_uavs=2)
    planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings)
    log = fly_search(world, planner, settings, seed=3)  # raises if a waypoint leaves the limits or hits a building
    assert log.images > 0 and log.area_covered_m2 > 0


def test_legs_avoid_building_boxes():
    grid = MapGrid.square(100.0, 1.0)
    building = Obstacle(10.0, 0.0, 10.0, 60.0, 120.0)  # a tall wall east of the UAV
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, buildings=(building,))
    p = np.full(grid.shape, 1e-6)
    p[:, 70:] = 1e-2  # value behind the wall
    waypoints = planner.plan(_map(grid, p), 0, np.array([-10.0, 0.0, 30.0]), 600.0)
    from attend.action.camera import segments_hit_box

    path = np.vstack([[-10.0, 0.0, 30.0], waypoints])
    assert not segments_hit_box(path[:-1], path[1:], building.bounds).any()


def test_plan_time_on_a_million_cells(capsys):
    """Reported, not asserted: a first plan (every value map computed) and a replan after one
    image (value maps recomputed on the changed tiles only)."""
    grid = MapGrid.square(1000.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 20.0)
    camera, model = Camera(), DetectionModel()
    planner = ExpectedFreeEnergySearchPlanner(model, camera, 10.0, 1.0)
    pose = np.array([-500.0, -500.0, 30.0])
    start = time.perf_counter()
    waypoints = planner.plan(belief, 0, pose, 600.0)
    first = time.perf_counter() - start
    pose = waypoints[-1]
    window = footprint_window(grid, pose, camera)
    visible = np.ones((window[0].stop - window[0].start, window[1].stop - window[1].start), dtype=bool)
    belief.update(ImageObservation(pose, 1.0, 10.0, window, visible, np.zeros((0, 2))), model, camera)
    start = time.perf_counter()
    waypoints = planner.plan(belief, 0, pose, 599.0)
    again = time.perf_counter() - start
    with capsys.disabled():
        print(f"\n  plan() on 1000 x 1000 cells: first {first:.3f} s, after an image {again:.3f} s")
    assert waypoints.shape[1] == 3


@pytest.mark.parametrize(
    "options, field",
    [
        ({"speed_m_s": 0.0}, "speed_m_s"),
        ({"image_rate_hz": -1.0}, "image_rate_hz"),
        ({"altitude_layers_m": (1.0, 500.0)}, "altitude_layers_m"),
        ({"altitude_limits_m": (50.0, 10.0)}, "altitude_limits_m"),
        ({"preference_nats_per_person": -1.0}, "preference_nats_per_person"),
        ({"horizon_m": 0.0}, "horizon_m"),
        ({"min_separation_m": -2.0}, "min_separation_m"),
        ({"target_threshold": 1.5}, "target_threshold"),
        ({"target_radius_m": 0.0}, "target_radius_m"),
        ({"climb_speed_m_s": 0.0}, "climb_speed_m_s"),
        ({"buildings": (object(),)}, "buildings"),
        ({"channel": "pixel"}, "channel"),
        ({"legs": 4}, "legs"),
        ({"beam_width": 0}, "beam_width"),
        ({"model": "paper"}, "model"),
        ({"camera": None}, "camera"),
    ],
)
def test_bad_arguments_name_the_argument(options, field):
    arguments = {"model": DetectionModel(), "camera": Camera(), "speed_m_s": 10.0, "image_rate_hz": 1.0}
    arguments.update(options)
    with pytest.raises(ActionInputError, match=field):
        ExpectedFreeEnergySearchPlanner(**arguments)


def test_bad_plan_input_names_the_argument():
    grid = MapGrid.square(50.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 2.0)
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0)
    with pytest.raises(ActionInputError, match="pose_m"):
        planner.plan(belief, 0, np.array([0.0, 0.0]), 100.0)
    with pytest.raises(ActionInputError, match="time_left_s"):
        planner.plan(belief, 0, np.array([0.0, 0.0, 30.0]), -1.0)
    with pytest.raises(ActionInputError, match="others"):
        planner.plan(belief, 0, np.array([0.0, 0.0, 30.0]), 100.0, others=[np.zeros((2, 2))])
    with pytest.raises(ActionInputError, match="allowed_legs"):
        planner.plan(belief, 0, np.array([0.0, 0.0, 30.0]), 100.0, allowed_legs="north only")


def test_allowed_legs_of_one_call_bound_that_call_only():
    """A call's filter replaces the planner's for that call: with legs allowed only east of the
    pose every waypoint lies east of it, and the planner keeps its own filter (None) after."""
    grid = MapGrid.square(300.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 5.0)
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, seed=2, fly_second_leg=True)
    pose = np.array([0.0, 0.0, 30.0])

    def east_only(starts, ends):
        return (ends[:, 0] >= pose[0]) & (starts[:, 0] >= pose[0])

    east = planner.plan(belief, 0, pose, 300.0, allowed_legs=east_only)
    assert np.all(east[:, 0] >= pose[0])
    assert planner.allowed_legs is None
    nothing = planner.plan(belief, 0, pose, 300.0, allowed_legs=lambda starts, ends: np.zeros(len(starts), bool))
    assert np.array_equal(nothing, pose[None])


def test_same_seed_same_plan():
    grid = MapGrid.square(200.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 5.0)
    a = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, seed=4)
    b = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, seed=4)
    pose = np.array([0.0, 0.0, 30.0])
    assert np.array_equal(a.plan(belief, 0, pose, 300.0), b.plan(belief, 0, pose, 300.0))


def test_cached_value_tables_equal_fresh_ones_after_map_changes():
    grid = MapGrid.square(300.0, 1.0)
    belief = ProbabilityMap.uniform(grid, 10.0)
    camera, model = Camera(), DetectionModel()
    cached = ExpectedFreeEnergySearchPlanner(model, camera, 10.0, 1.0)
    from attend.action.planners.salience import _Lattice as Lattice

    lattice = Lattice(grid)
    cached._value_tables(belief, lattice, 2.0)
    rng = np.random.default_rng(5)
    for k in range(3):
        pose = np.array([*rng.uniform(-140, 140, 2), 40.0])
        window = footprint_window(grid, pose, camera)
        visible = np.ones((window[0].stop - window[0].start, window[1].stop - window[1].start), dtype=bool)
        belief.update(ImageObservation(pose, float(k), 10.0, window, visible, pose[None, :2] + 3.0), model, camera)
        fresh = ExpectedFreeEnergySearchPlanner(model, camera, 10.0, 1.0)
        expected = fresh._value_tables(belief, lattice, 2.0)
        got = cached._value_tables(belief, lattice, 2.0)
        for table in range(expected.n_tables + 1):
            assert np.allclose(got.dense(table), expected.dense(table), rtol=1e-10, atol=1e-9)


def test_banded_summed_area_tables_equal_direct_sums_after_updates():
    """T_t[i, j] = sum V_t[:i, :j] at every corner, for bands that do and do not divide ny, after
    changes confined to a few rows; the extra table is zero."""
    from attend.action.planners.salience import BAND_ROWS, BandedSummedAreaTables

    rng = np.random.default_rng(11)
    for ny in (1, BAND_ROWS - 1, BAND_ROWS, 2 * BAND_ROWS, 2 * BAND_ROWS + 5):
        values = rng.normal(size=(3, ny, 17))
        tables = BandedSummedAreaTables(values)
        for _ in range(3):
            row0 = int(rng.integers(0, ny))
            row1 = int(rng.integers(row0 + 1, min(row0 + 7, ny) + 1))
            values[:, row0:row1] = rng.normal(size=(3, row1 - row0, 17))
            tables.update(values, {row // BAND_ROWS for row in range(row0, row1)})
            for t in range(3):
                direct = np.zeros((ny + 1, 18))
                direct[1:, 1:] = values[t].cumsum(axis=0).cumsum(axis=1)
                # partial sums of at most ny x 17 standard normals: rounding of order eps x count
                np.testing.assert_allclose(tables.dense(t), direct, rtol=0, atol=1e-13 * ny * 17)
            assert not tables.dense(3).any()
        r0, r1 = np.array([0, 1, ny - 1]), np.array([ny, ny, ny])
        c0, c1 = np.array([0, 3, 16]), np.array([17, 9, 17])
        direct = [values[1, a:b, c:d].sum() for a, b, c, d in zip(r0, r1, c0, c1)]
        np.testing.assert_allclose(tables.sums(1, r0, r1, c0, c1), direct, rtol=0, atol=1e-13 * ny * 17)


def test_footprint_follows_the_heading_when_the_camera_turns_with_the_uav():
    """A 60 x 45 degree camera at 40 m sees 2 h tan(30) = 46.2 m across-track and 2 h tan(22.5) =
    33.1 m along-track: along x for a north-south leg, along y for an east-west leg when the
    camera turns with the UAV; the paper's fixed camera keeps across-track along x."""
    from attend.action.planners.salience import _Lattice as Lattice

    grid = MapGrid.square(200.0, 1.0)
    lattice = Lattice(grid)
    camera = Camera(fov_x_deg=60.0, fov_y_deg=45.0)
    across, along = 2 * 40 * np.tan(np.radians(30)), 2 * 40 * np.tan(np.radians(22.5))
    starts = np.array([[0.0, 0.0, 40.0], [0.0, 0.0, 40.0]])
    ends = np.array([[0.0, 50.0, 40.0], [50.0, 0.0, 40.0]])  # north, east
    points = np.zeros((2, 1, 2))
    for turning, expected in ((True, [(across, along), (along, across)]), (False, [(across, along)] * 2)):
        planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), camera, 10.0, 1.0, altitude_layers_m=[40.0],
                                                  footprint_follows_heading=turning)
        r0, r1, c0, c1 = planner._footprint_ranges(lattice, points, np.array([0, 0]), starts, ends)
        for leg, (width_x, width_y) in enumerate(expected):
            # cells whose centres lie within the rectangle: its side in cells, to one cell
            assert abs((c1 - c0)[leg, 0] - width_x) <= 1.0 and abs((r1 - r0)[leg, 0] - width_y) <= 1.0


def test_three_collinear_legs_are_worth_the_straight_leg_they_make():
    """Along a straight leg the chain of looks is exact; split into three collinear legs at one
    altitude whose images fall where the straight leg's do (spacing s = 10 m), V_1 + V_2 + V_3
    (the third leg's chain running through the second leg's images, then the first's) equals the
    straight leg's value. Pure information (c_pref = 0), whose k-th look is worth less than the
    (k-1)-th, so the nearest-image bound never binds."""
    grid = MapGrid.square(300.0, 1.0)
    lattice = _Lattice(grid)
    rng = np.random.default_rng(3)
    belief = _map(grid, rng.uniform(1e-4, 0.05, grid.shape))
    planner = ExpectedFreeEnergySearchPlanner(DetectionModel(), Camera(), 10.0, 1.0, altitude_layers_m=[30.0],
                                              preference_nats_per_person=0.0, legs=3)
    tables = planner._value_tables(belief, lattice, 2.0)
    layer = np.array([0])
    pose, a, b, c = (np.array([x, 5.0, 30.0]) for x in (-100.0, -60.0, -30.0, 20.0))
    value1, _, ranges1, valid1, points1 = planner._leg_values(tables, lattice, pose[None], a[None], layer)
    value2, _ = planner._second_leg_values(tables, lattice, a[None], b[None], layer, _take(ranges1, 0),
                                           valid1[0], points1[0])
    value3, _ = planner._third_leg_values(tables, lattice, a, b, 0, _take(ranges1, 0), valid1[0], points1[0],
                                          c[None], layer)
    straight, *_ = planner._leg_values(tables, lattice, pose[None], c[None], layer)
    assert value1[0] > 0 and value3[0] > 0
    # sums of the same table entries in another order: equal to rounding
    assert value1[0] + value2[0] + value3[0] == pytest.approx(straight[0], rel=1e-10)


def test_three_legs_mission_with_buildings_respects_limits():
    """legs = 3, two UAVs among buildings: fly_search raises if a waypoint leaves the limits or
    hits a building; the beam changes which path is chosen, not the rules a path obeys."""
    world = make_world(150.0, 1.0, 4, seed=3, n_buildings=3)
    settings = SearchSettings(budget_s=60.0, n_uavs=2)
    planner = ExpectedFreeEnergySearchPlanner.for_world(world, settings, legs=3, beam_width=4)
    log = fly_search(world, planner, settings, seed=3)
    assert log.images > 0 and log.area_covered_m2 > 0 and log.separation_violations == 0

