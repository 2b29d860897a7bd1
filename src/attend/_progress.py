"""Progress bars for the long loops of the estimators, shown only where the caller asks for them.

The command line turns them on for ``attend estimate`` on a terminal (``--no-progress`` turns
them off); library code asks with ``with progress_bars(): ...``. A bar appears only once its loop
has run for a second and clears itself when done, so short runs and piped output stay clean.
"""

from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar

_SHOWN = ContextVar("attend_progress_bars", default=False)


@contextmanager
def progress_bars(shown: bool = True):
    """Within the block, the estimators' long loops show progress bars (on stderr) when ``shown``."""
    token = _SHOWN.set(bool(shown))
    try:
        yield
    finally:
        _SHOWN.reset(token)


def steps(iterable, description: str, total: int | None = None, unit: str = "sample"):
    """``iterable`` itself, or wrapped in a progress bar (tqdm) inside :func:`progress_bars`;
    description: the bar's label; total: its length (default len(iterable)); unit: what one step is."""
    if not _SHOWN.get():
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, desc=description, total=total, unit=unit, leave=False, delay=1.0, mininterval=0.5,
                dynamic_ncols=True)
