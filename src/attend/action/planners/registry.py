"""Every planner by name, in one place: :data:`PLANNERS` and :func:`make_planner`."""

from __future__ import annotations

from attend.action.errors import ActionInputError
from attend.action.planners.base import Planner, PlanningSetup
from attend.action.planners.baselines import LawnmowerPlanner, RandomPlanner
from attend.action.planners.cover_confirm import CoverConfirmPlanner
from attend.action.planners.free_energy import ExpectedFreeEnergyPlanner, SearchConfirmPlanner
from attend.action.planners.informative import AdaptivePlanner, PrecisionGainPlanner

#: planner name -> planner class (the names ``attend search --planner`` accepts).
PLANNERS: dict[str, type[Planner]] = {
    planner.name: planner
    for planner in (
        PrecisionGainPlanner,
        AdaptivePlanner,
        ExpectedFreeEnergyPlanner,
        SearchConfirmPlanner,
        LawnmowerPlanner,
        RandomPlanner,
        CoverConfirmPlanner,
    )
}


def make_planner(name: str, setup: PlanningSetup, seed: int = 0, **options) -> Planner:
    """The planner called ``name``, one of :data:`PLANNERS` ("precision_gain", "adaptive", "efe",
    "efe_confirm", "cover_confirm", "lawnmower", "random").

    name: the planner's name; setup: the planning setup; seed: seeds the planner; ``options`` go
    to the planner's constructor. Raises ActionInputError for an unknown name."""
    try:
        cls = PLANNERS[name]
    except KeyError:
        raise ActionInputError(f"planner: expected one of {sorted(PLANNERS)}, got {name!r}") from None
    return cls(setup, seed, **options)
