"""Expected free energy planners (paper Sec. 4.3.2): epistemic value plus a prior preference for
seeing people, so search gives way to confirming targets once the map is certain.

:class:`ExpectedFreeEnergyPlanner` ("efe") scores a path by -G = epistemic + pragmatic per
flight time:

    epistemic = I(x; z) = 0.5 log det(I + D^1/2 P D^1/2)  (nats),
    pragmatic = sum_images sum_cells [c p(detect) - k (1 - p(detect))],
    p(detect) = q tpr(h) + (1 - q) fpr(h),   q = clip((mean - 0.05) / 0.95, 0, 1),

q the occupancy probability (a cell never detected reads 0.05, so mean 0.05 means empty), c
(``preference_nats``) the log preference for observing a person per detected cell, k
(``empty_view_cost_nats``, default 0) a dis-preference for views of empty ground.

:class:`SearchConfirmPlanner` ("efe_confirm") runs it in two phases: search at 14 m until the
field is covered, then confirmation views at 8 m chosen by the pragmatic value of confirmation,
the expected number of cells pushed across the found threshold by the image:

    value(view) = tpr(h) sum_i q_i [mean_i <= 0.5] [mean'_i > 0.5],

mean' the exact Kalman mean after the image under the hypothesis that the candidate cells read 1
and the rest 0.05; search resumes when no unconfirmed detection is left. Decisions use the
belief only. Tuning history: docs/experiments/ipp.md.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from attend.action.belief import OccupancyMap, connected_groups
from attend.action.camera import DETECTED_VALUE, NOT_DETECTED_VALUE
from attend.action.errors import ActionInputError
from attend.action.metrics import FOUND_THRESHOLD
from attend.action.planners.base import PlanningSetup
from attend.action.planners.informative import InformativePlanner

#: efe_confirm: the search altitude [m] (footprint 11.6 m x 16.2 m, true-positive rate 0.89).
CONFIRM_SEARCH_ALTITUDE_M = 14.0
#: efe_confirm: the confirmation altitude [m] (true-positive rate 0.93, noise variance 0.33).
CONFIRM_ALTITUDE_M = 8.0
#: The field counts as covered for a cell once its variance fell below this share of the prior's.
COVERED_VARIANCE_SHARE = 0.5
#: Candidate centroids closer than this [m] also get a view at their midpoint.
CONFIRM_PAIR_DISTANCE_M = 8.0
#: Views within this distance [m] of a candidate centroid count as visits of it.
VISIT_RADIUS_M = 1.5


class ExpectedFreeEnergyPlanner(InformativePlanner):
    """Minimise expected free energy G = -(epistemic + pragmatic) per flight time (module
    docstring), optionally with a confirmation phase.

    Confirmation (``confirm_altitude_m`` not None): once the field is covered (a share
    ``confirm_after_coverage`` of cells whose variance fell below half the prior's), candidates
    are connected groups (8-neighbourhood, >= 2 cells) of cells with mean >
    ``confirm_candidate_mean`` that still hold an ambiguous cell (mean in
    (``confirm_ambiguous_mean``, 0.5]); views are their mean-weighted centroids and the midpoints
    of pairs closer than 8 m, at ``confirm_altitude_m``; the view taken maximises the value of
    confirmation (module docstring; ties: the nearer view). One image per replan; at most
    ``confirm_visits`` views per candidate centroid (within 1.5 m); with no candidate left, the
    EFE search resumes.

    setup: the planning setup; seed: seeds CMA-ES; preference_nats: c, nats per expected
    detected cell; empty_view_cost_nats: k, nats per expected empty cell in view;
    confirm_altitude_m: altitude of confirmation views [m] (None: no confirmation);
    confirm_after_coverage: covered share of the field before confirming; confirm_visits: views
    per candidate; search_altitude_m: search at this one altitude [m] (None: every layer);
    confirm_candidate_mean, confirm_ambiguous_mean: map means of candidate and ambiguous cells.
    """

    name = "efe"

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, preference_nats: float = 0.2, empty_view_cost_nats: float = 0.0,
        confirm_altitude_m: float | None = None, confirm_after_coverage: float = 0.9, confirm_visits: int = 3,
        search_altitude_m: float | None = None, confirm_candidate_mean: float = 0.25, confirm_ambiguous_mean: float = 0.4,
    ) -> None:
        low, high = setup.field.altitude_limits_m
        for name, value in (("confirm_altitude_m", confirm_altitude_m), ("search_altitude_m", search_altitude_m)):
            if value is not None and not (isinstance(value, (int, float)) and low <= value <= high):
                raise ActionInputError(f"{name}: expected an altitude in [{low:g}, {high:g}] m or None, got {value!r}")
        if not 0.0 <= confirm_after_coverage <= 1.0:
            raise ActionInputError(f"confirm_after_coverage: expected a share in [0, 1], got {confirm_after_coverage!r}")
        if int(confirm_visits) != confirm_visits or confirm_visits < 1:
            raise ActionInputError(f"confirm_visits: expected an integer >= 1, got {confirm_visits!r}")
        if not 0.0 < confirm_candidate_mean < FOUND_THRESHOLD:
            raise ActionInputError(
                f"confirm_candidate_mean: expected a map mean in (0, {FOUND_THRESHOLD}), got {confirm_candidate_mean!r}")
        if not confirm_candidate_mean <= confirm_ambiguous_mean < FOUND_THRESHOLD:
            raise ActionInputError(
                f"confirm_ambiguous_mean: expected a map mean in [confirm_candidate_mean, {FOUND_THRESHOLD}), "
                f"got {confirm_ambiguous_mean!r}"
            )
        self.preference_nats = preference_nats
        self.empty_view_cost_nats = empty_view_cost_nats
        self.confirm_altitude_m = confirm_altitude_m
        self.confirm_after_coverage = confirm_after_coverage
        self.confirm_visits = confirm_visits
        self.search_altitude_m = search_altitude_m
        self.confirm_candidate_mean = confirm_candidate_mean
        self.confirm_ambiguous_mean = confirm_ambiguous_mean
        super().__init__(setup, seed)
        if search_altitude_m is not None:
            self.setup = dataclasses.replace(setup, altitude_layers_m=(float(search_altitude_m),))

    def reset(self, seed: int = 0) -> None:
        """Start a new mission (forgets the visited views); seed: reseeds CMA-ES."""
        super().reset(seed)
        self._visits: list[np.ndarray] = []

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
        """One confirmation view when there is one to take, else the EFE search path.

        belief: the current map; pose: (x, y, z) [m]; remaining_budget_s: flight time left [s];
        time_to_next_image_s: time until the camera's next image [s]."""
        target = self._confirmation_target(belief, np.asarray(pose, float)) if self.confirm_altitude_m else None
        if target is not None:
            self._visits.append(target[:2].copy())
            return target[None]
        return super().plan(belief, pose, remaining_budget_s, time_to_next_image_s)

    def _field_covered(self, belief: OccupancyMap) -> bool:
        prior_variance = self.setup.map_prior.variance(belief.grid.cells_per_side)
        covered = belief.variance < COVERED_VARIANCE_SHARE * prior_variance
        return bool(np.mean(covered) >= self.confirm_after_coverage)

    def confirmation_candidates(self, belief: OccupancyMap) -> list[np.ndarray]:
        """Centroids (x, y) m of the unconfirmed detections not yet visited ``confirm_visits`` times.

        belief: the current map."""
        centres = belief.grid.cell_centres()
        out = []
        for cells in connected_groups(belief.mean > self.confirm_candidate_mean, belief.grid, min_cells=2):
            means = belief.mean[cells]
            if not np.any((means > self.confirm_ambiguous_mean) & (means <= FOUND_THRESHOLD)):
                continue
            centre = (centres[cells] * means[:, None]).sum(axis=0) / means.sum()
            if sum(np.hypot(*(centre - v)) < VISIT_RADIUS_M for v in self._visits) >= self.confirm_visits:
                continue
            out.append(centre)
        return out

    def confirmation_value(self, belief: OccupancyMap, view: np.ndarray) -> float:
        """Expected number of cells pushed across the found threshold by one image (module docstring).

        belief: the current map; view: (x, y, z) [m] of the image."""
        setup = self.setup
        altitude = float(view[2])
        cells = np.flatnonzero(setup.camera.visible_cells(np.asarray(view)[None], belief.grid, setup.field.obstacles)[0])
        if len(cells) == 0:
            return 0.0
        z = np.where(belief.mean[cells] > self.confirm_candidate_mean, DETECTED_VALUE, NOT_DETECTED_VALUE)
        after = kalman_mean(belief, cells, z, float(setup.detector.noise_variance(altitude)))
        crossing = (belief.mean <= FOUND_THRESHOLD) & (after > FOUND_THRESHOLD)
        return float(setup.detector.true_positive_rate(altitude)) * float(np.sum(occupancy_probability(belief.mean)[crossing]))

    def _confirmation_target(self, belief: OccupancyMap, pose: np.ndarray) -> np.ndarray | None:
        """The confirmation view (x, y, confirm_altitude_m), or None (search)."""
        if not self._field_covered(belief):
            return None
        centres = self.confirmation_candidates(belief)
        if not centres:
            return None
        views = list(centres) + [(a + b) / 2 for i, a in enumerate(centres) for b in centres[i + 1:]
                                 if np.hypot(*(a - b)) < CONFIRM_PAIR_DISTANCE_M]
        best, best_key = None, None
        for centre in views:
            view = np.array([centre[0], centre[1], float(self.confirm_altitude_m)])
            key = (self.confirmation_value(belief, view), -float(np.hypot(*(centre - pose[:2]))))
            if best_key is None or key > best_key:
                best, best_key = view, key
        return best

    def path_value(self, model, belief, visible, altitudes, valid) -> np.ndarray:
        """-G = epistemic + pragmatic (k,) of k image sets (module docstring).

        model, belief, visible, altitudes, valid: as in :meth:`InformativePlanner.path_value`."""
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
    """Expected free energy in two phases ("efe_confirm"): epistemic-led search at
    ``search_altitude_m`` (14 m), then, once the field is covered, confirmation at
    ``confirm_altitude_m`` (8 m) of the views with the largest expected number of cells pushed
    across the found threshold (module docstring), search resuming when nothing is left to
    confirm. Arguments as :class:`ExpectedFreeEnergyPlanner` (setup, seed, preference_nats,
    empty_view_cost_nats, confirm_altitude_m, confirm_after_coverage, confirm_visits,
    search_altitude_m, confirm_candidate_mean, confirm_ambiguous_mean), with the search
    preference 0.5 nats."""

    name = "efe_confirm"

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, preference_nats: float = 0.5, empty_view_cost_nats: float = 0.0,
        confirm_altitude_m: float | None = CONFIRM_ALTITUDE_M, confirm_after_coverage: float = 0.9,
        confirm_visits: int = 3, search_altitude_m: float | None = CONFIRM_SEARCH_ALTITUDE_M,
        confirm_candidate_mean: float = 0.25, confirm_ambiguous_mean: float = 0.4,
    ) -> None:
        super().__init__(setup, seed, preference_nats, empty_view_cost_nats, confirm_altitude_m, confirm_after_coverage,
                         confirm_visits, search_altitude_m, confirm_candidate_mean, confirm_ambiguous_mean)


def kalman_mean(belief: OccupancyMap, cells: np.ndarray, measurements: np.ndarray, noise_variance: float) -> np.ndarray:
    """Map mean after a hypothetical image, mean' = mean + P_:A (P_AA + r I)^-1 (z - mean_A)
    (exact full-covariance Kalman mean; the covariance is not updated, m^2 n + m^3 / 3 for m
    observed cells).

    belief: the current map; cells: the m observed cells A; measurements: their readings z (m,);
    noise_variance: r."""
    if belief.diagonal:
        v = belief.covariance[cells]
        out = belief.mean.copy()
        out[cells] += v / (v + noise_variance) * (measurements - belief.mean[cells])
        return out
    cross = belief.covariance[:, cells]
    factor = scipy.linalg.cho_factor(cross[cells] + noise_variance * np.eye(len(cells)), lower=True, check_finite=False)
    return belief.mean + cross @ scipy.linalg.cho_solve(factor, measurements - belief.mean[cells], check_finite=False)


def occupancy_probability(mean: np.ndarray) -> np.ndarray:
    """Occupancy probability q = clip((mean - z0) / (z1 - z0), 0, 1), z0 = 0.05 the reading of a
    cell without detection, z1 = 1 a detection; mean: map mean (n,)."""
    return np.clip((mean - NOT_DETECTED_VALUE) / (DETECTED_VALUE - NOT_DETECTED_VALUE), 0.0, 1.0)
