"""One BLAS thread inside attend's small-matrix loops, without the caller setting anything.

The nonlinear estimators multiply and factorise matrices of ~10-50 rows thousands of times; a
multi-threaded OpenBLAS spends more time waking its threads than computing (10-20x slower on
2 cores). :func:`single_blas_thread` is a context manager that sets every OpenBLAS loaded in the
process (NumPy's and SciPy's wheels each bundle one) to one thread and restores the previous
count on exit. Nothing happens at import: the libraries are looked up at the first use.

It is re-entrant and shared between Python threads (a counter: the first entry limits, the last
exit restores). While it is active, other code in the same process also sees one BLAS thread.
Libraries other than OpenBLAS (MKL, Accelerate, BLIS) are left alone; the estimators still run,
at that library's speed. Setting ``ATTEND_BLAS_THREADS=keep`` in the environment disables it.
"""

from __future__ import annotations

import ctypes
import functools
import os
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

_PREFIXES = ("openblas", "scipy_openblas")
_SUFFIXES = ("", "64_")

_lock = threading.RLock()
_depth = 0
_saved: list[tuple[object, int]] = []
_controls: list[tuple[object, object]] | None = None
_controls_key: tuple | None = None


def _loaded_paths() -> list[str]:
    """Files of the OpenBLAS libraries loaded in this process (Linux: /proc/self/maps; elsewhere
    the folders where the NumPy and SciPy wheels keep theirs)."""
    maps = Path("/proc/self/maps")
    paths: list[str] = []
    if maps.exists():
        try:
            for line in maps.read_text().splitlines():
                parts = line.split(None, 5)
                if len(parts) == 6 and "openblas" in Path(parts[5]).name.lower():
                    paths.append(parts[5].strip())
        except OSError:
            paths = []
    if not paths:
        for name in ("numpy", "scipy"):
            module = sys.modules.get(name)
            if module is None or not getattr(module, "__file__", None):
                continue
            package = Path(module.__file__).resolve().parent
            for folder in (package.parent / f"{name}.libs", package / ".dylibs", package / "lib"):
                if folder.is_dir():
                    paths.extend(str(p) for p in folder.iterdir() if "openblas" in p.name.lower())
    unique = []
    for path in paths:
        if path not in unique:
            unique.append(path)
    return unique


def _find_controls() -> list[tuple[object, object]]:
    """(get, set) function pairs of every loaded OpenBLAS (cached after the first call)."""
    global _controls, _controls_key
    key = tuple(name in sys.modules for name in ("numpy", "scipy.linalg"))  # SciPy's own OpenBLAS comes with scipy.linalg
    if _controls is not None and key == _controls_key:
        return _controls
    controls = []
    mode = getattr(os, "RTLD_NOLOAD", 0) | getattr(os, "RTLD_LOCAL", 0)
    for path in _loaded_paths():
        try:
            library = ctypes.CDLL(path, mode=mode)
        except OSError:
            continue
        for prefix in _PREFIXES:
            for suffix in _SUFFIXES:
                getter = getattr(library, f"{prefix}_get_num_threads{suffix}", None)
                setter = getattr(library, f"{prefix}_set_num_threads{suffix}", None)
                if getter is not None and setter is not None:
                    getter.restype = ctypes.c_int
                    getter.argtypes = []
                    setter.restype = None
                    setter.argtypes = [ctypes.c_int]
                    controls.append((getter, setter))
                    break
            else:
                continue
            break
    _controls, _controls_key = controls, key
    return controls


def with_single_blas_thread(function):
    """Decorator: ``function`` runs under :func:`single_blas_thread`."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with single_blas_thread():
            return function(*args, **kwargs)

    return wrapper


@contextmanager
def single_blas_thread():
    """Run the body with one OpenBLAS thread; the previous counts come back on exit."""
    global _depth
    if os.environ.get("ATTEND_BLAS_THREADS", "").lower() == "keep":
        yield
        return
    with _lock:
        if _depth == 0:
            _saved.clear()
            for getter, setter in _find_controls():
                try:
                    previous = int(getter())
                    if previous != 1:
                        setter(1)
                        _saved.append((setter, previous))
                except (OSError, ValueError):  # a library that refuses: leave it as it is
                    continue
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                for setter, previous in _saved:
                    setter(previous)
                _saved.clear()


def blas_threads() -> list[int]:
    """The current thread count of each loaded OpenBLAS (for tests and benchmarks)."""
    return [int(getter()) for getter, _ in _find_controls()]
