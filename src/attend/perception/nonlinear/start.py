"""The start of the D-step's flow: the static mode of the free energy for the first sample's data,
by Gauss-Newton with step halving (:meth:`attend.perception.nonlinear.NonlinearDEM.initial_state`)."""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.perception.nonlinear._linalg import scaled_solve


def gauss_newton_start(evaluate, X, iterations: int = 20) -> np.ndarray:
    """The mode of F from X: X <- X + inv(C) dF/dX, the step halved (up to 30 times) until F does not
    decrease; stops when F improves by less than 1e-12 relative or no step is accepted.

    evaluate: X -> (dF/dX, C, F) with C the Gauss-Newton curvature E' Pi~ E (an AttendInputError
    from it counts as F = -inf); X: the starting generalised state; iterations: the most steps."""
    gradient, curvature, energy = evaluate(X)
    for _ in range(iterations):
        if not (np.all(np.isfinite(curvature)) and np.all(np.isfinite(gradient))):
            break  # no step from a non-finite curvature or gradient (LAPACK would refuse it): X as it is
        try:
            step = scaled_solve(curvature, gradient)
        except np.linalg.LinAlgError:  # a system beyond the floating-point range: X as it is
            break
        accepted = False
        for _ in range(30):
            candidate = X + step
            try:
                g_new, c_new, e_new = evaluate(candidate)
            except AttendInputError:
                e_new = -np.inf
            if np.isfinite(e_new) and e_new >= energy:
                accepted = True
                break
            step = step / 2
        if not accepted:
            break
        X, gradient, curvature, improvement = candidate, g_new, c_new, e_new - energy
        energy = e_new
        if improvement <= 1e-12 * max(1.0, abs(energy)):
            break
    return X
