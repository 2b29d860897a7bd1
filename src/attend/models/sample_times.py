"""Time stamps of real logs: gaps (missing samples) and jitter (steps off the nominal dt).

The estimators run on a *grid*: the log's own time stamps plus one inserted sample per missing
one. A step h between two stamps counts as k = max(1, round(h / dt)) steps of h / k each (k - 1
inserted samples, without a measurement), so every step on the grid is within +-50 % of dt:

    0.5 dt <= h < 1.5 dt      one step of h (jitter)
    h ~ k dt, k >= 2          k steps of h / k: k - 1 missing samples (a gap)
    h < 0.5 dt, h = 0, h < 0  refused: a duplicated, repeated or backwards time stamp

The grid is *uniform* when every step is within UNIFORM_TOLERANCE of dt (gaps of whole samples
only); else it is *jittered* and each step is discretised exactly for its own length h.
Missing values of a signal that must be known at every sample (measured inputs; the outputs of
DEM, which needs a uniform embedding) are linearly interpolated over gaps of up to BRIDGED_GAP
consecutive samples; longer gaps are refused (:func:`bridge`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from attend._validation import AttendInputError, numeric_array

UNIFORM_TOLERANCE = 1e-4
"""Relative deviation of a step from (a whole number of) dt below which it counts as nominal."""

SHORTEST_STEP = 0.5
"""Shortest accepted step, in units of dt; shorter ones are refused as duplicated stamps."""

BRIDGED_GAP = 3
"""Longest run of consecutive missing samples interpolated in a signal that must be known at
every sample (measured inputs; DEM's outputs)."""


def matrix_with_gaps(value, field: str, columns: int) -> np.ndarray:
    """``value`` as an (N, columns) float array (field: its name in errors); NaN marks a missing
    value, inf is an error naming the index."""
    array = numeric_array(value, field, "a matrix of numbers")
    if array.ndim == 1 and columns == 1:
        array = array[:, None]
    if array.ndim != 2:
        raise AttendInputError(f"{field}: expected a 2-D matrix, got an array of shape {array.shape}")
    if array.shape[1] != columns:
        what = "output" if field == "outputs" else "input"
        raise AttendInputError(f"{field}: expected {columns} columns (one per {what}), got {array.shape[1]}")
    infinite = np.argwhere(np.isinf(array))
    if infinite.size:
        index = tuple(int(i) for i in infinite[0])
        raise AttendInputError(f"{field}: expected finite numbers (NaN for a missing value), found {array[index]} at "
                               f"index {index}")
    return array


class SampleGrid(NamedTuple):
    """The grid the estimators run on.

    time (M,) [s]: the log's stamps and the inserted samples; rows (N,): position of each log
    row on the grid; uniform: every step within UNIFORM_TOLERANCE of dt (else jittered:
    per-step discretisation); inserted: number of inserted (missing) samples; jitter: the
    largest |step - dt| / dt over the grid's steps; dt: the nominal sample time [s].
    """

    time: np.ndarray
    rows: np.ndarray
    uniform: bool
    inserted: int
    jitter: float
    dt: float

    @property
    def steps(self) -> np.ndarray:
        """(M - 1,) step lengths [s] of the grid."""
        return np.diff(self.time)

    def spread(self, values: np.ndarray) -> np.ndarray:
        """(M, ...) array with the rows of ``values`` (N, ...) at their grid positions, NaN elsewhere."""
        out = np.full((len(self.time),) + values.shape[1:], np.nan)
        out[self.rows] = values
        return out


def _label(labels, row: int) -> str:
    return f"row {row}" if labels is None else str(labels[row])


def _rows(indices, labels=None, limit: int = 5) -> str:
    indices = [int(i) for i in indices]
    text = ", ".join(_label(labels, i) for i in indices[:limit])
    return text + (f" and {len(indices) - limit} more" if len(indices) > limit else "")


def check_time_stamps(time, n_samples: int, dt: float, field: str = "time", labels=None) -> np.ndarray:
    """``time`` as a float (N,) array of finite, strictly increasing stamps [s], no step below
    SHORTEST_STEP dt [s]; errors name the rows and what was expected. n_samples: the expected N;
    field: the name errors use; labels: how errors name row k (default "row k", 0-based)."""
    try:
        stamps = np.asarray(time, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise AttendInputError(f"{field}: expected {n_samples} time stamps [s], got {time!r:.60}") from None
    if stamps.shape != (n_samples,):
        raise AttendInputError(f"{field}: expected {n_samples} time stamps (one per sample), got {stamps.size}")
    bad = np.flatnonzero(~np.isfinite(stamps))
    if bad.size:
        raise AttendInputError(f"{field}: {_rows(bad, labels)}: expected finite time stamps [s], got {stamps[bad[0]]}")
    steps = np.diff(stamps)
    backwards, repeated = np.flatnonzero(steps < 0) + 1, np.flatnonzero(steps == 0) + 1
    if backwards.size or repeated.size:  # the first problem in the log
        bad, what = (backwards, "before") if backwards.size and (not repeated.size or backwards[0] < repeated[0]) \
            else (repeated, "equal to")
        k = bad[0]
        raise AttendInputError(
            f"{field}: {_rows(bad, labels)}: time stamp {what} the previous one ({_label(labels, k)}: "
            f"{stamps[k]:.6g} s, {_label(labels, k - 1)}: {stamps[k - 1]:.6g} s); expected strictly increasing "
            "time stamps")
    bad = np.flatnonzero(steps < SHORTEST_STEP * dt) + 1
    if bad.size:
        k = bad[0]
        raise AttendInputError(
            f"{field}: {_rows(bad, labels)}: step of {steps[k - 1]:.6g} s ({_label(labels, k - 1)} to "
            f"{_label(labels, k)}) is shorter than half the "
            f"sample time dt = {dt:.6g} s; expected steps >= {SHORTEST_STEP * dt:.6g} s (a duplicated sample?)")
    return stamps


def sample_grid(time, dt: float, n_samples: int | None = None, field: str = "time", labels=None) -> SampleGrid:
    """The :class:`SampleGrid` of the time stamps ``time`` (N,) [s] for nominal sample time dt [s].

    Each step h is k = max(1, round(h / dt)) grid steps of h / k (see the module docstring);
    n_samples: the expected N (default len(time)); field, labels: as :func:`check_time_stamps`.
    """
    count = len(np.atleast_1d(time)) if n_samples is None else n_samples
    stamps = check_time_stamps(time, count, dt, field, labels)
    steps = np.diff(stamps)
    counts = np.maximum(1, np.floor(steps / dt + 0.5)).astype(int)
    rows = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    grid = np.empty(rows[-1] + 1)
    grid[rows] = stamps
    for k in np.flatnonzero(counts > 1):  # the inserted samples split the step evenly
        grid[rows[k]: rows[k + 1] + 1] = np.linspace(stamps[k], stamps[k + 1], counts[k] + 1)
    deviation = np.abs(steps / counts - dt) / dt if steps.size else np.zeros(0)
    jitter = float(deviation.max()) if deviation.size else 0.0
    return SampleGrid(grid, rows, bool(jitter <= UNIFORM_TOLERANCE), int(rows[-1] + 1 - len(stamps)), jitter, dt)


def nominal_step(time) -> float:
    """The nominal sample time [s] of stamps with gaps and jitter: the median step m, then
    (t_end - t_0) / sum_k max(1, round(h_k / m)) (every gap counted in whole samples)."""
    steps = np.diff(np.asarray(time, dtype=float))
    median = float(np.median(steps))
    counts = np.maximum(1, np.floor(steps / median + 0.5))
    return float((time[-1] - time[0]) / counts.sum())


def missing_runs(missing: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of every run of True in the (M,) mask ``missing`` (stop exclusive)."""
    padded = np.concatenate([[False], np.asarray(missing, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def bridge(grid: SampleGrid, values: np.ndarray, field: str, names=None, limit: int = BRIDGED_GAP,
           labels=None) -> np.ndarray:
    """``values`` (N, c) on the grid (M, c): missing samples (NaN, or inserted) linearly
    interpolated in time over runs of up to ``limit``; a longer run, or one at either end of the
    log, is an error naming the column and the rows around it. field: what errors call the columns
    (e.g. "log.csv: column"); names: the columns' names (default their indices); limit: the longest
    run bridged; labels: how errors name log row k (default "row k", e.g. "line 12")."""
    values = np.asarray(values, dtype=float).reshape(len(grid.rows), -1)
    on_grid = grid.spread(values)
    position = np.full(len(grid.time), -1)
    position[grid.rows] = np.arange(len(grid.rows))  # log row of each grid sample (-1: inserted)
    for column in range(on_grid.shape[1]):
        missing = np.isnan(on_grid[:, column])
        if not missing.any():
            continue
        name = str(column) if names is None else names[column]
        if missing.all():
            raise AttendInputError(f"{field} {name!r}: every value is missing (NaN); expected measured values")
        for start, stop in missing_runs(missing):
            if stop - start <= limit and start > 0 and stop < len(missing):
                continue
            count = f"{stop - start} consecutive missing sample{'s' if stop - start > 1 else ''}"
            if start == 0:
                where = f"before {_label(labels, position[stop])} (the start of the log)"
            elif stop == len(missing):
                where = f"after {_label(labels, position[start - 1])} (the end of the log)"
            else:
                where = f"between {_label(labels, position[start - 1])} and {_label(labels, position[stop])}"
            raise AttendInputError(
                f"{field} {name!r}: {count} {where}; expected gaps of at most {limit} samples between measured "
                "values, which are interpolated linearly")
        known = ~missing
        on_grid[missing, column] = np.interp(grid.time[missing], grid.time[known], on_grid[known, column])
    return on_grid


def describe(grid: SampleGrid, missing_outputs: int = 0, jitter: str = "each step discretised exactly") -> str:
    """One line: how many samples were missing and how much jitter was handled (grid: the log's
    grid; missing_outputs: rows with a missing output; jitter: how uneven steps were handled)."""
    parts = []
    if grid.inserted or missing_outputs:
        total = len(grid.time)
        stamps = f"{grid.inserted} skipped time stamp{'s' if grid.inserted != 1 else ''}"
        rows = f"{missing_outputs} row{'s' if missing_outputs != 1 else ''} with missing outputs"
        parts.append(f"{grid.inserted + missing_outputs} of {total} samples missing ({stamps}, {rows})")
    if not grid.uniform:
        steps = grid.steps
        parts.append(f"steps {steps.min():.6g}..{steps.max():.6g} s around dt = {grid.dt:.6g} s (jitter up to "
                     f"{100 * grid.jitter:.3g} %), {jitter}")
    return "; ".join(parts) if parts else "uniform and complete"
