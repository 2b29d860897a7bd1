"""Sample-by-sample nonlinear DEM (:class:`OnlineNonlinearDEM`), the online form of
:class:`attend.perception.nonlinear.NonlinearDEM`."""

from __future__ import annotations

import numpy as np

from attend._threads import with_single_blas_thread
from attend._validation import AttendInputError, require_finite
from attend.perception.nonlinear._workspace import StepWorkspace


class OnlineNonlinearDEM:
    """Sample-by-sample nonlinear DEM: fixed-size state, output delayed by ``estimator.delay``.

    ``step(y, u=None)`` takes sample k (outputs (m,), and the measured input or the input prior
    (r,)) and returns (states, inputs) of sample k - delay once enough samples have arrived (None
    before); ``finish()`` returns the last ``delay`` estimates, repeating the final sample as the
    batch mode does. Batch and online agree sample by sample.

    estimator: the :class:`NonlinearDEM` whose settings are used; initial_state: a guess of the
    order-0 states (n,) (or a full generalised state) where the Gauss-Newton start is sought at
    the first sample (default zeros).
    """

    def __init__(self, estimator: NonlinearDEM, initial_state=None):
        self.estimator = estimator
        mats = estimator.generalized_matrices()
        offsets = mats["offsets"]
        self._before = int(-offsets[0])
        self._lead = int(offsets[-1])
        self._window = len(offsets)
        self._m = estimator.system.n_outputs
        self._r = estimator.system.n_inputs
        self._buffer = np.zeros((self._window, self._m + self._r))
        self._count = 0
        self._row = 0
        self._total: int | None = None
        self._state: np.ndarray | None = None
        self._guess = initial_state
        self._order0 = estimator.edges == "order0"
        lean = estimator.motion == "linearized" and estimator.integration == "attend"
        self._workspace = StepWorkspace(estimator) if lean else None

    def _advance(self, at_end: bool):
        est = self.estimator
        row = self._row
        edge = self._order0 and (row < self._before or at_end)
        y_t, u_t = est.embed_row(self._buffer, edge, self._buffer[self._before])
        if est.integration == "spm":
            return self._advance_spm(y_t, u_t)
        if self._state is None:
            self._state = est.initial_state(y_t, u_t, self._guess)
        X = self._state
        workspace = self._workspace
        for _ in range(est.substeps):
            X, curvature = est.dstep(X, y_t, u_t) if workspace is None else workspace.step(X, y_t, u_t, est.substeps)
        est.check_divergence(X, row)
        self._state = X
        self._row += 1
        return (*est.order0_estimate(X, curvature, u_t), X.copy())

    def _advance_spm(self, y_t, u_t):
        """integration="spm": report the state reached before this sample, then step with the
        data moving along their generalised motion (substeps continue the motion)."""
        est = self.estimator
        if self._state is None:
            self._state = est.generalized_guess(self._guess)
        reported = X = self._state
        y_moving, u_moving = y_t, u_t
        for substep in range(est.substeps):
            X, y_moving, u_moving, curvature_step = est.dstep_spm(X, y_moving, u_moving)
            if substep == 0:
                curvature = curvature_step
        est.check_divergence(X, self._row)
        self._state = X
        self._row += 1
        return (*est.order0_estimate(reported, curvature, u_t), reported.copy())

    def push_row(self, sample):
        """Feed the checked sample k (m + r,) and return the raw row of sample k - delay, (states,
        inputs, curvature, X) without copies, or None while the window fills (the batch D-step's
        loop; :meth:`step` is the checked form)."""
        # before the first sample, the window holds the first sample repeated (as in batch mode)
        if self._count:
            self._buffer[:-1] = self._buffer[1:]
            self._buffer[-1] = sample
        else:
            self._buffer[:] = sample
        self._count += 1
        if self._count <= self._lead:
            return None
        return self._advance(at_end=False)

    def flush_rows(self):
        """The raw rows (as :meth:`push_row`) still waiting for future samples, end samples repeated."""
        out = []
        for _ in range(min(self._lead, self._count)):
            self._buffer[:-1] = self._buffer[1:].copy()
            out.append(self._advance(at_end=True))
        return out

    @with_single_blas_thread
    def step(self, output, input_value=None):
        """Feed sample k; return (states (n,), inputs (r,)) of sample k - delay, or None.

        output: the outputs y[k] (m,); input_value: the measured input u[k] (known inputs) or the
        input prior mean eta[k] (unknown inputs), (r,), default 0."""
        sample = np.concatenate([np.ravel(np.asarray(output, dtype=float)),
                                 np.zeros(self._r) if input_value is None
                                 else np.ravel(np.asarray(input_value, dtype=float))])
        if sample.shape[0] != self._m + self._r:
            raise AttendInputError(f"step: expected {self._m} outputs and {self._r} inputs")
        require_finite(sample, "step sample")
        out = self.push_row(sample)
        return None if out is None else (out[0].copy(), out[1].copy())

    @with_single_blas_thread
    def finish(self):
        """Flush the estimates still waiting for future samples (end samples repeated)."""
        return [(row[0].copy(), row[1].copy()) for row in self.flush_rows()]
