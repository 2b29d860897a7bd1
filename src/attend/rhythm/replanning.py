"""Replanning policies: a :mod:`schedule <attend.rhythm.schedule>` deciding when the UAV replans
in informative path planning (paper Sec. 4.4, Fig. 10).

The search-and-rescue UAV of :mod:`attend.action` plans a look-ahead path (w waypoints), flies
it taking images (each image is fused into the map at once), and at some point stops following
the plan and replans from the current belief. :func:`replan_policy` turns a schedule into that
decision (an :class:`attend.action.episode.ReplanPolicy`):

* :class:`FixedReplanning` (a :class:`FixedSchedule`): replan after ``perceive_s`` of flight on
  each plan (the segment being flown is cut there);
* :class:`RhythmicReplanning` (a :class:`RhythmicSchedule`): replan at each trough of the
  oscillator on the mission clock (the first image of a plan is always taken);
* :class:`PrecisionDrivenReplanning` (a :class:`PrecisionDrivenSchedule`): after every image
  (belief just updated) compare

      stay rate   s = [tr P - tr P_post(remaining planned path)] / T(remaining path)
      fresh rate  f = r_k * tr P / tr P_k

  (r_k: the rate of the plan chosen at the last replan k, evaluated on the belief then, with
  trace tr P_k) and replan iff  s < rho * f * exp(-kappa * sin theta(t))
  (:func:`attend.rhythm.schedule.switch_decision`). The gains are precision gains (expected
  trace reductions, covariance only: :func:`expected_trace_reduction`), scored like the
  planner's (per-cell belief: exact; full covariance: coarse-grained over 2 x 2 blocks,
  :func:`coarse_trace_reduction`).

Two anchors that are no schedule: :class:`SegmentReplanning` (replan at every waypoint, the
:mod:`attend.action` default) and :class:`ContinuousReplanning` (fly every plan to its end).
Every policy also replans when the plan is used up. :func:`make_replan_policy` builds one by
name ("segment", "fixed_20s", "oscillator", "precision", ...); :func:`fly_scheduled_mission` flies
one mission under a policy and logs, besides every map metric at every image, the replan
times, the planner wall time per replan and the wall time of the policy's own decisions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Sequence

import numpy as np
import scipy.linalg

from attend._validation import AttendInputError, positive_scalar
from attend.action.belief import OccupancyMap
from attend.action.episode import EpisodeLog, PlanContext, ReplanPolicy, fly
from attend.action.field import Grid
from attend.action.planners import Planner
from attend.rhythm.oscillator import PrecisionOscillator, _finite
from attend.rhythm.schedule import FixedSchedule, PrecisionDrivenSchedule, RhythmicSchedule, switch_decision

__all__ = [
    "ContinuousReplanning", "FixedReplanning", "PrecisionDrivenReplanning", "Replanning", "ReplanningLog",
    "RhythmicReplanning", "SegmentReplanning", "coarse_trace_reduction", "expected_trace_reduction",
    "fly_scheduled_mission", "make_replan_policy", "path_gain", "replan_policy",
]


# ----------------------------------------------------------------------------------------------
# Closed forms


def expected_trace_reduction(belief: OccupancyMap, cell_precision: np.ndarray) -> float:
    """trace(P) - trace(P_post) for measurement precision ``cell_precision`` (n,) per cell
    (d_i = sum over images of 1 / sigma^2; P_post = (P^-1 + D)^-1, independent of the data).

    Per-cell belief: sum_i v_i - 1 / (1 / v_i + d_i). Full covariance, observed set A:
    tr(T^-1 D^1/2 (P P)_AA D^1/2) with T = I + D^1/2 P_AA D^1/2.
    """
    d = np.asarray(cell_precision, dtype=float)
    if d.shape != (belief.grid.n_cells,) or np.any(d < 0) or not np.all(np.isfinite(d)):
        raise AttendInputError(f"cell_precision: expected {belief.grid.n_cells} finite values >= 0, got shape {d.shape}")
    observed = np.flatnonzero(d > 0)
    if len(observed) == 0:
        return 0.0
    if belief.diagonal:
        v = belief.covariance[observed]
        return float(np.sum(v - 1.0 / (1.0 / v + d[observed])))
    p = belief.covariance
    root = np.sqrt(d[observed])
    rows = p[observed]  # P_A: (m, n)
    t = p[np.ix_(observed, observed)] * root[:, None] * root[None, :]
    t[np.diag_indices_from(t)] += 1.0
    square = (rows @ rows.T) * root[:, None] * root[None, :]  # D^1/2 (P P)_AA D^1/2
    factor = scipy.linalg.cho_factor(t, lower=True, check_finite=False)
    return float(np.trace(scipy.linalg.cho_solve(factor, square, check_finite=False)))


def coarse_trace_reduction(belief: OccupancyMap, cell_precision: np.ndarray, block_cells: int) -> float:
    """:func:`expected_trace_reduction` of ``belief`` for ``cell_precision`` (n,) on the coarse-grained covariance the planners score with
    (attend.action.planners): P_b = B P B' over blocks of ``block_cells``^2 cells (B averages a
    block), precision summed per block, gain times the block area. ``block_cells`` = 1 (or a
    per-cell belief): exact."""
    block = int(block_cells)
    side = belief.grid.cells_per_side
    if belief.diagonal or block == 1:
        return expected_trace_reduction(belief, cell_precision)
    if block < 1 or side % block:
        raise AttendInputError(f"block_cells: expected a divisor of cells_per_side={side}, got {block_cells!r}")
    nb, n = side // block, belief.grid.n_cells
    rows = belief.covariance.reshape(n, nb, block, nb, block).sum(axis=(2, 4)).reshape(n, nb * nb)
    blocks = rows.T.reshape(nb * nb, nb, block, nb, block).sum(axis=(2, 4)).reshape(nb * nb, nb * nb)
    coarse = OccupancyMap(Grid(nb, belief.grid.cell_size_m * block), np.zeros(nb * nb), blocks / block**4)
    precision = np.asarray(cell_precision, float).reshape(nb, block, nb, block).sum(axis=(1, 3)).ravel()
    return expected_trace_reduction(coarse, precision) * block**2


def path_gain(planner: Planner, belief: OccupancyMap, pose: Sequence[float], waypoints: np.ndarray,
              time_to_next_image_s: float, time_left_s: float, block_cells: int | None = None) -> tuple[float, float]:
    """The precision gain (expected trace(P) reduction of ``belief``) of the images a path would
    take with ``planner``, and its flight time [s].

    The path starts at rest at ``pose`` and visits ``waypoints`` (w, 3) with the planner's
    flight, camera and detector models (images on the mission clock, first one after
    ``time_to_next_image_s``, flight stopped after ``time_left_s``; images taken moving are
    degraded by the detector's motion blur, if any). The gain is scored like the planner's (coarse-grained over ``block_cells``^2 blocks, default the planner's
    ``planning_block_cells``; 1: exact)."""
    path = np.asarray(waypoints, dtype=float).reshape(-1, 3)
    if len(path) == 0 or time_left_s <= 0:
        return 0.0, 0.0
    setup = planner.setup
    poses, valid, total, _, speeds = setup.flight.path_images(np.asarray(pose, float), path[None],
                                                              time_to_next_image_s, time_left_s, with_speeds=True)
    taken = poses[0][valid[0]]
    if len(taken) == 0:
        return 0.0, float(total[0])
    visible = setup.camera.visible_cells(taken, setup.field.grid, setup.field.obstacles)
    variance = setup.detector.image_noise_variance(taken[:, 2], speeds[0][valid[0]])
    precision = (visible / variance[:, None]).sum(axis=0)
    block = setup.planning_block_cells if block_cells is None else block_cells
    return coarse_trace_reduction(belief, precision, block), float(total[0])


# ----------------------------------------------------------------------------------------------
# Policies


class Replanning(ReplanPolicy):
    """Decides when the UAV stops following its plan and replans (an
    :class:`attend.action.episode.ReplanPolicy` that flies whole plans).

    ``deadline(plan_start_s, first_image_s)``: mission time [s] at which the plan is cut (inf:
    none); ``at_waypoint``: replan at every waypoint; ``start_plan(context)`` is called after
    each replan; ``after_image(context)`` after each image: True to replan now."""

    name = "schedule"
    at_waypoint = False

    def waypoints_per_plan(self, planner: Planner) -> int | None:
        """1 if the policy replans at every waypoint, else the whole plan (None); ``planner``
        is not consulted."""
        return 1 if self.at_waypoint else None


class ContinuousReplanning(Replanning):
    """Always moving, always sensing: fly every plan to its end, imaging on the way, then replan."""

    name = "continuous"


class SegmentReplanning(Replanning):
    """Replan at every waypoint (after every segment)."""

    name = "segment"
    at_waypoint = True


class FixedReplanning(Replanning):
    """Replan after ``schedule.perceive_s`` [s] of flight on each plan (or when the plan is used
    up). schedule: a :class:`FixedSchedule`."""

    def __init__(self, schedule: FixedSchedule) -> None:
        if not isinstance(schedule, FixedSchedule):
            raise AttendInputError(f"schedule: expected a FixedSchedule, got {type(schedule).__name__}")
        self.flight_time_s = schedule.perceive_s
        self.name = f"fixed_{self.flight_time_s:g}s"

    def deadline(self, plan_start_s: float, first_image_s: float) -> float:
        """``plan_start_s`` + the flight time per plan [s] (``first_image_s`` is not used)."""
        return plan_start_s + self.flight_time_s


class RhythmicReplanning(Replanning):
    """Replan at the troughs of ``schedule.oscillator`` (mission clock, s); a plan always keeps
    its first image (the first trough at or after it). schedule: a :class:`RhythmicSchedule`."""

    name = "oscillator"

    def __init__(self, schedule: RhythmicSchedule) -> None:
        if not isinstance(schedule, RhythmicSchedule):
            raise AttendInputError(f"schedule: expected a RhythmicSchedule, got {type(schedule).__name__}")
        self.oscillator = schedule.oscillator

    def deadline(self, plan_start_s: float, first_image_s: float) -> float:
        """The first trough at or after max(``plan_start_s``, ``first_image_s``) [s]."""
        start = max(plan_start_s, first_image_s)
        troughs = self.oscillator.trough_times(start, start + 2 * self.oscillator.period)
        return float(troughs[0])


class PrecisionDrivenReplanning(Replanning):
    """Keep flying while the rest of the plan still pays: replan iff
    stay rate < rho * fresh rate * exp(-kappa * sin theta(t)) (module docstring).

    schedule: a :class:`PrecisionDrivenSchedule` (oscillator on the mission clock, kappa, rho).
    ``switch_cost_s`` c >= 0: flight time a replan costs (the planning latency, spent hovering):
    a fresh plan of duration D_k then pays f D_k / (D_k + c) per second of battery (c = 0: the
    rule above). ``decisions`` logs (time [s], stay rate, fresh rate, replanned) of every
    decision of the current mission."""

    name = "precision"

    def __init__(self, schedule: PrecisionDrivenSchedule, switch_cost_s: float = 0.0) -> None:
        if not isinstance(schedule, PrecisionDrivenSchedule):
            raise AttendInputError(f"schedule: expected a PrecisionDrivenSchedule, got {type(schedule).__name__}")
        self.schedule = schedule
        cost = _finite(switch_cost_s, "switch_cost_s")
        if cost < 0:
            raise AttendInputError(f"switch_cost_s: expected a time >= 0 s, got {switch_cost_s!r}")
        self.switch_cost_s = cost
        self.reset()

    def reset(self) -> None:
        """Forget the last plan and the decisions (a new mission)."""
        self.plan_rate = 0.0
        self.plan_trace = 1.0
        self.plan_duration = 0.0
        self.decisions: list[tuple[float, float, float, bool]] = []

    def start_plan(self, context: PlanContext) -> None:
        """Record the new plan's precision gain rate r_k and trace tr P_k (``context``: the
        plan, belief and clock)."""
        gain, duration = path_gain(context.planner, context.belief, context.pose, context.remaining,
                                   context.time_to_next_image_s, context.time_left_s)
        self.plan_rate = gain / duration if duration > 0 else 0.0
        self.plan_trace = max(context.belief.trace(), 1e-12)
        self.plan_duration = duration

    def fresh_rate(self, belief: OccupancyMap) -> float:
        """r_k tr P / tr P_k for the current ``belief``: the last plan's rate scaled by the
        uncertainty left (times D_k / (D_k + c) when a replan costs c seconds)."""
        rate = self.plan_rate * belief.trace() / self.plan_trace
        if self.switch_cost_s > 0:
            rate *= self.plan_duration / (self.plan_duration + self.switch_cost_s)
        return rate

    def after_image(self, context: PlanContext) -> bool:
        """The rule after an image (``context``: the rest of the plan, belief and clock):
        True to replan now."""
        if len(context.remaining) == 0:
            return True
        gain, duration = path_gain(context.planner, context.belief, context.pose, context.remaining,
                                   context.time_to_next_image_s, context.time_left_s)
        stay = gain / duration if duration > 0 else 0.0
        fresh = self.fresh_rate(context.belief)
        phase = float(self.schedule.oscillator.phase_angle(context.time_s))
        decision = switch_decision(stay, fresh, phase, self.schedule.prior_weight, self.schedule.tolerance)
        self.decisions.append((context.time_s, stay, fresh, decision))
        return decision


def replan_policy(schedule, switch_cost_s: float = 0.0) -> Replanning:
    """The replanning policy of ``schedule``: :class:`FixedReplanning`,
    :class:`RhythmicReplanning` or :class:`PrecisionDrivenReplanning` (``switch_cost_s``: the
    replan cost its rule accounts for; the other kinds ignore it)."""
    if isinstance(schedule, FixedSchedule):
        return FixedReplanning(schedule)
    if isinstance(schedule, RhythmicSchedule):
        return RhythmicReplanning(schedule)
    if isinstance(schedule, PrecisionDrivenSchedule):
        return PrecisionDrivenReplanning(schedule, switch_cost_s)
    raise AttendInputError(f"schedule: expected a Rhythmic, Fixed or PrecisionDriven schedule, got {schedule!r}")


def _fixed_seconds(policy: str) -> float:
    try:
        return float(policy[len("fixed_"):-1])
    except ValueError:
        return float("nan")


def make_replan_policy(policy: str, oscillator_frequency_hz: float = 0.05, oscillator_phase_rad: float = 0.0,
                       prior_weight: float = 0.5, tolerance: float = 1.0, switch_cost_s: float = 0.0) -> Replanning:
    """Replanning policy by name: "segment", "fixed_<T>s" (e.g. "fixed_20s"), "oscillator",
    "precision" (with the oscillator prior), "precision_no_prior" (kappa = 0) or "continuous"
    (fly each plan to its end). The oscillator has frequency ``oscillator_frequency_hz`` [Hz]
    and phase ``oscillator_phase_rad``; ``prior_weight`` kappa, ``tolerance`` rho and
    ``switch_cost_s`` (the replan cost) go to the precision-driven rules."""
    if not isinstance(policy, str):
        raise AttendInputError(f"policy: expected a policy name, got {policy!r}")
    oscillator = PrecisionOscillator(frequency=oscillator_frequency_hz, phase=oscillator_phase_rad)
    if policy == "segment":
        return SegmentReplanning()
    if policy == "continuous":
        return ContinuousReplanning()
    if policy.startswith("fixed_") and policy.endswith("s"):
        seconds = _fixed_seconds(policy)
        if math.isfinite(seconds) and seconds > 0:
            return replan_policy(FixedSchedule(seconds))
    if policy == "oscillator":
        return replan_policy(RhythmicSchedule(oscillator))
    if policy in ("precision", "precision_no_prior"):
        weight = prior_weight if policy == "precision" else 0.0
        replanning = replan_policy(PrecisionDrivenSchedule(oscillator, weight, tolerance), switch_cost_s)
        replanning.name = policy
        return replanning
    raise AttendInputError(
        f"policy: expected 'segment', 'continuous', 'fixed_<seconds>s', 'oscillator', 'precision' or "
        f"'precision_no_prior', got {policy!r}")


# ----------------------------------------------------------------------------------------------
# Episode


@dataclass
class ReplanningLog(EpisodeLog):
    """An :class:`attend.action.EpisodeLog` plus the policy's record: ``schedule`` (policy name),
    ``replan_times_s`` (mission time of every replan, the first at 0), ``decision_times_s`` (wall
    time of the policy's own computations per plan) and ``decisions`` (precision-driven
    policies: (time s, stay rate, fresh rate, replanned) per image).

    The other fields are those of EpisodeLog (planner, seed, budget_s, people_total, times_s,
    poses_m, metrics, planner_times_s, waypoints_m, means, variances, clutter_cells, hover_s)."""

    schedule: str = ""
    decisions: list[tuple[float, float, float, bool]] = dataclass_field(default_factory=list)

    @property
    def n_replans(self) -> int:
        """Number of plans made (the first included)."""
        return len(self.replan_times_s)


def fly_scheduled_mission(field, planner: Planner, policy: Replanning, budget_s: float = 150.0, seed: int = 0,
                          diagonal: bool = False, keep_maps: bool = False,
                          planning_latency_s: float = 0.0, latency_mode: str = "hover") -> ReplanningLog:
    """Fly one mission of ``budget_s`` s [flight time]: plan, fly the plan taking and fusing
    images, replan when ``policy`` (a :class:`Replanning`) says so (or the plan is used up), until the budget is spent.

    field: an :class:`attend.action.SearchField`; planner: any :class:`attend.action.Planner`
    (its ``setup`` gives the camera, detector and flight models); seed: detector noise and
    planner seed; diagonal: per-cell (diagonal) map covariance; keep_maps: log the map after
    each image. Planning wall time is not charged against the budget (it is logged); a fixed
    ``planning_latency_s`` per plan is (the UAV hovers meanwhile, or with ``latency_mode`` "fly"
    keeps flying the old plan, see :func:`attend.action.fly`); motion blur comes with the planner's detector.
    The policy is consulted after every image except one taken where a plan starts (before
    it has flown)."""
    if not isinstance(policy, Replanning):
        raise AttendInputError(f"policy: expected a Replanning policy, got {type(policy).__name__}")
    if not isinstance(planner, Planner):
        raise AttendInputError(f"planner: expected an attend.action Planner, got {type(planner).__name__}")
    budget_s = positive_scalar(budget_s, "budget_s", "s")
    log = ReplanningLog(planner.name, seed, float(budget_s), len(field.people), schedule=policy.name)
    fly(field, planner, log.budget_s, seed, policy, diagonal=diagonal, keep_maps=keep_maps,
        planning_latency_s=planning_latency_s, latency_mode=latency_mode, log=log)
    log.decisions = list(getattr(policy, "decisions", []))
    return log
