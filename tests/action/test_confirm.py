"""Cover-then-confirm planner: reading statistics, detections, the confirmation value against the
exact Kalman mean, the coverage pattern and option checks."""

import numpy as np
import pytest

from attend.action import ActionInputError, Camera, OccupancyMap, PlanningSetup, make_field, make_planner
from attend.action.planners.cover_confirm import CoverConfirmPlanner, confirmation_value, detections
from attend.action.planners import kalman_mean


def _field():
    return make_field(0)


def _blob(grid, ix0, iy0, width=2, height=3):
    side = grid.cells_per_side
    return np.array([(iy0 + a) * side + ix0 + b for a in range(height) for b in range(width)])


def test_mean_reading_is_the_precision_weighted_mean_of_the_readings():
    grid = _field().grid
    belief = OccupancyMap.prior(grid)
    cells = np.arange(10)
    belief.fuse(cells, np.where(cells < 5, 1.0, 0.05), 0.4)
    belief.fuse(cells[:3], np.full(3, 0.05), 0.8)
    expected = np.zeros(grid.n_cells)
    expected[:3] = (1.0 / 0.4 + 0.05 / 0.8) / (1 / 0.4 + 1 / 0.8)
    expected[3:5] = 1.0
    expected[5:10] = 0.05
    assert np.allclose(belief.mean_reading(), expected)
    twin = belief.copy()
    twin.fuse(cells[:1], np.ones(1), 0.4)
    assert np.allclose(belief.mean_reading(), expected)  # the copy owns its statistics


def test_detections_are_the_marked_cells_without_the_halo():
    grid = _field().grid
    belief = OccupancyMap.prior(grid)
    blob = _blob(grid, 10, 10)
    view = _blob(grid, 6, 6, width=10, height=10)
    belief.fuse(view, np.where(np.isin(view, blob), 1.0, 0.05), 0.4)
    lone = np.array([30 * 40 + 30])
    belief.fuse(lone, np.ones(1), 0.4)  # a single marked cell is not a detection
    groups = detections(belief)
    assert len(groups) == 1 and set(groups[0]) == set(blob)
    assert np.all(belief.mean[view[~np.isin(view, blob)]] < 0.5)


def test_blob_detection_count_counts_only_person_sized_detections():
    grid = _field().grid
    belief = OccupancyMap.prior(grid)
    blob = _blob(grid, 10, 10)
    view = _blob(grid, 6, 6, width=10, height=10)
    touching = blob.max() + 1  # right of the blob's last row, inside the view
    assert touching in view
    for _ in range(2):
        belief.fuse(view, np.where(np.isin(view, blob), 1.0, 0.05), 0.4)
    # an isolated false positive beside the blob, in a later image: marked by its mean reading
    # but never part of a person-sized detection, so it does not join the detection
    belief.fuse(np.array([touching]), np.ones(1), 0.1)
    assert belief.mean_reading()[touching] >= 0.3
    counts = np.zeros(grid.n_cells, dtype=int)
    counts[blob] = 2
    np.testing.assert_array_equal(belief.blob_detection_count, counts)
    groups = detections(belief)
    assert len(groups) == 1 and set(groups[0]) == set(blob)
    # two neighbouring false positives from different images are no detection either
    a, b = 30 * 40 + 30, 30 * 40 + 31
    belief.fuse(np.array([a, b]), np.array([1.0, 0.05]), 0.4)
    belief.fuse(np.array([a, b]), np.array([0.05, 1.0]), 0.4)
    assert len(detections(belief)) == 1
    assert belief.copy().blob_detection_count is not belief.blob_detection_count


def test_confirmation_value_matches_exact_kalman_means_of_both_outcomes():
    field = _field()
    grid = field.grid
    belief = OccupancyMap.prior(grid)
    blob = _blob(grid, 18, 18)
    view = _blob(grid, 14, 14, width=10, height=10)
    belief.fuse(view, np.where(np.isin(view, blob), 1.0, 0.05), 0.5)
    groups = detections(belief)
    r, tpr, margin = 0.33, 0.9, 0.05
    observed = view
    detected = kalman_mean(belief, observed, np.where(np.isin(observed, blob), 1.0, 0.05), r)
    missed = kalman_mean(belief, observed, np.full(len(observed), 0.05), r)
    cap = 0.5 + margin
    now = min(belief.mean[blob].min(), cap)
    expected = tpr * min(detected[blob].min(), cap) + (1 - tpr) * min(missed[blob].min(), cap) - now
    assert confirmation_value(belief, observed, r, tpr, groups, margin) == pytest.approx(expected, rel=1e-10, abs=1e-12)
    # a view that does not see the detection is worth nothing
    assert confirmation_value(belief, np.arange(40), r, tpr, groups, margin) == 0.0


def test_confirmation_value_works_on_the_diagonal_map():
    grid = _field().grid
    belief = OccupancyMap.prior(grid, diagonal=True)
    blob = _blob(grid, 18, 18)
    belief.fuse(blob, np.ones(len(blob)), 0.5)
    groups = detections(belief)
    after = kalman_mean(belief, blob, np.ones(len(blob)), 0.3)
    expected = min(after[blob].min(), 0.55) - belief.mean[blob].min()
    assert confirmation_value(belief, blob, 0.3, 1.0, groups) == pytest.approx(expected)


def test_cover_pattern_sees_every_cell_once_per_pass():
    field = _field()
    planner = make_planner("cover_confirm", PlanningSetup(field), 0)
    assert isinstance(planner, CoverConfirmPlanner)
    stops = planner.cover_pattern()
    assert len(stops) == 12 and np.all(stops[:, 2] == 13.0)
    seen = Camera().visible_cells(stops, field.grid).sum(axis=0)
    assert seen.min() >= 2
    assert np.allclose(stops[6:], stops[:6][::-1])


def test_after_coverage_the_planner_confirms_the_unfound_detection():
    field = _field()
    planner = make_planner("cover_confirm", PlanningSetup(field), 0, cover_passes=0)
    grid = field.grid
    belief = OccupancyMap.prior(grid)
    blob = _blob(grid, 28, 8)
    everything = np.arange(grid.n_cells)
    belief.fuse(everything, np.where(np.isin(everything, blob), 1.0, 0.05), 0.5)
    assert belief.mean[blob].min() < 0.5
    centre = grid.cell_centres()[blob].mean(axis=0)
    route = planner.plan(belief, np.array([centre[0], centre[1] + 5.0, 13.0]), 100.0, 6.0)
    goal = route[-1]
    assert np.hypot(*(goal[:2] - centre)) < 1e-6 and goal[2] <= 10.0
    seen = Camera().visible_cells(goal[None], grid)[0]
    assert seen[blob].all()


def test_with_nothing_to_confirm_the_planner_searches_the_least_observed_ground():
    field = _field()
    planner = make_planner("cover_confirm", PlanningSetup(field), 0, cover_passes=0)
    grid = field.grid
    belief = OccupancyMap.prior(grid)
    left = np.flatnonzero(grid.cell_centres()[:, 0] < 0)
    belief.fuse(left, np.full(len(left), 0.05), 0.5)
    goal = planner.plan(belief, np.array([0.0, 0.0, 13.0]), 100.0, 6.0)[-1]
    assert goal[0] > 0 and goal[2] == 14.0


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"cover_altitude_m": 40.0}, "cover_altitude_m"),
        ({"search_altitude_m": 0.5}, "search_altitude_m"),
        ({"cover_passes": -1}, "cover_passes"),
        ({"cover_passes": 1.5}, "cover_passes"),
        ({"reading_threshold": 0.05}, "reading_threshold"),
        ({"margin": 0.6}, "margin"),
        ({"search_below": -1.0}, "search_below"),
        ({"search_lattice": 0}, "search_lattice"),
    ],
)
def test_bad_options_name_the_field(kwargs, name):
    with pytest.raises(ActionInputError, match=name):
        make_planner("cover_confirm", PlanningSetup(_field()), 0, **kwargs)
