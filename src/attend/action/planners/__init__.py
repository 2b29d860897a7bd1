"""Path planners behind one interface: ``plan(belief, pose, remaining_budget_s,
time_to_next_image_s) -> waypoints (w, 3) m``.

- :mod:`~attend.action.planners.base`: :class:`PlanningSetup` (what every planner knows) and
  :class:`Planner`;
- :mod:`~attend.action.planners.informative`: value per flight time, greedy lattice + CMA-ES:
  :class:`PrecisionGainPlanner`, :class:`AdaptivePlanner`;
- :mod:`~attend.action.planners.free_energy`: :class:`ExpectedFreeEnergyPlanner` ("efe") and
  its two-phase :class:`SearchConfirmPlanner` ("efe_confirm");
- :mod:`~attend.action.planners.cover_confirm`: :class:`CoverConfirmPlanner` (cover passes, then
  confirmation of every detection);
- :mod:`~attend.action.planners.baselines`: :class:`LawnmowerPlanner`, :class:`RandomPlanner`;
- :mod:`~attend.action.planners.registry`: :data:`PLANNERS` (name -> class), :func:`make_planner`.
"""

from attend.action.planners.base import ALTITUDE_LAYERS_M, Planner, PlanningSetup
from attend.action.planners.baselines import LawnmowerPlanner, RandomPlanner, coverage_stops
from attend.action.planners.cover_confirm import CoverConfirmPlanner, confirmation_value, detections
from attend.action.planners.free_energy import (
    ExpectedFreeEnergyPlanner,
    SearchConfirmPlanner,
    kalman_mean,
    occupancy_probability,
)
from attend.action.planners.informative import AdaptivePlanner, InformativePlanner, PrecisionGainPlanner
from attend.action.planners.registry import PLANNERS, make_planner

__all__ = [
    "ALTITUDE_LAYERS_M",
    "AdaptivePlanner",
    "CoverConfirmPlanner",
    "ExpectedFreeEnergyPlanner",
    "InformativePlanner",
    "LawnmowerPlanner",
    "PLANNERS",
    "Planner",
    "PlanningSetup",
    "PrecisionGainPlanner",
    "RandomPlanner",
    "SearchConfirmPlanner",
    "confirmation_value",
    "coverage_stops",
    "detections",
    "kalman_mean",
    "make_planner",
    "occupancy_probability",
]
