"""What every planner shares: the mission setup (:class:`PlanningSetup`) and the interface
``Planner.plan(belief, pose, remaining_budget_s, time_to_next_image_s) -> waypoints (w, 3) m``."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from attend.action.belief import PAPER_PRIOR, GaussianProcessPrior, OccupancyMap
from attend.action.camera import Camera, Detector
from attend.action.errors import ActionInputError
from attend.action.field import SearchField
from attend.action.flight import FlightModel

#: The altitude layers [m] of the candidate lattice (the spec's 4 layers between 5 and 14 m).
ALTITUDE_LAYERS_M = (5.0, 8.0, 11.0, 14.0)
#: The altitude [m] where the detector is best (the default ``Detector.best_altitude_m``): the
#: adaptive planner's preferred altitude and the lawnmower's (the spec's baseline at 10 m).
BEST_DETECTION_ALTITUDE_M = 10.0


@dataclass(frozen=True)
class PlanningSetup:
    """What every planner knows about the mission.

    field: field geometry (grid, obstacles, altitude limits; the people are not used);
    camera, detector, flight: sensor and flight models; altitude_layers_m: candidate altitudes (m);
    lattice_per_side: candidate positions per side and layer; lookahead_waypoints: w (3-5);
    cma_evaluations: CMA-ES budget per replan (15-45); planning_block_cells: coarse-graining of
    the screening covariance (1: screen on the exact full covariance); exact_candidates: how many
    of the best screened candidates are re-scored on the exact full covariance at each greedy step
    and at the end of CMA-ES (0: decide on the screening scores alone); obstacle_margin_m:
    clearance kept from boxes (m); map_prior: the GP prior the mission's belief starts from (and
    the planners compare against).
    """

    # the mission: field, sensor and flight models
    field: SearchField
    camera: Camera = Camera()
    detector: Detector = Detector()
    flight: FlightModel = FlightModel()
    # candidate waypoints
    altitude_layers_m: tuple[float, ...] = ALTITUDE_LAYERS_M
    lattice_per_side: int = 4
    # optimiser: look-ahead and CMA-ES budget
    lookahead_waypoints: int = 3
    cma_evaluations: int = 24
    # scoring: screening covariance and exact re-scoring
    planning_block_cells: int = 2
    exact_candidates: int = 4
    # clearance from obstacles, and the prior the mission's map starts from
    obstacle_margin_m: float = 1.0
    map_prior: GaussianProcessPrior = PAPER_PRIOR

    def __post_init__(self) -> None:
        low, high = self.field.altitude_limits_m
        layers = tuple(float(h) for h in self.altitude_layers_m)
        if not layers or any(not low <= h <= high for h in layers):
            raise ActionInputError(
                f"altitude_layers_m: expected altitudes within altitude_limits_m [{low:g}, {high:g}] m, got {layers}"
            )
        if not 1 <= int(self.lookahead_waypoints) <= 8:
            raise ActionInputError(f"lookahead_waypoints: expected an integer in 1..8, got {self.lookahead_waypoints!r}")
        side = self.field.grid.cells_per_side
        if int(self.exact_candidates) != self.exact_candidates or self.exact_candidates < 0:
            raise ActionInputError(f"exact_candidates: expected an integer >= 0, got {self.exact_candidates!r}")
        if self.planning_block_cells < 1 or side % self.planning_block_cells:
            raise ActionInputError(
                f"planning_block_cells: expected a divisor of cells_per_side={side}, got {self.planning_block_cells!r}"
            )

    def lattice(self) -> np.ndarray:
        """Candidate waypoints (m, 3): a lattice_per_side^2 grid per altitude layer, collision-free."""
        half = self.field.grid.size_m / 2
        ticks = -half + (np.arange(self.lattice_per_side) + 0.5) * (2 * half / self.lattice_per_side)
        xx, yy = np.meshgrid(ticks, ticks, indexing="ij")
        points = np.array([[x, y, h] for h in self.altitude_layers_m for x, y in zip(xx.ravel(), yy.ravel())])
        return points[~self.inside_obstacle(points)]

    def inside_obstacle(self, points: np.ndarray) -> np.ndarray:
        """Whether each point (k, 3) m lies within ``obstacle_margin_m`` of an obstacle box, (k,) bool.

        points: (k, 3) positions (x, y, z) in m."""
        inside = np.zeros(len(points), dtype=bool)
        m = self.obstacle_margin_m
        for box in self.field.obstacles:
            x0, x1, y0, y1, _, z1 = box.bounds
            inside |= (
                (points[:, 0] >= x0 - m) & (points[:, 0] <= x1 + m) & (points[:, 1] >= y0 - m) & (points[:, 1] <= y1 + m)
                & (points[:, 2] <= z1 + m)
            )
        return inside


class Planner(ABC):
    """``plan(belief, pose, remaining_budget_s, time_to_next_image_s) -> waypoints (w, 3) in m``.

    setup: what the planner knows about the mission (:class:`PlanningSetup`); seed: seeds its
    random generator (CMA-ES, random waypoints)."""

    name = "planner"
    #: waypoints flown before the next replan (None: all of them)
    waypoints_per_replan: int | None = None

    def __init__(self, setup: PlanningSetup, seed: int = 0) -> None:
        self.setup = setup
        self.reset(seed)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission (clears any internal state); seed: reseeds the planner's random generator."""
        self.rng = np.random.default_rng(seed)

    @abstractmethod
    def plan(
        self, belief: OccupancyMap, pose: Sequence[float], remaining_budget_s: float, time_to_next_image_s: float = 0.0
    ) -> np.ndarray:
        """Next waypoints (w, 3) in m from ``pose`` (x, y, z) m.

        belief: the current map; remaining_budget_s: flight time left [s]; time_to_next_image_s:
        time until the camera's next image [s]."""
