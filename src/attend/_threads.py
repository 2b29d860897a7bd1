"""One BLAS thread inside attend's small-matrix loops, without the caller setting anything.

The nonlinear estimators and the search planners multiply and factorise matrices of ~10-50 rows
thousands of times; a multi-threaded BLAS spends more time waking its threads than computing
(10-20x slower on 2 cores). :func:`single_blas_thread` is a context manager that limits every
BLAS loaded in the process (NumPy's and SciPy's wheels each bundle an OpenBLAS; MKL and BLIS
alike) to one thread through threadpoolctl, and restores the previous counts on exit.

threadpoolctl is imported at the first use, not at import of attend (importing it sets an
environment variable). The context is re-entrant. OpenBLAS has one thread pool per process, so
threadpoolctl lets one Python thread at a time change it: while one thread holds the limit, the
others run under it, and the limit ends when that thread leaves. ``ATTEND_BLAS_THREADS=keep`` in
the environment disables it.
"""

from __future__ import annotations

import functools
import os
import sys
import threading
from contextlib import contextmanager

_local = threading.local()
_controller = None
_controller_key: tuple | None = None


def _blas_controller():
    """threadpoolctl's controller over the BLAS libraries loaded now (rebuilt when NumPy or
    scipy.linalg, which bring their own, have been imported since)."""
    global _controller, _controller_key
    from threadpoolctl import ThreadpoolController

    key = tuple(name in sys.modules for name in ("numpy", "scipy.linalg"))
    if _controller is None or key != _controller_key:
        _controller, _controller_key = ThreadpoolController().select(user_api="blas"), key
    return _controller


def with_single_blas_thread(function):
    """Decorator: ``function`` runs under :func:`single_blas_thread`."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with single_blas_thread():
            return function(*args, **kwargs)

    return wrapper


@contextmanager
def single_blas_thread():
    """Run the body with one BLAS thread; the previous counts come back on exit (re-entrant)."""
    if os.environ.get("ATTEND_BLAS_THREADS", "").lower() == "keep" or getattr(_local, "depth", 0):
        _local.depth = getattr(_local, "depth", 0) + 1
        try:
            yield
        finally:
            _local.depth -= 1
        return
    _local.depth = 1
    try:
        with _blas_controller().limit(limits=1):
            yield
    finally:
        _local.depth = 0


def blas_threads() -> list[int]:
    """The current thread count of each loaded BLAS (for tests and benchmarks)."""
    return [int(info["num_threads"]) for info in _blas_controller().info()]


def set_blas_threads(count: int) -> None:
    """Set every loaded BLAS to ``count`` threads (for tests and benchmarks), leaving no Python
    thread in control of OpenBLAS's shared pool (threadpoolctl lets one thread at a time change it)."""
    from threadpoolctl import OpenBLASController

    _blas_controller().limit(limits=int(count))
    OpenBLASController.clear_controlling_thread()
