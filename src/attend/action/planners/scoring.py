"""Covariances the informative planners score candidate images on during one replan.

:class:`ScreeningModel` screens every candidate in one numpy batch (optionally on a
coarse-grained covariance); :class:`ExactModel` re-scores the best few on the exact full
covariance, reading only the rows of the observed cells.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from attend.action.belief import OccupancyMap, observation_gains
from attend.action.planners.base import PlanningSetup


class ScreeningModel:
    """Covariance used to screen candidates during one replan (conditioned between greedy steps):
    the belief's P, or with ``planning_block_cells`` b > 1 the coarse-grained P_b = B P B' over
    blocks of b^2 cells (B averages a block; observing c cells of a block with noise r counts as
    precision c / r on the block mean; gains scaled back by the block area b^2).

    belief: the current map; setup: the planning setup (block size); cell_weights: (n,) weights W
    of the trace reduction tr(W (P - P_post)), or None for W = I.
    """

    def __init__(self, belief: OccupancyMap, setup: PlanningSetup, cell_weights: np.ndarray | None) -> None:
        self.diagonal = belief.diagonal
        self.block = 1 if belief.diagonal else setup.planning_block_cells
        grid = belief.grid
        side = grid.cells_per_side
        nb = side // self.block
        iy, ix = np.divmod(np.arange(grid.n_cells), side)
        self.block_of_cell = (iy // self.block) * nb + ix // self.block
        self.n_blocks = nb * nb
        self.area = self.block**2
        weights = np.ones(grid.n_cells) if cell_weights is None else cell_weights
        if self.diagonal:
            self.covariance = belief.covariance.copy()
            self.weights = weights
        elif self.block == 1:
            self.covariance = belief.covariance.copy()
            self.weights = weights
        else:
            b = self.block
            n = grid.n_cells
            rows = belief.covariance.reshape(n, nb, b, nb, b).sum(axis=(2, 4)).reshape(n, self.n_blocks)
            blocks = rows.T.reshape(self.n_blocks, nb, b, nb, b).sum(axis=(2, 4)).reshape(self.n_blocks, self.n_blocks)
            self.covariance = blocks / self.area**2  # B P B', B averaging each block
            self.weights = weights.reshape(nb, b, nb, b).mean(axis=(1, 3)).ravel()
        self._refresh()

    def copy(self) -> "ScreeningModel":
        twin = object.__new__(ScreeningModel)
        twin.__dict__.update(self.__dict__)
        twin.covariance = self.covariance.copy()
        return twin

    def _refresh(self) -> None:
        self.weighted_square = None if self.diagonal else (self.covariance * self.weights[None, :]) @ self.covariance

    def precision(self, visible: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
        """Per-(block) measurement precision d (k, n_b) = sum_j visible_j / r_j.

        visible: (k, J, n) visibility masks of J images per candidate; noise_variance: (k, J) r."""
        per_cell = np.einsum("kjn,kj->kn", visible, 1.0 / noise_variance)
        if self.block == 1:
            return per_cell
        out = np.zeros((len(per_cell), self.n_blocks))
        np.add.at(out.T, self.block_of_cell, per_cell.T)
        return out

    def gains(
        self, precision: np.ndarray, want_information: bool = False, want_reduction: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Trace reduction tr(W (P - P_post)) (k,) and, if asked, information 0.5 log det(I + D^1/2 P D^1/2) (k,).

        precision: (k, n) summed measurement precision d per candidate; want_information: also
        return the information (else None); want_reduction: compute the trace reduction."""
        reduction, information = observation_gains(
            self.covariance,
            precision,
            weighted_square=self.weighted_square,
            diagonal=self.diagonal,
            cell_weights=self.weights,
            want_information=want_information,
        )
        return reduction * self.area, information

    def condition(self, precision: np.ndarray) -> None:
        """Covariance-only update P <- (P^-1 + D)^-1; precision: d (n_b,) per (block) cell."""
        if self.diagonal:
            self.covariance = 1.0 / (1.0 / self.covariance + precision)
            return
        observed = np.flatnonzero(precision > 0)
        if len(observed) == 0:
            return
        cross = self.covariance[:, observed]
        innovation = cross[observed] + np.diag(1.0 / precision[observed])
        self.covariance = self.covariance - cross @ np.linalg.solve(innovation, cross.T)
        self.covariance = 0.5 * (self.covariance + self.covariance.T)
        self._refresh()


class ExactModel:
    """Exact full covariance for re-scoring a few candidates, conditioned between greedy steps
    (belief: the current map; cell_weights: (n,) weights W, or None for W = I).

    Kept as P_g = P - U U' (P the belief's covariance, untouched; U n x q grows by the m cells of
    each chosen image set), so a candidate reads only the rows P_g[A, :] = P[A, :] - U_A U' of the
    m cells A it observes (summed precision d_A). With S = (P_g)_AA + D_A^-1 = L L':

        tr(W (P_g - P_post)) = tr(S^-1 (P_g)_A: W (P_g)_:A) = || L^-1 (P_g)_A: W^1/2 ||_F^2
        0.5 log det(I + D^1/2 (P_g)_AA D^1/2) = sum log diag L + 0.5 sum log d_A

    costs m q n + m^2 n + m^3 / 3 per candidate (information only: m^2 q + m^3 / 3), no n x n
    products.
    """

    def __init__(self, belief: OccupancyMap, cell_weights: np.ndarray | None) -> None:
        self.covariance = belief.covariance
        self.low_rank = np.zeros((len(belief.covariance), 0))
        self.root_weights = None if cell_weights is None else np.sqrt(np.maximum(cell_weights, 0.0))
        self.block, self.area = 1, 1

    def copy(self) -> "ExactModel":
        twin = object.__new__(ExactModel)
        twin.__dict__.update(self.__dict__)
        return twin

    def precision(self, visible: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
        """Per-cell measurement precision d (k, n) = sum_j visible_j / r_j.

        visible: (k, J, n) visibility masks of J images per candidate; noise_variance: (k, J) r."""
        return np.einsum("kjn,kj->kn", visible, 1.0 / noise_variance)

    def _rows(self, observed: np.ndarray, columns: np.ndarray | None = None) -> np.ndarray:
        """(P_g)[observed, columns] (all columns when None)."""
        if columns is None:
            rows = self.covariance[observed]
            return rows - self.low_rank[observed] @ self.low_rank.T if self.low_rank.shape[1] else rows
        rows = self.covariance[np.ix_(observed, columns)]
        return rows - self.low_rank[observed] @ self.low_rank[columns].T if self.low_rank.shape[1] else rows

    def _factor(self, d: np.ndarray, full_rows: bool):
        observed = np.flatnonzero(d > 0)
        rows = self._rows(observed) if full_rows else None
        s_matrix = rows[:, observed] if full_rows else self._rows(observed, observed)
        s_matrix = s_matrix + np.diag(1.0 / d[observed])
        return observed, rows, scipy.linalg.cholesky(s_matrix, lower=True, check_finite=False)

    def gains(
        self, precision: np.ndarray, want_information: bool = False, want_reduction: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Trace reduction tr(W (P - P_post)) (k,) and, if asked, information 0.5 log det(I + D^1/2 P D^1/2) (k,).

        precision: (k, n) summed measurement precision d per candidate; want_information: also
        return the information (else None); want_reduction: compute the trace reduction."""
        precision = np.atleast_2d(precision)
        reduction = np.zeros(len(precision))
        information = np.zeros(len(precision)) if want_information else None
        for k, d in enumerate(precision):
            if not np.any(d > 0):
                continue
            observed, rows, lower = self._factor(d, full_rows=want_reduction)
            if want_reduction:
                if self.root_weights is not None:
                    rows = rows * self.root_weights[None, :]
                solved = scipy.linalg.solve_triangular(lower, rows, lower=True, check_finite=False)
                reduction[k] = np.einsum("ij,ij->", solved, solved)
            if want_information:
                information[k] = np.log(np.diagonal(lower)).sum() + 0.5 * np.log(d[observed]).sum()
        return reduction, information

    def condition(self, precision: np.ndarray) -> None:
        """P_g <- P_g - (P_g)_:A S^-1 (P_g)_A:  (appends L^-1 (P_g)_A: to U); precision: d (n,) per cell."""
        if not np.any(precision > 0):
            return
        _, rows, lower = self._factor(precision, full_rows=True)
        half = scipy.linalg.solve_triangular(lower, rows, lower=True, check_finite=False)
        self.low_rank = np.hstack([self.low_rank, half.T])

    @property
    def dense(self) -> np.ndarray:
        """P_g as a dense matrix (for tests)."""
        return self.covariance - self.low_rank @ self.low_rank.T
