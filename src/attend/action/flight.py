"""UAV flight model: straight segments between waypoints, rest-to-rest trapezoidal speed profile.

A segment of length d with top speed v and acceleration a takes
    t(d) = d / v + v / a          if d >= v^2 / a  (reaches top speed),
    t(d) = 2 sqrt(d / a)          otherwise,
and the distance flown after time s into it is the trapezoid/triangle integral. Images are taken
every ``image_period_s`` (1 / 0.15 Hz) on the mission clock, so the first image of a new plan comes
``time_to_next_image_s`` after the plan starts; when a segment ends before the next image the UAV
hovers at the waypoint until it is taken (every waypoint yields at least one image).

Routes clear of buildings (:func:`clear_route`), from start s to goal g among boxes B_b: every
segment keeps a clearance c_b = min(m / 2, d(s, B_b) / 2, d(g, B_b) / 2) from box b (m the
margin, d the Euclidean distance from a point to a box: an end already closer than m / 2 to a
box may still leave it). In order:

1. the straight segment s -> g if it clears every box;
2. else the shortest path from s to g through the box corners inflated by m, at the goal's
   altitude g_z (the visibility graph: an edge is a segment clearing every box; corners
   outside the area are dropped), found by Dijkstra; the path bends only at corners, so it is
   the shortest route of that form, not the shortest in free space;
3. else over the top: climb at s to z_c = max(s_z, g_z, max over the boxes whose footprint,
   widened by m, the ground trace s -> g crosses of (roof + m)), fly level to above g, descend
   to g, when z_c <= the ceiling (the altitude limit) and these three segments clear every box;
4. else no route: ActionInputError.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.sparse.csgraph import csgraph_from_dense, dijkstra

from attend.action.camera import segments_hit_box
from attend.action.errors import ActionInputError
from attend.action.field import Obstacle


@dataclass(frozen=True)
class FlightModel:
    """speed_m_s: top speed; acceleration_m_s2: acceleration and deceleration;
    image_rate_hz: camera rate (images along the path)."""

    speed_m_s: float = 5.0
    acceleration_m_s2: float = 3.0
    image_rate_hz: float = 0.15

    def __post_init__(self) -> None:
        for name in ("speed_m_s", "acceleration_m_s2", "image_rate_hz"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ActionInputError(f"{name}: expected a number > 0, got {value!r}")

    @property
    def image_period_s(self) -> float:
        return 1.0 / self.image_rate_hz

    def segment_duration(self, distance_m: np.ndarray) -> np.ndarray:
        """Rest-to-rest time (s) for segments of the given lengths; distance_m: lengths [m]."""
        d = np.asarray(distance_m, dtype=float)
        v, a = self.speed_m_s, self.acceleration_m_s2
        return np.where(d >= v * v / a, d / v + v / a, 2 * np.sqrt(np.maximum(d, 0) / a))

    def distance_after(self, elapsed_s: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
        """Distance flown (m) ``elapsed_s`` into a rest-to-rest segment of length ``distance_m``."""
        s = np.asarray(elapsed_s, dtype=float)
        d = np.asarray(distance_m, dtype=float)
        v, a = self.speed_m_s, self.acceleration_m_s2
        total = self.segment_duration(d)
        cruise = d >= v * v / a
        peak_time = np.where(cruise, v / a, total / 2)  # end of acceleration
        peak_speed = a * peak_time
        brake_start = total - peak_time
        accel_part = 0.5 * a * np.minimum(s, peak_time) ** 2
        cruise_part = peak_speed * np.clip(s - peak_time, 0, np.maximum(brake_start - peak_time, 0))
        braking = np.clip(s - brake_start, 0, peak_time)
        brake_part = peak_speed * braking - 0.5 * a * braking**2
        return np.minimum(accel_part + cruise_part + brake_part, d)

    def speed_after(self, elapsed_s: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
        """Speed (m/s) ``elapsed_s`` into a rest-to-rest segment of length ``distance_m``: a s while
        accelerating, the peak speed while cruising, falling at a while braking, 0 once arrived
        (hovering)."""
        s = np.asarray(elapsed_s, dtype=float)
        d = np.asarray(distance_m, dtype=float)
        v, a = self.speed_m_s, self.acceleration_m_s2
        total = self.segment_duration(d)
        peak_time = np.where(d >= v * v / a, v / a, total / 2)
        peak_speed = a * peak_time
        speed = np.minimum(np.minimum(a * s, peak_speed), a * (total - s))
        return np.where((s > 0) & (s < total), np.maximum(speed, 0.0), 0.0)

    def segment_images(
        self,
        start_m: np.ndarray,
        end_m: np.ndarray,
        time_to_next_image_s: np.ndarray,
        time_left_s: np.ndarray,
        hover_for_image: bool = True,
        with_speeds: bool = False,
    ) -> tuple[np.ndarray, ...]:
        """Images taken on k segments start -> end (``start_m``, ``end_m``: arrays (k, 3) [m]),
        vectorised; time_to_next_image_s: time from each segment's start to its first image [s].

        The UAV hovers at the end of a segment until the next image when the segment is shorter
        than the time to that image (``hover_for_image``), so every waypoint reached before its
        image yields one. An image due at departure (time to next image 0) is taken at the start
        and belongs to it: a moving segment then waits for the image one period later.
        Flight stops at ``time_left_s``. Returns image poses (k, J, 3), image times since the
        segment start (k, J), valid mask (k, J), segment duration (k,) and the time from the
        segment end to the next image (k,); ``with_speeds``: also the speed at each image (k, J)
        [m/s] (0 when hovering).
        """
        start = np.atleast_2d(np.asarray(start_m, float))
        end = np.atleast_2d(np.asarray(end_m, float))
        k = max(len(start), len(end))
        start, end = np.broadcast_to(start, (k, 3)), np.broadcast_to(end, (k, 3))
        first = np.broadcast_to(np.asarray(time_to_next_image_s, float), (k,))
        time_left = np.broadcast_to(np.asarray(time_left_s, float), (k,))
        length = np.linalg.norm(end - start, axis=1)
        travel = self.segment_duration(length)
        # an image due at departure is the start's; the goal waits for the following one
        awaited = np.where((first <= 1e-9) & (travel > 1e-9), first + self.image_period_s, first)
        duration = np.maximum(travel, awaited) if hover_for_image else travel
        duration = np.minimum(duration, time_left)
        period = self.image_period_s
        n_images = np.where(first <= duration + 1e-9, np.floor((duration - first + 1e-9) / period) + 1, 0).astype(int)
        width = max(int(n_images.max()) if k else 0, 1)
        times = first[:, None] + period * np.arange(width)[None, :]
        valid = np.arange(width)[None, :] < n_images[:, None]
        flown = self.distance_after(np.minimum(times, travel[:, None]), length[:, None])
        fraction = np.where(length[:, None] > 0, flown / np.maximum(length[:, None], 1e-12), 0.0)
        poses = start[:, None, :] + fraction[..., None] * (end - start)[:, None, :]
        next_after = first + n_images * period - duration
        if with_speeds:
            return poses, times, valid, duration, next_after, self.speed_after(times, length[:, None])
        return poses, times, valid, duration, next_after

    def path_images(
        self, start_m: np.ndarray, paths_m: np.ndarray, time_to_next_image_s: float, time_left_s: float,
        with_speeds: bool = False,
    ) -> tuple[np.ndarray, ...]:
        """Images along k paths of w waypoints from a common start: poses (k, J, 3),
        valid (k, J), flight time of each path (k,) and per-segment durations (k, w).

        start_m: (x, y, z) [m]; paths_m: (k, w, 3) waypoints [m]; time_to_next_image_s: time to
        the first image [s]; time_left_s: flight time left [s]; with_speeds: also the speed at
        each image (k, J) [m/s]."""
        paths = np.asarray(paths_m, float)
        k, w, _ = paths.shape
        current = np.broadcast_to(np.asarray(start_m, float), (k, 3))
        first = np.full(k, float(time_to_next_image_s))
        left = np.full(k, float(time_left_s))
        all_poses, all_valid, durations, all_speeds = [], [], [], []
        for j in range(w):
            poses, _, valid, duration, first, *speeds = self.segment_images(current, paths[:, j], first, left,
                                                                             with_speeds=with_speeds)
            all_speeds.extend(speeds)
            all_poses.append(poses)
            all_valid.append(valid)
            durations.append(duration)
            left = left - duration
            current = paths[:, j]
        durations_arr = np.column_stack(durations)
        out = (np.concatenate(all_poses, axis=1), np.concatenate(all_valid, axis=1), durations_arr.sum(axis=1),
               durations_arr)
        return out + (np.concatenate(all_speeds, axis=1),) if with_speeds else out


def path_collides(points_m: np.ndarray, obstacles: Sequence[Obstacle], margin_m: float = 1.0) -> np.ndarray:
    """For paths (k, w, 3) (w points each, consecutive points joined), whether any segment
    passes within ``margin_m`` [m] of an obstacle box; returns (k,) bools.

    points_m: the paths' points (x, y, z) [m], (k, w, 3); obstacles: the boxes."""
    paths = np.asarray(points_m, dtype=float)
    k, w, _ = paths.shape
    if not obstacles or w < 2:
        return np.zeros(k, dtype=bool)
    start = paths[:, :-1].reshape(-1, 3)
    end = paths[:, 1:].reshape(-1, 3)
    hit = np.zeros(len(start), dtype=bool)
    for box in obstacles:
        hit |= segments_hit_box(start, end, box.bounds, margin_m)
    return hit.reshape(k, w - 1).any(axis=1)


def detour(start_m: np.ndarray, goal_m: np.ndarray, obstacles: Sequence[Obstacle], margin_m: float = 1.5) -> np.ndarray:
    """Waypoints (j, 3) from start to goal that go around the boxes in the way (via the box
    corners inflated by ``margin_m`` [m], at the goal altitude, shorter side first); ends at goal.

    start_m, goal_m: positions (x, y, z) [m], (3,); obstacles: the boxes, each detoured in turn."""
    start, goal = np.asarray(start_m, float), np.asarray(goal_m, float)
    route = [goal]
    for box in obstacles:
        if not path_collides(np.array([[start, route[0]]]), [box], margin_m * 0.5)[0]:
            continue
        x0, x1, y0, y1, _, _ = box.bounds
        corners = np.array(
            [[x0 - margin_m, y0 - margin_m], [x1 + margin_m, y0 - margin_m], [x1 + margin_m, y1 + margin_m], [x0 - margin_m, y1 + margin_m]]
        )
        altitude = goal[2]
        best, best_len = None, np.inf
        for i in range(4):
            for j in range(4):
                via = [np.r_[corners[i], altitude]] if i == j else [np.r_[corners[i], altitude], np.r_[corners[j], altitude]]
                if i != j and abs(i - j) == 2:
                    continue
                candidate = np.vstack([start[None], via, route[0][None]])
                if path_collides(candidate[None], [box], margin_m * 0.5)[0]:
                    continue
                length = np.linalg.norm(np.diff(candidate, axis=0), axis=1).sum()
                if length < best_len:
                    best, best_len = via, length
        if best is not None:
            route = list(best) + route
    return np.array(route)


def box_distance(point_m: np.ndarray, bounds: Sequence[float]) -> float:
    """Euclidean distance [m] from ``point_m`` (x, y, z) [m] to the box ``bounds`` (x_min, x_max,
    y_min, y_max, z_min, z_max) [m]; 0 inside or on it."""
    p = np.asarray(point_m, dtype=float)
    low, high = np.asarray(bounds, dtype=float)[0::2], np.asarray(bounds, dtype=float)[1::2]
    return float(np.linalg.norm(np.maximum(np.maximum(low - p, p - high), 0.0)))


def _segments_clear(start: np.ndarray, end: np.ndarray, obstacles: Sequence[Obstacle], clearances: np.ndarray) -> np.ndarray:
    """(k,) bools: segment start -> end (arrays (k, 3) [m]) keeps clearance c_b from every box b."""
    clear = np.ones(len(start), dtype=bool)
    for box, clearance in zip(obstacles, clearances):
        clear &= ~segments_hit_box(start, end, box.bounds, float(clearance))
    return clear


def clear_route(
    start_m: np.ndarray,
    goal_m: np.ndarray,
    obstacles: Sequence[Obstacle],
    margin_m: float = 1.5,
    ceiling_m: float = np.inf,
    extent_m: Sequence[float] | None = None,
) -> np.ndarray:
    """Waypoints (j, 3) [m] from start to goal, ending at goal, every segment (the first from the
    start) clear of every box: straight, else around the boxes by the shortest corner path,
    else over them (module docstring for the rule).

    start_m, goal_m: positions (x, y, z) [m], (3,); obstacles: the boxes; margin_m: m, how far
    outside the boxes the corners lie [m] (>= 0; the clearance kept is m / 2); ceiling_m:
    highest altitude a climb over the boxes may reach [m]; extent_m: (x0, x1, y0, y1) [m] of
    the area the corners must lie in (None: anywhere). Raises ActionInputError when no route
    of the three kinds exists (e.g. the goal inside a box)."""
    start, goal = np.asarray(start_m, dtype=float), np.asarray(goal_m, dtype=float)
    if start.shape != (3,) or goal.shape != (3,) or not (np.all(np.isfinite(start)) and np.all(np.isfinite(goal))):
        raise ActionInputError(f"start_m, goal_m: expected finite (x, y, z) in m, got {start_m!r}, {goal_m!r}")
    if not (np.isfinite(margin_m) and margin_m >= 0):
        raise ActionInputError(f"margin_m: expected a distance >= 0 m, got {margin_m!r}")
    boxes = tuple(obstacles)
    if not boxes:
        return goal[None].copy()
    clearances = np.array(
        [min(margin_m / 2, box_distance(start, b.bounds) / 2, box_distance(goal, b.bounds) / 2) for b in boxes]
    )
    if _segments_clear(start[None], goal[None], boxes, clearances)[0]:
        return goal[None].copy()
    # around: the visibility graph of the inflated corners at the goal's altitude
    corners = np.array([
        [x, y, goal[2]]
        for box in boxes
        for x in (box.bounds[0] - margin_m, box.bounds[1] + margin_m)
        for y in (box.bounds[2] - margin_m, box.bounds[3] + margin_m)
    ])
    if extent_m is not None:
        x0, x1, y0, y1 = extent_m
        corners = corners[(corners[:, 0] >= x0) & (corners[:, 0] <= x1) & (corners[:, 1] >= y0) & (corners[:, 1] <= y1)]
    nodes = np.vstack([start[None], goal[None], corners])
    i, j = np.triu_indices(len(nodes), 1)
    usable = _segments_clear(nodes[i], nodes[j], boxes, clearances)
    lengths = np.full((len(nodes), len(nodes)), np.inf)
    edge = np.maximum(np.linalg.norm(nodes[j] - nodes[i], axis=1), 1e-12)
    lengths[i[usable], j[usable]] = lengths[j[usable], i[usable]] = edge[usable]
    distance, previous = dijkstra(csgraph_from_dense(lengths, null_value=np.inf), indices=0, return_predecessors=True)
    if np.isfinite(distance[1]):
        path, node = [], 1
        while node != 0:
            path.append(nodes[node])
            node = previous[node]
        return np.array(path[::-1])
    # over: climb above the roofs under the ground trace
    ground_start, ground_goal = np.r_[start[:2], 0.0][None], np.r_[goal[:2], 0.0][None]
    under = [b for b in boxes if segments_hit_box(ground_start, ground_goal, b.bounds, margin_m)[0]]
    cruise = max([start[2], goal[2]] + [b.bounds[5] + margin_m for b in under])
    if cruise <= ceiling_m:
        route = np.array([[start[0], start[1], cruise], [goal[0], goal[1], cruise], goal])
        points = np.vstack([start[None], route])
        keep = np.r_[True, np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-9]
        points = points[keep]
        if _segments_clear(points[:-1], points[1:], boxes, clearances).all():
            return points[1:] if len(points) > 1 else goal[None].copy()
    raise ActionInputError(
        f"goal_m: no route clear of the buildings from {tuple(np.round(start, 3))} to {tuple(np.round(goal, 3))} m "
        f"around them or over them below the ceiling {ceiling_m:g} m"
    )
