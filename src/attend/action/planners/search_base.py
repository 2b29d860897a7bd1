"""The interface of planners on the probability map (:class:`attend.action.probability_map.ProbabilityMap`):
``SearchPlanner.plan(belief, uav, pose_m, time_left_s, others) -> waypoints (w, 3) m``.

One planner object plans for every UAV of a mission (``uav`` says which); ``others`` holds the
other UAVs' current pose and the rest of their plans, so that plans made one after another on
the shared map can be coordinated (kept apart, and not sent where another UAV will look).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Sequence

import numpy as np


class SearchPlanner(ABC):
    """``plan(belief, uav, pose_m, time_left_s, others) -> waypoints (w, 3)`` in m (x east, y
    north, z up; ground at z = 0).

    belief: the shared probability map; uav: index of the UAV to plan for; pose_m: its pose
    (x, y, z) [m]; time_left_s: its flight time left [s]; others: for every other UAV, an
    array (k, 3) [m] whose first row is its current pose and the rest its planned waypoints.
    """

    name = "search_planner"

    def reset(self, seed: int = 0) -> None:
        """Start a new mission; seed: reseeds any random choice of the planner."""
        self.rng = np.random.default_rng(seed)

    @abstractmethod
    def plan(
        self,
        belief,
        uav: int,
        pose_m: np.ndarray,
        time_left_s: float,
        others: Sequence[np.ndarray] = (),
    ) -> np.ndarray:
        """Next waypoints (w, 3) [m] for UAV ``uav`` from ``pose_m``.

        belief: the shared probability map; uav: which UAV; pose_m: its pose (x, y, z) [m];
        time_left_s: its flight time left [s]; others: per other UAV, its pose stacked on its
        remaining waypoints (k, 3) [m]."""
