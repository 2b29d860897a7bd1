"""Several UAVs searching a large area and sharing one probability map.

Flight: each UAV flies straight segments between its waypoints at the constant speed v
(altitude changes included in a segment's length |w_{i+1} - w_i|), turning instantly at
waypoints; a plan whose waypoints are all where the UAV already is makes it hover until its
next image. UAV k takes images every 1 / f seconds of the mission clock from k / (n f) on
(f the image rate, n the number of UAVs: staggered, so images of different UAVs rarely fall
at the same time), until the flight budget T ends; the speed recorded with an image is v while
flying and 0 while hovering.

Fusion: one event loop over all UAVs' next image and next waypoint times; images update the one
:class:`attend.action.probability_map.ProbabilityMap` in time order (ties: images first, then
lower UAV index). A UAV replans when it reaches the last waypoint of its plan (or, with
``replan_after_waypoints`` = k, after k waypoints of it), calling
``planner.plan(belief, uav, pose, T - t, others)`` with ``others`` the other UAVs' current
poses stacked on their remaining waypoints; at t = 0 the UAVs plan in index order.

Metrics after every image: the expected number of people sum p, the people found so far (a
person is found the first time a reported target lies within ``found_radius_m`` of them),
P(all found) (:meth:`ProbabilityMap.p_all_found`), the false targets (reported targets with no
person within ``found_radius_m``) and the area seen (searchable cells in view at least once).
sum p and P(all found) come from sums of p_c and of softplus(l_c) = -log(1 - p_c) kept per tile
of SUM_TILE_CELLS x SUM_TILE_CELLS cells: after an image the tiles its footprint window touches
are summed afresh and the map's sums are the sums over the tiles,

    sum_c p_c = sum_t S_t,    S_t = sum_{c in t} p_c,

so they are exact up to rounding (no drift to correct) and a metric costs
O(footprint + tiles + targets), not O(map).
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.special import expit

from attend.action.camera import Camera, segments_hit_box
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.planners.search_base import SearchPlanner
from attend.action.probability_map import ImageObservation, ProbabilityMap
from attend.action.world import SearchWorld, simulate_image

#: Side [cells] of the tiles over which the map's sums of p and softplus(l) are kept.
SUM_TILE_CELLS = 16


@dataclass(frozen=True)
class SearchSettings:
    """A search mission's settings.

    budget_s: flight time T [s] of every UAV; speed_m_s: v [m/s]; image_rate_hz: f [1/s] per
    UAV; n_uavs: n; min_separation_m: the distance [m] UAVs should keep (logged, not
    enforced: :attr:`SearchLog.separation_violations`); found_radius_m: a target within this
    of a person finds them [m]; target_threshold: least mass of a reported target; camera,
    model: the sensor; expected_people: E of the prior (None: the true number of people, as
    a team would give it); replan_after_waypoints: replan after this many waypoints of a plan
    (None: at its last); target_radius_m: disc radius of the targets [m] (None: the map's
    default, max(1.5 m, 2 cells)); clear_buildings: reject plans whose segments pass through
    a building (not only waypoints inside one).
    """

    budget_s: float = 600.0
    speed_m_s: float = 10.0
    image_rate_hz: float = 1.0
    n_uavs: int = 1
    min_separation_m: float = 10.0
    found_radius_m: float = 3.0
    target_threshold: float = 0.5
    camera: Camera = Camera()
    model: DetectionModel = DetectionModel()
    expected_people: float | None = None
    replan_after_waypoints: int | None = None
    target_radius_m: float | None = None
    clear_buildings: bool = True

    def __post_init__(self) -> None:
        for name in ("budget_s", "speed_m_s", "image_rate_hz", "found_radius_m", "target_threshold"):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)) or not np.isfinite(value) or value <= 0:
                raise ActionInputError(f"{name}: expected a number > 0, got {value!r}")
        if not (np.isfinite(self.min_separation_m) and self.min_separation_m >= 0):
            raise ActionInputError(f"min_separation_m: expected a distance >= 0 m, got {self.min_separation_m!r}")
        if isinstance(self.n_uavs, (bool, np.bool_)) or not isinstance(self.n_uavs, (int, np.integer)) or self.n_uavs < 1:
            raise ActionInputError(f"n_uavs: expected a whole number >= 1, got {self.n_uavs!r}")
        if self.expected_people is not None and not (np.isfinite(self.expected_people) and self.expected_people > 0):
            raise ActionInputError(f"expected_people: expected a number > 0 or None, got {self.expected_people!r}")
        k = self.replan_after_waypoints
        if k is not None and (not isinstance(k, (int, np.integer)) or isinstance(k, bool) or k < 1):
            raise ActionInputError(f"replan_after_waypoints: expected a whole number >= 1 or None, got {k!r}")
        if self.target_radius_m is not None and not (np.isfinite(self.target_radius_m) and self.target_radius_m > 0):
            raise ActionInputError(f"target_radius_m: expected a radius > 0 m or None, got {self.target_radius_m!r}")
        if not isinstance(self.camera, Camera):
            raise ActionInputError(f"camera: expected a Camera, got {type(self.camera).__name__}")
        if not isinstance(self.model, DetectionModel):
            raise ActionInputError(f"model: expected a DetectionModel, got {type(self.model).__name__}")


@dataclass
class SearchLog:
    """Everything a search-and-rescue team reads, per image in time order unless said.

    people_total: people in the world; budget_s: T [s]; times_s: image times [s]; uavs: which
    UAV took each image; expected_people: sum p after each image; people_found: people found
    so far; p_all_found: P(nobody outside the reported targets); false_targets_series: false
    targets after each image; area_covered_series_m2: searchable area seen so far [m^2];
    found_times_s: when each found person was first found [s], ascending (one per person
    found); person_found_times_s: (people_total,) per person (inf: never); false_targets: false
    targets at the end; area_covered_m2: searchable area seen [m^2]; distance_flown_m: per UAV
    [m]; planner_times_s: wall time of every plan call [s]; map_update_ms: wall time of every
    map update [ms] (Python's garbage collector paused during it); paths_m: per UAV the points flown (w, 3) [m] (start, waypoints reached,
    the position at the end); images: images taken; closest_approach_m: least distance between
    two UAVs at image times [m] (inf for one UAV); separation_violations: images at which two
    UAVs were closer than min_separation_m; final_map: the map at the end.
    """

    people_total: int
    budget_s: float
    times_s: list[float] = field(default_factory=list)
    uavs: list[int] = field(default_factory=list)
    expected_people: list[float] = field(default_factory=list)
    people_found: list[int] = field(default_factory=list)
    p_all_found: list[float] = field(default_factory=list)
    false_targets_series: list[int] = field(default_factory=list)
    area_covered_series_m2: list[float] = field(default_factory=list)
    found_times_s: list[float] = field(default_factory=list)
    person_found_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    false_targets: int = 0
    area_covered_m2: float = 0.0
    distance_flown_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    planner_times_s: list[float] = field(default_factory=list)
    map_update_ms: list[float] = field(default_factory=list)
    paths_m: list[np.ndarray] = field(default_factory=list)
    images: int = 0
    closest_approach_m: float = math.inf
    separation_violations: int = 0
    final_map: ProbabilityMap | None = None

    def time_to_fraction_s(self, fraction: float) -> float:
        """When the ceil(fraction n)-th of the n people was found [s] (inf if never); fraction
        in (0, 1]."""
        if not (np.isfinite(fraction) and 0 < fraction <= 1):
            raise ActionInputError(f"fraction: expected a number in (0, 1], got {fraction!r}")
        needed = max(1, math.ceil(fraction * self.people_total - 1e-9))
        if self.people_total == 0 or needed > len(self.found_times_s):
            return math.inf
        return float(sorted(self.found_times_s)[needed - 1])


class _Uav:
    """One UAV's flight state: the current leg (start -> end over [t0, t1]) and the plan after it."""

    def __init__(self, index: int, pose: np.ndarray, first_image_s: float, period_s: float) -> None:
        self.index = index
        self.leg_start, self.leg_end = pose.copy(), pose.copy()
        self.leg_t0 = self.leg_t1 = 0.0
        self.plan: list[np.ndarray] = []
        self.first_image_s, self.period_s, self.images_taken = first_image_s, period_s, 0
        self.next_image_s = first_image_s
        self.waypoints_done = 0
        self.path: list[np.ndarray] = [pose.copy()]
        self.distance_m = 0.0
        self.needs_plan = True

    def position(self, t: float) -> np.ndarray:
        if self.leg_t1 <= self.leg_t0:
            return self.leg_end.copy()
        fraction = min(max((t - self.leg_t0) / (self.leg_t1 - self.leg_t0), 0.0), 1.0)
        return self.leg_start + fraction * (self.leg_end - self.leg_start)

    def speed(self, speed_m_s: float) -> float:
        return speed_m_s if np.linalg.norm(self.leg_end - self.leg_start) > 1e-9 else 0.0

    def remaining(self, t: float) -> np.ndarray:
        """Current position stacked on the rest of the current leg and the plan, (k, 3)."""
        points = [self.position(t)]
        if self.leg_t1 > t and np.linalg.norm(self.leg_end - points[0]) > 1e-9:
            points.append(self.leg_end)
        points.extend(self.plan)
        return np.array(points)


def fly_search(
    world: SearchWorld,
    planner: SearchPlanner,
    settings: SearchSettings,
    seed: int,
    on_image: Callable[[ImageObservation, ProbabilityMap, SearchLog], None] | None = None,
) -> SearchLog:
    """Fly ``settings.n_uavs`` UAVs with ``planner`` over ``world`` for ``settings.budget_s``
    seconds, fusing all images into one map (module docstring).

    world: the truth; planner: plans for every UAV; settings: the mission; seed: seeds the
    detections and the planner (``planner.reset(seed)``); on_image: called as
    on_image(image, belief, log) after each image is fused and logged.
    Raises ActionInputError naming the planner when it returns waypoints outside the area or
    the altitude limits, or inside (or, with ``settings.clear_buildings``, through) a building.
    """
    if not isinstance(world, SearchWorld):
        raise ActionInputError(f"world: expected a SearchWorld, got {type(world).__name__}")
    if not isinstance(planner, SearchPlanner):
        raise ActionInputError(f"planner: expected a SearchPlanner, got {type(planner).__name__}")
    n = int(settings.n_uavs)
    if len(world.start_poses_m) < n:
        raise ActionInputError(f"n_uavs: expected at most the world's {len(world.start_poses_m)} start poses, got {n}")
    expected = settings.expected_people if settings.expected_people is not None else float(world.n_people)
    if expected <= 0:
        raise ActionInputError("expected_people: the world has nobody in it; give settings.expected_people > 0")
    if world.prior_map is not None:
        belief = ProbabilityMap.from_prior_map(world.grid, world.prior_map, expected, world.searchable)
    else:
        belief = ProbabilityMap.uniform(world.grid, expected, world.searchable)
    rng = np.random.default_rng(seed)
    planner.reset(seed)
    period = 1.0 / settings.image_rate_hz
    budget = float(settings.budget_s)
    uavs = [_Uav(k, np.asarray(world.start_poses_m[k], dtype=float), k * period / n, period) for k in range(n)]
    log = SearchLog(people_total=world.n_people, budget_s=budget)
    log.person_found_times_s = np.full(world.n_people, math.inf)
    tracker = _MapTracker(belief, settings)
    covered = np.zeros(world.grid.shape, dtype=bool)
    covered_cells = 0

    for uav in uavs:
        _replan(uav, uavs, planner, belief, world, settings, 0.0, log)
    while True:
        image_uav = min(uavs, key=lambda u: (u.next_image_s, u.index))
        arrive_uav = min(uavs, key=lambda u: (u.leg_t1, u.index))
        t_image, t_arrive = image_uav.next_image_s, arrive_uav.leg_t1
        if t_image > budget and t_arrive >= budget:
            break
        if t_image <= t_arrive or t_arrive >= budget:
            uav, t = image_uav, t_image
            pose = uav.position(t)
            image = simulate_image(
                world, pose, t, uav.speed(settings.speed_m_s), settings.model, settings.camera, rng, uav.index
            )
            log.map_update_ms.append(_timed_fuse(tracker, image))
            rows, cols = image.window
            seen = image.visible & world.searchable[rows, cols]
            before = int(np.count_nonzero(covered[rows, cols]))
            covered[rows, cols] |= seen
            covered_cells += int(np.count_nonzero(covered[rows, cols])) - before
            uav.images_taken += 1
            uav.next_image_s = uav.first_image_s + uav.images_taken * period
            _log_image(log, tracker, world, settings, t, uav.index, covered_cells)
            if n > 1:
                poses = np.array([u.position(t) for u in uavs])
                gaps = np.linalg.norm(poses[:, None] - poses[None], axis=-1)[np.triu_indices(n, 1)]
                log.closest_approach_m = min(log.closest_approach_m, float(gaps.min()))
                log.separation_violations += int(np.any(gaps < settings.min_separation_m))
            if on_image is not None:
                on_image(image, belief, log)
        else:
            uav, t = arrive_uav, t_arrive
            uav.distance_m += float(np.linalg.norm(uav.leg_end - uav.leg_start))
            if np.linalg.norm(uav.leg_end - uav.path[-1]) > 1e-9:
                uav.path.append(uav.leg_end.copy())
            uav.leg_start = uav.leg_end.copy()
            uav.leg_t0 = t
            uav.waypoints_done += 1
            limit = settings.replan_after_waypoints
            if not uav.plan or (limit is not None and uav.waypoints_done >= limit):
                _replan(uav, uavs, planner, belief, world, settings, t, log)
            else:
                _start_leg(uav, t, settings)
    for uav in uavs:
        end = uav.position(budget)
        if uav.leg_t1 > budget:
            uav.distance_m += float(np.linalg.norm(end - uav.leg_start))
        if np.linalg.norm(end - uav.path[-1]) > 1e-9:
            uav.path.append(end)
    log.distance_flown_m = np.array([u.distance_m for u in uavs])
    log.paths_m = [np.array(u.path) for u in uavs]
    log.area_covered_m2 = covered_cells * world.grid.cell_area_m2
    log.false_targets = log.false_targets_series[-1] if log.false_targets_series else 0
    log.found_times_s = sorted(float(t) for t in log.person_found_times_s if np.isfinite(t))
    log.final_map = belief
    return log


def _start_leg(uav: _Uav, t: float, settings: SearchSettings) -> None:
    """Fly from where the UAV is towards the next waypoint of its plan that is elsewhere (the
    waypoints where it already is count as reached); none left: hover until its next image."""
    goal = uav.plan.pop(0)
    while uav.plan and np.linalg.norm(goal - uav.leg_start) <= 1e-9:
        goal = uav.plan.pop(0)
        uav.waypoints_done += 1
    uav.leg_end, uav.leg_t0 = np.asarray(goal, dtype=float), t
    length = float(np.linalg.norm(uav.leg_end - uav.leg_start))
    if length > 1e-9:
        uav.leg_t1 = t + length / settings.speed_m_s
    else:
        uav.leg_t1 = uav.next_image_s if uav.next_image_s > t else t + uav.period_s


def _replan(
    uav: _Uav, uavs: Sequence[_Uav], planner: SearchPlanner, belief: ProbabilityMap, world: SearchWorld,
    settings: SearchSettings, t: float, log: SearchLog,
) -> None:
    """Ask the planner for the UAV's next waypoints, check them and start flying them."""
    pose = uav.position(t)
    others = [other.remaining(t) for other in uavs if other is not uav]
    start = time.perf_counter()
    waypoints = planner.plan(belief, uav.index, pose.copy(), settings.budget_s - t, others)
    log.planner_times_s.append(time.perf_counter() - start)
    plan = _checked_plan(waypoints, pose, planner, world, settings)
    uav.plan = [w for w in plan]
    uav.waypoints_done = 0
    uav.leg_start = pose
    _start_leg(uav, t, settings)


def _checked_plan(waypoints, pose: np.ndarray, planner: SearchPlanner, world: SearchWorld, settings: SearchSettings) -> np.ndarray:
    """The planner's waypoints as (w, 3), or ActionInputError naming the planner."""
    name = getattr(planner, "name", type(planner).__name__)
    try:
        plan = np.asarray(waypoints, dtype=float)
    except (TypeError, ValueError):
        raise ActionInputError(f"planner {name!r}: expected waypoints (w, 3) in m, got {waypoints!r}") from None
    if plan.ndim == 1 and plan.shape == (3,):
        plan = plan[None]
    if plan.ndim != 2 or plan.shape[1] != 3 or len(plan) == 0:
        raise ActionInputError(f"planner {name!r}: expected waypoints (w, 3) with w >= 1, got shape {plan.shape}")
    if not np.all(np.isfinite(plan)):
        raise ActionInputError(f"planner {name!r}: expected finite waypoints, got {plan.tolist()}")
    x0, x1, y0, y1 = world.grid.extent_m
    low, high = world.altitude_limits_m
    tolerance = 1e-6
    for i, (x, y, z) in enumerate(plan):
        if not (x0 - tolerance <= x <= x1 + tolerance and y0 - tolerance <= y <= y1 + tolerance):
            raise ActionInputError(
                f"planner {name!r}: waypoint {i} ({x:g}, {y:g}) m lies outside the area "
                f"x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}] m"
            )
        if not low - tolerance <= z <= high + tolerance:
            raise ActionInputError(
                f"planner {name!r}: waypoint {i} at altitude {z:g} m lies outside the limits [{low:g}, {high:g}] m"
            )
        for box in world.buildings:
            bx0, bx1, by0, by1, _, top = box.bounds
            if bx0 <= x <= bx1 and by0 <= y <= by1 and z <= top:
                raise ActionInputError(f"planner {name!r}: waypoint {i} ({x:g}, {y:g}, {z:g}) m lies inside a building {box}")
    if settings.clear_buildings and world.buildings:
        points = np.vstack([pose[None], plan])
        for box in world.buildings:
            hit = segments_hit_box(points[:-1], points[1:], box.bounds)
            if hit.any():
                i = int(np.argmax(hit))
                raise ActionInputError(
                    f"planner {name!r}: the segment to waypoint {i} {tuple(np.round(plan[i], 3))} m passes through a building {box}"
                )
    return plan


class _MapTracker:
    """The map with the sums of p and of log(1 + exp(l)) = -log(1 - p) over all cells, kept per
    tile of SUM_TILE_CELLS cells a side (module docstring)."""

    def __init__(self, belief: ProbabilityMap, settings: SearchSettings) -> None:
        self.belief = belief
        self.settings = settings
        self.images = 0
        ny, nx = belief.grid.shape
        self._tile_p, self._tile_softplus = self._tile_sums(slice(0, ny), slice(0, nx))
        self._total()

    def _tile_sums(self, rows: slice, cols: slice) -> tuple[np.ndarray, np.ndarray]:
        """Sums of p and softplus(l) per tile over the block (rows, cols), which starts on tile
        edges and ends on tile edges or the map's."""
        log_odds = self.belief.log_odds[rows, cols]
        row_starts = np.arange(0, log_odds.shape[0], SUM_TILE_CELLS)
        col_starts = np.arange(0, log_odds.shape[1], SUM_TILE_CELLS)
        p_sums = np.add.reduceat(np.add.reduceat(expit(log_odds), row_starts, axis=0), col_starts, axis=1)
        softplus = np.logaddexp(0.0, log_odds)
        return p_sums, np.add.reduceat(np.add.reduceat(softplus, row_starts, axis=0), col_starts, axis=1)

    def _total(self) -> None:
        self.sum_p = float(self._tile_p.sum())
        self.sum_softplus = float(self._tile_softplus.sum())

    def fuse(self, image: ImageObservation) -> None:
        """Fuse the image into the map and sum the tiles its window touches afresh."""
        self.belief.update(image, self.settings.model, self.settings.camera)
        self.images += 1
        rows, cols = image.window
        if rows.stop <= rows.start or cols.stop <= cols.start:
            return
        ny, nx = self.belief.grid.shape
        t = SUM_TILE_CELLS
        r0, r1 = rows.start // t, (rows.stop - 1) // t + 1
        c0, c1 = cols.start // t, (cols.stop - 1) // t + 1
        block = (slice(r0 * t, min(r1 * t, ny)), slice(c0 * t, min(c1 * t, nx)))
        self._tile_p[r0:r1, c0:c1], self._tile_softplus[r0:r1, c0:c1] = self._tile_sums(*block)
        self._total()

    def targets(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Target positions (k, 2) [m], masses (k,) and P(all found)."""
        positions, masses, cells = self.belief.target_discs(self.settings.target_threshold, self.settings.target_radius_m)
        log_none = -self.sum_softplus
        if cells:
            log_none += float(np.logaddexp(0.0, self.belief.log_odds.ravel()[np.concatenate(cells)]).sum())
        return positions, masses, float(np.exp(min(log_none, 0.0)))


def _timed_fuse(tracker: _MapTracker, image: ImageObservation) -> float:
    """Fuse the image; returns the wall time of the update [ms], with Python's cyclic garbage
    collector paused during it (a collection falling due then runs at the next allocation after
    it: its pause, tens of ms over a large process, is not the update's work)."""
    paused = gc.isenabled()
    gc.disable()
    try:
        start = time.perf_counter()
        tracker.fuse(image)
        return (time.perf_counter() - start) * 1e3
    finally:
        if paused:
            gc.enable()


def _log_image(
    log: SearchLog, tracker: _MapTracker, world: SearchWorld, settings: SearchSettings, t: float, uav: int, covered_cells: int
) -> None:
    positions, _, p_all = tracker.targets()
    log.times_s.append(t)
    log.uavs.append(uav)
    log.images += 1
    log.expected_people.append(tracker.sum_p)
    log.p_all_found.append(p_all)
    false_targets = 0
    if len(positions):
        if world.n_people:
            distance = np.linalg.norm(positions[:, None, :] - world.people_m[None, :, :], axis=-1)
            near = distance <= settings.found_radius_m
            newly = near.any(axis=0) & ~np.isfinite(log.person_found_times_s)
            log.person_found_times_s[newly] = t
            false_targets = int(np.count_nonzero(~near.any(axis=1)))
        else:
            false_targets = len(positions)
    log.people_found.append(int(np.count_nonzero(np.isfinite(log.person_found_times_s))))
    log.false_targets_series.append(false_targets)
    log.area_covered_series_m2.append(covered_cells * world.grid.cell_area_m2)
