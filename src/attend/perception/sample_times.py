"""Time stamps of real logs (gaps and jitter) now live in :mod:`attend.models.sample_times`: the
readers of :mod:`attend.io` check a log's stamps with them and may import nothing from perception.
This module keeps the old import path for the modules that still use it."""

from attend.models.sample_times import (  # noqa: F401
    BRIDGED_GAP,
    SHORTEST_STEP,
    UNIFORM_TOLERANCE,
    SampleGrid,
    bridge,
    check_time_stamps,
    describe,
    matrix_with_gaps,
    missing_runs,
    nominal_step,
    sample_grid,
)
