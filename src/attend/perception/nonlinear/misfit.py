"""Is a log described by DEM's generalised model? The free energy at the estimate against its expectation.

Under the model, every window's error e has precision Pi~, so 1/2 e' Pi~ e averages about
1/2 dim(e) at the truth, and less at an estimate fitted to the data. The misfit ratio is the mean
of 1/2 e' Pi~ e at the estimate over 1/2 dim(e). Well-specified logs give 0.3-2.3 (Lorenz,
pendulum, the random bank's good cases; both the D-step and path mode); logs whose inputs and
noise are held over each sample with little process noise give 1e1-1e9 (docs/nonlinear.md).
Above :data:`MISFIT_LIMIT` a ModelWarning says the estimates and std are not reliable. It is a
one-sided check: many bad estimates pass it.

An estimate that has left the data altogether is an error (:func:`check_excursion`): predicted
outputs g(x, v) more than :data:`EXCURSION_LIMIT` output scales from the measured ones, the scale
being the log's range of that output plus its sensor noise std 1/sqrt(Pi_z,ii). A sane estimate
predicts within ~1 scale; on the random nonlinear bank the D-step reached |x| ~ 4e4 against a
true scale of 1.8 on a sinusoidal-sensor case with only the misfit warning before this check.
"""

from __future__ import annotations

import warnings

import numpy as np

from attend._validation import AttendInputError
from attend.models.linear import ModelWarning

#: misfit ratio above which the log is called far from the generalised model
MISFIT_LIMIT = 20.0
#: windows the D-step's check evaluates at most (evenly spaced over the log)
CHECKED_WINDOWS = 50
#: predicted outputs farther than this many output scales (the log's range plus the sensor noise
#: std) from the data: the estimate has left the data (an error, not a warning)
EXCURSION_LIMIT = 100.0


def warn_if_misfit(ratio: float, who: str, stacklevel: int) -> None:
    """The ModelWarning of the module docstring when ``ratio`` exceeds MISFIT_LIMIT; who: the
    estimator's name in the message; stacklevel: as for warnings.warn (from the caller)."""
    if np.isfinite(ratio) and ratio > MISFIT_LIMIT:
        warnings.warn(
            f"{who}: the log is far from DEM's generalised model (free energy {ratio:.3g}x its expected value): "
            "typically inputs or noise held constant over each sample (zero-order hold) with little process "
            "noise, which smooth generalised coordinates do not describe; the estimates and their std are not "
            "reliable here (docs/nonlinear.md, 'unseen systems')", ModelWarning, stacklevel=stacklevel + 1)


def misfit_rows(dem, n_samples: int) -> np.ndarray:
    """The samples the misfit ratio averages over: those whose embedding window lies in the log,
    every k-th so that there are about CHECKED_WINDOWS (fewer than 2 CHECKED_WINDOWS). dem: the
    NonlinearDEM; n_samples: the log's length."""
    offsets = dem.generalized_matrices()["offsets"]
    rows = np.arange(-offsets[0], n_samples - offsets[-1])
    return rows[:: max(1, len(rows) // CHECKED_WINDOWS)]


def sample_misfit(dem, signals: np.ndarray, generalized: np.ndarray) -> float:
    """The misfit ratio of the D-step's estimates: 1/2 e' Pi~ e over 1/2 dim(e), averaged over up
    to CHECKED_WINDOWS samples whose embedding window lies in the log. dem: the NonlinearDEM;
    signals: (N, m + r) outputs and inputs; generalized: (N, dim X) its generalised estimates."""
    offsets = dem.generalized_matrices()["offsets"]
    rows = misfit_rows(dem, len(signals))
    if len(rows) == 0:
        return np.nan
    costs = []
    for k in rows:
        y_tilde, u_tilde = dem.embed_row(signals[k + offsets], False, signals[k])
        e, _, blocks = dem.errors(generalized[k], y_tilde, u_tilde)
        start, cost = 0, 0.0
        for block in blocks:
            part = e[start: start + block.shape[0]]
            cost += 0.5 * float(part @ block @ part)
            start += block.shape[0]
        costs.append(cost / (0.5 * len(e)))
    return float(np.mean(costs))


def excursion_rows(n_samples: int) -> np.ndarray:
    """The samples :func:`check_excursion` looks at: up to 2 CHECKED_WINDOWS evenly spaced, and the
    last. n_samples: the log's length."""
    return np.unique(np.r_[np.linspace(0, n_samples - 1, min(n_samples, 2 * CHECKED_WINDOWS)).astype(int),
                           n_samples - 1])


def check_excursion(dem, signals: np.ndarray, states: np.ndarray, inputs: np.ndarray, who: str,
                    predicted: np.ndarray | None = None) -> None:
    """Raise an AttendInputError when the estimate has left the data (module docstring), checked at
    the samples of :func:`excursion_rows`.

    dem: the NonlinearDEM; signals: (N, m + r) outputs then inputs; states (N, n), inputs (N, r):
    the estimates (inputs: estimated, or the measured ones); who: the estimator's name; predicted:
    g at those samples if already computed ((rows, m); default: computed here)."""
    m = dem.system.n_outputs
    outputs = signals[:, :m]
    rows = excursion_rows(len(outputs))
    with np.errstate(divide="ignore"):
        noise_std = 1.0 / np.sqrt(np.diag(dem.sensor_precision))
    scale = np.ptp(outputs, axis=0) + noise_std
    if predicted is None:
        predicted = np.array([dem.system.observe(states[k], inputs[k]) for k in rows])
    with np.errstate(invalid="ignore"):
        excursion = np.abs(predicted - outputs[rows]) / scale
    # a non-finite prediction is an excursion; inf / inf (an output without sensor precision) is none
    excursion = np.where(~np.isfinite(predicted) & np.isfinite(scale), np.inf, np.nan_to_num(excursion, nan=0.0))
    if not np.any(excursion > EXCURSION_LIMIT):
        return
    row, output = np.unravel_index(np.argmax(excursion), excursion.shape)
    k = int(rows[row])
    name = dem.system.output_names[output]
    raise AttendInputError(
        f"{who}: the estimate left the data: at sample {k} the predicted {name} = {predicted[row, output]:.4g} is "
        f"{excursion[row, output]:.3g} output scales from the measured {outputs[k, output]:.4g} (scale: the log's "
        f"range {np.ptp(outputs[:, output]):.3g} plus the sensor noise std {noise_std[output]:.3g}; limit "
        f"{EXCURSION_LIMIT:g}). The flow is not stable on this log: try states='path' (which also starts from the "
        "unscented smoother), the unscented smoother (model files: method = \"ukf\"), a lower embedding_order or "
        "kernel_width, or check f, g and the precisions.")

