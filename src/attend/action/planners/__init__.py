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

from attend._lazy import lazy_exports

#: Public name -> the module that defines it (imported on first use, PEP 562: a mission that
#: needs only the field-scale planner does not load the paper's Gaussian-process planners).
_EXPORTS = {
    **dict.fromkeys(("ALTITUDE_LAYERS_M", "Planner", "PlanningSetup"), "attend.action.planners.base"),
    **dict.fromkeys(("LawnmowerPlanner", "RandomPlanner", "coverage_stops"), "attend.action.planners.baselines"),
    **dict.fromkeys(("CoverConfirmPlanner", "confirmation_value", "detections"), "attend.action.planners.cover_confirm"),
    **dict.fromkeys(("ExpectedFreeEnergyPlanner", "SearchConfirmPlanner", "kalman_mean", "occupancy_probability"),
                    "attend.action.planners.free_energy"),
    **dict.fromkeys(("AdaptivePlanner", "InformativePlanner", "PrecisionGainPlanner"), "attend.action.planners.informative"),
    **dict.fromkeys(("PLANNERS", "make_planner"), "attend.action.planners.registry"),
}


__getattr__, __dir__ = lazy_exports("attend.action.planners", _EXPORTS, globals(), subpackages=False)


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
