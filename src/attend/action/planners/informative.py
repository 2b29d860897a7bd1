"""Informative planners: score a look-ahead path (w waypoints, images every 1/0.15 s along it)
by a value per flight time, value(path) / t(path).

* :class:`PrecisionGainPlanner`  value = trace(P) - trace(P_post)  (expected precision gain).
* :class:`AdaptivePlanner`       value = tr(W (P - P_post)) * mean_images N(h; h_opt, 7 m) / N(h_opt),
  W = diag(clip(mean + k sigma, 0, 1)), k = 1 (optimistic occupancy).
* expected free energy: :mod:`attend.action.planners.free_energy`.

Optimiser: greedy choice of each next waypoint from a lattice over 4 altitude layers (every
candidate evaluated in one numpy batch, the covariance conditioned on the chosen images between
steps), then CMA-ES (``cma``) refinement of the whole w-waypoint path (population evaluated as
a batch); the better of the two is returned.

Planning covariance: candidates are screened on a coarse-grained covariance P_b = B P B' over
blocks of ``planning_block_cells``^2 cells (:class:`ScreeningModel`), and every decision is
taken on the exact full covariance (:class:`ExactModel`): at each greedy step the
``exact_candidates`` best screened candidates are re-scored exactly (the exact covariance
conditioned on the chosen images as a low-rank update P - U U'), and at the end the greedy path
and the best CMA-ES paths are compared on exact scores (the greedy path's exact value is the sum
of its exact segment values). An exact score reads only the rows P[A, :] of the m observed cells:
tr(W (P - P_post)) = ||L^-1 P_A: W^1/2||_F^2 with L L' = P_AA + D_A^-1 (m^2 n), the information
0.5 log det(I + D^1/2 P_AA D^1/2) from L alone (m^3 / 3). ``exact_candidates=0`` decides on the
screening scores alone; ``planning_block_cells=1`` screens every candidate on the exact full
covariance (~25x slower).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from attend.action.belief import OccupancyMap
from attend.action.flight import path_collides
from attend.action.planners.base import BEST_DETECTION_ALTITUDE_M, Planner, PlanningSetup
from attend.action.planners.scoring import ExactModel, ScreeningModel

class InformativePlanner(Planner):
    """Greedy lattice search plus CMA-ES refinement of a value-per-flight-time objective
    value(path) / t(path) (module docstring); subclasses define ``path_value`` and
    ``cell_weights``.

    setup: the planning setup; seed: seeds CMA-ES."""

    name = "informative"
    waypoints_per_replan = 1
    #: the path value is a sum over its segments, each scored given the earlier ones
    additive_value = True

    def cell_weights(self, belief: OccupancyMap) -> np.ndarray | None:
        """Weights W (n,) of the trace reduction tr(W (P - P_post)), None for W = I; belief: the current map."""
        return None

    def path_value(
        self,
        model: ScreeningModel,
        belief: OccupancyMap,
        visible: np.ndarray,
        altitudes: np.ndarray,
        valid: np.ndarray,
    ) -> np.ndarray:
        """Value (k,) of k image sets, here the trace reduction tr(W (P - P_post)).

        model: the covariance scored on; belief: the current map; visible: (k, J, n) visibility
        masks of the J images of each set; altitudes: (k, J) image altitudes [m]; valid: (k, J)
        which images are taken."""
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
        self, model: ScreeningModel, belief: OccupancyMap, pose: np.ndarray, paths: np.ndarray, t_next: float, budget: float
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
        """Greedy path over the lattice, refined by CMA-ES (module docstring).

        belief: the current map; pose: (x, y, z) [m]; remaining_budget_s: flight time left [s];
        time_to_next_image_s: time until the camera's next image [s]."""
        setup = self.setup
        pose = np.asarray(pose, float)
        weights = self.cell_weights(belief)
        base_model = ScreeningModel(belief, setup, weights)
        model = base_model.copy()
        rescore = setup.exact_candidates > 0 and base_model.block > 1
        base_exact = ExactModel(belief, weights) if rescore else None
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
    """Maximise the expected reduction of trace(P) per flight time, value = trace(P) - trace(P_post).

    setup: the planning setup; seed: seeds CMA-ES."""

    name = "precision_gain"


class AdaptivePlanner(InformativePlanner):
    """Precision gain weighted by the optimistic occupancy and an altitude preference:
    value = tr(W (P - P_post)) * mean_images N(h; h_opt, s) / N(h_opt; h_opt, s),
    W = diag(clip(mean + k sigma, 0, 1)).

    setup: the planning setup; seed: seeds CMA-ES; optimism: k; preferred_altitude_m: h_opt [m];
    altitude_spread_m: s [m]."""

    name = "adaptive"
    additive_value = False  # gain times the mean altitude preference of the path's images

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, optimism: float = 1.0, preferred_altitude_m: float = BEST_DETECTION_ALTITUDE_M,
        altitude_spread_m: float = 7.0,
    ) -> None:
        self.optimism = optimism
        self.preferred_altitude_m = preferred_altitude_m
        self.altitude_spread_m = altitude_spread_m
        super().__init__(setup, seed)

    def cell_weights(self, belief: OccupancyMap) -> np.ndarray:
        """W = clip(mean + k sigma, 0, 1) (n,); belief: the current map."""
        return np.clip(belief.mean + self.optimism * np.sqrt(belief.variance), 0.0, 1.0)

    def path_value(self, model, belief, visible, altitudes, valid) -> np.ndarray:
        """Weighted trace reduction times the mean altitude preference of the images (k,).

        model, belief, visible, altitudes, valid: as in :meth:`InformativePlanner.path_value`."""
        reduction = super().path_value(model, belief, visible, altitudes, valid)
        preference = np.exp(-0.5 * ((altitudes - self.preferred_altitude_m) / self.altitude_spread_m) ** 2)
        mean_preference = (preference * valid).sum(axis=1) / np.maximum(valid.sum(axis=1), 1)
        return reduction * mean_preference
