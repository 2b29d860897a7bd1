"""The baseline plan of ``attend plan --planner lawnmower``: a boustrophedon over the area.

Altitude h*: among the UAV's allowed altitudes (its limits and the detector table's altitudes
between them), the lowest at which the UAVs together can fly the whole pattern in their flight
time; when none can, the one that maximises the detected ground per second, pd(h) w(h) (w the
across-track footprint width).

Pattern: parallel strips w(h*) apart along the long axis of the area's minimum rotated
rectangle, each strip cut to the flyable region F (:mod:`attend.action.mission.ground`) and
flown in alternating directions; consecutive strip pieces are joined by routes inside F. With n
UAVs the strips are shared out in n contiguous blocks of about equal length; each UAV flies its
block from the end nearer its home, then again backwards, until its flight time is spent. The
pattern is a fixed function of the mission file, so the
plan of a call is the rest of the pattern from the UAV's progress along it: the point of the
pattern nearest the UAV among those within its flown distance (elapsed time x speed, plus 10 %);
where the pattern passes the same place twice (within 2 m), the pass whose distance along the
pattern is nearest the flown distance.
"""

from __future__ import annotations

import numpy as np
import shapely

from attend.action.mission.ground import ring_vertices
from attend.action.mission.mission import UavPlan

#: Slack on the flown distance when locating a UAV on its pattern.
PROGRESS_SLACK = 0.1
#: Projections within this distance [m] of the nearest count as the same place.
PROGRESS_TIE_M = 2.0


def lawnmower_altitude_m(mission) -> float:
    """h* of the module docstring (the first UAV's limits and camera set the candidates), or
    the mission file's ``[planner] lawnmower_altitude_m``."""
    config = mission.config
    if config.lawnmower_altitude_m is not None:
        return float(config.lawnmower_altitude_m)
    uav = config.uavs[0]
    low, high = uav.altitude_m
    table = np.asarray(config.detector.altitudes_m)
    candidates = np.unique(np.r_[low, high, table[(table > low) & (table < high)]])
    area = float(mission.ground.searchable.sum()) * mission.ground.grid.cell_area_m2
    total_speed = sum(u.speed_m_s for u in config.uavs)
    for h in candidates:
        width = float(mission.cameras[0].footprint_m(h)[0])
        pattern_s = area / width / total_speed * 1.15  # strips plus turns and joins
        if pattern_s <= config.flight_time_s:
            return float(h)
    rate = config.detector.detection_probability(candidates) * mission.cameras[0].footprint_m(candidates)[0]
    return float(candidates[int(np.argmax(rate))])


def lawnmower_patterns(mission) -> list[np.ndarray]:
    """Per UAV the pattern (w, 3) [m]: from home (at h*), along its block of strips."""
    ground = mission.ground
    h = lawnmower_altitude_m(mission)
    width = float(mission.cameras[0].footprint_m(h)[0])
    free = ground.flyable
    rectangle = np.asarray(free.minimum_rotated_rectangle.exterior.coords)[:4]
    edges = np.diff(np.vstack([rectangle, rectangle[:1]]), axis=0)
    long_edge = edges[int(np.argmax(np.hypot(*edges.T)))]
    along = long_edge / np.hypot(*long_edge)
    across = np.array([-along[1], along[0]])
    corners = ring_vertices(free)
    a_lo, a_hi = (corners @ along).min() - 1.0, (corners @ along).max() + 1.0
    c_lo, c_hi = (corners @ across).min(), (corners @ across).max()
    offsets = np.arange(c_lo + width / 2, c_hi, width)
    if len(offsets) == 0:
        offsets = np.array([(c_lo + c_hi) / 2])
    strips = []
    for k, c in enumerate(offsets):
        line = shapely.LineString([a_lo * along + c * across, a_hi * along + c * across])
        pieces = shapely.intersection(free, line)
        parts = [g for g in getattr(pieces, "geoms", [pieces]) if g.geom_type == "LineString" and not g.is_empty]
        parts.sort(key=lambda g: np.asarray(g.coords)[:, :2].mean(axis=0) @ along)
        if k % 2:
            parts = parts[::-1]
        for part in parts:
            xy = np.asarray(part.coords)[:, :2]
            if (xy[-1] - xy[0]) @ along * (1 if k % 2 == 0 else -1) < 0:
                xy = xy[::-1]
            strips.append(xy[[0, -1]])
    n = len(mission.config.uavs)
    lengths = np.array([np.hypot(*(s[1] - s[0])) for s in strips])
    bounds = np.searchsorted(np.cumsum(lengths), np.linspace(0, lengths.sum(), n + 1)[1:-1])
    blocks = np.split(np.arange(len(strips)), bounds)
    patterns = []
    for k in range(n):
        home = mission.homes_m[k]
        pieces = [strips[i] for i in blocks[k]] if k < len(blocks) else []
        if pieces and np.hypot(*(pieces[-1][-1] - home)) < np.hypot(*(pieces[0][0] - home)):
            pieces = [p[::-1] for p in pieces[::-1]]
        points = [np.r_[home, h]]
        here = home
        flown, reach = 0.0, mission.config.flight_time_s * mission.config.uavs[k].speed_m_s
        while pieces and flown < reach:  # sweep the block again, backwards, until the flight time is spent
            for piece in pieces:
                for xy in ground.route(here, piece[0]):
                    flown += float(np.hypot(*(xy - points[-1][:2])))
                    points.append(np.r_[xy, h])
                flown += float(np.hypot(*(piece[1] - points[-1][:2])))
                points.append(np.r_[piece[1], h])
                here = piece[1]
            pieces = [p[::-1] for p in pieces[::-1]]
        patterns.append(np.array(points))
    return patterns


def plan_lawnmower(mission, horizon_s: float) -> list[UavPlan]:
    """The rest of each UAV's pattern from its progress (module docstring), cut at the horizon
    and where the flight time left no longer covers the way home."""
    plans = []
    for k, (uav, pattern) in enumerate(zip(mission.config.uavs, lawnmower_patterns(mission))):
        pose, elapsed = mission.uav_state(k)
        start = np.r_[pose, elapsed]
        length = np.r_[0.0, np.cumsum(np.hypot(*np.diff(pattern[:, :2], axis=0).T) + np.abs(np.diff(pattern[:, 2])))]
        expected = elapsed * uav.speed_m_s
        flown = expected * (1 + PROGRESS_SLACK) + 1.0
        candidates = []  # (segment, arc length, distance) of the UAV's projection on each segment
        for j in range(1, len(pattern)):
            a, b = pattern[j - 1, :2], pattern[j, :2]
            seg = b - a
            t = np.clip(((pose[:2] - a) @ seg) / max(seg @ seg, 1e-12), 0.0, 1.0)
            s = length[j - 1] + t * (length[j] - length[j - 1])
            if s > flown and j > 1:
                break
            candidates.append((j, s, float(np.hypot(*(a + t * seg - pose[:2])))))
        if not candidates:  # no strip left to this UAV (more UAVs than strips): it stays home
            plans.append(UavPlan(uav.name, start, np.zeros((0, 4)), mission.home_time_s(k, pose[:2])))
            continue
        nearest = min(c[2] for c in candidates)
        # on a path that passes the same place twice (the sweep back), the pass the flown distance points to
        best = min((c for c in candidates if c[2] <= nearest + PROGRESS_TIE_M), key=lambda c: abs(c[1] - expected))[0]
        rest = pattern[best:]
        rows = []
        clock = elapsed
        here = pose.copy()
        if len(rest) and not mission.ground.inside(*here[:2]):
            entry = mission.ground.entry_point(*here[:2])
            arrive = clock + float(np.hypot(*(entry - here[:2]))) / uav.speed_m_s
            if arrive + mission.home_time_s(k, entry) <= mission.config.flight_time_s:
                clock = arrive
                here = np.r_[entry, here[2]]
                rows.append(np.r_[here, clock])
            else:
                rest = rest[:0]  # not even the way in and back fits the flight time
        for point in rest:
            legs = mission.ground.route(here[:2], point[:2]) if mission.ground.inside(*here[:2]) else point[None, :2]
            ok = True
            for xy in legs:
                target = np.r_[xy, point[2]]
                if clock > elapsed + horizon_s:
                    ok = False
                    break
                fraction = _affordable_fraction(mission, k, here, target, clock)
                if fraction <= 0:
                    ok = False
                    break
                target = here + fraction * (target - here)
                clock += (float(np.hypot(*(target[:2] - here[:2]))) + abs(target[2] - here[2])) / uav.speed_m_s
                here = target
                rows.append(np.r_[here, clock])
                if fraction < 1:
                    ok = False
                    break
            if not ok:
                break
        rows = np.array(rows).reshape(-1, 4)
        end = rows[-1, :2] if len(rows) else pose[:2]
        plans.append(UavPlan(uav.name, start, rows, mission.home_time_s(k, end)))
    return plans


def _affordable_fraction(mission, k: int, here: np.ndarray, target: np.ndarray, clock: float) -> float:
    """The largest fraction f in [0, 1] of the leg here -> target after which UAV k still gets
    home within its flight time (bisection; 1 when the whole leg fits, 0 when none of it does)."""
    speed = mission.config.uavs[k].speed_m_s
    budget = mission.config.flight_time_s

    def fits(f: float) -> bool:
        point = here + f * (target - here)
        step = (float(np.hypot(*(point[:2] - here[:2]))) + abs(point[2] - here[2])) / speed
        return clock + step + mission.home_time_s(k, point[:2]) <= budget

    if fits(1.0):
        return 1.0
    low, high = 0.0, 1.0
    for _ in range(14):
        middle = (low + high) / 2
        low, high = (middle, high) if fits(middle) else (low, middle)
    return low if low > 1e-3 else 0.0

