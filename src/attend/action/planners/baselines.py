"""Baselines: :class:`LawnmowerPlanner` (serpentine coverage at 10 m, the spec's best pattern
that covers the field in budget, repeated until the budget is spent) and :class:`RandomPlanner`
(uniform random waypoints); :func:`coverage_stops`, the coverage lattice they and
cover_confirm fly."""

from __future__ import annotations

import numpy as np

from attend.action.flight import detour
from attend.action.planners.base import BEST_DETECTION_ALTITUDE_M, Planner, PlanningSetup


def coverage_stops(setup: PlanningSetup, altitude_m: float) -> np.ndarray:
    """The fewest image stops (m, 3) whose footprints at ``altitude_m`` tile the field, serpentine:
    columns spaced <= footprint width in x, rows <= footprint height in y; stops inside
    obstacles dropped.

    setup: the planning setup (field, camera); altitude_m: altitude of the stops [m]."""
    size = setup.field.grid.size_m
    width_x, width_y = setup.camera.footprint_m(altitude_m)
    columns = int(np.ceil(size / float(width_x)))
    rows = int(np.ceil(size / float(width_y)))
    xs = -size / 2 + (np.arange(columns) + 0.5) * size / columns
    ys = -size / 2 + (np.arange(rows) + 0.5) * size / rows
    stops = np.array([(x, y, altitude_m) for r, y in enumerate(ys) for x in (xs if r % 2 == 0 else xs[::-1])])
    return stops[~setup.inside_obstacle(stops)]



class LawnmowerPlanner(Planner):
    """Serpentine coverage at ``altitude_m`` with footprint-spaced stops (one image each), the
    pattern repeated back and forth until the budget is spent.

    setup: the planning setup; seed: unused (the pattern is fixed); altitude_m: coverage
    altitude [m] (the spec's baseline: 10 m); waypoints_per_plan: stops returned per plan."""

    name = "lawnmower"

    def __init__(self, setup: PlanningSetup, seed: int = 0, altitude_m: float = BEST_DETECTION_ALTITUDE_M, waypoints_per_plan: int = 3) -> None:
        self.altitude_m = altitude_m
        self.waypoints_per_plan = waypoints_per_plan
        super().__init__(setup, seed)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission at the beginning of the pattern; seed: reseeds (unused)."""
        super().reset(seed)
        self._pattern = self.pattern()
        self._next = 0

    def pattern(self) -> np.ndarray:
        """Stops (m, 3) of :func:`coverage_stops` at the lawnmower altitude."""
        return coverage_stops(self.setup, self.altitude_m)

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
        """The next ``waypoints_per_plan`` stops (with detours around obstacles).

        belief, remaining_budget_s, time_to_next_image_s: unused; pose: (x, y, z) [m]."""
        pose = np.asarray(pose, float)
        if self._next == 0 and len(self._pattern):
            # start the pattern at the end nearer to the UAV
            if np.linalg.norm(self._pattern[-1] - pose) < np.linalg.norm(self._pattern[0] - pose):
                self._pattern = self._pattern[::-1].copy()
        out = []
        current = pose
        for _ in range(self.waypoints_per_plan):
            if self._next >= len(self._pattern):
                self._pattern = self._pattern[::-1].copy()
                self._next = 1
            goal = self._pattern[self._next]
            self._next += 1
            route = detour(current, goal, self.setup.field.obstacles, self.setup.obstacle_margin_m + 0.5)
            out.extend(route)
            current = goal
        return np.array(out)


class RandomPlanner(Planner):
    """Uniform random waypoints in the field and between the lowest and highest altitude layer.

    setup: the planning setup; seed: seeds the waypoints; waypoints_per_plan: waypoints per plan."""

    name = "random"

    def __init__(self, setup: PlanningSetup, seed: int = 0, waypoints_per_plan: int = 3) -> None:
        self.waypoints_per_plan = waypoints_per_plan
        super().__init__(setup, seed)

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
        """``waypoints_per_plan`` random waypoints outside obstacles (with detours).

        belief, remaining_budget_s, time_to_next_image_s: unused; pose: (x, y, z) [m]."""
        half = self.setup.field.grid.size_m / 2 - 0.5
        low, high = min(self.setup.altitude_layers_m), max(self.setup.altitude_layers_m)
        out = []
        current = np.asarray(pose, float)
        while len(out) < self.waypoints_per_plan:
            goal = np.array([self.rng.uniform(-half, half), self.rng.uniform(-half, half), self.rng.uniform(low, high)])
            if self.setup.inside_obstacle(goal[None])[0]:
                continue
            out.extend(detour(current, goal, self.setup.field.obstacles, self.setup.obstacle_margin_m + 0.5))
            current = goal
        return np.array(out)
