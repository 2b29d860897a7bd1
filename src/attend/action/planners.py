"""Path planners behind one interface: ``plan(belief, pose, remaining_budget_s) -> waypoints``.

Informative planners score a look-ahead path (w waypoints, images every 1/0.15 s along it) by a
value per flight time, value(path) / t(path):

* PrecisionGainPlanner   value = trace(P) - trace(P_post)  (expected precision gain).
* AdaptivePlanner        value = tr(W (P - P_post)) * mean_images N(h; h_opt, 7 m) / N(h_opt),
                         W = diag(clip(mean + k sigma, 0, 1)), k = 1 (optimistic occupancy).
* ExpectedFreeEnergyPlanner  value = -G = epistemic + pragmatic:
                         epistemic = I(x; z) = 0.5 log det(I + D^1/2 P D^1/2)  (nats),
                         pragmatic = c * sum_images sum_cells p(detect),
                         p(detect) = q tpr(h) + (1 - q) fpr(h),
                         q = clip((mean - 0.05) / 0.95, 0, 1)  (occupancy probability: a cell
                         never detected reads 0.05, so mean 0.05 means empty),
                         c = log preference for observing a person (nats per detected cell);
                         optionally minus k * sum (1 - p(detect)), a dis-preference for views of
                         empty ground (``empty_view_cost_nats``, default 0), which makes the planner
                         descend over likely people once the map is certain.
* SearchConfirmPlanner ("efe_confirm")  the EFE planner in two phases: search at 14 m until
                         the field is covered, then confirmation views at 8 m chosen by the
                         pragmatic value of confirmation, the expected number of cells pushed across
                         the found threshold 0.5 by the image (exact Kalman mean under the
                         hypothesis that the detected cells read 1), search resuming when no
                         unconfirmed detection is left.

Optimiser: greedy choice of each next waypoint from a lattice over 4 altitude layers (every
candidate evaluated in one numpy batch, the covariance conditioned on the chosen images between
steps), then CMA-ES (``cma``) refinement of the whole w-waypoint path (population evaluated as
a batch); the better of the two is returned.

Planning covariance: candidates are screened on a coarse-grained covariance P_b = B P B' over
blocks of ``planning_block_cells``^2 cells (B averages a block; observing c cells of a block with
noise r counts as precision c / r on the block mean; gains scaled back by the block area), and
every decision is taken on the exact full covariance: at each greedy step the
``exact_candidates`` best screened candidates are re-scored exactly (the exact covariance
conditioned on the chosen images as a low-rank update P - U U'), and at the end the greedy path
and the best CMA-ES paths are compared on exact scores (the greedy path's exact value is the sum
of its exact segment values). An exact score reads only the rows P[A, :] of the m observed cells:
tr(W (P - P_post)) = ||L^-1 P_A: W^1/2||_F^2 with L L' = P_AA + D_A^-1 (m^2 n), the information
0.5 log det(I + D^1/2 P_AA D^1/2) from L alone (m^3 / 3). ``exact_candidates=0`` decides on the
screening scores alone; ``planning_block_cells=1`` screens every candidate on the exact full
covariance (~25x slower).

Finding every person: CoverConfirmPlanner ("cover_confirm", attend.action.confirm) covers the
field twice at 13 m, then confirms the detections (it registers itself in PLANNERS).

Baselines: LawnmowerPlanner (serpentine coverage at 10 m, repeated until the budget is spent) and
RandomPlanner (uniform random waypoints).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg

from attend.action.belief import OccupancyMap, observation_gains
from attend.action.camera import DETECTED_VALUE, NOT_DETECTED_VALUE, Camera, Detector
from attend.action.errors import ActionInputError
from attend.action.field import SearchField
from attend.action.flight import FlightModel, detour, path_collides


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
    clearance kept from boxes (m).
    """

    field: SearchField
    camera: Camera = Camera()
    detector: Detector = Detector()
    flight: FlightModel = FlightModel()
    altitude_layers_m: tuple[float, ...] = (5.0, 8.0, 11.0, 14.0)
    lattice_per_side: int = 4
    lookahead_waypoints: int = 3
    cma_evaluations: int = 24
    planning_block_cells: int = 2
    exact_candidates: int = 4
    obstacle_margin_m: float = 1.0

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
    """``plan(belief, pose, remaining_budget_s, time_to_next_image_s) -> waypoints (w, 3) in m``."""

    name = "planner"
    #: waypoints flown before the next replan (None: all of them)
    waypoints_per_replan: int | None = None

    def __init__(self, setup: PlanningSetup, seed: int = 0) -> None:
        self.setup = setup
        self.reset(seed)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission (clears any internal state, reseeds)."""
        self.rng = np.random.default_rng(seed)

    @abstractmethod
    def plan(
        self, belief: OccupancyMap, pose: Sequence[float], remaining_budget_s: float, time_to_next_image_s: float = 0.0
    ) -> np.ndarray:
        """Next waypoints (w, 3) in m from ``pose`` (x, y, z) m."""


# ----------------------------------------------------------------------------------------------
# Planning model: (coarse-grained) covariance and batched scoring


class _PlanningModel:
    """Covariance used to score candidates during one replan (conditioned between greedy steps)."""

    def __init__(self, belief: OccupancyMap, setup: PlanningSetup, cell_weights: np.ndarray | None) -> None:
        self.diagonal = belief.diagonal
        self.block = 1 if belief.diagonal else setup.planning_block_cells
        grid = belief.grid
        side = grid.cells_per_side
        nb = side // self.block
        iy, ix = np.divmod(np.arange(grid.n_cells), side)
        self.block_of_cell = (iy // self.block) * nb + ix // self.block
        self.n_blocks = nb * nb
        self.area = self.block**2
        weights = np.ones(grid.n_cells) if cell_weights is None else cell_weights
        if self.diagonal:
            self.covariance = belief.covariance.copy()
            self.weights = weights
        elif self.block == 1:
            self.covariance = belief.covariance.copy()
            self.weights = weights
        else:
            b = self.block
            n = grid.n_cells
            rows = belief.covariance.reshape(n, nb, b, nb, b).sum(axis=(2, 4)).reshape(n, self.n_blocks)
            blocks = rows.T.reshape(self.n_blocks, nb, b, nb, b).sum(axis=(2, 4)).reshape(self.n_blocks, self.n_blocks)
            self.covariance = blocks / self.area**2  # B P B', B averaging each block
            self.weights = weights.reshape(nb, b, nb, b).mean(axis=(1, 3)).ravel()
        self._refresh()

    def copy(self) -> "_PlanningModel":
        twin = object.__new__(_PlanningModel)
        twin.__dict__.update(self.__dict__)
        twin.covariance = self.covariance.copy()
        return twin

    def _refresh(self) -> None:
        self.weighted_square = None if self.diagonal else (self.covariance * self.weights[None, :]) @ self.covariance

    def precision(self, visible: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
        """Per-(block) measurement precision (k, n_b) from visibility masks (k, J, n) and noise (k, J)."""
        per_cell = np.einsum("kjn,kj->kn", visible, 1.0 / noise_variance)
        if self.block == 1:
            return per_cell
        out = np.zeros((len(per_cell), self.n_blocks))
        np.add.at(out.T, self.block_of_cell, per_cell.T)
        return out

    def gains(
        self, precision: np.ndarray, want_information: bool = False, want_reduction: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        reduction, information = observation_gains(
            self.covariance,
            precision,
            weighted_square=self.weighted_square,
            diagonal=self.diagonal,
            cell_weights=self.weights,
            want_information=want_information,
        )
        return reduction * self.area, information

    def condition(self, precision: np.ndarray) -> None:
        """Covariance-only update with per-(block) precision d (n_b,): P <- (P^-1 + D)^-1."""
        if self.diagonal:
            self.covariance = 1.0 / (1.0 / self.covariance + precision)
            return
        observed = np.flatnonzero(precision > 0)
        if len(observed) == 0:
            return
        cross = self.covariance[:, observed]
        innovation = cross[observed] + np.diag(1.0 / precision[observed])
        self.covariance = self.covariance - cross @ np.linalg.solve(innovation, cross.T)
        self.covariance = 0.5 * (self.covariance + self.covariance.T)
        self._refresh()


class _ExactModel:
    """Exact full covariance for re-scoring a few candidates, conditioned between greedy steps.

    Kept as P_g = P - U U' (P the belief's covariance, untouched; U n x q grows by the m cells of
    each chosen image set), so a candidate reads only the rows P_g[A, :] = P[A, :] - U_A U' of the
    m cells A it observes (summed precision d_A). With S = (P_g)_AA + D_A^-1 = L L':

        tr(W (P_g - P_post)) = tr(S^-1 (P_g)_A: W (P_g)_:A) = || L^-1 (P_g)_A: W^1/2 ||_F^2
        0.5 log det(I + D^1/2 (P_g)_AA D^1/2) = sum log diag L + 0.5 sum log d_A

    costs m q n + m^2 n + m^3 / 3 per candidate (information only: m^2 q + m^3 / 3), no n x n
    products.
    """

    def __init__(self, belief: OccupancyMap, cell_weights: np.ndarray | None) -> None:
        self.covariance = belief.covariance
        self.low_rank = np.zeros((len(belief.covariance), 0))
        self.root_weights = None if cell_weights is None else np.sqrt(np.maximum(cell_weights, 0.0))
        self.block, self.area = 1, 1

    def copy(self) -> "_ExactModel":
        twin = object.__new__(_ExactModel)
        twin.__dict__.update(self.__dict__)
        return twin

    def precision(self, visible: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
        return np.einsum("kjn,kj->kn", visible, 1.0 / noise_variance)

    def _rows(self, observed: np.ndarray, columns: np.ndarray | None = None) -> np.ndarray:
        """(P_g)[observed, columns] (all columns when None)."""
        if columns is None:
            rows = self.covariance[observed]
            return rows - self.low_rank[observed] @ self.low_rank.T if self.low_rank.shape[1] else rows
        rows = self.covariance[np.ix_(observed, columns)]
        return rows - self.low_rank[observed] @ self.low_rank[columns].T if self.low_rank.shape[1] else rows

    def _factor(self, d: np.ndarray, full_rows: bool):
        observed = np.flatnonzero(d > 0)
        rows = self._rows(observed) if full_rows else None
        s_matrix = rows[:, observed] if full_rows else self._rows(observed, observed)
        s_matrix = s_matrix + np.diag(1.0 / d[observed])
        return observed, rows, scipy.linalg.cholesky(s_matrix, lower=True, check_finite=False)

    def gains(
        self, precision: np.ndarray, want_information: bool = False, want_reduction: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        precision = np.atleast_2d(precision)
        reduction = np.zeros(len(precision))
        information = np.zeros(len(precision)) if want_information else None
        for k, d in enumerate(precision):
            if not np.any(d > 0):
                continue
            observed, rows, lower = self._factor(d, full_rows=want_reduction)
            if want_reduction:
                if self.root_weights is not None:
                    rows = rows * self.root_weights[None, :]
                solved = scipy.linalg.solve_triangular(lower, rows, lower=True, check_finite=False)
                reduction[k] = np.einsum("ij,ij->", solved, solved)
            if want_information:
                information[k] = np.log(np.diagonal(lower)).sum() + 0.5 * np.log(d[observed]).sum()
        return reduction, information

    def condition(self, precision: np.ndarray) -> None:
        """P_g <- P_g - (P_g)_:A S^-1 (P_g)_A:  (appends L^-1 (P_g)_A: to U)."""
        if not np.any(precision > 0):
            return
        _, rows, lower = self._factor(precision, full_rows=True)
        half = scipy.linalg.solve_triangular(lower, rows, lower=True, check_finite=False)
        self.low_rank = np.hstack([self.low_rank, half.T])

    @property
    def dense(self) -> np.ndarray:
        """P_g as a dense matrix (for tests)."""
        return self.covariance - self.low_rank @ self.low_rank.T


class InformativePlanner(Planner):
    """Greedy lattice search plus CMA-ES refinement of a value-per-flight-time objective."""

    name = "informative"
    waypoints_per_replan = 1
    #: the path value is a sum over its segments, each scored given the earlier ones
    additive_value = True

    def cell_weights(self, belief: OccupancyMap) -> np.ndarray | None:
        return None

    def path_value(
        self,
        model: _PlanningModel,
        belief: OccupancyMap,
        visible: np.ndarray,
        altitudes: np.ndarray,
        valid: np.ndarray,
    ) -> np.ndarray:
        """Value (k,) of image sets: visible (k, J, n) masks, altitudes (k, J) m, valid (k, J)."""
        noise = np.where(valid, self.setup.detector.noise_variance(altitudes), np.inf)
        reduction, _ = model.gains(model.precision(visible, noise))
        return reduction

    # -- helpers ---------------------------------------------------------------------------------
    def _visibility(self, poses: np.ndarray, valid: np.ndarray) -> np.ndarray:
        k, j, _ = poses.shape
        flat = poses.reshape(-1, 3)
        mask = np.zeros((k * j, self.setup.field.grid.n_cells), dtype=bool)
        rows = valid.ravel()
        if rows.any():
            mask[rows] = self.setup.camera.visible_cells(flat[rows], self.setup.field.grid, self.setup.field.obstacles)
        return mask.reshape(k, j, -1)

    def _score_paths(
        self, model: _PlanningModel, belief: OccupancyMap, pose: np.ndarray, paths: np.ndarray, t_next: float, budget: float
    ) -> np.ndarray:
        poses, valid, total_time, _ = self.setup.flight.path_images(pose, paths, t_next, budget)
        value = self.path_value(model, belief, self._visibility(poses, valid), poses[..., 2], valid)
        score = value / np.maximum(total_time, 1e-6)
        collides = path_collides(np.concatenate([np.broadcast_to(pose, (len(paths), 1, 3)), paths], axis=1),
                                 self.setup.field.obstacles, self.setup.obstacle_margin_m)
        return np.where(collides, -np.inf, score)

    def plan(
        self, belief: OccupancyMap, pose: Sequence[float], remaining_budget_s: float, time_to_next_image_s: float = 0.0
    ) -> np.ndarray:
        setup = self.setup
        pose = np.asarray(pose, float)
        weights = self.cell_weights(belief)
        base_model = _PlanningModel(belief, setup, weights)
        model = base_model.copy()
        rescore = setup.exact_candidates > 0 and base_model.block > 1
        base_exact = _ExactModel(belief, weights) if rescore else None
        exact = base_exact.copy() if rescore else None
        lattice = setup.lattice()
        flight = setup.flight
        # Greedy: choose each waypoint by the value rate of its segment, conditioning in between.
        current, t_next, left = pose, float(time_to_next_image_s), float(remaining_budget_s)
        chosen: list[np.ndarray] = []
        greedy_exact_value, greedy_time = 0.0, 0.0
        for _ in range(setup.lookahead_waypoints):
            if left <= 0:
                break
            distance = np.linalg.norm(lattice - current, axis=1)
            candidates = lattice[distance > 0.5]
            collides = path_collides(np.stack([np.broadcast_to(current, candidates.shape), candidates], axis=1),
                                     setup.field.obstacles, setup.obstacle_margin_m)
            candidates = candidates[~collides]
            if len(candidates) == 0:
                break
            poses, _, valid, duration, next_after = flight.segment_images(current, candidates, t_next, left)
            visible = self._visibility(poses, valid)
            value = self.path_value(model, belief, visible, poses[..., 2], valid)
            rate = value / np.maximum(duration, 1e-6)
            best = int(np.argmax(rate))
            if rescore:
                # screened on the coarse covariance; the best few re-scored on the exact one
                top = np.argsort(-rate, kind="stable")[: setup.exact_candidates]
                exact_value = self.path_value(exact, belief, visible[top], poses[top, :, 2], valid[top])
                pick = int(np.argmax(exact_value / np.maximum(duration[top], 1e-6)))
                best = int(top[pick])
                greedy_exact_value += float(exact_value[pick])
            greedy_time += float(duration[best])
            chosen.append(candidates[best])
            noise = np.where(valid[best], setup.detector.noise_variance(poses[best, :, 2]), np.inf)
            model.condition(model.precision(visible[best][None], noise[None])[0])
            if rescore and len(chosen) < setup.lookahead_waypoints:
                exact.condition(exact.precision(visible[best][None], noise[None])[0])
            current, t_next, left = candidates[best], float(next_after[best]), left - float(duration[best])
        if not chosen:
            return np.zeros((0, 3))
        greedy = np.array(chosen)
        if setup.cma_evaluations <= 0 or len(greedy) == 0:
            return greedy
        # the exact value of the greedy path is the sum of its exact segment values when the value is
        # additive over images given the earlier ones (trace reduction, information, pragmatic value)
        greedy_exact = greedy_exact_value / max(greedy_time, 1e-6) if rescore and self.additive_value else None
        return self._refine(belief, pose, greedy, float(time_to_next_image_s), float(remaining_budget_s), base_model,
                            base_exact, greedy_exact)

    def _refine(
        self, belief: OccupancyMap, pose: np.ndarray, greedy: np.ndarray, t_next: float, budget: float, model,
        exact=None, greedy_exact: float | None = None,
    ) -> np.ndarray:
        import cma

        setup = self.setup
        half = setup.field.grid.size_m / 2 - 0.5
        low = np.array([-half, -half, min(setup.altitude_layers_m)])
        high = np.array([half, half, max(setup.altitude_layers_m)])
        w = len(greedy)
        span = high - low  # 0 for the altitude when there is one layer (the altitude stays fixed)

        def to_paths(unit: np.ndarray) -> np.ndarray:
            return low + np.clip(unit, 0, 1).reshape(-1, w, 3) * span

        start_unit = ((greedy - low) / np.where(span > 0, span, 1.0)).ravel().clip(0, 1)
        greedy_score = float(self._score_paths(model, belief, pose, greedy[None], t_next, budget)[0])
        best_path, best_score = greedy, greedy_score
        popsize = 6
        options = {
            "bounds": [0.0, 1.0],
            "popsize": popsize,
            "maxfevals": setup.cma_evaluations,
            "seed": int(self.rng.integers(1, 2**31 - 1)),
            "verbose": -9,
            "tolfun": 1e-12,
        }
        strategy = cma.CMAEvolutionStrategy(start_unit, 0.15, options)
        evaluated: list[tuple[float, np.ndarray]] = []
        while not strategy.stop():
            population = strategy.ask()
            paths = to_paths(np.array(population))
            scores = self._score_paths(model, belief, pose, paths, t_next, budget)
            scale = abs(greedy_score) + 1e-9
            strategy.tell(population, [float(-s / scale) if np.isfinite(s) else 1e6 for s in scores])
            top = int(np.argmax(scores))
            if scores[top] > best_score:
                best_path, best_score = paths[top], float(scores[top])
            evaluated.extend((float(sc), path) for sc, path in zip(scores, paths) if np.isfinite(sc))
        if exact is None:
            return np.asarray(best_path)
        # Final choice on the exact full covariance: the greedy path and the best CMA-ES paths.
        evaluated.sort(key=lambda item: -item[0])
        finalists = [path for score, path in evaluated[: max(1, setup.exact_candidates // 2)] if score > greedy_score]
        if not finalists:
            return np.asarray(greedy)
        if greedy_exact is None:
            finalists.insert(0, greedy)
        exact_scores = self._score_paths(exact, belief, pose, np.array(finalists), t_next, budget)
        if greedy_exact is not None:
            finalists.insert(0, greedy)
            exact_scores = np.concatenate([[greedy_exact], exact_scores])
        return np.asarray(finalists[int(np.argmax(exact_scores))])


class PrecisionGainPlanner(InformativePlanner):
    """Maximise the expected reduction of trace(P) per flight time."""

    name = "precision_gain"


class AdaptivePlanner(InformativePlanner):
    """Precision gain weighted by optimistic occupancy mean + k sigma and an altitude preference
    N(h; preferred_altitude_m, altitude_spread_m)."""

    name = "adaptive"
    additive_value = False  # gain times the mean altitude preference of the path's images

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, optimism: float = 1.0, preferred_altitude_m: float = 10.0,
        altitude_spread_m: float = 7.0,
    ) -> None:
        self.optimism = optimism
        self.preferred_altitude_m = preferred_altitude_m
        self.altitude_spread_m = altitude_spread_m
        super().__init__(setup, seed)

    def cell_weights(self, belief: OccupancyMap) -> np.ndarray:
        return np.clip(belief.mean + self.optimism * np.sqrt(belief.variance), 0.0, 1.0)

    def path_value(self, model, belief, visible, altitudes, valid) -> np.ndarray:
        reduction = super().path_value(model, belief, visible, altitudes, valid)
        preference = np.exp(-0.5 * ((altitudes - self.preferred_altitude_m) / self.altitude_spread_m) ** 2)
        mean_preference = (preference * valid).sum(axis=1) / np.maximum(valid.sum(axis=1), 1)
        return reduction * mean_preference


class ExpectedFreeEnergyPlanner(InformativePlanner):
    """Minimise expected free energy G = -(epistemic + pragmatic) per flight time; the pragmatic
    term is ``preference_nats`` per expected detected cell (prior preference for seeing people).

    Optional search-then-confirm (``confirm_altitude_m``, default None: off; on in
    ``SearchConfirmPlanner``, "efe_confirm"). Search: the EFE path above, at ``search_altitude_m``
    only when given. Once the field is covered (share ``confirm_after_coverage`` of cells whose
    variance fell below half the prior's), the planner confirms: candidates are connected groups
    (8-neighbourhood, >= 2 cells) of cells with mean > ``confirm_candidate_mean`` that still hold
    an ambiguous cell (mean in (``confirm_ambiguous_mean``, 0.5]); candidate views are their
    centroids (mean-weighted) and the midpoints of pairs closer than 8 m, at ``confirm_altitude_m``.
    The view taken maximises the pragmatic value of confirmation, the expected number of cells
    pushed across the found threshold 0.5:
        tpr(h) * sum_i q_i [mean_i <= 0.5] [mean'_i > 0.5],
    mean' the exact Kalman mean after the image under the hypothesis that the candidate cells
    (mean > confirm_candidate_mean) read 1 and the rest 0.05, q the occupancy probability
    (ties: the nearer view). One image per replan; at most ``confirm_visits`` views per candidate
    centroid (within 1.5 m); with no candidate left, the EFE search resumes. Belief only, no
    ground truth.

    preference_nats = 0.2: on seeds 100-124 (disjoint from the evaluation seeds 0-24) final RSE /
    trace(P) 3.84 / 81.6 (0.1), 3.80 / 84.9 (0.2), 3.90 / 100.0 (0.5) against the lawnmower's 4.02 /
    92.8: 0.2 has the lowest RSE of the three with trace(P) below the lawnmower's (an earlier
    choice, 0.5 on seeds 100-107, bought map error with precision and lost to the lawnmower on
    trace(P)). The two-phase SearchConfirmPlanner keeps 0.5 for its search (see there)."""

    name = "efe"

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, preference_nats: float = 0.2, empty_view_cost_nats: float = 0.0,
        confirm_altitude_m: float | None = None, confirm_after_coverage: float = 0.9, confirm_visits: int = 3,
        search_altitude_m: float | None = None, confirm_candidate_mean: float = 0.25, confirm_ambiguous_mean: float = 0.4,
    ) -> None:
        self.preference_nats = preference_nats
        self.empty_view_cost_nats = empty_view_cost_nats
        low, high = setup.field.altitude_limits_m
        for name, value in (("confirm_altitude_m", confirm_altitude_m), ("search_altitude_m", search_altitude_m)):
            if value is not None and not (isinstance(value, (int, float)) and low <= value <= high):
                raise ActionInputError(f"{name}: expected an altitude in [{low:g}, {high:g}] m or None, got {value!r}")
        if not 0.0 <= confirm_after_coverage <= 1.0:
            raise ActionInputError(f"confirm_after_coverage: expected a share in [0, 1], got {confirm_after_coverage!r}")
        if int(confirm_visits) != confirm_visits or confirm_visits < 1:
            raise ActionInputError(f"confirm_visits: expected an integer >= 1, got {confirm_visits!r}")
        if not 0.0 < confirm_candidate_mean < 0.5:
            raise ActionInputError(f"confirm_candidate_mean: expected a map mean in (0, 0.5), got {confirm_candidate_mean!r}")
        if not confirm_candidate_mean <= confirm_ambiguous_mean < 0.5:
            raise ActionInputError(
                f"confirm_ambiguous_mean: expected a map mean in [confirm_candidate_mean, 0.5), got {confirm_ambiguous_mean!r}"
            )
        self.confirm_altitude_m = confirm_altitude_m
        self.confirm_after_coverage = confirm_after_coverage
        self.confirm_visits = confirm_visits
        self.search_altitude_m = search_altitude_m
        self.confirm_candidate_mean = confirm_candidate_mean
        self.confirm_ambiguous_mean = confirm_ambiguous_mean
        super().__init__(setup, seed)
        if search_altitude_m is not None:
            import dataclasses

            self.setup = dataclasses.replace(setup, altitude_layers_m=(float(search_altitude_m),))

    def reset(self, seed: int = 0) -> None:
        super().reset(seed)
        self._visits: list[np.ndarray] = []

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
        target = self._confirmation_target(belief, np.asarray(pose, float)) if self.confirm_altitude_m else None
        if target is not None:
            self._visits.append(target[:2].copy())
            return target[None]
        return super().plan(belief, pose, remaining_budget_s, time_to_next_image_s)

    def _field_covered(self, belief: OccupancyMap) -> bool:
        from attend.action.belief import _prior_covariance_cached, prior_covariance

        defaults = prior_covariance.__defaults__[1:]
        prior_var = np.diag(_prior_covariance_cached(belief.grid.cells_per_side, *defaults))
        return bool(np.mean(belief.variance < 0.5 * prior_var) >= self.confirm_after_coverage)

    def confirmation_candidates(self, belief: OccupancyMap) -> list[np.ndarray]:
        """Centroids (x, y) m of the unconfirmed detections not yet visited confirm_visits times."""
        import scipy.ndimage

        grid = belief.grid
        labels, n = scipy.ndimage.label((belief.mean > self.confirm_candidate_mean).reshape(grid.shape),
                                        structure=np.ones((3, 3)))
        labels = labels.ravel()
        centres = grid.cell_centres()
        out = []
        for g in range(1, n + 1):
            cells = np.flatnonzero(labels == g)
            means = belief.mean[cells]
            if len(cells) < 2 or not np.any((means > self.confirm_ambiguous_mean) & (means <= FOUND_MEAN)):
                continue
            centre = (centres[cells] * means[:, None]).sum(axis=0) / means.sum()
            if sum(np.hypot(*(centre - v)) < 1.5 for v in self._visits) >= self.confirm_visits:
                continue
            out.append(centre)
        return out

    def confirmation_value(self, belief: OccupancyMap, view: np.ndarray) -> float:
        """Expected number of cells pushed across 0.5 by one image at ``view`` (x, y, z) m (see the class)."""
        setup = self.setup
        altitude = float(view[2])
        cells = np.flatnonzero(setup.camera.visible_cells(np.asarray(view)[None], belief.grid, setup.field.obstacles)[0])
        if len(cells) == 0:
            return 0.0
        z = np.where(belief.mean[cells] > self.confirm_candidate_mean, DETECTED_VALUE, NOT_DETECTED_VALUE)
        after = kalman_mean(belief, cells, z, float(setup.detector.noise_variance(altitude)))
        crossing = (belief.mean <= FOUND_MEAN) & (after > FOUND_MEAN)
        return float(setup.detector.true_positive_rate(altitude)) * float(np.sum(occupancy_probability(belief.mean)[crossing]))

    def _confirmation_target(self, belief: OccupancyMap, pose: np.ndarray) -> np.ndarray | None:
        """The confirmation view (x, y, confirm_altitude_m), or None (search)."""
        if not self._field_covered(belief):
            return None
        centres = self.confirmation_candidates(belief)
        if not centres:
            return None
        views = list(centres) + [(a + b) / 2 for i, a in enumerate(centres) for b in centres[i + 1:]
                                 if np.hypot(*(a - b)) < 8.0]
        best, best_key = None, None
        for centre in views:
            view = np.array([centre[0], centre[1], float(self.confirm_altitude_m)])
            key = (self.confirmation_value(belief, view), -float(np.hypot(*(centre - pose[:2]))))
            if best_key is None or key > best_key:
                best, best_key = view, key
        return best

    def path_value(self, model, belief, visible, altitudes, valid) -> np.ndarray:
        detector = self.setup.detector
        noise = np.where(valid, detector.noise_variance(altitudes), np.inf)
        _, information = model.gains(model.precision(visible, noise), want_information=True, want_reduction=False)
        occupancy = occupancy_probability(belief.mean)
        tpr = detector.true_positive_rate(altitudes)[..., None]
        fpr = detector.false_positive_rate(altitudes)[..., None]
        p_detect = occupancy[None, None, :] * tpr + (1 - occupancy[None, None, :]) * fpr
        pragmatic = ((self.preference_nats * p_detect - self.empty_view_cost_nats * (1 - p_detect)) * visible).sum(axis=(1, 2))
        return information + pragmatic


class SearchConfirmPlanner(ExpectedFreeEnergyPlanner):
    """Expected free energy in two phases ("efe_confirm"): epistemic-led search at one altitude
    (``search_altitude_m`` 14 m: footprint 11.6 m x 16.2 m, true-positive rate 0.89), then, once
    the field is covered, confirmation at ``confirm_altitude_m`` 8 m (true-positive rate 0.93,
    near the best 0.95 at 10 m, with less noise: 0.33 against 0.39) of the views with the largest expected number of
    cells pushed across the found threshold (see ExpectedFreeEnergyPlanner), search resuming when
    nothing is left to confirm. Decisions use the belief only.

    Tuned on seeds 100-124, disjoint from the evaluation seeds 0-24 (all 7 found within 150 s,
    strict criterion). On seeds 100-111: confirming the nearest detection with any cell <= 0.5
    (the older option) 25-33 %; candidates need a cell in (0.4, 0.5]: 67 %; search at 14 m only and
    confirming after coverage 0.9: 58 %; views chosen by expected threshold crossings: 75-83 %
    (8 and 10 m views 58 %; coverage 0.8 / 0.95: 67 / 58 %; confirming interleaved with the search
    42 %; search preference_nats 0.1 / 0: 25 / 42 %, looking again at likely people from 14 m
    already pushes many of them across the threshold). On seeds 100-124: 64 % (5 x 5 search
    lattice 44 %; confirming also once <= 90 / 70 s are left: 68 / 64 %; search at 12 / 11 m: 52 / 56 %)."""

    name = "efe_confirm"

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, preference_nats: float = 0.5, empty_view_cost_nats: float = 0.0,
        confirm_altitude_m: float | None = 8.0, confirm_after_coverage: float = 0.9, confirm_visits: int = 3,
        search_altitude_m: float | None = 14.0, confirm_candidate_mean: float = 0.25, confirm_ambiguous_mean: float = 0.4,
    ) -> None:
        super().__init__(setup, seed, preference_nats, empty_view_cost_nats, confirm_altitude_m, confirm_after_coverage,
                         confirm_visits, search_altitude_m, confirm_candidate_mean, confirm_ambiguous_mean)


FOUND_MEAN = 0.5  # a person counts as found when all its cells' map mean exceed this (metrics.FOUND_THRESHOLD)


def kalman_mean(belief: OccupancyMap, cells: np.ndarray, measurements: np.ndarray, noise_variance: float) -> np.ndarray:
    """Map mean after a hypothetical image (exact full-covariance Kalman mean; the covariance is
    not updated, m^2 n + m^3 / 3 for m observed cells)."""
    if belief.diagonal:
        v = belief.covariance[cells]
        out = belief.mean.copy()
        out[cells] += v / (v + noise_variance) * (measurements - belief.mean[cells])
        return out
    cross = belief.covariance[:, cells]
    factor = scipy.linalg.cho_factor(cross[cells] + noise_variance * np.eye(len(cells)), lower=True, check_finite=False)
    return belief.mean + cross @ scipy.linalg.cho_solve(factor, measurements - belief.mean[cells], check_finite=False)


def occupancy_probability(mean: np.ndarray) -> np.ndarray:
    """Map mean to occupancy probability q = clip((mean - z0) / (1 - z0), 0, 1), z0 = 0.05 the
    reading of a cell without detection."""
    return np.clip((mean - NOT_DETECTED_VALUE) / (DETECTED_VALUE - NOT_DETECTED_VALUE), 0.0, 1.0)


def coverage_stops(setup: PlanningSetup, altitude_m: float) -> np.ndarray:
    """The fewest image stops (m, 3) whose footprints at ``altitude_m`` tile the field, serpentine:
    columns spaced <= footprint width in x, rows <= footprint height in y; stops inside
    obstacles dropped."""
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
    pattern repeated back and forth until the budget is spent."""

    name = "lawnmower"

    def __init__(self, setup: PlanningSetup, seed: int = 0, altitude_m: float = 10.0, waypoints_per_plan: int = 3) -> None:
        self.altitude_m = altitude_m
        self.waypoints_per_plan = waypoints_per_plan
        super().__init__(setup, seed)

    def reset(self, seed: int = 0) -> None:
        super().reset(seed)
        self._pattern = self.pattern()
        self._next = 0

    def pattern(self) -> np.ndarray:
        """Stops (m, 3) of :func:`coverage_stops` at the lawnmower altitude."""
        return coverage_stops(self.setup, self.altitude_m)

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
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
    """Uniform random waypoints in the field and between the lowest and highest altitude layer."""

    name = "random"

    def __init__(self, setup: PlanningSetup, seed: int = 0, waypoints_per_plan: int = 3) -> None:
        self.waypoints_per_plan = waypoints_per_plan
        super().__init__(setup, seed)

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
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


PLANNERS = {
    "precision_gain": PrecisionGainPlanner,
    "adaptive": AdaptivePlanner,
    "efe": ExpectedFreeEnergyPlanner,
    "efe_confirm": SearchConfirmPlanner,
    "lawnmower": LawnmowerPlanner,
    "random": RandomPlanner,
}
# attend.action.confirm adds "cover_confirm" (it builds on this module; the package imports it).


def make_planner(name: str, setup: PlanningSetup, seed: int = 0, **options) -> Planner:
    """Planner by name: one of ``PLANNERS`` ("precision_gain", "adaptive", "efe", "efe_confirm", "cover_confirm",
    "lawnmower", "random"); ``options`` go to the planner's constructor."""
    try:
        cls = PLANNERS[name]
    except KeyError:
        raise ActionInputError(f"planner: expected one of {sorted(PLANNERS)}, got {name!r}") from None
    return cls(setup, seed, **options)
