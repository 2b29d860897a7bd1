"""Boustrophedon coverage of a large area on the probability map: the strongest simple baseline.

The area (the map grid's extent) is cut into n equal strips along x, one per UAV; in its strip,
UAV k flies north-south tracks at altitude h spaced d apart (default d = w_x(h) = 2 h tan(fov_x / 2),
the footprint's width across the track: no gap and no overlap). A strip of width W takes
n = ceil(W / d) tracks, the first and last half a spacing inside the strip's edges and the
others evenly between them (spacing (W - d) / (n - 1) <= d: when W / d is not whole, the
overlap is spread over all tracks rather than put in one near-duplicate track), joined end to
end (serpentine). When the
pattern ends the UAV flies it again backwards. Every leg is flown by
:func:`attend.action.flight.clear_route`: straight when it clears every building by half the
building margin, else around the buildings by the shortest path through their corners (widened
by the margin, inside the area), else over them below the altitude ceiling. A pattern waypoint
inside a building widened by half the margin (a roof above h near the area's edge) is skipped.

:func:`best_lawnmower` tunes h and d / w_x(h) on given worlds by the median time to find a
fraction (90 %) of the people.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from attend.action.camera import Camera
from attend.action.errors import ActionInputError
from attend.action.field import Obstacle
from attend.action.flight import clear_route, path_collides
from attend.action.planners.search_base import SearchPlanner
from attend.action.probability_map import MapGrid


class FieldLawnmowerPlanner(SearchPlanner):
    """Serpentine tracks over strip ``uav`` of ``n_uavs`` (module docstring).

    altitude_m: h [m]; track_spacing_m: d [m] (None: the footprint width w_x(h)); camera: the
    footprint; n_uavs: strips the area is cut into (UAV k flies strip k mod n_uavs);
    buildings: boxes to fly around; waypoints_per_plan: pattern waypoints returned per plan
    (>= 1); end_inset_m: how far inside the area's south and north edges the tracks turn [m]
    (0: at the edges); building_margin_m: how far outside the buildings detours turn [m] (half
    of it is the clearance kept); max_altitude_m: the ceiling of climbs over buildings [m] (the
    world's upper altitude limit).
    """

    name = "lawnmower"

    def __init__(
        self,
        altitude_m: float = 30.0,
        track_spacing_m: float | None = None,
        camera: Camera = Camera(),
        n_uavs: int = 1,
        buildings: Sequence[Obstacle] = (),
        waypoints_per_plan: int = 4,
        end_inset_m: float = 0.0,
        building_margin_m: float = 1.5,
        max_altitude_m: float = 120.0,
    ) -> None:
        if not (np.isfinite(altitude_m) and altitude_m > 0):
            raise ActionInputError(f"altitude_m: expected an altitude > 0 m, got {altitude_m!r}")
        if track_spacing_m is not None and not (np.isfinite(track_spacing_m) and track_spacing_m > 0):
            raise ActionInputError(f"track_spacing_m: expected a spacing > 0 m or None, got {track_spacing_m!r}")
        if not isinstance(n_uavs, (int, np.integer)) or isinstance(n_uavs, bool) or n_uavs < 1:
            raise ActionInputError(f"n_uavs: expected a whole number >= 1, got {n_uavs!r}")
        if not isinstance(waypoints_per_plan, (int, np.integer)) or waypoints_per_plan < 1:
            raise ActionInputError(f"waypoints_per_plan: expected a whole number >= 1, got {waypoints_per_plan!r}")
        if not (np.isfinite(end_inset_m) and end_inset_m >= 0):
            raise ActionInputError(f"end_inset_m: expected a distance >= 0 m, got {end_inset_m!r}")
        if not (np.isfinite(building_margin_m) and building_margin_m >= 0):
            raise ActionInputError(f"building_margin_m: expected a distance >= 0 m, got {building_margin_m!r}")
        if not (np.isfinite(max_altitude_m) and max_altitude_m > 0):
            raise ActionInputError(f"max_altitude_m: expected an altitude > 0 m, got {max_altitude_m!r}")
        self.altitude_m = float(altitude_m)
        self.max_altitude_m = float(max_altitude_m)
        self.camera = camera
        self.track_spacing_m = float(track_spacing_m) if track_spacing_m is not None else float(camera.footprint_m(altitude_m)[0])
        self.n_uavs = int(n_uavs)
        self.buildings = tuple(buildings)
        self.waypoints_per_plan = int(waypoints_per_plan)
        self.end_inset_m = float(end_inset_m)
        self.building_margin_m = float(building_margin_m)
        self.reset(0)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission: every UAV starts its pattern afresh; seed: unused (the pattern is
        not random)."""
        super().reset(seed)
        self._patterns: dict[int, np.ndarray] = {}
        self._next: dict[int, int] = {}

    def strip_pattern(self, grid: MapGrid, strip: int) -> np.ndarray:
        """Waypoints (m, 3) [m] of the serpentine over strip ``strip`` of the grid's area: the
        first track the westmost, flown northwards."""
        x_left, x_right, y_bottom, y_top = grid.extent_m
        width = (x_right - x_left) / self.n_uavs
        x0, x1 = x_left + strip * width, x_left + (strip + 1) * width
        d = self.track_spacing_m
        if width <= d:
            xs = np.array([(x0 + x1) / 2])
        else:
            n_tracks = int(np.ceil(width / d - 1e-9))
            xs = x0 + d / 2 + (width - d) / (n_tracks - 1) * np.arange(n_tracks)
        inset = min(self.end_inset_m, (y_top - y_bottom) / 2)
        south, north = y_bottom + inset, y_top - inset
        points = []
        for i, x in enumerate(xs):
            ends = (south, north) if i % 2 == 0 else (north, south)
            points.extend([(x, ends[0], self.altitude_m), (x, ends[1], self.altitude_m)])
        return np.array(points)

    def plan(self, belief, uav: int, pose_m: np.ndarray, time_left_s: float, others: Sequence[np.ndarray] = ()) -> np.ndarray:
        """The next ``waypoints_per_plan`` waypoints of UAV ``uav``'s pattern (with detours
        around buildings), from ``pose_m`` [m]; belief: gives the grid; time_left_s, others:
        unused."""
        pose = np.asarray(pose_m, dtype=float)
        if uav not in self._patterns:
            self._patterns[uav] = self._oriented(self.strip_pattern(belief.grid, uav % self.n_uavs), pose)
            self._next[uav] = 0
        pattern = self._patterns[uav]
        chosen = []
        for _ in range(self.waypoints_per_plan):
            if self._next[uav] >= len(pattern):
                pattern = self._patterns[uav] = pattern[::-1].copy()
                self._next[uav] = 1 if len(pattern) > 1 else 0
            chosen.append(pattern[self._next[uav]])
            self._next[uav] += 1
        reachable = [w for w in chosen if not self._in_building(w)]
        if not reachable:
            return pose[None].copy()
        return self._around_buildings(pose, np.array(reachable), belief.grid.extent_m)

    def _oriented(self, pattern: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """Of the pattern's four mirror images (west/east first, north/south first), the one
        that starts nearest ``pose``."""
        x_mid = (pattern[:, 0].min() + pattern[:, 0].max()) / 2
        y_mid = (pattern[:, 1].min() + pattern[:, 1].max()) / 2
        variants = []
        for flip_x in (False, True):
            for flip_y in (False, True):
                v = pattern.copy()
                if flip_x:
                    v[:, 0] = 2 * x_mid - v[:, 0]
                if flip_y:
                    v[:, 1] = 2 * y_mid - v[:, 1]
                variants.append(v)
        return min(variants, key=lambda v: float(np.linalg.norm(v[0, :2] - pose[:2])))

    def _in_building(self, waypoint: np.ndarray) -> bool:
        """Whether the waypoint lies inside a building widened by half the building margin."""
        return bool(path_collides(np.array([[waypoint, waypoint]]), self.buildings, self.building_margin_m / 2)[0])

    def _around_buildings(self, pose: np.ndarray, waypoints: np.ndarray, extent_m) -> np.ndarray:
        """The waypoints with every leg (from ``pose`` [m]) flown by :func:`clear_route` inside
        the area ``extent_m`` (x0, x1, y0, y1) [m]."""
        if not self.buildings:
            return waypoints
        route, current = [], pose
        for goal in waypoints:
            route.extend(clear_route(current, goal, self.buildings, self.building_margin_m, self.max_altitude_m, extent_m))
            current = goal
        return np.array(route)


@dataclass
class LawnmowerTuning:
    """Result of :func:`best_lawnmower`: the best altitude_m [m] and spacing_factor (d / w_x(h)),
    their median time to find the fraction [s], and per (altitude, factor) the times of every
    seed [s] (inf: not reached in the budget)."""

    altitude_m: float
    spacing_factor: float
    median_time_s: float
    times_s: dict[tuple[float, float], list[float]] = field(default_factory=dict)

    def planner(
        self, camera: Camera, n_uavs: int, buildings: Sequence[Obstacle] = (), max_altitude_m: float = 120.0
    ) -> FieldLawnmowerPlanner:
        """The tuned planner for a world with these ``buildings``; camera: the footprint; n_uavs:
        strips; max_altitude_m: the ceiling of climbs over buildings [m]."""
        spacing = self.spacing_factor * float(camera.footprint_m(self.altitude_m)[0])
        return FieldLawnmowerPlanner(self.altitude_m, spacing, camera, n_uavs, buildings, max_altitude_m=max_altitude_m)


def best_lawnmower(
    world_factory: Callable[[int], object],
    seeds: Sequence[int],
    altitudes: Sequence[float],
    spacing_factors: Sequence[float],
    settings,
    fraction: float = 0.9,
) -> LawnmowerTuning:
    """The altitude h and spacing factor d / w_x(h) of :class:`FieldLawnmowerPlanner` with the
    least median (over ``seeds``) time to find ``fraction`` of the people; ties (e.g. never
    reached) broken by the larger mean fraction found at the end, then the lower altitude.

    world_factory: seed -> :class:`attend.action.world.SearchWorld`; seeds: the tuning seeds
    (keep them apart from evaluation seeds); altitudes: candidate h [m]; spacing_factors:
    candidate d / w_x(h) (> 0); settings: the :class:`attend.action.search_mission.SearchSettings`
    of the missions; fraction: of the people to find, in (0, 1]."""
    from attend.action.search_mission import fly_search  # the mission imports planners

    seeds, altitudes, factors = list(seeds), list(altitudes), list(spacing_factors)
    if not seeds or not altitudes or not factors:
        raise ActionInputError("seeds, altitudes, spacing_factors: expected at least one value each")
    if any(not (np.isfinite(f) and f > 0) for f in factors):
        raise ActionInputError(f"spacing_factors: expected factors > 0, got {factors!r}")
    worlds = {seed: world_factory(seed) for seed in seeds}
    table: dict[tuple[float, float], list[float]] = {}
    scores = []
    for h in altitudes:
        for factor in factors:
            times, found = [], []
            for seed in seeds:
                world = worlds[seed]
                spacing = factor * float(settings.camera.footprint_m(h)[0])
                planner = FieldLawnmowerPlanner(h, spacing, settings.camera, settings.n_uavs, world.buildings,
                                                max_altitude_m=world.altitude_limits_m[1])
                log = fly_search(world, planner, settings, seed)
                times.append(log.time_to_fraction_s(fraction))
                found.append(len(log.found_times_s) / max(log.people_total, 1))
            table[(float(h), float(factor))] = times
            scores.append((float(np.median(times)), -float(np.mean(found)), float(h), float(factor)))
    median, _, h, factor = min(scores)
    return LawnmowerTuning(h, factor, median, table)
