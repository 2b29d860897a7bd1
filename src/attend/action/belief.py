"""Occupancy map with its covariance (precision map), Gaussian-process prior and Kalman fusion.

Belief over the flat occupancy vector x (n cells): x ~ N(mean, P).

Prior: mean 0.1 everywhere; P from a Gaussian process with a Matern-3/2 kernel over cell
indices,  k(d) = s2 (1 + sqrt(3) d / l) exp(-sqrt(3) d / l)  (d: distance in cells, l = 3.67
cells, s2 = 1.82), conditioned as in the anchors:  P = K - K (K + r0 I)^-1 K,  r0 = 2.01.
trace(P) = 386.6 on the 40 x 40 grid.

Fusion of an image observing cells A with measurements z and noise variance r (H selects A):
    S = H P H' + r I,  G = P H' S^-1,  mean <- mean + G (z - H mean),  P <- P - G H P.
The diagonal option keeps only diag(P) and updates each observed cell alone:
    v <- v r / (v + r),  mean <- mean + v / (v + r) (z - mean).
Precision map: 1 / diag(P).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg
import scipy.ndimage

from attend.action.field import Grid


def matern32(distance: np.ndarray, length_scale: float, signal_variance: float) -> np.ndarray:
    """Matern-3/2 kernel  k(d) = s2 (1 + sqrt(3) d / l) exp(-sqrt(3) d / l).

    distance: d (any shape); length_scale: l, in the units of d; signal_variance: s2."""
    scaled = np.sqrt(3.0) * np.asarray(distance) / length_scale
    return signal_variance * (1 + scaled) * np.exp(-scaled)


@dataclass(frozen=True)
class GaussianProcessPrior:
    """The map prior x ~ N(mean 1, P), P = K - K (K + r0 I)^-1 K, K the Matern-3/2 kernel
    k(d) = s2 (1 + sqrt(3) d / l) exp(-sqrt(3) d / l) over cell indices (d in cells).

    mean: prior occupancy of every cell; length_scale_cells: l [cells]; signal_variance: s2;
    noise_variance: r0 (the anchors condition the GP on one reading of noise r0 per cell).
    """

    mean: float = 0.1
    length_scale_cells: float = 3.67
    signal_variance: float = 1.82
    noise_variance: float = 2.01

    def build_covariance(self, cells_per_side: int) -> np.ndarray:
        """Compute P = K - K (K + r0 I)^-1 K afresh (n x n, n = cells_per_side^2; uncached, for timing).

        cells_per_side: side of the square grid in cells."""
        grid = Grid(cells_per_side=int(cells_per_side))
        index = grid.cell_indices().astype(float)
        distance = np.sqrt(((index[:, None, :] - index[None, :, :]) ** 2).sum(-1))
        kernel = matern32(distance, float(self.length_scale_cells), float(self.signal_variance))
        # P = K - K (K + r0 I)^-1 K = r0 K (K + r0 I)^-1 ; solve with the SPD factor of K + r0 I.
        factor = scipy.linalg.cho_factor(kernel + float(self.noise_variance) * np.eye(len(kernel)))
        covariance = kernel - kernel @ scipy.linalg.cho_solve(factor, kernel)
        return 0.5 * (covariance + covariance.T)

    def covariance(self, cells_per_side: int) -> np.ndarray:
        """Prior covariance P (n x n, n = cells_per_side^2), read-only and shared (cached): copy
        before changing it.

        cells_per_side: side of the square grid in cells."""
        return _cached_covariance(self, int(cells_per_side))

    def variance(self, cells_per_side: int) -> np.ndarray:
        """Prior per-cell variance diag(P) (n,); cells_per_side: side of the square grid in cells."""
        return np.diag(self.covariance(cells_per_side)).copy()


@lru_cache(maxsize=4)
def _cached_covariance(prior: GaussianProcessPrior, cells_per_side: int) -> np.ndarray:
    covariance = prior.build_covariance(cells_per_side)
    covariance.setflags(write=False)
    return covariance


#: The anchors' prior for the 40 x 40 grid of 0.75 m cells (ICRA'19): trace(P) = 386.6.
PAPER_PRIOR = GaussianProcessPrior()


def prior_covariance(cells_per_side: int = 40, prior: GaussianProcessPrior = PAPER_PRIOR) -> np.ndarray:
    """Prior map covariance P = K - K (K + r0 I)^-1 K (a fresh copy, n x n).

    cells_per_side: side of the square grid in cells; prior: the GP hyperparameters."""
    return prior.covariance(cells_per_side).copy()


def kalman_update(
    mean: np.ndarray, covariance: np.ndarray, cells: np.ndarray, measurements: np.ndarray, noise_variance: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Full-covariance Kalman update for observations of ``cells`` (returns new mean and P):
    S = P_AA + R, mean' = mean + P_:A S^-1 (z - mean_A), P' = P - P_:A S^-1 P_A:.

    mean: (n,); covariance: P (n, n); cells: the observed cells A; measurements: z (m,);
    noise_variance: r, one for all or (m,)."""
    cells = np.asarray(cells)
    if len(cells) == 0:
        return mean.copy(), covariance.copy()
    r = np.broadcast_to(np.asarray(noise_variance, dtype=float), (len(cells),))
    cross = covariance[:, cells]  # P H'  (n, m)
    innovation_cov = cross[cells] + np.diag(r)  # S = H P H' + R
    factor = scipy.linalg.cho_factor(innovation_cov, lower=True, check_finite=False)
    gain_t = scipy.linalg.cho_solve(factor, cross.T, check_finite=False)  # S^-1 H P = G'
    new_mean = mean + gain_t.T @ (measurements - mean[cells])
    new_cov = covariance - cross @ gain_t
    new_cov = 0.5 * (new_cov + new_cov.T)
    return new_mean, new_cov


def kalman_update_diagonal(
    mean: np.ndarray, variance: np.ndarray, cells: np.ndarray, measurements: np.ndarray, noise_variance: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per-cell Kalman update:  v <- v r / (v + r),  mean <- mean + v / (v + r) (z - mean).

    mean, variance: (n,); cells: the observed cells; measurements: z; noise_variance: r."""
    new_mean, new_var = mean.copy(), variance.copy()
    v = variance[cells]
    gain = v / (v + noise_variance)
    new_mean[cells] = mean[cells] + gain * (measurements - mean[cells])
    new_var[cells] = v * (1 - gain)
    return new_mean, new_var


def connected_groups(marked: np.ndarray, grid: Grid, min_cells: int = 1) -> list[np.ndarray]:
    """Cell indices of each connected group (8-neighbourhood) of at least ``min_cells`` cells of
    the (n,) mask ``marked``; grid: the map's :class:`Grid` (n = cells_per_side^2 cells, row-major)."""
    if not marked.any():
        return []
    labels, n = scipy.ndimage.label(marked.reshape(grid.shape), structure=np.ones((3, 3)))
    groups = [np.flatnonzero(labels.ravel() == g) for g in range(1, n + 1)]
    return [cells for cells in groups if len(cells) >= min_cells]


@dataclass
class OccupancyMap:
    """Belief N(mean, P) over the occupancy of the ``grid`` cells.

    mean: (n,) occupancy estimate; covariance: (n, n) P when ``diagonal`` is False, else the
    (n,) per-cell variances diag(P). reading_precision, reading_sum: (n,) the data term of the
    information form kept beside the map, sum over images of 1 / r and of z / r per cell (zeros
    for the prior): the raw readings the map has fused, before the prior smooths them;
    blob_detection_count: (n,) how many of those readings were detections (z > 0.5) inside a
    detected blob of at least 2 cells (8-neighbourhood) of the same image: person-sized
    detections, not isolated false positives.
    """

    grid: Grid
    mean: np.ndarray
    covariance: np.ndarray
    diagonal: bool = False
    reading_precision: np.ndarray | None = None
    reading_sum: np.ndarray | None = None
    blob_detection_count: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.reading_precision is None:
            self.reading_precision = np.zeros(self.grid.n_cells)
        if self.reading_sum is None:
            self.reading_sum = np.zeros(self.grid.n_cells)
        if self.blob_detection_count is None:
            self.blob_detection_count = np.zeros(self.grid.n_cells, dtype=int)

    @classmethod
    def prior(cls, grid: Grid, diagonal: bool = False, prior: GaussianProcessPrior = PAPER_PRIOR) -> "OccupancyMap":
        """The belief before any image: mean ``prior.mean`` everywhere, covariance
        ``prior.covariance``.

        grid: the map's grid; diagonal: keep only diag(P) (per-cell filter); prior: the GP prior."""
        covariance = prior_covariance(grid.cells_per_side, prior)
        if diagonal:
            covariance = np.diag(covariance).copy()
        return cls(grid, np.full(grid.n_cells, prior.mean), covariance, diagonal)

    @property
    def variance(self) -> np.ndarray:
        """Per-cell variance diag(P), (n,)."""
        return self.covariance if self.diagonal else np.diag(self.covariance).copy()

    def precision_map(self) -> np.ndarray:
        """Precision 1 / diag(P) as an image (ny, nx)."""
        return (1.0 / self.variance).reshape(self.grid.shape)

    def trace(self) -> float:
        """trace(P)."""
        return float(self.covariance.sum() if self.diagonal else np.trace(self.covariance))

    def fuse(self, cells: np.ndarray, measurements: np.ndarray, noise_variance: float) -> None:
        """Kalman update with one image (in place), also adding its readings to the reading
        statistics.

        cells: the observed cells; measurements: their readings z; noise_variance: r of the image."""
        update = kalman_update_diagonal if self.diagonal else kalman_update
        self.mean, self.covariance = update(self.mean, self.covariance, cells, measurements, noise_variance)
        cells = np.asarray(cells, dtype=int)
        np.add.at(self.reading_precision, cells, 1.0 / noise_variance)
        np.add.at(self.reading_sum, cells, np.asarray(measurements, dtype=float) / noise_variance)
        detected = np.zeros(self.grid.n_cells, dtype=bool)
        detected[cells[np.asarray(measurements, dtype=float) > 0.5]] = True
        for blob in connected_groups(detected, self.grid, min_cells=2):
            self.blob_detection_count[blob] += 1

    def mean_reading(self) -> np.ndarray:
        """Precision-weighted mean reading per cell, sum(z / r) / sum(1 / r) (n,): 1 where every
        image detected the cell, 0.05 where none did; 0 for cells never observed."""
        observed = self.reading_precision > 0
        return np.where(observed, self.reading_sum / np.where(observed, self.reading_precision, 1.0), 0.0)

    def copy(self) -> "OccupancyMap":
        """An independent copy (its arrays copied)."""
        return OccupancyMap(self.grid, self.mean.copy(), self.covariance.copy(), self.diagonal,
                            self.reading_precision.copy(), self.reading_sum.copy(), self.blob_detection_count.copy())


def observation_gains(
    covariance: np.ndarray,
    cell_precision: np.ndarray,
    weighted_square: np.ndarray | None = None,
    diagonal: bool = False,
    cell_weights: np.ndarray | None = None,
    want_information: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Covariance-only value of k candidate observation sets, evaluated as one batch.

    cell_precision: (k, n) summed measurement precision per cell, d_i = sum over images 1 / r
    (exact for the covariance: P_post = (P^-1 + D)^-1 whatever the order of the images).
    Returns the trace reduction  tr(W (P - P_post))  and, if asked, the information gain
    0.5 log det(I + D^1/2 P D^1/2)  (nats), both (k,).

    Full P: restrict to the observed set A of each candidate (padded to a common size) and use
    T = I + D^1/2 P_AA D^1/2 = L L':  tr(W (P - P_post)) = tr(T^-1 D^1/2 (P W P)_AA D^1/2),
    0.5 log det T = sum log diag L. ``weighted_square`` is P W P (precomputed once per replan).
    covariance: P (n, n), or diag(P) (n,) when ``diagonal``; cell_weights: W = diag(w) (None:
    W = I); want_information: also return the information (else None).
    Diagonal P: per cell, v - 1 / (1 / v + d).
    """
    precision = np.atleast_2d(cell_precision)
    k, n = precision.shape
    if diagonal:
        variance = covariance
        posterior = 1.0 / (1.0 / variance[None, :] + precision)
        reduction = variance[None, :] - posterior
        weights = np.ones(n) if cell_weights is None else cell_weights
        trace_reduction = (reduction * weights[None, :]).sum(axis=1)
        information = 0.5 * np.log1p(precision * variance[None, :]).sum(axis=1) if want_information else None
        return trace_reduction, information
    if weighted_square is None:
        weighted = covariance if cell_weights is None else covariance * cell_weights[None, :]
        weighted_square = weighted @ covariance
    observed = precision > 0
    counts = observed.sum(axis=1)
    size = max(int(counts.max()), 1)
    order = np.argsort(~observed, axis=1, kind="stable")[:, :size]  # observed cells first
    valid = np.arange(size)[None, :] < counts[:, None]
    order = np.where(valid, order, 0)
    root_d = np.where(valid, np.sqrt(np.take_along_axis(precision, order, axis=1)), 0.0)
    rows, cols = order[:, :, None], order[:, None, :]
    scale = root_d[:, :, None] * root_d[:, None, :]
    t_matrix = covariance[rows, cols] * scale
    t_matrix[:, np.arange(size), np.arange(size)] += 1.0
    lower = np.linalg.cholesky(t_matrix)
    g_matrix = weighted_square[rows, cols] * scale
    identity = np.broadcast_to(np.eye(size), t_matrix.shape)
    lower_inv = scipy.linalg.solve_triangular(lower, identity, lower=True, check_finite=False)
    # tr(T^-1 G) = sum((L^-1 G) * L^-1)
    trace_reduction = np.einsum("kij,kij->k", lower_inv @ g_matrix, lower_inv)
    information = None
    if want_information:
        information = np.log(np.diagonal(lower, axis1=1, axis2=2)).sum(axis=1)
    return trace_reduction, information
