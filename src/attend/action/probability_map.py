"""Probability map of the scalable search: per cell, the expected number of people whose centre lies in it.

Grid: ``nx`` x ``ny`` square cells of side s [m], cell (ix, iy) spans
[x0 + ix s, x0 + (ix + 1) s] x [y0 + iy s, y0 + (iy + 1) s] with (x0, y0) the grid's origin (the
lower-left corner); maps are arrays (ny, nx) and the flat index of a cell is iy * nx + ix.

Belief: D_c = the expected number of people whose centre lies in cell c (an intensity, as in
a first-moment filter, but updated with at most one person per neighbourhood: below). A cell's reported probability p_c is its expected count D_c; p_c is P(a person's centre lies in
c) when a cell holds at most one person, i.e. when cells are small against the spacing of
people (then P(c holds someone) = E[people in c]). p_c is stored as log-odds
l_c = log(p_c / (1 - p_c)), clipped to p_c in [9e-14, 1 - 1e-12] (l in [-30, 27.6]). Cells that
cannot hold anybody (outside the search area, under a roof) are not searchable: p = 0,
l = -inf, never updated.

Update by one image taken at altitude h and speed v, detection probability pd = pd(h, v),
clutter density kappa = kappa(h) [1/m^2], position error sigma = sigma(h) [m], reported
positions d_1 .. d_k (:mod:`attend.action.detection`). For every searchable cell c in view:

    D_c <- D_c [ (1 - pd) + pd sum_j f_jc / kappa_jc ] / [ (1 - pd M_c) + pd sum_j F_jc / kappa_jc ],

    M_c = sum of D over N(c),      F_jc = sum_{c' in N(c)} f_jc' D_c',
    kappa_jc = kappa + pd sum_{c' in view, not in N(c)} f_jc' D_c',

    f_jc = f(d_j | c) = (1 / a) * integral over the cell of N(d_j; u, sigma^2 I) du
         = g_x g_y,   g(t) = [Phi((t_hi - t) / sigma) - Phi((t_lo - t) / sigma)] / s,

with D from before the image, N(c) the cells in view within k cells of c in x and in y (a square
of 2k + 1 cells a side, k = ceil(max(target radius, sigma) / s)) and M_c capped at 1 - 1e-9.
This is the exact Bayes update of one person who is in N(c) with probability M_c, spread there
as D / M_c, missed with probability 1 - pd or reported once at their centre (uniform in their
cell of area a = s^2) plus N(0, sigma^2 I), every other detection coming from a Poisson field:
the clutter, density kappa, plus the people the map expects in view outside N(c). So each
neighbourhood stands for at most one person: its mass never exceeds 1 through repeated
detections (they share the person among its cells), an image of nothing scales it by
(1 - pd) / (1 - pd M) (a person known to be there, M = 1, stays there), and a detection far from
every other person moves at most one expected person. For one searchable cell alone in its
neighbourhood it is Bernoulli Bayes, odds *= (1 - pd) + pd sum_j f_jc / kappa_jc; with diffuse
D (M << 1) it is the first-moment (PHD, Poisson) update
D_c <- D_c [(1 - pd) + sum_j pd f_jc / (kappa + pd sum_{c' in view} f_jc' D_c')].
The PHD update alone is not calibrated over a mission of static people: it treats a cluster
of mass 1 as Poisson, so a detection lifts it to about 2 - pd and a miss drops it to (1 - pd)
whatever came before. The limit of this update: two people closer than the neighbourhood share
the mass of one (targets then report one of them). The neighbourhood is the target disc's square
(or sigma's, where sigma is larger): with 2 sigma instead, people 2-7 m apart were explained away
and P(all found) was over-confident (docs/search.md). Terms run only on the cells within reach r
of each detection (widened by k cells for F), r being the distance beyond which
pd f < 1e-3 (1 - pd) kappa; the cost of an update is O(cells in view + detections x cells within
reach). kappa is floored at 1e-6 per m^2 (one false detection per km^2) so that a clutter-free
model keeps every ratio finite.

Targets: the mass of a disc of radius r around a cell, m_c = sum of p over the cells whose
centres lie within r of c's centre, the expected number of people in the disc; a target is a
local maximum (3 x 3) of m with m >= the threshold. Targets are taken greedily, largest mass
first, each claiming its disc's cells, a later target's mass counting only cells not yet claimed
(so reported targets never share a cell); a target's position is the probability-weighted
centroid of its cells. P(all found), the probability that nobody lies outside the targets, is
the product over the cells outside every target of (1 - p_c) (cells independent; within 0.002
of exp(-sum p_c) there on simulated missions, and of lower Brier score).
A disc whose cells are all below p = 1e-3 cannot reach a threshold of 0.5 unless it holds 500
cells, so the mass is evaluated only around the cells above 1e-3 (in each 64 x 64-cell tile, the
box bounding them, widened by a disc radius): the cost grows with those cells, not with the map.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from attend.action.log_odds import logistic, logit, normal_cdf

from attend.action.camera import Camera
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError

#: Least searchable log-odds (p = 9e-14).
LOG_ODDS_LIMIT = 30.0
#: Largest p (expected people) a cell holds.
MAX_CELL_PROBABILITY = 1.0 - 1e-12
#: Largest searchable log-odds, logit(MAX_CELL_PROBABILITY) = 27.6.
LOG_ODDS_MAX = float(np.log(MAX_CELL_PROBABILITY) - np.log1p(-MAX_CELL_PROBABILITY))
#: Least clutter density [1/m^2] used in the update (keeps the likelihood ratio finite).
MIN_CLUTTER_DENSITY_PER_M2 = 1e-6
#: Largest probability a prior gives a cell.
MAX_PRIOR_PROBABILITY = 0.5
#: Cells with p above this are the candidate centres of targets.
TARGET_PROBABILITY_FLOOR = 1e-3
#: Largest mass of a neighbourhood in the update (it stands for at most one person).
MAX_NEIGHBOURHOOD_MASS = 1.0 - 1e-9
#: Relative size of the omitted tail of a detection's likelihood ratio (module docstring).
DETECTION_TAIL_TOLERANCE = 1e-3
_TILE_CELLS = 64


@dataclass(frozen=True)
class MapGrid:
    """``nx`` x ``ny`` square cells of ``cell_size_m`` [m]; ``origin_m`` (x0, y0) [m] is the
    lower-left corner of cell (0, 0). Arrays of the map are (ny, nx), flat index iy * nx + ix."""

    nx: int
    ny: int
    cell_size_m: float
    origin_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("nx", "ny"):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)) or int(value) != value or value < 1:
                raise ActionInputError(f"{name}: expected a whole number of cells >= 1, got {value!r}")
            object.__setattr__(self, name, int(value))
        size = self.cell_size_m
        if isinstance(size, (bool, np.bool_)) or not np.isfinite(size) or size <= 0:
            raise ActionInputError(f"cell_size_m: expected a cell side > 0 m, got {size!r}")
        object.__setattr__(self, "cell_size_m", float(size))
        try:
            x0, y0 = (float(v) for v in self.origin_m)
        except (TypeError, ValueError):
            raise ActionInputError(f"origin_m: expected (x0, y0) in m, got {self.origin_m!r}") from None
        if not (np.isfinite(x0) and np.isfinite(y0)):
            raise ActionInputError(f"origin_m: expected finite (x0, y0) in m, got {self.origin_m!r}")
        object.__setattr__(self, "origin_m", (x0, y0))

    @classmethod
    def square(cls, size_m: float, cell_size_m: float) -> "MapGrid":
        """A square grid centred on the origin, like :class:`attend.action.field.Grid`:
        n = round(size_m / cell_size_m) cells per side (at least 1), spanning +-n s / 2.

        size_m: side of the area [m]; cell_size_m: s [m]."""
        if not (np.isfinite(size_m) and size_m > 0):
            raise ActionInputError(f"size_m: expected a side > 0 m, got {size_m!r}")
        if not (np.isfinite(cell_size_m) and cell_size_m > 0):
            raise ActionInputError(f"cell_size_m: expected a cell side > 0 m, got {cell_size_m!r}")
        n = max(1, int(round(size_m / cell_size_m)))
        half = n * cell_size_m / 2
        return cls(n, n, float(cell_size_m), (-half, -half))

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return (self.ny, self.nx)

    @property
    def n_cells(self) -> int:
        return self.nx * self.ny

    @property
    def cell_area_m2(self) -> float:
        return self.cell_size_m**2

    @property
    def centres_x(self) -> np.ndarray:
        """x of the cell centres of each column [m], (nx,)."""
        return self.origin_m[0] + (np.arange(self.nx) + 0.5) * self.cell_size_m

    @property
    def centres_y(self) -> np.ndarray:
        """y of the cell centres of each row [m], (ny,)."""
        return self.origin_m[1] + (np.arange(self.ny) + 0.5) * self.cell_size_m

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) [m], the grid's edges."""
        x0, y0 = self.origin_m
        return (x0, x0 + self.nx * self.cell_size_m, y0, y0 + self.ny * self.cell_size_m)

    def contains(self, x_m, y_m) -> np.ndarray:
        """Whether each point (x_m, y_m) [m] lies on the grid (edges included), bool array."""
        x0, x1, y0, y1 = self.extent_m
        x, y = np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float)
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    def cell_of(self, x_m, y_m) -> tuple[np.ndarray, np.ndarray]:
        """(ix, iy) int arrays of the cells holding the points (x_m, y_m) [m]; a point on the
        upper edge of the grid belongs to the last cell, a point off the grid gets ix = iy = -1."""
        x, y = np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float)
        inside = self.contains(x, y)
        x0, y0 = self.origin_m
        with np.errstate(invalid="ignore"):
            ix = np.minimum(np.floor((x - x0) / self.cell_size_m), self.nx - 1)
            iy = np.minimum(np.floor((y - y0) / self.cell_size_m), self.ny - 1)
        return np.where(inside, ix, -1).astype(int), np.where(inside, iy, -1).astype(int)

    def window(self, x_m: float, y_m: float, width_x_m: float, width_y_m: float) -> tuple[slice, slice]:
        """(rows, cols) slices of the cells whose centres lie in the rectangle of ``width_x_m``
        by ``width_y_m`` [m] centred at (``x_m``, ``y_m``) [m] (edges included), clipped to the
        grid; either slice may be empty. Rows run along y, columns along x."""
        if not (np.isfinite(width_x_m) and np.isfinite(width_y_m)) or width_x_m < 0 or width_y_m < 0:
            raise ActionInputError(f"width_x_m, width_y_m: expected widths >= 0 m, got {width_x_m!r}, {width_y_m!r}")
        if not (np.isfinite(x_m) and np.isfinite(y_m)):
            raise ActionInputError(f"x_m, y_m: expected a finite centre in m, got ({x_m!r}, {y_m!r})")
        x0, y0 = self.origin_m
        cols = _centre_range(float(x_m) - x0, float(width_x_m), self.cell_size_m, self.nx)
        rows = _centre_range(float(y_m) - y0, float(width_y_m), self.cell_size_m, self.ny)
        return rows, cols

    def window_centres(self, window: tuple[slice, slice]) -> tuple[np.ndarray, np.ndarray]:
        """(x of the window's columns (c,), y of its rows (r,)) [m]; window: (rows, cols) slices."""
        rows, cols = window
        return self.centres_x[cols], self.centres_y[rows]


def _centre_range(offset_m: float, width_m: float, cell_m: float, n: int) -> slice:
    """Slice of the indices i in [0, n) with (i + 0.5) cell_m within offset_m +- width_m / 2."""
    tolerance = 1e-9
    low = int(np.ceil((offset_m - width_m / 2) / cell_m - 0.5 - tolerance))
    high = int(np.floor((offset_m + width_m / 2) / cell_m - 0.5 + tolerance))
    start = min(max(low, 0), n)
    stop = max(min(high + 1, n), start)
    return slice(start, stop)


@dataclass(frozen=True)
class ImageObservation:
    """One processed image.

    pose_m: camera (x, y, z) [m]; time_s: when it was taken [s]; speed_m_s: ground speed then
    [m/s]; window: (rows, cols) slices of the footprint cells (:meth:`MapGrid.window` of the
    camera footprint); visible: bool (rows, cols) over the window, True where the ground is in
    line of sight; detections_m: (k, 2) reported person positions (x, y) [m]; uav: which UAV.
    """

    pose_m: np.ndarray
    time_s: float
    speed_m_s: float
    window: tuple[slice, slice]
    visible: np.ndarray
    detections_m: np.ndarray
    uav: int = 0

    def __post_init__(self) -> None:
        pose = np.asarray(self.pose_m, dtype=float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ActionInputError(f"pose_m: expected a finite (x, y, z) in m, got {self.pose_m!r}")
        object.__setattr__(self, "pose_m", pose)
        rows, cols = self.window
        shape = (rows.stop - rows.start, cols.stop - cols.start)
        visible = np.asarray(self.visible, dtype=bool)
        if visible.shape != shape:
            raise ActionInputError(f"visible: expected a bool array of the window's shape {shape}, got {visible.shape}")
        object.__setattr__(self, "visible", visible)
        detections = np.asarray(self.detections_m, dtype=float).reshape(-1, 2) if np.size(self.detections_m) else np.zeros((0, 2))
        if not np.all(np.isfinite(detections)):
            raise ActionInputError("detections_m: expected finite (x, y) positions in m")
        object.__setattr__(self, "detections_m", detections)


class ProbabilityMap:
    """Each cell: p = the expected number of people whose centre lies in it (P(a person's centre
    lies in the cell) when cells are small against the spacing of people), stored as log-odds
    l = log(p / (1 - p)) (module docstring for the update and the targets).

    grid: the :class:`MapGrid`; log_odds: (ny, nx) float64; searchable: (ny, nx) bool, False
    outside the area or under a roof (p = 0, log-odds -inf, never updated; read-only, shared
    by copies).
    """

    def __init__(self, grid: MapGrid, log_odds: np.ndarray, searchable: np.ndarray | None = None) -> None:
        if not isinstance(grid, MapGrid):
            raise ActionInputError(f"grid: expected a MapGrid, got {type(grid).__name__}")
        self.grid = grid
        self.searchable = _searchable_mask(grid, searchable)
        values = np.array(log_odds, dtype=float)
        if values.shape != grid.shape:
            raise ActionInputError(f"log_odds: expected an array of shape {grid.shape}, got {values.shape}")
        if np.any(np.isnan(values)):
            raise ActionInputError("log_odds: expected no NaN")
        values[self.searchable] = np.clip(values[self.searchable], -LOG_ODDS_LIMIT, LOG_ODDS_MAX)
        values[~self.searchable] = -np.inf
        self.log_odds = values

    @classmethod
    def uniform(cls, grid: MapGrid, expected_people: float, searchable: np.ndarray | None = None) -> "ProbabilityMap":
        """p = expected_people / (number of searchable cells) on every searchable cell.

        grid: the map grid; expected_people: the expected number of people E (> 0, at most half
        the searchable cells); searchable: (ny, nx) bool (None: every cell)."""
        return cls.from_prior_map(grid, np.ones(grid.shape), expected_people, searchable)

    @classmethod
    def from_prior_map(
        cls, grid: MapGrid, relative_likelihood: np.ndarray, expected_people: float, searchable: np.ndarray | None = None
    ) -> "ProbabilityMap":
        """p_c = min(s r_c, 1/2) on searchable cells, with the scale s chosen so that sum p_c = E
        (the cells a plain proportional prior would push above 1/2 are held at 1/2 and their
        excess spread over the others in proportion to r).

        grid: the map grid; relative_likelihood: r (ny, nx), finite, >= 0, not 0 on every
        searchable cell (values on cells that are not searchable are ignored); expected_people:
        E > 0, below half the number of searchable cells with r > 0; searchable: (ny, nx) bool
        (None: every cell). Searchable cells with r = 0 get the least log-odds, -30."""
        mask = _searchable_mask(grid, searchable)
        r = np.asarray(relative_likelihood, dtype=float)
        if r.shape != grid.shape:
            raise ActionInputError(f"relative_likelihood: expected an array of shape {grid.shape}, got {r.shape}")
        if not np.all(np.isfinite(r)) or np.any(r < 0):
            raise ActionInputError("relative_likelihood: expected finite values >= 0")
        weights = np.where(mask, r, 0.0)
        positive = weights[weights > 0]
        if len(positive) == 0:
            raise ActionInputError("relative_likelihood: expected a value > 0 on at least one searchable cell")
        if isinstance(expected_people, (bool, np.bool_)) or not np.isfinite(expected_people) or expected_people <= 0:
            raise ActionInputError(f"expected_people: expected a number > 0, got {expected_people!r}")
        if expected_people >= MAX_PRIOR_PROBABILITY * len(positive):
            raise ActionInputError(
                f"expected_people: expected fewer than {MAX_PRIOR_PROBABILITY:g} x {len(positive)} searchable cells "
                f"with a likelihood > 0, got {expected_people!r}"
            )
        scale = _capped_scale(positive, float(expected_people), MAX_PRIOR_PROBABILITY)
        p = np.minimum(scale * weights, MAX_PRIOR_PROBABILITY)
        with np.errstate(divide="ignore"):
            log_odds = np.log(p) - np.log1p(-p)
        log_odds[mask & (weights == 0)] = -LOG_ODDS_LIMIT
        return cls(grid, log_odds, mask)

    @property
    def probability(self) -> np.ndarray:
        """p (ny, nx) = 1 / (1 + exp(-l)); 0 on cells that are not searchable."""
        return logistic(self.log_odds)

    def copy(self) -> "ProbabilityMap":
        """An independent copy (the read-only searchable mask is shared)."""
        twin = object.__new__(ProbabilityMap)
        twin.grid, twin.searchable, twin.log_odds = self.grid, self.searchable, self.log_odds.copy()
        return twin

    def expected_people(self) -> float:
        """sum_c p_c, the expected number of people on the map (the mean of the Poisson count)."""
        return float(logistic(self.log_odds).sum())

    def update(self, image: ImageObservation, model: DetectionModel, camera: Camera) -> None:
        """Fuse one image (module docstring): on the searchable cells c the image sees,
        D_c <- D_c [(1 - pd) + pd sum_j f_jc / kappa_jc] / [(1 - pd M_c) + pd sum_j F_jc / kappa_jc].

        image: the image (pose, speed, footprint window, visibility, detections); model: the
        detector (pd, kappa, sigma); camera: its footprint (for kappa)."""
        rows, cols = image.window
        mask = image.visible & self.searchable[rows, cols]
        if not mask.any():
            return
        altitude = float(image.pose_m[2])
        pd = float(model.detection_probability(altitude, image.speed_m_s))
        sigma = float(model.position_error_m(altitude))
        half = self.neighbourhood_cells(sigma)
        view = self.log_odds[rows, cols]
        density = np.where(mask, logistic(view), 0.0)
        mass = np.minimum(_box_sum(density, half), MAX_NEIGHBOURHOOD_MASS)
        numerator = np.full(mask.shape, 1.0 - pd)
        denominator = 1.0 - pd * mass
        if len(image.detections_m) and pd > 0:
            kappa = max(float(model.clutter_density_per_m2(altitude, camera)), MIN_CLUTTER_DENSITY_PER_M2)
            self._add_detection_terms(
                image.detections_m, (rows, cols), mask, density, half, sigma, pd, kappa, numerator, denominator
            )
        view[mask] = _scaled_log_odds(view[mask], numerator[mask] / denominator[mask])

    def neighbourhood_cells(self, sigma_m: float) -> int:
        """k, the half-width [cells] of the square neighbourhood taken as one person in the
        update: ceil(max(target radius, sigma) / s); sigma_m: the position error [m]."""
        return max(1, int(np.ceil(max(self.default_target_radius_m(), sigma_m) / self.grid.cell_size_m - 1e-9)))

    def _add_detection_terms(
        self, detections_m: np.ndarray, window: tuple[slice, slice], in_view: np.ndarray, density: np.ndarray,
        half: int, sigma: float, pd: float, kappa: float, numerator: np.ndarray, denominator: np.ndarray,
    ) -> None:
        """Add pd f_jc / kappa_jc to ``numerator`` and pd F_jc / kappa_jc to ``denominator`` (window
        arrays; module docstring), each detection on the cells within its reach (widened by the
        neighbourhood half-width ``half`` for F) only; D (``density``) is from before the image."""
        rows, cols = window
        s = self.grid.cell_size_m
        peak = 1.0 / (2 * np.pi * sigma**2)
        tail = DETECTION_TAIL_TOLERANCE * max(1 - pd, 1e-12) * kappa / pd
        reach = sigma * np.sqrt(2 * max(np.log(peak / tail), 8.0)) + s + half * s
        x0, y0 = self.grid.origin_m
        for dx, dy in detections_m:
            near_rows, near_cols = self.grid.window(dx, dy, 2 * reach, 2 * reach)
            r0, r1 = max(near_rows.start, rows.start), min(near_rows.stop, rows.stop)
            c0, c1 = max(near_cols.start, cols.start), min(near_cols.stop, cols.stop)
            if r0 >= r1 or c0 >= c1:
                continue
            local = (slice(r0 - rows.start, r1 - rows.start), slice(c0 - cols.start, c1 - cols.start))
            g_x = np.diff(normal_cdf((x0 + np.arange(c0, c1 + 1) * s - dx) / sigma)) / s
            g_y = np.diff(normal_cdf((y0 + np.arange(r0, r1 + 1) * s - dy) / sigma)) / s
            f = g_y[:, None] * g_x[None, :] * in_view[local]
            weighted = f * density[local]
            near_mass = _box_sum(weighted, half)
            others = kappa + np.maximum(pd * (float(weighted.sum()) - near_mass), 0.0)
            numerator[local] += pd * f / others
            denominator[local] += pd * near_mass / others

    def expected_no_detection_update(
        self,
        image_windows: Sequence[tuple[slice, slice]],
        altitudes_m: Sequence[float],
        model: DetectionModel,
        camera: Camera,
        speeds_m_s: Sequence[float] | None = None,
        visible: Sequence[np.ndarray | None] | None = None,
    ) -> None:
        """The update as if every image saw nothing, image after image: D_c <- D_c (1 - pd) /
        (1 - pd M_c) (pd = pd(h_i, v_i), M_c as in :meth:`update`) on the searchable cells of each
        window (used by planners to book images other UAVs will take).

        image_windows: (rows, cols) slices per image; altitudes_m: h_i [m] per image; model:
        the detector (pd, and sigma for the neighbourhood); camera: unused (kept for the signature of
        :meth:`update`); speeds_m_s:
        v_i [m/s] per image (None: hovering); visible: per image a bool (rows, cols) mask of
        the ground in view, or None for the whole window (None: every window whole)."""
        windows = list(image_windows)
        altitudes = np.asarray(altitudes_m, dtype=float).reshape(-1)
        if len(altitudes) != len(windows):
            raise ActionInputError(
                f"altitudes_m: expected one altitude per window ({len(windows)}), got {len(altitudes)}"
            )
        speeds = np.zeros(len(windows)) if speeds_m_s is None else np.asarray(speeds_m_s, dtype=float).reshape(-1)
        if len(speeds) != len(windows):
            raise ActionInputError(f"speeds_m_s: expected one speed per window ({len(windows)}), got {len(speeds)}")
        masks = [None] * len(windows) if visible is None else list(visible)
        if len(masks) != len(windows):
            raise ActionInputError(f"visible: expected one mask (or None) per window ({len(windows)}), got {len(masks)}")
        pd = np.asarray(model.detection_probability(altitudes, speeds), dtype=float)
        sigmas = np.asarray(model.position_error_m(altitudes), dtype=float)
        for (rows, cols), chance, sigma, seen in zip(windows, pd, sigmas, masks):
            mask = self.searchable[rows, cols]
            if seen is not None:
                mask = mask & np.asarray(seen, dtype=bool)
            if not mask.any():
                continue
            view = self.log_odds[rows, cols]
            density = np.where(mask, logistic(view), 0.0)
            mass = np.minimum(_box_sum(density, self.neighbourhood_cells(float(sigma))), MAX_NEIGHBOURHOOD_MASS)
            factor = (1.0 - chance) / (1.0 - chance * mass)
            view[mask] = _scaled_log_odds(view[mask], factor[mask])

    def default_target_radius_m(self) -> float:
        """max(1.5 m, 2 cells) [m], the default disc radius of :meth:`targets`."""
        return max(1.5, 2 * self.grid.cell_size_m)

    def target_discs(
        self, threshold: float = 0.5, radius_m: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """Targets with the cells they claim (module docstring): positions (k, 2) [m], masses
        (k,), and per target the flat indices of its cells.

        threshold: least mass of a target (> 0); radius_m: disc radius [m] (None:
        :meth:`default_target_radius_m`)."""
        radius = self._target_radius(radius_m)
        if not (np.isfinite(threshold) and threshold > 0):
            raise ActionInputError(f"threshold: expected a mass > 0, got {threshold!r}")
        candidates = self.log_odds > logit(TARGET_PROBABILITY_FLOOR)
        rows_c, cols_c = np.nonzero(candidates)
        empty = (np.zeros((0, 2)), np.zeros(0), [])
        if len(rows_c) == 0:
            return empty
        disc_dy, disc_dx = _disc_offsets(radius / self.grid.cell_size_m)
        reach = int(np.max(np.abs(disc_dx)))
        kernel = np.zeros((2 * reach + 1, 2 * reach + 1))
        kernel[disc_dy + reach, disc_dx + reach] = 1.0
        ny, nx = self.grid.shape
        tiles_per_row = (nx + _TILE_CELLS - 1) // _TILE_CELLS
        tile_of = (rows_c // _TILE_CELLS) * tiles_per_row + cols_c // _TILE_CELLS
        order = np.argsort(tile_of, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(tile_of[order]) != 0])
        boxes = np.column_stack([
            np.minimum.reduceat(rows_c[order], starts), np.maximum.reduceat(rows_c[order], starts),
            np.minimum.reduceat(cols_c[order], starts), np.maximum.reduceat(cols_c[order], starts),
        ])
        peaks_found: dict[tuple[int, int], float] = {}
        for low_row, high_row, low_col, high_col in boxes:
            # peaks may lie up to a disc away from the candidates: look that far around them
            r0, r1 = max(low_row - reach - 1, 0), min(high_row + reach + 2, ny)
            c0, c1 = max(low_col - reach - 1, 0), min(high_col + reach + 2, nx)
            # mass on that region and a 1-cell ring (for the local-maximum test), from p on a wider box
            m0, m1, n0, n1 = max(r0 - 1, 0), min(r1 + 1, ny), max(c0 - 1, 0), min(c1 + 1, nx)
            p0, p1, q0, q1 = max(m0 - reach, 0), min(m1 + reach, ny), max(n0 - reach, 0), min(n1 + reach, nx)
            p_box = logistic(self.log_odds[p0:p1, q0:q1])
            mass_box = _window_sums(p_box, kernel)
            mass = mass_box[m0 - p0 : m1 - p0, n0 - q0 : n1 - q0]
            peaks = mass == _window_maxima_3x3(mass)
            inner = (slice(r0 - m0, r1 - m0), slice(c0 - n0, c1 - n0))
            chosen = peaks[inner] & (mass[inner] >= threshold)
            for i, j in zip(*np.nonzero(chosen)):
                peaks_found[(r0 + int(i), c0 + int(j))] = float(mass[inner][i, j])
        heap = [(-m, iy, ix) for (iy, ix), m in peaks_found.items()]
        heapq.heapify(heap)
        claimed = np.zeros(0, dtype=np.int64)
        positions, masses, cells = [], [], []
        while heap:
            stored, iy, ix = heapq.heappop(heap)
            disc_rows, disc_cols = iy + disc_dy, ix + disc_dx
            inside = (disc_rows >= 0) & (disc_rows < ny) & (disc_cols >= 0) & (disc_cols < nx)
            flat = disc_rows[inside] * nx + disc_cols[inside]
            flat = flat[~np.isin(flat, claimed)]
            p = logistic(self.log_odds.ravel()[flat])
            mass_now = float(p.sum())
            if mass_now < threshold:
                continue
            if heap and mass_now < -heap[0][0] and mass_now != -stored:
                heapq.heappush(heap, (-mass_now, iy, ix))
                continue
            flat, p = flat[p > 0], p[p > 0]
            centre_x = self.grid.centres_x[flat % nx]
            centre_y = self.grid.centres_y[flat // nx]
            positions.append([np.dot(p, centre_x) / mass_now, np.dot(p, centre_y) / mass_now])
            masses.append(mass_now)
            cells.append(flat)
            claimed = np.concatenate([claimed, flat])
        if not positions:
            return empty
        return np.array(positions), np.array(masses), cells

    def targets(self, threshold: float = 0.5, radius_m: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Reported targets: positions (k, 2) [m] and probability masses (k,), largest first
        (module docstring).

        threshold: least mass of a target (> 0); radius_m: disc radius [m] (None: max(1.5 m,
        2 cells))."""
        positions, masses, _ = self.target_discs(threshold, radius_m)
        return positions, masses

    def p_all_found(self, threshold: float = 0.5, radius_m: float | None = None) -> float:
        """P(nobody outside the reported targets) = prod over the searchable cells outside every
        target's disc of (1 - p_c).

        threshold, radius_m: as in :meth:`targets`."""
        _, _, cells = self.target_discs(threshold, radius_m)
        log_none = -float(np.logaddexp(0.0, self.log_odds).sum())
        if cells:
            claimed = np.concatenate(cells)
            log_none += float(np.logaddexp(0.0, self.log_odds.ravel()[claimed]).sum())
        return float(np.exp(log_none))

    def _target_radius(self, radius_m: float | None) -> float:
        if radius_m is None:
            return self.default_target_radius_m()
        if not (np.isfinite(radius_m) and radius_m > 0):
            raise ActionInputError(f"radius_m: expected a radius > 0 m, got {radius_m!r}")
        return float(radius_m)


def _box_sum(values: np.ndarray, half: int) -> np.ndarray:
    """Sum of ``values`` (2-D) over the (2 half + 1)^2 square around each entry (zero outside)."""
    padded = np.pad(values, ((half + 1, half), (half + 1, half)))
    table = padded.cumsum(axis=0).cumsum(axis=1)
    n = 2 * half + 1
    total = table[n:, n:] - table[:-n, n:] - table[n:, :-n] + table[:-n, :-n]
    return np.maximum(total, 0.0)


def _scaled_log_odds(log_odds: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """The log-odds of p' = p factor (p = logistic(log_odds), factor >= 0), clipped to
    [-LOG_ODDS_LIMIT, LOG_ODDS_MAX]: log p' - log(1 - p'), computed in logs (exact for tiny p)."""
    with np.errstate(divide="ignore"):
        log_p = -np.logaddexp(0.0, -log_odds) + np.log(factor)
    p = np.minimum(np.exp(log_p), MAX_CELL_PROBABILITY)
    return np.clip(log_p - np.log1p(-p), -LOG_ODDS_LIMIT, LOG_ODDS_MAX)


def _disc_offsets(radius_cells: float) -> tuple[np.ndarray, np.ndarray]:
    """(dy, dx) integer offsets of the cells whose centres lie within ``radius_cells`` cells of a
    cell's centre (the cell itself always included)."""
    reach = int(np.floor(radius_cells + 1e-9))
    dy, dx = np.mgrid[-reach : reach + 1, -reach : reach + 1]
    inside = dx**2 + dy**2 <= radius_cells**2 + 1e-9
    return dy[inside], dx[inside]


def _searchable_mask(grid: MapGrid, searchable: np.ndarray | None) -> np.ndarray:
    """The searchable mask as a read-only bool (ny, nx) array (None: every cell)."""
    if searchable is None:
        mask = np.ones(grid.shape, dtype=bool)
    else:
        raw = np.asarray(searchable)
        if raw.shape != grid.shape or raw.dtype != bool:
            raise ActionInputError(
                f"searchable: expected a bool array of shape {grid.shape}, got {raw.dtype} {raw.shape}"
            )
        if not raw.any():
            raise ActionInputError("searchable: expected at least one searchable cell")
        mask = raw.copy() if raw.flags.writeable else raw
    mask.flags.writeable = False
    return mask


def _capped_scale(weights: np.ndarray, total: float, cap: float) -> float:
    """The s > 0 with sum_i min(s w_i, cap) = total, for weights w_i > 0 and total < cap * len(w)."""
    ordered = np.sort(weights)[::-1]
    tail = np.cumsum(ordered[::-1])[::-1]  # tail[j] = sum of ordered[j:]
    capped = np.arange(len(ordered))
    scale = (total - cap * capped) / tail
    fits = scale * ordered <= cap * (1 + 1e-12)
    return float(scale[np.argmax(fits)])


def _window_sums(values: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """out[i, j] = sum_{a, b} kernel[a, b] values[i + a - r, j + b - r] (zero outside values),
    r = kernel.shape[0] // 2; values: (m, n); kernel: (2 r + 1, 2 r + 1) of 0 and 1."""
    reach = kernel.shape[0] // 2
    padded = np.pad(values, reach)
    out = np.zeros_like(values, dtype=float)
    m, n = values.shape
    for a, b in zip(*np.nonzero(kernel)):
        out += padded[a : a + m, b : b + n]
    return out


def _window_maxima_3x3(values: np.ndarray) -> np.ndarray:
    """out[i, j] = max of values over the 3 x 3 cells around (i, j) (-inf outside values)."""
    padded = np.pad(values, 1, constant_values=-np.inf)
    m, n = values.shape
    out = padded[1 : 1 + m, 1 : 1 + n].copy()
    for a in range(3):
        for b in range(3):
            np.maximum(out, padded[a : a + m, b : b + n], out=out)
    return out
