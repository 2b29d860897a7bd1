"""Episode runner: plan, fly (images at 0.15 Hz along the path), fuse, replan, until the flight
budget is spent; every metric of metrics.map_metrics logged at every image.

Costs of switching between action and perception (both off by default, which is the plain
episode bit for bit):

- motion blur: a :class:`attend.action.Detector` with blur coefficients degrades every image by
  the UAV's speed when it is taken (rest-to-rest segments: sharp at waypoints and in hover);
- ``planning_latency_s`` L: every (re)plan takes L seconds of on-board computing, which count
  against the flight budget (the battery). ``latency_mode`` "hover": the UAV hovers where it
  stopped; the images due meanwhile are taken there (sharp). "fly": it keeps flying the rest of
  the old plan for L s (imaging, no decisions) and then starts the new plan from where it is;
  when no old plan is left (at take-off, or a plan flown to its end) it hovers. Either way the
  plan is made from the belief at the start of the latency.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Callable, Sequence

import numpy as np

from attend.action.belief import OccupancyMap
from attend.action.camera import take_image
from attend.action.errors import ActionInputError
from attend.action.field import SearchField, validate_pose
from attend.action.metrics import map_metrics
from attend.action.planners import Planner


@dataclass
class EpisodeLog:
    """Everything logged in one mission.

    times_s (m,): image times; poses_m (m, 3): image poses; metrics: name -> (m,) per image
    (entry 0 is the prior at t = 0, before any image); planner_times_s: wall time per replan;
    waypoints_m (w, 3): the flown waypoints (start first); means / variances (m + 1, n): map
    after each image (entry 0 the prior); clutter_cells: false blobs per image; people_total;
    replan_times_s: mission time [s] of every replan (the first at 0); decision_times_s: wall
    time [s] of the replan policy's own decisions per plan; hover_s: flight time [s] spent
    hovering for planning latency. planner: the planner's name; seed: the mission's seed;
    budget_s: flight budget [s].
    """

    planner: str
    seed: int
    budget_s: float
    people_total: int
    times_s: list[float] = dataclass_field(default_factory=list)
    poses_m: list[np.ndarray] = dataclass_field(default_factory=list)
    metrics: dict[str, list[float]] = dataclass_field(default_factory=dict)
    planner_times_s: list[float] = dataclass_field(default_factory=list)
    waypoints_m: list[np.ndarray] = dataclass_field(default_factory=list)
    means: list[np.ndarray] = dataclass_field(default_factory=list)
    variances: list[np.ndarray] = dataclass_field(default_factory=list)
    clutter_cells: list[np.ndarray] = dataclass_field(default_factory=list)
    replan_times_s: list[float] = dataclass_field(default_factory=list)
    decision_times_s: list[float] = dataclass_field(default_factory=list)
    hover_s: float = 0.0

    def series(self, name: str) -> np.ndarray:
        """The metric ``name`` per metric entry (prior first)."""
        return np.asarray(self.metrics[name])

    @property
    def metric_times_s(self) -> np.ndarray:
        """Times of the metric entries: 0 for the prior, then each image time."""
        return np.concatenate([[0.0], np.asarray(self.times_s)])

    def time_to_find_all_s(self, criterion: str = "people_found") -> float:
        """First image time at which all people are found (inf if never); ``criterion`` is the
        metric counting found people ("people_found" or "people_found_person_mean")."""
        found = self.series(criterion)
        hits = np.flatnonzero(found >= self.people_total)
        return float(self.metric_times_s[hits[0]]) if len(hits) else float("inf")

    def value_at(self, name: str, times_s: np.ndarray) -> np.ndarray:
        """Step-interpolated metric ``name`` at the times ``times_s`` [s] (value after the last
        image before t)."""
        index = np.searchsorted(self.metric_times_s, np.asarray(times_s), side="right") - 1
        return self.series(name)[np.clip(index, 0, None)]


@dataclass
class PlanContext:
    """What a replan policy sees at a decision: the ``planner``, the ``belief`` (just updated), the
    ``pose`` [m], the rest of the plan ``remaining`` (k, 3) [m], the mission ``time_s``, the time to
    the next image ``time_to_next_image_s`` and the flight time left ``time_left_s`` [s]."""

    planner: Planner
    belief: OccupancyMap
    pose: np.ndarray
    remaining: np.ndarray
    time_s: float
    time_to_next_image_s: float
    time_left_s: float


class ReplanPolicy:
    """When the UAV stops following its plan and replans (the hook of :func:`fly`).

    This base policy is the plain episode: fly the planner's ``waypoints_per_replan`` waypoints
    of each plan (all if None), then replan. Subclasses (attend.rhythm.replanning) override
    ``waypoints_per_plan``, ``deadline(plan_start_s, first_image_s)`` (mission time [s] at which
    a plan is cut), ``start_plan(context)`` (after each replan) and ``after_image(context)``
    (after each image but one taken where a plan starts: True to replan now)."""

    name = "planner"

    def reset(self) -> None:
        """Start a new mission."""

    def waypoints_per_plan(self, planner: Planner) -> int | None:
        """Waypoints of each plan to fly before replanning (None: all); planner: the mission's planner."""
        return planner.waypoints_per_replan

    def deadline(self, plan_start_s: float, first_image_s: float) -> float:
        """Mission time [s] at which the current plan is cut (inf: no deadline); plan_start_s:
        mission time of the plan's start [s]; first_image_s: mission time of its first image [s]."""
        return float("inf")

    def start_plan(self, context: PlanContext) -> None:
        """Called after every replan with the new plan in ``context.remaining``."""

    def after_image(self, context: PlanContext) -> bool:
        """Called after every image (the belief already holds it): replan now? context: the
        decision's :class:`PlanContext`."""
        return False


def fly(
    field: SearchField,
    planner: Planner,
    budget_s: float = 150.0,
    seed: int = 0,
    policy: ReplanPolicy | None = None,
    *,
    diagonal: bool = False,
    keep_maps: bool = True,
    charge_planning_time: bool = False,
    inject_false_detection_images: Sequence[int] = (),
    planning_latency_s: float = 0.0,
    latency_mode: str = "hover",
    on_image: Callable[[float], None] | None = None,
    log: EpisodeLog | None = None,
) -> EpisodeLog:
    """Fly one mission: plan, fly the plan taking images at the camera rate and fusing each into
    the map (every metric of :func:`attend.action.metrics.map_metrics` logged at each), replan
    when ``policy`` says so or the plan is flown, until ``budget_s`` of flight time is spent.
    Camera, detector (its blur coefficients degrade images by the speed at which they are taken)
    and flight model come from ``planner.setup``, the map prior from ``planner.setup.map_prior``.

    field: the search field (people, obstacles, start pose); planner: any :class:`Planner`
    (reset with ``seed`` at the start); budget_s: flight budget [s] (> 0); seed: seeds the
    detector noise and the planner; policy: when to replan (:class:`ReplanPolicy`; None: after
    the planner's ``waypoints_per_replan`` waypoints); diagonal: per-cell (diagonal) Kalman
    filter instead of the full covariance; keep_maps: log the map mean and variance after every
    image; charge_planning_time: the UAV hovers while planning and that wall time counts against
    the budget; inject_false_detection_images: image numbers (0 = first) that get one false
    2 x 3-cell blob; planning_latency_s: seconds of on-board planning per (re)plan, counted
    against the budget; latency_mode: "hover" (wait where the UAV stopped) or "fly" (keep flying
    the rest of the old plan, if any, while the new one is computed; module docstring);
    on_image: called with the mission time [s] of every image (e.g. to show progress); log: an
    empty :class:`EpisodeLog` (or subclass) with this ``budget_s`` and ``seed`` to fill (None: a
    new one). Returns the log, including the mission time of every replan and the wall time of
    the policy's decisions per plan.
    """
    if not (np.isfinite(budget_s) and budget_s > 0):
        raise ActionInputError(f"budget_s: expected a flight budget > 0 s, got {budget_s!r}")
    if latency_mode not in ("hover", "fly"):
        raise ActionInputError(f"latency_mode: expected 'hover' or 'fly', got {latency_mode!r}")
    latency = float(planning_latency_s)
    if not (np.isfinite(latency) and latency >= 0):
        raise ActionInputError(f"planning_latency_s: expected a latency >= 0 s, got {planning_latency_s!r}")
    if log is None:
        log = EpisodeLog(planner.name, seed, float(budget_s), len(field.people))
    elif log.times_s or log.budget_s != float(budget_s) or log.seed != seed:
        raise ActionInputError(f"log: expected an empty EpisodeLog with budget_s={budget_s!r} and seed={seed!r}")
    mission = _Mission(field, planner, log, ReplanPolicy() if policy is None else policy, diagonal, keep_maps,
                       inject_false_detection_images, on_image)
    mission.run(charge_planning_time, latency, latency_mode)
    return log


class _Mission:
    """The state of one flight: belief, pose, mission time, images taken (used by :func:`fly`)."""

    def __init__(self, field, planner, log, policy, diagonal, keep_maps, inject_false_detection_images, on_image) -> None:
        self.field, self.planner, self.log, self.policy = field, planner, log, policy
        setup = planner.setup
        self.camera, self.detector, self.flight = setup.camera, setup.detector, setup.flight
        self.keep_maps, self.on_image = keep_maps, on_image
        self.inject = set(int(i) for i in inject_false_detection_images)
        self.pose = validate_pose(field.start_pose_m, field.grid, field.altitude_limits_m, "start_pose_m")
        self.rng = np.random.default_rng(log.seed)
        planner.reset(log.seed)
        policy.reset()
        self.belief = OccupancyMap.prior(field.grid, diagonal=diagonal, prior=setup.map_prior)
        self.elapsed, self.time_to_next_image, self.n_images, self.deciding = 0.0, 0.0, 0, 0.0
        self.record()
        log.waypoints_m.append(self.pose.copy())

    def record(self, image=None) -> None:
        """Log every metric of the belief (and the maps, the image) after the prior or an image."""
        belief, field, log = self.belief, self.field, self.log
        values = map_metrics(belief.mean, belief.variance, field.truth, field.person_cells, field.grid.shape)
        for key, value in values.items():
            log.metrics.setdefault(key, []).append(value)
        if self.keep_maps:
            log.means.append(belief.mean.copy())
            log.variances.append(belief.variance.copy())
        if image is not None:
            log.times_s.append(image.time_s)
            log.poses_m.append(image.pose_m)
            log.clutter_cells.append(image.clutter_cells)

    def take(self, image_pose, image_time: float, speed: float = 0.0) -> None:
        """Take an image at ``image_pose`` [m] and mission time ``image_time`` [s], fuse and log it."""
        image = take_image(self.field, self.camera, self.detector, image_pose, image_time, self.rng,
                           inject_false_blob=self.n_images in self.inject, speed_m_s=speed)
        self.belief.fuse(image.cells, image.measurements, image.noise_variance)
        self.record(image)
        self.n_images += 1
        if self.on_image is not None:
            self.on_image(image.time_s)


    def follow(self, path: np.ndarray, limit: int | None, stop: float, decide: bool) -> tuple[bool, np.ndarray]:
        """Fly the first ``limit`` waypoints of ``path`` (all if None) until mission time ``stop``,
        imaging and fusing; with ``decide`` the policy may cut after each image. Returns whether
        it cut and the rest of ``path`` not reached."""
        flight = self.flight
        count = len(path) if limit is None else min(limit, len(path))
        for j in range(count):
            goal = path[j]
            if stop - self.elapsed <= 1e-9:
                return False, path[j:]
            start = self.pose
            travel = float(flight.segment_duration(np.linalg.norm(goal - start)))
            poses, times, valid, duration, next_after, speeds = flight.segment_images(
                start, goal, self.time_to_next_image, stop - self.elapsed, with_speeds=True)
            flown, next_image, cut = float(duration[0]), float(next_after[0]), False
            for image_pose, image_time, speed in zip(poses[0][valid[0]], times[0][valid[0]], speeds[0][valid[0]]):
                self.take(image_pose, self.elapsed + image_time, float(speed))
                if not decide or (j == 0 and image_time <= 1e-9):
                    continue  # taken where the plan starts, before any flight: no decision yet
                rest = path[j + 1:] if image_time >= travel - 1e-9 else path[j:]
                tic = time.perf_counter()
                cut = self.policy.after_image(PlanContext(
                    self.planner, self.belief, np.asarray(image_pose, float), rest, self.elapsed + image_time,
                    flight.image_period_s, self.log.budget_s - self.elapsed - image_time))
                self.deciding += time.perf_counter() - tic
                if cut:
                    flown, next_image = float(image_time), flight.image_period_s
                    break
            arrived = flown >= travel - 1e-9
            self.pose = np.asarray(goal, float) if arrived else flight_position(flight, start, goal, flown)
            self.log.waypoints_m.append(self.pose.copy())
            self.elapsed += flown
            self.time_to_next_image = next_image
            if cut or self.elapsed >= stop - 1e-9:
                return cut, path[j + 1:] if arrived else path[j:]
        return False, path[count:]

    def hover(self, duration_s: float) -> None:
        """Hover ``duration_s`` [s] where the UAV is; the camera keeps shooting (sharp images)."""
        while self.time_to_next_image < duration_s - 1e-9:
            self.take(self.pose.copy(), self.elapsed + self.time_to_next_image)
            self.time_to_next_image += self.flight.image_period_s
        self.time_to_next_image -= duration_s
        self.elapsed += duration_s
        self.log.hover_s += duration_s

    def plan(self, charge_planning_time: bool, latency: float, latency_mode: str,
             leftover: np.ndarray) -> np.ndarray | None:
        """One (re)plan with its costs: planning latency (hovering, or flying ``leftover``, the
        rest of the old plan) and charged planning time. Returns the plan, or None when the
        budget ran out meanwhile."""
        budget_s, log = self.log.budget_s, self.log
        # latency flown on the old plan: plan now (belief and time of now) from where the UAV will be
        fly_old = latency > 0 and latency_mode == "fly" and len(leftover) > 0
        if fly_old:
            planning_belief, planning_time = self.belief.copy(), self.elapsed
            self.follow(leftover, None, min(budget_s, self.elapsed + latency), decide=False)
            if self.elapsed >= budget_s - 1e-9:
                return None
        else:
            planning_belief, planning_time = self.belief, self.elapsed
        tic = time.perf_counter()
        plan = self.planner.plan(planning_belief, self.pose, budget_s - self.elapsed, self.time_to_next_image)
        planning = time.perf_counter() - tic
        log.planner_times_s.append(planning)
        log.replan_times_s.append(planning_time)
        if charge_planning_time:
            self.elapsed += planning
            self.time_to_next_image = max(self.time_to_next_image - planning, 0.0)
            if self.elapsed >= budget_s:
                return None
        if latency > 0 and not fly_old:  # hover while the on-board computer plans
            self.hover(min(latency, budget_s - self.elapsed))
            if self.elapsed >= budget_s - 1e-9:
                return None
        return np.atleast_2d(plan).reshape(-1, 3)

    def run(self, charge_planning_time: bool, latency: float, latency_mode: str) -> None:
        """Plan and fly until the budget is spent (or a planner returns no waypoint)."""
        budget_s, log, policy = self.log.budget_s, self.log, self.policy
        leftover = np.zeros((0, 3))
        while self.elapsed < budget_s - 1e-9:
            plan = self.plan(charge_planning_time, latency, latency_mode, leftover)
            if plan is None or len(plan) == 0:
                break
            tic = time.perf_counter()
            policy.start_plan(PlanContext(self.planner, self.belief, self.pose, plan, self.elapsed,
                                          self.time_to_next_image, budget_s - self.elapsed))
            self.deciding = time.perf_counter() - tic
            deadline = policy.deadline(self.elapsed, self.elapsed + self.time_to_next_image)
            _, leftover = self.follow(plan, policy.waypoints_per_plan(self.planner), min(budget_s, deadline), decide=True)
            log.decision_times_s.append(self.deciding)


def belief_after_images(field: SearchField, setup, poses_m: Sequence[Sequence[float]], seed: int = 0,
                        diagonal: bool = False) -> OccupancyMap:
    """The map after one image at each pose (taken at t = 0, no flight), from the setup's prior.

    field: the search field; setup: a :class:`attend.action.PlanningSetup` (camera, detector,
    map prior); poses_m: image poses (x, y, z) [m]; seed: seeds the detector noise; diagonal:
    per-cell (diagonal) map."""
    rng = np.random.default_rng(seed)
    belief = OccupancyMap.prior(field.grid, diagonal=diagonal, prior=setup.map_prior)
    for pose in poses_m:
        image = take_image(field, setup.camera, setup.detector, pose, 0.0, rng)
        belief.fuse(image.cells, image.measurements, image.noise_variance)
    return belief


def flight_position(flight, start: np.ndarray, goal: np.ndarray, elapsed_s: float) -> np.ndarray:
    """Position after ``elapsed_s`` [s] on the rest-to-rest segment start -> goal.

    flight: the flight model; start, goal: segment ends (x, y, z) [m]; elapsed_s: time flown [s]."""
    length = float(np.linalg.norm(goal - start))
    if length == 0:
        return np.asarray(start, float)
    flown = float(flight.distance_after(elapsed_s, length))
    return start + (goal - start) * flown / length
