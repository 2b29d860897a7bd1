"""map.png and map.tif written by a second process, so that loading matplotlib and rasterio,
drawing and encoding overlap with the fusion, the planning and the other outputs of
``attend plan`` (on Linux, where the process can be forked; elsewhere they are written by the
calling process).

The painter is forked before the mission is read. The child loads matplotlib and rasterio and
waits on a pipe; :meth:`MapPainter.submit` sends it the jobs, pickled: ("png", a
:class:`~attend.action.mission.map_plot.MapPicture`, path) and ("tif", (probability, origin_xy_m,
cell_size_m, crs_wkt), path). :meth:`MapPainter.wait` returns, per file name, None when it was
written or the error "Type: message". Either process ending early closes the pipes, so neither
waits for ever.
"""

from __future__ import annotations

import os
import pickle
import signal
import sys
from pathlib import Path


class MapPainter:
    """Writes map files in a forked child process (module docstring); ``enabled``: False writes
    them in this process when :meth:`submit` is called."""

    def __init__(self, enabled: bool = True) -> None:
        self.pid = None
        self._results: dict | None = None
        self._picture_write = self._result_read = None
        if not (enabled and sys.platform.startswith("linux") and hasattr(os, "fork")):
            return
        picture_read, picture_write = os.pipe()
        result_read, result_write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: never returns
            os.close(picture_write)
            os.close(result_read)
            _child(picture_read, result_write)
        os.close(picture_read)
        os.close(result_write)
        self.pid = pid
        self._picture_write, self._result_read = picture_write, result_read

    def submit(self, jobs: list) -> None:
        """Start the jobs: a list of (kind, payload, path), kind "png" (payload a MapPicture) or
        "tif" (payload (probability, origin_xy_m, cell_size_m, crs_wkt))."""
        jobs = [(kind, payload, str(path)) for kind, payload, path in jobs]
        if self.pid is None:
            self._results = run_jobs(jobs)
            return
        data = pickle.dumps(jobs, protocol=pickle.HIGHEST_PROTOCOL)
        descriptor, self._picture_write = self._picture_write, None
        with os.fdopen(descriptor, "wb") as pipe:
            pipe.write(data)

    def wait(self) -> dict:
        """{file name: None if written, else "Type: message"} of the submitted jobs."""
        if self.pid is None:
            results, self._results = self._results or {}, None
            return results
        descriptor, self._result_read = self._result_read, None
        with os.fdopen(descriptor, "rb") as pipe:
            data = pipe.read()
        os.waitpid(self.pid, 0)
        self.pid = None
        try:
            return pickle.loads(data)
        except Exception:  # the child died before reporting
            raise RuntimeError("the process writing map.png and map.tif ended early") from None

    def close(self) -> None:
        """Stop the child if its results were not collected (an error before the outputs): killed
        at once when nothing was submitted (it has written nothing), else it sees the pipes close
        and exits."""
        if self.pid is not None and self._picture_write is not None:  # nothing submitted
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        for name in ("_picture_write", "_result_read"):
            descriptor = getattr(self, name)
            if descriptor is not None:
                try:
                    os.close(descriptor)
                except OSError:
                    pass
                setattr(self, name, None)
        if self.pid is not None:
            os.waitpid(self.pid, 0)
            self.pid = None


def run_jobs(jobs: list) -> dict:
    """Run (kind, payload, path) jobs (:meth:`MapPainter.submit`) here; returns {file name: None
    or "Type: message"}."""
    from attend.action.mission.map_plot import draw_map
    from attend.action.mission.plan_files import write_geotiff

    results = {}
    for kind, payload, path in jobs:
        try:
            if kind == "png":
                draw_map(payload, path)
            elif kind == "tif":
                write_geotiff(path, *payload)
            else:
                raise ValueError(f"unknown job {kind!r}")
            results[Path(path).name] = None
        except Exception as error:  # reported to the caller, which decides
            results[Path(path).name] = f"{type(error).__name__}: {error}"
    return results


def _child(picture_read: int, result_write: int) -> None:
    """Load matplotlib and rasterio, read the jobs from the pipe, run them, report the results."""
    try:
        try:
            import matplotlib.backends.backend_agg  # noqa: F401  the imports are the work done early
            import matplotlib.colors  # noqa: F401
            import matplotlib.figure  # noqa: F401
            import matplotlib.ticker  # noqa: F401

            from attend.action.mission import map_plot, plan_files  # noqa: F401
            try:
                import rasterio  # noqa: F401
            except ImportError:  # map.tif reports it
                pass
            with os.fdopen(picture_read, "rb") as pipe:
                data = pipe.read()
            results = run_jobs(pickle.loads(data)) if data else {}
        except BaseException as error:  # reported to the parent for every file
            results = {"map.png": f"{type(error).__name__}: {error}", "map.tif": f"{type(error).__name__}: {error}"}
        with os.fdopen(result_write, "wb") as pipe:
            pipe.write(pickle.dumps(results))
    finally:
        os._exit(0)
