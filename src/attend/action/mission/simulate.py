"""A dry run of a mission (``attend plan --simulate``): people placed by a seed, images and
detections simulated with the mission's own detector, the plan flown and replanned.

People: round(people) of them (at least 1), each in a searchable cell drawn with probability
proportional to the prior p_c, uniform within the cell. Flight: every ``replan_s`` seconds all
UAVs replan (:meth:`Mission.plan`) and fly their plans, straight between waypoints at their speed
(timed by the plan's t_s), one image every image_interval_s, heading along the leg. An image at
altitude h sees the ground rectangle of :func:`attend.action.mission.mission.footprint_cells`;
each person in it is reported with probability pd(h) at their position plus N(0, sigma^2 I); a
Poisson number lambda(h) of false detections fall uniformly in the rectangle. A person counts as
found when a target lies within ``found_radius_m`` of them (default 3 sigma, at least two cells).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from attend.action.log_odds import logistic

from attend.action.mission.errors import MissionInputError
from attend.action.mission.flight_logs import FlightLogs
from attend.action.mission.mission import Mission


@dataclass
class SimulationResult:
    """A simulated mission: people_m (n, 2) [m]; found_times_s (n,) when each was first found
    (inf: never); false_targets: targets with nobody within the found radius at the end;
    replans: calls to the planner; planner_times_s: their wall times [s]; p_all_found: at the
    end; found_radius_m [m]."""

    people_m: np.ndarray
    found_times_s: np.ndarray
    false_targets: int
    replans: int
    planner_times_s: list = field(default_factory=list)
    p_all_found: float = float("nan")
    found_radius_m: float = 0.0

    def time_to_fraction_s(self, fraction: float) -> float:
        """Time [s] at which ceil(fraction n) people were found (inf: never)."""
        need = max(1, math.ceil(fraction * len(self.people_m) - 1e-9))
        times = np.sort(self.found_times_s)
        return float(times[need - 1]) if len(times) >= need else math.inf


def place_people(mission: Mission, rng: np.random.Generator) -> np.ndarray:
    """(n, 2) [m] positions of round(people) people (module docstring); mission: their area
    and prior; rng: the random generator."""
    grid = mission.ground.grid
    weights = np.where(mission.ground.searchable, logistic(mission.prior.log_odds), 0.0).ravel()
    n = max(1, int(round(mission.config.people)))
    cells = rng.choice(weights.size, size=n, replace=True, p=weights / weights.sum())
    rows, cols = np.divmod(cells, grid.nx)
    x = grid.origin_m[0] + (cols + rng.uniform(size=n)) * grid.cell_size_m
    y = grid.origin_m[1] + (rows + rng.uniform(size=n)) * grid.cell_size_m
    return np.column_stack([x, y])


def simulate_mission(mission: Mission, seed: int, planner: str | None = None, replan_s: float = 30.0,
                     found_radius_m: float | None = None, on_replan=None, found_check_s: float = 10.0) -> SimulationResult:
    """Fly ``mission`` to the end of its flight time (module docstring); its logs end up holding
    the simulated images and detections. seed: places the people and draws the detections;
    planner: "efe" or "lawnmower" (None: the mission's); replan_s: time between replans [s];
    found_radius_m: a person is found when a target lies this close [m] (None: module
    docstring); on_replan(mission, plans, t): called after each plan; found_check_s: the targets
    are looked at every found_check_s seconds of flight [s] (the images up to then fused; the
    flight and the plans do not depend on it), so a found time is known to within it."""
    if not (isinstance(found_check_s, (int, float)) and math.isfinite(found_check_s) and found_check_s > 0):
        raise MissionInputError(f"found_check_s: expected a time > 0 s, got {found_check_s!r}")
    config = mission.config
    rng = np.random.default_rng(seed)
    people = place_people(mission, rng)
    sigma = config.detector.position_std_m
    radius = found_radius_m if found_radius_m is not None else max(3 * sigma, 2 * config.cell_size_m)
    found = np.full(len(people), np.inf)
    mission.set_logs(FlightLogs.empty())
    columns = {name: [] for name in ("t", "uav", "x", "y", "alt", "yaw")}
    detections = {name: [] for name in ("image", "x", "y", "score")}
    clock = 0.0
    next_image = [config.uavs[k].image_interval_s * (1 + k / len(config.uavs)) for k in range(len(config.uavs))]
    headings = [0.0] * len(config.uavs)
    times, replans = [], 0
    while clock < config.flight_time_s - 1e-9:
        plans = mission.plan(planner)
        times.append(mission.planner_time_s)
        replans += 1
        if on_replan is not None:
            on_replan(mission, plans, clock)
        stop = min(clock + replan_s, config.flight_time_s)
        first_new = len(columns["t"])
        flew = False
        for k, plan in enumerate(plans):
            uav = config.uavs[k]
            if len(plan.waypoints) == 0:
                continue
            track = np.vstack([plan.start[None], plan.waypoints])  # x, y, alt, t
            end = min(stop, float(track[-1, 3]))
            while next_image[k] <= end + 1e-9:
                t = next_image[k]
                j = int(np.clip(np.searchsorted(track[:, 3], t), 1, len(track) - 1))
                a, b = track[j - 1], track[j]
                f = 0.0 if b[3] <= a[3] else (t - a[3]) / (b[3] - a[3])
                point = a[:3] + min(max(f, 0.0), 1.0) * (b[:3] - a[:3])
                if np.hypot(*(b[:2] - a[:2])) > 1e-6:
                    headings[k] = math.degrees(math.atan2(b[0] - a[0], b[1] - a[1])) % 360.0
                index = len(columns["t"])
                for name, value in zip(columns, (t, k, point[0], point[1], point[2], headings[k])):
                    columns[name].append(value)
                _detect(mission, k, point, headings[k], people, rng, index, detections)
                next_image[k] = t + uav.image_interval_s
                flew = True
        for k in range(len(plans)):  # a plan that ended early (or was empty): the UAV waits for the next call
            next_image[k] = max(next_image[k], stop)
        new_times = np.asarray(columns["t"][first_new:], dtype=float)
        logs = _as_logs(mission, columns, detections, first_new) if len(new_times) else None
        checks = np.arange(clock + found_check_s, stop - 1e-9, found_check_s).tolist() + [stop]
        appended = np.zeros(len(new_times), dtype=bool)
        for check in checks:  # the images up to each check fused, then the targets looked at
            chunk = ~appended & (new_times <= check + 1e-9)
            if chunk.any():
                mission.append_images(logs.subset(chunk))
                appended |= chunk
            elif check != stop:
                continue
            positions = mission.targets()[0]
            if len(positions):
                d = np.hypot(people[:, 0, None] - positions[None, :, 0], people[:, 1, None] - positions[None, :, 1])
                newly = (d.min(axis=1) <= radius) & ~np.isfinite(found)
                found[newly] = check
        clock = stop
        if not flew and all(len(p.waypoints) == 0 for p in plans):
            break
    positions = mission.targets()[0]
    false = 0
    if len(positions):
        d = np.hypot(people[:, 0, None] - positions[None, :, 0], people[:, 1, None] - positions[None, :, 1])
        false = int(np.count_nonzero(d.min(axis=0) > radius))
    return SimulationResult(people, found, false, replans, times, mission.p_all_found(), radius)


def _detect(mission: Mission, k: int, point, yaw_deg: float, people, rng, index: int, out: dict) -> None:
    config = mission.config
    fov = config.uavs[k].camera_fov_deg
    h = float(point[2])
    half_across = h * math.tan(math.radians(fov[0]) / 2)
    half_along = h * math.tan(math.radians(fov[1]) / 2)
    s, c = math.sin(math.radians(yaw_deg)), math.cos(math.radians(yaw_deg))
    across, along = np.array([c, -s]), np.array([s, c])
    pd = float(config.detector.detection_probability(h))
    sigma = config.detector.position_std_m
    d = people - np.asarray(point[:2])
    seen = (np.abs(d @ across) <= half_across) & (np.abs(d @ along) <= half_along)
    for person in people[seen]:
        if rng.random() < pd:
            q = person + rng.normal(0.0, sigma, 2)
            out["image"].append(index), out["x"].append(q[0]), out["y"].append(q[1])
            out["score"].append(float(rng.uniform(0.6, 1.0)))
    for _ in range(rng.poisson(float(config.detector.false_detections_per_image(h)))):
        q = np.asarray(point[:2]) + rng.uniform(-half_across, half_across) * across + rng.uniform(-half_along, half_along) * along
        out["image"].append(index), out["x"].append(q[0]), out["y"].append(q[1])
        out["score"].append(float(rng.uniform(0.3, 0.9)))


def _as_logs(mission: Mission, columns: dict, detections: dict, first: int) -> FlightLogs:
    """The images from row ``first`` on (and their detections) as FlightLogs in lon/lat."""
    frame = mission.ground.frame
    lon, lat = frame.to_lon_lat(np.asarray(columns["x"][first:]), np.asarray(columns["y"][first:]))
    image = np.asarray(detections["image"], dtype=int)
    keep = image >= first
    d_lon, d_lat = frame.to_lon_lat(np.asarray(detections["x"])[keep], np.asarray(detections["y"])[keep])
    return FlightLogs(
        image_time_s=np.asarray(columns["t"][first:], dtype=float), image_uav=np.asarray(columns["uav"][first:], dtype=int),
        image_lon=lon, image_lat=lat, image_alt_m=np.asarray(columns["alt"][first:], dtype=float),
        image_yaw_deg=np.asarray(columns["yaw"][first:], dtype=float), detection_image=image[keep] - first,
        detection_lon=d_lon, detection_lat=d_lat, detection_score=np.asarray(detections["score"])[keep])
