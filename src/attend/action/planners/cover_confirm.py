"""Cover, then confirm ("cover_confirm"): a planner for finding every person, not only a precise map.

A person counts as found when every one of its cells has map mean > 0.5. The informative
planners spread their images to shrink trace(P); that rarely pushes the last cell of every person
across 0.5 within 23 images. This planner spends its images in two phases.

Cover: ``cover_passes`` serpentine passes over the minimal lattice of stops that tiles the field at
``cover_altitude_m`` (13 m: footprint 10.8 m x 15.0 m, 3 x 2 stops, true-positive rate 0.92), the
second pass in reverse. Two looks miss a person with probability (1 - 0.92)^2 = 0.007 where one
look misses 0.08 (all 7 seen: 0.95 against 0.55).

Confirm: the detections are the groups (8-neighbourhood, >= 2 cells) of cells that were part of a
person-sized detection (a detected blob of >= 2 cells in one image,
``OccupancyMap.blob_detection_count``) and whose mean reading, sum(z / r) / sum(1 / r) over the
images that saw them (``OccupancyMap.mean_reading``), is at least ``reading_threshold``: the cells
the detector marked, without the halo the smooth prior spreads around them and without isolated
false positives (a false-positive cell beside a person would hold the group's worst cell below
0.5 for good). Each image goes to the view that most advances the worst cell of the detections
in expectation over the detector's two outcomes,

    value(view) = sum_g [ p_g b_g(detected) + (1 - p_g) b_g(missed) ] - b_g(now),
    b_g = min(min_{i in g} mean_i, 0.5 + margin),   p_g = tpr(h) min(1, 2 f_g),

f_g the share of group g in view, the means after the image exact Kalman means (linear in the
readings: mean' = mean + P_CA S^-1 (z - mean_A), z = 0.05 on every observed cell plus 0.95 on
the cells of the detected group; the other groups enter at their expected readings). Candidate
views: each detection's centroid at 8 and 10 m, midpoints of pairs closer than 10 m at 10 and
12 m, centroids of such pairs with a third detection within 9 m of both at 12 and 14 m, and a 5 x 5 lattice at 14 m; only
views the UAV reaches before its next image. When no view advances any detection by
``search_below``, the image searches instead: the view with the most expected undetected person
cells, tpr(h) sum over ungrouped cells in view of P(x_i > 0.5) = Phi((mean_i - 0.5) / sigma_i).
One view (one image) per replan. Decisions use the belief only.

Tuning history: docs/experiments/ipp.md.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.special


from attend.action.belief import OccupancyMap, connected_groups
from attend.action.camera import DETECTED_VALUE, NOT_DETECTED_VALUE
from attend.action.errors import ActionInputError
from attend.action.flight import detour
from attend.action.metrics import FOUND_THRESHOLD
from attend.action.planners.base import Planner, PlanningSetup
from attend.action.planners.baselines import coverage_stops

#: Cover passes fly at this altitude [m] (footprint 10.8 m x 15.0 m, 3 x 2 stops, tpr 0.92).
COVER_ALTITUDE_M = 13.0
#: The search lattice's altitude [m].
SEARCH_ALTITUDE_M = 14.0
#: Candidate views [m]: at each detection's centroid, a pair's midpoint, a triple's centroid.
CENTROID_ALTITUDES_M = (8.0, 10.0)
PAIR_ALTITUDES_M = (10.0, 12.0)
TRIPLE_ALTITUDES_M = (12.0, 14.0)
#: Pairs of detections closer than this [m] get views at their midpoint; a third within
#: TRIPLE_DISTANCE_M of both makes a triple.
PAIR_DISTANCE_M = 10.0
TRIPLE_DISTANCE_M = 9.0


def detections(belief: OccupancyMap, reading_threshold: float = 0.3, min_cells: int = 2) -> list[np.ndarray]:
    """Cell indices of each detection: connected groups (8-neighbourhood) of at least
    ``min_cells`` cells that were part of a person-sized detection at least once
    (``OccupancyMap.blob_detection_count``) and whose mean reading is >= ``reading_threshold``.

    belief: the current map; reading_threshold: least mean reading sum(z / r) / sum(1 / r);
    min_cells: least cells of a group."""
    marked = (belief.blob_detection_count > 0) & (belief.mean_reading() >= reading_threshold)
    return connected_groups(marked, belief.grid, min_cells)


def _covariance_block(belief: OccupancyMap, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """P[rows, columns] for a full or diagonal belief."""
    if belief.diagonal:
        return (rows[:, None] == columns[None, :]) * belief.covariance[rows][:, None]
    return belief.covariance[np.ix_(rows, columns)]


def confirmation_value(
    belief: OccupancyMap, observed: np.ndarray, noise_variance: float, true_positive_rate: float,
    groups: list[np.ndarray], margin: float = 0.05,
) -> float:
    """Expected advance of the detections' worst cells by one image observing ``observed`` cells
    (see the module docstring); 0 when no detection is in view.

    belief: the current map; observed: indices of the cells in view; noise_variance: r of the
    image; true_positive_rate: tpr(h) of the image; groups: cell indices of each detection;
    margin: the worst cells count up to FOUND_THRESHOLD + margin."""
    observed = np.asarray(observed, dtype=int)
    in_view = np.zeros(belief.grid.n_cells, dtype=bool)
    in_view[observed] = True
    visible = [g for g in groups if in_view[g].any()]
    if not visible or len(observed) == 0:
        return 0.0
    innovation = _covariance_block(belief, observed, observed) + noise_variance * np.eye(len(observed))
    factor = scipy.linalg.cho_factor(innovation, lower=True, check_finite=False)
    cells = np.concatenate(visible)
    cross = _covariance_block(belief, cells, observed)  # P_CA
    missed = belief.mean[cells] + cross @ scipy.linalg.cho_solve(
        factor, NOT_DETECTED_VALUE - belief.mean[observed], check_finite=False)
    jumps = np.column_stack([np.isin(observed, g) * (DETECTED_VALUE - NOT_DETECTED_VALUE) for g in visible])
    shifts = cross @ scipy.linalg.cho_solve(factor, jumps, check_finite=False)  # (|C|, groups)
    p_detect = np.array([true_positive_rate * min(1.0, 2.0 * in_view[g].mean()) for g in visible])
    expected = missed + shifts @ p_detect
    cap = FOUND_THRESHOLD + margin
    value, start = 0.0, 0
    for k, g in enumerate(visible):
        rows = slice(start, start + len(g))
        start += len(g)
        others = expected[rows] - p_detect[k] * shifts[rows, k]
        now = min(float(belief.mean[g].min()), cap)
        if_detected = min(float((others + shifts[rows, k]).min()), cap)
        if_missed = min(float(others.min()), cap)
        value += p_detect[k] * if_detected + (1 - p_detect[k]) * if_missed - now
    return value


class CoverConfirmPlanner(Planner):
    """Cover the field in passes, then confirm the detections (module docstring); ``plan`` returns
    the route to one view (one image).

    setup: the planning setup; seed: seeds the planner (unused: it is deterministic);
    cover_altitude_m: altitude of the cover passes [m]; cover_passes: how many passes;
    reading_threshold: least mean reading of a detection's cells; margin: a detection counts as
    confirmed once its worst cell exceeds FOUND_THRESHOLD + margin; search_below: search instead
    when no view advances a detection by this much; search_altitude_m: altitude of the search
    lattice [m]; search_lattice: its views per side."""

    name = "cover_confirm"

    def __init__(
        self, setup: PlanningSetup, seed: int = 0, cover_altitude_m: float = COVER_ALTITUDE_M, cover_passes: int = 2,
        reading_threshold: float = 0.3, margin: float = 0.03, search_below: float = 0.005,
        search_altitude_m: float = SEARCH_ALTITUDE_M, search_lattice: int = 5,
    ) -> None:
        low, high = setup.field.altitude_limits_m
        for name, value in (("cover_altitude_m", cover_altitude_m), ("search_altitude_m", search_altitude_m)):
            if not (isinstance(value, (int, float)) and low <= value <= high):
                raise ActionInputError(f"{name}: expected an altitude in [{low:g}, {high:g}] m, got {value!r}")
        if int(cover_passes) != cover_passes or cover_passes < 0:
            raise ActionInputError(f"cover_passes: expected an integer >= 0, got {cover_passes!r}")
        if not NOT_DETECTED_VALUE < reading_threshold <= DETECTED_VALUE:
            raise ActionInputError(
                f"reading_threshold: expected a mean reading in ({NOT_DETECTED_VALUE}, {DETECTED_VALUE}], got {reading_threshold!r}")
        if not 0 <= margin < 1 - FOUND_THRESHOLD:
            raise ActionInputError(f"margin: expected a map mean in [0, {1 - FOUND_THRESHOLD}), got {margin!r}")
        if search_below < 0:
            raise ActionInputError(f"search_below: expected a value >= 0, got {search_below!r}")
        if int(search_lattice) != search_lattice or search_lattice < 1:
            raise ActionInputError(f"search_lattice: expected an integer >= 1, got {search_lattice!r}")
        self.cover_altitude_m = float(cover_altitude_m)
        self.cover_passes = int(cover_passes)
        self.reading_threshold = float(reading_threshold)
        self.margin = float(margin)
        self.search_below = float(search_below)
        self.search_altitude_m = float(search_altitude_m)
        self.search_lattice = int(search_lattice)
        super().__init__(setup, seed)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission with every cover stop ahead; seed: reseeds the planner."""
        super().reset(seed)
        self._cover_stops = list(self.cover_pattern())

    def cover_pattern(self) -> np.ndarray:
        """Stops (m, 3) of all cover passes: :func:`coverage_stops` at the cover altitude, every
        other pass reversed."""
        one_pass = coverage_stops(self.setup, self.cover_altitude_m)
        passes = [one_pass if p % 2 == 0 else one_pass[::-1] for p in range(self.cover_passes)]
        return np.concatenate(passes) if passes else np.zeros((0, 3))

    def candidate_views(self, belief: OccupancyMap, groups: list[np.ndarray]) -> np.ndarray:
        """Views (k, 3) m: the search lattice and the detections' centroid, pair and triple views.

        belief: the current map; groups: cell indices of each detection."""
        half = belief.grid.size_m / 2
        ticks = -half + (np.arange(self.search_lattice) + 0.5) * (2 * half / self.search_lattice)
        views = [(x, y, self.search_altitude_m) for x in ticks for y in ticks]
        centres = belief.grid.cell_centres()
        middles = [centres[g].mean(axis=0) for g in groups]
        for i, a in enumerate(middles):
            views += [(a[0], a[1], h) for h in CENTROID_ALTITUDES_M]
            for j in range(i + 1, len(middles)):
                b = middles[j]
                if np.hypot(*(a - b)) >= PAIR_DISTANCE_M:
                    continue
                views += [((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, h) for h in PAIR_ALTITUDES_M]
                for c in middles[j + 1:]:
                    if max(np.hypot(*(a - c)), np.hypot(*(b - c))) < TRIPLE_DISTANCE_M:
                        centre = (a + b + c) / 3
                        views += [(centre[0], centre[1], h) for h in TRIPLE_ALTITUDES_M]
        views = np.array(views, dtype=float)
        low, high = self.setup.field.altitude_limits_m
        views[:, 2] = np.clip(views[:, 2], low, high)
        return views[~self.setup.inside_obstacle(views)]

    def plan(self, belief, pose, remaining_budget_s, time_to_next_image_s=0.0) -> np.ndarray:
        """Route to the next cover stop, else to the best view (one image).

        belief: the current map; pose: (x, y, z) [m]; remaining_budget_s: flight time left [s]
        (unused); time_to_next_image_s: time until the camera's next image [s]."""
        pose = np.asarray(pose, dtype=float)
        if self._cover_stops:
            goal = self._cover_stops.pop(0)
        else:
            goal = self.best_view(belief, pose, max(float(time_to_next_image_s), self.setup.flight.image_period_s))
        return np.asarray(detour(pose, goal, self.setup.field.obstacles, self.setup.obstacle_margin_m + 0.5))

    def best_view(self, belief: OccupancyMap, pose: np.ndarray, reach_s: float) -> np.ndarray:
        """The view for the next image: best confirmation, else best search (module docstring).

        belief: the current map; pose: (x, y, z) [m]; reach_s: only views reachable within this
        flight time [s] (all when none is)."""
        setup = self.setup
        groups = detections(belief, self.reading_threshold)
        views = self.candidate_views(belief, groups)
        distance = np.linalg.norm(views - pose[None], axis=1)
        reachable = setup.flight.segment_duration(distance) <= reach_s + 1e-9
        if reachable.any():
            views, distance = views[reachable], distance[reachable]
        visible = setup.camera.visible_cells(views, belief.grid, setup.field.obstacles)
        tpr = setup.detector.true_positive_rate(views[:, 2])
        noise = setup.detector.noise_variance(views[:, 2])
        values = np.array([
            confirmation_value(belief, np.flatnonzero(visible[k]), float(noise[k]), float(tpr[k]), groups, self.margin)
            for k in range(len(views))
        ])
        if values.max() < self.search_below:
            grouped = np.zeros(belief.grid.n_cells, dtype=bool)
            for g in groups:
                grouped[g] = True
            sigma = np.sqrt(np.maximum(belief.variance, 1e-12))
            undetected = scipy.special.ndtr(-(FOUND_THRESHOLD - belief.mean) / sigma) * ~grouped
            values = tpr * (visible @ undetected)
        best = np.lexsort((distance, -values))[0]  # highest value, then the nearest
        return views[best]

