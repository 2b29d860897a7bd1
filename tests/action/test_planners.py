"""Search-then-confirm expected free energy ("efe_confirm"): confirmation logic and option checks."""

import numpy as np
import pytest

from attend.action.belief import OccupancyMap, kalman_update
from attend.action.errors import ActionInputError
from attend.action.field import make_field
from attend.action.planners import PlanningSetup, SearchConfirmPlanner, kalman_mean, make_planner


@pytest.fixture(scope="module")
def field():
    return make_field(0)


def covered_belief(field, blobs, scale=0.1):
    """A belief whose field is covered (covariance ``scale`` times the prior's, below half), empty
    except ``blobs``: {((iy, ix), ...): means}."""
    belief = OccupancyMap.prior(field.grid)
    belief.covariance = belief.covariance * scale
    belief.mean[:] = 0.05
    for cells, means in blobs.items():
        flat = np.array([iy * 40 + ix for iy, ix in cells])
        belief.mean[flat] = means
    return belief


def centroid(field, belief, cells):
    flat = np.array([iy * 40 + ix for iy, ix in cells])
    w = belief.mean[flat]
    return (field.grid.cell_centres()[flat] * w[:, None]).sum(axis=0) / w.sum()


CONFIRMED = ((5, 5), (5, 6), (6, 5), (6, 6))
UNCONFIRMED = ((30, 30), (30, 31), (31, 30), (31, 31))


def test_registered_and_searches_at_its_search_altitude_before_the_field_is_covered(field):
    setup = PlanningSetup(field, cma_evaluations=6)
    planner = make_planner("efe_confirm", setup, 0)
    assert isinstance(planner, SearchConfirmPlanner) and planner.name == "efe_confirm"
    belief = OccupancyMap.prior(field.grid)
    assert planner._confirmation_target(belief, np.array(field.start_pose_m)) is None  # nothing covered: search
    waypoints = planner.plan(belief, np.array(field.start_pose_m), 150.0, 0.0)
    np.testing.assert_allclose(waypoints[:, 2], 14.0)


def test_confirmation_picks_the_unconfirmed_detection_not_the_confirmed_one(field):
    planner = make_planner("efe_confirm", PlanningSetup(field, cma_evaluations=0), 0)
    belief = covered_belief(field, {CONFIRMED: 0.9, UNCONFIRMED: [0.9, 0.9, 0.45, 0.45]})
    pose = np.array([-10.0, -10.0, 14.0])  # nearer the confirmed one
    waypoints = planner.plan(belief, pose, 100.0, 0.0)
    target = centroid(field, belief, UNCONFIRMED)
    np.testing.assert_allclose(waypoints, [[target[0], target[1], 8.0]])
    assert planner.confirmation_value(belief, waypoints[0]) > 0
    # after confirm_visits views of it, the planner searches again
    for _ in range(planner.confirm_visits - 1):
        planner.plan(belief, pose, 100.0, 0.0)
    assert planner._confirmation_target(belief, pose) is None
    # a confirmed map (every candidate cell above 0.5) holds nothing to confirm
    planner.reset(0)
    assert planner._confirmation_target(covered_belief(field, {CONFIRMED: 0.9, UNCONFIRMED: 0.9}), pose) is None


def test_confirmation_prefers_the_view_that_pushes_more_cells_across_the_threshold(field):
    planner = make_planner("efe_confirm", PlanningSetup(field, cma_evaluations=0), 0)
    few = ((5, 5), (5, 6), (6, 5), (6, 6))  # one ambiguous cell
    many = ((30, 30), (30, 31), (31, 30), (31, 31))  # three ambiguous cells
    belief = covered_belief(field, {few: [0.9, 0.9, 0.9, 0.45], many: [0.9, 0.45, 0.45, 0.45]}, scale=0.4)
    pose = np.array(field.grid.cell_centres()[5 * 40 + 5].tolist() + [8.0])  # right above the weaker one
    values = {name: planner.confirmation_value(belief, np.r_[centroid(field, belief, cells), 8.0])
              for name, cells in (("few", few), ("many", many))}
    assert values["many"] > values["few"] > 0
    target = planner._confirmation_target(belief, pose)
    np.testing.assert_allclose(target[:2], centroid(field, belief, many))


def test_kalman_mean_equals_the_full_update_mean(field):
    belief = OccupancyMap.prior(field.grid)
    rng = np.random.default_rng(0)
    cells = np.sort(rng.choice(field.grid.n_cells, 60, replace=False))
    z = np.where(rng.random(60) < 0.2, 1.0, 0.05)
    expected, _ = kalman_update(belief.mean, belief.covariance, cells, z, 0.33)
    np.testing.assert_allclose(kalman_mean(belief, cells, z, 0.33), expected, atol=1e-10)
    diagonal = OccupancyMap.prior(field.grid, diagonal=True)
    after = kalman_mean(diagonal, cells, z, 0.33)
    v = diagonal.covariance[cells]
    np.testing.assert_allclose(after[cells], 0.1 + v / (v + 0.33) * (z - 0.1))


def test_single_altitude_layer_refinement_keeps_the_altitude(field):
    setup = PlanningSetup(field, altitude_layers_m=(12.0,), cma_evaluations=12)
    waypoints = make_planner("precision_gain", setup, 0).plan(OccupancyMap.prior(field.grid), np.array(field.start_pose_m),
                                                              150.0, 0.0)
    assert np.all(np.isfinite(waypoints)) and np.allclose(waypoints[:, 2], 12.0)


@pytest.mark.parametrize("kwargs, name", [
    ({"search_altitude_m": 40.0}, "search_altitude_m"),
    ({"search_altitude_m": "high"}, "search_altitude_m"),
    ({"confirm_altitude_m": 1.0}, "confirm_altitude_m"),
    ({"confirm_candidate_mean": 0.6}, "confirm_candidate_mean"),
    ({"confirm_candidate_mean": 0.0}, "confirm_candidate_mean"),
    ({"confirm_ambiguous_mean": 0.1}, "confirm_ambiguous_mean"),
    ({"confirm_ambiguous_mean": 0.5}, "confirm_ambiguous_mean"),
    ({"confirm_visits": 1.5}, "confirm_visits"),
    ({"confirm_after_coverage": -0.1}, "confirm_after_coverage"),
])
@pytest.mark.parametrize("planner", ["efe", "efe_confirm"])
def test_confirmation_options_are_validated(field, planner, kwargs, name):
    with pytest.raises(ActionInputError, match=name):
        make_planner(planner, PlanningSetup(field), 0, **kwargs)
