"""Is a log described by DEM's generalised model? The free energy at the estimate against its expectation.

Under the model, every window's error e has precision Pi~, so 1/2 e' Pi~ e averages about
1/2 dim(e) at the truth, and less at an estimate fitted to the data. The misfit ratio is the mean
of 1/2 e' Pi~ e at the estimate over 1/2 dim(e). Well-specified logs give 0.3-2.3 (Lorenz,
pendulum, the random bank's good cases; both the D-step and path mode); logs whose inputs and
noise are held over each sample with little process noise give 1e1-1e9 (docs/nonlinear.md).
Above :data:`MISFIT_LIMIT` a ModelWarning says the estimates and std are not reliable. It is a
one-sided check: many bad estimates pass it.
"""

from __future__ import annotations

import warnings

import numpy as np

from attend.systems import ModelWarning

#: misfit ratio above which the log is called far from the generalised model
MISFIT_LIMIT = 20.0
#: windows the D-step's check evaluates at most (evenly spaced over the log)
CHECKED_WINDOWS = 50


def warn_if_misfit(ratio: float, who: str, stacklevel: int) -> None:
    """The ModelWarning of the module docstring when ``ratio`` exceeds MISFIT_LIMIT; who: the
    estimator's name in the message; stacklevel: as for warnings.warn (from the caller)."""
    if np.isfinite(ratio) and ratio > MISFIT_LIMIT:
        warnings.warn(
            f"{who}: the log is far from DEM's generalised model (free energy {ratio:.3g}x its expected value): "
            "typically inputs or noise held constant over each sample (zero-order hold) with little process "
            "noise, which smooth generalised coordinates do not describe; the estimates and their std are not "
            "reliable here (docs/nonlinear.md, 'unseen systems')", ModelWarning, stacklevel=stacklevel + 1)


def sample_misfit(dem, signals: np.ndarray, generalized: np.ndarray) -> float:
    """The misfit ratio of the D-step's estimates: 1/2 e' Pi~ e over 1/2 dim(e), averaged over up
    to CHECKED_WINDOWS samples whose embedding window lies in the log. dem: the NonlinearDEM;
    signals: (N, m + r) outputs and inputs; generalized: (N, dim X) its generalised estimates."""
    offsets = dem._matrices["offsets"]
    rows = np.arange(-offsets[0], len(signals) - offsets[-1])
    if len(rows) == 0:
        return np.nan
    rows = rows[:: max(1, len(rows) // CHECKED_WINDOWS)]
    costs = []
    for k in rows:
        y_tilde, u_tilde = dem._embed_row(signals[k + offsets], False, signals[k])
        e, _, blocks = dem.errors(generalized[k], y_tilde, u_tilde)
        start, cost = 0, 0.0
        for block in blocks:
            part = e[start: start + block.shape[0]]
            cost += 0.5 * float(part @ block @ part)
            start += block.shape[0]
        costs.append(cost / (0.5 * len(e)))
    return float(np.mean(costs))
