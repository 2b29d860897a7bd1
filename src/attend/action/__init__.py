"""Precision-modulated action: a UAV (or several) searching an area for people.

At field scale (the default of ``attend search``): :class:`DetectionModel` (detection
probability, clutter and position error by altitude) -> :class:`ProbabilityMap` (P(person) per
cell as log-odds, Bayes' rule on every image, 10^6 cells) -> :class:`ExpectedFreeEnergySearchPlanner`
(information gain plus the preference for confirming people, per second of flight) or
:class:`FieldLawnmowerPlanner` -> :func:`fly_search` (several UAVs on one map, images fused in
time order) -> :func:`run_probability_search` (one mission with its files). The ground:
:func:`make_world` (a square area with people and buildings) or :func:`world_from_field` (the
paper's field).

The paper's Gaussian occupancy map (Figs. 6-9):

Data path: SearchField (people, obstacles) -> Camera + Detector (images at 0.15 Hz) ->
OccupancyMap (GP prior, Kalman fusion, precision map) -> Planner (expected precision gain,
adaptive, expected free energy, cover-then-confirm; lawnmower and random baselines; all listed in
``PLANNERS``) -> :func:`fly` (one mission, the only flight loop) -> :func:`run_search` (one
mission with its files, ``attend search``).
"""

from attend.action.belief import (
    PAPER_PRIOR,
    GaussianProcessPrior,
    OccupancyMap,
    kalman_update,
    kalman_update_diagonal,
    observation_gains,
    prior_covariance,
)
from attend.action.camera import Camera, Detector, Image, noise_variance, take_image
from attend.action.detection import DetectionModel
from attend.action.episode import EpisodeLog, PlanContext, ReplanPolicy, fly
from attend.action.errors import ActionInputError
from attend.action.field import Grid, Obstacle, Person, SearchField, make_field
from attend.action.flight import FlightModel
from attend.action.metrics import FOUND_THRESHOLD, map_metrics, root_squared_error
from attend.action.paper_search import run_search
from attend.action.planners.field_lawnmower import FieldLawnmowerPlanner
from attend.action.planners.salience import ExpectedFreeEnergySearchPlanner
from attend.action.planners.search_base import SearchPlanner
from attend.action.probability_map import ImageObservation, MapGrid, ProbabilityMap
from attend.action.search_mission import SearchLog, SearchSettings, fly_search
from attend.action.search_run import run_probability_search
from attend.action.world import SearchWorld, make_world, simulate_image, world_from_field
from attend.action.planners import (
    PLANNERS,
    AdaptivePlanner,
    CoverConfirmPlanner,
    ExpectedFreeEnergyPlanner,
    LawnmowerPlanner,
    Planner,
    PlanningSetup,
    PrecisionGainPlanner,
    RandomPlanner,
    SearchConfirmPlanner,
    confirmation_value,
    detections,
    make_planner,
)

__all__ = [
    "ActionInputError",
    "DetectionModel",
    "ExpectedFreeEnergySearchPlanner",
    "FieldLawnmowerPlanner",
    "ImageObservation",
    "MapGrid",
    "ProbabilityMap",
    "SearchLog",
    "SearchPlanner",
    "SearchSettings",
    "SearchWorld",
    "fly_search",
    "make_world",
    "run_probability_search",
    "simulate_image",
    "world_from_field",
    "AdaptivePlanner",
    "Camera",
    "CoverConfirmPlanner",
    "Detector",
    "EpisodeLog",
    "ExpectedFreeEnergyPlanner",
    "FOUND_THRESHOLD",
    "FlightModel",
    "GaussianProcessPrior",
    "Grid",
    "Image",
    "LawnmowerPlanner",
    "Obstacle",
    "OccupancyMap",
    "PAPER_PRIOR",
    "PLANNERS",
    "Person",
    "PlanContext",
    "Planner",
    "PlanningSetup",
    "PrecisionGainPlanner",
    "RandomPlanner",
    "ReplanPolicy",
    "SearchConfirmPlanner",
    "SearchField",
    "confirmation_value",
    "detections",
    "fly",
    "kalman_update",
    "kalman_update_diagonal",
    "make_field",
    "make_planner",
    "map_metrics",
    "noise_variance",
    "observation_gains",
    "prior_covariance",
    "root_squared_error",
    "run_search",
    "take_image",
]
