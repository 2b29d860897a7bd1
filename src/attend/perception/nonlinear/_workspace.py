"""The D-step of :class:`attend.perception.nonlinear.NonlinearDEM` with its arrays kept between
samples (:class:`StepWorkspace`): the same equations as ``NonlinearDEM.dstep`` for
motion="linearized" and integration="attend", with fewer NumPy calls per sample.

The step works in the flow's units: X_s = S X with S = diag(dt^k) (k the order of each coordinate;
S = I with flow_time="seconds"), and E_s = E inv(S), so that E_s' Pi E_s = inv(S) E' Pi E inv(S)
(the curvature in sample units) and E_s X_s = E X. The constant parts of E_s (D on the motion
rows, I on the input-prior rows) are written once; each sample overwrites only the Jacobian
blocks (through strided views of their block diagonals) and the error column. The errors ride as
the last column of [E_s | e], so that one product gives [[E_s' Pi E_s, E_s' Pi e], [., e' Pi e]]:
the curvature and the gradient -E_s' Pi e together. For linearized motion the errors are affine
in X given the Jacobians: e = E X + [y~; 0; -eta~] at orders >= 1, and the order-0 rows take
f(x, v), g(x, v) themselves.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided

from attend.perception.nonlinear._linalg import expm_last_column


def _diagonal_view(matrix, row0: int, col0: int, block: tuple, count: int):
    """A writable (count, a, b) view of ``count`` blocks of ``block`` = (a, b) on a block diagonal
    of ``matrix`` (C-ordered, 2-D) starting at (row0, col0), or None if a block is empty."""
    a, b = block
    if count == 0 or a == 0 or b == 0:
        return None
    step_row, step_col = matrix.strides
    return as_strided(matrix[row0:, col0:], shape=(count, a, b),
                      strides=(a * step_row + b * step_col, step_row, step_col))


class StepWorkspace:
    """Arrays of one estimator's D-step, reused from sample to sample (one per online run).

    estimator: the :class:`NonlinearDEM` (motion="linearized", integration="attend")."""

    def __init__(self, estimator):
        mats = estimator.generalized_matrices()
        n, r, p, d, top = mats["sizes"]
        m = estimator.system.n_outputs
        self.estimator, self.system = estimator, estimator.system
        self.n, self.r, self.p, self.d, self.top, self.m = n, r, p, d, top, m
        self.n_x, self.n_y = estimator.n_state_coordinates, m * (p + 1)
        self.estimates_inputs = mats["estimates_inputs"]
        template = mats["E_template"]
        rows, size = template.shape
        self.size = size
        self.samples = estimator.flow_time == "samples"
        self.scale = mats["order_scale"] if self.samples else np.ones(size)
        self.augmented = np.zeros((rows, size + 1))  # [E_s | e]
        self.augmented[:, :size] = template / self.scale
        self.jacobian = self.augmented[:, :size]
        self.weighted = np.empty_like(self.augmented)
        self.Pi, self.D_X = mats["Pi"], mats["D_X"]
        orders = -1.0 / (estimator.dt ** np.arange(p + 1) if self.samples else np.ones(p + 1))
        self.factors = orders[:, None, None], orders[:top, None, None]  # -1 / dt^k per block
        self.views = dict(gx=_diagonal_view(self.augmented, 0, 0, (m, n), p + 1),
                          fx=_diagonal_view(self.augmented, self.n_y, 0, (n, n), p + 1))
        if self.estimates_inputs:
            self.views.update(gv=_diagonal_view(self.augmented, 0, self.n_x, (m, r), top),
                              fv=_diagonal_view(self.augmented, self.n_y, self.n_x, (n, r), top))
        self.v_pad = np.zeros((p + 1, r))
        self.block = np.zeros((size + 1, size + 1))
        self.motion = np.zeros((size, size + 1))  # [D | D X_s]
        self.motion[:, :size] = self.D_X
        self.scratch = np.empty((5, size + 1, size + 1))

    def _errors(self, X, X_scaled, y_tilde, u_tilde) -> None:
        """Write E_s and e at X into [E_s | e] (as NonlinearDEM._errors, integration="attend")."""
        n, r, m, n_x, n_y = self.n, self.r, self.m, self.n_x, self.n_y
        system = self.system
        x0, v0 = X[:n], X[n_x: n_x + r] if self.estimates_inputs else u_tilde[:r]
        fx, fv, gx, gv = system.evaluate_jacobians(x0, v0)
        views, (factor_x, factor_v) = self.views, self.factors
        np.multiply(gx, factor_x, out=views["gx"])
        np.multiply(fx, factor_x, out=views["fx"])
        if self.estimates_inputs:
            np.multiply(gv, factor_v, out=views["gv"])
            np.multiply(fv, factor_v, out=views["fv"])
        errors = self.jacobian @ X_scaled  # orders >= 1: y~ - g~, x~' - f~ with y~ and eta~ added below
        errors[:n_y] += y_tilde
        np.subtract(y_tilde[:m], system.evaluate("g", x0, v0), out=errors[:m])
        f0 = system.evaluate("f", x0, v0)
        if self.p:
            np.subtract(X[n: 2 * n], f0, out=errors[n_y: n_y + n])
        else:  # order 0 is the top order: its motion error is -f
            np.negative(f0, out=errors[n_y: n_y + n])
        if self.estimates_inputs:
            errors[n_y + n_x:] -= u_tilde
        elif r:  # known inputs: their part of g~ and f~ at orders >= 1
            v_pad = self.v_pad
            v_pad[: self.top] = u_tilde.reshape(self.d + 1, r)[: self.top]
            errors[m:n_y] -= (v_pad[1:] @ gv.T).ravel()
            errors[n_y + n: n_y + n_x] -= (v_pad[1:] @ fv.T).ravel()
        self.augmented[:, self.size] = errors

    def _products(self, X, X_scaled, y_tilde, u_tilde) -> np.ndarray:
        """[E_s | e]' Pi [E_s | e] at X (X_scaled = S X; y_tilde, u_tilde: the embedded data)."""
        self._errors(X, X_scaled, y_tilde, u_tilde)
        augmented, weighted = self.augmented, self.weighted
        start = 0
        for block in self.Pi:
            stop = start + block.shape[0]
            np.matmul(block, augmented[start:stop], out=weighted[start:stop])
            start = stop
        return augmented.T @ weighted

    def gradient_curvature(self, X, y_tilde, u_tilde):
        """(dF/dX, E' Pi E, F) at X, as NonlinearDEM._gradient_curvature: the gradient -E' Pi e,
        the Gauss-Newton curvature and the free energy -e' Pi e / 2, in the units of X.
        X: the generalised state; y_tilde, u_tilde: the embedded data."""
        scale, size = self.scale, self.size
        products = self._products(X, X * scale, y_tilde, u_tilde)
        return (-products[:size, size] * scale, products[:size, :size] * np.outer(scale, scale),
                -0.5 * products[size, size])

    def step(self, X, y_tilde, u_tilde, substeps: int):
        """One D-step over dt / substeps (NonlinearDEM.dstep): returns (X, curvature), the curvature
        in the flow's units (inv(S) E' Pi E inv(S); the order-0 entries are E' Pi E's own).
        X: the generalised state; y_tilde, u_tilde: the embedded data; substeps: per sample."""
        X_scaled = X * self.scale
        products = self._products(X, X_scaled, y_tilde, u_tilde)
        size, block, motion = self.size, self.block, self.motion
        np.matmul(self.D_X, X_scaled, out=motion[:, size])
        np.subtract(motion, products[:size], out=block[:size])  # [D - curvature | D X_s + gradient]
        if not self.samples:
            block *= self.estimator.dt / substeps
        elif substeps != 1:
            block /= substeps
        with np.errstate(over="ignore", invalid="ignore"):
            increment = expm_last_column(block, self.scratch)
            if self.samples:
                increment /= self.scale
        return X + increment, products[:size, :size]
