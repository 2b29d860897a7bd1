"""SearchWorld: placement, buildings hiding the ground, simulated images, reproducibility, bad input."""

import numpy as np
import pytest

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.field import Obstacle, make_field
from attend.action.probability_map import MapGrid
from attend.action.world import SearchWorld, make_world, simulate_image, world_from_field

NO_CLUTTER = DetectionModel(false_detections_at_best=0.0, false_detections_at_useless=0.0)


def test_people_on_distinct_searchable_cells_and_buildings_as_drawn():
    world = make_world(300.0, 1.0, 50, seed=4, n_buildings=6)
    assert world.people_m.shape == (50, 2)
    ix, iy = world.grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])
    assert np.all(ix >= 0) and np.all(world.searchable[iy, ix])
    assert len(set(zip(ix, iy))) == 50
    x0, x1, y0, y1 = world.grid.extent_m
    assert len(world.buildings) == 6
    for box in world.buildings:
        bx0, bx1, by0, by1, _, top = box.bounds
        assert 8 <= box.width_m <= 30 and 8 <= box.depth_m <= 30 and 5 <= top <= 40
        assert bx0 >= x0 + 3 and bx1 <= x1 - 3 and by0 >= y0 + 3 and by1 <= y1 - 3
        under = (world.grid.centres_x[None, :] >= bx0) & (world.grid.centres_x[None, :] <= bx1) & \
            (world.grid.centres_y[:, None] >= by0) & (world.grid.centres_y[:, None] <= by1)
        assert not np.any(world.searchable & under)
    assert world.start_poses_m.shape == (8, 3)
    np.testing.assert_allclose(world.start_poses_m[0], [x0, y0, 30.0])


def test_seeded_reproducibility():
    a = make_world(200.0, 2.0, 10, seed=7, n_buildings=3, prior="informative")
    b = make_world(200.0, 2.0, 10, seed=7, n_buildings=3, prior="informative")
    c = make_world(200.0, 2.0, 10, seed=8, n_buildings=3, prior="informative")
    np.testing.assert_array_equal(a.people_m, b.people_m)
    np.testing.assert_array_equal(a.prior_map, b.prior_map)
    assert a.buildings == b.buildings
    assert not np.array_equal(a.people_m, c.people_m)
    pose = np.array([0.0, 0.0, 40.0])
    images = [simulate_image(a, pose, 0.0, 5.0, DetectionModel(), Camera(), np.random.default_rng(3)) for _ in range(2)]
    np.testing.assert_array_equal(images[0].detections_m, images[1].detections_m)


def test_informative_prior_places_people_by_the_prior():
    """Over 10 worlds of 300 x 300 cells with 200 people each, the share of people in the cells
    holding the top half of each world's prior mass is 1/2 (binomial error; 200 people in
    thousands of such cells: sampling without replacement changes little)."""
    shares = []
    for seed in range(10):
        world = make_world(300.0, 1.0, 200, seed=seed, prior="informative")
        prior = world.prior_map
        assert prior.sum() == pytest.approx(1.0)
        order = np.argsort(prior.ravel())[::-1]
        top = order[: np.searchsorted(np.cumsum(prior.ravel()[order]), 0.5) + 1]
        assert len(top) > 2000
        ix, iy = world.grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])
        shares.append(np.isin(iy * world.grid.nx + ix, top).mean())
    assert np.mean(shares) == pytest.approx(0.5, abs=3 * np.sqrt(0.25 / 2000))


def small_world(people, buildings=()):
    grid = MapGrid.square(60.0, 1.0)
    searchable = np.ones(grid.shape, dtype=bool)
    world = SearchWorld(grid, np.array(people, float).reshape(-1, 2), tuple(buildings), searchable, None,
                        np.array([[-30.0, -30.0, 30.0]]), (5.0, 120.0))
    under = world.building_cells()
    return SearchWorld(grid, world.people_m, world.buildings, ~under, None, world.start_poses_m, (5.0, 120.0))


def test_person_hidden_behind_a_building_is_never_detected():
    model = DetectionModel(max_detection_probability=1.0, low_altitude_loss=0.0, false_detections_at_best=0.0,
                           false_detections_at_useless=0.0)
    camera = Camera()
    # camera at (0, 0, 30); a 25 m tower between x = 4 and 8; a person at (10.2, 0.3): the sight
    # line reaches z = 30 (1 - 8 / 10.2) = 6.5 m at the tower's far face, below its top
    tower = Obstacle(6.0, 0.0, 4.0, 6.0, 25.0)
    hidden = small_world([[10.2, 0.3]], [tower])
    shown = small_world([[10.2, 0.3]])
    rng = np.random.default_rng(0)
    pose = np.array([0.0, 0.0, 30.0])
    image = simulate_image(hidden, pose, 0.0, 0.0, model, camera, rng)
    rows, cols = image.window
    ix, iy = hidden.grid.cell_of(10.2, 0.3)
    assert not image.visible[iy - rows.start, ix - cols.start]
    assert image.visible[iy - rows.start, ix - cols.start - 12]  # x = -1.8: in front of the tower
    for _ in range(200):
        assert len(simulate_image(hidden, pose, 0.0, 0.0, model, camera, rng).detections_m) == 0
    assert len(simulate_image(shown, pose, 0.0, 0.0, model, camera, rng).detections_m) == 1


def test_detection_frequency_and_position_error():
    model = DetectionModel(max_detection_probability=0.9, false_detections_at_best=0.0, false_detections_at_useless=0.0,
                           position_error_at_best_m=0.5)
    world = small_world([[2.3, -4.1]])
    rng = np.random.default_rng(1)
    h = 50.0
    pd, sigma = float(model.detection_probability(h)), float(model.position_error_m(h))
    trials = 3000
    errors = []
    for _ in range(trials):
        image = simulate_image(world, np.array([0.0, 0.0, h]), 0.0, 0.0, model, Camera(), rng)
        errors.extend(image.detections_m - world.people_m[0])
    assert len(errors) / trials == pytest.approx(pd, abs=4 * np.sqrt(pd * (1 - pd) / trials))
    assert np.std(np.ravel(errors)) == pytest.approx(sigma, rel=0.05)
    assert abs(np.mean(np.ravel(errors))) < 4 * sigma / np.sqrt(2 * len(errors))


def test_clutter_count_and_spread():
    model = DetectionModel(false_detections_at_best=1.5, false_detections_at_useless=3.0)
    camera = Camera()
    world = small_world(np.zeros((0, 2)))
    rng = np.random.default_rng(2)
    h = 50.0
    counts, positions = [], []
    for _ in range(3000):
        image = simulate_image(world, np.array([5.0, 0.0, h]), 0.0, 0.0, model, camera, rng)
        counts.append(len(image.detections_m))
        positions.extend(image.detections_m)
    rows, cols = image.window
    visible_area = (rows.stop - rows.start) * (cols.stop - cols.start) * world.grid.cell_area_m2
    mean = float(model.clutter_density_per_m2(h, camera)) * visible_area
    assert np.mean(counts) == pytest.approx(mean, abs=4 * np.sqrt(mean / 3000))
    assert np.var(counts) == pytest.approx(mean, rel=0.1)  # Poisson
    x0, x1, y0, y1 = world.grid.extent_m
    positions = np.array(positions)
    assert positions[:, 0].min() >= x0 + cols.start and positions[:, 0].max() <= x0 + cols.stop
    assert positions[:, 1].min() >= y0 + rows.start and positions[:, 1].max() <= y0 + rows.stop


def test_world_from_field_keeps_the_fields_cells_people_and_obstacles():
    field = make_field(3, obstacles="buildings")
    world = world_from_field(field)
    yy, xx = np.meshgrid(world.grid.centres_y, world.grid.centres_x, indexing="ij")
    np.testing.assert_allclose(np.column_stack([xx.ravel(), yy.ravel()]), field.grid.cell_centres())
    np.testing.assert_allclose(world.people_m, [[p.x_m, p.y_m] for p in field.people])
    np.testing.assert_array_equal(world.searchable.ravel(), ~field.obstacle_cells())
    np.testing.assert_allclose(world.start_poses_m[0], field.start_pose_m)
    assert world.altitude_limits_m == field.altitude_limits_m


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"area_m": -5.0}, "area_m"),
        ({"cell_size_m": 0.0}, "cell_size_m"),
        ({"cell_size_m": 500.0}, "cell_size_m"),
        ({"n_people": 0}, "n_people"),
        ({"n_people": 2.5}, "n_people"),
        ({"n_people": 10_001}, "n_people"),
        ({"n_buildings": -1}, "n_buildings"),
        ({"prior": "gaussian"}, "prior"),
        ({"seed": -3}, "seed"),
        ({"altitude_limits_m": (50.0, 10.0)}, "altitude_limits_m"),
        ({"area_m": 10000.0, "cell_size_m": 1.0}, "cell_size_m"),
    ],
)
def test_bad_input_is_named(kwargs, name):
    arguments = dict(area_m=100.0, cell_size_m=1.0, n_people=5, seed=0)
    arguments.update(kwargs)
    with pytest.raises(ActionInputError, match=name):
        make_world(**arguments)


def test_user_prior_map_is_the_worlds_and_places_the_people():
    """People only where the user's map is > 0, in proportion to it: the 20 x 60 cells of the
    southern third weigh 9, the rest 1, so 9 / (9 + 2) of the people fall there (binomial error
    over 40 worlds of 20 people); row 0 is the south edge."""
    grid = MapGrid.square(60.0, 1.0)
    user = np.ones(grid.shape)
    user[:20, :] = 9.0
    user[:, :5] = 0.0
    south = []
    for seed in range(40):
        world = make_world(60.0, 1.0, 20, seed=seed, prior_map=user)
        np.testing.assert_array_equal(world.prior_map, user)
        ix, iy = world.grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])
        assert np.all(user[iy, ix] > 0) and np.all(world.people_m[:, 0] >= grid.extent_m[0] + 5.0)
        south.append(np.mean(world.people_m[:, 1] < grid.extent_m[2] + 20.0))
    share = 9 * 20 / (9 * 20 + 40)
    assert np.mean(south) == pytest.approx(share, abs=3 * np.sqrt(share * (1 - share) / 800))
    assert world.prior_map is not user  # a copy: the user's array stays theirs


@pytest.mark.parametrize(
    "prior_map, kwargs",
    [
        (np.ones((59, 60)), {}),
        (np.full((60, 60), np.nan), {}),
        (-np.ones((60, 60)), {}),
        (np.pad(np.ones((1, 2)), ((0, 59), (0, 58))), {}),  # 2 cells > 0 for 3 people
        (np.ones((60, 60)), {"prior": "informative"}),
    ],
)
def test_bad_user_prior_map_is_named(prior_map, kwargs):
    with pytest.raises(ActionInputError, match="prior_map"):
        make_world(60.0, 1.0, 3, seed=0, prior_map=prior_map, **kwargs)
