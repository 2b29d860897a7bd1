"""CSV logs (read and checked) and the CSV of estimates."""

from __future__ import annotations

import csv
import io as _text_io
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from attend._validation import LARGEST_MAGNITUDE, AttendInputError, unique_names
from attend.io.fields import _read_text
from attend.models.linear import LinearSystem

if TYPE_CHECKING:  # only named in annotations
    from attend.io.model import ModelFile


@dataclass(frozen=True)
class Log:
    """A log: time [s] (N,), and named columns (name -> (N,) values); path: the CSV file or bag
    (errors name it); line_numbers: (N,) the file line of each sample (None: line k + 2 of a CSV);
    origin: how the samples were made when they are not the rows of a CSV ("": a CSV; a bag: its
    grid, resampling rule and time stamps, :mod:`attend.io.bags`)."""

    time: np.ndarray
    columns: dict[str, np.ndarray]
    path: str = ""
    line_numbers: np.ndarray | None = None  # line of each sample in the file (errors name it)
    origin: str = ""  # a bag's grid and resampling (attend.io.bags); "" for a CSV

    @property
    def dt(self) -> float:
        """Sample time [s]: the mean step of a uniform log; with gaps or jitter the nominal step
        (:func:`attend.models.sample_times.nominal_step`: gaps counted in whole samples)."""
        mean = float((self.time[-1] - self.time[0]) / (len(self.time) - 1))
        if self.uniform:
            return mean
        from attend.models.sample_times import nominal_step

        return nominal_step(self.time)

    @property
    def uniform(self) -> bool:
        """Every step within 1e-4 of the mean step (no skipped time stamps, no jitter)."""
        if len(self.time) < 2:
            return True
        mean = (self.time[-1] - self.time[0]) / (len(self.time) - 1)
        return bool(np.all(np.abs(np.diff(self.time) - mean) <= UNIFORM_STEP_TOLERANCE * mean))

    @property
    def labels(self) -> list[str]:
        """How errors name each sample: "line L" of a CSV, "sample k (t = T s)" of a bag."""
        if self.origin and self.line_numbers is None:
            return [f"sample {k + 1} (t = {t:.6g} s)" for k, t in enumerate(self.time)]
        lines = self.line_numbers if self.line_numbers is not None else np.arange(len(self.time)) + 2
        return [f"line {line}" for line in lines]

    def matrix(self, names, missing: bool = False) -> np.ndarray:
        """Columns ``names`` side by side as an (N, len(names)) array; NaN, inf and values beyond
        +-1e150 in them are errors naming the file, line and column. missing=True: NaN (an empty
        or "nan" cell) is kept as a missing value, inf and values beyond +-1e150 are still errors."""
        absent = [name for name in names if name not in self.columns]
        if absent:
            raise AttendInputError(
                f"{self.path}: {'the log' if self.origin else 'CSV'} is missing the declared column"
                f"{'s' if len(absent) > 1 else ''} {', '.join(map(repr, absent))}; it has {', '.join(self.columns)}"
            )
        labels = self.labels
        for name in names:
            values = self.columns[name]
            _check_log_column(np.where(np.isnan(values), 0.0, values) if missing else values, self.path, name, labels)
        return np.column_stack([self.columns[name] for name in names]) if names else np.zeros((len(self.time), 0))


UNIFORM_STEP_TOLERANCE = 1e-4
"""Relative deviation from the mean step below which a log's time stamps count as uniform."""


def read_log(path: str | Path, time_column: str | ModelFile = "t", *,
             relative_tolerance: float = UNIFORM_STEP_TOLERANCE, gaps: bool = False) -> Log:
    """Read a CSV log with a header; check the time column is present, finite and uniform.

    path: the CSV file, or a ROS bag (.bag, .mcap, .db3, or a ROS 2 bag folder), read with
    :func:`attend.io.bags.read_bag` onto one uniform grid (this needs the model file's
    [log.columns]); time_column: the name of the time column [s], or the parsed model file
    (:class:`ModelFile`: its [log] time_column and, for a bag, its topics, fields and grid).
    CSV: UTF-8 with or without a BOM, LF or CRLF line ends. Every cell must be a number; values beyond +-1e150 are errors.
    Time stamps count as uniform when every step is within ``relative_tolerance`` of the mean step.
    gaps=True (`attend estimate`): a log with missing samples and jitter is accepted: empty
    cells read as NaN (missing), time stamps need only increase strictly (errors name the lines
    where they repeat or go backwards); :mod:`attend.models.sample_times` says how the
    estimators treat skipped stamps and uneven steps.
    """
    path = Path(path)
    layout = None
    if not isinstance(time_column, str):  # a ModelFile: its [log] section says how to read the log
        time_column, layout = time_column.time_column, time_column.bag_layout
    from attend.io.bags import is_bag, read_bag

    if is_bag(path):
        return read_bag(path, layout, time_column, gaps=gaps)
    if path.is_dir():
        raise AttendInputError(f"log: {path} is a directory; expected a CSV file, or a ROS 2 bag folder (with metadata.yaml)")
    text = _read_text(path, "log")
    try:
        lines = list(csv.reader(_text_io.StringIO(text, newline=None)))
    except csv.Error as error:
        raise AttendInputError(f"{path}: not a readable CSV ({error})") from None
    numbered = [(number_, row) for number_, row in enumerate(lines, start=1) if any(cell.strip() for cell in row)]
    if not numbered:
        raise AttendInputError(f"{path}: the CSV is empty (expected a header row and samples)")
    header = [name.strip() for name in numbered[0][1]]
    rows = numbered[1:]
    unique_names([name for name in header if name], f"{path}: header")
    if not rows:
        raise AttendInputError(f"{path}: the CSV has a header but no samples")
    if time_column not in header:
        raise AttendInputError(f"{path}: CSV is missing the time column {time_column!r}; it has {', '.join(header)}")
    try:
        cells = [row for _, row in rows]
        if gaps:  # an empty cell is a missing value
            cells = [[cell if cell.strip() else "nan" for cell in row] for row in cells]
        values = np.array(cells, dtype=float)
    except ValueError:
        for line, row in rows:
            if len(row) != len(header):
                raise AttendInputError(f"{path}: line {line} has {len(row)} fields, the header has {len(header)}") from None
            for name, cell in zip(header, row):
                try:
                    float(cell if cell.strip() or not gaps else "nan")
                except ValueError:
                    raise AttendInputError(f"{path}: line {line}, column {name!r}: expected a number, got {cell!r}") from None
        raise
    line_numbers = np.array([line for line, _ in rows])
    columns = {name: values[:, j] for j, name in enumerate(header)}
    time = columns[time_column]
    _check_log_column(time, path, time_column, [f"line {line}" for line in line_numbers])
    if gaps and len(time) >= 2:
        from attend.models.sample_times import check_time_stamps

        check_time_stamps(time, len(time), float(np.min(np.abs(np.diff(time)))) or 1.0,
                          f"{path}: column {time_column!r}", [f"line {line}" for line in line_numbers])
    elif len(time) >= 2:
        steps = np.diff(time)
        mean_step = (time[-1] - time[0]) / (len(time) - 1)
        if mean_step <= 0:
            raise AttendInputError(f"{path}: column {time_column!r}: time stamps must increase")
        worst = int(np.argmax(np.abs(steps - mean_step)))
        if abs(steps[worst] - mean_step) > relative_tolerance * mean_step:
            raise AttendInputError(
                f"{path}: column {time_column!r}: non-uniform time stamps (step {steps[worst]:.6g} s at line "
                f"{line_numbers[worst + 1]}, mean step {mean_step:.6g} s); resample the log to a uniform rate first "
                "(`attend estimate` accepts gaps and jitter)"
            )
    return Log(time, columns, str(path), line_numbers)


def _check_log_column(values: np.ndarray, path, name: str, labels: list[str]) -> None:
    """NaN, inf and values beyond +-1e150 are errors naming the file, sample (labels: "line L" or
    "sample k (t = T s)" of each) and column."""
    bad = ~np.isfinite(values) | (np.abs(values) > LARGEST_MAGNITUDE)
    if bad.any():
        row = int(np.argmax(bad))
        expected = "a finite number" if not np.isfinite(values[row]) else f"a value within +-{LARGEST_MAGNITUDE:.0e}"
        sample = "" if labels[row].startswith("sample") else f" (sample {row + 1})"
        raise AttendInputError(
            f"{path}: {labels[row]}{sample}, column {name!r}: expected {expected}, got {values[row]:.6g}"
        )



def write_estimates(path: str | Path, log: Log, system: LinearSystem, estimate) -> Path:
    """CSV with time, each state and input estimate, and their standard deviations.

    path: the CSV to write (parent folders created); log: the :class:`Log` estimated (its time
    column [s] is written); system: names the state and input columns; estimate: any estimator's
    result with states (N, n), inputs (N, r) and their stds state_std, input_std. Returns the path."""
    path = Path(path)
    header = ["t"]
    header += list(system.state_names) + list(system.input_names)
    header += [f"{name}_std" for name in system.state_names] + [f"{name}_std" for name in system.input_names]
    table = np.column_stack([log.time, estimate.states, estimate.inputs, estimate.state_std, estimate.input_std])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.10g")
    return path
