"""ProbabilityMap and MapGrid: the update against brute-force Bayes, calibration on simulated
images, negative information, locality, closed forms of the summaries, targets, size."""

import itertools
import time
import tracemalloc

import numpy as np
import pytest

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.field import Grid
from attend.action.probability_map import ImageObservation, MapGrid, ProbabilityMap
from attend.action.world import make_world, simulate_image


def image_over(grid, window, detections=(), altitude=30.0, speed=0.0, visible=None):
    rows, cols = window
    shape = (rows.stop - rows.start, cols.stop - cols.start)
    visible = np.ones(shape, dtype=bool) if visible is None else visible
    return ImageObservation(np.array([0.0, 0.0, altitude]), 0.0, speed, window, visible, np.asarray(detections, float).reshape(-1, 2))


# --- grid ---------------------------------------------------------------------------------


def test_square_grid_has_the_old_fields_cells_and_window_matches_the_old_camera():
    old = Grid()
    grid = MapGrid.square(old.size_m, old.cell_size_m)
    yy, xx = np.meshgrid(grid.centres_y, grid.centres_x, indexing="ij")
    np.testing.assert_allclose(np.column_stack([xx.ravel(), yy.ravel()]), old.cell_centres())
    for pose in ([0.0, 0.0, 10.0], [-12.3, 7.9, 17.0], [14.0, -14.0, 6.0]):
        mask = Camera().visible_cells(np.array([pose]), old)[0].reshape(old.shape)
        rows, cols = grid.window(pose[0], pose[1], *[float(w) for w in Camera().footprint_m(pose[2])])
        expected = np.zeros(grid.shape, dtype=bool)
        expected[rows, cols] = True
        np.testing.assert_array_equal(mask, expected)


def test_window_is_the_cells_with_centres_in_the_rectangle():
    grid = MapGrid(37, 23, 1.7, (-5.0, 11.0))
    rng = np.random.default_rng(0)
    yy, xx = np.meshgrid(grid.centres_y, grid.centres_x, indexing="ij")
    for _ in range(200):
        x, y = rng.uniform(-30, 80), rng.uniform(-10, 70)
        wx, wy = rng.uniform(0, 40, 2)
        rows, cols = grid.window(x, y, wx, wy)
        inside = (np.abs(xx - x) <= wx / 2) & (np.abs(yy - y) <= wy / 2)
        got = np.zeros(grid.shape, dtype=bool)
        got[rows, cols] = True
        np.testing.assert_array_equal(got, inside)


def test_cell_of_and_extent():
    grid = MapGrid(4, 3, 2.0, (1.0, -1.0))
    assert grid.extent_m == (1.0, 9.0, -1.0, 5.0)
    ix, iy = grid.cell_of([1.0, 2.9, 9.0, 0.99, 5.0], [-1.0, 0.0, 5.0, 0.0, 5.01])
    np.testing.assert_array_equal(ix, [0, 0, 3, -1, -1])
    np.testing.assert_array_equal(iy, [0, 0, 2, -1, -1])
    assert grid.n_cells == 12 and grid.shape == (3, 4) and grid.cell_area_m2 == 4.0


@pytest.mark.parametrize("kwargs, name", [({"nx": 0}, "nx"), ({"ny": 2.5}, "ny"), ({"cell_size_m": -1.0}, "cell_size_m"),
                                          ({"origin_m": (0.0, np.nan)}, "origin_m")])
def test_bad_grid_is_named(kwargs, name):
    base = dict(nx=3, ny=3, cell_size_m=1.0)
    base.update(kwargs)
    with pytest.raises(ActionInputError, match=name):
        MapGrid(**base)


# --- priors and closed-form summaries ------------------------------------------------------


def test_uniform_and_prior_map_closed_forms():
    grid = MapGrid(10, 10, 1.0)
    searchable = np.ones(grid.shape, dtype=bool)
    searchable[0, :] = False
    belief = ProbabilityMap.uniform(grid, 4.5, searchable)
    np.testing.assert_allclose(belief.probability[searchable], 4.5 / 90)
    assert np.all(belief.probability[~searchable] == 0) and np.all(np.isneginf(belief.log_odds[~searchable]))
    assert belief.expected_people() == pytest.approx(4.5)
    # one heavy cell: a proportional prior would give it 10 / 109 * 3 > 0.5; it is held at 0.5
    prior = np.ones(grid.shape)
    prior[5, 5] = 20.0
    belief = ProbabilityMap.from_prior_map(grid, prior, 3.0, searchable)
    p = belief.probability
    assert p[5, 5] == pytest.approx(0.5)
    assert p.sum() == pytest.approx(3.0)
    others = p[searchable].copy()
    others = others[others < 0.5]
    np.testing.assert_allclose(others, 2.5 / 89)


def test_expected_people_and_p_all_found_on_a_tiny_map():
    grid = MapGrid(2, 2, 1.0)
    p = np.array([[0.1, 0.2], [0.3, 0.4]])
    belief = ProbabilityMap(grid, np.log(p / (1 - p)))
    assert belief.expected_people() == pytest.approx(1.0)
    assert belief.targets(threshold=0.5, radius_m=0.5)[0].shape == (0, 2)
    assert belief.p_all_found(threshold=0.5, radius_m=0.5) == pytest.approx(0.9 * 0.8 * 0.7 * 0.6)
    # a target on the 0.9 cell (disc of radius 0.5 m: that cell alone) counts as found
    p = np.array([[0.1, 0.2], [0.3, 0.9]])
    belief = ProbabilityMap(grid, np.log(p / (1 - p)))
    positions, masses = belief.targets(threshold=0.5, radius_m=0.5)
    np.testing.assert_allclose(positions, [[1.5, 1.5]])
    np.testing.assert_allclose(masses, [0.9])
    assert belief.p_all_found(threshold=0.5, radius_m=0.5) == pytest.approx(0.9 * 0.8 * 0.7)


def test_bad_priors_are_named():
    grid = MapGrid(4, 4, 1.0)
    with pytest.raises(ActionInputError, match="relative_likelihood"):
        ProbabilityMap.from_prior_map(grid, np.zeros(grid.shape), 1.0)
    with pytest.raises(ActionInputError, match="relative_likelihood"):
        ProbabilityMap.from_prior_map(grid, -np.ones(grid.shape), 1.0)
    with pytest.raises(ActionInputError, match="relative_likelihood"):
        ProbabilityMap.from_prior_map(grid, np.ones((3, 4)), 1.0)
    with pytest.raises(ActionInputError, match="relative_likelihood"):
        ProbabilityMap.from_prior_map(grid, np.full(grid.shape, np.nan), 1.0)
    with pytest.raises(ActionInputError, match="expected_people"):
        ProbabilityMap.uniform(grid, 8.0)
    with pytest.raises(ActionInputError, match="expected_people"):
        ProbabilityMap.uniform(grid, 0.0)
    with pytest.raises(ActionInputError, match="searchable"):
        ProbabilityMap.uniform(grid, 1.0, np.ones((4, 4)))


# --- the update ----------------------------------------------------------------------------


def test_no_detection_scales_visible_searchable_cells_by_the_bernoulli_miss_and_nothing_else():
    grid = MapGrid(40, 30, 1.0)
    searchable = np.ones(grid.shape, dtype=bool)
    searchable[12:15, 18:22] = False
    belief = ProbabilityMap.uniform(grid, 3.0, searchable)
    before = belief.log_odds.copy()
    model = DetectionModel()
    window = grid.window(20.0, 15.0, 12.0, 9.0)
    rows, cols = window
    visible = np.ones((rows.stop - rows.start, cols.stop - cols.start), dtype=bool)
    visible[:, :3] = False
    belief.update(image_over(grid, window, altitude=45.0, speed=4.0, visible=visible), model, Camera())
    pd = float(model.detection_probability(45.0, 4.0))
    k = belief.neighbourhood_cells(float(model.position_error_m(45.0)))
    changed = np.zeros(grid.shape, dtype=bool)
    changed[rows, cols] = visible
    changed &= searchable
    d = np.where(changed, 1 / (1 + np.exp(-before)), 0.0)
    expected = before.copy()
    for iy, ix in zip(*np.nonzero(changed)):
        mass = d[max(iy - k, 0) : iy + k + 1, max(ix - k, 0) : ix + k + 1].sum()
        new_p = d[iy, ix] * (1 - pd) / (1 - pd * mass)
        expected[iy, ix] = np.log(new_p / (1 - new_p))
    np.testing.assert_allclose(belief.log_odds[changed], expected[changed], rtol=1e-10)
    np.testing.assert_array_equal(belief.log_odds[~changed], before[~changed])
    # the planners' booking of an empty image is the same update
    booked = ProbabilityMap(grid, before, searchable)
    booked.expected_no_detection_update([window], [45.0], model, Camera(), speeds_m_s=[4.0], visible=[visible])
    np.testing.assert_array_equal(booked.log_odds, belief.log_odds)


def cell_average_density(d, cell_low, cell_size, sigma, n=200):
    """f(d | c) by the midpoint rule over the cell (an independent reference for the erf form)."""
    u = cell_low[:, None] + (np.arange(n) + 0.5)[None, :] / n * cell_size
    gx = np.exp(-((d[0] - u[0]) ** 2) / (2 * sigma**2))
    gy = np.exp(-((d[1] - u[1]) ** 2) / (2 * sigma**2))
    return gx.mean() * gy.mean() / (2 * np.pi * sigma**2)


def brute_force_posterior(prior, detections, pd, kappa, sigma, cell_size=1.0):
    """Exact P(cell occupied | detections) on a tiny map by enumerating every occupancy (at most
    one person per cell, independent priors) and every assignment of detections to people or
    clutter (Poisson, density kappa); all cells in view."""
    ny, nx = prior.shape
    cells = [(iy, ix) for iy in range(ny) for ix in range(nx)]
    f = np.array([[cell_average_density(np.asarray(d), np.array([ix * cell_size, iy * cell_size]), cell_size, sigma)
                   for d in detections] for iy, ix in cells])
    posterior_mass = np.zeros(len(cells))
    evidence = 0.0
    for occupied in itertools.product([False, True], repeat=len(cells)):
        idx = [i for i, o in enumerate(occupied) if o]
        weight = np.prod([prior.flat[i] if o else 1 - prior.flat[i] for i, o in enumerate(occupied)])
        if weight == 0:
            continue
        # sum over injective maps detection -> person (or clutter)
        likelihood = 0.0
        for assignment in itertools.product([None] + idx, repeat=len(detections)):
            people = [a for a in assignment if a is not None]
            if len(set(people)) != len(people):
                continue
            term = (1 - pd) ** (len(idx) - len(people))
            for j, a in enumerate(assignment):
                term *= kappa if a is None else pd * f[a, j]
            likelihood += term
        evidence += weight * likelihood
        for i in idx:
            posterior_mass[i] += weight * likelihood
    return (posterior_mass / evidence).reshape(prior.shape)


def test_update_equals_exact_bayes_for_one_candidate_cell():
    """Only the middle cell can hold someone: the update is then exact (no approximation)."""
    grid = MapGrid(3, 3, 1.0)
    model = DetectionModel(max_detection_probability=0.8, false_detections_at_best=0.3, position_error_at_best_m=0.6)
    camera = Camera()
    pd = float(model.detection_probability(30.0))
    kappa = float(model.clutter_density_per_m2(30.0, camera))
    sigma = float(model.position_error_m(30.0))
    searchable = np.zeros(grid.shape, dtype=bool)
    searchable[1, 1] = True
    prior = np.zeros(grid.shape)
    prior[1, 1] = 0.3
    for detections in ([], [(1.5, 1.5)], [(1.2, 1.9), (2.7, 0.4)], [(1.5, 1.5), (1.6, 1.4)], [(4.0, 4.0)]):
        belief = ProbabilityMap.from_prior_map(grid, prior, 0.3, searchable)
        belief.update(image_over(grid, (slice(0, 3), slice(0, 3)), detections), model, camera)
        exact = brute_force_posterior(prior, detections, pd, kappa, sigma)
        assert belief.probability[1, 1] == pytest.approx(exact[1, 1], rel=1e-6)


def test_update_against_exact_bayes_with_several_candidate_cells():
    """Every cell of a 3 x 3 map may hold someone (p = 0.03; the exact posterior takes the cells
    as independent, at most one person each). One detection: the update (the map is one
    neighbourhood, one person) is within 20 % of the exact odds. Two detections 2.5 m apart:
    the exact posterior holds 1.9 people, the update at most one per neighbourhood (a known
    limit: people closer than the neighbourhood share one person's mass)."""
    grid = MapGrid(3, 3, 1.0)
    model = DetectionModel(max_detection_probability=0.8, false_detections_at_best=0.3, position_error_at_best_m=0.6)
    camera = Camera()
    pd = float(model.detection_probability(30.0))
    kappa = float(model.clutter_density_per_m2(30.0, camera))
    sigma = float(model.position_error_m(30.0))
    prior = np.full(grid.shape, 0.03)
    belief = ProbabilityMap.from_prior_map(grid, prior, prior.sum())
    belief.update(image_over(grid, (slice(0, 3), slice(0, 3)), [(1.5, 1.5)]), model, camera)
    exact = brute_force_posterior(prior, [(1.5, 1.5)], pd, kappa, sigma)
    odds, exact_odds = belief.probability / (1 - belief.probability), exact / (1 - exact)
    np.testing.assert_allclose(odds, exact_odds, rtol=0.20)
    belief = ProbabilityMap.from_prior_map(grid, prior, prior.sum())
    belief.update(image_over(grid, (slice(0, 3), slice(0, 3)), [(0.6, 0.7), (2.4, 2.2)]), model, camera)
    exact = brute_force_posterior(prior, [(0.6, 0.7), (2.4, 2.2)], pd, kappa, sigma)
    assert exact.sum() > 1.5 and belief.expected_people() < 1.0


def test_update_equals_its_closed_form_computed_directly():
    """The windowed, reach-limited update against the closed form evaluated densely over the
    whole footprint (every cell, every detection): agreement to the reach tolerance."""
    grid = MapGrid(40, 30, 1.0, (-20.0, -15.0))
    rng = np.random.default_rng(5)
    model = DetectionModel(false_detections_at_best=1.0, false_detections_at_useless=3.0)
    camera = Camera()
    p0 = rng.uniform(0.0, 0.2, grid.shape)
    p0[10:13, 20:23] = [[0.1, 0.3, 0.1], [0.3, 0.6, 0.3], [0.1, 0.3, 0.1]]
    searchable = np.ones(grid.shape, dtype=bool)
    searchable[2:5, 2:6] = False
    window = grid.window(0.0, 0.0, 30.0, 24.0)
    rows, cols = window
    visible = rng.random((rows.stop - rows.start, cols.stop - cols.start)) < 0.9
    detections = np.array([[1.3, -3.2], [1.9, -2.5], [-8.0, 6.0], [14.6, 11.0]])
    altitude = 40.0
    belief = ProbabilityMap(grid, np.log(p0 / (1 - p0)), searchable)
    before = belief.probability
    belief.update(image_over(grid, window, detections, altitude=altitude, visible=visible), model, camera)
    pd = float(model.detection_probability(altitude))
    kappa = float(model.clutter_density_per_m2(altitude, camera))
    sigma = float(model.position_error_m(altitude))
    k = belief.neighbourhood_cells(sigma)
    mask = visible & searchable[rows, cols]
    d = np.where(mask, before[rows, cols], 0.0)
    ys, xs = np.meshgrid(np.arange(rows.start, rows.stop), np.arange(cols.start, cols.stop), indexing="ij")
    f = np.array([[[cell_average_density(dj, np.array([grid.origin_m[0] + x, grid.origin_m[1] + y]), 1.0, sigma, n=400)
                    for x, y in zip(xr, yr)] for xr, yr in zip(xs, ys)] for dj in detections]) * mask
    expected = before.copy()
    for i, j in zip(*np.nonzero(mask)):
        near = (slice(max(i - k, 0), i + k + 1), slice(max(j - k, 0), j + k + 1))
        mass = min(d[near].sum(), 1 - 1e-9)
        numerator, denominator = 1 - pd, 1 - pd * mass
        for fj in f:
            local = (fj * d)[near].sum()
            others = kappa + pd * ((fj * d).sum() - local)
            numerator += pd * fj[i, j] / others
            denominator += pd * local / others
        expected[rows.start + i, cols.start + j] = d[i, j] * numerator / denominator
    np.testing.assert_allclose(belief.probability, expected, rtol=2e-3, atol=1e-12)


def test_posterior_is_calibrated_on_simulated_images():
    """Reliability of one image's update: among cells whose posterior p falls in a bin, the
    fraction that hold a person's centre matches the bin's mean p within 3 binomial standard
    errors plus 0.01 (the independent-cells approximation). Worlds of 40 m with 30 people in
    1600 cells (prior 0.019), clutter 0.5 per image."""
    model = DetectionModel(max_detection_probability=0.9, false_detections_at_best=0.5, false_detections_at_useless=3.0,
                           position_error_at_best_m=0.8)
    camera = Camera()
    probabilities, truths = [], []
    for seed in range(200):
        world = make_world(40.0, 1.0, 30, seed=seed)
        belief = ProbabilityMap.uniform(world.grid, 30.0, world.searchable)
        rng = np.random.default_rng(1000 + seed)
        pose = np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), 30.0])
        belief.update(simulate_image(world, pose, 0.0, 0.0, model, camera, rng), model, camera)
        truth = np.zeros(world.grid.shape, dtype=bool)
        ix, iy = world.grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])
        truth[iy, ix] = True
        probabilities.append(belief.probability.ravel())
        truths.append(truth.ravel())
    p, truth = np.concatenate(probabilities), np.concatenate(truths)
    edges = [0.0, 0.01, 0.05, 0.1, 0.2, 0.3, 0.45]
    for low, high in zip(edges[:-1], edges[1:]):
        chosen = (p >= low) & (p < high)
        n = chosen.sum()
        assert n >= 100, (low, high, n)
        mean_p, frequency = p[chosen].mean(), truth[chosen].mean()
        error = 3 * np.sqrt(mean_p * (1 - mean_p) / n) + 0.01
        assert abs(frequency - mean_p) <= error, (low, high, n, mean_p, frequency)


def test_update_touches_only_the_footprint_and_is_fast_on_a_million_cells():
    grid = MapGrid(1000, 1000, 1.0, (-500.0, -500.0))
    tracemalloc.start()
    belief = ProbabilityMap.uniform(grid, 20.0)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert belief.log_odds.shape == (1000, 1000) and belief.log_odds.dtype == np.float64
    assert belief.log_odds.nbytes + belief.searchable.nbytes <= 100e6
    assert peak <= 100e6
    model = DetectionModel(false_detections_at_best=2.0)
    camera = Camera()
    rng = np.random.default_rng(0)
    durations = []
    for k in range(40):
        before = belief.log_odds.copy()
        x, y = rng.uniform(-480, 480, 2)
        window = grid.window(x, y, *[float(w) for w in camera.footprint_m(32.0)])
        rows, cols = window
        assert 900 <= (rows.stop - rows.start) * (cols.stop - cols.start) <= 1100
        detections = np.column_stack([rng.uniform(x - 10, x + 10, 3), rng.uniform(y - 14, y + 14, 3)])
        image = ImageObservation(np.array([x, y, 32.0]), float(k), 10.0, window,
                                 np.ones((rows.stop - rows.start, cols.stop - cols.start), dtype=bool), detections)
        start = time.perf_counter()
        belief.update(image, model, camera)
        durations.append(time.perf_counter() - start)
        outside = np.ones(grid.shape, dtype=bool)
        outside[rows, cols] = False
        np.testing.assert_array_equal(belief.log_odds[outside], before[outside])
        assert np.all(np.isfinite(belief.log_odds))
    assert np.median(durations) < 10e-3


def test_copy_is_independent():
    grid = MapGrid(5, 5, 1.0)
    belief = ProbabilityMap.uniform(grid, 1.0)
    twin = belief.copy()
    twin.expected_no_detection_update([(slice(0, 2), slice(0, 2))], [30.0], DetectionModel(), Camera())
    assert belief.expected_people() == pytest.approx(1.0)
    assert twin.expected_people() < 1.0


# --- targets -------------------------------------------------------------------------------


def blob_map(grid, centres, masses, background=1e-5):
    p = np.full(grid.shape, background)
    for (x, y), mass in zip(centres, masses):
        ix, iy = grid.cell_of(x, y)
        weights = np.array([[0.05, 0.1, 0.05], [0.1, 0.4, 0.1], [0.05, 0.1, 0.05]])
        p[iy - 1 : iy + 2, ix - 1 : ix + 2] = mass * weights
    return ProbabilityMap(grid, np.log(p / (1 - p)))


def test_targets_on_known_blobs():
    grid = MapGrid(200, 200, 1.0, (-100.0, -100.0))
    # the last blob 4 m from the second: their 3 x 3 patches are 1 cell apart, their discs touch
    centres = [(-50.5, 20.5), (30.5, -70.5), (80.5, 80.5), (-10.5, -10.5), (34.5, -70.5)]
    masses = [0.95, 0.8, 0.7, 0.3, 0.9]  # the 0.3 blob is below the threshold
    belief = blob_map(grid, centres, masses)
    positions, found = belief.targets(threshold=0.5, radius_m=1.5)
    assert len(positions) == 4
    order = np.argsort(-found)
    np.testing.assert_allclose(found, np.sort(found)[::-1])
    expected = {(-50.5, 20.5): 0.95, (30.5, -70.5): 0.8, (80.5, 80.5): 0.7, (34.5, -70.5): 0.9}
    for (x, y), mass in expected.items():
        k = np.argmin(np.hypot(positions[:, 0] - x, positions[:, 1] - y))
        assert np.hypot(positions[k, 0] - x, positions[k, 1] - y) < 1e-3
        assert found[k] == pytest.approx(mass, abs=0.1)
    assert np.argmin(np.hypot(positions[order[0], 0] + 50.5, positions[order[0], 1] - 20.5)) == 0
    _, _, cells = belief.target_discs(threshold=0.5, radius_m=1.5)
    everything = np.concatenate(cells)
    assert len(np.unique(everything)) == len(everything)


def test_targets_are_fast_on_a_million_cells():
    grid = MapGrid(1000, 1000, 1.0, (-500.0, -500.0))
    rng = np.random.default_rng(3)
    centres = rng.uniform(-480, 480, (20, 2)).round() + 0.5
    belief = blob_map(grid, centres, np.full(20, 0.9))
    start = time.perf_counter()
    positions, _ = belief.targets()
    assert time.perf_counter() - start < 0.2
    assert len(positions) == 20


def test_whole_missions_are_calibrated():
    """150 seeded worlds of 60 m x 60 m (1 m cells, 3-6 people, clutter 0.5-3 per image), each
    searched by 20-60 images from random poses at 40-95 m (pd 0.25-0.95, sigma 0.7-1.6 m; every
    cell seen about 10 times). At the end: (a) targets of mass >= 0.9 hold a person within the
    found radius (3 m) as often as their mean mass says, within 3 binomial standard errors (the
    mass is capped at 1 for a person: it counts people in the disc); (b) sum p over the map
    is the true number of people within 5 % on average (measured: -1.4 % +- 0.2 % on 600
    missions: people missed at high altitude); (c) among missions with P(all found) >= 0.9,
    the fraction with every person within 3 m of a target matches the mean P within 3
    standard errors. Between 0.5 and 0.9 (about 12 of these missions) the bin is too small to
    test here; on 600 missions it reads 0.75 against 0.66 observed (docs/search.md)."""
    model = DetectionModel(false_detections_at_best=0.5, false_detections_at_useless=3.0)
    camera = Camera()
    masses, hits, ratios, p_all, all_found = [], [], [], [], []
    for seed in range(1000, 1150):
        rng = np.random.default_rng(seed)
        world = make_world(60.0, 1.0, int(rng.integers(3, 7)), seed=seed)
        n_images = int(rng.integers(20, 61))
        poses = np.column_stack([rng.uniform(-30, 30, n_images), rng.uniform(-30, 30, n_images), rng.uniform(40, 95, n_images)])
        belief = ProbabilityMap.uniform(world.grid, float(world.n_people), world.searchable)
        for k, pose in enumerate(poses):
            belief.update(simulate_image(world, pose, float(k), 0.0, model, camera, rng), model, camera)
        positions, found_masses = belief.targets(0.5)
        near = np.linalg.norm(positions[:, None] - world.people_m[None], axis=-1) <= 3.0
        masses.extend(np.minimum(found_masses, 1.0))
        hits.extend(near.any(axis=1))
        ratios.append(belief.expected_people() / world.n_people)
        p_all.append(belief.p_all_found(0.5))
        all_found.append(near.any(axis=0).all())
    masses, hits, p_all, all_found = map(np.asarray, (masses, hits, p_all, all_found))
    strong = masses >= 0.9
    mean, n = masses[strong].mean(), strong.sum()
    assert n >= 300 and abs(hits[strong].mean() - mean) <= 3 * np.sqrt(mean * (1 - mean) / n) + 1e-3
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.05)
    sure = p_all >= 0.9
    mean, n = p_all[sure].mean(), sure.sum()
    assert n >= 80 and abs(all_found[sure].mean() - mean) <= 3 * np.sqrt(mean * (1 - mean) / n) + 1e-3



def test_window_sums_and_maxima_equal_scipy_ndimage():
    """The target search's disc sums and 3 x 3 maxima (numpy windows) against scipy.ndimage."""
    import scipy.ndimage

    from attend.action.probability_map import _window_maxima_3x3, _window_sums

    rng = np.random.default_rng(7)
    for _ in range(30):
        values = rng.random((int(rng.integers(1, 25)), int(rng.integers(1, 25))))
        reach = int(rng.integers(0, 4))
        dy, dx = np.mgrid[-reach : reach + 1, -reach : reach + 1]
        kernel = (dy**2 + dx**2 <= reach**2 + 0.5).astype(float)
        expected = scipy.ndimage.correlate(values, kernel, mode="constant", cval=0.0)
        # sums of at most 49 numbers in [0, 1]: the order of additions changes the last bits only
        np.testing.assert_allclose(_window_sums(values, kernel), expected, rtol=0, atol=64 * np.finfo(float).eps)
        np.testing.assert_array_equal(_window_maxima_3x3(values),
                                      scipy.ndimage.maximum_filter(values, size=3, mode="constant", cval=-np.inf))
