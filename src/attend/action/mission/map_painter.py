"""map.png drawn by a second process, so that loading matplotlib and drawing overlap with the
fusion, the planning and the other outputs of ``attend plan`` (on Linux, where the process can
be forked; elsewhere the map is drawn in the calling process).

The painter is forked before the mission is read. The child loads matplotlib and waits on a
pipe; :meth:`MapPainter.submit` sends it a :class:`~attend.action.mission.map_plot.MapPicture`
(plain arrays, pickled) and the path, :meth:`MapPainter.wait` returns when the file is written
and raises if the child failed. Either process ending early closes the pipes, so neither waits
for ever.
"""

from __future__ import annotations

import os
import pickle
import sys


class MapPainter:
    """Draws one map.png in a forked child process (module docstring); ``enabled``: False draws
    in this process when :meth:`submit` is called."""

    def __init__(self, enabled: bool = True) -> None:
        self.pid = None
        self._pending = None
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

    def submit(self, picture, path) -> None:
        """Start drawing ``picture`` (a MapPicture) to ``path`` (PNG)."""
        if self.pid is None:
            from attend.action.mission.map_plot import draw_map

            draw_map(picture, path)
            return
        data = pickle.dumps((picture, str(path)), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            with os.fdopen(self._picture_write, "wb") as pipe:
                pipe.write(data)
        finally:
            self._picture_write = None
        self._pending = path

    def wait(self) -> None:
        """Return when the submitted map is written; raises RuntimeError with the child's message
        if it could not be drawn."""
        if self.pid is None or self._pending is None:
            return
        with os.fdopen(self._result_read, "rb") as pipe:
            message = pipe.read().decode("utf-8", "replace")
        self._result_read = None
        os.waitpid(self.pid, 0)
        self.pid, self._pending = None, None
        if message != "ok":
            raise RuntimeError(f"map.png could not be drawn: {message or 'the drawing process ended early'}")

    def close(self) -> None:
        """Stop the child if nothing was submitted (an error before the outputs): it sees the
        pipe close and exits."""
        if self.pid is None:
            return
        for name in ("_picture_write", "_result_read"):
            descriptor = getattr(self, name)
            if descriptor is not None:
                try:
                    os.close(descriptor)
                except OSError:
                    pass
                setattr(self, name, None)
        os.waitpid(self.pid, 0)
        self.pid = None


def _child(picture_read: int, result_write: int) -> None:
    """Load matplotlib, read (picture, path) from the pipe, draw, report "ok" or the error."""
    status = 0
    try:
        try:
            from attend.action.mission.map_plot import draw_map
            import matplotlib.backends.backend_agg  # noqa: F401  the import is the work done early
            import matplotlib.colors  # noqa: F401
            import matplotlib.figure  # noqa: F401
            import matplotlib.ticker  # noqa: F401

            with os.fdopen(picture_read, "rb") as pipe:
                data = pipe.read()
            if data:
                picture, path = pickle.loads(data)
                draw_map(picture, path)
                message = "ok"
            else:
                message = ""  # nothing submitted: the parent stopped early
        except BaseException as error:  # reported to the parent, which raises it
            message = f"{type(error).__name__}: {error}"
            status = 1
        with os.fdopen(result_write, "wb") as pipe:
            pipe.write(message.encode("utf-8"))
    finally:
        os._exit(status)
