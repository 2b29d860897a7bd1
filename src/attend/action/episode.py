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
from typing import Sequence

import numpy as np

from attend.action.belief import OccupancyMap
from attend.action.camera import take_image
from attend.action.errors import ActionInputError
from attend.action.field import validate_pose
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
    hovering for planning latency.
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
        """Step-interpolated metric at the given times (value after the last image before t)."""
        index = np.searchsorted(self.metric_times_s, np.asarray(times_s), side="right") - 1
        return self.series(name)[np.clip(index, 0, None)]


@dataclass
class PlanContext:
    """What a replan policy sees at a decision: the ``planner``, the ``belief`` (just updated), the
    ``pose`` [m], the rest of the plan ``remaining`` (k, 3) [m], the mission ``time_s``, the time to
    the next image and the flight time left [s]."""

    planner: Planner
    belief: OccupancyMap
    pose: np.ndarray
    remaining: np.ndarray
    time_s: float
    time_to_next_image_s: float
    time_left_s: float


class ReplanPolicy:
    """When the UAV stops following its plan and replans (the hook of :func:`fly_mission`).

    This base policy is the plain episode: fly the planner's ``waypoints_per_replan`` waypoints
    of each plan (all if None), then replan. Subclasses (attend.rhythm.ipp_schedule) override
    ``waypoints_per_plan``, ``deadline(plan_start_s, first_image_s)`` (mission time [s] at which
    a plan is cut), ``start_plan(context)`` (after each replan) and ``after_image(context)``
    (after each image but one taken where a plan starts: True to replan now)."""

    name = "planner"

    def reset(self) -> None:
        """Start a new mission."""

    def waypoints_per_plan(self, planner: Planner) -> int | None:
        """Waypoints of each plan to fly before replanning (None: all)."""
        return planner.waypoints_per_replan

    def deadline(self, plan_start_s: float, first_image_s: float) -> float:
        """Mission time [s] at which the current plan is cut (inf: no deadline)."""
        return float("inf")

    def start_plan(self, context: PlanContext) -> None:
        """Called after every replan with the new plan in ``context.remaining``."""

    def after_image(self, context: PlanContext) -> bool:
        """Called after every image (the belief already holds it): replan now?"""
        return False


def run_episode(
    field,
    planner: Planner,
    camera,
    detector,
    flight,
    budget_s: float = 150.0,
    seed: int = 0,
    diagonal: bool = False,
    charge_planning_time: bool = False,
    inject_false_detection_images: Sequence[int] = (),
    keep_maps: bool = True,
    on_image=None,
    planning_latency_s: float = 0.0,
    latency_mode: str = "hover",
) -> EpisodeLog:
    """Fly one mission of ``budget_s`` s with ``planner``; detector randomness from ``seed``.

    diagonal: per-cell (diagonal) Kalman filter instead of full covariance;
    charge_planning_time: the UAV hovers while planning and that time counts against the budget;
    inject_false_detection_images: image numbers (0 = first) that get one false 2 x 3-cell blob;
    on_image: called with the mission time [s] of every image (e.g. to show progress);
    planning_latency_s: seconds of on-board planning per (re)plan, counted against the budget,
    spent hovering (latency_mode "hover") or flying the old plan ("fly").
    """
    if not (np.isfinite(budget_s) and budget_s > 0):
        raise ActionInputError(f"budget_s: expected a flight budget > 0 s, got {budget_s!r}")
    log = EpisodeLog(planner.name, seed, float(budget_s), len(field.people))
    return fly_mission(field, planner, camera, detector, flight, log, ReplanPolicy(), diagonal=diagonal,
                       charge_planning_time=charge_planning_time,
                       inject_false_detection_images=inject_false_detection_images, keep_maps=keep_maps,
                       on_image=on_image, planning_latency_s=planning_latency_s, latency_mode=latency_mode)


def fly_mission(field, planner: Planner, camera, detector, flight, log: EpisodeLog, policy: ReplanPolicy,
                diagonal: bool = False, charge_planning_time: bool = False,
                inject_false_detection_images: Sequence[int] = (), keep_maps: bool = True,
                on_image=None, planning_latency_s: float = 0.0, latency_mode: str = "hover") -> EpisodeLog:
    """The flight loop behind every episode: plan, fly the plan taking and fusing images (every
    metric logged at each), replan when ``policy`` says so or the plan is flown, until
    ``log.budget_s`` is spent. Detector noise and planner seed from ``log.seed``; ``log`` (an
    empty :class:`EpisodeLog` or subclass) is filled and returned, including the mission time of
    every replan (``replan_times_s``) and the wall time of the policy's decisions per plan.
    ``on_image``, if given, is called with the mission time [s] of every image.
    ``planning_latency_s``: seconds of on-board planning per (re)plan, charged against the budget;
    ``latency_mode`` "hover" (wait where the UAV stopped) or "fly" (keep flying the rest of the old
    plan, if any, while the new one is computed; module docstring); ``detector`` blur
    coefficients degrade images by the speed at which they are taken."""
    if latency_mode not in ("hover", "fly"):
        raise ActionInputError(f"latency_mode: expected 'hover' or 'fly', got {latency_mode!r}")
    latency = float(planning_latency_s)
    if not (np.isfinite(latency) and latency >= 0):
        raise ActionInputError(f"planning_latency_s: expected a latency >= 0 s, got {planning_latency_s!r}")
    budget_s, seed = log.budget_s, log.seed
    pose = validate_pose(field.start_pose_m, field.grid, field.altitude_limits_m, "start_pose_m")
    rng = np.random.default_rng(seed)
    planner.reset(seed)
    policy.reset()
    belief = OccupancyMap.prior(field.grid, diagonal=diagonal)
    truth = field.truth

    def record(image=None) -> None:
        values = map_metrics(belief.mean, belief.variance, truth, field.person_cells, field.grid.shape)
        for key, value in values.items():
            log.metrics.setdefault(key, []).append(value)
        if keep_maps:
            log.means.append(belief.mean.copy())
            log.variances.append(belief.variance.copy())
        if image is not None:
            log.times_s.append(image.time_s)
            log.poses_m.append(image.pose_m)
            log.clutter_cells.append(image.clutter_cells)

    record()
    log.waypoints_m.append(pose.copy())
    elapsed, time_to_next_image = 0.0, 0.0
    n_images = 0
    inject = set(int(i) for i in inject_false_detection_images)

    def take(image_pose, image_time, speed=0.0) -> None:
        nonlocal n_images
        image = take_image(field, camera, detector, image_pose, image_time, rng,
                           inject_false_blob=n_images in inject, speed_m_s=speed)
        belief.fuse(image.cells, image.measurements, image.noise_variance)
        record(image)
        n_images += 1
        if on_image is not None:
            on_image(image.time_s)

    deciding = 0.0

    def fly(path: np.ndarray, limit: int | None, stop: float, decide: bool) -> tuple[bool, np.ndarray]:
        """Fly the first ``limit`` waypoints of ``path`` (all if None) until mission time ``stop``,
        imaging and fusing; with ``decide`` the policy may cut after each image. Returns whether
        it cut and the rest of ``path`` not reached."""
        nonlocal pose, elapsed, time_to_next_image, deciding
        count = len(path) if limit is None else min(limit, len(path))
        for j in range(count):
            goal = path[j]
            if stop - elapsed <= 1e-9:
                return False, path[j:]
            start = pose
            travel = float(flight.segment_duration(np.linalg.norm(goal - start)))
            poses, times, valid, duration, next_after, speeds = flight.segment_images(
                start, goal, time_to_next_image, stop - elapsed, with_speeds=True)
            flown, next_image, cut = float(duration[0]), float(next_after[0]), False
            for image_pose, image_time, speed in zip(poses[0][valid[0]], times[0][valid[0]], speeds[0][valid[0]]):
                take(image_pose, elapsed + image_time, float(speed))
                if not decide or (j == 0 and image_time <= 1e-9):
                    continue  # taken where the plan starts, before any flight: no decision yet
                rest = path[j + 1:] if image_time >= travel - 1e-9 else path[j:]
                tic = time.perf_counter()
                cut = policy.after_image(PlanContext(planner, belief, np.asarray(image_pose, float), rest,
                                                     elapsed + image_time, flight.image_period_s,
                                                     budget_s - elapsed - image_time))
                deciding += time.perf_counter() - tic
                if cut:
                    flown, next_image = float(image_time), flight.image_period_s
                    break
            arrived = flown >= travel - 1e-9
            pose = np.asarray(goal, float) if arrived else flight_position(flight, start, goal, flown)
            log.waypoints_m.append(pose.copy())
            elapsed += flown
            time_to_next_image = next_image
            if cut or elapsed >= stop - 1e-9:
                return cut, path[j + 1:] if arrived else path[j:]
        return False, path[count:]

    leftover = np.zeros((0, 3))
    while elapsed < budget_s - 1e-9:
        # latency flown on the old plan: plan now (belief and time of now) from where the UAV will be
        fly_old = latency > 0 and latency_mode == "fly" and len(leftover) > 0
        if fly_old:
            planning_belief, planning_time = belief.copy(), elapsed
            fly(leftover, None, min(budget_s, elapsed + latency), decide=False)
            if elapsed >= budget_s - 1e-9:
                break
        else:
            planning_belief, planning_time = belief, elapsed
        tic = time.perf_counter()
        plan = np.atleast_2d(planner.plan(planning_belief, pose, budget_s - elapsed, time_to_next_image)).reshape(-1, 3)
        planning = time.perf_counter() - tic
        log.planner_times_s.append(planning)
        log.replan_times_s.append(planning_time)
        if charge_planning_time:
            elapsed += planning
            time_to_next_image = max(time_to_next_image - planning, 0.0)
            if elapsed >= budget_s:
                break
        if latency > 0 and not fly_old:  # hover while the on-board computer plans; the camera keeps shooting (sharp)
            hover = min(latency, budget_s - elapsed)
            while time_to_next_image < hover - 1e-9:
                take(pose.copy(), elapsed + time_to_next_image)
                time_to_next_image += flight.image_period_s
            time_to_next_image -= hover
            elapsed += hover
            log.hover_s += hover
            if elapsed >= budget_s - 1e-9:
                break
        if len(plan) == 0:
            break
        tic = time.perf_counter()
        policy.start_plan(PlanContext(planner, belief, pose, plan, elapsed, time_to_next_image, budget_s - elapsed))
        deciding = time.perf_counter() - tic
        deadline = policy.deadline(elapsed, elapsed + time_to_next_image)
        _, leftover = fly(plan, policy.waypoints_per_plan(planner), min(budget_s, deadline), decide=True)
        log.decision_times_s.append(deciding)
    return log


def flight_position(flight, start: np.ndarray, goal: np.ndarray, elapsed_s: float) -> np.ndarray:
    """Position after ``elapsed_s`` on the rest-to-rest segment start -> goal."""
    length = float(np.linalg.norm(goal - start))
    if length == 0:
        return np.asarray(start, float)
    flown = float(flight.distance_after(elapsed_s, length))
    return start + (goal - start) * flown / length
