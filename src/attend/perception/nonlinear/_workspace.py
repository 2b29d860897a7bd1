"""The D-step of :class:`attend.perception.nonlinear.NonlinearDEM` with its arrays kept between
samples (:class:`StepWorkspace`): the same equations as ``NonlinearDEM._step`` for
motion="linearized" and integration="attend", with fewer NumPy calls per sample.

The constant parts of E = de/dX (D on the motion rows, I on the input-prior rows) are written once;
each sample overwrites only the Jacobian blocks (through strided views of their block diagonals)
and the error column. The errors ride as the last column of [E | e], so that one product gives
[E | e]' Pi [E | e] = [[E' Pi E, E' Pi e], [e' Pi E, e' Pi e]]: the curvature and the gradient
-E' Pi e together.
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
        mats = estimator._matrices
        system = estimator.system
        n, r, p, d, top = mats["sizes"]
        m = system.n_outputs
        self.estimator, self.system = estimator, system
        self.n, self.r, self.p, self.d, self.top = n, r, p, d, top
        self.n_x = estimator.n_state_coordinates
        self.estimates_inputs = mats["estimates_inputs"]
        template = mats["E_template"]
        rows, size = template.shape
        self.size, self.n_y = size, m * (p + 1)
        self.augmented = np.zeros((rows, size + 1))  # [E | e]
        self.augmented[:, :size] = template
        self.errors = self.augmented[:, size]
        self.weighted = np.empty_like(self.augmented)
        self.Pi, self.D_X = mats["Pi"], mats["D_X"]
        n_y = self.n_y
        view = _diagonal_view
        self.views = dict(gx=view(self.augmented, 0, 0, (m, n), p + 1),
                          fx=view(self.augmented, n_y, 0, (n, n), p + 1))
        if self.estimates_inputs:
            self.views.update(gv=view(self.augmented, 0, self.n_x, (m, r), top),
                              fv=view(self.augmented, n_y, self.n_x, (n, r), top))
        self.v_pad = np.zeros((p + 1, r))
        self.samples = estimator.flow_time == "samples"
        self.scale, self.scale_outer = mats["order_scale"], mats["scale_outer"]
        self.block = np.zeros((size + 1, size + 1))
        self.scratch = np.empty((5, size + 1, size + 1))

    def _fill(self, X, y_tilde, u_tilde) -> None:
        """Write E and e at X into [E | e] (as NonlinearDEM._errors, integration="attend")."""
        n, r, p, top, n_x, n_y = self.n, self.r, self.p, self.top, self.n_x, self.n_y
        system = self.system
        x = X[:n_x].reshape(p + 1, n)
        v = X[n_x:].reshape(self.d + 1, r) if self.estimates_inputs else u_tilde.reshape(self.d + 1, r)
        fx, fv, gx, gv = system.jacobians(x[0], v[0])
        views = self.views
        np.negative(gx, out=views["gx"])
        np.negative(fx, out=views["fx"])
        g_t, f_t = x @ gx.T, x @ fx.T
        if r:
            v_pad = self.v_pad
            v_pad[:top] = v[:top]
            g_t += v_pad @ gv.T
            f_t += v_pad @ fv.T
            if self.estimates_inputs:
                np.negative(gv, out=views["gv"])
                np.negative(fv, out=views["fv"])
        g_t[0] = system.observe(x[0], v[0])
        f_t[0] = system.flow(x[0], v[0])
        errors = self.errors
        np.subtract(y_tilde, g_t.ravel(), out=errors[:n_y])
        motion = errors[n_y: n_y + n_x]
        np.subtract(x[1:].ravel(), f_t[:-1].ravel(), out=motion[:-n])
        np.negative(f_t[-1], out=motion[-n:])
        if self.estimates_inputs:
            np.subtract(X[n_x:], u_tilde, out=errors[n_y + n_x:])

    def step(self, X, y_tilde, u_tilde, substeps: int):
        """One D-step over dt / substeps (NonlinearDEM._step): returns (X, curvature).
        X: the generalised state; y_tilde, u_tilde: the embedded data; substeps: per sample."""
        self._fill(X, y_tilde, u_tilde)
        augmented, weighted = self.augmented, self.weighted
        start = 0
        for block in self.Pi:
            stop = start + block.shape[0]
            np.matmul(block, augmented[start:stop], out=weighted[start:stop])
            start = stop
        products = augmented.T @ weighted
        size = self.size
        curvature, minus_gradient = products[:size, :size], products[:size, size]
        block = self.block
        if self.samples:
            scale = self.scale
            np.subtract(self.D_X, curvature / self.scale_outer, out=block[:size, :size])
            np.subtract(self.D_X @ (X * scale), minus_gradient / scale, out=block[:size, size])
            if substeps != 1:
                block /= substeps
            with np.errstate(over="ignore", invalid="ignore"):
                increment = expm_last_column(block, self.scratch) / scale
        else:
            duration = self.estimator.dt / substeps
            np.multiply(self.D_X - curvature, duration, out=block[:size, :size])
            np.multiply(self.D_X @ X - minus_gradient, duration, out=block[:size, size])
            with np.errstate(over="ignore", invalid="ignore"):
                increment = expm_last_column(block, self.scratch)
        return X + increment, curvature
