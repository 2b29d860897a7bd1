"""Precision-modulated action: informative path planning with precision maps for UAV search and
rescue (seed §4.3, Figs. 6-9).

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
from attend.action.episode import EpisodeLog, PlanContext, ReplanPolicy, fly
from attend.action.errors import ActionInputError
from attend.action.field import Grid, Obstacle, Person, SearchField, make_field
from attend.action.flight import FlightModel
from attend.action.metrics import FOUND_THRESHOLD, map_metrics, root_squared_error
from attend.action.mission import run_search
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
