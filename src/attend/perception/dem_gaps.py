"""DEM on logs with missing values and irregular time stamps.

DEM's embedding needs samples on a uniform grid, so a log with gaps or jitter is brought to one:
every column bridged on the log's grid (:func:`attend.models.sample_times.bridge`: linear in
time, at most BRIDGED_GAP missing samples in a row, a longer gap an error naming its rows),
resampled onto t_0 + k dt (k = 0 .. ceil((t_end - t_0) / dt)) by linear interpolation, estimated
there, and the estimates and their standard deviations interpolated back to the log's stamps.
"""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.models.sample_times import bridge, matrix_with_gaps, sample_grid


def estimate_with_gaps(observer, outputs, inputs, time, **options):
    """:meth:`attend.perception.dem.DEMObserver.estimate` of a log with gaps or jitter.

    observer: the DEMObserver; outputs (N, m) with NaN where missing; inputs (N, r) measured
    inputs or prior means (None: 0 for unknown inputs); time (N,) [s] the stamps (None: k dt);
    options: estimate()'s keep_generalized, initial_state and segment. Returns the DEMEstimate at
    the log's rows (time: the stamps)."""
    system, dt = observer.system, observer.dt
    m, r = system.n_outputs, system.n_inputs
    y = matrix_with_gaps(outputs, "outputs", m)
    field_name = "inputs" if observer.known_inputs else "input_prior"
    if inputs is None:
        if observer.known_inputs:
            raise AttendInputError("inputs: the observer was built with known_inputs=True; pass the measured inputs")
        u = np.zeros((y.shape[0], r))
    else:
        u = matrix_with_gaps(inputs, field_name, r)
        if u.shape != (y.shape[0], r):
            raise AttendInputError(f"{field_name}: expected shape ({y.shape[0]}, {r}), got {u.shape}")
    stamps = np.arange(y.shape[0]) * dt if time is None else time
    grid = sample_grid(stamps, dt, y.shape[0])
    columns = bridge(grid, y, "outputs", list(system.output_names))
    if r:
        columns = np.hstack([columns, bridge(grid, u, field_name, list(system.input_names))])
    if grid.uniform:
        on_grid = columns
    else:
        uniform = grid.time[0] + np.arange(int(np.ceil((grid.time[-1] - grid.time[0]) / dt - 1e-9)) + 1) * dt
        on_grid = np.column_stack([np.interp(uniform, grid.time, column) for column in columns.T])
    result = observer.estimate(on_grid[:, :m], on_grid[:, m:] if r else None, **options).details  # a DEMEstimate
    log_time = grid.time[grid.rows]

    def at_rows(values):
        if values is None:
            return None
        values = np.asarray(values)
        if grid.uniform:
            return values[grid.rows]
        return np.column_stack([np.interp(log_time, uniform, column) for column in values.T]).reshape(
            len(log_time), -1)

    return result._replace(time=np.asarray(stamps, dtype=float), states=at_rows(result.states),
                           inputs=at_rows(result.inputs), state_std=at_rows(result.state_std),
                           input_std=at_rows(result.input_std), generalized=at_rows(result.generalized))
