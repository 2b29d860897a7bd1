"""Planners, episode runner and mission outputs: properties on short missions."""

import json

import numpy as np
import pytest

from attend.action.episode import fly
from attend.action.errors import ActionInputError
from attend.action.field import make_field
from attend.action.flight import path_collides
from attend.action.paper_search import run_search
from attend.action.planners import PLANNERS, PlanningSetup, make_planner
from attend.action.belief import OccupancyMap


@pytest.fixture(scope="module")
def buildings_setup():
    field = make_field(1, obstacles="buildings")
    return field, PlanningSetup(field, cma_evaluations=12)


@pytest.mark.parametrize("name", sorted(PLANNERS))
def test_planners_return_feasible_waypoints(name, buildings_setup):
    field, setup = buildings_setup
    planner = make_planner(name, setup, seed=2)
    pose = np.array(field.start_pose_m)
    waypoints = planner.plan(OccupancyMap.prior(field.grid), pose, 150.0, 0.0)
    assert waypoints.ndim == 2 and waypoints.shape[1] == 3 and len(waypoints) >= 1
    half = field.grid.size_m / 2
    assert np.all(np.abs(waypoints[:, :2]) <= half)
    low, high = field.altitude_limits_m
    assert np.all((waypoints[:, 2] >= low) & (waypoints[:, 2] <= high))
    path = np.vstack([pose, waypoints])[None]
    assert not path_collides(path, field.obstacles, margin_m=0.0)[0]


@pytest.mark.parametrize("exact_candidates", [0, 4])
def test_precision_gain_choice_beats_lattice_candidates_on_its_objective(exact_candidates):
    """Screening only: best on the coarse score; with exact re-scoring: best on the exact
    full-covariance score (here the exact best is among the screened top 4)."""
    field = make_field(0)
    setup = PlanningSetup(field, cma_evaluations=0, lookahead_waypoints=1, exact_candidates=exact_candidates)
    planner = make_planner("precision_gain", setup)
    belief = OccupancyMap.prior(field.grid)
    pose = np.array(field.start_pose_m)
    chosen = planner.plan(belief, pose, 150.0, 0.0)
    from attend.action.planners.scoring import ExactModel, ScreeningModel

    model = ExactModel(belief, None) if exact_candidates else ScreeningModel(belief, setup, None)
    candidates = np.vstack([chosen, setup.lattice()])
    scores = planner._score_paths(model, belief, pose, candidates[:, None, :], 0.0, 150.0)
    assert scores[0] >= scores[1:].max() - 1e-9


def test_episode_logs_every_image_and_trace_never_increases():
    field = make_field(4)
    setup = PlanningSetup(field, cma_evaluations=6)
    log = fly(field, make_planner("lawnmower", setup), 40.0, seed=4)
    n_images = len(log.times_s)
    assert n_images == int(40.0 * 0.15) + 1  # one image every 6.67 s from t = 0
    for key in ("rse", "trace", "trace_interest", "people_found", "false_alarm_cells", "rmse"):
        assert len(log.series(key)) == n_images + 1
    assert np.all(np.diff(log.series("trace")) <= 1e-9)
    assert log.series("rse")[0] == pytest.approx(np.sqrt(np.sum((0.1 - field.truth) ** 2)))


def test_diagonal_filter_runs_and_is_less_informed_by_neighbours():
    field = make_field(5)
    setup = PlanningSetup(field, cma_evaluations=6)
    full = fly(field, make_planner("lawnmower", setup), 20.0, seed=5)
    diag = fly(field, make_planner("lawnmower", setup), 20.0, seed=5,
                       diagonal=True)
    assert diag.series("trace")[0] == pytest.approx(full.series("trace")[0])
    # without correlations an image only informs the cells it sees
    assert diag.series("trace")[-1] > full.series("trace")[-1]


def test_fly_rejects_bad_budget():
    field = make_field(0)
    setup = PlanningSetup(field)
    with pytest.raises(ActionInputError, match="budget_s"):
        fly(field, make_planner("random", setup), 0.0)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"budget_s": -5.0}, "budget_s"),
        ({"fov_deg": (180.0, 60.0)}, "fov_deg"),
        ({"fov_deg": (45.0, 0.0)}, "fov_deg"),
        ({"start_pose_m": (0.0, 20.0, 7.0)}, "start_pose_m"),
        ({"altitude_limits_m": (20.0, 5.0)}, "altitude_limits_m"),
        ({"planner": "astar"}, "planner"),
        ({"obstacles": "mountains"}, "obstacles"),
    ],
)
def test_run_search_bad_input(kwargs, name, tmp_path):
    with pytest.raises(ValueError, match=name):
        run_search(out_dir=tmp_path, **kwargs)


def test_run_search_writes_outputs(tmp_path):
    paths = run_search("precision_gain", seed=1, budget_s=14.0, out_dir=tmp_path, cma_evaluations=6)
    for key in ("metrics", "maps", "path_3d", "metrics_plot", "gif"):
        assert paths[key].exists() and paths[key].stat().st_size > 0
    data = json.loads(paths["metrics"].read_text())
    assert len(data["per_image"]["rse"]) == len(data["per_image"]["time_s"]) == 4  # prior + 3 images
    assert data["summary"]["people_total"] == 7


def test_injected_false_detection_is_resolved_by_revisits():
    field = make_field(3, people_region="lower_half")
    setup = PlanningSetup(field)
    log = fly(field, make_planner("lawnmower", setup), 150.0, seed=3,
                      inject_false_detection_images=(0,))
    blob = log.clutter_cells[0]
    assert len(blob) == 6 and np.all(field.truth[blob] == 0)
    blob_mean = np.array([m[blob].mean() for m in log.means])
    assert blob_mean[1] > 0.5  # the false detection looks like a person at first
    assert blob_mean[-1] < 0.4  # the lawnmower's revisits (no detection there) resolve it
    assert log.series("false_alarm_objects")[-1] == 0


def test_coarse_grained_planning_gains_rank_candidates_like_exact_full_covariance():
    from attend.action.episode import belief_after_images
    from attend.action.planners.scoring import ScreeningModel

    field = make_field(0)
    setup_exact = PlanningSetup(field, planning_block_cells=1)
    belief = belief_after_images(field, setup_exact, ([10, 0, 10], [0, 5, 14], [-8, -8, 8]), seed=0)
    lattice = setup_exact.lattice()
    visible = setup_exact.camera.visible_cells(lattice, field.grid)[:, None, :]
    noise = setup_exact.detector.noise_variance(lattice[:, 2])[:, None]
    gains = {}
    for block in (1, 2):
        model = ScreeningModel(belief, PlanningSetup(field, planning_block_cells=block), None)
        gains[block], _ = model.gains(model.precision(visible, noise))
    # exact trace reduction equals the dense posterior formula for one candidate
    k = int(np.argmax(gains[1]))
    d = visible[k, 0] / noise[k, 0]
    posterior = np.linalg.inv(np.linalg.inv(belief.covariance) + np.diag(d))
    assert gains[1][k] == pytest.approx(np.trace(belief.covariance) - np.trace(posterior), rel=1e-6)
    ranks = [np.argsort(np.argsort(gains[b])) for b in (1, 2)]
    assert np.corrcoef(*ranks)[0, 1] > 0.95
    assert np.argmax(gains[2]) == k


def test_exact_rescoring_model_matches_dense_full_covariance_gains():
    from attend.action.episode import belief_after_images
    from attend.action.planners.scoring import ExactModel, ScreeningModel

    field = make_field(0)
    setup = PlanningSetup(field, planning_block_cells=1)
    belief = belief_after_images(field, setup, ([10, 0, 10], [0, 5, 14]), seed=0)
    lattice = setup.lattice()[::5]
    visible = setup.camera.visible_cells(lattice, field.grid)[:, None, :]
    noise = setup.detector.noise_variance(lattice[:, 2])[:, None]
    weights = np.random.default_rng(1).random(field.grid.n_cells)
    for cell_weights in (None, weights):
        dense, exact = ScreeningModel(belief, setup, cell_weights), ExactModel(belief, cell_weights)
        for _ in range(2):  # before and after conditioning on one image
            want = dense.gains(dense.precision(visible, noise), want_information=True)
            got = exact.gains(exact.precision(visible, noise), want_information=True)
            np.testing.assert_allclose(got[0], want[0], rtol=1e-9)
            np.testing.assert_allclose(got[1], want[1], rtol=1e-9)
            d = exact.precision(visible[:1], noise[:1])[0]
            dense.condition(d)
            exact.condition(d)
        np.testing.assert_allclose(exact.dense, dense.covariance, atol=1e-12)
    assert np.trace(belief.covariance) == pytest.approx(np.trace(exact.covariance))  # belief untouched


def test_exact_candidates_is_validated():
    with pytest.raises(ActionInputError, match="exact_candidates"):
        PlanningSetup(make_field(0), exact_candidates=-1)


@pytest.mark.parametrize("name", ["precision_gain", "efe"])
def test_greedy_exact_value_from_segments_equals_exact_path_score(name):
    """Chain rule: the exact segment values summed over the greedy path equal the exact score of
    the whole path (so the greedy path need not be re-scored at the end)."""
    from attend.action.episode import belief_after_images
    from attend.action.planners.scoring import ExactModel

    field = make_field(2)
    setup = PlanningSetup(field, cma_evaluations=6)
    planner = make_planner(name, setup, 0)
    belief = belief_after_images(field, setup, ([10, 0, 10], [0, 5, 14]), seed=0)
    seen = {}

    def spy(belief_, pose_, greedy, t_next, budget, model, exact=None, greedy_exact=None):
        exact_model = ExactModel(belief_, planner.cell_weights(belief_))
        seen["path"] = float(planner._score_paths(exact_model, belief_, pose_, greedy[None], t_next, budget)[0])
        seen["segments"] = greedy_exact
        return greedy

    planner._refine = spy
    planner.plan(belief, np.array([0.0, 0.0, 10.0]), 120.0, 2.0)
    assert seen["segments"] == pytest.approx(seen["path"], rel=1e-9)


def test_efe_confirmation_visits_the_unconfirmed_detection_once_the_field_is_covered():
    field = make_field(0)
    setup = PlanningSetup(field, cma_evaluations=0)
    planner = make_planner("efe", setup, 0, confirm_altitude_m=8.0, confirm_after_coverage=0.9, confirm_visits=1)
    belief = OccupancyMap.prior(field.grid)
    pose = np.array([0.0, 0.0, 10.0])
    assert planner._confirmation_target(belief, pose) is None  # nothing covered yet: search
    belief.covariance = belief.covariance * 0.1  # covered
    belief.mean[:] = 0.05
    blob = np.array([[20, 30], [20, 31], [21, 30], [21, 31]])  # (iy, ix) cells
    flat = blob[:, 0] * 40 + blob[:, 1]
    belief.mean[flat] = [0.9, 0.9, 0.55, 0.45]  # detected, not yet confirmed
    weights = belief.mean[flat]
    centre = (field.grid.cell_centres()[flat] * weights[:, None]).sum(axis=0) / weights.sum()  # mean-weighted
    waypoints = planner.plan(belief, pose, 100.0, 0.0)
    np.testing.assert_allclose(waypoints, [[centre[0], centre[1], 8.0]])
    assert planner._confirmation_target(belief, pose) is None  # visited confirm_visits times
    belief.mean[flat] = 0.9  # confirmed: no target
    planner.reset(0)
    assert planner._confirmation_target(belief, pose) is None


@pytest.mark.parametrize("kwargs, name", [({"confirm_altitude_m": 40.0}, "confirm_altitude_m"),
                                          ({"confirm_after_coverage": 1.5}, "confirm_after_coverage"),
                                          ({"confirm_visits": 0}, "confirm_visits")])
def test_efe_confirmation_options_are_validated(kwargs, name):
    with pytest.raises(ActionInputError, match=name):
        make_planner("efe", PlanningSetup(make_field(0)), 0, **kwargs)
