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
mission with its files, ``attend search``)."""

from __future__ import annotations

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562): a
#: command that needs one part of the action package does not load the others (the paper's
#: Gaussian map imports scipy.linalg, the planners scipy.stats).
_EXPORTS = {
    "ActionInputError": "attend.action.errors",
    "AdaptivePlanner": "attend.action.planners",
    "Camera": "attend.action.camera",
    "confirmation_value": "attend.action.planners",
    "CoverConfirmPlanner": "attend.action.planners",
    "DetectionModel": "attend.action.detection",
    "detections": "attend.action.planners",
    "Detector": "attend.action.camera",
    "EpisodeLog": "attend.action.episode",
    "ExpectedFreeEnergyPlanner": "attend.action.planners",
    "ExpectedFreeEnergySearchPlanner": "attend.action.planners.salience",
    "FieldLawnmowerPlanner": "attend.action.planners.field_lawnmower",
    "FlightModel": "attend.action.flight",
    "fly": "attend.action.episode",
    "fly_search": "attend.action.search_mission",
    "FOUND_THRESHOLD": "attend.action.metrics",
    "GaussianProcessPrior": "attend.action.belief",
    "Grid": "attend.action.field",
    "Image": "attend.action.camera",
    "ImageObservation": "attend.action.probability_map",
    "kalman_update": "attend.action.belief",
    "kalman_update_diagonal": "attend.action.belief",
    "LawnmowerPlanner": "attend.action.planners",
    "make_field": "attend.action.field",
    "make_planner": "attend.action.planners",
    "make_world": "attend.action.world",
    "map_metrics": "attend.action.metrics",
    "MapGrid": "attend.action.probability_map",
    "noise_variance": "attend.action.camera",
    "observation_gains": "attend.action.belief",
    "Obstacle": "attend.action.field",
    "OccupancyMap": "attend.action.belief",
    "PAPER_PRIOR": "attend.action.belief",
    "Person": "attend.action.field",
    "PlanContext": "attend.action.episode",
    "Planner": "attend.action.planners",
    "PLANNERS": "attend.action.planners",
    "PlanningSetup": "attend.action.planners",
    "PrecisionGainPlanner": "attend.action.planners",
    "prior_covariance": "attend.action.belief",
    "ProbabilityMap": "attend.action.probability_map",
    "RandomPlanner": "attend.action.planners",
    "ReplanPolicy": "attend.action.episode",
    "root_squared_error": "attend.action.metrics",
    "run_probability_search": "attend.action.search_run",
    "run_search": "attend.action.paper_search",
    "SearchConfirmPlanner": "attend.action.planners",
    "SearchField": "attend.action.field",
    "SearchLog": "attend.action.search_mission",
    "SearchPlanner": "attend.action.planners.search_base",
    "SearchSettings": "attend.action.search_mission",
    "SearchWorld": "attend.action.world",
    "simulate_image": "attend.action.world",
    "take_image": "attend.action.camera",
    "world_from_field": "attend.action.world",
}

__all__ = ["ActionInputError", "DetectionModel", "ExpectedFreeEnergySearchPlanner", "FieldLawnmowerPlanner", "ImageObservation", "MapGrid", "ProbabilityMap", "SearchLog", "SearchPlanner", "SearchSettings", "SearchWorld", "fly_search", "make_world", "run_probability_search", "simulate_image", "world_from_field", "AdaptivePlanner", "Camera", "CoverConfirmPlanner", "Detector", "EpisodeLog", "ExpectedFreeEnergyPlanner", "FOUND_THRESHOLD", "FlightModel", "GaussianProcessPrior", "Grid", "Image", "LawnmowerPlanner", "Obstacle", "OccupancyMap", "PAPER_PRIOR", "PLANNERS", "Person", "PlanContext", "Planner", "PlanningSetup", "PrecisionGainPlanner", "RandomPlanner", "ReplanPolicy", "SearchConfirmPlanner", "SearchField", "confirmation_value", "detections", "fly", "kalman_update", "kalman_update_diagonal", "make_field", "make_planner", "map_metrics", "noise_variance", "observation_gains", "prior_covariance", "root_squared_error", "run_search", "take_image"]


__getattr__, __dir__ = lazy_exports("attend.action", _EXPORTS, globals())
