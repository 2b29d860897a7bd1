"""Precision-modulated action: informative path planning with precision maps for UAV search and
rescue (seed §4.3, Figs. 6-9).

Data path: SearchField (people, obstacles) -> Camera + Detector (images at 0.15 Hz) ->
OccupancyMap (GP prior, Kalman fusion, precision map) -> Planner (expected precision gain,
adaptive, expected free energy, cover-then-confirm; lawnmower and random baselines) -> run_episode / run_search.
"""

from attend.action.belief import OccupancyMap, kalman_update, kalman_update_diagonal, observation_gains, prior_covariance
from attend.action.camera import Camera, Detector, Image, noise_variance, take_image
from attend.action.confirm import CoverConfirmPlanner, confirmation_value, detections
from attend.action.episode import EpisodeLog, PlanContext, ReplanPolicy, fly_mission, run_episode
from attend.action.errors import ActionInputError
from attend.action.field import Grid, Obstacle, Person, SearchField, make_field
from attend.action.flight import FlightModel
from attend.action.metrics import map_metrics, root_squared_error
from attend.action.mission import run_search
from attend.action.planners import (
    PLANNERS,
    AdaptivePlanner,
    ExpectedFreeEnergyPlanner,
    LawnmowerPlanner,
    Planner,
    PlanningSetup,
    PrecisionGainPlanner,
    RandomPlanner,
    SearchConfirmPlanner,
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
    "FlightModel",
    "Grid",
    "Image",
    "LawnmowerPlanner",
    "Obstacle",
    "OccupancyMap",
    "PLANNERS",
    "Person",
    "PlanContext",
    "Planner",
    "PlanningSetup",
    "PrecisionGainPlanner",
    "RandomPlanner",
    "SearchConfirmPlanner",
    "ReplanPolicy",
    "SearchField",
    "confirmation_value",
    "detections",
    "kalman_update",
    "kalman_update_diagonal",
    "fly_mission",
    "make_field",
    "make_planner",
    "map_metrics",
    "noise_variance",
    "observation_gains",
    "prior_covariance",
    "root_squared_error",
    "run_episode",
    "run_search",
    "take_image",
]
