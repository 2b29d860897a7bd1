"""Expected free energy search on a probability map, at field scale (10^6 cells).

:class:`ExpectedFreeEnergySearchPlanner` ("efe") flies the path whose images have the lowest
expected free energy per second of flight, -G / t with -G = epistemic + pragmatic value. No
phase, altitude or coverage pattern is coded: when the planner re-images a detection, changes
altitude or leaves resolved ground, the score chose it.

Channel. A detection is associated with cell c when it is reported within 2 sigma(h) of c
(sigma(h) the position error of the detector), an association area A(h) = a + pi (2 sigma(h))^2
(a the cell area). One look at altitude h gives

    P(detection | person in c) = pd(h, v),   P(detection | nobody in c) = pf(h) = 1 - exp(-kappa(h) A(h)),

kappa(h) the clutter density [1/m^2], v the cruise speed.

Epistemic value of one look (mutual information of the binary channel, nats):

    I(q) = H_b(q pd + (1 - q) pf) - q H_b(pd) - (1 - q) H_b(pf),   H_b(q) = -q ln q - (1 - q) ln(1 - q),

q the probability that the channel's unit holds a person. The unit ("disc", the default) is the
target disc around c: q = m_c = min(1, sum of p over the (2 k + 1)^2 cells around c), k =
round(r_t / s) (r_t the radius of the map's target discs, s the cell side), shared out over the
disc's cells in proportion to their mass, e_c = (p_c / m_c) I(m_c), so that an image's sum
counts each disc about once. The map updates cells independently and one detection lifts every
cell within the position error, so a detected person soon holds m_c >= 1 and e_c = 0: the
planner leaves resolved people instead of re-imaging the rim of their blur, where single cells
stay near p = 1/2 for ever (with the unit "cell", e_c = I(p_c), it does).

Pragmatic value (the prior preference for observing people: ln P~(o) = c_pref nats per newly
confirmed person). A person counts as found when the mass of a target disc reaches theta; a
look confirms the disc when m_c is below theta and a detection would lift it to theta or above:

    k_c = p_c pd 1[m_c < theta <= m_c^+],   m^+ = m pd / (m pd + (1 - m) pf),

the expected number of people newly confirmed, cell by cell. Value per cell and layer:
v_h(c) = e_c + c_pref k_c; -G of an image = sum of v_h over the cells whose centres lie in its
footprint (``Camera.footprint_m``), computed in O(1) from the summed-area table of v_h.

Images of a path. One image every s = speed / rate metres along the path, the last at each
waypoint: a straight leg of horizontal length L holds n = max(1, round(L / s)) images at
distances L, L - s, ... from its start, all at the leg's altitude (the UAV changes altitude
first, at its start, then flies level). Overlap: a cell seen by k images of a path is worth
v_h^(k), the value of k looks (the k-look information I_k of the count of detections, and the
probability that k looks confirm), for k up to K_h = min(``max_looks``, the most looks one
straight leg gives). With the differences Delta_k = v^(k) - v^(k-1) and the tables T_1 =
Delta_1, T_k = Delta_k - Delta_{k-1}, T_{K+1} = -Delta_K, the value of a chain of images is
sum_j [T_1(F_j) + sum_i T_{i+1}(F_j ∩ F_{j-i})] (F_{j-i} the i-th image before F_j): exact along
a straight leg, where the footprints a cell lies in are consecutive. For the second leg the chain
continues through the first leg's images, and each image also loses at least its overlap with
the nearest image of the first (-T_2 over their intersection; the larger loss is taken).

Time of a leg: t = L / v + |dz| / v_z, and at least n / rate (the camera's pace).

Candidates (receding horizon, two legs): first legs to a lattice of headings x distances
(geometric, from half the lowest footprint to ``horizon_m``) x altitude layers, plus legs that
only change altitude, legs above the most probable cells within the horizon, and legs straight
to the best blocks of a coarse block-summed value map of the whole area (so the UAV still goes
where the value is when nothing near is worth looking at); then second legs from the best first
legs. The first leg of the pair with the largest (V_1 + V_2) / (t_1 + t_2) is flown and the
mission replans at its end (``fly_second_leg``: both legs). With ``legs=3`` the ``beam_width``
pairs of largest rate are each extended by third legs from the end of their second (the chain of
looks continuing through the second leg's images, then the first's, and the nearest-image loss
taken over both), and the first leg of the triple with the largest (V_1 + V_2 + V_3) / (t_1 +
t_2 + t_3) is flown (the best pair's when no third leg is feasible). Rejected: legs leaving the map's
extent or the altitude limits; legs passing within ``OBSTACLE_MARGIN_M`` of a building box
(:func:`attend.action.camera.segments_hit_box`; margin 0 when no leg clears it, e.g. right after
take-off next to a building); legs whose end lies within ``min_separation_m`` (3-D distance) of
another UAV's pose or waypoints; legs that bring the UAV within ``min_separation_m`` of another
UAV flying its plan (both at v, compared at the same times; a UAV already closer may only move
apart). Optional CMA-ES refinement of the legs is not done.

Several UAVs: plans are made one after another on the shared map; before scoring, the images
the other UAVs will take along their plans are booked on a copy of the map as if they saw
nothing (``ProbabilityMap.expected_no_detection_update``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from attend.action.log_odds import log_binomial_coefficient, logistic
from attend._threads import single_blas_thread

from attend.action.camera import Camera, segments_hit_box
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError
from attend.action.planners.search_base import SearchPlanner

#: Radius of the association disc in position errors: 2 sigma(h).
ASSOCIATION_SIGMAS = 2.0
#: Clearance [m] kept from every building box.
OBSTACLE_MARGIN_M = 2.0
#: Headings of the first-leg lattice and of the second legs.
FIRST_HEADINGS = 24
SECOND_HEADINGS = 16
#: Distances of the first-leg lattice (geometric) and of the second legs.
FIRST_DISTANCES = 6
SECOND_DISTANCES = 3
#: First legs expanded with a second leg.
EXPANDED_FIRST_LEGS = 8
#: Legs over the most probable cells within the horizon (per layer), and to the best coarse blocks (per layer).
PEAK_CELLS = 6
LONG_RANGE_BLOCKS = 4
#: Times along a leg at which the distance to the other UAVs is checked.
SEPARATION_SAMPLES = 24
#: Side [cells] of the tiles on which value maps are recomputed when the map changed.
VALUE_TILE_CELLS = 64
#: Rows per band of the summed-area tables (:class:`BandedSummedAreaTables`): 2^BAND_SHIFT.
BAND_SHIFT = 6
BAND_ROWS = 1 << BAND_SHIFT
#: Default number of altitude layers.
DEFAULT_LAYERS = 5
#: Logit range [-L, L] of the tabulated levels of the value functions (``value_levels``).
LEVEL_LOGIT_LIMIT = 30.0
#: Most looks of one cell along a path whose value is counted (later looks count 0: a lower bound).
MAX_LOOKS = 8

_EPS = 1e-12


def binary_entropy(q: np.ndarray | float) -> np.ndarray:
    """H_b(q) = -q ln q - (1 - q) ln(1 - q) in nats (0 at q = 0 and q = 1); q: probabilities."""
    q = np.clip(np.asarray(q, dtype=float), 0.0, 1.0)
    out = np.zeros_like(q)
    inside = (q > 0) & (q < 1)
    qi = q[inside]
    out[inside] = -qi * np.log(qi) - (1 - qi) * np.log1p(-qi)
    return out


def mutual_information(p: np.ndarray | float, pd: float, pf: float) -> np.ndarray:
    """I(p) = H_b(p pd + (1 - p) pf) - p H_b(pd) - (1 - p) H_b(pf) [nats]: the information one
    look gives about a binary state that is 1 with probability p, the look reporting a detection
    with probability pd when it is 1 and pf when it is 0.

    p: prior probability of the state (array); pd: detection probability; pf: false-alarm
    probability."""
    p = np.clip(np.asarray(p, dtype=float), 0.0, 1.0)
    h_pd, h_pf = binary_entropy(pd), binary_entropy(pf)
    return np.maximum(binary_entropy(p * pd + (1 - p) * pf) - p * h_pd - (1 - p) * h_pf, 0.0)


def _binomial_pmf(k: int, q: float) -> np.ndarray:
    """P(j of k independent looks report, each with probability q), j = 0 .. k."""
    j = np.arange(k + 1)
    log_choose = log_binomial_coefficient(k, j)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_pmf = log_choose + np.where(j > 0, j * np.log(q), 0.0) + np.where(k - j > 0, (k - j) * np.log1p(-q), 0.0)
    return np.exp(log_pmf)


def multi_look_information(p: np.ndarray | float, pd: float, pf: float, looks: int) -> np.ndarray:
    """I_k(p) [nats]: the information k independent looks give about a binary state that is 1
    with probability p, each look reporting with probability pd when it is 1 and pf when it is 0
    (the count of reports is a sufficient statistic: Binomial(k, pd) or Binomial(k, pf)).
    I_1 = :func:`mutual_information`."""
    p = np.clip(np.asarray(p, dtype=float), 0.0, 1.0)
    one, zero = _binomial_pmf(looks, pd), _binomial_pmf(looks, pf)
    mixture = p[..., None] * one + (1 - p[..., None]) * zero
    with np.errstate(divide="ignore", invalid="ignore"):
        h_mix = -np.sum(np.where(mixture > 0, mixture * np.log(np.where(mixture > 0, mixture, 1.0)), 0.0), axis=-1)
        h_one = -np.sum(np.where(one > 0, one * np.log(np.where(one > 0, one, 1.0)), 0.0))
        h_zero = -np.sum(np.where(zero > 0, zero * np.log(np.where(zero > 0, zero, 1.0)), 0.0))
    return np.maximum(h_mix - p * h_one - (1 - p) * h_zero, 0.0)


def confirmation_probability(mass: np.ndarray | float, pd: float, pf: float, looks: int, threshold: float) -> np.ndarray:
    """P(k looks confirm a person who is there): the probability, given a person in a disc of
    mass m < theta, that the reports of k looks (j ~ Binomial(k, pd)) lift the disc's odds,
    m / (1 - m) (pd / pf)^j ((1 - pd) / (1 - pf))^(k - j), to theta / (1 - theta) or above (the
    mass after the k looks; 0 when m >= theta)."""
    m = np.clip(np.asarray(mass, dtype=float), 0.0, 1.0)
    j = np.arange(looks + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        hit = np.log(pd) - np.log(pf) if pf > 0 else np.inf
        miss = np.log1p(-pd) - np.log1p(-pf) if pd < 1 else -np.inf
        lift = np.where(j > 0, j * hit, 0.0) + np.where(looks - j > 0, (looks - j) * miss, 0.0)
        log_odds = np.log(m) - np.log1p(-m)
        reached = (log_odds[..., None] + lift) >= np.log(threshold) - np.log1p(-threshold)
    reached &= (m < threshold)[..., None]
    return np.sum(np.where(reached, _binomial_pmf(looks, pd), 0.0), axis=-1)


def summed_area_table(values: np.ndarray) -> np.ndarray:
    """Summed-area table T (ny + 1, nx + 1) of values (ny, nx): T[i, j] = sum(values[:i, :j]), so
    that the sum over rows r0:r1 and columns c0:c1 is T[r1, c1] - T[r0, c1] - T[r1, c0] + T[r0, c0]."""
    values = np.asarray(values, dtype=float)
    table = np.zeros((values.shape[0] + 1, values.shape[1] + 1))
    np.cumsum(values, axis=0, out=table[1:, 1:])
    np.cumsum(table[1:, 1:], axis=1, out=table[1:, 1:])
    return table


def rectangle_sums(table: np.ndarray, rows0, rows1, cols0, cols1) -> np.ndarray:
    """Sums of the values over rows [rows0, rows1) and columns [cols0, cols1) from their
    summed-area table (:func:`summed_area_table`), O(1) each; index arrays of one shape, clipped
    to the table with rows0 <= rows1 and cols0 <= cols1."""
    return table[rows1, cols1] - table[rows0, cols1] - table[rows1, cols0] + table[rows0, cols0]


def box_sums(values: np.ndarray, half_width_cells: int) -> np.ndarray:
    """Sum of values (ny, nx) over the (2 k + 1)^2 cells around each cell, clipped at the edges;
    half_width_cells: k >= 0."""
    k = int(half_width_cells)
    if k == 0:
        return np.asarray(values, dtype=float).copy()
    table = summed_area_table(values)
    ny, nx = values.shape
    rows, cols = np.arange(ny), np.arange(nx)
    r0, r1 = np.maximum(rows - k, 0), np.minimum(rows + k + 1, ny)
    c0, c1 = np.maximum(cols - k, 0), np.minimum(cols + k + 1, nx)
    return (table[np.ix_(r1, c1)] - table[np.ix_(r0, c1)]) - (table[np.ix_(r1, c0)] - table[np.ix_(r0, c0)])


class BandedSummedAreaTables:
    """Summed-area tables T_t (t = 0 .. n - 1) of value maps V_t (ny, nx), stored in bands of
    ``BAND_ROWS`` rows so that a change in a few rows costs O(band x nx) per table instead of
    O(ny x nx):

        T_t[i, j] = B_t[i // R, j] + L_t[i, j],   L_t[i, j] = sum V_t[R (i // R) : i, :j],
        B_t[b, j] = sum V_t[: R b, :j],

    R = ``BAND_ROWS``, i in 0..ny, j in 0..nx (T_t[i, j] = sum V_t[:i, :j]). Table n is zero (the
    planner's index for "no table"). values: (n, ny, nx)."""

    def __init__(self, values: np.ndarray) -> None:
        self.n_tables, self.ny, self.nx = values.shape
        self.n_bands = self.ny // BAND_ROWS + 1
        self.local = np.zeros((self.n_tables + 1, self.ny + 1, self.nx + 1))
        self.band_base = np.zeros((self.n_tables + 1, self.n_bands, self.nx + 1))
        self._band_totals = np.zeros((self.n_tables, self.n_bands, self.nx + 1))
        self.update(values, range(self.n_bands))

    def update(self, values: np.ndarray, bands) -> None:
        """Recompute ``bands`` (band indices) from ``values`` (n, ny, nx), then the band bases."""
        for band in sorted(set(int(b) for b in bands)):
            top, bottom = band * BAND_ROWS, min((band + 1) * BAND_ROWS, self.ny)
            if bottom <= top:
                continue
            block = self.local[: self.n_tables, top + 1 : bottom + 1, 1:]
            np.cumsum(values[:, top:bottom, :], axis=2, out=block)  # row prefixes
            self._band_totals[:, band, 1:] = block.sum(axis=1)
            np.cumsum(block, axis=1, out=block)
            if bottom == (band + 1) * BAND_ROWS:  # row `bottom` starts the next band, where L = 0
                self.local[: self.n_tables, bottom, :] = 0.0
        np.cumsum(self._band_totals[:, :-1], axis=1, out=self.band_base[: self.n_tables, 1:])

    def sums(self, tables, rows0, rows1, cols0, cols1) -> np.ndarray:
        """Sums of V_t over rows [rows0, rows1) and columns [cols0, cols1), t = ``tables``
        (index arrays broadcast; table n gives 0)."""
        return (self.corner(tables, rows1, cols1) - self.corner(tables, rows0, cols1)
                - self.corner(tables, rows1, cols0) + self.corner(tables, rows0, cols0))

    def corner(self, tables, rows, cols) -> np.ndarray:
        """T_t[rows, cols] (index arrays broadcast)."""
        return self.local[tables, rows, cols] + self.band_base[tables, rows >> BAND_SHIFT, cols]

    def dense(self, table: int) -> np.ndarray:
        """T_table (ny + 1, nx + 1) in full."""
        return self.local[table] + self.band_base[table][np.arange(self.ny + 1) // BAND_ROWS]


class _Lattice:
    """Index geometry of a map grid: the cells whose centres lie in an axis-aligned rectangle."""

    def __init__(self, grid) -> None:
        self.nx, self.ny = int(grid.nx), int(grid.ny)
        self.cell = float(grid.cell_size_m)
        cx, cy = np.asarray(grid.centres_x, float), np.asarray(grid.centres_y, float)
        self.x0, self.y0 = float(cx[0]), float(cy[0])
        self.y_step = self.cell if cy.size < 2 or cy[-1] >= cy[0] else -self.cell
        self.extent = tuple(float(v) for v in grid.extent_m)

    def ranges(self, x, y, half_x, half_y):
        """Half-open index ranges (r0, r1, c0, c1) of the cells whose centres lie in
        [x - half_x, x + half_x] x [y - half_y, y + half_y] (arrays broadcast), clipped to the map."""
        tol = 1e-9
        c0 = np.ceil((x - half_x - self.x0) / self.cell - tol)
        c1 = np.floor((x + half_x - self.x0) / self.cell + tol) + 1
        ya = (y - half_y - self.y0) / self.y_step
        yb = (y + half_y - self.y0) / self.y_step
        low, high = np.minimum(ya, yb), np.maximum(ya, yb)
        r0 = np.ceil(low - tol)
        r1 = np.floor(high + tol) + 1
        c0 = np.clip(c0, 0, self.nx).astype(np.intp)
        c1 = np.clip(c1, 0, self.nx).astype(np.intp)
        r0 = np.clip(r0, 0, self.ny).astype(np.intp)
        r1 = np.clip(r1, 0, self.ny).astype(np.intp)
        return r0, np.maximum(r1, r0), c0, np.maximum(c1, c0)

    def cell_centre(self, rows, cols):
        """Centres (x, y) [m] of the cells (rows, cols)."""
        return self.x0 + cols * self.cell, self.y0 + rows * self.y_step


def _intersect(a, b):
    """Intersection of two sets of half-open index ranges (r0, r1, c0, c1)."""
    r0, c0 = np.maximum(a[0], b[0]), np.maximum(a[2], b[2])
    return r0, np.maximum(np.minimum(a[1], b[1]), r0), c0, np.maximum(np.minimum(a[3], b[3]), c0)


def _take(ranges, index):
    return tuple(r[index] for r in ranges)


class ExpectedFreeEnergySearchPlanner(SearchPlanner):
    """Fly the images with the lowest expected free energy per second of flight (module
    docstring: channel, epistemic and pragmatic value, overlap, candidates).

    model: the detector (pd, clutter density, position error); camera: the footprint;
    speed_m_s: cruise speed v [m/s]; image_rate_hz: camera rate [1/s]; altitude_layers_m: the
    candidate altitudes [m] (None: ``DEFAULT_LAYERS`` geometric layers from max(low limit,
    h_best / 2) to min(high limit, h_best + 3/4 (h_useless - h_best))); altitude_limits_m:
    (min, max) flight altitude [m]; buildings: boxes to keep ``OBSTACLE_MARGIN_M`` from (each
    with ``.bounds`` (x0, x1, y0, y1, z0, z1) [m]); preference_nats_per_person: c_pref, the log
    preference [nats] for newly confirming one person; horizon_m: longest first leg of the
    lattice [m] (None: max(4 s, 3 widest footprint), s = v / rate the image spacing);
    min_separation_m: least distance [m] kept from the other UAVs' poses and waypoints;
    target_threshold: theta, the mass at which a person counts as confirmed; target_radius_m:
    r_t, the radius of a target disc [m] (None: the map's ``default_target_radius_m()``, else
    max(1.5 m, 2 cells)); climb_speed_m_s: v_z [m/s] (None: v); channel: "disc" (the unit of the
    epistemic value is the target disc, module docstring) or "cell" (I(p_c) per cell);
    single_legs: let a first leg alone compete with the two-leg paths (False: every path has
    two legs when a second leg is feasible); fly_second_leg: return the second leg too (False:
    only the first leg is flown and the mission replans at its end, a receding horizon of one
    leg); seed: seeds the random rotation of the heading lattice; allowed_legs: None, or a
    function (starts (m, 3), ends (m, 3)) [m] -> (m,) bool of the straight legs the UAV may fly
    (an area that is not the map's rectangle, no-fly zones); route_toward: None, or a function
    (start (3,), goal (3,)) [m] -> (x, y) [m], the first waypoint of an allowed route from start
    to goal (the long-range legs go there when the straight leg is not allowed);
    book_other_plans: book the images the other UAVs will take along their plans (False: the
    caller has booked them on the map it passes); value_levels: None (the channel's functions
    at every distinct value of the map, exact) or a number of levels evenly spaced in logit at
    which they are tabulated and interpolated (faster on detailed maps; :meth:`_levels`);
    max_looks: the most looks of one cell along a path whose value is counted (later looks count
    0: a lower bound of the path's value; fewer looks, fewer tables to sum);
    footprint_follows_heading: the camera turns with the UAV (False: it keeps its across-track
    side along x, as in the paper's world): the footprint of a leg flown closer to east-west than
    to north-south has its across-track side along y (the axis-aligned rectangle of the nearer
    axis; a diagonal leg's rotated footprint is approximated by it); legs: 2 (pairs of legs
    scored) or 3 (the ``beam_width`` best pairs extended by a third leg, module docstring);
    beam_width: the number of pairs extended when legs = 3.
    """

    name = "efe"

    def __init__(
        self,
        model: DetectionModel,
        camera: Camera,
        speed_m_s: float,
        image_rate_hz: float,
        altitude_layers_m: Sequence[float] | None = None,
        altitude_limits_m: Sequence[float] = (5.0, 120.0),
        buildings: Sequence = (),
        preference_nats_per_person: float = 1.0,
        horizon_m: float | None = None,
        min_separation_m: float = 10.0,
        target_threshold: float = 0.5,
        target_radius_m: float | None = None,
        climb_speed_m_s: float | None = None,
        channel: str = "disc",
        single_legs: bool = False,
        fly_second_leg: bool = False,
        seed: int = 0,
        allowed_legs=None,
        route_toward=None,
        book_other_plans: bool = True,
        value_levels: int | None = None,
        max_looks: int = MAX_LOOKS,
        footprint_follows_heading: bool = False,
        legs: int = 2,
        beam_width: int = 8,
    ) -> None:
        if not isinstance(model, DetectionModel):
            raise ActionInputError(f"model: expected a DetectionModel, got {type(model).__name__}")
        if not isinstance(camera, Camera):
            raise ActionInputError(f"camera: expected a Camera, got {type(camera).__name__}")
        for name, value in (("speed_m_s", speed_m_s), ("image_rate_hz", image_rate_hz)):
            if not (_is_number(value) and value > 0):
                raise ActionInputError(f"{name}: expected a finite number > 0, got {value!r}")
        try:
            low, high = (float(v) for v in altitude_limits_m)
        except (TypeError, ValueError):
            raise ActionInputError(f"altitude_limits_m: expected (min, max) in m, got {altitude_limits_m!r}") from None
        if not (np.isfinite(low) and np.isfinite(high) and 0 < low < high):
            raise ActionInputError(f"altitude_limits_m: expected 0 < min < max in m, got ({low!r}, {high!r})")
        if altitude_layers_m is None:
            bottom = max(low, model.best_altitude_m / 2)
            top = min(high, model.best_altitude_m + 0.75 * (model.useless_altitude_m - model.best_altitude_m))
            layers = np.geomspace(bottom, max(top, bottom), DEFAULT_LAYERS) if top > bottom else np.array([bottom])
        else:
            try:
                layers = np.asarray([float(h) for h in altitude_layers_m])
            except (TypeError, ValueError):
                raise ActionInputError(
                    f"altitude_layers_m: expected a sequence of altitudes in m, got {altitude_layers_m!r}") from None
            if layers.size == 0 or not np.all(np.isfinite(layers)) or np.any((layers < low) | (layers > high)):
                raise ActionInputError(
                    f"altitude_layers_m: expected altitudes within altitude_limits_m [{low:g}, {high:g}] m, "
                    f"got {tuple(layers)}")
        for k, box in enumerate(buildings):
            bounds = getattr(box, "bounds", None)
            if bounds is None or len(tuple(bounds)) != 6:
                raise ActionInputError(
                    f"buildings[{k}]: expected a box with .bounds (x0, x1, y0, y1, z0, z1), got {box!r}")
        if not (_is_number(preference_nats_per_person) and preference_nats_per_person >= 0):
            raise ActionInputError(
                f"preference_nats_per_person: expected a number >= 0 (nats), got {preference_nats_per_person!r}")
        if horizon_m is not None and not (_is_number(horizon_m) and horizon_m > 0):
            raise ActionInputError(f"horizon_m: expected a distance > 0 m or None, got {horizon_m!r}")
        if not (_is_number(min_separation_m) and min_separation_m >= 0):
            raise ActionInputError(f"min_separation_m: expected a distance >= 0 m, got {min_separation_m!r}")
        if not (_is_number(target_threshold) and 0 < target_threshold < 1):
            raise ActionInputError(f"target_threshold: expected a probability in (0, 1), got {target_threshold!r}")
        if channel not in ("disc", "cell"):
            raise ActionInputError(f"channel: expected 'disc' or 'cell', got {channel!r}")
        if target_radius_m is not None and not (_is_number(target_radius_m) and target_radius_m > 0):
            raise ActionInputError(f"target_radius_m: expected a radius > 0 m or None, got {target_radius_m!r}")
        if climb_speed_m_s is not None and not (_is_number(climb_speed_m_s) and climb_speed_m_s > 0):
            raise ActionInputError(f"climb_speed_m_s: expected a speed > 0 m/s or None, got {climb_speed_m_s!r}")
        self.model = model
        self.camera = camera
        self.speed_m_s = float(speed_m_s)
        self.image_rate_hz = float(image_rate_hz)
        self.altitude_layers_m = np.sort(layers)
        self.altitude_limits_m = (low, high)
        self.buildings = tuple(buildings)
        self.preference_nats_per_person = float(preference_nats_per_person)
        self.min_separation_m = float(min_separation_m)
        self.target_threshold = float(target_threshold)
        self.channel = channel
        self.single_legs = bool(single_legs)
        self.fly_second_leg = bool(fly_second_leg)
        if allowed_legs is not None and not callable(allowed_legs):
            raise ActionInputError(f"allowed_legs: expected None or a function (starts, ends) -> mask, got {allowed_legs!r}")
        if route_toward is not None and not callable(route_toward):
            raise ActionInputError(f"route_toward: expected None or a function (start, goal) -> (x, y), got {route_toward!r}")
        self.allowed_legs = allowed_legs
        self.route_toward = route_toward
        self.book_other_plans = bool(book_other_plans)
        self.footprint_follows_heading = bool(footprint_follows_heading)
        if legs not in (2, 3) or isinstance(legs, bool):
            raise ActionInputError(f"legs: expected 2 or 3 (legs scored per plan), got {legs!r}")
        if not (isinstance(beam_width, (int, np.integer)) and not isinstance(beam_width, bool) and beam_width >= 1):
            raise ActionInputError(f"beam_width: expected a whole number >= 1 (pairs extended), got {beam_width!r}")
        self.legs = int(legs)
        self.beam_width = int(beam_width)
        if value_levels is not None and not (isinstance(value_levels, (int, np.integer)) and value_levels >= 16):
            raise ActionInputError(f"value_levels: expected None or a whole number >= 16, got {value_levels!r}")
        self.value_levels = None if value_levels is None else int(value_levels)
        self._level_functions: dict = {}
        self.target_radius_m = float(target_radius_m) if target_radius_m is not None else None
        self.climb_speed_m_s = float(climb_speed_m_s) if climb_speed_m_s is not None else self.speed_m_s
        self.image_spacing_m = self.speed_m_s / self.image_rate_hz
        widths = np.array(camera.footprint_m(self.altitude_layers_m))  # (2, L)
        self._half_widths = widths / 2
        self.horizon_m = float(horizon_m) if horizon_m is not None else max(4 * self.image_spacing_m, 3 * widths.max())
        # per layer: detection and false-alarm probabilities, association window
        h = self.altitude_layers_m
        self._pd = np.asarray(model.detection_probability(h, self.speed_m_s), dtype=float)
        self._sigma = np.asarray(model.position_error_m(h), dtype=float)
        # per layer: K_h, the most looks of one cell by consecutive images of a straight leg
        # (floor(diagonal / s) + 1 at any heading), capped at max_looks; tables T_1 .. T_{K_h + 1}
        diagonal = np.hypot(widths[0], widths[1])
        if not (isinstance(max_looks, (int, np.integer)) and max_looks >= 1):
            raise ActionInputError(f"max_looks: expected a whole number >= 1, got {max_looks!r}")
        self._looks = np.minimum(np.floor(diagonal / self.image_spacing_m + 1e-9).astype(int) + 1, int(max_looks))
        self._looks = np.maximum(self._looks, 1)
        counts = self._looks + 1
        self._table_offset = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
        self._n_tables = int(counts.sum())
        # _table_index[layer, i]: the table T_{i + 1} of the layer, or the zero table (last) beyond T_{K_h + 1}
        width = int(counts.max())
        index = np.full((len(h), width + 1), self._n_tables, dtype=np.intp)
        for layer, count in enumerate(counts):
            index[layer, :count] = self._table_offset[layer] + np.arange(count)
        self._table_index = index
        self.reset(seed)

    def reset(self, seed: int = 0) -> None:
        """Start a new mission: forget the cached value maps; seed: reseeds the heading lattice's rotation."""
        super().reset(seed)
        self._cache = None

    @classmethod
    def for_world(cls, world, settings, **options) -> "ExpectedFreeEnergySearchPlanner":
        """The planner for a :class:`attend.action.world.SearchWorld` flown with
        :class:`attend.action.search_mission.SearchSettings` (detector, camera, speed, image
        rate, separation, target threshold; altitude limits and buildings of the world).

        world: the search world; settings: the mission settings; options: further constructor
        arguments (e.g. preference_nats_per_person, horizon_m, altitude_layers_m, seed)."""
        return cls(
            model=settings.model,
            camera=settings.camera,
            speed_m_s=settings.speed_m_s,
            image_rate_hz=settings.image_rate_hz,
            altitude_limits_m=world.altitude_limits_m,
            buildings=tuple(world.buildings),
            min_separation_m=settings.min_separation_m,
            target_threshold=settings.target_threshold,
            **options,
        )

    # ----------------------------------------------------------------------------------------
    # value maps

    def layer_values(
        self, probability: np.ndarray, cell_size_m: float, target_radius_m: float | None = None
    ) -> np.ndarray:
        """Difference maps T (n + 1, ny, nx) [nats per cell] of the looks from each altitude layer
        (module docstring): for layer h, rows ``_table_index[h, :K_h + 1]`` hold T_1 = Delta_1,
        T_k = Delta_k - Delta_{k-1} (2 <= k <= K_h) and T_{K_h + 1} = -Delta_{K_h}, Delta_k =
        v_h^(k) - v_h^(k-1) the value of a cell's k-th look; the last row is zeros.

        probability: p (ny, nx), P(a person's centre is in the cell) (0 where not searchable);
        cell_size_m: side s of a cell [m]; target_radius_m: r_t [m] (None: the planner's, else
        max(1.5 m, 2 s))."""
        p = np.asarray(probability, dtype=float)
        radius = self._target_radius(cell_size_m) if target_radius_m is None else float(target_radius_m)
        mass = np.minimum(box_sums(p, int(round(radius / cell_size_m))), 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(mass > _EPS, p / np.maximum(mass, _EPS), 0.0)
        out = np.zeros((self._n_tables + 1,) + p.shape)
        unit = p if self.channel == "cell" else mass
        unit_levels = self._levels(unit)
        mass_levels = unit_levels if self.channel == "disc" else self._levels(mass)
        for layer in range(len(self.altitude_layers_m)):
            self._layer_value(p, share, layer, cell_size_m, out, unit_levels, mass_levels)
        return out

    def _levels(self, values: np.ndarray):
        """(levels, gather): the values at which the channel's functions are evaluated, and a
        function taking those functions' values at the levels to the cells. Exact (value_levels
        None): the distinct values; else ``value_levels`` levels evenly spaced in logit on
        [-30, 30], linearly interpolated in logit (a sort of the map avoided)."""
        if self.value_levels is None:
            levels, inverse = np.unique(values, return_inverse=True)
            inverse = inverse.reshape(values.shape)
            return levels, lambda table: table[inverse]
        n = self.value_levels
        grid = np.linspace(-LEVEL_LOGIT_LIMIT, LEVEL_LOGIT_LIMIT, n)
        clipped = np.clip(values, 1e-300, 1.0)
        with np.errstate(divide="ignore"):
            z = np.log(clipped) - np.log1p(-np.minimum(clipped, 1.0 - 1e-16))
        position = np.clip((z + LEVEL_LOGIT_LIMIT) / (grid[1] - grid[0]), 0.0, n - 1.000001)
        low = position.astype(np.intp)
        weight = position - low
        levels = logistic(grid)
        levels[0], levels[-1] = 0.0, 1.0
        return levels, lambda table: table[low] * (1.0 - weight) + table[low + 1] * weight

    def _target_radius(self, cell_size_m: float) -> float:
        if self.target_radius_m is not None:
            return self.target_radius_m
        return max(1.5, 2 * cell_size_m)

    def _layer_value(self, p, share, layer: int, cell_size_m: float, out: np.ndarray, unit_levels,
                     mass_levels) -> None:
        """Write the difference maps T_1 .. T_{K+1} of one layer into ``out`` from p and the shares
        p / m (m the disc masses, clipped to 1); the channel's functions of the unit (m, or p)
        and of m are evaluated at their levels (:meth:`_levels`) and gathered to the cells."""
        h = self.altitude_layers_m[layer]
        pd = float(self._pd[layer])
        association = cell_size_m**2 + np.pi * (ASSOCIATION_SIGMAS * self._sigma[layer]) ** 2
        pf = float(self.model.false_alarm_probability_per_cell(h, self.camera, association))
        looks = int(self._looks[layer])
        levels, gather = unit_levels
        tabulated = self.value_levels is not None  # the same levels every time: keep the functions
        key = (layer, cell_size_m)
        if tabulated and key in self._level_functions:
            information, confirms = self._level_functions[key]
        else:
            information = np.stack([multi_look_information(levels, pd, pf, k) for k in range(1, looks + 1)])
            confirms = None
            if self.preference_nats_per_person > 0:
                confirms = np.stack([confirmation_probability(mass_levels[0], pd, pf, k, self.target_threshold)
                                     for k in range(1, looks + 1)])
            if tabulated:
                self._level_functions[key] = (information, confirms)
        weight = np.ones_like(p) if self.channel == "cell" else share
        if self.preference_nats_per_person > 0:
            m_gather = mass_levels[1]
        previous_delta = np.zeros_like(p)
        previous_value = np.zeros_like(p)
        base = int(self._table_offset[layer])
        for k in range(looks):
            value = weight * gather(information[k])
            if self.preference_nats_per_person > 0:
                value += self.preference_nats_per_person * p * m_gather(confirms[k])
            delta = value - previous_value
            out[base + k] = delta - previous_delta
            previous_value, previous_delta = value, delta
        out[base + looks] = -previous_delta

    # ----------------------------------------------------------------------------------------
    # planning

    def plan(
        self, belief, uav: int, pose_m: np.ndarray, time_left_s: float, others: Sequence[np.ndarray] = (),
        allowed_legs=None,
    ) -> np.ndarray:
        """Next waypoints (w, 3) [m] for UAV ``uav``: the two legs with the largest expected free
        energy reduction per second (module docstring), an altitude change at the start of a leg
        given as its own waypoint.

        belief: the shared :class:`attend.action.probability_map.ProbabilityMap`; uav: index of
        the UAV; pose_m: its pose (x, y, z) [m]; time_left_s: flight time left [s]; others: per
        other UAV an array (k, 3) [m], its current pose then its planned waypoints; allowed_legs:
        None (the planner's own ``allowed_legs``) or a function (starts (m, 3), ends (m, 3)) [m]
        -> (m,) bool that replaces it for this call (e.g. legs after which this UAV still gets
        home in time)."""
        try:
            pose = np.asarray(pose_m, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise ActionInputError(f"pose_m: expected (x, y, z) in m, got {pose_m!r}") from None
        if not np.all(np.isfinite(pose)):
            raise ActionInputError(f"pose_m: expected finite (x, y, z) in m, got {tuple(pose)}")
        if not (_is_number(time_left_s) and time_left_s >= 0):
            raise ActionInputError(f"time_left_s: expected a time >= 0 s, got {time_left_s!r}")
        other_paths = []
        for k, path in enumerate(others):
            arr = np.asarray(path, dtype=float)
            if arr.ndim != 2 or arr.shape[1] != 3 or len(arr) == 0 or not np.all(np.isfinite(arr)):
                raise ActionInputError(f"others[{k}]: expected a finite array (k >= 1, 3) in m, got shape {arr.shape}")
            other_paths.append(arr)
        if allowed_legs is not None and not callable(allowed_legs):
            raise ActionInputError(f"allowed_legs: expected None or a function (starts, ends) -> mask, got {allowed_legs!r}")
        allowed = self.allowed_legs if allowed_legs is None else allowed_legs
        with single_blas_thread():
            return self._plan(belief, pose, float(time_left_s), other_paths, allowed)

    def _plan(self, belief, pose: np.ndarray, time_left_s: float, others: list[np.ndarray], allowed) -> np.ndarray:
        grid = belief.grid
        lattice = _Lattice(grid)
        if self.book_other_plans and any(len(path) > 1 for path in others):
            belief = belief.copy()
            windows, altitudes = self._booked_images(grid, others)
            if windows:
                belief.expected_no_detection_update(
                    windows, altitudes, self.model, self.camera, speeds_m_s=np.full(len(windows), self.speed_m_s))
        radius = self.target_radius_m
        if radius is None and hasattr(belief, "default_target_radius_m"):
            radius = float(belief.default_target_radius_m())
        if radius is None:
            radius = self._target_radius(lattice.cell)
        tables = self._value_tables(belief, lattice, float(radius))
        # first legs
        ends, layers = self._first_candidates(pose, lattice, tables, belief, allowed)
        starts = np.broadcast_to(pose, ends.shape)
        keep = self._feasible(starts, ends, lattice, others, allowed)
        margin = OBSTACLE_MARGIN_M
        if not np.any(keep):  # e.g. started within the margin of a building: only stay out of it
            margin = 0.0
            keep = self._feasible(starts, ends, lattice, others, allowed, margin)
        if not np.any(keep):
            return pose[None].copy()
        ends, layers, starts = ends[keep], layers[keep], starts[keep]
        value1, time1, ranges1, valid1, images1 = self._leg_values(tables, lattice, starts, ends, layers)
        within = time1 <= max(time_left_s, 1.0 / self.image_rate_hz)
        if np.any(within):
            ends, layers, starts = ends[within], layers[within], starts[within]
            value1, time1 = value1[within], time1[within]
            ranges1, valid1, images1 = _take(ranges1, within), valid1[within], images1[within]
        rate1 = value1 / time1
        order = np.argsort(-rate1, kind="stable")[:EXPANDED_FIRST_LEGS]
        # second legs from the best first legs
        best_rate, best = (rate1[order[0]], (order[0], None)) if self.single_legs else (-np.inf, (order[0], None))
        pairs = []
        for parent in order:
            ends2, layers2 = self._second_candidates(ends[parent], layers[parent], lattice)
            starts2 = np.broadcast_to(ends[parent], ends2.shape)
            ok = self._feasible(starts2, ends2, lattice, others, allowed, margin, float(time1[parent]))
            if not np.any(ok):
                continue
            ends2, layers2, starts2 = ends2[ok], layers2[ok], starts2[ok]
            value2, time2 = self._second_leg_values(
                tables, lattice, starts2, ends2, layers2, _take(ranges1, parent), valid1[parent], images1[parent])
            rate = (value1[parent] + value2) / (time1[parent] + time2)
            j = int(np.argmax(rate))
            if rate[j] > best_rate:
                best_rate, best = rate[j], (parent, ends2[j])
            if self.legs == 3:
                pairs.append((rate, np.full(len(rate), parent), ends2, layers2, value1[parent] + value2,
                              time1[parent] + time2))
        if pairs:
            pairs = tuple(np.concatenate(column) for column in zip(*pairs))
            third = self._best_third_legs(tables, lattice, pairs, ends, ranges1, valid1, images1, others, allowed,
                                          margin, best_rate if self.single_legs else -np.inf)
            if third is not None:
                best = third
        parent, second = best
        waypoints = _leg_waypoints(pose, ends[parent])
        if second is not None and self.fly_second_leg:
            waypoints += _leg_waypoints(ends[parent], second)
        return np.array(waypoints, dtype=float)

    def _best_third_legs(self, tables, lattice: _Lattice, pairs, ends1, ranges1, valid1, images1, others, allowed,
                         margin: float, floor_rate: float):
        """(first leg's index, second leg's end) of the triple with the largest (V_1 + V_2 + V_3) /
        (t_1 + t_2 + t_3) over the ``beam_width`` pairs of largest rate, each extended by the
        third legs of :meth:`_second_candidates` from its end; None when no third leg is feasible
        or no triple's rate exceeds ``floor_rate``.

        pairs: arrays over the feasible pairs (rate, first leg's index, second leg's end (m, 3),
        layer, V_1 + V_2, t_1 + t_2); ends1, ranges1, valid1, images1: the first legs' ends, image
        ranges, validity and positions (:meth:`_leg_values`)."""
        rates, parents, ends2, layers2, values12, times12 = pairs
        best_rate, best = floor_rate, None
        for b in np.argsort(-rates, kind="stable")[:self.beam_width]:
            parent, end2, layer2, value12, time12 = int(parents[b]), ends2[b], int(layers2[b]), values12[b], times12[b]
            ends3, layers3 = self._second_candidates(end2, layer2, lattice)
            ok = self._feasible(np.broadcast_to(end2, ends3.shape), ends3, lattice, others, allowed, margin,
                                float(time12))
            if not np.any(ok):
                continue
            value3, time3 = self._third_leg_values(tables, lattice, ends1[parent], end2, layer2, _take(ranges1, parent),
                                                   valid1[parent], images1[parent], ends3[ok], layers3[ok])
            rate = (value12 + value3) / (time12 + time3)
            j = int(np.argmax(rate))
            if rate[j] > best_rate:
                best_rate, best = rate[j], (parent, end2)
        return best

    def _third_leg_values(self, tables, lattice: _Lattice, start2, end2, layer2: int, ranges1, valid1, points1,
                          ends3, layers3):
        """Value (m,) [nats] and time (m,) [s] of third legs end2 -> ends3 (m, 3) at ``layers3``
        after the second leg start2 -> end2 at ``layer2``: :meth:`_second_leg_values` with the
        chain of looks (latest first) through the second leg's images, then the first leg's
        (``ranges1``, ``valid1``, ``points1``: the first leg's, as :meth:`_leg_values` gives them)."""
        points2, valid2, _ = self._image_points(start2[None], end2[None])
        ranges2 = self._footprint_ranges(lattice, points2, np.array([layer2]), start2[None], end2[None])
        n2, n1 = int(valid2[0].sum()), int(valid1.sum())
        chain_ranges = tuple(np.concatenate([r2[0, :n2], r1[:n1]]) for r2, r1 in zip(ranges2, ranges1))
        chain_points = np.concatenate([points2[0, :n2], points1[:n1]])
        return self._second_leg_values(tables, lattice, np.broadcast_to(end2, ends3.shape), ends3, layers3,
                                       chain_ranges, np.ones(n1 + n2, dtype=bool), chain_points)

    def _value_tables(self, belief, lattice: _Lattice, radius_m: float) -> "BandedSummedAreaTables":
        """Summed-area tables (:class:`BandedSummedAreaTables`) of the value maps of ``belief``; the value maps
        are kept between calls and recomputed only where they depend on a changed cell: per
        tile (``VALUE_TILE_CELLS`` square) holding changed cells, the bounding box of those cells
        grown by the disc's reach k (a cell's value depends on the cells within k)."""
        log_odds = np.asarray(belief.log_odds, dtype=float)
        searchable = getattr(belief, "searchable", None)
        k = int(round(radius_m / lattice.cell))
        tile = max(VALUE_TILE_CELLS, 2 * k + 1)
        cache = self._cache
        fresh = (
            cache is None or cache["grid"] != belief.grid or cache["radius"] != radius_m
            or cache["searchable"] is not searchable or cache["log_odds"].shape != log_odds.shape
        )
        if not fresh:
            changed = log_odds != cache["log_odds"]
            if not changed.any():
                return cache["tables"]
            boxes = _changed_boxes(changed, tile, k)
            fresh = int(np.sum((boxes[:, 1] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 2]))) > 0.5 * log_odds.size
        if fresh:
            values = self.layer_values(_probability(log_odds, searchable), lattice.cell, radius_m)
            cache = {"grid": belief.grid, "radius": radius_m, "searchable": searchable, "log_odds": log_odds.copy(),
                     "values": values, "tables": BandedSummedAreaTables(values)}
            self._cache = cache
            return cache["tables"]
        ny, nx = log_odds.shape
        values = cache["values"]
        for r0, r1, c0, c1 in boxes:
            h0, h1, g0, g1 = max(r0 - k, 0), min(r1 + k, ny), max(c0 - k, 0), min(c1 + k, nx)
            mask = None if searchable is None else searchable[h0:h1, g0:g1]
            local = self.layer_values(_probability(log_odds[h0:h1, g0:g1], mask), lattice.cell, radius_m)
            values[:, r0:r1, c0:c1] = local[:, r0 - h0:r1 - h0, c0 - g0:c1 - g0]
        np.copyto(cache["log_odds"], log_odds)
        cache["tables"].update(values, {row // BAND_ROWS for r0, r1, _, _ in boxes for row in range(r0, r1)})
        return cache["tables"]

    def _booked_images(self, grid, others: list[np.ndarray]):
        """Windows and altitudes of the images the other UAVs will take along their plans."""
        windows, altitudes = [], []
        for path in others:
            for a, b in zip(path[:-1], path[1:]):
                length = float(np.hypot(*(b[:2] - a[:2])))
                n = max(1, int(round(length / self.image_spacing_m)))
                for j in range(n):
                    point = b + (a - b) * (j * self.image_spacing_m / length if length > 0 else 0.0)
                    h = float(b[2])
                    width_x, width_y = self.camera.footprint_m(h)
                    if self.footprint_follows_heading and abs(b[0] - a[0]) > abs(b[1] - a[1]):
                        width_x, width_y = width_y, width_x  # an east-west leg: across-track along y
                    windows.append(grid.window(float(point[0]), float(point[1]), float(width_x), float(width_y)))
                    altitudes.append(h)
        return windows, altitudes

    def _first_candidates(self, pose, lattice: _Lattice, tables: np.ndarray, belief, allowed):
        """First-leg end points (m, 3) and their layer indices (m,); allowed: the legs' filter (or None)."""
        n_layers = len(self.altitude_layers_m)
        smallest = 2 * float(self._half_widths[:, 0].min())
        distances = np.geomspace(max(smallest / 2, lattice.cell), max(self.horizon_m, smallest), FIRST_DISTANCES)
        headings = self.rng.uniform(0, 2 * np.pi) + np.arange(FIRST_HEADINGS) * (2 * np.pi / FIRST_HEADINGS)
        dx = (distances[:, None] * np.cos(headings)[None]).ravel()
        dy = (distances[:, None] * np.sin(headings)[None]).ravel()
        xy = [np.column_stack([pose[0] + dx, pose[1] + dy]), pose[None, :2]]
        # over the most probable cells within the horizon
        r0, r1, c0, c1 = lattice.ranges(pose[0], pose[1], self.horizon_m, self.horizon_m)
        searchable = getattr(belief, "searchable", None)
        near = _probability(belief.log_odds[r0:r1, c0:c1], None if searchable is None else searchable[r0:r1, c0:c1])
        if near.size:
            count = min(PEAK_CELLS, near.size)
            flat = np.argpartition(near.ravel(), near.size - count)[near.size - count:]
            rows, cols = np.unravel_index(flat, near.shape)
            cx, cy = lattice.cell_centre(rows + r0, cols + c0)
            xy.append(np.column_stack([cx, cy]))
        xy = np.vstack(xy)
        ends = [np.column_stack([xy, np.full(len(xy), h)]) for h in self.altitude_layers_m]
        layers = [np.full(len(xy), k) for k in range(n_layers)]
        # straight to the best coarse blocks of the whole area
        far = self._long_range_targets(pose, lattice, tables)
        if len(far) and self.route_toward is not None and allowed is not None:
            blocked = ~np.asarray(allowed(np.broadcast_to(pose, (len(far), 3)), far[:, :3]), dtype=bool)
            for i in np.flatnonzero(blocked):
                far[i, :2] = self.route_toward(pose.copy(), far[i, :3].copy())
        if len(far):
            ends.append(far[:, :3])
            layers.append(far[:, 3].astype(np.intp))
        return np.vstack(ends), np.concatenate(layers)

    def _long_range_targets(self, pose, lattice: _Lattice, tables: np.ndarray) -> np.ndarray:
        """(k, 4) rows (x, y, h, layer): centres of the blocks (one footprint each, tiling the
        map) with the largest value per second of flying there and imaging them, per layer."""
        out = []
        for layer, h in enumerate(self.altitude_layers_m):
            bx = max(1, int(2 * self._half_widths[0, layer] / lattice.cell))
            by = max(1, int(2 * self._half_widths[1, layer] / lattice.cell))
            r0 = np.arange(0, lattice.ny, by)
            c0 = np.arange(0, lattice.nx, bx)
            r1, c1 = np.minimum(r0 + by, lattice.ny), np.minimum(c0 + bx, lattice.nx)
            table = self._table_offset[layer]  # T_1: the value of a first look
            block = tables.sums(table, r0[:, None], r1[:, None], c0[None, :], c1[None, :])
            cx, _ = lattice.cell_centre(0, (c0 + c1 - 1) / 2)
            _, cy = lattice.cell_centre((r0 + r1 - 1) / 2, 0)
            distance = np.hypot(cx[None, :] - pose[0], cy[:, None] - pose[1])
            seconds = distance / self.speed_m_s + abs(h - pose[2]) / self.climb_speed_m_s + 1.0 / self.image_rate_hz
            score = block / seconds
            count = min(LONG_RANGE_BLOCKS, score.size)
            flat = np.argpartition(score.ravel(), score.size - count)[score.size - count:]
            rows, cols = np.unravel_index(flat, score.shape)
            for i, j in zip(rows, cols):
                if block[i, j] > 0:
                    out.append((cx[j], cy[i], h, layer))
        return np.array(out, dtype=float).reshape(-1, 4)

    def _second_candidates(self, start, layer: int, lattice: _Lattice):
        """Second-leg end points (m, 3) from ``start`` at the start's layer and its neighbours, and their layers."""
        n_layers = len(self.altitude_layers_m)
        smallest = 2 * float(self._half_widths[:, 0].min())
        distances = np.geomspace(max(smallest, lattice.cell), max(self.horizon_m / 2, smallest), SECOND_DISTANCES)
        headings = np.arange(SECOND_HEADINGS) * (2 * np.pi / SECOND_HEADINGS)
        dx = (distances[:, None] * np.cos(headings)[None]).ravel()
        dy = (distances[:, None] * np.sin(headings)[None]).ravel()
        xy = np.column_stack([start[0] + dx, start[1] + dy])
        chosen = [k for k in (layer - 1, layer, layer + 1) if 0 <= k < n_layers]
        ends = np.vstack([np.column_stack([xy, np.full(len(xy), self.altitude_layers_m[k])]) for k in chosen])
        layers = np.concatenate([np.full(len(xy), k) for k in chosen])
        return ends, layers

    def _feasible(self, starts, ends, lattice: _Lattice, others: list[np.ndarray], allowed,
                  margin_m: float = OBSTACLE_MARGIN_M, delay_s: float = 0.0):
        """(m,) mask of legs inside the map and altitude limits, ``margin_m`` clear of buildings,
        passed by ``allowed`` (None: every leg), ending ``min_separation_m`` from the other UAVs'
        poses and waypoints and kept apart from them in flight (:meth:`_kept_apart`; the leg
        starts ``delay_s`` [s] from now)."""
        x0, x1, y0, y1 = lattice.extent
        low, high = self.altitude_limits_m
        ok = (ends[:, 0] >= x0) & (ends[:, 0] <= x1) & (ends[:, 1] >= y0) & (ends[:, 1] <= y1)
        ok &= (ends[:, 2] >= low - 1e-9) & (ends[:, 2] <= high + 1e-9)
        if self.buildings:
            corner = np.column_stack([starts[:, :2], ends[:, 2]])
            for box in self.buildings:
                bounds = tuple(box.bounds)
                ok &= ~segments_hit_box(starts, corner, bounds, margin_m)
                ok &= ~segments_hit_box(corner, ends, bounds, margin_m)
        if allowed is not None and ok.any():
            ok[ok] &= np.asarray(allowed(starts[ok], ends[ok]), dtype=bool)
        if others and self.min_separation_m > 0:
            points = np.vstack(others)
            gap = np.sqrt(((ends[:, None, :] - points[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
            ok &= gap >= self.min_separation_m
            ok &= self._kept_apart(starts, ends, others, delay_s)
        return ok

    def _kept_apart(self, starts, ends, others: list[np.ndarray], delay_s: float) -> np.ndarray:
        """(m,) mask of legs along which the UAV stays ``min_separation_m`` from every other UAV
        flying its plan (at v, then hovering at its end), or at least does not close in on one it
        is already nearer than that; the leg starts ``delay_s`` from now, is flown altitude change
        first at v, and both are compared at ``SEPARATION_SAMPLES`` times along it."""
        fraction = np.linspace(0.0, 1.0, SEPARATION_SAMPLES)
        vertical = np.abs(ends[:, 2] - starts[:, 2])
        horizontal = np.hypot(ends[:, 0] - starts[:, 0], ends[:, 1] - starts[:, 1])
        length = vertical + horizontal
        walked = length[:, None] * fraction[None, :]  # (m, S) distance along the leg
        up = np.clip(walked / np.maximum(vertical[:, None], _EPS), 0.0, 1.0)
        level = np.clip((walked - vertical[:, None]) / np.maximum(horizontal[:, None], _EPS), 0.0, 1.0)
        mine = np.empty(walked.shape + (3,))
        mine[..., 2] = starts[:, None, 2] + up * (ends[:, None, 2] - starts[:, None, 2])
        for axis in (0, 1):
            mine[..., axis] = starts[:, None, axis] + level * (ends[:, None, axis] - starts[:, None, axis])
        ok = np.ones(len(starts), dtype=bool)
        for path in others:
            theirs = _along_path(path, delay_s * self.speed_m_s + walked)  # (m, S, 3)
            gap = np.linalg.norm(mine - theirs, axis=2)
            closing = (gap < self.min_separation_m) & (gap < gap[:, :1] - 1e-9)
            ok &= ~closing.any(axis=1)
        return ok

    def _image_points(self, starts, ends):
        """Image positions (m, n, 2) along legs (last image at the end), validity (m, n), time (m,)."""
        delta = ends[:, :2] - starts[:, :2]
        length = np.hypot(delta[:, 0], delta[:, 1])
        count = np.maximum(1, np.round(length / self.image_spacing_m)).astype(np.intp)
        n = int(count.max())
        back = np.arange(n)[None, :] * self.image_spacing_m  # distance back from the end
        valid = np.arange(n)[None, :] < count[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            unit = np.where(length[:, None] > 0, delta / np.maximum(length[:, None], _EPS), 0.0)
        along = np.clip(length[:, None] - back, 0.0, None)
        points = starts[:, None, :2] + unit[:, None, :] * along[..., None]
        seconds = length / self.speed_m_s + np.abs(ends[:, 2] - starts[:, 2]) / self.climb_speed_m_s
        seconds = np.maximum(seconds, count / self.image_rate_hz)
        return points, valid, seconds

    def _footprint_ranges(self, lattice: _Lattice, points, layers, starts=None, ends=None):
        """Index ranges of the footprints of images at ``points`` (m, n, 2) from ``layers`` (m,),
        on legs starts -> ends (m, 3) (their headings orient the footprints when
        ``footprint_follows_heading``)."""
        half_x = self._half_widths[0, layers]
        half_y = self._half_widths[1, layers]
        if self.footprint_follows_heading and starts is not None:
            east_west = np.abs(ends[:, 0] - starts[:, 0]) > np.abs(ends[:, 1] - starts[:, 1])
            half_x, half_y = np.where(east_west, half_y, half_x), np.where(east_west, half_x, half_y)
        return lattice.ranges(points[..., 0], points[..., 1], half_x[:, None], half_y[:, None])

    def _chain_values(self, tables, lay, ranges, predecessors):
        """Per image (m, n): T_1(F_j) + sum_i T_{i+1}(F_j ∩ F_{j-i}) over the images' i-th
        predecessors in time (``predecessors[i - 1]``: (ranges, valid)), i = 1 .. the most."""
        value = _table_sums(tables, self._table_index[lay, 0], ranges)
        for i, (previous, has) in enumerate(predecessors, start=1):
            if i >= self._table_index.shape[1]:
                break
            term = _table_sums(tables, self._table_index[lay, i], _intersect(ranges, previous))
            value = value + np.where(has, term, 0.0)
        return value

    def _leg_values(self, tables, lattice: _Lattice, starts, ends, layers):
        """Value (m,) [nats] of each leg's images (a cell's k-th look along the leg worth
        Delta_k), time (m,) [s], and the image ranges, validity and positions (for the second
        leg)."""
        points, valid, seconds = self._image_points(starts, ends)
        ranges = self._footprint_ranges(lattice, points, layers, starts, ends)
        lay = np.broadcast_to(layers[:, None], valid.shape)
        n = valid.shape[1]
        # images are ordered from the end backwards: image j's i-th predecessor in time is j + i
        predecessors = []
        for i in range(1, min(n, int(self._looks.max()) + 1)):
            shifted = tuple(np.concatenate([r[:, i:], np.repeat(r[:, -1:], i, axis=1)], axis=1) for r in ranges)
            has = np.concatenate([valid[:, i:], np.zeros((len(valid), i), dtype=bool)], axis=1)
            predecessors.append((shifted, has))
        per_image = self._chain_values(tables, lay, ranges, predecessors)
        net = np.where(valid, np.maximum(per_image, 0.0), 0.0)
        return net.sum(axis=1), seconds, ranges, valid, points

    def _second_leg_values(self, tables, lattice: _Lattice, starts, ends, layers, ranges1, valid1, points1):
        """Value (m,) and time (m,) of second legs: the chain of looks continues through the
        first leg's images (its last image the earliest image's predecessor); each image loses
        at least what it would lose if the nearest image of the first leg had seen its cells
        once before (-T_2 over their intersection: the larger loss is taken)."""
        points, valid, seconds = self._image_points(starts, ends)
        ranges = self._footprint_ranges(lattice, points, layers, starts, ends)
        lay = np.broadcast_to(layers[:, None], valid.shape)
        count = valid.sum(axis=1)
        count1 = int(valid1.sum())
        idx = np.arange(valid.shape[1])[None, :]
        predecessors = []
        for i in range(1, int(self._looks.max()) + 1):
            own = idx + i < count[:, None]
            own_index = np.minimum(idx + i, valid.shape[1] - 1)
            first_index = np.clip(idx + i - count[:, None], 0, max(count1 - 1, 0))
            previous = tuple(np.where(own, np.take_along_axis(r, own_index, axis=1), r1[first_index])
                             for r, r1 in zip(ranges, ranges1))
            has = own | (idx + i - count[:, None] < count1)
            predecessors.append((previous, has))
        own_value = _table_sums(tables, self._table_index[lay, 0], ranges)
        chain = self._chain_values(tables, lay, ranges, predecessors)
        # nearest image of the first leg
        p1 = points1[valid1]
        r1 = tuple(r[valid1] for r in ranges1)
        d2 = ((points[:, :, None, :] - p1[None, None, :, :]) ** 2).sum(axis=3)
        nearest = np.argmin(d2, axis=2)
        near_ranges = tuple(r[nearest] for r in r1)
        near_loss = -_table_sums(tables, self._table_index[lay, 1], _intersect(ranges, near_ranges))
        net = np.where(valid, np.maximum(np.minimum(chain, own_value - near_loss), 0.0), 0.0)
        return net.sum(axis=1), seconds


def _probability(log_odds: np.ndarray, searchable: np.ndarray | None) -> np.ndarray:
    """p = 1 / (1 + exp(-l)), 0 where not searchable."""
    p = logistic(np.asarray(log_odds, dtype=float))
    return p if searchable is None else np.where(searchable, p, 0.0)


def _changed_boxes(changed: np.ndarray, tile: int, reach: int) -> np.ndarray:
    """(b, 4) boxes (r0, r1, c0, c1), half-open: per tile of ``tile`` cells holding a changed
    cell, the bounding box of its changed cells grown by ``reach`` cells, clipped to the map."""
    ny, nx = changed.shape
    rows, cols = np.nonzero(changed)
    tiles_per_row = (nx + tile - 1) // tile
    tile_of = (rows // tile) * tiles_per_row + cols // tile
    order = np.argsort(tile_of, kind="stable")
    rows, cols, tile_of = rows[order], cols[order], tile_of[order]
    starts = np.flatnonzero(np.r_[True, np.diff(tile_of) != 0])
    boxes = np.column_stack([
        np.maximum(np.minimum.reduceat(rows, starts) - reach, 0),
        np.minimum(np.maximum.reduceat(rows, starts) + 1 + reach, ny),
        np.maximum(np.minimum.reduceat(cols, starts) - reach, 0),
        np.minimum(np.maximum.reduceat(cols, starts) + 1 + reach, nx),
    ])
    return boxes.astype(np.intp)


def _along_path(path: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """Points (..., 3) at ``distance_m`` along the polyline ``path`` (k, 3) from its first point
    (its last point beyond its end)."""
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    if len(steps) == 0 or steps.sum() <= 0:
        return np.broadcast_to(path[0], np.shape(distance_m) + (3,))
    cumulative = np.concatenate([[0.0], np.cumsum(steps)])
    d = np.clip(distance_m, 0.0, cumulative[-1])
    return np.stack([np.interp(d, cumulative, path[:, axis]) for axis in range(3)], axis=-1)


def _table_sums(tables: BandedSummedAreaTables, layers, ranges):
    r0, r1, c0, c1 = ranges
    return tables.sums(layers, r0, r1, c0, c1)


def _leg_waypoints(start, end) -> list[np.ndarray]:
    """A leg flown as an altitude change at its start (when there is one), then level flight."""
    out = []
    if abs(end[2] - start[2]) > 1e-9 and np.hypot(end[0] - start[0], end[1] - start[1]) > 1e-9:
        out.append(np.array([start[0], start[1], end[2]]))
    out.append(np.asarray(end, dtype=float).copy())
    return out


def _is_number(value) -> bool:
    return (
        isinstance(value, (int, float, np.integer, np.floating))
        and not isinstance(value, (bool, np.bool_))
        and bool(np.isfinite(value))
    )
