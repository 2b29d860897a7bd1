"""`attend estimate` on a log with gaps or jitter: the model file's estimator run on it.

A log read with ``read_log(..., gaps=True)`` may have empty or NaN cells and time stamps that skip
samples or jitter (:mod:`attend.models.sample_times`). The linear estimators take such logs:

- method "kalman": no update for a missing output at that sample; skipped stamps are steps
  without a measurement; each step is discretised for its own length (jitter);
- method "dem": every column resampled onto the uniform grid by linear interpolation, bridging
  at most BRIDGED_GAP missing samples in a row (longer gaps are refused).

Measured inputs must be known at every step: gaps of at most BRIDGED_GAP samples are
interpolated linearly, longer ones (and gaps at either end of the log) are refused.

Nonlinear models run on the log's grid when its stamps are uniform (whole samples may be skipped):
method "ukf" with no update for a missing output (a skipped stamp is a sample without outputs),
split at every gap of more than BRIDGED_GAP samples without outputs, each part from its own start
(:func:`_segments`); method "dem" on the outputs bridged as for the linear DEM; their estimates are
returned at the log's rows. Jittered stamps: the unscented smoother integrates each step over its
own length (its process noise scaled to it); nonlinear DEM refuses them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from attend._validation import AttendInputError
from attend.io import Log, ModelFile
from attend.models.noise import GAUSSIAN_SPECTRUM_DENOMINATOR
from attend.models.sample_times import BRIDGED_GAP, UNIFORM_TOLERANCE, SampleGrid, bridge, describe, sample_grid
from attend.perception.file_estimators import file_estimator, file_nonlinear_order
from attend.workflows.estimate import located

JITTERED_DT_TOLERANCE = 1e-2
"""Relative distance between [model] dt and a jittered log's nominal step that is accepted (the
nominal step of a jittered log is known only to about jitter / sqrt(N))."""


def _used_columns(model: ModelFile) -> tuple[list[str], list[str]]:
    """(output columns, measured-input columns) the model file reads from the log."""
    return list(model.output_columns), [spec.column for spec in model.inputs if spec.known]


def has_gaps(model: ModelFile, log: Log) -> bool:
    """True when the log skips or jitters time stamps, or the model's columns hold missing values."""
    if not log.uniform:
        return True
    outputs, inputs = _used_columns(model)
    return any(name in log.columns and np.isnan(log.columns[name]).any() for name in outputs + inputs)


def _first_gap(model: ModelFile, log: Log) -> str:
    """Where the log first misses a value or steps unevenly, in the file's lines."""
    labels = log.labels
    outputs, inputs = _used_columns(model)
    for name in outputs + inputs:
        if name in log.columns and np.isnan(log.columns[name]).any():
            return f"{labels[int(np.argmax(np.isnan(log.columns[name])))]}, column {name!r}: a missing value"
    steps = np.diff(log.time)
    mean = (log.time[-1] - log.time[0]) / (len(log.time) - 1)
    worst = int(np.argmax(np.abs(steps - mean)))
    return f"{labels[worst + 1]}: a step of {steps[worst]:.6g} s (mean step {mean:.6g} s)"


def _sample_time(model: ModelFile, log: Log) -> float:
    """The nominal sample time: the log's (gaps counted in whole samples), checked against [model] dt."""
    dt = log.dt
    if model.dt is not None:
        tolerance = 1e-4 if log.uniform else JITTERED_DT_TOLERANCE
        if abs(model.dt - dt) > tolerance * dt:
            raise AttendInputError(f"{model.path}: [model] dt = {model.dt} s but the log {log.path} is sampled every "
                                   f"{dt:.6g} s (nominal step, gaps counted in whole samples)")
        dt = float(model.dt)
    return dt


def estimate_with_gaps(model: ModelFile, log: Log):
    """(observer, estimate, summary) of the model file's linear estimator on a log with gaps or
    jitter: estimates at every row of the log; summary: one line on what was missing and the
    jitter handled. Errors name the file and lines."""
    if model.nonlinear:
        return _nonlinear_with_gaps(model, log)
    minimum = 2 if model.method == "kalman" else max(model.learning_order, model.input_order) + 1
    if len(log.time) < max(minimum, 2):
        raise AttendInputError(f"{log.path}: expected at least {max(minimum, 2)} samples, got {len(log.time)}")
    dt = _sample_time(model, log)
    outputs = log.matrix(model.output_columns, missing=True)
    grid = sample_grid(log.time, dt, field=f"{log.path}: column {model.time_column!r}", labels=log.labels)
    signals = np.zeros((len(log.time), model.system.n_inputs))
    bridged = 0
    for j, spec in enumerate(model.inputs):
        if spec.known:
            column = log.matrix([spec.column], missing=True)[:, 0]
            bridge(grid, column, f"{log.path}: column", [spec.column], labels=log.labels)  # refuses long gaps
            bridged += int(np.isnan(column).sum())
            signals[:, j] = column - spec.operating_point
        else:
            signals[:, j] = spec.prior_mean
    if not np.isfinite(outputs).any():
        raise AttendInputError(f"{log.path}: every value of the output columns {', '.join(model.output_columns)} is "
                               "missing; expected measured outputs")
    if model.method == "dem":
        bridge(grid, outputs, f"{log.path}: column", list(model.output_columns), labels=log.labels)
    try:
        observer = file_estimator(model, dt, outputs, signals, log.time)
    except AttendInputError as error:  # as estimate_from_files: P_v is the [[inputs]] prior_precision
        message = str(error).replace("input_prior_precision", "[[inputs]] prior_precision")
        raise AttendInputError(message if message.startswith(str(model.path)) else
                               f"{model.path}: [observer] {message}") from None
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            estimate = observer.estimate(outputs, signals, time=log.time)
        except AttendInputError as error:  # a failure of the recursion itself names the files
            raise AttendInputError(located(error, model, log)) from None
    _check_estimate(model, log, estimate)
    return observer, estimate, summary(grid, outputs, bridged, model.method)


def _nonlinear_with_gaps(model: ModelFile, log: Log):
    """:func:`estimate_with_gaps` of a nonlinear model file (module docstring): the estimator runs on
    the log's uniform grid, its estimates are returned at the log's rows. The observer returned is
    the last part's (its choices, e.g. an unknown input's width, are that part's)."""
    from attend.perception.nonlinear.start_search import AmbiguousStartError

    if len(log.time) < 2:
        raise AttendInputError(f"{log.path}: expected at least 2 samples, got {len(log.time)}")
    dt = _sample_time(model, log)
    grid = sample_grid(log.time, dt, field=f"{log.path}: column {model.time_column!r}", labels=log.labels)
    if not grid.uniform and model.method == "dem":
        raise AttendInputError(
            f"{log.path}: {_first_gap(model, log)}; nonlinear DEM needs time stamps on t0 + k dt (within "
            f"{UNIFORM_TOLERANCE:g} dt; skipped samples are handled): use method \"ukf\" (the default), which "
            "integrates each step over its own length, or resample the log")
    steps = None if grid.uniform else np.diff(grid.time)
    outputs = log.matrix(model.output_columns, missing=True)
    if not np.isfinite(outputs).any():
        raise AttendInputError(f"{log.path}: every value of the output columns {', '.join(model.output_columns)} is "
                               "missing; expected measured outputs")
    minimum = 2 if model.method == "ukf" else max(file_nonlinear_order(model, dt), model.input_order) + 1
    if len(grid.time) < max(minimum, 2):
        raise AttendInputError(f"{log.path}: expected at least {max(minimum, 2)} samples, got {len(grid.time)}")
    if model.method == "dem":  # DEM's embedding needs every sample
        on_grid = bridge(grid, outputs, f"{log.path}: column", list(model.output_columns), labels=log.labels)
    else:
        on_grid = grid.spread(outputs)
    signals = np.empty((len(grid.time), model.system.n_inputs))
    bridged = 0
    for j, spec in enumerate(model.inputs):
        if spec.known:
            column = log.matrix([spec.column], missing=True)[:, 0]
            bridged += int(np.isnan(column).sum())
            signals[:, j] = bridge(grid, column, f"{log.path}: column", [spec.column], labels=log.labels)[:, 0] \
                - spec.operating_point
        else:
            signals[:, j] = spec.prior_mean
    parts = _segments(on_grid)
    pieces = []
    for number, part in enumerate(parts):
        # after a long gap the state is searched again (the file's initial_state is the first part's)
        part_model = model if number == 0 else replace(model, initial_state=None)
        try:
            observer = file_estimator(part_model, dt)
        except AttendInputError as error:  # as estimate_from_files: the settings, in the file's words
            message = str(error)
            raise AttendInputError(message if message.startswith(str(model.path)) else
                                   f"{model.path}: [observer] {message}") from None
        with np.errstate(over="ignore", invalid="ignore"):
            try:
                estimate = observer.estimate(on_grid[part], signals[part],
                                             None if steps is None else steps[part.start:part.stop - 1])
            except AmbiguousStartError as error:  # names the setting that decides: [observer] initial_state
                raise AttendInputError(f"{model.path}: [observer] {_in_part(error, parts, number, log, grid)}") from None
            except AttendInputError as error:
                if model.python_path and str(error).startswith(model.python_path):
                    raise  # the user's f or g failed: the message names the file and the function
                raise AttendInputError(located(_in_part(error, parts, number, log, grid), model, log)) from None
        pieces.append((part, estimate))
    estimate = _at_log_rows(pieces, grid, log)
    _check_estimate(model, log, estimate)
    text = summary(grid, outputs, bridged, model.method, nonlinear=True)
    if len(parts) > 1:
        text += (f"; split at {len(parts) - 1} gap{'s' if len(parts) > 2 else ''} of more than {BRIDGED_GAP} samples "
                 "without outputs, each part from its own start (searched, or the file's initial_state for the "
                 "first)")
    return observer, estimate, text


def _segments(outputs: np.ndarray) -> list[slice]:
    """The parts of the grid a nonlinear smoother runs on: split inside every run of more than
    BRIDGED_GAP samples without any output (the Gaussian approximation of the unscented smoother
    is not trusted to carry the state over more: after a long gap its prediction may span several
    of the model's modes, e.g. turns of a pendulum). A run at either end stays with its neighbour.
    outputs (M, m) on the grid, NaN where missing."""
    measured = np.flatnonzero(np.isfinite(outputs).any(axis=1))
    starts, stops = [0], []
    for before, after in zip(measured[:-1], measured[1:]):
        if after - before - 1 > BRIDGED_GAP:
            stops.append(int(before) + 1)
            starts.append(int(after))
    stops.append(len(outputs))
    return [slice(start, stop) for start, stop in zip(starts, stops)]


def _in_part(error: Exception, parts: list, number: int, log: Log, grid: SampleGrid) -> str:
    """The error's message, naming the part of the log (its first and last rows) when it was split."""
    if len(parts) == 1:
        return str(error)
    rows = [int(row) for row in np.flatnonzero((grid.rows >= parts[number].start) & (grid.rows < parts[number].stop))]
    where = f"{log.labels[rows[0]]} to {log.labels[rows[-1]]}" if rows else "a part without rows"
    return (f"{error} (on the part of the log from {where}; the log is split at its gaps of more than {BRIDGED_GAP} "
            "samples without outputs)")


def _at_log_rows(pieces: list, grid: SampleGrid, log: Log):
    """One Estimate at the log's rows from the estimates of the grid's parts ((slice, Estimate) in order):
    every array of their details with a row per grid sample taken at the log's rows, the others
    (e.g. a log-likelihood) summed over the parts; time: the log's stamps."""
    from attend.perception.estimate import as_estimate

    M = len(grid.time)
    first = pieces[0][1]
    fields = {}
    for name, value in first.details._asdict().items():
        values = [getattr(estimate.details, name) for _, estimate in pieces]
        if isinstance(value, np.ndarray) and value.ndim and all(
                isinstance(v, np.ndarray) and v.shape[0] == part.stop - part.start for (part, _), v in zip(pieces, values)):
            whole = np.full((M,) + value.shape[1:], np.nan)
            for (part, _), v in zip(pieces, values):
                whole[part] = v
            fields[name] = whole[grid.rows]
        elif isinstance(value, float) and len(pieces) > 1:
            fields[name] = float(sum(values))
    fields["time"] = np.asarray(log.time, dtype=float)
    return as_estimate(first.details._replace(**fields), first.method)


def _check_estimate(model: ModelFile, log: Log, estimate) -> None:
    """Non-finite estimates or standard deviations are errors naming the model file."""
    for name, values in (("states", estimate.states), ("inputs", estimate.inputs)):
        if not np.all(np.isfinite(values)):
            raise AttendInputError(f"{model.path}: [observer] the estimated {name} are not finite on the log "
                                   f"{log.path}: the observer is numerically unstable for these settings")
    names = list(model.system.state_names) + list(model.system.input_names)
    undefined = ~np.all(np.isfinite(np.hstack([estimate.state_std, estimate.input_std])), axis=0)
    if undefined.any():
        hidden = ", ".join(name for name, bad in zip(names, undefined) if bad)
        raise AttendInputError(f"{model.path}: [observer] {hidden}: not informed by the outputs under these settings "
                               "(no finite standard deviation); add outputs that see them, or give [observer] "
                               "initial_state and initial_state_std with method = \"kalman\"")


def summary(grid: SampleGrid, outputs: np.ndarray, bridged_inputs: int, method: str, nonlinear: bool = False) -> str:
    """One line: samples missing, jitter handled, and how (per method). grid: the log's
    :class:`attend.models.sample_times.SampleGrid`; outputs: (N, m) the output columns (NaN:
    missing); bridged_inputs: how many missing measured-input values were interpolated; method:
    the model file's [observer] method; nonlinear: a nonlinear model's (its smoother integrates each
    jittered step over its own length)."""
    missing_rows = int(np.sum(~np.isfinite(outputs).all(axis=1)))
    if method == "dem":
        how = "resampled onto t0 + k dt"
    elif nonlinear:
        how = "each step integrated over its own length (RK4), its process noise scaled to it"
    else:
        how = (f"each step discretised exactly (continuous-time noise models of order "
               f"{len(GAUSSIAN_SPECTRUM_DENOMINATOR) - 1})")
    text = "gaps and jitter: " + describe(grid, missing_rows, how)
    if bridged_inputs:
        text += f"; {bridged_inputs} missing input value{'s' if bridged_inputs != 1 else ''} interpolated"
    if method == "dem":
        text += (f"; DEM ran on the uniform grid (columns interpolated linearly, gaps of up to {BRIDGED_GAP} samples "
                 "bridged), its estimates interpolated back to every row")
    else:
        text += "; estimates at every row of the log"
    return text
