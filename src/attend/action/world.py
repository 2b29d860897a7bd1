"""Ground truth of a large search: the area, the people, the buildings, and simulated images.

Frame: x east, y north, z up [m], ground at z = 0; the area is the square map grid
(:class:`attend.action.probability_map.MapGrid`) centred on the origin. A person is a point, the
centre of the body; a building is an axis-aligned box (:class:`attend.action.field.Obstacle`)
that hides the ground beneath it and behind it from the camera.

An image at pose (x, y, h), speed v: the footprint cells are those whose centres lie in the
camera footprint w_x(h) x w_y(h) centred below it; a cell is visible when the segment from the
camera to its centre misses every building (only buildings overlapping the footprint can be in
the way: the segment's ground trace stays inside the footprint). Every person whose cell is
visible is reported with probability pd(h, v) at its position plus N(0, sigma(h)^2 I); clutter:
Poisson(kappa(h) A_visible) false detections uniform over the visible cells, where A_visible is
the visible ground area and kappa(h) the clutter density of :mod:`attend.action.detection` (so
the clutter density on visible ground is kappa(h) whatever the buildings hide).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from attend.action.camera import Camera, segments_hit_box
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.field import Obstacle, SearchField, validate_altitude_limits
from attend.action.probability_map import ImageObservation, MapGrid

#: Start poses in a world: this many, along the south edge from the south-west corner.
MAX_UAVS = 8
#: Altitude [m] of the start poses (clipped into the altitude limits).
START_ALTITUDE_M = 30.0
#: Largest map make_world builds (cells).
MAX_CELLS = 4_000_000
#: Least distance [m] between a building and the edge of the area (room to fly around it).
BUILDING_EDGE_MARGIN_M = 3.0


@dataclass(frozen=True)
class SearchWorld:
    """The truth of one search.

    grid: the map grid (the area); people_m: (k, 2) positions of the people's centres [m];
    buildings: boxes; searchable: (ny, nx) bool, inside the area and not under a building;
    prior_map: (ny, nx) relative likelihood of a person per cell the planner may be given
    (None: no prior knowledge); start_poses_m: (u, 3) take-off poses [m], UAV i starts at row i;
    altitude_limits_m: (low, high) flight altitudes [m].
    """

    grid: MapGrid
    people_m: np.ndarray
    buildings: tuple[Obstacle, ...]
    searchable: np.ndarray
    prior_map: np.ndarray | None
    start_poses_m: np.ndarray
    altitude_limits_m: tuple[float, float]

    def __post_init__(self) -> None:
        people = np.asarray(self.people_m, dtype=float).reshape(-1, 2)
        if not np.all(self.grid.contains(people[:, 0], people[:, 1])):
            raise ActionInputError("people_m: expected every person inside the grid")
        object.__setattr__(self, "people_m", people)
        object.__setattr__(self, "buildings", tuple(self.buildings))
        searchable = np.asarray(self.searchable, dtype=bool)
        if searchable.shape != self.grid.shape:
            raise ActionInputError(f"searchable: expected shape {self.grid.shape}, got {searchable.shape}")
        object.__setattr__(self, "searchable", searchable)
        starts = np.atleast_2d(np.asarray(self.start_poses_m, dtype=float))
        if starts.ndim != 2 or starts.shape[1] != 3 or not np.all(np.isfinite(starts)):
            raise ActionInputError(f"start_poses_m: expected (u, 3) finite poses in m, got shape {starts.shape}")
        object.__setattr__(self, "start_poses_m", starts)
        object.__setattr__(self, "altitude_limits_m", validate_altitude_limits(self.altitude_limits_m))

    @property
    def n_people(self) -> int:
        return len(self.people_m)

    def building_cells(self) -> np.ndarray:
        """(ny, nx) bool: cells whose centres lie under a building."""
        return _under_buildings(self.grid, self.buildings)


def make_world(
    area_m: float,
    cell_size_m: float,
    n_people: int,
    seed: int,
    n_buildings: int = 0,
    prior: str = "uniform",
    altitude_limits_m: Sequence[float] = (5.0, 120.0),
    prior_map: np.ndarray | None = None,
) -> SearchWorld:
    """A square search area of side ``area_m`` centred on the origin, with people and buildings
    drawn by ``seed``.

    Buildings: boxes of side U(8, 30) m (at most area / 3) and height U(5, 40) m, at least 3 m
    from the area's edge and from each other, placed first. People: each in a different
    searchable cell, at a uniform position in it; the cell drawn uniformly ("uniform": no
    prior map) or from an informative prior map ("informative": 2 to 4 Gaussian blobs of
    standard deviation area / 20 to area / 8 (60 % of the mass), a trail (a Gaussian band of
    standard deviation area / 50 about a random line, 35 %) and a uniform floor (5 %); the same map is the world's prior_map, so the
    prior is right). Start poses: 8 along the south edge from the south-west corner, spaced
    min(10 m, area / 8), at 30 m (clipped into the altitude limits).

    area_m: side [m]; cell_size_m: map cell side [m] (<= area_m); n_people: people (>= 1, at
    most the searchable cells); seed: seeds everything; n_buildings: buildings (>= 0);
    prior: "uniform" or "informative"; altitude_limits_m: (low, high) flight altitudes [m];
    prior_map: a user's relative likelihood of a person per cell, (ny, nx) on the grid (row 0
    south, ``MapGrid.square(area_m, cell_size_m)``), finite, >= 0, > 0 on at least n_people
    searchable cells: the world's prior_map, and the people's cells are drawn from it (with
    prior="uniform"; "informative" with a prior_map is an error).
    """
    if isinstance(area_m, (bool, np.bool_)) or not np.isfinite(area_m) or area_m <= 0:
        raise ActionInputError(f"area_m: expected a side > 0 m, got {area_m!r}")
    if isinstance(cell_size_m, (bool, np.bool_)) or not np.isfinite(cell_size_m) or cell_size_m <= 0:
        raise ActionInputError(f"cell_size_m: expected a cell side > 0 m, got {cell_size_m!r}")
    if cell_size_m > area_m:
        raise ActionInputError(f"cell_size_m: expected a cell no larger than area_m={area_m!r} m, got {cell_size_m!r}")
    if round(area_m / cell_size_m) ** 2 > MAX_CELLS:
        raise ActionInputError(
            f"cell_size_m: expected at most {MAX_CELLS} cells, got {round(area_m / cell_size_m) ** 2} "
            f"for area_m={area_m!r} m"
        )
    for name, value, least in (("n_people", n_people, 1), ("n_buildings", n_buildings, 0)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < least:
            raise ActionInputError(f"{name}: expected a whole number >= {least}, got {value!r}")
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ActionInputError(f"seed: expected a whole number >= 0, got {seed!r}")
    if prior not in ("uniform", "informative"):
        raise ActionInputError(f"prior: expected 'uniform' or 'informative', got {prior!r}")
    if prior_map is not None and prior != "uniform":
        raise ActionInputError(f"prior_map: expected prior='uniform' with a prior_map given, got prior={prior!r}")
    low, high = validate_altitude_limits(altitude_limits_m)
    rng = np.random.default_rng(seed)
    grid = MapGrid.square(area_m, cell_size_m)
    user_map = None
    if prior_map is not None:
        user_map = np.array(prior_map, dtype=float)
        if user_map.shape != grid.shape:
            raise ActionInputError(f"prior_map: expected an array of the grid's shape {grid.shape}, got {user_map.shape}")
        if not np.all(np.isfinite(user_map)) or np.any(user_map < 0):
            raise ActionInputError("prior_map: expected finite values >= 0")
    buildings = _place_buildings(grid, int(n_buildings), rng)
    searchable = ~_under_buildings(grid, buildings)
    if n_people > searchable.sum():
        raise ActionInputError(
            f"n_people: expected at most the {int(searchable.sum())} searchable cells, got {n_people!r}"
        )
    prior_map = _informative_prior(grid, rng) if prior == "informative" else user_map
    weights = (prior_map if prior_map is not None else np.ones(grid.shape))[searchable]
    if np.count_nonzero(weights) < n_people:
        name = "prior_map" if user_map is not None else "n_people"
        raise ActionInputError(
            f"{name}: expected at least n_people={n_people} searchable cells the prior allows, got {np.count_nonzero(weights)}"
        )
    cells = np.flatnonzero(searchable)[rng.choice(len(weights), size=int(n_people), replace=False, p=weights / weights.sum())]
    iy, ix = np.divmod(cells, grid.nx)
    x0, y0 = grid.origin_m
    people = np.column_stack(
        [x0 + (ix + rng.random(len(cells))) * grid.cell_size_m, y0 + (iy + rng.random(len(cells))) * grid.cell_size_m]
    )
    x_left, _, y_bottom, _ = grid.extent_m
    spacing = min(10.0, area_m / MAX_UAVS)
    altitude = float(np.clip(START_ALTITUDE_M, low, high))
    starts = np.array([[x_left + k * spacing, y_bottom, altitude] for k in range(MAX_UAVS)])
    return SearchWorld(grid, people, buildings, searchable, prior_map, starts, (low, high))


def world_from_field(field: SearchField) -> SearchWorld:
    """The paper's field (:mod:`attend.action.field`) on the scalable stack: the same cells
    (``MapGrid.square(size, cell)``), the people's centres, the obstacles as buildings, the
    start pose and the altitude limits; no prior map.

    field: the search field."""
    if not isinstance(field, SearchField):
        raise ActionInputError(f"field: expected a SearchField, got {type(field).__name__}")
    grid = MapGrid.square(field.grid.size_m, field.grid.cell_size_m)
    people = np.array([[p.x_m, p.y_m] for p in field.people]).reshape(-1, 2)
    buildings = tuple(field.obstacles)
    searchable = ~_under_buildings(grid, buildings)
    return SearchWorld(
        grid, people, buildings, searchable, None, np.asarray(field.start_pose_m, dtype=float)[None], field.altitude_limits_m
    )


def footprint_window(grid: MapGrid, pose_m: np.ndarray, camera: Camera) -> tuple[slice, slice]:
    """(rows, cols) of the cells whose centres lie in the camera footprint below ``pose_m``
    (x, y, h) [m]; camera: the footprint w_x(h) x w_y(h)."""
    width_x, width_y = camera.footprint_m(pose_m[2])
    return grid.window(pose_m[0], pose_m[1], float(width_x), float(width_y))


def visible_in_window(
    grid: MapGrid, pose_m: np.ndarray, window: tuple[slice, slice], buildings: Sequence[Obstacle]
) -> np.ndarray:
    """(rows, cols) bool over ``window``: the segment from the camera at ``pose_m`` (x, y, h) [m]
    to the cell centre misses every building (a cell under a building is hidden). Only the
    buildings overlapping the window's cells are tested."""
    rows, cols = window
    visible = np.ones((rows.stop - rows.start, cols.stop - cols.start), dtype=bool)
    if not buildings or visible.size == 0:
        return visible
    xs, ys = grid.window_centres(window)
    half = grid.cell_size_m / 2
    for box in buildings:
        x0, x1, y0, y1, _, _ = box.bounds
        if x1 < xs[0] - half or x0 > xs[-1] + half or y1 < ys[0] - half or y0 > ys[-1] + half:
            continue
        yy, xx = np.meshgrid(ys, xs, indexing="ij")
        ends = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
        starts = np.broadcast_to(np.asarray(pose_m, dtype=float), ends.shape)
        visible &= ~segments_hit_box(starts, ends, box.bounds).reshape(visible.shape)
    return visible


def simulate_image(
    world: SearchWorld,
    pose_m: Sequence[float],
    time_s: float,
    speed_m_s: float,
    model: DetectionModel,
    camera: Camera,
    rng: np.random.Generator,
    uav: int = 0,
) -> ImageObservation:
    """One image at ``pose_m`` (module docstring): footprint window, visibility, people reported
    with pd(h, v) at position + N(0, sigma(h)^2 I), Poisson clutter on the visible cells.

    world: the truth; pose_m: camera (x, y, h) [m], h > 0; time_s: when [s]; speed_m_s: ground
    speed v [m/s]; model: the detector; camera: the footprint; rng: the random generator of the
    detections; uav: which UAV took it."""
    pose = np.asarray(pose_m, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)) or pose[2] <= 0:
        raise ActionInputError(f"pose_m: expected a finite (x, y, z) in m with z > 0, got {pose_m!r}")
    grid = world.grid
    window = footprint_window(grid, pose, camera)
    visible = visible_in_window(grid, pose, window, world.buildings)
    rows, cols = window
    altitude = pose[2]
    reports = []
    if world.n_people and visible.any():
        ix, iy = grid.cell_of(world.people_m[:, 0], world.people_m[:, 1])
        in_window = (iy >= rows.start) & (iy < rows.stop) & (ix >= cols.start) & (ix < cols.stop)
        seen = np.flatnonzero(in_window)
        seen = seen[visible[iy[seen] - rows.start, ix[seen] - cols.start]]
        pd = float(model.detection_probability(altitude, speed_m_s))
        reported = seen[rng.random(len(seen)) < pd]
        sigma = float(model.position_error_m(altitude))
        reports.append(world.people_m[reported] + sigma * rng.standard_normal((len(reported), 2)))
    visible_cells = np.flatnonzero(visible)
    if len(visible_cells):
        kappa = float(model.clutter_density_per_m2(altitude, camera))
        n_clutter = rng.poisson(kappa * len(visible_cells) * grid.cell_area_m2)
        chosen = visible_cells[rng.integers(0, len(visible_cells), size=n_clutter)]
        r, c = np.divmod(chosen, visible.shape[1])
        x0, y0 = grid.origin_m
        s = grid.cell_size_m
        reports.append(
            np.column_stack(
                [x0 + (cols.start + c + rng.random(n_clutter)) * s, y0 + (rows.start + r + rng.random(n_clutter)) * s]
            )
        )
    detections = np.concatenate(reports) if reports else np.zeros((0, 2))
    return ImageObservation(pose, float(time_s), float(speed_m_s), window, visible, detections, int(uav))


def _under_buildings(grid: MapGrid, buildings: Sequence[Obstacle]) -> np.ndarray:
    """(ny, nx) bool: cells whose centres lie under (within the footprint of) a building."""
    under = np.zeros(grid.shape, dtype=bool)
    for box in buildings:
        x0, x1, y0, y1, _, _ = box.bounds
        rows, cols = grid.window((x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0)
        under[rows, cols] = True
    return under


def _place_buildings(grid: MapGrid, n_buildings: int, rng: np.random.Generator) -> tuple[Obstacle, ...]:
    """``n_buildings`` boxes (sides U(8, 30) m, at most a third of the area; heights U(5, 40) m)
    at least BUILDING_EDGE_MARGIN_M from the area's edge and from each other."""
    if n_buildings == 0:
        return ()
    x_left, x_right, y_bottom, y_top = grid.extent_m
    size = x_right - x_left
    largest = min(30.0, size / 3)
    smallest = min(8.0, largest)
    boxes: list[Obstacle] = []
    for _ in range(200 * n_buildings):
        if len(boxes) == n_buildings:
            break
        width, depth = rng.uniform(smallest, largest, size=2)
        height = rng.uniform(5.0, 40.0)
        margin = BUILDING_EDGE_MARGIN_M
        if size - width - 2 * margin <= 0 or size - depth - 2 * margin <= 0:
            continue
        x = rng.uniform(x_left + margin + width / 2, x_right - margin - width / 2)
        y = rng.uniform(y_bottom + margin + depth / 2, y_top - margin - depth / 2)
        box = Obstacle(float(x), float(y), float(width), float(depth), float(height))
        if any(_boxes_closer_than(box, other, margin) for other in boxes):
            continue
        boxes.append(box)
    if len(boxes) < n_buildings:
        raise ActionInputError(f"n_buildings: could not place {n_buildings} buildings apart in the area")
    return tuple(boxes)


def _boxes_closer_than(a: Obstacle, b: Obstacle, gap_m: float) -> bool:
    ax0, ax1, ay0, ay1, _, _ = a.bounds
    bx0, bx1, by0, by1, _, _ = b.bounds
    return ax0 < bx1 + gap_m and bx0 < ax1 + gap_m and ay0 < by1 + gap_m and by0 < ay1 + gap_m


def _informative_prior(grid: MapGrid, rng: np.random.Generator) -> np.ndarray:
    """Relative likelihood (ny, nx) summing to 1: 2-4 Gaussian blobs, a trail band, a 5 % floor."""
    x_left, x_right, y_bottom, y_top = grid.extent_m
    size = x_right - x_left
    xs, ys = grid.centres_x, grid.centres_y
    density = np.zeros(grid.shape)
    for _ in range(int(rng.integers(2, 5))):
        cx, cy = rng.uniform(x_left + size / 8, x_right - size / 8), rng.uniform(y_bottom + size / 8, y_top - size / 8)
        spread = rng.uniform(size / 20, size / 8)
        weight = rng.uniform(0.5, 1.0)
        blob = np.exp(-((ys[:, None] - cy) ** 2) / (2 * spread**2)) * np.exp(-((xs[None, :] - cx) ** 2) / (2 * spread**2))
        density += weight * blob / blob.sum()
    angle = rng.uniform(0, np.pi)
    through_x, through_y = rng.uniform(x_left + size / 4, x_right - size / 4), rng.uniform(y_bottom + size / 4, y_top - size / 4)
    distance = np.abs(-(xs[None, :] - through_x) * np.sin(angle) + (ys[:, None] - through_y) * np.cos(angle))
    trail = np.exp(-((distance / (size / 50)) ** 2) / 2)
    density = density / density.sum() * 0.6 + trail / trail.sum() * 0.35
    density += 0.05 / grid.n_cells
    return density / density.sum()
