"""A search mission on the team's own ground: the area, the logs flown so far, the map, the next plan.

:class:`Mission` is what ``attend plan`` runs. Its state is a function of the mission file and
the logs only: the map is rebuilt from the prior and every logged image, fused in time order
(ties by the UAV's order in the mission file), so a mission split over any number of calls gives
the same map, targets and plan as one call.

Images. An image taken at (x, y) [m], altitude h above home and heading psi (from north,
clockwise) sees the ground rectangle of half-widths h tan(fov_across / 2) across-track, along
(cos psi, -sin psi), and h tan(fov_along / 2) along-track, along (sin psi, cos psi); the cells
whose centres it covers are fused by :meth:`attend.action.probability_map.ProbabilityMap.update`
with the mission's detector table.

Plan. Each UAV's plan starts where it is (its last image, else its home, at the start of the
altitude band) at its elapsed time (its last image's t_s, else 0). Legs are chosen by the
planner one at a time, the UAV whose plan ends first going next, each leg's images booked on a
working copy of the map as if they saw nothing (so later legs and other UAVs go elsewhere), until
the plan reaches ``horizon_s`` past the UAV's elapsed time or no further leg fits the flight time
left, the route home included (the route inside the area to the home's entry point, then
straight home, at the UAV's speed). The autopilot returns home at the end of a plan unless
replanned.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from attend.action.log_odds import logistic

from attend.action.camera import Camera
from attend.action.mission.area_files import read_area
from attend.action.mission.config import MissionConfig, read_mission
from attend.action.mission.errors import MissionInputError
from attend.action.mission.flight_logs import FlightLogs, read_flight_logs
from attend.action.mission.ground import SearchGround, check_home_distance
from attend.action.planners.salience import ExpectedFreeEnergySearchPlanner
from attend.action.probability_map import ImageObservation, ProbabilityMap

#: Probability mass at which a disc of the map counts as a target (a likely person).
TARGET_THRESHOLD = 0.5
#: Altitude layers the expected-free-energy planner chooses from, per UAV.
PLANNER_LAYERS = 4
#: Levels at which the planner tabulates its value functions (interpolated between them).
VALUE_LEVELS = 2048
#: Looks of one cell along a planned path whose value counts (the rest count 0).
MAX_LOOKS = 4
#: Legs per UAV and call at most (a guard; the horizon ends a plan first).
MAX_LEGS = 200


@dataclass
class UavPlan:
    """The next waypoints of one UAV: name; waypoints (w, 4): x, y [m], altitude above home
    [m], planned arrival time since mission start [s]; start (4,): where and when the plan
    starts; home_time_s: flight time [s] from the last waypoint home."""

    name: str
    start: np.ndarray
    waypoints: np.ndarray
    home_time_s: float


class Mission:
    """One search mission (module docstring): ``Mission(config)`` or ``Mission.from_file(path)``,
    then :meth:`set_logs`, :meth:`targets`, :meth:`plan`, :meth:`summary`, :meth:`write`.

    config: a :class:`attend.action.mission.config.MissionConfig`."""

    def __init__(self, config: MissionConfig) -> None:
        if not isinstance(config, MissionConfig):
            raise MissionInputError(f"config: expected a MissionConfig, got {type(config).__name__}")
        self.config = config
        self.area = read_area(config.boundary, config.exclude)
        self.ground = SearchGround.from_polygons(self.area.boundary, self.area.exclusions, config.cell_size_m)
        frame = self.ground.frame
        homes = []
        for uav in config.uavs:
            x, y = frame.to_local(*uav.home)
            check_home_distance(self.ground, (float(x), float(y)), uav.name, config.path)
            homes.append(np.array([float(x), float(y)]))
        self.homes_m = homes
        self.cameras = [Camera(fov_x_deg=u.camera_fov_deg[0], fov_y_deg=u.camera_fov_deg[1]) for u in config.uavs]
        self.prior = self._prior()
        self.set_logs(FlightLogs.empty())

    @classmethod
    def from_file(cls, path: str | Path) -> "Mission":
        """The mission of the TOML file at ``path``."""
        return cls(read_mission(path))

    # ------------------------------------------------------------------------------------
    # logs and the map

    def read_logs(self, images_path=None, detections_path=None) -> None:
        """Read the logs and rebuild the map from them; images_path: images.csv (None: nothing
        flown yet); detections_path: detections.csv (None: no detections)."""
        logs = read_flight_logs(images_path, detections_path, [u.name for u in self.config.uavs],
                                [u.altitude_m for u in self.config.uavs])
        self.set_logs(logs, images_path)

    def set_logs(self, logs: FlightLogs, images_path=None) -> None:
        """Rebuild the map from the prior and every image of ``logs`` (module docstring);
        images_path: the file the logs came from (named in errors; None: not from a file)."""
        start = time.perf_counter()
        self._targets = None
        self.logs = logs
        self.belief = self.prior.copy()
        self.seen = np.zeros(self.ground.grid.shape, dtype=bool)
        frame = self.ground.frame
        self._image_x, self._image_y = frame.to_local(logs.image_lon, logs.image_lat)
        self._detection_x, self._detection_y = frame.to_local(logs.detection_lon, logs.detection_lat)
        by_image: dict[int, list[int]] = {}
        for j, i in enumerate(logs.detection_image):
            by_image.setdefault(int(i), []).append(j)
        for i in logs.fusion_order():
            self._fuse(int(i), by_image.get(int(i), []), images_path)
        self.fusion_time_s = time.perf_counter() - start

    def append_images(self, new: FlightLogs) -> None:
        """Add the images of ``new`` (and their detections), taken after every image already
        fused, fusing only them: the same map as :meth:`set_logs` with all of them.

        new: FlightLogs of the new images, detection_image indexing into them."""
        old = self.logs
        if old.n_images and new.n_images and new.image_time_s.min() < old.image_time_s.max():
            raise MissionInputError("append_images: expected images after the last one fused; use set_logs")
        start = time.perf_counter()
        self._targets = None
        offset = old.n_images
        merged = FlightLogs(*(np.concatenate([getattr(old, name), getattr(new, name) + (offset if name == "detection_image" else 0)])
                              for name in FlightLogs.__dataclass_fields__))
        self.logs = merged
        frame = self.ground.frame
        x, y = frame.to_local(new.image_lon, new.image_lat)
        self._image_x, self._image_y = np.r_[self._image_x, x], np.r_[self._image_y, y]
        x, y = frame.to_local(new.detection_lon, new.detection_lat)
        self._detection_x, self._detection_y = np.r_[self._detection_x, x], np.r_[self._detection_y, y]
        by_image: dict[int, list[int]] = {}
        for j in range(len(old.detection_image), len(merged.detection_image)):
            by_image.setdefault(int(merged.detection_image[j]), []).append(j)
        order = np.lexsort((new.image_uav, new.image_time_s)) + offset
        for i in order:
            self._fuse(int(i), by_image.get(int(i), []), None)
        self.fusion_time_s = time.perf_counter() - start

    def _fuse(self, i: int, detections: list[int], images_path) -> None:
        logs = self.logs
        k = int(logs.image_uav[i])
        uav = self.config.uavs[k]
        x, y, h = float(self._image_x[i]), float(self._image_y[i]), float(logs.image_alt_m[i])
        window, visible = footprint_cells(self.ground.grid, x, y, h, float(logs.image_yaw_deg[i]), uav.camera_fov_deg)
        rows, cols = window
        if not (visible & self.ground.in_area[rows, cols]).any():
            raise MissionInputError(
                f"the image at ({logs.image_lon[i]:.7f}, {logs.image_lat[i]:.7f}) sees nothing of the area: expected "
                "images over the search area", file=images_path, row=self._row_of(i), column="lon")
        detections_m = np.column_stack([self._detection_x[detections], self._detection_y[detections]])
        image = ImageObservation(pose_m=np.array([x, y, h]), time_s=float(logs.image_time_s[i]), speed_m_s=0.0,
                                 window=window, visible=visible, detections_m=detections_m, uav=k)
        self.belief.update(image, self.config.detector, self.cameras[k])
        self.seen[rows, cols] |= visible

    @staticmethod
    def _row_of(i: int) -> int:
        return i + 2

    def _prior(self) -> ProbabilityMap:
        grid, searchable = self.ground.grid, self.ground.searchable
        people = self.config.people
        if people >= 0.5 * searchable.sum():
            raise MissionInputError(f"expected fewer people than half the {int(searchable.sum())} searchable cells, "
                                    f"got {people:g}", file=self.config.path, column="search.people")
        if self.config.prior_map is None:
            return ProbabilityMap.uniform(grid, people, searchable)
        from attend.action.mission.prior_files import read_prior_weights

        weights = read_prior_weights(self.config.prior_map, self.ground)
        return ProbabilityMap.from_prior_map(grid, weights, people, searchable)

    # ------------------------------------------------------------------------------------
    # where the UAVs are

    def uav_state(self, k: int) -> tuple[np.ndarray, float]:
        """UAV k's pose (x, y, altitude) [m] and elapsed time [s]: its last image, else its
        home at the lowest allowed altitude at t = 0."""
        logs = self.logs
        mine = np.flatnonzero(logs.image_uav == k)
        if len(mine):
            last = mine[np.argmax(logs.image_time_s[mine])]
            return np.array([self._image_x[last], self._image_y[last], logs.image_alt_m[last]]), float(
                logs.image_time_s[last])
        low = self.config.uavs[k].altitude_m[0]
        return np.array([self.homes_m[k][0], self.homes_m[k][1], low]), 0.0

    def flown_paths_m(self) -> list[np.ndarray]:
        """Per UAV (n, 3) image positions (x, y, altitude) [m] in time order, from home."""
        out = []
        for k in range(len(self.config.uavs)):
            mine = np.flatnonzero(self.logs.image_uav == k)
            mine = mine[np.argsort(self.logs.image_time_s[mine], kind="stable")]
            home = np.r_[self.homes_m[k], 0.0]
            path = np.column_stack([self._image_x[mine], self._image_y[mine], self.logs.image_alt_m[mine]])
            out.append(np.vstack([home[None], path]))
        return out

    def home_time_s(self, k: int, xy) -> float:
        """Flight time [s] of UAV k from xy = (x, y) [m] back home (routed inside the area)."""
        return self.ground.route_length_m(xy, self.homes_m[k], leave_area=True) / self.config.uavs[k].speed_m_s

    # ------------------------------------------------------------------------------------
    # targets and summaries

    def targets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
        """Likely people, most probable first: positions (k, 2) [m], probabilities (k,) (the
        mass of the target disc, at most 1), detections within the disc radius plus 2 sigma of
        each (k,), and the flat indices of each target's cells (kept until the map changes)."""
        if self._targets is not None:
            return self._targets
        positions, masses, cells = self.belief.target_discs(TARGET_THRESHOLD)
        order = np.argsort(-np.asarray(masses), kind="stable")
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)[order]
        masses = np.minimum(np.asarray(masses, dtype=float)[order], 1.0)
        cells = [cells[i] for i in order]
        reach = self.belief.default_target_radius_m() + 2 * self.config.detector.position_std_m
        counts = np.zeros(len(positions), dtype=int)
        if len(positions) and len(self._detection_x):
            d = np.hypot(positions[:, 0, None] - self._detection_x[None], positions[:, 1, None] - self._detection_y[None])
            counts = (d <= reach).sum(axis=1)
        self._targets = (positions, masses, counts, cells)
        return self._targets

    def p_all_found(self, cells: list[np.ndarray] | None = None) -> float:
        """P(everyone found). Expected number of people (the default): P(nobody outside the
        targets) = prod over searchable cells outside every target of (1 - p_c). Known number N
        (``[search] people_known``): P(at least N of the targets are people), each target a
        person with its probability m_k independently (a Poisson-binomial tail); cells: the
        targets' flat cell indices (None: :meth:`targets`)."""
        if self.config.people_known:
            masses = np.clip(self.targets()[1], 0.0, 1.0)
            return at_least(masses, int(self.config.people))
        if cells is None:
            cells = self.targets()[3]
        log_odds = self.belief.log_odds
        outside = self.ground.searchable.copy()
        if cells:
            outside.ravel()[np.concatenate(cells)] = False
        return float(np.exp(-np.logaddexp(0.0, log_odds[outside]).sum()))

    # ------------------------------------------------------------------------------------
    # planning

    def plan(self, planner: str | None = None, horizon_s: float | None = None) -> list[UavPlan]:
        """The next plan of every UAV (module docstring); planner: "efe" (default: the mission
        file's) or "lawnmower"; horizon_s: how far ahead [s] (default: the mission file's)."""
        name = planner or self.config.planner
        horizon = float(horizon_s if horizon_s is not None else self.config.horizon_s)
        start = time.perf_counter()
        if name == "efe":
            plans = self._plan_efe(horizon)
        elif name == "lawnmower":
            from attend.action.mission.lawnmower import plan_lawnmower

            plans = plan_lawnmower(self, horizon)
        else:
            raise MissionInputError(f"planner: expected 'efe' or 'lawnmower', got {name!r}")
        self.planner_time_s = time.perf_counter() - start
        self.planner_name = name
        return plans

    def efe_planner(self, k: int) -> ExpectedFreeEnergySearchPlanner:
        """The expected-free-energy planner of UAV k, kept inside the area."""
        uav = self.config.uavs[k]
        low, high = uav.altitude_m
        layers = np.geomspace(low, high, PLANNER_LAYERS) if high > low else np.array([low])
        ground = self.ground

        def toward(start, goal):
            try:
                return ground.route(start[:2], ground.entry_point(goal[0], goal[1]))[0]
            except MissionInputError:  # another part of the area: stay
                return start[:2]

        return ExpectedFreeEnergySearchPlanner(
            model=self.config.detector, camera=self.cameras[k], speed_m_s=uav.speed_m_s,
            image_rate_hz=1.0 / uav.image_interval_s, altitude_layers_m=layers,
            altitude_limits_m=(low, high + 1e-9), min_separation_m=self.config.min_separation_m,
            target_threshold=TARGET_THRESHOLD, seed=self.config.seed, allowed_legs=ground.legs_allowed,
            route_toward=toward, book_other_plans=False, fly_second_leg=True,
            value_levels=VALUE_LEVELS, max_looks=MAX_LOOKS, footprint_follows_heading=True)

    def _plan_efe(self, horizon: float) -> list[UavPlan]:
        uavs = self.config.uavs
        work = self.belief.copy()
        shared: dict = {}  # UAVs of the same kind share one planner (and its value maps)
        planners = []
        for k, uav in enumerate(uavs):
            kind = (uav.speed_m_s, uav.image_interval_s, uav.altitude_m, uav.camera_fov_deg)
            if kind not in shared:
                shared[kind] = self.efe_planner(k)
            planners.append(shared[kind])
        states = [self.uav_state(k) for k in range(len(uavs))]
        paths = [[pose.copy()] for pose, _ in states]
        clocks = [elapsed for _, elapsed in states]
        starts = [np.r_[pose, elapsed] for pose, elapsed in states]
        waypoints: list[list[np.ndarray]] = [[] for _ in uavs]
        open_ = [True] * len(uavs)
        for k, (pose, elapsed) in enumerate(states):
            pose = self._clamped_altitude(k, pose)
            if not self.ground.inside(pose[0], pose[1]):  # a home outside the area: fly to its entry first
                entry = self.ground.entry_point(pose[0], pose[1])
                arrive = clocks[k] + float(np.hypot(*(entry - pose[:2]))) / uavs[k].speed_m_s
                if arrive + self.home_time_s(k, entry) > self.config.flight_time_s:
                    open_[k] = False  # not even the way in and back fits the flight time
                    continue
                clocks[k] = arrive
                pose = np.r_[entry, pose[2]]
                waypoints[k].append(np.r_[pose, clocks[k]])
            paths[k] = [pose]
        for _ in range(MAX_LEGS * len(uavs)):
            live = [k for k in range(len(uavs)) if open_[k]]
            if not live:
                break
            k = min(live, key=lambda j: (clocks[j], j))
            if clocks[k] >= starts[k][3] + horizon:
                open_[k] = False
                continue
            leg = self._next_leg(k, planners[k], work, paths, clocks[k])
            if leg is None:
                open_[k] = False
                continue
            uav = uavs[k]
            for point in leg:
                length = float(np.hypot(*(point[:2] - paths[k][-1][:2]))) + abs(point[2] - paths[k][-1][2])
                clocks[k] += length / uav.speed_m_s
                waypoints[k].append(np.r_[point, clocks[k]])
                self._book(work, k, paths[k][-1], point)
                paths[k].append(point)
        plans = []
        for k, uav in enumerate(uavs):
            rows = np.array(waypoints[k]).reshape(-1, 4)
            end = rows[-1, :2] if len(rows) else starts[k][:2]
            plans.append(UavPlan(uav.name, starts[k], rows, self.home_time_s(k, end)))
        return plans

    def _clamped_altitude(self, k: int, pose: np.ndarray) -> np.ndarray:
        low, high = self.config.uavs[k].altitude_m
        return np.r_[pose[:2], min(max(pose[2], low), high)]

    def _next_leg(self, k: int, planner, work: ProbabilityMap, paths, clock: float):
        """The planner's next leg (j, 3) for UAV k from the end of its path, or None when no
        leg fits the time left with the way home."""
        uav = self.config.uavs[k]
        pose = paths[k][-1]
        others = [np.array(paths[j]) for j in range(len(paths)) if j != k]
        budget = self.config.flight_time_s - clock
        left = budget - self.home_time_s(k, pose[:2])
        home = np.asarray(self.homes_m[k], dtype=float)
        entry = self.ground.entry_point(*home)
        outside = float(np.hypot(*(home - entry)))
        area_legs = self.ground.legs_allowed

        def allowed(starts, ends):
            """Legs in the area after which the UAV can still fly home in time: the straight line
            from the pose to the leg's start (a first leg, then a second), the leg, and a lower
            bound of the way home (straight to the home's entry point)."""
            ok = np.asarray(area_legs(starts, ends), dtype=bool)
            before = np.hypot(starts[:, 0] - pose[0], starts[:, 1] - pose[1]) + np.abs(starts[:, 2] - pose[2])
            during = np.hypot(ends[:, 0] - starts[:, 0], ends[:, 1] - starts[:, 1]) + np.abs(ends[:, 2] - starts[:, 2])
            after = np.hypot(ends[:, 0] - entry[0], ends[:, 1] - entry[1]) + outside
            return ok & ((before + during + after) / uav.speed_m_s <= budget)

        return self._feasible_leg(k, planner, work, pose, others, budget, left, allowed)

    def _feasible_leg(self, k: int, planner, work: ProbabilityMap, pose, others, budget: float, left: float,
                      allowed):
        """The planner's leg from ``pose`` among the legs ``allowed`` passes, shortened until it
        and the way home fit ``budget`` [s] (up to 3 tries), or None."""
        uav = self.config.uavs[k]
        for _ in range(3):
            if left <= uav.image_interval_s:
                return None
            leg = np.asarray(planner.plan(work, k, pose, left, others, allowed_legs=allowed), dtype=float).reshape(-1, 3)
            moved = np.hypot(*(leg[:, :2] - pose[:2]).T) + np.abs(leg[:, 2] - pose[2])
            if not np.any(moved > 1e-6):
                return None
            points = np.vstack([pose[None], leg])
            keep = np.r_[True, np.any(np.abs(np.diff(points, axis=0)) > 1e-9, axis=1)]
            points = points[keep]
            duration = float(np.sum(np.hypot(*np.diff(points[:, :2], axis=0).T) + np.abs(np.diff(points[:, 2])))) \
                / uav.speed_m_s
            overshoot = duration + self.home_time_s(k, points[-1, :2]) - budget
            if overshoot <= 0:
                return points[1:]
            left -= overshoot + uav.image_interval_s
        return None

    def _book(self, work: ProbabilityMap, k: int, a: np.ndarray, b: np.ndarray) -> None:
        """Book the images UAV k takes from a to b (x, y, altitude) [m] as if they saw nothing."""
        uav = self.config.uavs[k]
        spacing = uav.speed_m_s * uav.image_interval_s
        length = float(np.hypot(*(b[:2] - a[:2])))
        if length <= 1e-9:
            return
        n = max(1, int(round(length / spacing)))
        camera = self.cameras[k]
        width_x, width_y = camera.footprint_m(float(b[2]))
        if abs(b[0] - a[0]) > abs(b[1] - a[1]):  # an east-west leg: the across-track side along y
            width_x, width_y = width_y, width_x
        windows = []
        for j in range(n):
            point = b + (a - b) * (j * spacing / length)
            windows.append(work.grid.window(float(point[0]), float(point[1]), float(width_x), float(width_y)))
        work.expected_no_detection_update(windows, np.full(n, float(b[2])), self.config.detector, camera)

    # ------------------------------------------------------------------------------------
    def summary(self, plans: list[UavPlan] | None = None) -> dict:
        """Elapsed and remaining time per UAV, expected people found, P(all found), area seen,
        the planner's time (the figures of summary.json); plans: the plans just made (their
        lengths are added per UAV), or None."""
        positions, masses, counts, cells = self.targets()
        grid = self.ground.grid
        searchable = self.ground.searchable
        per_uav = []
        for k, uav in enumerate(self.config.uavs):
            _, elapsed = self.uav_state(k)
            item = {"uav": uav.name, "elapsed_s": round(elapsed, 3),
                    "remaining_s": round(max(self.config.flight_time_s - elapsed, 0.0), 3),
                    "images": int(np.count_nonzero(self.logs.image_uav == k))}
            if plans is not None:
                plan = plans[k]
                item["plan_waypoints"] = int(len(plan.waypoints))
                item["plan_end_s"] = round(float(plan.waypoints[-1, 3]) if len(plan.waypoints) else elapsed, 3)
                item["return_home_s"] = round(plan.home_time_s, 3)
            per_uav.append(item)
        probability = logistic(self.belief.log_odds)
        seen_area = float(np.count_nonzero(self.seen & searchable)) * grid.cell_area_m2
        return {
            "uavs": per_uav,
            "expected_people": float(self.config.people),
            "expected_people_found": round(float(np.sum(masses)), 6),
            "expected_people_left": round(float(probability[searchable].sum() - np.sum(
                [probability.ravel()[c].sum() for c in cells])), 6) if cells else round(float(probability[searchable].sum()), 6),
            "p_all_found": round(self.p_all_found(cells), 6),
            "p_all_found_model": "known number of people" if self.config.people_known else "expected number of people",
            "targets": int(len(positions)),
            "area_m2": round(float(np.count_nonzero(searchable)) * grid.cell_area_m2, 3),
            "area_covered_m2": round(seen_area, 3),
            "area_covered_fraction": round(seen_area / max(float(np.count_nonzero(searchable)) * grid.cell_area_m2, 1e-12), 6),
            "images": int(self.logs.n_images),
            "detections": int(len(self.logs.detection_lon)),
            "cells": int(grid.n_cells),
            "cell_size_m": grid.cell_size_m,
            "planner": getattr(self, "planner_name", None),
            "planner_time_s": round(getattr(self, "planner_time_s", 0.0), 4),
            "fusion_time_s": round(self.fusion_time_s, 4),
        }


def at_least(probabilities: np.ndarray, count: int) -> float:
    """P(at least ``count`` of independent events happen), event k with probability
    probabilities[k] (the Poisson-binomial tail, by the O(k count) recursion over events)."""
    if count <= 0:
        return 1.0
    # distribution of the number of events so far, truncated at count (the last bin holds >= count)
    counts = np.zeros(count + 1)
    counts[0] = 1.0
    for q in np.asarray(probabilities, dtype=float):
        moved = counts * q
        counts = counts * (1.0 - q)
        counts[1:] += moved[:-1]
        counts[-1] += moved[-1]
    return float(counts[-1])


def footprint_cells(grid, x: float, y: float, altitude_m: float, yaw_deg: float, fov_deg) -> tuple[tuple[slice, slice], np.ndarray]:
    """The window (rows, cols) and the bool mask of its cells whose centres lie in the ground
    rectangle of a nadir image (module docstring).

    grid: the MapGrid; x, y: the camera's position [m]; altitude_m: h above the ground [m];
    yaw_deg: heading psi from north, clockwise [deg]; fov_deg: (across-track, along-track) full
    fields of view [deg]."""
    h = max(float(altitude_m), 0.0)
    half_across = h * np.tan(np.radians(fov_deg[0]) / 2)
    half_along = h * np.tan(np.radians(fov_deg[1]) / 2)
    psi = np.radians(yaw_deg)
    s, c = np.sin(psi), np.cos(psi)
    wx = abs(half_across * c) + abs(half_along * s)
    wy = abs(half_across * s) + abs(half_along * c)
    window = grid.window(x, y, 2 * wx, 2 * wy)
    cx, cy = grid.window_centres(window)
    dx, dy = cx[None, :] - x, cy[:, None] - y
    tol = 1e-9
    visible = (np.abs(dx * c - dy * s) <= half_across + tol) & (np.abs(dx * s + dy * c) <= half_along + tol)
    return window, visible
