"""The search-and-rescue field: a square of ground cells, people lying on it, box obstacles.

Frame: field-centred, metres. x and y span [-size/2, size/2], z is altitude above ground.
Grid: ``cells_per_side`` x ``cells_per_side`` square cells of ``cell_size_m``; a map is a flat
array of length n = cells_per_side**2 in row-major order ``index = iy * cells_per_side + ix``
(reshape to (ny, nx) for images, row iy runs along +y).

People are 0.75 m x 2 m rectangles at a random position and heading; a cell belongs to a person
when the rectangle covers any of its 10 x 10 sample points, which gives 7.7 cells per person on
average on a 0.75 m grid (53.6 +- 2.6 cells for 7 people over 100 seeds; the anchors have 54). Obstacles are axis-aligned boxes standing on
the ground; they block flight and hide the ground beneath and behind them from the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from attend.action.errors import ActionInputError

DEFAULT_START_POSE_M = (10.0, 0.0, 7.0)


@dataclass(frozen=True)
class Obstacle:
    """An axis-aligned box on the ground: centre (``x_m``, ``y_m``) [m], footprint ``width_m`` (x) by
    ``depth_m`` (y) and ``height_m`` [m]."""

    x_m: float
    y_m: float
    width_m: float = 4.0
    depth_m: float = 4.0
    height_m: float = 13.0

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """(x_min, x_max, y_min, y_max, z_min, z_max) in m."""
        return (
            self.x_m - self.width_m / 2,
            self.x_m + self.width_m / 2,
            self.y_m - self.depth_m / 2,
            self.y_m + self.depth_m / 2,
            0.0,
            self.height_m,
        )


@dataclass(frozen=True)
class Person:
    """A person lying on the ground: a rectangle of ``length_m`` x ``width_m`` centred at
    (``x_m``, ``y_m``) [m], long axis at ``heading_rad`` from +x."""

    x_m: float
    y_m: float
    heading_rad: float
    length_m: float = 2.0
    width_m: float = 0.75

    def corners(self) -> np.ndarray:
        """The 4 corners, shape (4, 2), in m."""
        c, s = np.cos(self.heading_rad), np.sin(self.heading_rad)
        along = np.array([c, s]) * self.length_m / 2
        across = np.array([-s, c]) * self.width_m / 2
        centre = np.array([self.x_m, self.y_m])
        return np.array(
            [centre + along + across, centre - along + across, centre - along - across, centre + along - across]
        )


@dataclass(frozen=True)
class Grid:
    """A square grid of ``cells_per_side``**2 cells of ``cell_size_m``, centred on the origin."""

    cells_per_side: int = 40
    cell_size_m: float = 0.75

    @property
    def size_m(self) -> float:
        return self.cells_per_side * self.cell_size_m

    @property
    def n_cells(self) -> int:
        return self.cells_per_side**2

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) for images of a flat map."""
        return (self.cells_per_side, self.cells_per_side)

    def cell_centres(self) -> np.ndarray:
        """Centres of all cells, shape (n, 2), in m, flat index iy * nx + ix."""
        ticks = -self.size_m / 2 + (np.arange(self.cells_per_side) + 0.5) * self.cell_size_m
        yy, xx = np.meshgrid(ticks, ticks, indexing="ij")
        return np.column_stack([xx.ravel(), yy.ravel()])

    def cell_indices(self) -> np.ndarray:
        """Integer (ix, iy) of all cells, shape (n, 2)."""
        iy, ix = np.meshgrid(np.arange(self.cells_per_side), np.arange(self.cells_per_side), indexing="ij")
        return np.column_stack([ix.ravel(), iy.ravel()])

    def contains(self, x_m: float, y_m: float) -> bool:
        """Whether the point (x_m, y_m) [m] lies in the field."""
        half = self.size_m / 2
        return bool(-half <= x_m <= half and -half <= y_m <= half)


@dataclass(frozen=True)
class SearchField:
    """Ground truth of one search mission.

    grid: the map grid; people: the people on the ground; obstacles: box obstacles;
    start_pose_m: (x, y, z) take-off pose in m; altitude_limits_m: (min, max) flight altitude in m;
    person_cells: the cell indices of each person (filled from the people when empty).
    """

    grid: Grid
    people: tuple[Person, ...]
    obstacles: tuple[Obstacle, ...] = ()
    start_pose_m: tuple[float, float, float] = DEFAULT_START_POSE_M
    altitude_limits_m: tuple[float, float] = (2.0, 26.0)
    person_cells: tuple[np.ndarray, ...] = field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        validate_altitude_limits(self.altitude_limits_m)
        validate_obstacles(self.obstacles, self.grid)
        validate_pose(self.start_pose_m, self.grid, self.altitude_limits_m, "start_pose_m")
        if not self.person_cells:
            object.__setattr__(self, "person_cells", tuple(person_cell_indices(p, self.grid) for p in self.people))

    @property
    def truth(self) -> np.ndarray:
        """Occupancy ground truth, flat (n,): 1 on person cells, 0 elsewhere."""
        occupancy = np.zeros(self.grid.n_cells)
        for cells in self.person_cells:
            occupancy[cells] = 1.0
        return occupancy

    def obstacle_cells(self) -> np.ndarray:
        """Boolean (n,) mask of cells whose centre lies under an obstacle."""
        centres = self.grid.cell_centres()
        under = np.zeros(self.grid.n_cells, dtype=bool)
        for box in self.obstacles:
            x0, x1, y0, y1, _, _ = box.bounds
            under |= (centres[:, 0] >= x0) & (centres[:, 0] <= x1) & (centres[:, 1] >= y0) & (centres[:, 1] <= y1)
        return under


def validate_altitude_limits(limits: Sequence[float]) -> tuple[float, float]:
    """``limits`` = (min, max) flight altitudes [m] as floats, checked finite with 0 < min < max;
    errors name altitude_limits_m."""
    try:
        low, high = (float(v) for v in limits)
    except (TypeError, ValueError):
        raise ActionInputError(f"altitude_limits_m: expected (min, max) in m, got {limits!r}") from None
    if not (np.isfinite(low) and np.isfinite(high)) or low <= 0 or low >= high:
        raise ActionInputError(
            f"altitude_limits_m: expected 0 < min < max in m, got min={low!r}, max={high!r}"
        )
    return low, high


def validate_pose(pose: Sequence[float], grid: Grid, altitude_limits_m: Sequence[float], name: str) -> np.ndarray:
    """Check that ``pose`` = (x, y, z) m lies inside the field and the altitude limits; returns it as (3,).

    grid: the field's :class:`Grid` (x, y within +-size_m / 2); altitude_limits_m: (min, max)
    altitudes [m] for z; name: the argument's name, used in error messages."""
    try:
        xyz = np.asarray(pose, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise ActionInputError(f"{name}: expected (x, y, z) in m, got {pose!r}") from None
    half = grid.size_m / 2
    if not np.all(np.isfinite(xyz)):
        raise ActionInputError(f"{name}: expected finite (x, y, z) in m, got {tuple(xyz)}")
    if abs(xyz[0]) > half or abs(xyz[1]) > half:
        raise ActionInputError(
            f"{name}: expected x and y inside the field [-{half:g}, {half:g}] m, got ({xyz[0]:g}, {xyz[1]:g})"
        )
    low, high = altitude_limits_m
    if not low <= xyz[2] <= high:
        raise ActionInputError(f"{name}: expected altitude z in [{low:g}, {high:g}] m, got {xyz[2]:g}")
    return xyz


def validate_obstacles(obstacles: Sequence[Obstacle], grid: Grid) -> None:
    """Check that each of ``obstacles`` is an :class:`Obstacle` with positive width, depth and
    height [m] whose footprint lies inside the field of ``grid`` (within +-size_m / 2)."""
    half = grid.size_m / 2
    for k, box in enumerate(obstacles):
        if not isinstance(box, Obstacle):
            raise ActionInputError(f"obstacles[{k}]: expected an Obstacle, got {type(box).__name__}")
        x0, x1, y0, y1, _, z1 = box.bounds
        if min(box.width_m, box.depth_m, box.height_m) <= 0:
            raise ActionInputError(f"obstacles[{k}]: expected positive width, depth and height in m, got {box}")
        if x0 < -half or x1 > half or y0 < -half or y1 > half:
            raise ActionInputError(
                f"obstacles[{k}]: expected the box inside the field [-{half:g}, {half:g}] m, "
                f"got x in [{x0:g}, {x1:g}], y in [{y0:g}, {y1:g}]"
            )


def person_cell_indices(person: Person, grid: Grid, samples_per_side: int = 10) -> np.ndarray:
    """Flat indices of the cells the person covers: a cell is occupied when any of its
    ``samples_per_side``**2 evenly spaced sample points lies on the rectangle (overlap of
    about 1 % of the cell or more; slivers below that are ignored). person: the rectangle (centre,
    length, width [m], heading [rad]); grid: the field's :class:`Grid`."""
    centres = grid.cell_centres()
    reach = np.hypot(person.length_m, person.width_m) / 2 + grid.cell_size_m
    near = np.flatnonzero(np.hypot(centres[:, 0] - person.x_m, centres[:, 1] - person.y_m) <= reach)
    offsets = ((np.arange(samples_per_side) + 0.5) / samples_per_side - 0.5) * grid.cell_size_m
    dx = centres[near, 0, None, None] + offsets[None, :, None] - person.x_m
    dy = centres[near, 1, None, None] + offsets[None, None, :] - person.y_m
    c, s = np.cos(person.heading_rad), np.sin(person.heading_rad)
    along, across = dx * c + dy * s, -dx * s + dy * c
    on_person = (np.abs(along) <= person.length_m / 2) & (np.abs(across) <= person.width_m / 2)
    return np.sort(near[on_person.any(axis=(1, 2))])


def preset_obstacles(name: str) -> tuple[Obstacle, ...]:
    """The obstacle layout called ``name``: "none"; "buildings": a 26 m tower at the centre and a
    13 m block."""
    if name == "none":
        return ()
    if name == "buildings":
        return (Obstacle(0.0, 0.0, 4.0, 4.0, 26.0), Obstacle(-8.0, 8.0, 4.0, 4.0, 13.0))
    raise ActionInputError(f"obstacles: expected 'none' or 'buildings', got {name!r}")


def make_field(
    seed: int,
    n_people: int = 7,
    obstacles: Sequence[Obstacle] | str = "none",
    people_region: str = "all",
    grid: Grid | None = None,
    start_pose_m: Sequence[float] = DEFAULT_START_POSE_M,
    altitude_limits_m: Sequence[float] = (2.0, 26.0),
    min_separation_m: float = 2.5,
) -> SearchField:
    """Place ``n_people`` people by seed (uniform position and heading, no overlap with each other
    or with obstacles, ``min_separation_m`` between centres).

    seed: seeds the placement; n_people: how many people; obstacles: boxes, or a preset name
    ("none", "buildings"); people_region: "all" (whole field) or "lower_half" (y < 0, the seed's
    Fig. 9 case); grid: the map grid (default 40 x 40 cells of 0.75 m); start_pose_m: take-off
    (x, y, z) [m]; altitude_limits_m: (min, max) flight altitude [m]; min_separation_m: least
    distance between people's centres [m].
    """
    grid = grid or Grid()
    if isinstance(obstacles, str):
        obstacles = preset_obstacles(obstacles)
    obstacles = tuple(obstacles)
    validate_obstacles(obstacles, grid)
    if people_region not in ("all", "lower_half"):
        raise ActionInputError(f"people_region: expected 'all' or 'lower_half', got {people_region!r}")
    if int(n_people) != n_people or n_people < 0:
        raise ActionInputError(f"n_people: expected a non-negative integer, got {n_people!r}")
    rng = np.random.default_rng(seed)
    half = grid.size_m / 2 - 1.2
    y_low, y_high = (-half, half) if people_region == "all" else (-half, -1.0)
    people: list[Person] = []
    for _ in range(20000):
        if len(people) == n_people:
            break
        x, y = rng.uniform(-half, half), rng.uniform(y_low, y_high)
        if any(np.hypot(x - p.x_m, y - p.y_m) < min_separation_m for p in people):
            continue
        if any(_near_box(x, y, box, margin=1.5) for box in obstacles):
            continue
        people.append(Person(x, y, rng.uniform(0, np.pi)))
    if len(people) < n_people:
        raise ActionInputError(f"n_people: could not place {n_people} people without overlap in the field")
    return SearchField(
        grid=grid,
        people=tuple(people),
        obstacles=obstacles,
        start_pose_m=tuple(float(v) for v in start_pose_m),
        altitude_limits_m=tuple(float(v) for v in altitude_limits_m),
    )


def _near_box(x: float, y: float, box: Obstacle, margin: float) -> bool:
    x0, x1, y0, y1, _, _ = box.bounds
    return x0 - margin <= x <= x1 + margin and y0 - margin <= y <= y1 + margin
